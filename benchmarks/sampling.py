"""Sampling and training speed of the affordance pipeline (ADM + AMDM).

Usage:
    python benchmarks/sampling.py [--sizes cpu,paper] [--batches 1,32] [--full]

For each model size (``cpu`` = the CPU default, ``paper`` = the papers' sizes) it
prints milliseconds per motion (ADM then AMDM, whole pipeline) for the samplers
DDPM-1000, DDPM-500 and DDIM-100/50/20/10 at batch 1 and 32, and the training
steps/s of ADM and AMDM (forward + backward + AdamW at the config's batch size).

Every sampler step is one denoiser call, so the time of a sampler is linear in
its number of steps. Without ``--full`` the long samplers (DDPM, DDIM-100) are
*extrapolated* from the measured per-step time of DDIM-10/20 (marked ``~``);
``--full`` runs them all (slow on a CPU). Weights are random: speed does not
depend on them. Crop sizes: 2048 points (cpu), 8192 (paper); 120 frames.
"""

from __future__ import annotations

import argparse
import os
import platform
import time

import jax
import jax.numpy as jnp
import numpy as np
import optax
from flax import nnx

from jaxmotion.diffusion import SamplerSpec, make_schedule
from jaxmotion.models import (
    AMDM,
    ADMConfig,
    AMDMConfig,
    PointTransformerConfig,
    PointTransformerSeg,
    make_adm,
)
from jaxmotion.models.frozen import ADMNet
from jaxmotion.pipelines.affordance import AffordancePipeline

SAMPLERS = [("DDPM-1000", "ddpm", 1000), ("DDPM-500", "ddpm", 500), ("DDIM-100", "ddim", 100),
            ("DDIM-50", "ddim", 50), ("DDIM-20", "ddim", 20), ("DDIM-10", "ddim", 10)]


def build(size: str, text_dim: int = 384):
    pt = getattr(PointTransformerConfig, size)()
    adm_cfg = getattr(ADMConfig, size)()
    amdm_cfg = getattr(AMDMConfig, size)()
    import dataclasses

    adm_cfg = dataclasses.replace(adm_cfg, text_dim=text_dim, feature_dim=pt.out_dim)
    amdm_cfg = dataclasses.replace(amdm_cfg, text_dim=text_dim)
    backbone = PointTransformerSeg(pt, rngs=nnx.Rngs(0))
    backbone.eval()
    net = ADMNet(backbone, make_adm(adm_cfg, rngs=nnx.Rngs(1)))
    net.eval()
    amdm = AMDM(amdm_cfg, rngs=nnx.Rngs(2))
    amdm.eval()
    zeros6, ones6 = jnp.zeros(6), jnp.ones(6)
    pipe = AffordancePipeline(net, make_schedule("cosine", 1000), (zeros6, ones6), amdm,
                              make_schedule("cosine", 1000),
                              (jnp.zeros(66), jnp.ones(66), zeros6, ones6))
    return pipe, adm_cfg, amdm_cfg


def inputs(b, n, t, rng, text_dim=384):
    pts = rng.uniform(-2, 2, (b, n, 3)).astype(np.float32)
    pts[..., 2] = np.abs(pts[..., 2])
    return (jnp.asarray(pts), jnp.asarray(rng.uniform(-1, 1, (b, n, 3)), jnp.float32),
            jnp.asarray(rng.normal(size=(b, text_dim)), jnp.float32), jnp.ones((b, t), bool))


def time_call(fn, repeats=2):
    jax.block_until_ready(fn())  # compile
    best = float("inf")
    for _ in range(repeats):
        t0 = time.perf_counter()
        jax.block_until_ready(fn())
        best = min(best, time.perf_counter() - t0)
    return best


