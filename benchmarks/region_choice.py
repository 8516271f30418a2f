"""How often the choice among same-class objects finds the object an instruction means.

When the words leave several objects of the named class, ``generate`` chooses among them:
by default the one a body reaches most freely (:mod:`jaxmotion.grounding.reach`), with
``--grounding adm`` the ADM's map. The words do not say which one is meant there, so no
rule can beat chance by reading them; this measures that neither does worse. On a dataset
split's instructions whose room has several objects of the named class when the relation is
ignored (as ``--grounding adm`` reads them), it prints how often the meant object is chosen
by the free floor, by the lowest object id (a baseline), at chance (the mean of 1 / candidates)
and, with ``--adm``, by the shipped text ADM at generate's steps and guidance.

    python benchmarks/region_choice.py --data data/synth300 --split val [--cases 300] [--adm]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np


def main(argv=None) -> int:
    from jaxmotion.data.format import load_sample
    from jaxmotion.grounding.reach import most_reachable
    from jaxmotion.grounding.target import ground_candidates, read_instruction
    from jaxmotion.scene import load_scene

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", required=True, help="a dataset built by `jaxmotion synth`")
    ap.add_argument("--split", default="val")
    ap.add_argument("--cases", type=int, default=300, help="the split's first N instructions")
    ap.add_argument("--adm", action="store_true", help="also the ADM's choice (loads it)")
    args = ap.parse_args(argv)
    files = sorted((Path(args.data) / "samples" / args.split).glob("*.npz"))[:args.cases]
    if not files:
        raise SystemExit(f"{Path(args.data) / 'samples' / args.split}: no samples; build a "
                         "dataset with `jaxmotion synth --out DIR`")
    adm_hits = None
    if args.adm:
        from jaxmotion.eval.region_probe import case_regions
        from jaxmotion.pipelines.affordance import AffordancePipeline
        from jaxmotion.pipelines.checkpoints import default_checkpoints, text_adm_for

        adm, amdm = default_checkpoints()
        pipe = AffordancePipeline.from_workdirs(text_adm_for(adm), amdm)
        regions = case_regions(args.data, args.split, pipe, num_cases=args.cases,
                               grounding="adm")
        adm_hits = {i: r["chosen"] == r["target"] for i, r in enumerate(regions)}
    rows = []  # (free floor, lowest id, 1 / candidates, adm or None)
    for i, f in enumerate(files):
        s = load_sample(f)
        room = load_scene(Path(args.data) / "scenes" / f"{s['scene_id']}.npz")
        ins = read_instruction(str(s["text"]))
        cands = ground_candidates(room, ins, "adm").objects
        target = int(s["target_id"])
        if len(cands) < 2 or target not in {int(o["id"]) for o in cands}:
            continue
        pick = int(cands[most_reachable(room, cands, ins.action)]["id"])
        rows.append((pick == target, min(int(o["id"]) for o in cands) == target,
                     1.0 / len(cands), None if adm_hits is None else adm_hits[i]))
    if not rows:
        raise SystemExit("no instruction of the split leaves several objects of its class")
    r = np.array([row[:3] for row in rows], float)
    n = len(rows)
    half = 196.0 * np.sqrt(max(r[:, 2].mean() * (1 - r[:, 2].mean()), 1e-9) / n)
    print(f"{n} instructions of {len(files)} ({args.data}, {args.split}) leave several objects "
          f"of their class; meant object chosen (±{half:.0f} points at this size):")
    print(f"  free floor (default)  {100 * r[:, 0].mean():5.1f} %")
    print(f"  lowest id             {100 * r[:, 1].mean():5.1f} %")
    if adm_hits is not None:
        print(f"  ADM (--grounding adm) {100 * np.mean([row[3] for row in rows]):5.1f} %")
    print(f"  chance                {100 * r[:, 2].mean():5.1f} %")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
