"""``jaxmotion eval``: run checkpoints over a split, K samples per case, R replications.

For every model (an ADM + AMDM pair and a sampler) and every replication ``r`` (seed
``(seed, r)``), each case of the split is sampled ``K`` times on the crop the models were
trained on (no rotation), then scored:

- **physical** (the paper's Table 2 columns): goal distance at the anchor frame, contact
  (s > −5 cm), non-collision, APD over the K samples and foot skating. With ``body=True``
  (default) SMPL-X bodies are fitted to the joints (:func:`jaxmotion.body.fit_joints_to_body`)
  and the mannequin mesh gives the signed distances, as the papers do with SMPL-X (every
  ``vertex_stride``-th vertex, default 4: 6,064 of 24,256, about 2 cm apart; the mesh
  distances cost T·N·V per sample, 20+ s per case on 2 CPU cores with every vertex); with
  ``body=False`` the joints-only sphere body (:mod:`jaxmotion.eval.joint_spheres`) is used.
- **grounding** (Table 3): min / pelvis / all distance and success at 0.1 / 0.3 / 0.5 m of the
  ADM maps against the points of the target's semantic class (the paper's definition: any
  chair counts for "sit on the chair ..."), plus the stricter success at 0.3 m against the
  target instance only (two-stage models only).
- **text–motion** (with an evaluator, :mod:`jaxmotion.eval.evaluator`): FID, R-precision
  top 1/2/3, MultiModal distance, Diversity, MultiModality (K ≥ 2), and a "real" row from the
  ground truth.
- **action** (with a recognizer, :mod:`jaxmotion.eval.recognizer`; the object-centric paper's
  Table 1): action accuracy (``action_recognized``), and on the recognizer's penultimate-layer
  features ``rec_fid`` (each of the K sample sets against the dataset's motions of the same
  cases, averaged), ``rec_diversity`` (random pairs, as Diversity above) and
  ``rec_multimodality`` (pairs among each case's K samples, K ≥ 2; the paper pairs motions of
  the same action class instead), with the dataset's own ``rec_diversity`` in the "real" row.
  FID, diversity and multimodality are numbers of a whole sample set: they are in
  ``results.json`` (per replication and summary), not in ``cases.jsonl``.

**Protocols.** ``protocol="paper"`` (default) crops each case around the dataset's motion, as
the papers do; where that crop sits then tells much of where the target is (the object of the
target's class nearest to its centre is the target in ~9 of 10 synthetic validation cases).
``protocol="generate"`` crops where ``jaxmotion generate`` would, from the room and the text
alone (:func:`jaxmotion.eval.region_probe.case_regions`: the named objects, narrowed by the
scene graph with ``grounding="auto"``, then the ADM among what is left); the goal distance is
then measured against the target's points in the whole room (a wrong region is a long
distance, not a missing value), the instance success is 0 when the target is outside the crop,
and each model's ``regions`` say how often the region was centred on the target.
``protocol="text"`` is text to motion with a floor on converted HumanML3D (the affordance
paper's Table 1, :mod:`jaxmotion.eval.text_protocol`): it needs an evaluator, scores the
joints alone (no bodies) at the data's frame rate, and leaves out the columns that need a
target object or furniture (:data:`~jaxmotion.eval.text_protocol.NOT_APPLICABLE`, grounding,
action).

A row with ``affordance=gt`` feeds the AMDM the ground-truth affordance maps (from the
dataset's motion) instead of the ADM's, with the same motion noise as the ADM row: the gap
between the two rows is the part of the error that comes from the ADM.

Per replication a metric is the mean over cases (and samples); the report gives the mean over
replications ± the 95 % interval ``1.96 σ / √R`` (the HumanML3D convention).
"""

from __future__ import annotations

import dataclasses
import functools
import json
import math
import time
from pathlib import Path

import numpy as np

from jaxmotion.constants import SCENE_FPS, TEXT_ENCODER
from jaxmotion.errors import GenerateError
from jaxmotion.eval.text_protocol import (
    NOT_APPLICABLE,
    check_text_data,
    format_table1,
    mean_ci_cell,
)
from jaxmotion.options import GROUNDINGS, check_candidates, check_consistency

__all__ = ["ModelSpec", "evaluate", "format_markdown", "parse_model", "write_report"]

PHYSICAL = ("goal_distance", "contact", "non_collision", "apd", "skating")
#: Per-case plausibility columns (means over the case's K motions; jaxmotion.eval.plausibility)
#: and, per replication, the percentiles over every motion (``pelvis_speed_p99``).
PLAUSIBILITY = ("teleport", "pelvis_speed_max", "joint_speed_max", "jerk_mean",
                "floor_penetration")
GROUNDING = ("min_dist", "pelvis_dist", "all_dist", "success@0.1", "success@0.3", "success@0.5")
TEXT_MOTION = ("fid", "r_precision_top1", "r_precision_top2", "r_precision_top3",
               "multimodal_dist", "diversity", "multimodality")
#: On the action recognizer's features (the object-centric paper's Table 1), with a recognizer.
RECOGNIZER_SET = ("rec_fid", "rec_diversity", "rec_multimodality")


@dataclasses.dataclass(frozen=True)
class ModelSpec:
    """One row: a name, the ADM and AMDM (workdirs or ``.safetensors``), the sampler and
    the classifier-free guidance scale of each stage (1 = none)."""

    name: str
    adm: str
    amdm: str
    method: str = "ddim"
    steps: int = 50
    adm_guidance: float = 1.0
    amdm_guidance: float = 1.0
    affordance: str = "adm"  # "gt": the AMDM gets ground-truth maps (an oracle row)
    consistency: float = 0.0  # affordance-consistency guidance strength of the AMDM (0 = off)
    adm_candidates: int = 1  # ADM maps per sample; the one lighting the known target is kept
    adm_steps: int | None = None  # DDIM steps of the ADM stage (None: ``steps``)
    motion_candidates: int = 1  # motions per map; the one reaching the known target is kept
    trajectory: str | None = None  # with completion: the object-centric pipeline samples the row
    completion: str | None = None  # (the ADM still finds the generate protocol's regions)
    keep_trajectory: bool = True  # object-centric: the completion holds the stage-1 trajectory
    anchor: float = 1.0  # object-centric: anchor guidance strength on the trajectory (0 = off)
    standing: float = 1.0  # object-centric: standing-height guidance on the trajectory (0 = off)
    feet: float = 1.0  # object-centric: foot guidance strength on the completion (0 = off)
    traj_sensor: str = "trajectory"  # object-centric: where the trajectory sensor sits
    cvae: str | None = None  # the HUMANISE cVAE samples the row (the ADM, AMDM set the crops)

    @property
    def object_centric(self) -> bool:
        return self.trajectory is not None

    @property
    def pipeline(self) -> str:
        """Which pipeline samples the row's motions: affordance, object-centric or cvae."""
        return ("object-centric" if self.object_centric else
                "cvae" if self.cvae is not None else "affordance")

    @property
    def sampler_label(self) -> str:
        if self.cvae is not None:
            return "cVAE (one latent z ~ N(0, I) per motion)"
        label = "DDPM (all steps)" if self.method == "ddpm" else f"DDIM-{self.steps}"
        if self.object_centric:
            label = "object-centric, " + label
            if not self.keep_trajectory:
                label += " (completion writes its own trajectory)"
            if self.traj_sensor != "trajectory":
                label += " (trajectory sensor on the noisy estimate)"
            for name, strength in (("anchor", self.anchor), ("standing", self.standing),
                                   ("foot", self.feet)):
                if strength != 1.0:
                    label += (f" (no {name} guidance)" if strength == 0
                              else f" ({name} guidance {strength:g})")
        guided = [f"{stage} w={g:g}" for stage, g in
                  (("ADM", self.adm_guidance), ("AMDM", self.amdm_guidance)) if g != 1.0]
        if self.consistency:
            guided.append(f"consistency {self.consistency:g}")
        if self.affordance == "gt":
            guided.append("ground-truth maps")
        if self.adm_steps is not None and self.method == "ddim":
            guided.append(f"ADM DDIM-{self.adm_steps}")
        if self.adm_candidates > 1:
            guided.append(f"best of {self.adm_candidates} ADM maps")
        if self.motion_candidates > 1:
            guided.append(f"best of {self.motion_candidates} motions")
        return label + (f" ({', '.join(guided)})" if guided else "")


