"""The training loop shared by every model: optimiser, EMA, data parallelism, checkpoints, logs.

A *task* (see :mod:`jaxmotion.train.tasks`) says what to train: it builds the
model, yields host batches, and computes the loss. This module does the rest:

- optax AdamW with linear warm-up, optional cosine decay, global-norm clipping;
- EMA of the parameters (``optim.ema_decay``; 0 disables it);
- data parallelism over all local devices with ``jax.sharding``: parameters
  replicated, the batch split along its first axis over a 1-D ``data`` mesh
  (XLA inserts the gradient all-reduce). Multi-host: call
  ``jax.distributed.initialize()`` first (``JAXMOTION_DISTRIBUTED=1`` does it);
  every process builds the same global batch and feeds its own rows;
- per-step randomness from ``fold_in(key(seed), step)``; data batches are a
  function of ``(seed, step)``; so ``resume=True`` continues **bit-identically**
  from the last checkpoint (tested);
- Orbax checkpoints every ``ckpt_every`` steps keeping ``keep_checkpoints``;
  ``config.json``, ``metrics.jsonl`` and TensorBoard events in the workdir;
- a progress bar with loss and steps/s, periodic validation loss, and a loud
  stop (``FloatingPointError``) on a non-finite loss or gradient;
- optionally a *probe*: a task with ``probe_every(cfg) > 0`` scores the EMA weights
  on fixed cases every so many steps (``probe(model, batch, key)`` returns per-case
  metrics; the one named ``task.probe_score`` is the score). The run logs the means
  under ``grounding/`` and exports the best-scoring weights to
  ``model_best.safetensors`` (``best.json``: step, score, metrics), so selection
  survives a resume.
"""

from __future__ import annotations

import json
import os
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Iterator, Protocol

import jax
import jax.numpy as jnp
import numpy as np
import optax
from flax import nnx
from jax.sharding import NamedSharding
from jax.sharding import PartitionSpec as P

from jaxmotion.config import config_from_dict, config_to_dict, save_config_json
from jaxmotion.models.weights import save_weights
from jaxmotion.train.checkpoint import Checkpointer
from jaxmotion.train.metrics import MetricsWriter

__all__ = ["Task", "TrainResult", "make_optimizer", "train"]


class Task(Protocol):
    """What a training run needs from a model family."""

    def build_model(self, cfg, rngs: nnx.Rngs) -> nnx.Module: ...

    def train_batches(self, cfg, start_step: int) -> Iterator[dict]: ...

    def val_batches(self, cfg) -> list[dict]: ...

    def loss(self, model: nnx.Module, batch: dict, key: jax.Array, *, train: bool
             ) -> tuple[jax.Array, dict]: ...


@dataclass
class TrainResult:
    workdir: Path
    step: int
    last_loss: float
    val_loss: float | None
    resumed_from: int | None


def make_optimizer(optim, total_steps: int) -> optax.GradientTransformation:
    """AdamW with linear warm-up (and cosine decay if ``optim.cosine``), clipped by global norm."""
    warmup = max(0, min(int(optim.warmup_steps), total_steps))
    if optim.cosine and total_steps > warmup:
        schedule = optax.warmup_cosine_decay_schedule(
            0.0, optim.lr, warmup, total_steps, end_value=optim.lr * optim.final_lr_fraction)
    elif warmup > 0:
        schedule = optax.join_schedules(
            [optax.linear_schedule(0.0, optim.lr, warmup), optax.constant_schedule(optim.lr)],
            [warmup])
    else:
        schedule = optax.constant_schedule(optim.lr)
    return optax.chain(
        optax.clip_by_global_norm(optim.clip_norm),
        optax.adamw(schedule, b1=optim.b1, b2=optim.b2, weight_decay=optim.weight_decay),
    )


def _mesh():
    devices = np.array(jax.devices())
    return jax.sharding.Mesh(devices, ("data",))


