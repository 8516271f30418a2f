"""Velocity and acceleration losses on predicted motions: brute-force numpy, masks, and that
they tell a staircase from a smooth path where the position loss does not."""

from __future__ import annotations

import numpy as np

from jaxmotion.diffusion.geometric_losses import acceleration_loss, velocity_loss


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


def test_staircase_costs_more_than_a_smooth_path_with_the_same_position_error():
    t = np.arange(60, dtype=np.float32)
    walk = np.zeros((1, 60, 1, 3), np.float32)
    walk[0, :, 0, 0] = 1.2 * t / 30.0  # 1.2 m/s
    stairs = walk.copy()
    stairs[0, :, 0, 0] = 0.2 * np.floor(walk[0, :, 0, 0] / 0.2)  # hold, then jump 20 cm
    shifted = walk + np.array([0.0, 0.1, 0.0], np.float32)  # same size of position error
    mask = np.ones((1, 60), bool)
    pos = lambda a: float(np.mean(np.sum((a - walk) ** 2, -1)))  # noqa: E731
    assert pos(shifted) >= pos(stairs)  # the x0 loss prefers the staircase ...
    assert velocity_loss(stairs, walk, mask, 30.0) > 100 * velocity_loss(shifted, walk, mask,
                                                                          30.0) + 1.0
    assert float(velocity_loss(shifted, walk, mask, 30.0)) < 1e-6  # ... this one does not


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