def _checked(text: str, check, *args):
    """``check(*args)`` (a :mod:`jaxmotion.options` check) with the ``--model`` text named in
    its error."""
    try:
        return check(*args)
    except GenerateError as e:
        raise ValueError(f"--model {text!r}: {e}") from None


def parse_model(text: str) -> ModelSpec:
    """``NAME=ADM,AMDM[,ddimN|ddpm][,adm_guidance=G][,amdm_guidance=G][,consistency=S]
    [,affordance=adm|gt][,adm_candidates=C][,adm_steps=N][,motion_candidates=M]
    [,trajectory=T,completion=C[,keep_trajectory=1|0][,anchor=S][,standing=S][,feet=S]
    [,traj_sensor=trajectory|estimate]][,cvae=W]`` → :class:`ModelSpec` (the
    ``--model`` syntax). ``adm_steps``: DDIM steps of the ADM stage when they differ from the
    sampler's (as ``jaxmotion generate --adm-steps``).
    ``adm_candidates`` (generate protocol only): C ADM maps per sample, the one lighting the
    region's object most is kept, as ``jaxmotion generate --adm-candidates``;
    ``motion_candidates`` (generate protocol only): M motions per map, the one that comes closest
    to the region's object at the anchor frame is kept, as ``jaxmotion generate
    --motion-candidates``. ``consistency``: the
    strength in [0, 1] of affordance-consistency guidance on the AMDM (0, the default, = off).
    ``affordance=gt`` feeds the AMDM the ground-truth affordance maps instead of the ADM's: the
    row then measures the AMDM alone. ``trajectory`` and ``completion`` (workdirs or files,
    both or neither): the object-centric pipeline samples the row's motions (the sampler and
    ``amdm_guidance`` apply to both of its stages), while the ADM and AMDM still set the
    crops and find the generate protocol's regions; ``keep_trajectory=0`` lets the completion
    model write its own trajectory (the authors' way) instead of holding the stage-1 one;
    ``anchor`` is the strength in [0, 1] of the trajectory stage's anchor guidance (default 1;
    0 = off, :mod:`jaxmotion.diffusion.anchor_guidance`), ``standing`` of its standing-height
    guidance (the same module) and ``feet`` of the completion stage's foot guidance
    (:mod:`jaxmotion.diffusion.foot_guidance`), both default 1; ``traj_sensor`` (a
    completion model trained with ``model.traj_sensor=true``): the trajectory sensor on the
    stage-1 trajectory (``trajectory``, the default) or on the noisy sample's trajectory at
    every step (``estimate``, the authors' code). ``cvae`` (a ``configs/cvae.py``
    run's workdir or weights file): the HUMANISE cVAE samples the row's motions, one latent
    per motion, in the crops the ADM and AMDM set (as ``generate --pipeline cvae``); the
    sampler options then do not apply."""
    name, sep, rest = text.partition("=")
    usage = (f"--model {text!r}: expected NAME=ADM,AMDM[,ddimN|ddpm][,adm_guidance=G]"
             "[,amdm_guidance=G][,consistency=S][,affordance=adm|gt], e.g. "
             "two_stage=runs/adm,runs/amdm,ddim50")
    parts = rest.split(",")
    options = [p for p in parts[2:] if "=" in p]
    positional = [p for p in parts if "=" not in p]
    if not sep or not name or len(positional) not in (2, 3) or not all(parts) \
            or parts[:len(positional)] != positional:
        raise ValueError(usage)
    method, steps = "ddim", 50
    if len(positional) == 3:
        s = positional[2].lower()
        if s == "ddpm":
            method = "ddpm"
        elif s.startswith("ddim") and s[4:].isdigit() and int(s[4:]) > 0:
            steps = int(s[4:])
        else:
            raise ValueError(f"--model {text!r}: sampler {positional[2]!r} is not ddimN (N > 0) "
                             "or ddpm")
    guidance = {"adm_guidance": 1.0, "amdm_guidance": 1.0}
    affordance, consistency, candidates, adm_steps, motions = "adm", 0.0, 1, None, 1
    objects = {}
    for opt in options:
        key, _, value = opt.partition("=")
        if key in ("trajectory", "completion", "cvae"):
            objects[key] = value
            continue
        if key == "keep_trajectory":
            if value not in ("0", "1"):
                raise ValueError(f"--model {text!r}: keep_trajectory must be 1 (the completion "
                                 f"model holds the stage-1 trajectory) or 0, got {value!r}")
            objects[key] = value == "1"
            continue
        if key == "traj_sensor":
            from jaxmotion.pipelines.object_centric import TRAJ_SENSOR_PLACEMENTS

            if value not in TRAJ_SENSOR_PLACEMENTS:
                raise ValueError(f"--model {text!r}: traj_sensor must be trajectory (on the "
                                 "stage-1 trajectory) or estimate (on the noisy sample at every "
                                 f"step), got {value!r}")
            objects[key] = value
            continue
        if key in ("anchor", "standing", "feet"):
            try:
                strength = float(value)
            except ValueError:
                strength = -1.0
            if not 0.0 <= strength <= 1.0:
                raise ValueError(f"--model {text!r}: {key} must be a strength in [0, 1] "
                                 f"(0 = no {key} guidance), got {value!r}")
            objects[key] = strength
            continue
        if key in ("adm_candidates", "adm_steps", "motion_candidates"):
            if not value.isdigit() or int(value) < 1:
                raise ValueError(f"--model {text!r}: {key} must be an integer ≥ 1, "
                                 f"got {value!r}")
            if key == "adm_candidates":
                candidates = _checked(text, check_candidates, key, int(value))
            elif key == "motion_candidates":
                motions = _checked(text, check_candidates, key, int(value))
            elif method != "ddim":
                raise ValueError(f"--model {text!r}: adm_steps needs a DDIM sampler (ddimN)")
            else:
                adm_steps = int(value)
            continue
        if key == "consistency":
            consistency = _checked(text, check_consistency, value)
            continue
        if key == "affordance":
            if value not in ("adm", "gt"):
                raise ValueError(f"--model {text!r}: affordance must be adm (the ADM's maps) or "
                                 f"gt (ground-truth maps), got {value!r}")
            affordance = value
            continue
        if key not in guidance:
            raise ValueError(f"--model {text!r}: unknown option {key!r}; valid: "
                             + ", ".join([*guidance, "consistency", "affordance",
                                          "adm_candidates", "adm_steps",
                                          "motion_candidates", "trajectory", "completion",
                                          "keep_trajectory", "anchor", "standing",
                                          "feet", "traj_sensor", "cvae"]))
        try:
            guidance[key] = float(value)
        except ValueError:
            raise ValueError(f"--model {text!r}: {key} must be a number, got {value!r}") from None
        if not guidance[key] > 0:
            raise ValueError(f"--model {text!r}: {key} must be > 0 (1 = no guidance)")
    if "cvae" in objects:
        if set(objects) - {"cvae"}:
            raise ValueError(f"--model {text!r}: a row is sampled by one pipeline: give cvae= "
                             "or trajectory= and completion=, not both")
        if affordance == "gt" or consistency or candidates > 1 or motions > 1:
            raise ValueError(f"--model {text!r}: affordance, consistency, adm_candidates and "
                             "motion_candidates act on the diffusion pipelines; a cvae row "
                             "draws one latent per motion")
    elif objects and not {"trajectory", "completion"} <= set(objects):
        raise ValueError(f"--model {text!r}: the object-centric pipeline needs both "
                         "trajectory=PATH and completion=PATH")
    if objects and (affordance == "gt" or consistency or candidates > 1):
        raise ValueError(f"--model {text!r}: affordance, consistency and adm_candidates act on "
                         "affordance maps, which the object-centric pipeline does not use")
    return ModelSpec(name, positional[0], positional[1], method, steps, **guidance,
                     affordance=affordance, consistency=consistency, adm_candidates=candidates,
                     adm_steps=adm_steps, motion_candidates=motions, **objects)


