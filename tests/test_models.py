"""Models: shapes, geometry kernels, equivariance, key-padding masks, gradients, jit, presets."""

import dataclasses
from functools import partial

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from flax import nnx

from jaxmotion.config import apply_overrides
from jaxmotion.models import (ADM, ADMMLP, AMDM, PRESET_NAMES, ADMConfig, ADMPointTransformer,
                              AMDMConfig, PointTransformerConfig, PointTransformerEncoder,
                              PointTransformerSeg, PointTransformerUNet, build_geometry,
                              farthest_point_sampling, knn, make_adm, param_count,
                              preset_overrides, segmentation_loss, sinusoidal_embedding)
from jaxmotion.models.point_transformer import PointTransformerBlock

B, N, T = 2, 64, 8
ADM_ARCHS = ("perceiver", "mlp", "point_transformer")
# Unoptimised XLA builds compile these tiny programs about twice as fast; the suite is
# dominated by compilation.
FAST = {"xla_backend_optimization_level": 0}


def _jit(f):
    """``nnx.jit`` for ``f(module, *arrays)`` with FAST compiler options (state updates kept)."""

    @partial(jax.jit, static_argnums=0, compiler_options=FAST)
    def pure(graphdef, state, *args):
        module = nnx.merge(graphdef, state)
        return f(module, *args), nnx.state(module)

    def call(module, *args):
        out, state = pure(*nnx.split(module), *args)
        nnx.update(module, state)
        return out

    return call


def _key(i):
    return jax.random.fold_in(jax.random.PRNGKey(0), i)


def _cloud(i=0, n=N, b=B):
    return jax.random.uniform(_key(i), (b, n, 3), minval=-2.0, maxval=2.0)


def _adm_cond(cfg, xyz):
    return dict(text=jax.random.normal(_key(10), (xyz.shape[0], cfg.text_dim)),
                features=jax.random.normal(_key(11), (*xyz.shape[:2], cfg.feature_dim)),
                xyz=xyz)


def _amdm_cond(cfg, xyz, mask=None):
    b = xyz.shape[0]
    return dict(text=jax.random.normal(_key(20), (b, cfg.text_dim)), xyz=xyz,
                affordance=jax.random.normal(_key(21), (*xyz.shape[:2], cfg.affordance_dim)),
                rgb=jax.random.uniform(_key(22), xyz.shape, minval=-1.0, maxval=1.0),
                mask=jnp.ones((b, T), bool) if mask is None else mask)


def _adm(arch, **kw):
    return make_adm(dataclasses.replace(ADMConfig.tiny(), arch=arch, **kw), rngs=nnx.Rngs(0))


def _amdm(arch="enc", **kw):
    return AMDM(dataclasses.replace(AMDMConfig.tiny(), arch=arch, **kw), rngs=nnx.Rngs(0))


# ----------------------------------------------------------------------------- geometry

def test_knn_matches_numpy_brute_force():
    q, p = np.asarray(_cloud(1, n=40)), np.asarray(_cloud(2, n=70))
    idx, d2 = knn(jnp.asarray(q), jnp.asarray(p), 5, budget=420)  # 3-query chunks + padding
    ref_d2 = ((q[:, :, None] - p[:, None]) ** 2).sum(-1)
    ref_idx = np.argsort(ref_d2, axis=-1)[..., :5]
    np.testing.assert_array_equal(np.asarray(idx), ref_idx)
    np.testing.assert_allclose(np.asarray(d2), np.take_along_axis(ref_d2, ref_idx, -1),
                               atol=1e-5)
    assert idx.dtype == jnp.int32
    with pytest.raises(ValueError, match="neighbours"):
        knn(jnp.asarray(q), jnp.asarray(p[:, :3]), 5)


def test_fps_distinct_deterministic_and_spread():
    pts = _cloud(3, n=128)
    a = np.asarray(farthest_point_sampling(pts, 32))
    b = np.asarray(jax.jit(farthest_point_sampling, static_argnums=1,
                           compiler_options=FAST)(pts, 32))
    np.testing.assert_array_equal(a, b)
    assert (a[:, 0] == 0).all()
    assert all(len(set(row)) == 32 for row in a)
    # the second pick is the farthest point from the first
    p = np.asarray(pts)
    far = np.argmax(((p - p[:, :1]) ** 2).sum(-1), axis=1)
    np.testing.assert_array_equal(a[:, 1], far)
    # duplicated points (padded crops) still give distinct indices
    dup = jnp.concatenate([pts[:, :8]] * 4, axis=1)
    d = np.asarray(farthest_point_sampling(dup, 20))
    assert all(len(set(row)) == 20 for row in d)