def _put_batch(batch: dict, sharding: NamedSharding, n_dev: int) -> dict:
    """Host batch -> global arrays sharded over the data axis (strings stay on the host)."""
    out = {}
    pc, pi = jax.process_count(), jax.process_index()
    for k, v in batch.items():
        if not isinstance(v, np.ndarray) or v.dtype.kind in "OUS":
            continue
        if v.shape[0] % n_dev:
            raise ValueError(
                f"batch size {v.shape[0]} is not divisible by the {n_dev} devices; "
                f"set batch_size to a multiple of {n_dev}")
        rows = v.shape[0] // pc
        local = v[pi * rows:(pi + 1) * rows]
        out[k] = jax.make_array_from_process_local_data(sharding, local, v.shape)
    return out


def _check_finite(step: int, metrics: dict):
    bad = [k for k, v in metrics.items() if not np.isfinite(v)]
    if bad:
        raise FloatingPointError(
            f"non-finite {', '.join(bad)} at step {step} "
            f"({', '.join(f'{k}={metrics[k]}' for k in bad)}). Training stopped; the last "
            "checkpoint is intact. Try a lower optim.lr, a smaller optim.clip_norm, or check the "
            "data statistics (stats.npz) for zero standard deviations.")


def _check_compatible(workdir: Path, cfg) -> None:
    """A resumed run must use the same model/optimiser/data settings as the saved one."""
    path = workdir / "config.json"
    if not path.is_file():
        return
    old, new = json.loads(path.read_text()), config_to_dict(cfg)
    try:  # settings added since the run was saved count as their defaults
        old = config_to_dict(config_from_dict(type(cfg), old))
    except (TypeError, ValueError, KeyError):
        pass
    free = {"steps", "resume", "workdir", "log_every", "eval_every", "ckpt_every", "progress",
            "keep_checkpoints", "data_dir", "loader_workers", "grounding_every",
            "grounding_cases", "grounding_steps", "grounding_guidance"}
    diff = sorted(k for k in set(old) | set(new) if k not in free and old.get(k) != new.get(k))
    if diff:
        raise ValueError(
            f"{workdir} holds a run with a different config ({', '.join(diff)} differ); "
            "resume with the same config, pass resume=false to start over, or use another workdir")


def _fresh_rngs(rngs, key):
    """Every RNG stream re-keyed from ``key`` (and its counter reset): randomness is a pure
    function of the step key, so nothing RNG-related needs checkpointing."""
    leaves, treedef = jax.tree.flatten(rngs)
    new = [jax.random.fold_in(key, 1000 + i) if jnp.issubdtype(x.dtype, jax.dtypes.prng_key)
           else jnp.zeros_like(x) for i, x in enumerate(leaves)]
    return jax.tree.unflatten(treedef, new)