# --------------------------------------------------------------------------- per case
def physical_fn(body: bool, fps: float):
    """Jitted ``(points, goal_points, goal_mask, joints [K,T,22,3], mask, anchor, verts,
    normals) -> metrics [K]`` (+ APD); the goal distance is measured to the masked
    ``goal_points``, the rest to ``points``."""
    import jax

    from jaxmotion.eval.metrics import (
        apd,
        contact,
        foot_skating,
        goal_distance,
        joint_sphere_sdf_frames,
        joints_goal_distance,
        non_collision,
        signed_distance_to_body_frames,
    )

    def one(points, goal_points, target_mask, joints, mask, anchor, verts, normals):
        if body:
            sdf = signed_distance_to_body_frames(points, verts, normals)
            goal = goal_distance(goal_points, verts[anchor], normals[anchor],
                                 target_mask=target_mask)
        else:
            sdf = joint_sphere_sdf_frames(points, joints)
            goal = joints_goal_distance(goal_points, joints[anchor], target_mask=target_mask)
        skate = foot_skating(joints, mask, fps=fps)
        skate = skate["skate_ratio"]
        return {"goal_distance": goal, "contact": contact(sdf, mask=mask),
                "non_collision": non_collision(sdf, mask), "skating": skate}

    @jax.jit
    def run(points, goal_points, target_mask, joints, mask, anchor, verts, normals):
        per = jax.vmap(one, in_axes=(None, None, None, 0, None, None, 0, 0))(
            points, goal_points, target_mask, joints, mask, anchor, verts, normals)
        per["apd"] = apd(joints, mask)
        return per

    return run


def _bodies(joints, mask, fps: float, stride: int = 1):
    """Fitted mannequin vertices and normals ``[K,T,V/stride,3]`` for joints ``[K,T,22,3]``
    (every ``stride``-th vertex; normals from the full mesh)."""
    from jaxmotion.body import body_forward, fit_joints_to_body, load_mannequin

    fit = fit_joints_to_body(joints, np.broadcast_to(mask, joints.shape[:2]), iters=100, fps=fps)
    out = body_forward(load_mannequin(), fit.global_orient, fit.body_pose, fit.transl)
    return (out.vertices[..., ::stride, :], out.vertex_normals[..., ::stride, :],
            float(np.asarray(fit.mean_error).mean()))


def score_cases(cases, joints, affs, phys, body: bool, fps: float, fit_errors: list, bar,
                 stride: int = 1, recognizer=None):
    """Per-case metric rows for joints ``[C,K,T,22,3]`` (and ADM maps ``affs[c][k]``): the
    physical metrics, plausibility (:data:`PLAUSIBILITY`), the geometric action judge
    (``action_judged``: the K motions' share that do the case's action on its target,
    :mod:`jaxmotion.eval.action_judge`) and, with a ``recognizer``
    (:func:`jaxmotion.eval.recognizer.load_recognizer`), ``action_recognized``."""
    import jax

    from jaxmotion.eval.metrics import affordance_grounding_from_map
    from jaxmotion.eval.plausibility import plausibility

    rows = []
    for ci, c in enumerate(cases):
        mask = c["mask"]
        plaus = jax.device_get(plausibility(
            joints[ci], np.broadcast_to(mask, joints[ci].shape[:2]), fps=fps))
        valid = np.flatnonzero(mask)
        anchor = int(valid[0] if c["action"] == "stand_up" else valid[-1])
        if body:
            verts, normals, err = _bodies(joints[ci], mask, fps, stride)
            fit_errors.append(err)
        else:
            verts = normals = np.zeros((joints.shape[1], 1, 1, 3), np.float32)
        goal_points, goal_mask = c.get("goal_points"), c["target_mask"]
        if goal_points is None:  # the paper protocol: the target's points in the crop
            goal_points = c["points"]
        else:  # the generate protocol: the target's points in the whole room
            goal_mask = np.ones(len(goal_points), bool)
        m = jax.device_get(phys(c["points"], goal_points, goal_mask, joints[ci], mask, anchor,
                                verts, normals))
        row = {k: float(np.mean(v)) for k, v in m.items()}
        row.update({k: float(np.mean(plaus[k])) for k in PLAUSIBILITY})
        row["in_furniture"] = _in_furniture(c, joints[ci])
        row["pelvis_speeds"] = [float(v) for v in np.atleast_1d(plaus["pelvis_speed_max"])]
        row.update(_action_columns(c, joints[ci], recognizer))
        # the paper's definition: the target mask holds every point of the target's class
        class_mask = c.get("target_class_mask", c["target_mask"])
        outside = "goal_points" in c and not c["target_mask"].any()
        if affs is not None and (c["target_mask"].any() or outside):
            if class_mask.any():
                g = [jax.device_get(affordance_grounding_from_map(a, class_mask))
                     for a in affs[ci]]
                row.update({k: float(np.mean([x[k] for x in g])) for k in GROUNDING})
            # stricter: only the target instance's points count (0 when it is not in the crop)
            g = [jax.device_get(affordance_grounding_from_map(a, c["target_mask"]))
                 for a in affs[ci]] if not outside else [{"success@0.3": 0.0}]
            row["instance_success@0.3"] = float(np.mean([x["success@0.3"] for x in g]))
        rows.append(row)
        if bar is not None:
            bar.update(1)
    return rows


