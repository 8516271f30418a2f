"""Does an ADM read the spatial relation of an instruction, or only the object's class?

For every case whose crop holds several objects of the target's class and whose text
uses "closest" or "farthest", the instruction is rewritten in two canonical forms with
the same action, class and anchor: the true relation ("sit on the chair closest to the
fridge") and the opposite one ("sit on the chair farthest from the fridge"). The ADM
samples a map for the original text and for both rewrites on the same crop with the same
noise, and each map is scored by success@0.3 against the target *instance*. An ADM that
reads the relation hits the target with the true form and misses it with the opposite
one; an ADM that ignores it hits the target equally often with both.

The crop is a 4 m square around the motion, and the anchor often lies outside it: then no
model that sees only the crop can resolve the relation. The rates are therefore also given
for the cases whose crop holds an object of the anchor's class (``anchor_visible``). A
room-view ADM (``crop.centre=room``) is probed on its view of the whole room instead, where
the case selection and ``anchor_visible`` use the view too.

    python -m jaxmotion.eval.relation_probe --data data/synth --adm A --amdm M

(``A``, ``M``: training workdirs or ``.safetensors``; the AMDM only supplies the crop
settings, as in ``jaxmotion eval``.) Instructions are read by the reader ``generate`` uses
(:func:`jaxmotion.grounding.target.read_instruction`), so datasets of either phrasing
(``jaxmotion synth --phrasing default|rich``) are probed; a "sit at the desk closest to …"
(the seat at an object) is left out, its relation being about the desk, not the seat.
"""

from __future__ import annotations

import argparse
import json
import sys

import numpy as np

__all__ = ["anchor_visible", "canonical_pair", "relation_probe"]

_PHRASE = {"closest": "closest to the {a}", "farthest": "farthest from the {a}"}
_OPPOSITE = {"closest": "farthest", "farthest": "closest"}


def canonical_pair(text: str) -> tuple[str, str] | None:
    """``(true form, opposite form)`` of a "closest" / "farthest" instruction, else None."""
    from jaxmotion.scene.instructions import simple_text

    ref, action = _reference(text)
    if ref is None or ref.relation not in _PHRASE or len(ref.anchors) != 1:
        return None
    base = simple_text(action, ref.target)
    true = f"{base} {_PHRASE[ref.relation].format(a=ref.anchors[0])}"
    return true, f"{base} {_PHRASE[_OPPOSITE[ref.relation]].format(a=ref.anchors[0])}"


def _reference(text):
    """``(Reference, action)`` of an instruction as ``generate`` reads it; ``(None, None)``
    when it names no class or no action, or asks for the seat at an object."""
    from jaxmotion.grounding.target import read_instruction

    ins = read_instruction(text)
    if ins.action is None or ins.reference is None or ins.reading.seat_at:
        return None, None
    return ins.reference, ins.action


