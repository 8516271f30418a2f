"""Three-step stories in held-out rooms: stand up from a seat, walk to an object, sit on another
seat (:func:`jaxmotion.planning.story.tell`), scored as the stories issue asks.

For each room (a ``jaxmotion synth`` dataset's scenes, e.g. built with a seed no training used)
the first seat (chair, armchair, sofa, stool) is the one to get up from, the seat farthest from
it the one to sit on, and the walk goes to the object nearest the middle of the two that is
neither. A story succeeds when

- it **starts seated** on the first seat (the geometric judge's stand-up check at frame 0),
- it **ends seated** on the last seat (the judge's sit check at the last frame; with
  ``--last lie`` the last step lies on the bed or sofa farthest from the first seat, and the
  judge's lie check counts),
- it has **no teleport** (:func:`jaxmotion.eval.plausibility.teleports`), and
- it **keeps out of other furniture**: joints inside the box of an object other than the two
  seats and the walk's target (shrunk by 5 cm, floors and walls aside) in at most 1 % of
  frames.

Prints each story's checks, the rates, the top speeds and the warm time per story (the first
story compiles; the target is ≤ 15 s warm on a 2-core CPU).

    python benchmarks/stories.py --data data/unseen9001 [--rooms 30] [--skip 0] [--seed 0]
        [--last sit|lie] [--out DIR]
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

SEATS = ("chair", "armchair", "sofa", "stool")
BEDS = ("bed", "sofa")
SKIP = ("door", "window", "floor", "wall", "rug", "curtain")


def choose_plan(scene, last: str = "sit"):
    """``[stand_up A, walk C, sit B]`` for a room, or None when it has fewer than two seats;
    with ``last="lie"``, ``[stand_up A, walk C, lie B]`` with B a bed (or a sofa), None when
    the room has no seat and bed apart."""
    objs = [o for o in scene.objects if o["category"] in SEATS]
    beds = [o for o in scene.objects if o["category"] in BEDS]
    centre = {o["id"]: 0.5 * (np.asarray(o["bbox_min"][:2]) + np.asarray(o["bbox_max"][:2]))
              for o in scene.objects}
    if last == "lie":
        a = objs[0] if objs else None
        beds = [o for o in beds if a is not None and o["id"] != a["id"]]
        if not beds:
            return None
        b = max(beds, key=lambda o: np.linalg.norm(centre[o["id"]] - centre[a["id"]]))
    else:
        if len(objs) < 2:
            return None
        a = objs[0]
        b = max(objs[1:], key=lambda o: np.linalg.norm(centre[o["id"]] - centre[a["id"]]))
    mid = 0.5 * (centre[a["id"]] + centre[b["id"]])
    others = [o for o in scene.objects if o["id"] not in (a["id"], b["id"])
              and o["category"] not in SKIP]
    if not others:
        return None
    c = min(others, key=lambda o: np.linalg.norm(centre[o["id"]] - mid))
    return [{"action": "stand_up", "object": a["id"]}, {"action": "walk", "object": c["id"]},
            {"action": last, "object": b["id"]}], (a, b, c)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--data", required=True, help="a jaxmotion synth dataset (its scenes/)")
    p.add_argument("--rooms", type=int, default=30)
    p.add_argument("--last", choices=("sit", "lie"), default="sit",
                   help="the last step: sit on a seat (default) or lie on a bed or sofa")
    p.add_argument("--skip", type=int, default=0,
                   help="leave out the first SKIP scene files (another set of rooms)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--out", default=None, help="write stories.jsonl and the motions here")
    args = p.parse_args(argv)

    import jax.numpy as jnp

    from jaxmotion.eval.action_judge import judge_actions
    from jaxmotion.eval.furniture import furniture_frames
    from jaxmotion.eval.plausibility import plausibility
    from jaxmotion.planning.story import tell
    from jaxmotion.scene.demo import load_scene_arg

    files = sorted((Path(args.data) / "scenes").glob("*.npz"))[args.skip:]
    if not files:
        print(f"no scenes in {args.data}/scenes", file=sys.stderr)
        return 2
    out = Path(args.out) if args.out else None
    if out:
        out.mkdir(parents=True, exist_ok=True)
    rows, times = [], []
    for f in files:
        if len(rows) >= args.rooms:
            break
        scene = load_scene_arg(str(f))
        chosen = choose_plan(scene, args.last)
        if chosen is None:
            continue
        plan, (a, b, c) = chosen
        t0 = time.perf_counter()
        try:
            story = tell(scene, plan, seed=args.seed)
        except Exception as e:  # noqa: BLE001  (a refused story counts as a failure)
            rows.append({"scene": f.name, "plan": plan, "error": str(e), "success": False})
            print(f"{f.name}: refused: {e}", flush=True)
            continue
        times.append(time.perf_counter() - t0)
        j = story.joints

        def seated(action, obj, frames, scene=scene):
            pts = scene.xyz[scene.instance == obj["id"]][None]
            rep = judge_actions(frames[None], np.ones((1, len(frames)), bool), [action],
                                np.asarray(obj["bbox_min"])[None],
                                np.asarray(obj["bbox_max"])[None], pts)
            return bool(rep["success"][0])

        pl = plausibility(jnp.asarray(j), None)
        row = {"scene": f.name, "plan": plan, "frames": len(j),
               "start_seated": seated("stand_up", a, j), "end_seated": seated(args.last, b, j),
               "teleport": bool(pl["teleport"]),
               "pelvis_speed_max": float(pl["pelvis_speed_max"]),
               "joint_speed_max": float(pl["joint_speed_max"]),
               "skating": float(pl["skate_ratio"]),
               "furniture": float(furniture_frames(j, scene.objects,
                                                   (a["id"], b["id"], c["id"]))),
               "seconds": times[-1]}
        row["success"] = (row["start_seated"] and row["end_seated"] and not row["teleport"]
                          and row["furniture"] <= 0.01)
        rows.append(row)
        print(f"{f.name}: {'ok ' if row['success'] else 'BAD'} start {row['start_seated']} "
              f"end {row['end_seated']} teleport {row['teleport']} furniture "
              f"{row['furniture']:.3f} pelvis max {row['pelvis_speed_max']:.2f} m/s, "
              f"{len(j) / 30:.1f} s of motion in {times[-1]:.1f} s", flush=True)
        if out:
            np.savez(out / f"{f.stem}.npz", joints=story.joints, motion=story.motion,
                     segments=json.dumps(story.segments))
    done = [r for r in rows if "error" not in r]
    n = len(rows)

    def rate(key):
        return 100.0 * sum(bool(r.get(key)) for r in rows) / max(n, 1)

    print(f"\n{n} stories ({n - len(done)} refused): success {rate('success'):.1f} %, start "
          f"seated {rate('start_seated'):.1f} %, end seated {rate('end_seated'):.1f} %, "
          f"teleport {rate('teleport'):.1f} %")
    if done:
        print(f"furniture frames mean {np.mean([r['furniture'] for r in done]):.4f}; skating "
              f"{100 * np.mean([r['skating'] for r in done]):.1f} %; pelvis speed max median "
              f"{np.median([r['pelvis_speed_max'] for r in done]):.2f} m/s; seconds per story "
              f"(warm, after the first) median {np.median(times[1:] or times):.1f}")
    if out:
        with open(out / "stories.jsonl", "w") as fh:
            fh.writelines(json.dumps(r) + "\n" for r in rows)
    return 0


if __name__ == "__main__":
    sys.exit(main())