def train(cfg, task: Task, *, on_step: Callable[[int, dict], None] | None = None) -> TrainResult:
    """Run (or resume) training as configured; returns where it ended."""
    if os.environ.get("JAXMOTION_DISTRIBUTED") == "1":
        jax.distributed.initialize()
    workdir = Path(cfg.workdir)
    workdir.mkdir(parents=True, exist_ok=True)
    ckpt = Checkpointer(workdir / "checkpoints", keep=cfg.keep_checkpoints)
    resume_step = ckpt.latest_step() if cfg.resume else None
    if resume_step is not None:
        _check_compatible(workdir, cfg)
    elif ckpt.latest_step() is not None:
        for s in ckpt.all_steps():  # resume=False: start over in this workdir
            import shutil

            shutil.rmtree(ckpt.directory / str(s), ignore_errors=True)
        ckpt.close()
        ckpt = Checkpointer(workdir / "checkpoints", keep=cfg.keep_checkpoints)
    if jax.process_index() == 0:
        save_config_json(cfg, workdir / "config.json")

    mesh = _mesh()
    n_dev = mesh.devices.size
    batch_sharding = NamedSharding(mesh, P("data"))
    replicated = NamedSharding(mesh, P())

    model = task.build_model(cfg, nnx.Rngs(cfg.seed))
    trainable = getattr(task, "trainable", nnx.Param)  # frozen sub-networks stay in `rest`
    graphdef, params, batch_stats, rng_state, rest = nnx.split(
        model, trainable, nnx.BatchStat, nnx.RngState, ...)
    tx = make_optimizer(cfg.optim, cfg.steps)
    state = {
        "params": params,
        "batch_stats": batch_stats,
        "opt_state": tx.init(params),
        "ema": jax.tree.map(jnp.copy, params),
        "step": jnp.zeros((), jnp.int32),
    }
    state = jax.device_put(state, replicated)
    rng_state = jax.device_put(rng_state, replicated)
    rest = jax.device_put(rest, replicated)
    if resume_step is not None:
        state = ckpt.restore(state, resume_step)
    start = int(state["step"])
    decay = float(cfg.optim.ema_decay)
    base_key = jax.random.key(cfg.seed)

    def loss_fn(params, batch_stats, rngs, frozen, batch, key, train):
        # rngs (dropout streams) are traced inputs, reseeded from the step key: never saved.
        # `frozen` (non-trainable sub-networks) is an argument, not a closure: no huge constants.
        # Rebuild the (non-differentiated) BatchStat variables inside this trace so that
        # BatchNorm may update them here.
        batch_stats = jax.tree.map(lambda x: x, batch_stats)
        m = nnx.merge(graphdef, params, batch_stats, _fresh_rngs(rngs, key), frozen)
        loss, aux = task.loss(m, batch, key, train=train)
        new_stats = nnx.state(m, nnx.BatchStat)
        return loss, (aux, new_stats)

    @jax.jit
    def train_step(state, rngs, frozen, batch, key):
        (loss, (aux, stats)), grads = jax.value_and_grad(loss_fn, has_aux=True)(
            state["params"], state["batch_stats"], rngs, frozen, batch, key, True)
        updates, opt_state = tx.update(grads, state["opt_state"], state["params"])
        params = optax.apply_updates(state["params"], updates)
        # EMA with warm-up (min(decay, (1+t)/(10+t))) so early EMA weights are not stuck at init.
        t = state["step"].astype(jnp.float32)
        d = jnp.minimum(decay, (1.0 + t) / (10.0 + t))
        ema = (jax.tree.map(lambda e, p: d * e + (1.0 - d) * p, state["ema"], params)
               if decay > 0 else params)
        new = dict(params=params, batch_stats=stats, opt_state=opt_state, ema=ema,
                   step=state["step"] + 1)
        return new, {"loss": loss, "grad_norm": optax.tree.norm(grads), **aux}

    @jax.jit
    def eval_step(state, rngs, frozen, batch, key):
        params = state["ema"] if decay > 0 else state["params"]
        loss, (aux, _) = loss_fn(params, state["batch_stats"], rngs, frozen, batch, key, False)
        return {"loss": loss, **aux}

    val = task.val_batches(cfg) if cfg.eval_every > 0 else []
    probe_every = int(task.probe_every(cfg)) if hasattr(task, "probe_every") else 0
    probe_data = task.probe_batches(cfg) if probe_every > 0 else []

    @jax.jit
    def probe_step(state, rngs, frozen, batch, key):
        params = state["ema"] if decay > 0 else state["params"]
        m = nnx.merge(graphdef, params, state["batch_stats"], _fresh_rngs(rngs, key), frozen)
        return task.probe(m, batch, key)

    best_file = workdir / "best.json"
    if resume_step is None:
        best_file.unlink(missing_ok=True)
        (workdir / "model_best.safetensors").unlink(missing_ok=True)
    best = json.loads(best_file.read_text()) if best_file.is_file() else None

    def export(path, done):
        if jax.process_index() != 0:
            return
        save_weights(path, state["ema"] if decay > 0 else state["params"], state["batch_stats"],
                     {**config_to_dict(cfg), "step": done,
                      **getattr(task, "export_config", dict)()},
                     extra=getattr(task, "export_tensors", dict)())

    def run_probe(done):
        nonlocal best
        sums, n = {}, 0.0
        for i, b in enumerate(probe_data):
            out = jax.device_get(probe_step(state, rng_state, rest,
                                            _put_batch(b, batch_sharding, n_dev),
                                            jax.random.fold_in(base_key, 2**30 + i)))
            valid = b["valid"].astype(np.float64)
            for k, v in out.items():
                sums[k] = sums.get(k, 0.0) + float(np.sum(np.where(valid > 0, v, 0.0)))
            n += valid.sum()
        metrics = {f"grounding/{k}": v / max(n, 1.0) for k, v in sums.items()}
        if writer:
            writer.write(done, metrics)
        score = metrics[f"grounding/{task.probe_score}"]
        if best is None or score > best["score"]:
            export(workdir / "model_best.safetensors", done)
            best = {"step": done, "score": score, "metrics": metrics}
            if jax.process_index() == 0:
                from jaxmotion.data.format import write_json_atomic

                write_json_atomic(best_file, best)

    writer = MetricsWriter(workdir, resume_step=resume_step) if jax.process_index() == 0 else None
    from tqdm.auto import tqdm

    bar = tqdm(total=cfg.steps, initial=start, desc=f"train {cfg.task}", unit="step",
               disable=not cfg.progress or jax.process_index() != 0, dynamic_ncols=True)
    batches = task.train_batches(cfg, start)
    last_loss, val_loss, t_log, n_log = float("nan"), None, time.perf_counter(), 0
    sums: dict[str, float] = {}
    try:
        for step in range(start, cfg.steps):
            batch = _put_batch(next(batches), batch_sharding, n_dev)
            state, m = train_step(state, rng_state, rest, batch, jax.random.fold_in(base_key, step))
            m = {k: float(v) for k, v in jax.device_get(m).items()}
            _check_finite(step + 1, m)
            last_loss = m["loss"]
            for k, v in m.items():
                sums[k] = sums.get(k, 0.0) + v
            n_log += 1
            done = step + 1
            if done % cfg.log_every == 0 or done == cfg.steps:
                now = time.perf_counter()
                logged = {k: v / n_log for k, v in sums.items()}  # means over the interval
                logged["steps_per_s"] = n_log / max(now - t_log, 1e-9)
                t_log, n_log, sums = now, 0, {}
                if writer:
                    writer.write(done, logged)
                bar.set_postfix(loss=f"{logged['loss']:.4f}", sps=f"{logged['steps_per_s']:.2f}")
            if val and (done % cfg.eval_every == 0 or done == cfg.steps):
                vals = [jax.device_get(eval_step(state, rng_state, rest, _put_batch(b, batch_sharding, n_dev),
                                                 jax.random.fold_in(base_key, 2**31 - 1 - i)))
                        for i, b in enumerate(val)]
                val_loss = float(np.mean([v["loss"] for v in vals]))
                if writer:
                    writer.write(done, {"val_loss": val_loss})
            if probe_data and (done % probe_every == 0 or done == cfg.steps):
                run_probe(done)
            if done % cfg.ckpt_every == 0 or done == cfg.steps:
                ckpt.save(done, state)
                export(workdir / "model.safetensors", done)
            if on_step is not None:
                on_step(done, m)
            bar.update()
    finally:
        bar.close()
        if writer:
            writer.close()
        ckpt.close()
        close = getattr(batches, "close", None)
        if close:
            close()
    return TrainResult(workdir, int(state["step"]), last_loss, val_loss, resume_step)


def load_trained(workdir, task: Task, cfg, *, ema: bool = True, step: int | None = None) -> Any:
    """Rebuild a trained model from ``workdir`` (EMA weights by default)."""
    model = task.build_model(cfg, nnx.Rngs(cfg.seed))
    graphdef, params, batch_stats, rng_state, rest = nnx.split(
        model, getattr(task, "trainable", nnx.Param), nnx.BatchStat, nnx.RngState, ...)
    tx = make_optimizer(cfg.optim, cfg.steps)
    target = {"params": params, "batch_stats": batch_stats, "opt_state": tx.init(params),
              "ema": params, "step": jnp.zeros((), jnp.int32)}
    ckpt = Checkpointer(Path(workdir) / "checkpoints", keep=cfg.keep_checkpoints)
    try:
        state = ckpt.restore(target, step)
    finally:
        ckpt.close()
    chosen = state["ema"] if ema and cfg.optim.ema_decay > 0 else state["params"]
    return nnx.merge(graphdef, chosen, state["batch_stats"], rng_state, rest)