def _applicable(protocol: str, rows: list[dict]) -> list[dict]:
    """``rows`` without the columns that need a target object under the text protocol."""
    if protocol != "text":
        return rows
    return [{k: v for k, v in row.items() if k not in NOT_APPLICABLE} for row in rows]


def nan_mean(values) -> float:
    """Mean of the non-NaN ``values``; NaN (quietly) when there are none, e.g. the seat height
    of a walk, which has no seat."""
    v = np.asarray(values, np.float64).ravel()
    v = v[~np.isnan(v)]
    return float(v.mean()) if v.size else float("nan")


#: The geometric judge's checks and measures at the anchor frame that ``cases.jsonl`` carries
#: per case (``judge/<name>``: the mean over the case's motions).
JUDGE_DETAILS = ("over_footprint", "seat_height_ok", "lie_height_ok", "torso_upright",
                 "torso_horizontal", "knees_bent", "standing_height", "feet_on_floor",
                 "near_box", "pelvis_box_xy_distance", "pelvis_above_surface")


def _action_columns(case, joints, recognizer) -> dict:
    """The share of the K motions ``joints [K,T,22,3]`` that do the case's action on its
    target, by the geometric judge (``action_judged``, and its checks as ``judge/<name>``,
    :data:`JUDGE_DETAILS`) and by the recognizer (``action_recognized``, with one)."""
    from jaxmotion.eval.action_judge import judge_on_object

    k = joints.shape[0]
    mask = np.broadcast_to(case["mask"], joints.shape[:2])
    target = case.get("goal_points")
    if target is None:
        target = case["points"][case["target_mask"]]
    out = {}
    box = _target_box(case)
    if box is not None or len(target):
        lo, hi, surface = box if box is not None else (target.min(0), target.max(0), np.nan)
        rep = judge_on_object(joints, mask, case["action"], lo, hi, target, surface)
        out["action_judged"] = float(np.mean(rep["success"]))
        for name in JUDGE_DETAILS:  # which of the judge's checks fail, to see why
            out[f"judge/{name}"] = nan_mean(rep[name])
    if recognizer is not None:
        from jaxmotion.eval.recognizer import action_accuracy

        out["action_recognized"] = float(action_accuracy(recognizer, joints, mask,
                                                         [case["action"]] * k))
    return out


def _add_real(report: dict, values: dict, prefix: str = "") -> None:
    """Put the dataset's own numbers ``values`` in ``report["real"]`` (as ``prefix + key``),
    keeping those already there: every model's first replication scores the same motions."""
    real = report.setdefault("real", {})
    for k, v in values.items():
        real.setdefault(prefix + k, float(v))


def _in_furniture(case, joints) -> float:
    """The mean over the K motions ``joints [K,T,22,3]`` (crop frame) of the share of frames
    with a joint inside another object's box (:func:`jaxmotion.eval.furniture.
    furniture_frames`; a walk's target counts too, which the dataset's walks never enter).
    NaN (not counted in the means) for a case without the room's object table or crop frame."""
    from jaxmotion.eval.furniture import furniture_frames

    if not case.get("objects") or "rotation" not in case or "shift" not in case:
        return float("nan")
    world = joints @ np.asarray(case["rotation"]) + np.asarray(case["shift"])
    target = case.get("target_id")
    exclude = () if case["action"] == "walk" or target is None else (target,)
    return float(np.mean(furniture_frames(world, case["objects"], exclude, case["mask"])))


def _target_box(case):
    """The case's target from the room's object table in the crop frame: ``(bbox_min [3],
    bbox_max [3], surface height or NaN)``, or None without a table entry. A crop's few points
    on the target are a poor guide to its seat height; the table's box and surface are exact."""
    obj = next((o for o in case.get("objects", ()) if o["id"] == case.get("target_id")), None)
    if obj is None:
        return None
    lo, hi = np.asarray(obj["bbox_min"], np.float64), np.asarray(obj["bbox_max"], np.float64)
    corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1])
                        for z in (lo[2], hi[2])])
    crop = (corners - case["shift"]) @ np.asarray(case["rotation"]).T
    surface = obj.get("surface_height")
    surface = np.nan if surface is None else float(surface) - float(case["shift"][2])
    return crop.min(0).astype(np.float32), crop.max(0).astype(np.float32), surface


def _speed_percentiles(rows) -> dict:
    """The 50th / 99th percentile, over every motion of ``rows``, of its top pelvis speed."""
    speeds = np.array([v for row in rows for v in row.get("pelvis_speeds", ())], np.float64)
    if not len(speeds):
        return {}
    return {"pelvis_speed_p50": float(np.percentile(speeds, 50)),
            "pelvis_speed_p99": float(np.percentile(speeds, 99))}


def mean_ci95(values) -> dict:
    v = np.asarray(values, np.float64)
    v = v[np.isfinite(v)]
    if len(v) == 0:
        return {"mean": None, "ci95": None, "n": 0}
    half = 1.96 * v.std(ddof=1) / math.sqrt(len(v)) if len(v) > 1 else 0.0
    return {"mean": float(v.mean()), "ci95": float(half), "n": int(len(v))}