def test_build_geometry_shapes_and_errors():
    cfg = PointTransformerConfig.tiny()
    geo = jax.jit(build_geometry, static_argnums=1, static_argnames=("upsample", "neighbors"),
                  compiler_options=FAST)(_cloud(), cfg, upsample=True, neighbors=(True, True))
    assert [g.xyz.shape[1] for g in geo] == [64, 16]
    assert geo[1].group.shape == (B, 16, 4) and geo[1].neighbors.shape == (B, 16, 4)
    assert geo[1].up_idx.shape == (B, 64, 3) and geo[0].group is None
    np.testing.assert_allclose(np.asarray(geo[1].up_weight.sum(-1)), 1.0, rtol=1e-5)
    # stage points are a subset of the previous stage's
    prev, cur = np.asarray(geo[0].xyz[0]), np.asarray(geo[1].xyz[0])
    assert all(np.any(np.all(prev == c, -1)) for c in cur)
    stride = build_geometry(_cloud(), dataclasses.replace(cfg, sampling="stride"))
    np.testing.assert_array_equal(np.asarray(stride[1].xyz), np.asarray(_cloud()[:, ::4]))
    with pytest.raises(ValueError, match="divisible"):
        build_geometry(_cloud(n=62), cfg)


# ----------------------------------------------------------------------------- equivariance

@pytest.mark.parametrize("norm", ["batch", "layer"])
def test_point_transformer_block_permutation_equivariant(norm):
    block = PointTransformerBlock(16, 4, norm, rngs=nnx.Rngs(0))  # vector attention inside
    xyz, x = _cloud(4), jax.random.normal(_key(5), (B, N, 16))
    perm = np.asarray(jax.random.permutation(_key(6), N))
    nbr = knn(xyz, xyz, 6)[0]
    nbr_p = knn(xyz[:, perm], xyz[:, perm], 6)[0]
    fwd = _jit(lambda m, x, xyz, nbr: m(x, xyz, nbr))  # training mode: batch statistics
    y = fwd(block, x, xyz, nbr)                             # are permutation invariant
    y_p = fwd(block, x[:, perm], xyz[:, perm], nbr_p)
    np.testing.assert_allclose(np.asarray(y_p), np.asarray(y[:, perm]), atol=1e-5)


@pytest.mark.parametrize("arch", ["perceiver", "mlp"])
def test_adm_point_permutation_equivariant(arch):
    model = _adm(arch)
    model.eval()
    xyz = _cloud(7)
    cond = _adm_cond(model.cfg, xyz)
    x, t = jax.random.normal(_key(8), (B, N, 6)), jnp.array([3, 40])
    perm = np.asarray(jax.random.permutation(_key(9), N))
    fwd = _jit(lambda m, x, c: m(x, t, c))
    y = fwd(model, x, cond)
    cond_p = {k: (v[:, perm] if v.ndim == 3 else v) for k, v in cond.items()}
    y_p = fwd(model, x[:, perm], cond_p)
    np.testing.assert_allclose(np.asarray(y_p), np.asarray(y[:, perm]), atol=1e-5)
    if arch == "mlp":  # the public nnx.jit agrees (the other tests use FAST compiles)
        y_nnx = nnx.jit(lambda m, x, c: m(x, t, c))(model, x, cond)
        np.testing.assert_allclose(np.asarray(y_nnx), np.asarray(y), atol=1e-5)


# ----------------------------------------------------------------------------- shapes

def _shape(f, *args):
    """Output shapes and dtypes without compiling (``nnx.eval_shape``)."""
    return nnx.eval_shape(f, *args)


