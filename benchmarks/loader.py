"""Training-batch throughput of :class:`jaxmotion.data.Dataset`: one background thread against
``workers`` processes (``loader_workers`` in a training config).

    python benchmarks/loader.py --data data/synth [--batch 64] [--batches 40] [--workers 0,2,4]

Prints crops per second for each setting (host batches with the ground-truth affordance maps,
as a training step receives them, text not encoded) and the ratio to the thread. A GPU step of
the ADM at batch 64 takes about 43 ms (23 steps/s on an H100, session 9): it needs about 1,500
crops/s, which one thread does not give. The batches are the same with any number of workers
(``tests/test_data.py``).
"""

from __future__ import annotations

import argparse
import os
import platform
import time

from jaxmotion.data import CropSpec, Dataset


def rate(ds: Dataset, batch: int, batches: int, workers: int) -> float:
    it = ds.iterate(batch, seed=0, start_step=1000, workers=workers)
    next(it)  # start-up (process spawn, first scene reads, the affordance program's compile)
    t = time.perf_counter()
    for _ in range(batches):
        next(it)
    dt = time.perf_counter() - t
    it.close()
    return batch * batches / dt


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", default="data/synth", help="dataset folder (jaxmotion synth)")
    ap.add_argument("--batch", type=int, default=64)
    ap.add_argument("--batches", type=int, default=40, help="timed batches per setting")
    ap.add_argument("--workers", default="0,2", help="comma-separated; 0 = one thread")
    args = ap.parse_args()
    ds = Dataset(args.data, "train", CropSpec())
    print(f"machine: {platform.machine()}, {os.cpu_count()} cores; {len(ds)} training samples, "
          f"batch {args.batch}, {args.batches} batches")
    base = None
    print(f"{'loader':>12} {'crops/s':>9} {'vs thread':>10}")
    for w in (int(x) for x in args.workers.split(",")):
        r = rate(ds, args.batch, args.batches, w)
        base = base or r
        name = "thread" if w == 0 else f"{w} workers"
        print(f"{name:>12} {r:9.0f} {r / base:9.2f}x")


if __name__ == "__main__":
    main()
