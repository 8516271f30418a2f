"""Throughput of the jitted affordance map against numpy and the machine's FLOP bound.

Usage:
    python benchmarks/affordance.py [--repeats 5] [--quick]

For each case it prints points·joints·frames per second (warm, best of
``--repeats``) of

- ``jaxmotion``: :func:`jaxmotion.geometry.affordance_map` (jitted, chunked);
- ``numpy``: a plain vectorised numpy version (broadcast difference, squared
  norm, min over frames, chunked over points so that it fits in memory);

and the ratio between them. The FLOP bound is measured in the same run: the
best float32 GFLOP/s of a jitted 2048² matmul on this machine (the practical
peak of its vector units), divided by the 7 FLOPs per point·joint·frame of the
kernel's inner loop (3 fused multiply-adds + 1 min). "of bound" is the fraction
of that bound reached.
"""

from __future__ import annotations

import argparse
import os
import platform
import time

import jax
import jax.numpy as jnp
import numpy as np

from jaxmotion.geometry import affordance_map

FLOPS_PER_PJF = 7
CASES = [("N=32768, T=120, J=22", 32_768, 120, 22), ("N=1000000, T=120, J=6", 1_000_000, 120, 6)]


def numpy_affordance_map(points, joints, sigma=0.8, chunk=4096):
    """Plain vectorised numpy: [N,3], [T,J,3] -> [N,J]."""
    out = np.empty((points.shape[0], joints.shape[1]), np.float32)
    for s in range(0, points.shape[0], chunk):
        diff = points[s : s + chunk, None, None, :] - joints[None]  # [C, T, J, 3]
        d2 = np.einsum("ctjk,ctjk->ctj", diff, diff).min(axis=1)
        out[s : s + chunk] = np.exp(-d2 / (2 * sigma * sigma))
    return out


def best_time(fn, repeats):
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times)


def matmul_peak_gflops(repeats):
    a = jnp.asarray(np.random.default_rng(0).normal(size=(2048, 2048)), jnp.float32)
    f = jax.jit(lambda x: x @ x)
    jax.block_until_ready(f(a))
    t = best_time(lambda: jax.block_until_ready(f(a)), repeats)
    return 2 * 2048**3 / t / 1e9


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--numpy-repeats", type=int, default=1, help="numpy is slow; 1 is enough")
    ap.add_argument("--quick", action="store_true", help="only the first (small) case")
    args = ap.parse_args(argv)

    print(f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores, "
          f"jax {jax.__version__} on {jax.devices()[0].platform}")
    peak = matmul_peak_gflops(args.repeats)
    bound = peak * 1e9 / FLOPS_PER_PJF
    print(f"matmul peak: {peak:.1f} GFLOP/s -> FLOP bound {bound / 1e9:.1f} G pjf/s "
          f"({FLOPS_PER_PJF} FLOP per point·joint·frame)\n")

    header = f"{'case':24s} {'jaxmotion':>12s} {'numpy':>12s} {'vs numpy':>9s} {'of bound':>9s} {'max |diff|':>11s}"
    print(header)
    print("-" * len(header))
    rng = np.random.default_rng(0)
    cases = CASES[:1] if args.quick else CASES
    data, results = [], []
    for name, n, t, j in cases:
        points = rng.uniform(-2.0, 2.0, (n, 3)).astype(np.float32)
        joints = (np.cumsum(rng.normal(scale=0.03, size=(t, 1, 3)), 0)
                  + rng.normal(scale=0.4, size=(1, j, 3))).astype(np.float32)
        data.append((points, joints))
    # All JAX timings first, then numpy: the two do not disturb each other's caches/threads.
    for (name, n, t, j), (points, joints) in zip(cases, data):
        pj, jj = jnp.asarray(points), jnp.asarray(joints)
        out = jax.block_until_ready(affordance_map(pj, jj))  # compile + warm up
        t_jax = best_time(lambda: jax.block_until_ready(affordance_map(pj, jj)), args.repeats)
        results.append((t_jax, np.asarray(out)))
    for (name, n, t, j), (points, joints), (t_jax, out) in zip(cases, data, results):
        t_np = best_time(lambda: numpy_affordance_map(points, joints), args.numpy_repeats)
        k = min(n, 20_000)
        err = float(np.abs(out[:k] - numpy_affordance_map(points[:k], joints)).max())
        work = n * t * j
        print(f"{name:24s} {work / t_jax / 1e9:9.2f} G/s {work / t_np / 1e9:9.3f} G/s "
              f"{t_np / t_jax:8.1f}x {work / t_jax / bound:8.1%} {err:11.1e}")
    print("\nG/s = 1e9 points·joints·frames per second, warm, best of the repeats.")


if __name__ == "__main__":
    main()