# --------------------------------------------------------------------------- main
def evaluate(
    data_dir,
    models: list[ModelSpec],
    *,
    split: str = "test",
    num_cases: int = 64,
    samples: int = 4,
    replications: int = 3,
    seed: int = 0,
    body: bool = True,
    evaluator=None,
    recognizer=None,
    ground_truth: bool = True,
    vertex_stride: int = 4,
    batch_size: int = 16,
    protocol: str = "paper",
    grounding: str = "auto",
    progress: bool = True,
    keep_motions: bool = False,
) -> dict:
    """Evaluate ``models`` on the first ``num_cases`` cases of ``split``; see the module
    docstring (``protocol``: ``paper``, ``generate`` or ``text``; ``grounding``: how the generate
    protocol finds the region, ``auto`` or ``adm``, as ``jaxmotion generate --grounding``).
    Returns a JSON-ready dict: settings, and per model its sampler, per-replication metrics
    and ``summary`` ``{metric: {mean, ci95, n}}``. With ``keep_motions`` each model's entry
    also holds ``motions``: the sampled joints ``[R, C, K, T, 22, 3]`` in each case's crop
    frame and that model's crops (``rotation``, ``shift``: under the generate protocol each
    model finds its own regions), and the report ``motion_cases`` (``files``, ``texts``,
    ``actions``, ``mask``); :func:`write_report` writes them to ``motions.npz``, leaving them
    out of ``results.json``. With ``ground_truth`` the dataset's
    own motions are scored the same way (``report["ground_truth"]``: the metrics' ceiling on
    this data; APD is 0 with one motion per case)."""
    import jax
    from tqdm.auto import tqdm

    from jaxmotion.data.cases import case_inputs
    from jaxmotion.diffusion import SamplerSpec
    from jaxmotion.pipelines.affordance import AffordancePipeline, take_text
    from jaxmotion.scene.instructions import anchor_is_first
    from jaxmotion.text import load_text_encoder

    if samples < 1 or replications < 1 or num_cases < 1:
        raise ValueError("num_cases, samples and replications must be ≥ 1")
    if protocol not in ("paper", "generate", "text"):
        raise ValueError(f"protocol must be 'paper' (crops around the dataset's motion), "
                         f"'generate' (crops where jaxmotion generate puts them) or 'text' "
                         f"(HumanML3D, text to motion on a floor), got {protocol!r}")
    if grounding not in GROUNDINGS:
        raise ValueError(f"grounding must be one of {', '.join(GROUNDINGS)}, got {grounding!r}")
    if evaluator is not None and isinstance(evaluator, (str, Path)):
        from jaxmotion.eval.evaluator import load_evaluator

        evaluator = load_evaluator(evaluator)
    if recognizer is not None and isinstance(recognizer, (str, Path)):
        from jaxmotion.eval.recognizer import load_recognizer

        recognizer = load_recognizer(recognizer)
    fps = SCENE_FPS
    if protocol == "text":
        if evaluator is None or recognizer is not None:
            raise ValueError("protocol 'text' scores text-motion agreement: it needs an "
                             "evaluator (--evaluator) and reads no action recognizer")
        if any(m.pipeline != "affordance" for m in models):
            raise ValueError("protocol 'text' scores the affordance pipeline's text-to-motion "
                             "on a floor; the object-centric pipeline needs a target object "
                             "and the cVAE a room (give ADM,AMDM rows only)")
        fps, body = check_text_data(data_dir, evaluator), False
    encoder = load_text_encoder(TEXT_ENCODER)
    phys = physical_fn(body, fps)
    report = {"settings": {"data_dir": str(data_dir), "split": split, "num_cases": num_cases,
                           "samples": samples, "replications": replications, "seed": seed,
                           "body": (f"mannequin (SMPL-X fit, every {vertex_stride}th vertex)"
                                    if body else "joint spheres"),
                           "evaluator": getattr(evaluator, "version", None),
                           "recognizer": (recognizer.describe() if recognizer is not None
                                          else None),
                           "protocol": protocol, "fps": fps,
                           **({"grounding": grounding} if protocol == "generate" else {})},
              "models": {}}
    total = len(models) * replications
    bar = tqdm(total=total * num_cases, desc="eval", disable=not progress, unit="case")
    first_regions = None
    for spec in models:
        t_model = time.perf_counter()
        pipe = AffordancePipeline.from_workdirs(spec.adm, spec.amdm)
        adm_sampler = SamplerSpec(spec.method, spec.adm_steps or spec.steps,
                                  guidance=spec.adm_guidance)
        regions = None
        if protocol == "generate":
            from jaxmotion.eval.region_probe import case_regions

            regions = case_regions(data_dir, split, pipe, num_cases=num_cases,
                                   grounding=grounding, sampler=adm_sampler, seed=seed,
                                   progress=progress)
            first_regions = first_regions if first_regions is not None else regions
        cases = load_eval_cases(data_dir, split, pipe.amdm_config, num_cases, seed, regions,
                            adm_config=pipe.adm_config,
                            exclude=grounding == "auto" and not pipe.room_view)
        report["settings"]["num_cases"] = len(cases)  # fewer when the split has fewer
        emb = pipe.embed_text([c["text"] for c in cases], encoder)
        amdm_sampler = SamplerSpec(spec.method, spec.steps, guidance=spec.amdm_guidance,
                                   consistency=spec.consistency)
        two_stage = pipe.amdm.cfg.scene_input == "affordance" and spec.pipeline == "affordance"
        oracle = spec.affordance == "gt"
        objects = None
        if spec.object_centric:
            from jaxmotion.grounding import read_instruction
            from jaxmotion.models.weights import weights_path
            from jaxmotion.pipelines.object_centric import (
                ObjectCentricPipeline,
                action_index,
                furniture_mask,
                keeps_out_of_target,
            )
            from jaxmotion.text.condition import pooled_text

            objects = ObjectCentricPipeline.from_files(weights_path(spec.trajectory),
                                                       weights_path(spec.completion))
            if spec.traj_sensor != "trajectory" and not objects.completion.cfg.traj_sensor:
                raise ValueError(f"--model {spec.name!r}: traj_sensor={spec.traj_sensor} needs a "
                                 f"completion model with a trajectory sensor; {spec.completion} "
                                 "was trained without one (train with model.traj_sensor=true)")
            # one compiled program for every batch: called eagerly, the samplers' scans
            # compile again for each batch and every executable keeps its memory maps
            object_sample = jax.jit(functools.partial(
                objects.sample, trajectory=amdm_sampler, completion=amdm_sampler,
                motion_candidates=spec.motion_candidates, keep_trajectory=spec.keep_trajectory,
                anchor_guidance=spec.anchor, standing_guidance=spec.standing,
                foot_guidance=spec.feet, traj_sensor_on=spec.traj_sensor))
        cvae = None
        if spec.cvae is not None:
            cvae = _cvae_sampler(spec, cases, encoder)
        if spec.adm_candidates > 1 and (protocol != "generate" or oracle or pipe.room_view):
            raise ValueError(f"--model {spec.name!r}: adm_candidates picks the ADM map that "
                             "lights the object generate's region was centred on; it needs "
                             "--protocol generate and a crop-view ADM (not affordance=gt)")
        if spec.motion_candidates > 1 and protocol != "generate":
            raise ValueError(f"--model {spec.name!r}: motion_candidates keeps the motion that "
                             "comes closest to the object generate's region was centred on; it "
                             "needs --protocol generate")
        if oracle:
            if not two_stage:
                raise ValueError(f"--model {spec.name!r}: affordance=gt needs an AMDM that reads "
                                 "affordance maps; this one reads the point colours (one-stage)")
            from jaxmotion.data.loader import batched_affordance

            gt_maps = np.asarray(jax.device_get(batched_affordance(pipe.sigma)(
                np.stack([c["points"] for c in cases]), np.stack([c["gt"] for c in cases]),
                np.stack([c["mask"] for c in cases]))))
        reps, fit_errors, case_rows, kept = [], [], [], []
        for r in range(replications):
            key = jax.random.fold_in(jax.random.key(seed), r)
            rows = [(ci, k) for ci in range(len(cases)) for k in range(samples)]
            joints = np.zeros((len(cases), samples, *cases[0]["gt"].shape), np.float32)
            affs = [[None] * samples for _ in cases]
            for start in range(0, len(rows), batch_size):
                chunk = rows[start:start + batch_size]
                idx = [ci for ci, _ in chunk] + [chunk[-1][0]] * (batch_size - len(chunk))
                x = case_inputs(cases, idx)
                if objects is not None:
                    target = np.stack([cases[i]["chosen_mask" if regions is not None
                                             else "target_mask"] for i in idx])
                    acts = [read_instruction(cases[i]["text"]).action for i in idx]
                    avoid = np.stack([furniture_mask(cases[i]["points"], t,
                                                     target_too=keeps_out_of_target(a))
                                      for i, t, a in zip(idx, target, acts)])
                    res = jax.device_get(object_sample(
                        jax.random.fold_in(key, start), x["points"], x["normals"], target,
                        pooled_text(take_text(emb, idx)), x["betas"], x["mask"],
                        anchor_first=np.array([anchor_is_first(cases[i]["text"]) for i in idx]),
                        action=np.array([action_index(a) for a in acts]), avoid=avoid))
                elif cvae is not None:
                    res = {"joints": cvae(jax.random.fold_in(key, start), x, idx)}
                else:
                    res = jax.device_get(pipe.sample(
                        jax.random.fold_in(key, start), x["points"], x["colors"], take_text(emb, idx),
                        x["mask"], adm=adm_sampler, amdm=amdm_sampler,
                        affordance=gt_maps[idx] if oracle else None, view=x["view"],
                        exclude=x["exclude"], candidates=spec.adm_candidates,
                        target=None if regions is None else np.stack(
                            [cases[i]["chosen_mask"] for i in idx]),
                        motion_candidates=spec.motion_candidates,
                        anchor_first=np.array([anchor_is_first(cases[i]["text"]) for i in idx])))
                for j, (ci, k) in enumerate(chunk):
                    joints[ci, k] = res["joints"][j]
                    if two_stage:
                        affs[ci][k] = res["affordance"][j]
            if keep_motions:
                kept.append(joints)
            # ground-truth maps are not scored, nor maps of a floor without a target
            grounded = two_stage and not oracle and protocol != "text"
            per_case = _applicable(protocol, score_cases(
                cases, joints, affs if grounded else None, phys, body, fps, fit_errors, bar,
                vertex_stride, recognizer))
            keys = sorted({k for row in per_case for k in row} - {"pelvis_speeds"})
            rep = {k: nan_mean([row.get(k, np.nan) for row in per_case]) for k in keys}
            rep.update(_speed_percentiles(per_case))
            case_rows += [_case_row(spec.name, r, ci, cases[ci], row,
                                    None if regions is None else regions[ci])
                          for ci, row in enumerate(per_case)]
            if evaluator is not None:
                from jaxmotion.eval.evaluator import text_motion_scores

                mask = np.stack([c["mask"] for c in cases])
                tm = text_motion_scores(evaluator, [c["text"] for c in cases],
                                        np.stack([c["gt"] for c in cases]), mask, joints,
                                        np.broadcast_to(mask[:, None], joints.shape[:3]),
                                        np.random.default_rng([seed, r]))
                rep.update({k: float(v) for k, v in tm["generated"].items()
                            if not k.endswith("_ci95")})  # intervals come from replications
                if r == 0 and "real" in tm:
                    _add_real(report, tm["real"])
            if recognizer is not None:
                from jaxmotion.eval.recognizer import recognizer_scores

                mask = np.stack([c["mask"] for c in cases])
                rs = recognizer_scores(recognizer, np.stack([c["gt"] for c in cases]), mask,
                                       joints, np.broadcast_to(mask[:, None], joints.shape[:3]),
                                       np.random.default_rng([seed, r, 1]))
                rep.update({f"rec_{k}": float(v) for k, v in rs["generated"].items()})
                if r == 0:  # the dataset's motions (the same for every model)
                    _add_real(report, rs["real"], "rec_")
            reps.append(rep)
        keys = sorted({k for rep in reps for k in rep})
        report["models"][spec.name] = {
            "adm": str(spec.adm), "amdm": str(spec.amdm), "sampler": spec.sampler_label,
            "two_stage": two_stage,
            "scene_input": {"object-centric": "sensors", "cvae": "rgb"}.get(
                spec.pipeline, pipe.amdm.cfg.scene_input),
            "pipeline": spec.pipeline,
            **({"trajectory": str(spec.trajectory), "completion": str(spec.completion)}
               if spec.object_centric else {}),
            **({"cvae": str(spec.cvae)} if spec.cvae is not None else {}),
            "affordance": "ground truth" if oracle else ("adm" if two_stage else None),
            "adm_arch": _adm_arch(spec.adm),
            "replications": reps,
            "summary": {k: mean_ci95([rep.get(k, np.nan) for rep in reps]) for k in keys},
            "body_fit_error_m": float(np.mean(fit_errors)) if fit_errors else None,
            "seconds": time.perf_counter() - t_model,
            "cases": case_rows,
        }
        if keep_motions:  # the crops are this model's; the cases are the same for every model
            report["models"][spec.name]["motions"] = {
                "joints": np.stack(kept),
                "rotation": np.stack([np.asarray(c["rotation"]) for c in cases]),
                "shift": np.stack([np.asarray(c["shift"]) for c in cases])}
            report.setdefault("motion_cases", {
                "files": [c["file"] for c in cases], "texts": [c["text"] for c in cases],
                "actions": [c["action"] for c in cases],
                "mask": np.stack([c["mask"] for c in cases])})
        if regions is not None:
            report["models"][spec.name]["regions"] = _region_summary(regions)
    if ground_truth:
        from jaxmotion.models.weights import read_config

        cases = load_eval_cases(data_dir, split, read_config(models[0].amdm), num_cases, seed,
                            first_regions)
        gt = np.stack([c["gt"] for c in cases])[:, None]
        rows = _applicable(protocol, score_cases(cases, gt, None, phys, body, fps, [], None,
                                                 vertex_stride, recognizer))
        report["ground_truth"] = {k: nan_mean([r[k] for r in rows]) for k in rows[0]
                                  if k != "pelvis_speeds"}
        report["ground_truth"].update(_speed_percentiles(rows))
    bar.close()
    return report


