"""The action recognizer: tiny training on a synthetic dataset, accuracy above chance on its
training motions, export/load round trip, versioning, invariance to where the motion is,
padding independence, chunked batches, and action accuracy on hand-made inputs."""

import json

import numpy as np
import pytest

from jaxmotion.config import load_config
from jaxmotion.data.format import ACTIONS, load_sample
from jaxmotion.data.synth import SynthSettings, build_dataset
from jaxmotion.eval.evaluator import manifest_sha256
from jaxmotion.eval.recognizer import (
    RECOGNIZER_VERSION,
    Recognizer,
    action_accuracy,
    action_ids,
    load_recognizer,
)
from jaxmotion.train import load_trained, train
from jaxmotion.train.recognizer_task import MotionActionDataset
from jaxmotion.train.tasks import get_task

STEPS = 60


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    root = tmp_path_factory.mktemp("recognizer")
    data = root / "data"
    build_dataset(data, SynthSettings(scenes=6, per_scene=4, seed=2, points_per_scene=2000),
                  progress=False, stats=False)
    cfg = load_config("configs/recognizer.py", [f"data_dir={data}", f"workdir={root / 'run'}",
                                                 "preset=tiny", f"steps={STEPS}", "log_every=10",
                                                 f"ckpt_every={STEPS}", "eval_every=0"])
    result = train(cfg, get_task(cfg))
    ds = MotionActionDataset(data, "train")
    return cfg, result, load_recognizer(root / "run"), ds.batch(np.arange(len(ds)))


def test_loss_falls_and_export_is_versioned(run):
    cfg, result, rec, _ = run
    rows = [json.loads(x) for x in (result.workdir / "metrics.jsonl").read_text().splitlines()]
    losses = [r["loss"] for r in rows if "loss" in r]
    assert len(losses) == STEPS // 10 and np.isfinite(losses).all()
    assert np.mean(losses[-2:]) < 0.7 * np.mean(losses[:1]), losses
    assert all(0.0 <= r["accuracy"] <= 1.0 for r in rows if "accuracy" in r)
    desc = rec.describe()
    assert rec.version == desc["recognizer_version"] == RECOGNIZER_VERSION
    assert desc["data_manifest_sha256"] == manifest_sha256(cfg.data_dir)
    assert desc["step"] == STEPS and desc["fps"] == 30 and len(desc["weights_sha256"]) == 64
    assert rec.actions == ACTIONS == ("walk", "sit", "stand_up", "lie")


def test_dataset_labels_and_time_crop(run):
    cfg, _, _, b = run
    ds = MotionActionDataset(cfg.data_dir, "train")
    assert b["joints"].shape == (len(ds), cfg.max_frames, 22, 3) and b["action"].dtype == np.int32
    want = [ACTIONS.index(load_sample(f)["action"]) for f in ds.files]
    np.testing.assert_array_equal(b["action"], want)
    cropped = MotionActionDataset(cfg.data_dir, "train", time_crop=0.2)
    c1 = cropped.batch(np.arange(4), np.random.default_rng(0))
    c2 = cropped.batch(np.arange(4), np.random.default_rng(0))
    np.testing.assert_array_equal(c1["joints"], c2["joints"])  # a function of the rng
    n, full = c1["mask"].sum(1), b["mask"][:4].sum(1)
    assert (n <= full).all() and (n >= 0.6 * full - 1).all() and (n < full).any()
    for i in range(4):  # a prefix mask, zero past the end, a contiguous window of the motion
        assert c1["mask"][i, : n[i]].all() and not c1["mask"][i, n[i]:].any()
        assert not c1["joints"][i, n[i]:].any()
        src = b["joints"][i, : full[i]]
        starts = [s for s in range(full[i] - n[i] + 1)
                  if np.array_equal(src[s:s + n[i]], c1["joints"][i, : n[i]])]
        assert starts, i
    with pytest.raises(ValueError, match="time_crop"):
        MotionActionDataset(cfg.data_dir, "train", time_crop=0.5)


def test_accuracy_on_training_motions_beats_chance(run):
    _, _, rec, b = run
    acc = action_accuracy(rec, b["joints"], b["mask"], b["action"])
    majority = np.bincount(b["action"], minlength=4).max() / len(b["action"])
    assert acc >= max(0.75, majority + 0.1), (acc, majority)
    names = [ACTIONS[i] for i in b["action"]]
    assert action_accuracy(rec, b["joints"], b["mask"], names) == acc


def _rot_z(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]], np.float32)


