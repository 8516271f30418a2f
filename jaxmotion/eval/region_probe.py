"""Does ``jaxmotion generate`` find the object an instruction is about?

``jaxmotion eval`` scores the models on crops placed around the dataset's motion, as the papers
do; the crop's placement alone then tells a lot about where the target is (the object of the
target's class nearest to the crop's centre is the target in about 9 cases out of 10 on the
synthetic validation split). ``generate`` has no such crop: it must find the region in the
whole room. This probe runs generate's region choice (:func:`jaxmotion.generation
.candidate_objects`, then the ADM among the candidates: the very code ``generate`` runs) on a
split's rooms and instructions and counts how often the chosen object is the target:

- ``hit``: over all cases; ``hit_multi``: over the cases whose room has several objects of
  the named class (the only ones where there is a choice to make);
- ``chance`` / ``chance_multi``: the same rates for a uniform pick among the candidates of
  the named class (what an ADM that ignores everything but the class would reach).

    python -m jaxmotion.eval.region_probe --data data/synth --split val --cases 200 \\
        [--adm A --amdm M] [--grounding auto|adm]

(``A``, ``M``: ADM / AMDM workdirs or ``.safetensors``; default the shipped ones.)
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

from jaxmotion.options import DEFAULT_ADM_STEPS, DEFAULT_GUIDANCE

__all__ = ["case_regions", "region_probe"]


def case_regions(data_dir, split: str, pipe, *, num_cases: int | None = None,
                 grounding: str = "auto", sampler=None, seed: int = 0,
                 progress: bool = False) -> list[dict]:
    """Where ``jaxmotion generate`` would centre its crop for each of the first ``num_cases``
    cases of a split, given only the room and the instruction (the very code ``generate``
    runs: :func:`jaxmotion.grounding.find_region`; among several candidates the room's free
    floor chooses, or with ``grounding="adm"`` the pipeline's ADM). ``sampler``: the ADM's
    (default generate's: DDIM, its steps and guidance).

    Returns per case ``centre`` (xy, world), ``chosen`` (object id or None), ``how``
    (:attr:`jaxmotion.result.Generation.grounding`), ``target`` (the dataset's target id),
    ``named`` (how many objects of the named class the room has) and ``has_target`` (the
    target is among them)."""
    import jax
    from tqdm.auto import tqdm

    from jaxmotion.constants import TEXT_ENCODER
    from jaxmotion.data.crop import crop_spec_from_config
    from jaxmotion.data.format import load_sample
    from jaxmotion.diffusion import SamplerSpec
    from jaxmotion.grounding import AdmChooser, find_region, mentioned_objects
    from jaxmotion.grounding.region import room_view_maps
    from jaxmotion.options import GROUNDINGS
    from jaxmotion.scene import load_scene
    from jaxmotion.text import load_text_encoder

    if grounding not in GROUNDINGS:
        raise ValueError(f"grounding must be one of {', '.join(GROUNDINGS)}, got {grounding!r}")
    files = sorted((Path(data_dir) / "samples" / split).glob("*.npz"))[:num_cases]
    if not files:
        raise FileNotFoundError(f"{Path(data_dir) / 'samples' / split}: no samples; build a "
                                "dataset with `jaxmotion synth --out DIR`")
    spec = crop_spec_from_config(pipe.amdm_config)
    sampler = sampler if sampler is not None else SamplerSpec(
        "ddim", DEFAULT_ADM_STEPS, guidance=DEFAULT_GUIDANCE[0])
    encoder = load_text_encoder(TEXT_ENCODER)
    out = []
    for i, f in enumerate(tqdm(files, desc="regions", disable=not progress)):
        s = load_sample(f)
        room = load_scene(Path(data_dir) / "scenes" / f"{s['scene_id']}.npz")
        text, target = str(s["text"]), int(s["target_id"])
        named = mentioned_objects(room, text)
        emb = pipe.embed_text([text], encoder)
        key = jax.random.fold_in(jax.random.key(seed), i)
        view = None
        if pipe.room_view:
            view = room_view_maps(room, pipe.adm_config, jax.tree.map(lambda a: a[0], emb),
                                  key, sampler, 1, seed + i, None, "", lambda: pipe)
        centre, chosen, how = find_region(
            room, text, grounding, spec, view=view,
            adm=AdmChooser(lambda: pipe, emb, lambda k=key: k, sampler, seed + i), seed=seed + i)
        out.append({"centre": np.asarray(centre, np.float64), "chosen": chosen, "how": how,
                    "target": target, "named": len(named),
                    "has_target": any(o["id"] == target for o in named)})
    return out


def region_probe(data_dir, adm=None, amdm=None, *, split: str = "val", num_cases: int = 200,
                 grounding: str = "auto", steps: int = DEFAULT_ADM_STEPS,
                 guidance: float = DEFAULT_GUIDANCE[0], seed: int = 0,
                 progress: bool = False) -> dict:
    """Run the probe (module docstring); returns the rates, the counts and the settings."""
    from jaxmotion.diffusion import SamplerSpec
    from jaxmotion.pipelines.affordance import AffordancePipeline
    from jaxmotion.pipelines.checkpoints import default_checkpoints, text_adm_for

    if grounding not in ("auto", "adm"):
        raise ValueError(f"grounding must be 'auto' or 'adm', got {grounding!r}")
    default_adm, default_amdm = default_checkpoints()
    adm = adm or text_adm_for(default_adm)  # generate's ADM when no target is known
    pipe = AffordancePipeline.from_workdirs(adm, amdm or default_amdm)
    regions = case_regions(data_dir, split, pipe, num_cases=num_cases, grounding=grounding,
                           sampler=SamplerSpec("ddim", int(steps), guidance=float(guidance)),
                           seed=seed, progress=progress)
    rows = [(r["chosen"] == r["target"], r["named"] > 1,
             (1.0 / r["named"]) if r["has_target"] else 0.0) for r in regions]
    hit, multi, chance = (np.array(c, float) for c in zip(*rows, strict=True))
    multi = multi.astype(bool)
    rate = lambda x, m: float(x[m].mean()) if m.any() else float("nan")
    return {"cases": len(rows), "multi_cases": int(multi.sum()),
            "hit": float(hit.mean()), "hit_multi": rate(hit, multi),
            "chance": float(chance.mean()), "chance_multi": rate(chance, multi),
            "split": split, "grounding": grounding, "adm": str(adm),
            "room_view": pipe.room_view, "steps": steps, "guidance": guidance, "seed": seed}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", required=True, help="dataset folder (jaxmotion synth)")
    ap.add_argument("--adm", default=None, help="ADM workdir or .safetensors (default: the "
                    "shipped ADM generate chooses regions with)")
    ap.add_argument("--amdm", default=None, help="AMDM workdir or .safetensors (default: shipped)")
    ap.add_argument("--split", default="val")
    ap.add_argument("--cases", type=int, default=200, help="first cases of the split (200)")
    ap.add_argument("--grounding", choices=("auto", "adm"), default="auto")
    ap.add_argument("--steps", type=int, default=DEFAULT_ADM_STEPS,
                    help=f"DDIM steps of the ADM (default generate's, {DEFAULT_ADM_STEPS})")
    ap.add_argument("--guidance", type=float, default=DEFAULT_GUIDANCE[0],
                    help=f"ADM guidance scale ({DEFAULT_GUIDANCE[0]:g})")
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args(argv)
    r = region_probe(args.data, args.adm, args.amdm, split=args.split, num_cases=args.cases,
                     grounding=args.grounding, steps=args.steps, guidance=args.guidance,
                     seed=args.seed, progress=True)
    print(f"generate's region choice (grounding={r['grounding']}) picks the target object in "
          f"{100 * r['hit']:.1f} % of {r['cases']} cases (chance {100 * r['chance']:.1f} %); "
          f"with several objects of the named class in the room ({r['multi_cases']} cases): "
          f"{100 * r['hit_multi']:.1f} % (chance {100 * r['chance_multi']:.1f} %)")
    print(json.dumps(r))
    return 0


if __name__ == "__main__":
    sys.exit(main())