def _cvae_sampler(spec: ModelSpec, cases: list[dict], encoder):
    """``(key, inputs, idx) -> joints [B, T, 22, 3]`` (NumPy): one cVAE motion per row of the
    batch ``inputs`` (:func:`~jaxmotion.data.cases.case_inputs` of cases ``idx``), one latent
    each; the words' token states of every case's text are computed once here. A
    :class:`ValueError` names a cVAE whose crops or length differ from the cases'."""
    import jax

    from jaxmotion.models.weights import read_config
    from jaxmotion.text import pad_tokens

    saved = read_config(spec.cvae)  # checked before the weights are read
    points, frames = cases[0]["points"].shape[0], cases[0]["mask"].shape[0]
    want, makes = int(saved["model"]["num_points"]), int(saved["max_frames"])
    if want != points or makes != frames:
        raise ValueError(f"--model {spec.name!r}: the cVAE {spec.cvae} reads {want} points "
                         f"and makes {makes} frames, but the cases (from the AMDM's config) "
                         f"have {points} points and {frames} frames; give an AMDM with the "
                         f"cVAE's crop.num_points and max_frames")
    cv, run = _cvae_program(*_file_key(spec.cvae))
    tokens, token_mask = pad_tokens(encoder.token_states([c["text"] for c in cases]),
                                    int(cv.run_config["model"]["text_tokens"]), encoder.dim)

    def sample(key, x, idx):
        return np.asarray(jax.device_get(run(key, x["points"], x["colors"], tokens[idx],
                                             token_mask[idx], x["betas"], x["mask"])))
    return sample


