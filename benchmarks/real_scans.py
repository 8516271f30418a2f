"""Simple instructions on real scans you have: is the action done, without teleports, clear of
the other furniture?

    python benchmarks/real_scans.py ROOM [ROOM ...] [--seeds 0 1] [--strip-labels] [--json OUT]

ROOM: any file ``jaxmotion generate --scene`` reads (a ScanNet ``*_vh_clean_2.ply`` or its
``labels.ply``, a PLY / OBJ / GLB of a phone scan, ...). No scan ships with jaxmotion (their
licences forbid it); public samples that repositories carry are listed in
``docs/benchmarks.md`` ("Real scans"). ``--strip-labels`` also runs each room as a plain point
cloud (xyz and colour only, written to a temporary PLY), as a user's unlabelled scan is.

Per room (version) and seed, six instructions: "sit on the chair", "sit on the sofa", "have a
seat on the couch", "lie on the bed", "walk to the table", "walk to the table and sit on the
chair". Per motion: refused (the message), the target and whether its category is of the kind
asked, a teleport (a joint > 9 m/s or the pelvis > 3 m/s: :func:`jaxmotion.eval.plausibility`),
the geometric judge (:func:`jaxmotion.eval.action_judge.judge_on_object`: seated, lying or
standing near the target at the end), the share of frames with a joint inside another object's
box (:func:`jaxmotion.eval.furniture.furniture_frames`, the protocol's furniture metric; a sit's
or lie's own target aside), the stricter share of frames with a joint within 4 cm of another
object's points (:func:`jaxmotion.eval.furniture.contact_frames`: doors, windows, pictures,
curtains, rugs, floor mats and structure aside), the lowest
foot. Printed per motion and in total; ``--json`` keeps the rows.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np

TEXTS = [("sit on the chair", "sit", {"chair", "armchair", "stool"}),
         ("sit on the sofa", "sit", {"sofa"}),
         ("have a seat on the couch", "sit", {"sofa"}),
         ("lie on the bed", "lie", {"bed"}),
         ("walk to the table", "walk", {"table", "coffee table", "desk"}),
         ("walk to the table and sit on the chair", "sit", {"chair", "armchair", "stool"})]
PASS = ("door", "window", "picture", "curtain", "rug", "floor mat", "wall", "floor", "ceiling")
FEET = [7, 8, 10, 11]


def near_share(joints, scene, target, radius=0.04) -> float:
    """Share of frames with a joint within ``radius`` of another object's points
    (:func:`jaxmotion.eval.furniture.contact_frames`; floor mats are walked on)."""
    from jaxmotion.eval.furniture import contact_frames

    objects = [o for o in scene.objects if o["category"] not in PASS]
    return float(contact_frames(joints[None], scene.xyz, scene.instance, objects,
                                exclude=() if target is None else (target,),
                                radius=radius)[0])


def strip(path: Path, tmp: Path) -> Path:
    """The room as a plain point cloud: xyz and colour only."""
    import trimesh

    from jaxmotion.scene.demo import load_scene_arg

    s = load_scene_arg(str(path), segment=False)
    out = tmp / f"{path.stem}_unlabelled.ply"
    trimesh.PointCloud(s.xyz, (np.clip(s.rgb, 0, 1) * 255).astype(np.uint8)).export(out)
    return out


def run_room(path: Path, name: str, seeds) -> list[dict]:
    import jaxmotion
    from jaxmotion.eval.action_judge import judge_on_object
    from jaxmotion.eval.furniture import furniture_frames
    from jaxmotion.eval.plausibility import plausibility
    from jaxmotion.scene.demo import load_scene_arg

    t0 = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        room = load_scene_arg(str(path))
    print(f"## {name}: {len(room.objects)} objects, prepared in {time.perf_counter() - t0:.1f} s",
          flush=True)
    rows = []
    for text, action, kinds in TEXTS:
        for seed in seeds:
            row = {"room": name, "text": text, "seed": seed}
            t1 = time.perf_counter()
            try:
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")
                    res = jaxmotion.generate(room, text, seed=seed, fit=False)
            except jaxmotion.generation.GenerateError as e:
                row["refused"] = str(e)
                rows.append(row)
                print(f"  {text!r} seed {seed}: refused: {str(e)[:160]}", flush=True)
                continue
            j = np.asarray(res.joints[0], np.float64)
            cats = {o["id"]: o["category"] for o in res.scene.objects}
            tid = res.target_id
            pl = plausibility(j[None])
            row.update(seconds=round(time.perf_counter() - t1, 2), target=tid,
                       category=cats.get(tid), right_kind=cats.get(tid) in kinds,
                       teleport=bool(pl["teleport"][0]), pelvis_end=round(float(j[-1, 0, 2]), 3),
                       lowest_foot=round(float(j[:, FEET, 2].min()), 3),
                       near_4cm=round(near_share(j, res.scene, tid), 3),
                       in_furniture=round(float(furniture_frames(
                           j[None], res.scene.objects,
                           () if action == "walk" or tid is None else (tid,))[0]), 3))
            if tid is not None:
                o = next(o for o in res.scene.objects if o["id"] == tid)
                pts = res.scene.xyz[res.scene.instance == tid]
                judged = judge_on_object(j[None].astype(np.float32), None, action,
                                         np.asarray(o["bbox_min"]), np.asarray(o["bbox_max"]),
                                         pts, o.get("surface_height"))
                row["judge"] = bool(judged["success"][0])
            rows.append(row)
            print(f"  {text!r} seed {seed}: {cats.get(tid)} {tid} (kind ok: {row['right_kind']})"
                  f", teleport {row['teleport']}, judge {row.get('judge')}, pelvis end "
                  f"{row['pelvis_end']:.2f} m, inside furniture "
                  f"{100 * row['in_furniture']:.0f} % / near other furniture "
                  f"{100 * row['near_4cm']:.0f} % of frames, lowest foot "
                  f"{100 * row['lowest_foot']:.1f} cm", flush=True)
    return rows


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("rooms", nargs="+", type=Path)
    ap.add_argument("--seeds", type=int, nargs="+", default=[0, 1])
    ap.add_argument("--strip-labels", action="store_true",
                    help="also run each room with its labels removed")
    ap.add_argument("--json", type=Path, default=None)
    args = ap.parse_args(argv)
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for path in args.rooms:
            rows += run_room(path, path.name, args.seeds)
            if args.strip_labels:
                rows += run_room(strip(path, Path(tmp)), path.name + " (labels removed)",
                                 args.seeds)
    done = [r for r in rows if "refused" not in r]
    acts = [r for r in done if r["text"] != "walk to the table"]
    print(f"\n{len(rows)} runs: {len(rows) - len(done)} refused; of the {len(done)} made, "
          f"{sum(r['teleport'] for r in done)} with a teleport, "
          f"{sum(r['right_kind'] for r in done)} on an object of the kind asked; "
          f"sit / lie done on the kind asked (judge): "
          f"{sum(bool(r.get('judge')) and r['right_kind'] for r in acts)} of {len(acts)}; "
          f"frames inside furniture (boxes): "
          f"{100 * np.mean([r['in_furniture'] for r in done]):.1f} %, near other furniture "
          f"(4 cm of its points): {100 * np.mean([r['near_4cm'] for r in done]):.1f} % (means)"
          if done else f"\n{len(rows)} runs, all refused")
    if args.json:
        args.json.write_text("\n".join(json.dumps(r) for r in rows) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
