"""Batch generation's throughput against a loop of single ``generate`` calls.

    python benchmarks/batch.py [--requests 16] [--loop 4] [--devices 1 2] [--batch-size B]
                               [--json OUT]

Target (issue 49): the batch path ≥ 3× the motions per second of a loop of single
``jaxmotion generate`` calls on the same machine, with the same motions per seed.

Requests: the demo room, four instructions ("sit on the chair", "walk to the table", "sit on
the armchair", "walk to the fridge") × seeds, one sample each, no video (``--video none``
for the loop too). All runs share one compilation cache, warmed first (a first
``generate`` and a first batch run whose figures are not counted), so every figure is a
warm machine's: the loop pays each command's start-up (loading JAX, the models and the
compiled programs), the batch pays it once.

1. **loop**: ``--loop`` separate ``jaxmotion generate`` processes, one request each;
2. **in-process loop**: ``jaxmotion.generate`` + ``save`` in one warm Python process (what a
   script without batching does), ``--requests`` requests;
3. **batch** on each ``--devices`` count (host devices of this CPU:
   ``--xla_force_host_platform_device_count``): ``jaxmotion generate --batch`` in a new
   process, start-up included, ``--requests`` requests.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

TEXTS = ("sit on the chair", "walk to the table", "sit on the armchair", "walk to the fridge")


def _env(cache: str, devices: int = 1) -> dict:
    return {**os.environ, "JAXMOTION_CACHE": cache, "XLA_FLAGS":
            f"--xla_force_host_platform_device_count={devices}"}


def _cases(n: int) -> list[dict]:
    return [{"text": TEXTS[i % len(TEXTS)], "seed": i // len(TEXTS)} for i in range(n)]


def _cli(args, env) -> float:
    t0 = time.perf_counter()
    subprocess.run([sys.executable, "-m", "jaxmotion", "generate", *args], env=env, check=True,
                   capture_output=True, text=True)
    return time.perf_counter() - t0


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--requests", type=int, default=16)
    ap.add_argument("--loop", type=int, default=4, help="single generate commands timed")
    ap.add_argument("--devices", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--batch-size", type=int, default=None,
                    help="rows per device per call (default: the command's own default)")
    ap.add_argument("--json", default=None)
    args = ap.parse_args(argv)
    cache = tempfile.mkdtemp(prefix="jm-batch-bench-")
    tmp = Path(tempfile.mkdtemp(prefix="jm-batch-out-"))
    cases = _cases(args.requests)
    figures: dict = {"requests": args.requests, "batch_size": args.batch_size,
                     "cpu_count": os.cpu_count()}

    # warm the cache: one single generate, one batch run per device count
    _cli(["--scene", "demo", "--text", TEXTS[0], "--video", "none", "--out",
          str(tmp / "warm")], _env(cache))
    size = [] if args.batch_size is None else ["--batch-size", str(args.batch_size)]
    (tmp / "cases.jsonl").write_text("".join(json.dumps(c) + "\n" for c in cases))
    for d in args.devices:
        _cli(["--batch", str(tmp / "cases.jsonl"), "--out", str(tmp / f"warm-{d}"), *size],
             _env(cache, d))

    # 1. a loop of commands
    seconds = [_cli(["--scene", "demo", "--text", c["text"], "--seed", str(c["seed"]),
                     "--video", "none", "--out", str(tmp / f"loop-{i}")], _env(cache))
               for i, c in enumerate(cases[:args.loop])]
    figures["loop_s_per_request"] = sum(seconds) / len(seconds)
    figures["loop_per_s"] = 1 / figures["loop_s_per_request"]
    print(f"loop of commands: {figures['loop_s_per_request']:.2f} s a request "
          f"({figures['loop_per_s']:.3f} motions/s)", flush=True)

    # 2. an in-process loop
    code = ("import json, sys, time, jaxmotion\n"
            "cases = json.loads(sys.argv[1]); out = sys.argv[2]\n"
            "r = jaxmotion.generate('demo', cases[0]['text'], seed=99)\n"
            "t0 = time.perf_counter()\n"
            "for i, c in enumerate(cases):\n"
            "    jaxmotion.generate('demo', c['text'], seed=c['seed']).save("
            "f'{out}/{i}', video=None)\n"
            "print(time.perf_counter() - t0)\n")
    done = subprocess.run([sys.executable, "-c", code, json.dumps(cases), str(tmp / "inproc")],
                          env=_env(cache), check=True, capture_output=True, text=True)
    s = float(done.stdout.strip().splitlines()[-1])
    figures["in_process_per_s"] = len(cases) / s
    print(f"in-process loop: {s / len(cases):.2f} s a request "
          f"({figures['in_process_per_s']:.3f} motions/s)", flush=True)

    # 3. batch, per device count
    for d in args.devices:
        s = _cli(["--batch", str(tmp / "cases.jsonl"), "--out", str(tmp / f"batch-{d}"),
                  *size], _env(cache, d))
        figures[f"batch_{d}dev_per_s"] = len(cases) / s
        ratio = figures[f"batch_{d}dev_per_s"] / figures["loop_per_s"]
        figures[f"batch_{d}dev_vs_loop"] = ratio
        figures[f"batch_{d}dev_vs_in_process"] = (figures[f"batch_{d}dev_per_s"]
                                                  / figures["in_process_per_s"])
        print(f"batch, {d} device(s): {s:.1f} s for {len(cases)} requests "
              f"({figures[f'batch_{d}dev_per_s']:.3f} motions/s): {ratio:.1f}x the loop of "
              f"commands, {figures[f'batch_{d}dev_vs_in_process']:.1f}x the in-process loop",
              flush=True)
    if args.json:
        Path(args.json).write_text(json.dumps(figures, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