def test_predict_shapes_invariance_and_padding(run):
    _, _, rec, b = run
    joints, mask = b["joints"][:8].copy(), b["mask"][:8]
    logits = rec.logits(joints, mask)
    pred = rec.predict(joints, mask)
    assert logits.shape == (8, 4) and logits.dtype == np.float32
    assert pred.shape == (8,) and pred.dtype == np.int32
    np.testing.assert_array_equal(pred, np.argmax(logits, -1))
    assert rec.predict_names(joints, mask) == [ACTIONS[i] for i in pred]
    moved = joints @ _rot_z(2.1).T + np.array([3.7, -5.2, 0.0], np.float32)
    np.testing.assert_allclose(rec.logits(moved, mask), logits, atol=1e-4)
    joints[~mask] = np.nan  # padded frames are never read
    np.testing.assert_allclose(rec.logits(joints, mask), logits, atol=1e-5)
    lengths = mask.sum(1)
    t = lengths.max()
    longer = np.concatenate([joints[:, :t], np.full((8, 37, 22, 3), 9.0, np.float32)], axis=1)
    np.testing.assert_allclose(rec.logits(longer, np.pad(mask[:, :t], ((0, 0), (0, 37)))),
                               logits, atol=1e-5)
    one = rec.logits(joints[2:3, : lengths[2]])  # no mask: every frame valid
    np.testing.assert_allclose(one, logits[2:3], atol=1e-5)
    chunked = Recognizer(rec.model, rec.info, batch_size=3)  # chunks 3 + 3 + 2, each padded
    np.testing.assert_allclose(chunked.logits(joints, mask), logits, atol=1e-5)


def test_exported_weights_match_the_checkpoint(run):
    from flax import nnx

    cfg, result, rec, b = run
    model = load_trained(result.workdir, get_task(cfg), cfg)
    joints, mask = b["joints"][:8], b["mask"][:8]
    want = nnx.jit(lambda m, j, k: m(j, k, deterministic=True))(model, joints, mask)
    np.testing.assert_allclose(rec.logits(joints, mask), np.asarray(want), atol=1e-5)


def test_action_accuracy_on_hand_made_inputs():
    class Fixed:  # stands in for a Recognizer: predicts walk, sit, stand_up, lie
        def predict(self, joints, mask):
            return np.array([0, 1, 2, 3], np.int32)

    joints, mask = np.zeros((4, 5, 22, 3), np.float32), np.ones((4, 5), bool)
    assert action_accuracy(Fixed(), joints, mask, ["walk", "sit", "stand_up", "lie"]) == 1.0
    assert action_accuracy(Fixed(), joints, mask, ["walk", "sit", "lie", "lie"]) == 0.75
    assert action_accuracy(Fixed(), joints, mask, np.array([3, 2, 1, 0])) == 0.0
    assert action_accuracy(Fixed(), joints, mask, [0, "sit", np.int64(0), "walk"]) == 0.5
    np.testing.assert_array_equal(action_ids(["lie", "walk", 2]), [3, 0, 2])
    with pytest.raises(ValueError, match="one action per motion"):
        action_accuracy(Fixed(), joints, mask, ["walk"])
    with pytest.raises(ValueError, match="unknown action 'run'"):
        action_ids(["run"])
    with pytest.raises(ValueError, match="out of range"):
        action_ids([4])
    with pytest.raises(TypeError, match="not a single str"):
        action_ids("sit")


def test_clear_errors_and_version_refusal(run, tmp_path):
    from jaxmotion.models.weights import load_weights, save_weights

    _, result, rec, b = run
    joints, mask = b["joints"][:2], b["mask"][:2]
    with pytest.raises(ValueError, match=r"joints must be \[B, T, 22, 3\]"):
        rec.predict(joints.reshape(2, -1, 66), mask)
    with pytest.raises(ValueError, match=r"mask must be \[B, T\]"):
        rec.predict(joints, mask[:, :10])
    holes = mask.copy()
    holes[0, 3] = False
    with pytest.raises(ValueError, match="prefix"):
        rec.predict(joints, holes)
    tensors, saved = load_weights(result.workdir / "model.safetensors")
    save_weights(tmp_path / "old.safetensors", {}, {},
                 {**saved, "recognizer_version": "jm-action-0"}, extra=tensors)
    with pytest.raises(ValueError, match=r"version 'jm-action-0'.*retrain it with python -m "
                                         r"jaxmotion\.train --config configs/recognizer\.py"):
        load_recognizer(tmp_path / "old.safetensors")
    save_weights(tmp_path / "other.safetensors", {}, {}, {"task": "evaluator",
                                                          "evaluator_version": "jm-eval-1"})
    with pytest.raises(ValueError, match="not an action recognizer"):
        load_recognizer(tmp_path / "other.safetensors")
    with pytest.raises(FileNotFoundError, match="configs/recognizer.py"):
        load_recognizer(tmp_path / "nowhere")