def sampler_table(size, batches, full, n_points, frames):
    pipe, _, _ = build(size)
    rng = np.random.default_rng(0)
    rows = []
    for b in batches:
        pts, col, txt, mask = inputs(b, n_points, frames, rng)
        key = jax.random.key(0)
        measured = {}
        for name, method, steps in SAMPLERS:
            if not full and steps > 20:
                continue
            spec = SamplerSpec(method, steps)
            measured[name] = time_call(lambda s=spec: pipe.sample(key, pts, col, txt, mask,
                                                                   adm=s, amdm=s)["joints"], 1)
        # per-step cost from the two short samplers (removes the fixed per-call overhead)
        per_step = (measured["DDIM-20"] - measured["DDIM-10"]) / 10
        fixed = measured["DDIM-10"] - 10 * per_step
        for name, method, steps in SAMPLERS:
            if name in measured:
                rows.append((size, b, name, measured[name] / b * 1e3, ""))
            else:
                rows.append((size, b, name, (fixed + steps * per_step) / b * 1e3, "~"))
    return rows


def train_steps_per_s(size, n_points, frames, batch):
    pipe, adm_cfg, amdm_cfg = build(size)
    rng = np.random.default_rng(1)
    pts, col, txt, mask = inputs(batch, n_points, frames, rng)
    net, amdm = pipe.adm_net, pipe.amdm
    net.adm.train()
    amdm.train()
    out = {}
    sched = make_schedule("cosine", 1000)
    from jaxmotion.diffusion import diffusion_loss

    def adm_loss(model, key):
        feats = net.features(pts, col)
        fixed = {"features": feats, "xyz": pts}
        return diffusion_loss(key, lambda x, t, c: model(x, t, {**c, **fixed}), sched,
                              jnp.zeros((batch, n_points, 6)), {"text": txt})

    def amdm_loss(model, key):
        cond = {"text": txt, "mask": mask, "xyz": pts, "affordance": jnp.zeros((batch, n_points, 6))}
        return diffusion_loss(key, lambda x, t, c: model(x, t, c), sched,
                              jnp.zeros((batch, frames, 66)), cond, mask, cond_drop_prob=0.0)

    for name, model, loss in (("ADM", net.adm, adm_loss), ("AMDM", amdm, amdm_loss)):
        opt = nnx.Optimizer(model, optax.adamw(1e-4), wrt=nnx.Param)

        @nnx.jit
        def step(model, opt, key):
            lval, grads = nnx.value_and_grad(loss)(model, key)
            opt.update(model, grads)
            return lval

        key = jax.random.key(0)
        t = time_call(lambda: step(model, opt, key), 2)
        out[name] = 1.0 / t
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--sizes", default="cpu,paper")
    ap.add_argument("--batches", default="1,32")
    ap.add_argument("--full", action="store_true", help="run every sampler (no extrapolation)")
    ap.add_argument("--frames", type=int, default=120)
    ap.add_argument("--train-batch", type=int, default=8)
    args = ap.parse_args(argv)
    print(f"machine: {platform.machine()}, {os.cpu_count()} cores, jax {jax.__version__} on "
          f"{jax.devices()[0].platform}")
    batches = [int(b) for b in args.batches.split(",")]
    print(f"\n{'size':6s} {'batch':>5s} {'sampler':10s} {'ms / motion':>14s}")
    for size in args.sizes.split(","):
        n = 2048 if size == "cpu" else 8192
        for s, b, name, ms, mark in sampler_table(size, batches, args.full, n, args.frames):
            print(f"{s:6s} {b:5d} {name:10s} {mark:>2s}{ms:12.1f}")
    print(f"\ntraining (batch {args.train_batch}, forward + backward + AdamW):")
    for size in args.sizes.split(","):
        n = 2048 if size == "cpu" else 8192
        sps = train_steps_per_s(size, n, args.frames, args.train_batch)
        print(f"{size:6s} ADM {sps['ADM']:.2f} steps/s   AMDM {sps['AMDM']:.2f} steps/s")
    print("\n~ = extrapolated from the measured per-step time of DDIM-10 and DDIM-20 (see --full)")


if __name__ == "__main__":
    main()
