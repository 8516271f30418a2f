"""Object discovery: speed, what it finds, and generate on rooms whose labels are removed.

    python benchmarks/segment.py [--rooms 30] [--seed 9001] [--generate 12] [--json OUT]

1. **Speed** (the target: a 50k–200k-point room in at most 10 s on 2 cores): levelling plus
   segmentation of a room of an unseen seed at 50k, 100k and 200k points, no normals given
   (they are estimated), against the time of reading the same room's labels
   (``table_from_labels``, the labelled path) measured in the same run.
2. **Discovery** on ``--rooms`` rooms of seed ``--seed`` (never trained on: the classifier's
   rooms are seeds 100000+), labels removed, clean scans and degraded ones
   (:func:`jaxmotion.data.object_features.degrade`): per-instance recall of the furniture
   (IoU >= 0.5; doors, windows, pictures, lamps and TVs aside) and the category accuracy of
   the matched instances (strict: an armchair called a chair is wrong; and by the action
   they afford: any seat for a seat).
3. **Generate** (``--generate K`` rooms, 0 to skip): "sit on the <seat>", "lie on the bed",
   "walk to the table" (what each room has) with the shipped models, once in the room as
   labelled and once with its labels removed (segmented as a user's scan is). Per motion:
   teleport (a joint > 9 m/s or the pelvis > 3 m/s), the geometric judge on the true
   object the motion went to (the discovered target's best-overlapping true object, which
   must be of the class asked for), goal distance (pelvis at the anchor frame to the target's
   points, xy).

Synthetic rooms: the numbers say how discovery works where the truth is known, not how it
does on real scans.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
import time

import numpy as np

WALLM = ("door", "window", "picture", "lamp", "tv")
SEATS = {"chair", "armchair", "sofa", "stool", "toilet", "bed"}


def _strip(scene):
    return dataclasses.replace(scene, normal=None, semantic=None, instance=None, objects=())


def speed(seed: int) -> list[dict]:
    from jaxmotion.scene.level import level_scene
    from jaxmotion.scene.objects import table_from_labels
    from jaxmotion.scene.rooms import room_to_scene, sample_room
    from jaxmotion.scene.segment import segment_scene

    rows = []
    for n in (50_000, 100_000, 200_000):
        scene = room_to_scene(sample_room(seed), n, np.random.default_rng(seed))
        bare = _strip(scene)
        segment_scene(bare)  # first call: imports and the classifier's load
        t0 = time.perf_counter()
        levelled, _ = level_scene(bare)
        segment_scene(levelled)
        t = time.perf_counter() - t0
        t1 = time.perf_counter()
        table_from_labels(scene.xyz, scene.semantic, scene.instance)
        base = time.perf_counter() - t1
        rows.append({"points": n, "segment_s": round(t, 3), "labels_s": round(base, 4),
                     "ratio_to_labels": round(t / max(base, 1e-6), 1),
                     "target_s": 10.0, "within_target": t <= 10.0})
        print(f"  {n:>7} points: level + segment {t:5.2f} s (reading labels {base:.4f} s, "
              f"x{t / max(base, 1e-6):.0f}); target 10 s", flush=True)
    return rows


def _match(truth, found):
    """Per true furniture object: (category, best IoU, the found object's category)."""
    out = []
    cats = {o["id"]: o["category"] for o in found.objects}
    for o in truth.objects:
        if o["category"] in WALLM:
            continue
        g = truth.instance == o["id"]
        best, which = 0.0, None
        for c in np.unique(found.instance[g]):
            if c < 0:
                continue
            p = found.instance == c
            iou = (g & p).sum() / (g | p).sum()
            if iou > best:
                best, which = float(iou), cats.get(int(c))
        out.append((o["category"], best, which))
    return out


def discovery(rooms: int, seed: int) -> dict:
    from jaxmotion.data.object_features import degrade
    from jaxmotion.scene.rooms import room_to_scene, sample_room
    from jaxmotion.scene.segment import segment_scene

    result = {}
    for kind in ("clean", "degraded"):
        matched = []
        for r in range(rooms):
            rng = np.random.default_rng([seed, r])
            scene = room_to_scene(sample_room(seed + r), 80_000, rng)
            if kind == "degraded":
                scene = degrade(scene, rng)
            found, _ = segment_scene(_strip(scene))
            matched += _match(scene, found)
        hits = [m for m in matched if m[1] >= 0.5]
        strict = np.mean([c == w for c, _, w in hits]) if hits else 0.0
        seat = np.mean([(c in SEATS) == (w in SEATS) and (c not in SEATS or w in SEATS)
                        for c, _, w in hits]) if hits else 0.0
        per = {}
        for c, iou, w in matched:
            row = per.setdefault(c, [0, 0, 0])
            row[0] += 1
            row[1] += iou >= 0.5
            row[2] += iou >= 0.5 and c == w
        result[kind] = {"furniture": len(matched), "recall": round(len(hits) / len(matched), 3),
                        "category_accuracy": round(float(strict), 3),
                        "seat_or_not_accuracy": round(float(seat), 3),
                        "per_category": {c: {"objects": a, "found": b, "named": n}
                                         for c, (a, b, n) in sorted(per.items())}}
        print(f"  {kind:>8}: recall {result[kind]['recall']:.1%} of {len(matched)} furniture "
              f"objects, category accuracy {strict:.1%} (seat or not: {seat:.1%})", flush=True)
    return result


def _cases(scene):
    cats = {o["category"] for o in scene.objects}
    out = []
    seat = next((c for c in ("chair", "sofa", "armchair", "stool") if c in cats), None)
    if seat:
        out.append(("sit", f"sit on the {seat}", seat))
    if "bed" in cats:
        out.append(("lie", "lie on the bed", "bed"))
    if "table" in cats:
        out.append(("walk", "walk to the table", "table"))
    return out


def generate_protocol(rooms: int, seed: int) -> dict:
    import warnings

    import jaxmotion
    from jaxmotion.eval.action_judge import judge_on_object
    from jaxmotion.eval.plausibility import plausibility
    from jaxmotion.scene.rooms import room_to_scene, sample_room

    rows = []
    for r in range(rooms):
        scene = room_to_scene(sample_room(seed + r), 60_000, np.random.default_rng([seed, r]))
        bare = _strip(scene)
        for action, text, cat in _cases(scene):
            for kind, room in (("labelled", scene), ("unlabelled", bare)):
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")
                    try:
                        res = jaxmotion.generate(room, text, seed=r)
                    except ValueError as e:
                        rows.append({"room": r, "text": text, "kind": kind, "error": str(e)})
                        continue
                joints = res.joints[0]
                tele = bool(plausibility(joints)["teleport"])
                found = res.scene
                tid = res.target_id
                sel = (found.instance == tid) if tid is not None else np.zeros(
                    found.num_points, bool)
                # the true object the discovered target is (most of its points)
                ids, counts = np.unique(scene.instance[sel], return_counts=True) if sel.any() \
                    else (np.array([-1]), np.array([1]))
                true_id = int(ids[np.argmax(counts)])
                obj = next((o for o in scene.objects if o["id"] == true_id), None)
                ok_class = obj is not None and obj["category"] == cat
                judged = False
                goal = float("nan")
                if obj is not None:
                    pts = scene.xyz[scene.instance == true_id]
                    rep = judge_on_object(joints[None], None, action, np.asarray(obj["bbox_min"]),
                                          np.asarray(obj["bbox_max"]), pts,
                                          obj.get("surface_height"))
                    judged = bool(rep["success"][0])
                    end = joints[0 if action == "stand_up" else -1, 0, :2]
                    goal = float(np.min(np.linalg.norm(pts[:, :2] - end, axis=1)))
                rows.append({"room": r, "text": text, "kind": kind, "teleport": tele,
                             "right_class": ok_class, "judge": judged and ok_class,
                             "goal_xy_m": round(goal, 3), "pipeline": res.pipeline})
                print(f"  room {r:>2} {kind:>10} {text!r}: pipeline {res.pipeline}, teleport "
                      f"{tele}, right object {ok_class}, judge {judged and ok_class}, goal "
                      f"{goal:.2f} m", flush=True)
    out = {}
    for kind in ("labelled", "unlabelled"):
        rs = [x for x in rows if x["kind"] == kind and "error" not in x]
        errors = [x for x in rows if x["kind"] == kind and "error" in x]
        out[kind] = {"motions": len(rs), "errors": len(errors),
                     "teleports": round(float(np.mean([x["teleport"] for x in rs])), 3)
                     if rs else None,
                     "judge": round(float(np.mean([x["judge"] for x in rs])), 3) if rs else None,
                     "right_object": round(float(np.mean([x["right_class"] for x in rs])), 3)
                     if rs else None,
                     "goal_xy_median_m": round(float(np.nanmedian([x["goal_xy_m"] for x in rs])),
                                               3) if rs else None}
        print(f"  {kind}: {out[kind]}", flush=True)
    return {"summary": out, "rows": rows}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--rooms", type=int, default=30)
    ap.add_argument("--seed", type=int, default=9001)
    ap.add_argument("--generate", type=int, default=0, metavar="K")
    ap.add_argument("--no-speed", action="store_true")
    ap.add_argument("--json", default=None)
    args = ap.parse_args(argv)
    report: dict = {"seed": args.seed}
    if not args.no_speed:
        print("speed (level + segment, 2 cores):", flush=True)
        report["speed"] = speed(args.seed)
    if args.rooms:
        print(f"discovery on {args.rooms} rooms of seed {args.seed}, labels removed:", flush=True)
        report["discovery"] = discovery(args.rooms, args.seed)
    if args.generate:
        print(f"generate on {args.generate} rooms, labelled and not:", flush=True)
        report["generate"] = generate_protocol(args.generate, args.seed)
    if args.json:
        with open(args.json, "w") as f:
            json.dump(report, f, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
