"""Trajectory control on held-out paths, with OmniControl's metrics
(:mod:`jaxmotion.eval.control`) and foot skating against the dataset's own.

Two kinds of held-out path, each followed by ``jaxmotion.planning.control.follow`` (the
object-centric completion model, the pelvis held to the path) in its own room:

- ``dataset``: the pelvis paths (x, y at 30 fps) of the walks of a split (default ``test``)
  of a ``jaxmotion synth`` dataset; the reference row scores the dataset's own motions;
- ``planned``: a walk between two random free places of each room (A* on the room's points,
  the rule speed profile: :func:`jaxmotion.planning.trajectory.path_trajectory`), longer than
  the dataset's 4 s clips, so that the windows' joins are tested too.

Prints per path and in total: average error (m), location error (share of frames > 50 cm),
trajectory error (share of paths with a frame > 50 cm), foot skating, teleports, and the warm
seconds per second of motion. Targets (the stories issue): average error ≤ 5 cm, location
error ≤ 1 %, skating ≤ the dataset's + 2 points.

    python benchmarks/trajectory_control.py --data data/synth --cases 24 \
        [--planned data/unseen9001 --rooms 12] [--steps 20] [--out DIR]
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np


def dataset_paths(data, split, cases):
    """``(scene_id, xy [T, 2], joints [T, 22, 3], text, target)`` of a split's walks."""
    from jaxmotion.data.format import load_sample

    out = []
    for f in sorted((Path(data) / "samples" / split).glob("*.npz")):
        s = load_sample(f)
        if str(s["action"]) != "walk":
            continue
        m = np.asarray(s["mask"], bool)
        j = np.asarray(s["joints"], np.float32)[m]
        out.append((str(s["scene_id"]), j[:, 0, :2], j, str(s["text"]), int(s["target_id"])))
        if len(out) >= cases:
            break
    return out


def planned_paths(data, rooms, seed):
    """A walk between two random free places (≥ 2 m apart) in each of ``rooms`` rooms."""
    from jaxmotion.motion.planner import PlanningError
    from jaxmotion.planning.paths import point_grid, scene_path
    from jaxmotion.planning.trajectory import path_trajectory
    from jaxmotion.scene import load_scene

    out = []
    rng = np.random.default_rng(seed)
    for f in sorted((Path(data) / "scenes").glob("*.npz"))[:rooms]:
        scene = load_scene(f)
        grid = point_grid(scene.xyz, scene.instance)
        lo, hi = scene.xyz[:, :2].min(0) + 0.4, scene.xyz[:, :2].max(0) - 0.4
        cand = rng.uniform(lo, hi, size=(600, 2))
        free = cand[grid.clearance_at(cand) > 0.35]
        for _ in range(20):
            if len(free) < 2:
                break
            a, b = free[rng.integers(len(free), size=2)]
            if np.linalg.norm(a - b) < 2.0:
                continue
            try:
                path = scene_path(grid, a, b)
            except PlanningError:
                continue
            xy = path_trajectory(path)[:, :2]
            out.append((f.stem, xy, None, "walk across the room", None))
            break
    return out


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--data", default="data/synth", help="dataset for the dataset paths")
    p.add_argument("--split", default="test")
    p.add_argument("--cases", type=int, default=24, help="dataset walks to follow")
    p.add_argument("--planned", default=None, help="dataset whose rooms get planned paths")
    p.add_argument("--rooms", type=int, default=12)
    p.add_argument("--steps", type=int, default=20, help="DDIM steps")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--out", default=None, help="folder for results.json")
    args = p.parse_args(argv)

    from jaxmotion.eval.control import control_errors
    from jaxmotion.eval.plausibility import plausibility
    from jaxmotion.eval.skating import foot_skating
    from jaxmotion.planning.control import follow
    from jaxmotion.scene import load_scene

    sets = []
    if args.cases:
        sets.append(("dataset", args.data, dataset_paths(args.data, args.split, args.cases)))
    if args.planned:
        sets.append(("planned", args.planned, planned_paths(args.planned, args.rooms,
                                                            args.seed)))
    report = {}
    for name, data, paths in sets:
        rows, warm = [], []
        print(f"\n{name} paths ({len(paths)}) in {data}", flush=True)
        for i, (sid, xy, ref, text, target) in enumerate(paths):
            scene = load_scene(Path(data) / "scenes" / f"{sid}.npz")
            t0 = time.perf_counter()
            story = follow(scene, xy, text, seed=args.seed + i, steps=args.steps,
                           object_id=target)
            dt = time.perf_counter() - t0
            if i:
                warm.append(dt / (len(xy) / 30.0))
            j = story.joints
            err = {k: float(v) for k, v in control_errors(j, xy).items()}
            row = {"scene": sid, "seconds": len(xy) / 30.0, **err,
                   "skating": float(foot_skating(j)["skate_ratio"]),
                   "teleport": bool(plausibility(j)["teleport"])}
            if ref is not None:
                row["skating_dataset"] = float(foot_skating(ref)["skate_ratio"])
            rows.append(row)
            print(f"  {i:3d} {sid} {row['seconds']:4.1f} s  avg err {err['average_error']:.4f} m"
                  f"  skating {row['skating']:.3f}"
                  + (f" (dataset {row['skating_dataset']:.3f})" if ref is not None else "")
                  + ("  TELEPORT" if row["teleport"] else ""), flush=True)
        if not rows:
            continue
        mean = lambda k: float(np.mean([r[k] for r in rows]))  # noqa: E731
        summary = {"paths": len(rows), "average_error_m": mean("average_error"),
                   "location_error": mean("location_error"),
                   "trajectory_error": mean("trajectory_error"), "skating": mean("skating"),
                   "teleport": mean("teleport"), "seconds_per_motion_second":
                   float(np.median(warm)) if warm else None}
        if "skating_dataset" in rows[0]:
            summary["skating_dataset"] = mean("skating_dataset")
        report[name] = {"summary": summary, "rows": rows}
        print(f"{name}: " + ", ".join(f"{k} {v:.4f}" if isinstance(v, float) else f"{k} {v}"
                                      for k, v in summary.items()), flush=True)
    if args.out:
        out = Path(args.out)
        out.mkdir(parents=True, exist_ok=True)
        (out / "results.json").write_text(json.dumps(report, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