def _file_key(path) -> tuple[str, int]:
    """A weights file (or workdir) as a cache key: its resolved path and modification time."""
    from jaxmotion.models.weights import weights_path

    src = weights_path(path).resolve()
    return str(src), src.stat().st_mtime_ns if src.is_file() else 0


@functools.lru_cache(maxsize=4)
def _cvae_program(path: str, mtime: int):
    """``(CVAEPipeline, jitted one-motion-per-row sampler)`` of a cVAE weights file, kept for
    the process (an evaluation run twice, or two models with one cVAE, compile it once)."""
    import jax

    from jaxmotion.pipelines.cvae import CVAEPipeline

    cv = CVAEPipeline.from_file(path)
    return cv, jax.jit(lambda key, p, c, t, tm, b, m: cv.sample(key, p, c, t, tm, b, m, 1)
                       ["joints"][:, 0])


def load_eval_cases(data_dir, split, amdm_config, num_cases, seed, regions, adm_config=None,
                exclude=False):
    """:func:`jaxmotion.data.cases.load_cases`; with ``regions`` (the generate protocol) the crops
    are centred on them (and each case has ``goal_points``), each case gets ``chosen_mask``
    (the crop's points on the region's object) and, with ``exclude``, the ``exclude`` mask of
    generate (the crop's points on the other objects of that object's class)."""
    from jaxmotion.data.cases import load_cases

    cases, _ = load_cases(data_dir, split, amdm_config, num_cases=num_cases, seed=seed,
                          adm_config=adm_config,
                          centres=None if regions is None else [r["centre"] for r in regions])
    if regions is None:
        return cases
    from jaxmotion.grounding import same_class_others

    for i, c in enumerate(cases):
        chosen = regions[i]["chosen"]
        c["chosen_mask"] = (np.zeros(len(c["instance"]), bool) if chosen is None
                            else c["instance"] == chosen)
        if exclude:  # as generate does (its step 3)
            c["exclude"] = np.isin(c["instance"], same_class_others(c["objects"], chosen))
    return cases


def _case_row(model: str, replication: int, index: int, case: dict, metrics: dict,
              region: dict | None) -> dict:
    """One line of ``cases.jsonl``: which case (index, sample file, action, text), its metrics
    (means over its K samples) and, under the generate protocol, the region's object."""
    row = {"model": model, "replication": replication, "case": index, "file": case["file"],
           "action": case["action"], "text": case["text"]}
    if region is not None:
        row.update(region_object=region["chosen"], target_object=region["target"],
                   region_how=region["how"])
    return {**row, **metrics}


def _region_summary(regions) -> dict:
    """How the generate protocol's regions were found: ``hit`` (centred on the target),
    ``hit_multi`` (among cases whose room has several objects of the named class) and the
    count of each ``how``."""
    hit = np.array([r["chosen"] == r["target"] for r in regions], float)
    multi = np.array([r["named"] > 1 for r in regions])
    how: dict[str, int] = {}
    for r in regions:
        how[r["how"] or "none"] = how.get(r["how"] or "none", 0) + 1
    return {"hit": float(hit.mean()), "multi_cases": int(multi.sum()),
            "hit_multi": float(hit[multi].mean()) if multi.any() else None, "how": how}


def _adm_arch(adm) -> str:
    from jaxmotion.models.weights import read_config

    return str(read_config(adm)["model"].get("arch", "perceiver"))


