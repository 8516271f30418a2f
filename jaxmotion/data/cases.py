"""Dataset cases as pipeline inputs: crops of a split's samples as the models were trained on.

:func:`load_cases` reads the first cases of a split (crops as in training, no rotation, padded
to the model's ``max_frames``, with the target's masks for the metrics); :func:`case_inputs`
stacks some of them into a batch for :meth:`jaxmotion.pipelines.AffordancePipeline.sample`.
The eval runner, the probes and the ADM's training probe read cases through here.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

__all__ = ["case_inputs", "load_cases"]


def load_cases(data_dir, split: str, model_config: dict, *, num_cases: int | None = None,
               seed: int = 0, num_points: int | None = None,
               adm_config: dict | None = None, centres=None) -> tuple[list[dict], Any]:
    """The first ``num_cases`` samples of a split as model inputs: crops as in training (the
    AMDM run's ``crop`` config, no rotation), padded to its ``max_frames``. Each case: ``text``,
    ``action``, ``points``, ``colors``, ``mask``, ``gt`` joints, ``target_mask`` (the target
    instance's points), ``target_class_mask`` (the points of every object of the target's
    semantic class, as the grounding metrics of the paper use; the instance when the scene
    has no semantic labels), ``instance`` (the crop points' instance ids), ``objects`` (the
    room's object table, a list of dicts, empty when the scene has none), ``target_id``,
    ``rotation``,
    ``shift`` (``x_world = x_crop @ rotation + shift``), ``file``, ``normals`` (the crop points'
    normals, crop frame), ``betas`` (the sample's body shape).

    ``centres``: one xy crop centre per case (world frame) replacing the crop's placement
    around the motion, e.g. where ``jaxmotion generate`` would crop
    (:func:`jaxmotion.eval.region_probe.case_regions`). The crop may then miss the target, so
    each case also gets ``goal_points``: as many of the target's points in the whole room as
    the crop has points, in the crop frame."""
    import json

    from jaxmotion.data.crop import crop_sample, crop_spec_from_config
    from jaxmotion.data.format import load_sample

    spec = crop_spec_from_config(model_config, **({"num_points": num_points} if num_points
                                                  else {}))
    view_spec = None
    if adm_config is not None and adm_config.get("crop", {}).get("centre") == "room":
        view_spec = crop_spec_from_config(adm_config)
    max_frames = int(model_config["max_frames"])
    files = sorted((Path(data_dir) / "samples" / split).glob("*.npz"))[:num_cases]
    if not files:
        raise FileNotFoundError(f"{Path(data_dir) / 'samples' / split}: no samples; build a "
                                "dataset with `jaxmotion synth --out DIR`")
    if centres is not None and len(centres) != len(files):
        raise ValueError(f"load_cases: {len(centres)} crop centres for {len(files)} cases")
    cases = []
    for i, f in enumerate(files):
        s = load_sample(f)
        with np.load(Path(data_dir) / "scenes" / f"{s['scene_id']}.npz") as sc:
            xyz, rgb, inst = sc["xyz"], sc["rgb"], sc["instance"]
            normal = sc["normal"] if "normal" in sc.files else np.zeros_like(xyz)
            sem = sc["semantic"] if "semantic" in sc.files else None
            objects = json.loads(str(sc["objects"])) if "objects" in sc.files else []
        c = crop_sample(np.random.default_rng([seed, i]), xyz, rgb, inst, s["joints"], s["mask"],
                        s["target_id"], spec,
                        centre=None if centres is None else centres[i])
        class_of = lambda crop: crop.target_mask  # noqa: E731  (no labels: the instance)
        on_target = inst == s["target_id"]
        if sem is not None and on_target.any():
            labels, counts = np.unique(sem[on_target], return_counts=True)
            target_class = labels[np.argmax(counts)]
            class_of = lambda crop: sem[crop.indices] == target_class  # noqa: E731
        class_mask = class_of(c)
        t = min(len(s["mask"]), max_frames)
        mask = np.zeros(max_frames, bool)
        mask[:t] = s["mask"][:t]
        gt = np.zeros((max_frames, 22, 3), np.float32)
        gt[:t] = c.joints[:t]
        goal = {}
        if centres is not None:
            on = np.flatnonzero(on_target)
            if len(on) == 0:
                raise ValueError(f"{f.name}: the target object {int(s['target_id'])} has no "
                                 "point in its scene; rebuild the dataset")
            n = len(c.points)
            pick = np.random.default_rng([seed, i, 2]).choice(on, n, replace=len(on) < n)
            goal["goal_points"] = ((xyz[pick] - c.shift) @ c.rotation.T).astype(np.float32)
        view = None
        if view_spec is not None:
            v = crop_sample(np.random.default_rng([seed, i, 1]), xyz, rgb, inst, s["joints"],
                            s["mask"], s["target_id"], view_spec)
            in_crop = ((v.to_world(v.points) - c.shift) @ c.rotation.T).astype(np.float32)
            view = dict(points=v.points, colors=v.colors, in_crop=in_crop,
                        instance=inst[v.indices], target_mask=v.target_mask,
                        target_class_mask=class_of(v))
        cases.append(dict(text=str(s["text"]), action=str(s["action"]), points=c.points,
                          colors=c.colors, mask=mask, gt=gt, target_mask=c.target_mask,
                          target_class_mask=class_mask, instance=inst[c.indices],
                          objects=objects, rotation=c.rotation, shift=c.shift, file=f.name,
                          view=view, target_id=int(s["target_id"]),
                          normals=(normal[c.indices] @ c.rotation.T).astype(np.float32),
                          betas=np.asarray(s["betas"], np.float32), **goal))
    return cases, spec


def case_inputs(cases: list[dict], idx) -> dict:
    """The pipeline's inputs for cases ``idx`` (as :func:`load_cases` makes them), stacked:
    ``points``, ``colors``, ``mask``, ``normals``, ``betas``, ``view`` (stacked, or None
    without views) and ``exclude`` (stacked, or None when the cases have none)."""
    stack = lambda get: np.stack([get(cases[i]) for i in idx])  # noqa: E731
    exclude = None
    if cases[idx[0]].get("exclude") is not None:
        exclude = stack(lambda c: c["exclude"])
    view = None
    if cases[idx[0]].get("view") is not None:
        view = {k: stack(lambda c, k=k: c["view"][k]) for k in ("points", "colors", "in_crop")}
    return {"points": stack(lambda c: c["points"]), "colors": stack(lambda c: c["colors"]),
            "mask": stack(lambda c: c["mask"]), "view": view, "exclude": exclude,
            "normals": stack(lambda c: c["normals"]), "betas": stack(lambda c: c["betas"])}
