"""A story from Python: several steps told as one continuous motion in the demo room.

    python examples/story.py [--out DIR] [--steps 10]

The steps are given as a plan on object ids (the ids ``jaxmotion scene info demo`` lists);
``jaxmotion.generate("demo", "stand up from chair 4, walk to the fridge, then sit on the
stool next to it")`` reads the same kind of plan from words. The result is one motion with
its steps (``segments``) and planned walking paths (``paths``), saved as the files
``jaxmotion generate`` writes (without the video, to keep the example quick).
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np

import jaxmotion
from jaxmotion.scene.demo import demo_scene

PLAN = [{"action": "stand_up", "object": 4},  # get up from chair 4
        {"action": "walk", "object": 9},      # walk to the fridge
        {"action": "sit", "object": 8}]       # sit on stool 8


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", default=None, help="folder for the files (default: a temp folder)")
    ap.add_argument("--steps", type=int, default=10, help="DDIM steps per stage")
    args = ap.parse_args()

    names = {o["id"]: o["category"] for o in demo_scene().objects}
    print("plan:", ", ".join(f"{s['action']} {names[s['object']]} {s['object']}" for s in PLAN))
    t0 = time.perf_counter()
    story = jaxmotion.generate("demo", plan=PLAN, seed=0, steps=args.steps)
    t1 = time.perf_counter()

    assert story.joints.shape[0] == 1 and np.isfinite(story.joints).all()
    assert [s["action"] for s in story.segments][-1] == "sit"
    frames = story.joints.shape[1]
    print(f"one motion of {frames} frames ({frames / story.fps:.1f} s at {story.fps:g} fps) "
          f"in {t1 - t0:.1f} s; pipeline {story.pipeline!r}")
    for s in story.segments:
        print(f"  {s['action']:9s} {names.get(s['object'], '-'):9s} frames {s['first']:3d}-"
              f"{s['last']:3d}")
    for i, path in enumerate(story.paths):
        length = float(np.linalg.norm(np.diff(np.asarray(path), axis=0), axis=1).sum())
        print(f"  walking path {i}: {len(path)} points, {length:.2f} m")

    out = Path(args.out) if args.out else Path(tempfile.mkdtemp(prefix="jaxmotion-story-")) / "story"
    files = story.save(out, video=None)
    print(f"wrote {', '.join(sorted(files))} to {out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