# --------------------------------------------------------------------------- report
def format_markdown(report: dict) -> str:
    """Tables laid out like the paper's Tables 2 (motion), 3 (grounding) and 5 (samplers);
    under the text protocol, like its Table 1 (:func:`~jaxmotion.eval.text_protocol.
    format_table1`)."""
    st = report["settings"]
    if st.get("protocol") == "text":
        return format_table1(report)
    lines = [f"Split `{st['split']}` of `{st['data_dir']}`: {st['num_cases']} cases × "
             f"{st['samples']} samples × {st['replications']} replications; body: {st['body']}; "
             f"mean ± 95 % interval over replications.", ""]
    if st.get("protocol") == "generate":
        lines[0] += (f" Protocol **generate** (grounding `{st['grounding']}`): each crop is "
                     "centred where `jaxmotion generate` puts it, from the room and the text; "
                     "goal distance to the target's points in the whole room.")
        for name, m in report["models"].items():
            r = m.get("regions")
            if r:
                multi = (f"; {100 * r['hit_multi']:.1f} % of the {r['multi_cases']} with several "
                         "objects of the named class" if r["hit_multi"] is not None else "")
                lines.append(f"- {name}: region centred on the target in {100 * r['hit']:.1f} % "
                             f"of cases{multi} (found by: "
                             + ", ".join(f"{k} {v}" for k, v in sorted(r["how"].items())) + ")")
        lines.append("")
    models = report["models"]
    has_tm = any("fid" in m["summary"] for m in models.values())
    head = ["method", "sampler", "goal dist. (m) ↓", "contact (%) ↑", "non-collision (%) ↑",
            "APD ↑", "skating (%) ↓"]
    if has_tm:
        head += ["FID ↓", "R-prec. top-3 ↑", "MM dist. ↓", "diversity →", "multimodality ↑"]
    lines += ["**Motion (as Table 2)**", "", "| " + " | ".join(head) + " |",
              "|" + "---|" * len(head)]
    if "ground_truth" in report or (has_tm and "real" in report):
        g, r = report.get("ground_truth", {}), report.get("real", {})
        num = lambda d, k, scale=1.0, digits=3: (  # noqa: E731
            f"{d[k] * scale:.{digits}f}" if d.get(k) is not None else "–")
        cells = ["dataset motions", "–", num(g, "goal_distance"), num(g, "contact", 100, 2),
                 num(g, "non_collision", 100, 2), "–", num(g, "skating", 100, 2)]
        if has_tm:
            cells += ["–", num(r, "r_precision_top3"), num(r, "multimodal_dist"),
                      num(r, "diversity"), "–"]
        lines.append("| " + " | ".join(cells) + " |")
    for name, m in models.items():
        s = m["summary"]
        cells = [name, m["sampler"], mean_ci_cell(s.get("goal_distance")),
                 mean_ci_cell(s.get("contact"), 100, 2),
                 mean_ci_cell(s.get("non_collision"), 100, 2),
                 mean_ci_cell(s.get("apd")), mean_ci_cell(s.get("skating"), 100, 2)]
        if has_tm:
            cells += [mean_ci_cell(s.get(k)) for k in ("fid", "r_precision_top3",
                                                       "multimodal_dist", "diversity",
                                                       "multimodality")]
        lines.append("| " + " | ".join(cells) + " |")
    head = ["method", "sampler", "teleport (%) ↓", "pelvis speed p50 (m/s)",
            "pelvis speed p99 (m/s) ↓", "top joint speed (m/s) ↓", "jerk (m/s³) ↓",
            "floor penetration (cm) ↓", "in furniture (%) ↓", "action, judge (%) ↑",
            "action, recognizer (%) ↑"]
    plaus_keys = (("teleport", 100, 1), ("pelvis_speed_p50", 1, 2), ("pelvis_speed_p99", 1, 2),
                  ("joint_speed_max", 1, 2), ("jerk_mean", 1, 1), ("floor_penetration", 100, 2),
                  ("in_furniture", 100, 1), ("action_judged", 100, 1),
                  ("action_recognized", 100, 1))
    has_rec = any(k in m["summary"] for m in models.values() for k in RECOGNIZER_SET)
    about_rec = ""
    if has_rec:
        head += ["FID (rec.) ↓", "diversity (rec.) →", "multimodality (rec.) ↑"]
        plaus_keys += tuple((k, 1, 3) for k in RECOGNIZER_SET)
        about_rec = ("; FID, diversity and multimodality (rec.): on the action recognizer's "
                     "features, as the object-centric paper's Table 1")
    lines += ["", ("**Plausibility and action** (a teleport: a joint faster than 9 m/s or the "
                   "pelvis faster than 3 m/s between two frames; in furniture: the share of "
                   "frames with a joint inside the box, shrunk 5 cm, of an object other than "
                   "the target, a walk's target included; action: the share of motions "
                   "doing the instruction's action on its target, by the geometric judge at the "
                   f"anchor frame and by the action recognizer{about_rec})"), "",
              "| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    real = {k: v for k, v in report.get("real", {}).items() if k in RECOGNIZER_SET}
    if "ground_truth" in report or (has_rec and real):
        g = {**report.get("ground_truth", {}), **real}  # FID against itself: 0, not shown
        lines.append("| " + " | ".join(["dataset motions", "–"] + [
            f"{g[k] * sc:.{d}f}" if g.get(k) is not None and np.isfinite(g[k])
            and k != "rec_fid" else "–"
            for k, sc, d in plaus_keys]) + " |")
    for name, m in models.items():
        s = m["summary"]
        lines.append("| " + " | ".join([name, m["sampler"]] + [
            mean_ci_cell(s.get(k), sc, d) for k, sc, d in plaus_keys]) + " |")
    grounded = {n: m for n, m in models.items()
                if m["two_stage"] and m.get("affordance", "adm") == "adm"}
    if grounded:
        head = ["method", "ADM", "min dist. ↓", "pelvis dist. ↓", "all dist. ↓", "succ. 0.1 ↑",
                "succ. 0.3 ↑", "succ. 0.5 ↑", "succ. 0.3, instance ↑"]
        lines += ["", "**Affordance grounding (as Table 3)**", "", "| " + " | ".join(head) + " |",
                  "|" + "---|" * len(head)]
        for name, m in grounded.items():
            s = m["summary"]
            lines.append("| " + " | ".join([name, m["adm_arch"]] + [
                mean_ci_cell(s.get(k)) if "dist" in k else mean_ci_cell(s.get(k), 100, 1)
                for k in (*GROUNDING, "instance_success@0.3")]) + " |")
        lines += ["", "Grounding columns use the points of every object of the target's class "
                  "(the paper's definition); the last column counts only the target instance."]
    return "\n".join(lines) + "\n"


def write_report(report: dict, out) -> tuple[Path, Path]:
    """Write ``out/results.json``, ``out/results.md`` and ``out/cases.jsonl`` (atomically).

    ``cases.jsonl`` holds one JSON line per model, replication and case (see
    :func:`_case_row`): the per-case metrics behind the means, to find where a model fails;
    ``results.json`` holds everything else. A report of ``evaluate(keep_motions=True)`` also
    gives ``out/motions.npz``: per model ``<name>/joints`` ``[R, C, K, T, 22, 3]`` in each
    case's crop frame and that model's crops ``<name>/rotation`` ``[C, 3, 3]`` /
    ``<name>/shift`` ``[C, 3]`` (a crop point ``p`` is the room point ``p @ rotation +
    shift``), and per case ``files``, ``texts``, ``actions``, ``mask``."""
    from jaxmotion._atomic import atomic_open

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    models = {name: {k: v for k, v in m.items() if k not in ("cases", "motions")}
              for name, m in report["models"].items()}
    if "motion_cases" in report:
        arrays = {k: np.asarray(v) for k, v in report["motion_cases"].items()}
        arrays.update({f"{name}/{k}": v for name, m in report["models"].items()
                       for k, v in m.get("motions", {}).items()})
        with atomic_open(out / "motions.npz", "wb") as f:
            np.savez_compressed(f, **arrays)
    report = {k: v for k, v in report.items() if k != "motion_cases"}
    with atomic_open(out / "cases.jsonl", "w") as f:
        for m in report["models"].values():
            for row in m.get("cases", []):
                f.write(json.dumps(row) + "\n")
    with atomic_open(out / "results.json", "w") as f:
        json.dump({**report, "models": models}, f, indent=2)
    with atomic_open(out / "results.md", "w") as f:
        f.write(format_markdown(report))
    return out / "results.json", out / "results.md"