def test_point_transformer_shapes():
    cfg = PointTransformerConfig.tiny()
    xyz, rgb = _cloud(), jax.random.uniform(_key(1), (B, N, 3))
    seg = PointTransformerSeg(cfg, rngs=nnx.Rngs(0))
    feats, logits = _shape(lambda m: m(xyz, rgb), seg)
    assert feats.shape == (B, N, cfg.out_dim) and logits.shape == (B, N, cfg.num_classes)
    three = dataclasses.replace(cfg, planes=(16, 32, 32), blocks=(2, 1, 2), strides=(1, 4, 2),
                                nsample=(4, 4, 3), decoder_blocks=2)
    enc = PointTransformerEncoder(three, 6, rngs=nnx.Rngs(0))
    pts, tok = _shape(lambda m: m(xyz, jnp.zeros((B, N, 6))), enc)
    assert pts.shape == (B, N // 8, 3) and tok.shape == (B, N // 8, 32)
    unet = PointTransformerUNet(dataclasses.replace(three, norm="layer"), 0, rngs=nnx.Rngs(0))
    levels = _shape(lambda m: m.levels(xyz), unet)
    assert [lv.shape for lv in levels] == [(B, 64, 16), (B, 16, 32), (B, 8, 32)]
    proj = PointTransformerSeg(dataclasses.replace(cfg, out_dim=8), rngs=nnx.Rngs(0))
    assert _shape(lambda m: m(xyz, rgb)[0], proj).shape == (B, N, 8)


@pytest.mark.parametrize("arch", ADM_ARCHS)
def test_adm_shapes(arch):
    model = _adm(arch)
    assert type(model) is {"perceiver": ADM, "mlp": ADMMLP,
                           "point_transformer": ADMPointTransformer}[arch]
    cond = _adm_cond(model.cfg, _cloud())
    y = _shape(lambda m: m(jnp.zeros((B, N, 6)), jnp.array([0, 499]), cond), model)
    assert y.shape == (B, N, 6) and y.dtype == jnp.float32
    with pytest.raises(ValueError, match="shape"):
        model(jnp.zeros((B, N, 6)), jnp.zeros(B), {**cond, "text": jnp.zeros((B, 7))})


@pytest.mark.parametrize("arch,scene", [("enc", "affordance"), ("dec", "affordance"),
                                        ("enc", "rgb"), ("dec", "rgb")])
def test_amdm_shapes(arch, scene):
    model = _amdm(arch, scene_input=scene)
    cond = _amdm_cond(model.cfg, _cloud())
    if scene == "rgb":
        del cond["affordance"]
    y = _shape(lambda m: m(jnp.zeros((B, T, 66)), jnp.array([1, 999]), cond), model)
    assert y.shape == (B, T, 66) and y.dtype == jnp.float32
    if arch == "dec":  # cross-attention after all but the last of 5 layers, coarsest first
        deep = dataclasses.replace(model.cfg, num_layers=5, encoder=dataclasses.replace(
            model.cfg.encoder, planes=(16,) * 4, blocks=(1,) * 4, strides=(1, 2, 2, 2),
            nsample=(2,) * 4))
        assert AMDM(deep, rngs=nnx.Rngs(0)).n_cross == 4


# ----------------------------------------------------------------------------- masks and cond

@pytest.mark.parametrize("arch", ["enc", "dec"])
def test_amdm_key_padding_mask(arch):
    model = _amdm(arch)
    model.eval()
    lengths = jnp.array([T, 5])
    mask = jnp.arange(T)[None] < lengths[:, None]
    cond = _amdm_cond(model.cfg, _cloud(), mask)
    x = jax.random.normal(_key(2), (B, T, 66))
    noise = 100.0 * jax.random.normal(_key(3), x.shape)
    x2 = jnp.where(mask[..., None], x, noise)
    t = jnp.array([5, 5])
    fwd = _jit(lambda m, x: m(x, t, cond))
    y, y2 = fwd(model, x), fwd(model, x2)
    valid = np.asarray(mask)
    np.testing.assert_allclose(np.asarray(y2)[valid], np.asarray(y)[valid], atol=1e-5)
    assert not np.allclose(np.asarray(y2)[~valid], np.asarray(y)[~valid])


def test_condition_dropout_and_cached_tokens():
    model = _amdm("enc")
    model.eval()
    base = _amdm_cond(model.cfg, _cloud())
    base = {**base, "drop_text": jnp.zeros(B, bool), "drop_affordance": jnp.zeros(B, bool)}
    x, t = jax.random.normal(_key(4), (B, T, 66)), jnp.array([2, 3])
    fwd = _jit(lambda m, c: m(x, t, c))
    y = fwd(model, base)
    cached = _jit(lambda m, c: m(x, t, m.encode_condition(c)))(model, base)
    np.testing.assert_allclose(np.asarray(cached), np.asarray(y), atol=1e-5)
    drop = jnp.array([True, False])
    y_drop = fwd(model, {**base, "drop_text": drop})
    y_zero = fwd(model, {**base, "text": base["text"].at[0].set(0.0)})
    np.testing.assert_allclose(np.asarray(y_drop), np.asarray(y_zero), atol=1e-5)
    np.testing.assert_allclose(np.asarray(y_drop[1]), np.asarray(y[1]), atol=1e-5)
    y_aff = fwd(model, {**base, "drop_affordance": drop})
    assert not np.allclose(np.asarray(y_aff[0]), np.asarray(y[0]))
    np.testing.assert_allclose(np.asarray(y_aff[1]), np.asarray(y[1]), atol=1e-5)
    zeros = {**base, "text": jnp.zeros_like(base["text"]),
             "affordance": jnp.zeros_like(base["affordance"])}
    assert np.isfinite(np.asarray(fwd(model, zeros))).all()


# ----------------------------------------------------------------------------- grads and jit

def _model_and_loss(name):
    xyz = _cloud()
    t = jnp.array([1, 7])
    if name == "seg":
        rgb = jax.random.uniform(_key(1), (B, N, 3))
        labels = jax.random.randint(_key(2), (B, N), -1, 44)
        return (PointTransformerSeg(PointTransformerConfig.tiny(), rngs=nnx.Rngs(0)),
                lambda m: segmentation_loss(m(xyz, rgb)[1], labels)[0])
    if name.startswith("adm_"):
        x = jax.random.normal(_key(3), (B, N, 6))
        model = _adm(name[4:])
        return model, lambda m: jnp.sum(m(x, t, _adm_cond(m.cfg, xyz)) ** 2)
    x = jax.random.normal(_key(4), (B, T, 66))
    model = _amdm(name[5:])
    return model, lambda m: jnp.sum(m(x, t, _amdm_cond(m.cfg, xyz)) ** 2)


# Training mode (dropout, batch statistics) where it adds a code path: the segmentation
# network (BatchNorm) and the Perceiver (attention dropout); eval mode elsewhere keeps the
# suite's compile time down.
@pytest.mark.parametrize("name,train", [("seg", True), ("adm_perceiver", True),
                                        ("adm_mlp", False), ("adm_point_transformer", False),
                                        ("amdm_enc", False), ("amdm_dec", False)])
def test_gradients_finite_under_jit(name, train):
    model, loss = _model_and_loss(name)
    if not train:
        model.eval()
    value, grads = _jit(nnx.value_and_grad(loss))(model)
    leaves = jax.tree.leaves(grads)
    assert np.isfinite(float(value))
    assert leaves and all(np.isfinite(np.asarray(g)).all() for g in leaves)
    assert sum(float(jnp.abs(g).sum()) for g in leaves) > 0


# ----------------------------------------------------------------------------- configs

def test_configs_presets_and_overrides():
    for cls in (PointTransformerConfig, ADMConfig, AMDMConfig):
        assert cls() == cls.cpu() == cls.preset("default")
        for name in PRESET_NAMES:
            cfg = cls.preset(name)
            assert apply_overrides(cls(), preset_overrides(cls, name)) == cfg
    paper = AMDMConfig.paper()
    assert (paper.d_model, paper.num_layers, paper.ff_dim, paper.num_heads) == (512, 5, 1024, 8)
    assert paper.encoder.planes == (32, 64, 128, 256) and paper.encoder.total_stride == 64
    seg = PointTransformerConfig.paper()
    assert seg.blocks == (2, 3, 4, 6, 3) and seg.total_stride == 256
    adm = ADMConfig.paper()
    assert (adm.point_width, adm.latent_width, adm.self_layers) == (256, 512, 2)
    with pytest.raises(ValueError, match="share_planes"):
        PointTransformerConfig(planes=(30, 64, 128, 256))
    with pytest.raises(ValueError, match="unknown preset"):
        ADMConfig.preset("huge")


def test_sinusoidal_embedding_and_loss():
    e = sinusoidal_embedding(jnp.array([0, 3]), 8)
    np.testing.assert_allclose(np.asarray(e[0]), [0, 1] * 4, atol=1e-7)
    np.testing.assert_allclose(float(e[1, 0]), np.sin(3.0), rtol=1e-6)
    logits = jnp.array([[[5.0, 0.0], [0.0, 5.0], [9.0, 0.0]]])
    loss, acc = segmentation_loss(logits, jnp.array([[0, 0, -1]]))
    assert float(acc) == 0.5 and float(loss) > 0


@pytest.mark.slow
def test_paper_parameter_counts():
    counts = {
        "seg": param_count(PointTransformerSeg(PointTransformerConfig.paper(), rngs=nnx.Rngs(0))),
        **{f"adm_{a}": param_count(make_adm(dataclasses.replace(ADMConfig.paper(), arch=a),
                                            rngs=nnx.Rngs(0))) for a in ADM_ARCHS},
        **{f"amdm_{a}": param_count(AMDM(dataclasses.replace(AMDMConfig.paper(), arch=a),
                                         rngs=nnx.Rngs(0))) for a in ("enc", "dec")},
    }
    print("paper parameter counts:", counts)
    # 13-class S3DIS Point Transformer: 7.8 M in the literature; ours with 44 classes
    assert 7.7e6 < counts["seg"] < 7.9e6
    assert 11e6 < counts["amdm_enc"] < 13e6
