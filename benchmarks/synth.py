"""Build time of the synthetic dataset, and the projection to HUMANISE's size.

Usage:
    python benchmarks/synth.py [--scenes 40] [--per-scene 10] [--workers 2]
    python benchmarks/synth.py --scenes 2000 --workers 2      # the full build, timed

Builds a dataset into a temporary folder (deleted afterwards unless ``--keep``)
with ``jaxmotion.data.synth.build_dataset`` and prints scenes/s, samples/s,
the time of each stage, and the projected wall time of the full
2,000 scenes × 10 instructions build (HUMANISE's size; target ≤ 30 min on 2 cores).
The baseline in the same run is one worker, so the parallel speed-up is visible.
"""

from __future__ import annotations

import argparse
import os
import shutil
import tempfile
import time

from jaxmotion.data.synth import SynthSettings, build_dataset


def timed_build(scenes, per_scene, workers, seed, keep):
    root = tempfile.mkdtemp(prefix="jm_synth_bench_")
    try:
        t0 = time.perf_counter()
        m = build_dataset(root, SynthSettings(scenes=scenes, per_scene=per_scene, seed=seed),
                          workers=workers, progress=False, stats=False)
        t_build = time.perf_counter() - t0
        return t_build, m
    finally:
        if keep:
            print(f"kept {root}")
        else:
            shutil.rmtree(root, ignore_errors=True)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--scenes", type=int, default=40)
    ap.add_argument("--per-scene", type=int, default=10)
    ap.add_argument("--workers", type=int, default=min(2, os.cpu_count() or 1))
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--keep", action="store_true")
    ap.add_argument("--no-baseline", action="store_true", help="skip the 1-worker baseline")
    args = ap.parse_args(argv)

    rows = []
    if not args.no_baseline and args.workers > 1:
        rows.append((1, *timed_build(args.scenes, args.per_scene, 1, args.seed, False)))
    rows.append((args.workers, *timed_build(args.scenes, args.per_scene, args.workers, args.seed,
                                            args.keep)))
    n = args.scenes * args.per_scene
    print(f"{os.cpu_count()} cores; {args.scenes} scenes x {args.per_scene} samples = {n} samples")
    print(f"{'workers':>7s} {'seconds':>9s} {'scenes/s':>9s} {'samples/s':>10s} "
          f"{'retries':>8s} {'2000x10 projected':>18s}")
    for w, t, m in rows:
        proj = t / args.scenes * 2000
        print(f"{w:7d} {t:9.1f} {args.scenes / t:9.2f} {n / t:10.2f} "
              f"{m['retries_this_run']:8d} {proj / 60:14.1f} min")
    if len(rows) == 2:
        print(f"speed-up of {rows[1][0]} workers over 1: {rows[0][1] / rows[1][1]:.2f}x")


if __name__ == "__main__":
    main()