def relation_probe(data_dir, adm, amdm, *, splits=("val", "test"), num_cases: int = 400,
                   steps: int = 20, guidance: float = 5.0, seed: int = 0,
                   batch_size: int = 32) -> dict:
    """Run the probe (module docstring) over the first ``num_cases`` of each split.

    Returns ``{"cases": n, "hit_original", "hit_true", "hit_opposite", "hit_both"}``: the
    fractions of the ``n`` probed cases whose map hits the target instance (NaN when no case
    qualifies), plus the settings, ``anchor_visible_cases`` and, when there are such cases,
    ``anchor_visible``: the four rates over them alone.
    """
    import jax

    from jaxmotion.data.cases import load_cases
    from jaxmotion.diffusion import SamplerSpec
    from jaxmotion.eval.metrics import affordance_grounding_from_map
    from jaxmotion.pipelines.affordance import AffordancePipeline
    from jaxmotion.text import load_text_encoder

    pipe = AffordancePipeline.from_workdirs(adm, amdm)
    picked = []
    for split in splits:
        cases, _ = load_cases(data_dir, split, pipe.amdm_config, num_cases=num_cases, seed=seed,
                              adm_config=pipe.adm_config)
        for c in cases:
            seen = _adm_input(c)
            if seen["target_class_mask"].sum() <= seen["target_mask"].sum():
                continue  # the only object of its class the ADM sees: nothing to choose
            pair = canonical_pair(c["text"])
            if pair is not None:
                picked.append((seen, c["text"], *pair))
    visible = np.array([anchor_visible(p[0]) for p in picked], bool)
    out = {"cases": len(picked), "splits": list(splits), "num_cases": num_cases, "steps": steps,
           "guidance": guidance, "seed": seed}
    if not picked:
        return {**out, **{k: float("nan") for k in
                          ("hit_original", "hit_true", "hit_opposite", "hit_both")}}
    encoder = load_text_encoder("minilm")
    spec = SamplerSpec("ddim", int(steps), guidance=float(guidance))
    hits = np.zeros((3, len(picked)))
    for lo in range(0, len(picked), batch_size):
        chunk = picked[lo:lo + batch_size]
        pts = np.stack([p[0]["points"] for p in chunk])
        col = np.stack([p[0]["colors"] for p in chunk])
        key = jax.random.fold_in(jax.random.key(seed), lo)
        for form in range(3):  # original, true, opposite: the same crop and noise for each
            emb = pipe.embed_text([p[1 + form] for p in chunk], encoder)
            maps = np.asarray(pipe.sample_affordance(key, pts, col, emb, spec))
            for i, p in enumerate(chunk):
                g = affordance_grounding_from_map(maps[i], p[0]["target_mask"])
                hits[form, lo + i] = float(jax.device_get(g)["success@0.3"])
    res = {**out, **_rates(hits), "anchor_visible_cases": int(visible.sum())}
    if visible.any():
        res["anchor_visible"] = _rates(hits[:, visible])
    return res


def _adm_input(case) -> dict:
    """What the ADM reads for a case: its room view when it has one, else the crop (with the
    text and the room's object table either way)."""
    if case.get("view") is None:
        return case
    return {**case["view"], "text": case["text"], "objects": case["objects"]}


def _rates(hits) -> dict:
    return {"hit_original": float(hits[0].mean()), "hit_true": float(hits[1].mean()),
            "hit_opposite": float(hits[2].mean()), "hit_both": float((hits[1] * hits[2]).mean())}


def anchor_visible(case, min_points: int = 5) -> bool:
    """Whether an object of the anchor's class has at least ``min_points`` points in the case's
    crop (or the ADM's view): only then can any model that sees the crop resolve "closest /
    farthest from it"."""
    ref, _ = _reference(case["text"])
    if ref is None or not ref.anchors:
        return False
    ids = [o["id"] for o in case.get("objects", ()) if o["category"] in ref.anchors[:1]]
    return any(int((case["instance"] == i).sum()) >= min_points for i in ids)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", required=True, help="dataset folder (jaxmotion synth)")
    ap.add_argument("--adm", required=True, help="ADM workdir or .safetensors")
    ap.add_argument("--amdm", required=True, help="AMDM workdir or .safetensors (crop settings)")
    ap.add_argument("--splits", default="val,test", help="comma-separated (default val,test)")
    ap.add_argument("--cases", type=int, default=400, help="first cases of each split (400)")
    ap.add_argument("--steps", type=int, default=20, help="DDIM steps (20)")
    ap.add_argument("--guidance", type=float, default=5.0, help="ADM guidance scale (5)")
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args(argv)
    r = relation_probe(args.data, args.adm, args.amdm, splits=tuple(args.splits.split(",")),
                       num_cases=args.cases, steps=args.steps, guidance=args.guidance,
                       seed=args.seed)
    print(f"{r['cases']} cases with several objects of the target's class and a closest / "
          "farthest relation; the ADM's map hits the target instance (success@0.3):")
    for name, k in (("original text", "hit_original"), ("canonical, true relation", "hit_true"),
                    ("canonical, opposite relation", "hit_opposite"),
                    ("both canonical forms", "hit_both")):
        sub = r.get("anchor_visible", {}).get(k, float("nan"))
        print(f"  {name:<30} {100 * r[k]:5.1f} %   anchor in the crop: {100 * sub:5.1f} %")
    print(f"(the anchor's class is in the crop in {r.get('anchor_visible_cases', 0)} of the "
          f"{r['cases']} cases; elsewhere no model that sees only the crop can resolve the "
          "relation)")
    print(json.dumps(r))
    return 0


if __name__ == "__main__":
    sys.exit(main())
