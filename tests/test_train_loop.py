"""The generic training loop on a small regression task: loss falls, logs, checkpoints,
bit-identical resume, loud stop on non-finite values, two-device data parallelism."""

import dataclasses
import itertools
import json
import os
import subprocess
import sys
import textwrap

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from flax import nnx

from jaxmotion.train import TrainConfig, load_trained, train


@dataclasses.dataclass(frozen=True)
class RegConfig(TrainConfig):
    task: str = "regression"
    width: int = 16
    nan_at: int = -1


class Net(nnx.Module):
    def __init__(self, width, *, rngs):
        self.a = nnx.Linear(4, width, rngs=rngs)
        self.drop = nnx.Dropout(0.1, rngs=rngs)
        self.b = nnx.Linear(width, 1, rngs=rngs)

    def __call__(self, x, train):
        return self.b(self.drop(nnx.gelu(self.a(x)), deterministic=not train))


W = np.array([[1.0], [-2.0], [0.5], [3.0]], np.float32)


class RegressionTask:
    def build_model(self, cfg, rngs):
        return Net(cfg.width, rngs=rngs)

    def _batch(self, cfg, step):
        rng = np.random.default_rng([cfg.seed, step])
        x = rng.normal(size=(cfg.batch_size, 4)).astype(np.float32)
        y = x @ W + 0.01 * rng.normal(size=(cfg.batch_size, 1)).astype(np.float32)
        if step == cfg.nan_at:
            y[0, 0] = np.nan
        return {"x": x, "y": y}

    def train_batches(self, cfg, start_step):
        return (self._batch(cfg, s) for s in itertools.count(start_step))

    def val_batches(self, cfg):
        return [self._batch(cfg, 10**6 + i) for i in range(2)]

    def loss(self, model, batch, key, *, train):
        err = model(batch["x"], train) - batch["y"]
        return jnp.mean(err**2), {"mae": jnp.mean(jnp.abs(err))}


def cfg_for(tmp_path, **kw):
    base = dict(workdir=str(tmp_path / "run"), steps=60, batch_size=8, log_every=10,
                eval_every=30, ckpt_every=20, progress=False)
    base["optim"] = dataclasses.replace(RegConfig().optim, lr=3e-2, warmup_steps=5, clip_norm=10.0)
    base.update(kw)
    return RegConfig(**base)


def test_loss_falls_and_logs_are_written(tmp_path):
    cfg = cfg_for(tmp_path)
    res = train(cfg, RegressionTask())
    work = tmp_path / "run"
    rows = [json.loads(line) for line in (work / "metrics.jsonl").read_text().splitlines()]
    losses = [r["loss"] for r in rows if "loss" in r]
    assert rows[0]["step"] == 10 and losses[-1] < 0.2 * losses[0]
    assert any("val_loss" in r for r in rows) and res.val_loss is not None
    assert json.loads((work / "config.json").read_text())["steps"] == 60
    assert sorted(p.name for p in (work / "checkpoints").iterdir() if p.name.isdigit()) == ["20", "40", "60"]
    assert any(p.name.startswith("events.out.tfevents") for p in (work / "tb").iterdir())
    assert (work / "model.safetensors").is_file()
    assert res.step == 60


def test_resume_is_bit_identical(tmp_path):
    full = train(cfg_for(tmp_path / "a"), RegressionTask())
    train(cfg_for(tmp_path / "b", steps=40), RegressionTask())  # "interrupted" at 40
    resumed = train(cfg_for(tmp_path / "b"), RegressionTask())
    assert resumed.resumed_from == 40 and resumed.step == 60
    ma = load_trained(tmp_path / "a" / "run", RegressionTask(), cfg_for(tmp_path / "a"), ema=False)
    mb = load_trained(tmp_path / "b" / "run", RegressionTask(), cfg_for(tmp_path / "b"), ema=False)
    for x, y in zip(jax.tree.leaves(nnx.state(ma, nnx.Param)), jax.tree.leaves(nnx.state(mb, nnx.Param))):
        np.testing.assert_array_equal(np.asarray(x), np.asarray(y))
    assert full.last_loss == resumed.last_loss
    rows = [json.loads(line) for line in (tmp_path / "b" / "run" / "metrics.jsonl").read_text().splitlines()]
    assert [r["step"] for r in rows if "loss" in r] == [10, 20, 30, 40, 50, 60]  # one history


def test_incompatible_resume_and_restart(tmp_path):
    train(cfg_for(tmp_path, steps=20), RegressionTask())
    with pytest.raises(ValueError, match="different config.*width"):
        train(cfg_for(tmp_path, steps=40, width=8), RegressionTask())
    res = train(cfg_for(tmp_path, steps=20, width=8, resume=False), RegressionTask())
    assert res.resumed_from is None and res.step == 20


def test_non_finite_loss_stops_loudly(tmp_path):
    with pytest.raises(FloatingPointError, match="non-finite .*loss.*at step 26"):
        train(cfg_for(tmp_path, nan_at=25), RegressionTask())
    kept = sorted(p.name for p in (tmp_path / "run" / "checkpoints").iterdir() if p.name.isdigit())
    assert kept == ["20"]


def test_two_devices_data_parallel(tmp_path):
    script = textwrap.dedent(f"""
        import sys, jax
        sys.path.insert(0, {os.path.dirname(__file__)!r})
        from test_train_loop import RegressionTask, cfg_for
        from jaxmotion.train import train
        import pathlib
        assert len(jax.devices()) == 2, jax.devices()
        res = train(cfg_for(pathlib.Path({str(tmp_path)!r}), steps=30), RegressionTask())
        print("LOSS", res.last_loss)
        try:
            train(cfg_for(pathlib.Path({str(tmp_path)!r}) / "odd", steps=2, batch_size=7), RegressionTask())
        except ValueError as e:
            print("ERR", e)
    """)
    env = dict(os.environ, XLA_FLAGS="--xla_force_host_platform_device_count=2", JAX_PLATFORMS="cpu")
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, env=env,
                         timeout=300)
    assert out.returncode == 0, out.stderr[-2000:]
    loss = float(out.stdout.split("LOSS")[1].split()[0])
    one = train(cfg_for(tmp_path / "one", steps=30), RegressionTask()).last_loss
    np.testing.assert_allclose(loss, one, rtol=1e-4)  # same maths, other reduction order
    assert "not divisible by the 2 devices" in out.stdout


def test_resume_accepts_a_run_saved_before_a_setting_was_added(tmp_path):
    """A config.json written before ``crop.centre`` existed resumes (the missing setting is
    its default); a real difference in the same section still refuses."""
    train(cfg_for(tmp_path, steps=20), RegressionTask())
    path = tmp_path / "run" / "config.json"
    saved = json.loads(path.read_text())
    del saved["crop"]["centre"]
    path.write_text(json.dumps(saved))
    res = train(cfg_for(tmp_path, steps=40), RegressionTask())
    assert res.resumed_from == 20 and res.step == 40
    saved["crop"]["size"] = 8.0
    path.write_text(json.dumps(saved))
    with pytest.raises(ValueError, match="different config.*crop"):
        train(cfg_for(tmp_path, steps=60), RegressionTask())
