"""How many DDIM steps the ADM's region choice needs, and how much its choice is noise.

``generate --grounding adm`` runs the crop-view ADM to choose the region when the words leave
several objects of the named class (one map per candidate) or none (one map per tile of the
room). The choice is a ranking of maps, not the map the motion is drawn from, so it may need
fewer steps than the affordance stage. For each step count this prints, on a dataset split's
rooms:

- among candidates (``--grounding adm``: every object of the named class): how often the
  chosen object is the one meant, and how often the choice is the baseline's (5 steps, seed 0);
- among tiles (texts naming no object, ``--grounding adm``: "wander around for a bit", ...):
  how often the chosen object is the baseline's, and the chosen square's centre within 0.5 m
  of it;

and the same agreements for the baseline with another seed: the choice's own noise, which a
step count within it does not change.

    python benchmarks/region_steps.py --data data/synth --split val --cases 300 \\
        [--steps 1,2,3] [--guidance 5]
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

TILE_TEXTS = ("wander around for a bit", "dance around the room", "walk around",
              "stroll around for a while")


def tile_regions(data_dir, split: str, pipe, embs, sampler, seed: int) -> list[tuple]:
    """``(centre, chosen id)`` of generate's region choice for :data:`TILE_TEXTS` (``embs``:
    their text conditions) in every room of the split."""
    import jax

    from jaxmotion.data.crop import crop_spec_from_config
    from jaxmotion.grounding import AdmChooser, find_region
    from jaxmotion.scene import load_scene

    spec = crop_spec_from_config(pipe.amdm_config)
    files = sorted((Path(data_dir) / "samples" / split).glob("*.npz"))
    scenes = sorted({str(np.load(f)["scene_id"]) for f in files})
    out = []
    for i, sid in enumerate(scenes):
        room = load_scene(Path(data_dir) / "scenes" / f"{sid}.npz")
        for j, text in enumerate(TILE_TEXTS):
            key = jax.random.fold_in(jax.random.key(seed), i * len(TILE_TEXTS) + j)
            centre, chosen, _ = find_region(room, text, "adm", spec, adm=AdmChooser(
                lambda: pipe, embs[text], lambda k=key: k, sampler, seed + i))
            out.append((np.asarray(centre), chosen))
    return out


def main(argv=None) -> int:
    from jaxmotion.constants import TEXT_ENCODER
    from jaxmotion.diffusion import SamplerSpec
    from jaxmotion.eval.region_probe import case_regions
    from jaxmotion.pipelines.affordance import AffordancePipeline
    from jaxmotion.pipelines.checkpoints import default_checkpoints, text_adm_for
    from jaxmotion.text import load_text_encoder

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", required=True)
    ap.add_argument("--split", default="val")
    ap.add_argument("--cases", type=int, default=300)
    ap.add_argument("--steps", default="1,2,3", help="step counts to compare with 5")
    ap.add_argument("--guidance", type=float, default=5.0)
    args = ap.parse_args(argv)
    adm, amdm = default_checkpoints()
    pipe = AffordancePipeline.from_workdirs(text_adm_for(adm), amdm)
    encoder = load_text_encoder(TEXT_ENCODER)
    embs = {t: pipe.embed_text([t], encoder) for t in TILE_TEXTS}  # once for every run
    runs = [(5, 0), (5, 1), *((int(s), 0) for s in args.steps.split(","))]
    cands, tiles = {}, {}
    for steps, seed in runs:
        t = time.perf_counter()
        sampler = SamplerSpec("ddim", steps, guidance=args.guidance)
        cands[steps, seed] = [r for r in case_regions(
            args.data, args.split, pipe, num_cases=args.cases, grounding="adm",
            sampler=sampler, seed=seed) if r["named"] > 1]
        tiles[steps, seed] = tile_regions(args.data, args.split, pipe, embs, sampler, seed)
        print(f"  {steps} steps, seed {seed}: {time.perf_counter() - t:.0f} s", flush=True)
    base_c, base_t = cands[5, 0], tiles[5, 0]
    print(f"{len(base_c)} cases with several objects of the named class, {len(base_t)} room x "
          f"text cases naming none ({args.split}, guidance {args.guidance:g})")
    print("| steps, seed | meant object (candidates) | = 5 steps' choice (candidates) "
          "| = 5 steps' object (tiles) | centre within 0.5 m (tiles) |")
    print("|---|---|---|---|---|")
    for run in runs:
        c, t = cands[run], tiles[run]
        hit = np.mean([r["chosen"] == r["target"] for r in c])
        agree = np.mean([a["chosen"] == b["chosen"] for a, b in zip(base_c, c, strict=True)])
        same = np.mean([a[1] == b[1] for a, b in zip(base_t, t, strict=True)])
        near = np.mean([np.linalg.norm(a[0] - b[0]) < 0.5 for a, b in zip(base_t, t, strict=True)])
        print(f"| {run[0]}, {run[1]} | {100 * hit:.1f} % | {100 * agree:.1f} % | "
              f"{100 * same:.1f} % | {100 * near:.1f} % |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