def test_features_are_the_pre_logit_layer_and_invariant(run):
    """The features are what the last layer reads (logits = fc2(features)); like the logits
    they ignore padded frames and the padded length, and a shift and a turn about z."""
    from flax import nnx

    from jaxmotion.eval.recognizer import recognizer_features

    _, _, rec, b = run
    joints, mask = b["joints"][:8].copy(), b["mask"][:8]
    f = rec.features(joints, mask)
    assert f.shape == (8, rec.dim) == (8, 16) and f.dtype == np.float32
    fc2 = rec.model.fc2
    np.testing.assert_allclose(f @ np.asarray(fc2.kernel[...]) + np.asarray(fc2.bias[...]),
                               rec.logits(joints, mask), atol=1e-4)
    assert np.std(f, axis=0).max() > 1e-3  # motions differ in feature space
    moved = joints @ _rot_z(-1.3).T + np.array([-2.5, 4.1, 0.0], np.float32)
    np.testing.assert_allclose(rec.features(moved, mask), f, atol=1e-4)
    joints[~mask] = np.nan  # padded frames are never read
    np.testing.assert_allclose(rec.features(joints, mask), f, atol=1e-5)
    t = mask.sum(1).max()
    longer = np.concatenate([joints[:, :t], np.full((8, 21, 22, 3), -4.0, np.float32)], axis=1)
    np.testing.assert_allclose(rec.features(longer, np.pad(mask[:, :t], ((0, 0), (0, 21)))),
                               f, atol=1e-5)
    # the pure function, jitted directly on the module (no host-side padding to 32 frames)
    pure = nnx.jit(recognizer_features)(rec.model, np.nan_to_num(joints[:, :t], nan=7.0),
                                        mask[:, :t])
    np.testing.assert_allclose(np.asarray(pure), f, atol=1e-5)


def test_fid_diversity_multimodality_on_recognizer_features(run):
    """recognizer_scores: the real set against itself has FID ~0 and the same diversity; a
    perturbed sample set (joints jittered by 5 cm per frame) is far from it; multimodality
    only with K > 1; the numbers are text_motion_metrics' on Recognizer.features."""
    from jaxmotion.eval.recognizer import recognizer_scores
    from jaxmotion.eval.text_motion_metrics import diversity, fid, multimodality

    _, _, rec, b = run
    joints, mask = b["joints"], b["mask"]
    n = len(joints)
    same = recognizer_scores(rec, joints, mask, joints, mask, rng=3)
    assert abs(same["generated"]["fid"]) < 1e-4, same  # ~0 (a rank-deficient sqrtm), not exactly 0
    assert same["generated"]["diversity"] == pytest.approx(same["real"]["diversity"])
    assert same["real"]["diversity"] > 0 and "multimodality" not in same["generated"]
    assert same["protocol"] == {"num_cases": n, "sample_sets": 1, "diversity_pairs": n}
    assert same["recognizer"] == rec.describe()
    noisy = joints + np.random.default_rng(0).normal(0, 0.05, joints.shape).astype(np.float32)
    gen = np.stack([joints, noisy], axis=1)  # K = 2: the real set and a jittered one
    gen_mask = np.repeat(mask[:, None], 2, axis=1)
    out = recognizer_scores(rec, joints, mask, gen, gen_mask, rng=3)
    real_f, noisy_f = rec.features(joints, mask), rec.features(noisy, mask)
    fid_noisy = fid(real_f, noisy_f)
    assert fid_noisy > 0.5 and fid_noisy > 1000 * abs(same["generated"]["fid"]), fid_noisy
    assert out["generated"]["fid"] == pytest.approx(fid_noisy / 2, rel=1e-3, abs=1e-4)
    want_div = np.mean([diversity(f, n, np.random.default_rng([3, 1]))
                        for f in (real_f, noisy_f)])
    assert out["generated"]["diversity"] == pytest.approx(want_div, rel=1e-4)
    mm = multimodality(np.stack([real_f, noisy_f], 1), 2, np.random.default_rng([3, 2]))
    assert out["generated"]["multimodality"] == pytest.approx(mm, rel=1e-4)
    assert out["protocol"]["mm_pairs"] == 2
    with pytest.raises(ValueError, match="gen_joints must be"):
        recognizer_scores(rec, joints, mask, gen[:-1], gen_mask[:-1])
