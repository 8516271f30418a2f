"""A self-contained HTML page that plays the motion in its scene (WebGL2, no network, no library).

The page embeds everything: the JSON payload in a ``<script type="application/json"
id="jm-data">`` element, arrays as base64 of little-endian binary, each as
``{"dtype", "shape", "b64"}`` plus, for quantised arrays, per-axis ``"offset"`` and
``"step"`` (value = offset + q · step):

- ``scene.xyz``: ``[N, 3]`` uint16 quantised over the points' bounding box
  (error ≤ half a step: 0.08 mm for a 10 m room); ``scene.rgb``: ``[N, 3]`` uint8, lit by
  a fixed light from the scene's normals where it has them; ``scene.instance``: ``[N]``
  uint8 / uint16, 1 + the index of the point's object in ``objects`` (0: none). At most
  ``max_points`` points (a seeded random subset).
- ``objects``: ``{"id", "category", "lo", "hi"}`` (the axis-aligned box); ``target``: the
  index of the target object (−1: none); ``highlight``: its tint
  (:data:`jaxmotion.render.scene.HIGHLIGHT`).
- ``affordance.values``: ``[N, C]`` uint8 (value / 255) with the channel names.
- ``joints``: ``[K, T, 22, 3]`` float32; ``parents``, ``fps``, ``text``.
- ``body`` (from SMPL-X parameters): the skinned mesh, blended on the GPU. Per distinct
  shape its rest ``positions [V, 3]`` uint16 quantised and unit ``normals [V, 3]`` int8
  (/ 127); shared ``faces [F, 3]``, the 4 strongest skinning ``joints [V, 4]`` and
  ``weights [V, 4]`` uint8 (/ 255); ``bones [K, T, J, 12]`` uint16 quantised, the row-major
  3 × 4 linear blend skinning map of every joint (:func:`jaxmotion.render.body.skinning`);
  ``shape_of [K]`` and the samples' ``colours``. The mannequin (at most 4 joints a vertex,
  no pose correctives) is posed as ``body_forward`` poses it, to within 1 mm; for a user's
  SMPL-X model, as in ``motion.glb``, the pose-corrective blend shapes are dropped and the
  weights beyond the 4 strongest folded into them.
- ``segments`` (a story's steps: ``first``, ``last``, ``label``, ``object`` index or −1)
  and ``paths`` (planned ground paths).

Size: the mannequin (24k vertices) costs about 0.9 MB once and 0.2 MB per sample at
T = 120; 60k scene points about 0.8 MB, a one-channel affordance map 0.08 MB: 2.0 MB
for the demo room with one sample, 2.8 MB with four. Per-frame vertices, even decimated
to 2,200 clusters, would cost 2.1 MB per sample at T = 120.

Controls: see :mod:`jaxmotion.export._viewer_page`.
"""

from __future__ import annotations

import base64
import html
import json
import re
from pathlib import Path

import numpy as np

from jaxmotion._atomic import atomic_open
from jaxmotion.export._common import (
    INFERNO,
    PALETTE,
    affordance_channels,
    check_array,
    check_fps,
    random_subset,
    scene_points,
    strongest_influences,
    vertex_normals,
)
from jaxmotion.export._viewer_page import PAGE
from jaxmotion.geometry.affordance import AFFORDANCE_JOINTS
from jaxmotion.geometry.skeleton import JOINT_NAMES, NUM_JOINTS, PARENTS

__all__ = ["write_viewer_html"]


def _encode(a: np.ndarray) -> dict:
    a = np.ascontiguousarray(a)
    data = a.astype(a.dtype.newbyteorder("<"), copy=False).tobytes()
    return {"dtype": a.dtype.name, "shape": list(a.shape), "b64": base64.b64encode(data).decode()}


def _quantised(a: np.ndarray) -> dict:
    """uint16 per last-axis component over the array's range: error ≤ step / 2."""
    flat = a.reshape(-1, a.shape[-1])
    lo = flat.min(axis=0) if len(flat) else np.zeros(a.shape[-1])
    step = (flat.max(axis=0) - lo) / 65535 if len(flat) else np.ones(a.shape[-1])
    step = np.where(step > 0, step, 1.0)
    q = np.round((a - lo) / step).astype(np.uint16)
    return {**_encode(q), "offset": lo.tolist(), "step": step.tolist()}


_LIGHT = np.array([0.35, -0.45, 0.82]) / np.linalg.norm([0.35, -0.45, 0.82])


def _lit(rgb: np.ndarray, normal) -> np.ndarray:
    """``rgb`` lit two-sided by the fixed light ``_LIGHT`` where ``normal`` is non-zero."""
    if normal is None:
        return rgb
    n = check_array("scene_normal", normal, (len(rgb), 3))
    known = np.linalg.norm(n, axis=1) > 0
    shade = np.where(known, 0.55 + 0.45 * np.abs(n @ _LIGHT), 1.0)
    return np.clip(rgb * shade[:, None], 0.0, 1.0)


def _body(smplx: dict, model, k: int, t: int) -> dict:
    """The skinned body payload (see the module docstring) of SMPL-X parameters ``smplx``."""
    from jaxmotion.render.body import skinning
    from jaxmotion.render.frames import body_colour

    skin = skinning(smplx["global_orient"], smplx["body_pose"], smplx["transl"],
                    smplx.get("betas"), model)
    if skin.affine.shape[:2] != (k, t):
        raise ValueError(f"the SMPL-X parameters have {list(skin.affine.shape[:2])} samples and "
                         f"frames, the joints [{k}, {t}]")
    faces = np.asarray(skin.models[0].faces, np.int64)
    joint, weight = strongest_influences(np.asarray(skin.models[0].weights, np.float64), 4)
    shapes, shape_of, seen = [], [], {}
    for vertices, _ in skin.rest:
        key = vertices.tobytes()
        if key not in seen:
            seen[key] = len(shapes)
            normals = vertex_normals(vertices, faces)
            shapes.append({"positions": _quantised(vertices),
                           "normals": _encode(np.round(normals * 127).astype(np.int8))})
        shape_of.append(seen[key])
    return {
        "shapes": shapes,
        "shape_of": shape_of,
        "faces": _encode(faces.astype(np.uint16 if faces.max() < 65536 else np.uint32)),
        "joints": _encode(joint.astype(np.uint8 if joint.max() < 256 else np.uint16)),
        "weights": _encode(np.round(weight * 255).astype(np.uint8)),
        "bones": _quantised(skin.affine.reshape(k, t, -1, 12)),
        "colours": [np.round(body_colour(s), 4).tolist() for s in range(k)],
    }


def write_viewer_html(
    path,
    *,
    scene_xyz,
    scene_rgb,
    joints,
    fps: float,
    text: str = "",
    affordance=None,
    smplx=None,
    model=None,
    scene_normal=None,
    scene_instance=None,
    objects=(),
    target_id=None,
    max_points: int = 60_000,
    seed: int = 0,
    segments=(),
    paths=(),
) -> Path:
    """Write one self-contained HTML page playing the motion in the scene, atomically.

    Args:
      path: the ``.html`` file to write.
      scene_xyz: ``[N, 3]`` scene points, z-up, metres; scene_rgb: ``[N, 3]`` in [0, 1] or None.
      joints: ``[T, 22, 3]`` or ``[K, T, 22, 3]`` (K samples), same frame as the scene.
      fps: frames per second.
      text: the instruction, shown on the page (HTML-escaped).
      affordance: ``[N]`` or ``[N, 6]`` affordance map in [0, 1] (the six channels of
        ``jaxmotion.geometry.AFFORDANCE_JOINTS``), offered as a heat layer; optional.
      smplx: the fitted SMPL-X parameters (``global_orient [(K,) T, 3]``, ``body_pose
        [(K,) T, 21, 3]``, ``transl [(K,) T, 3]``, optional ``betas [(K,) B]``), posed on
        ``model`` (None: the mannequin at each sample's betas): the skinned bodies; without
        them the page draws the skeletons.
      scene_normal: ``[N, 3]`` normals (zero rows: unknown) that light the points; optional.
      scene_instance: ``[N]`` object id of each point (−1: none), with ``objects`` the
        scene's object table (``id``, ``category``, ``bbox_min``, ``bbox_max``): hover labels,
        the cutaway by whole objects; target_id: the object highlighted (None: none).
      max_points: scene points kept (seeded random subset); seed: for the subset.
      segments: a story's steps, ``{"action", "object", "first", "last"}`` (optional
        ``"label"``): listed, the current one named beside the clock and its object
        highlighted.
      paths: planned ground paths ``[M, 2]`` (or ``[M, 3]``), drawn on the floor.
    Returns:
      the path written.
    """
    xyz, rgb = scene_points(scene_xyz, scene_rgb)
    rgb = _lit(rgb, scene_normal)
    fps = check_fps(fps)
    j = np.asarray(joints, np.float64)
    j = check_array("joints", j[None] if j.ndim == 3 else j, (None, None, NUM_JOINTS, 3))
    k, t = j.shape[:2]
    if t == 0:
        raise ValueError("joints has no frame (T = 0)")
    if max_points < 1:
        raise ValueError(f"max_points must be ≥ 1, got {max_points}")
    from jaxmotion.render.scene import HIGHLIGHT

    keep = random_subset(len(xyz), max_points, seed)
    table = [{"id": int(o["id"]), "category": str(o["category"]),
              "lo": np.round(np.asarray(o["bbox_min"], float), 3).tolist(),
              "hi": np.round(np.asarray(o["bbox_max"], float), 3).tolist()} for o in objects]
    index = {o["id"]: i for i, o in enumerate(table)}
    if target_id is not None and int(target_id) >= 0 and int(target_id) not in index:
        raise ValueError(f"target_id {target_id} is not in objects (ids {sorted(index)})")
    instance = np.zeros(len(keep), np.int64)
    if scene_instance is not None:
        ids = check_array("scene_instance", scene_instance, (len(xyz),), np.int64)[keep]
        instance = np.array([index.get(int(i), -1) + 1 for i in ids], np.int64)
    data: dict = {
        "text": str(text),
        "fps": fps,
        "num_samples": k,
        "num_frames": t,
        "parents": list(PARENTS),
        "joint_names": list(JOINT_NAMES),
        "palette": PALETTE.tolist(),
        "inferno": INFERNO.tolist(),
        "highlight": HIGHLIGHT.tolist(),
        "scene": {
            "xyz": _quantised(xyz[keep]),
            "rgb": _encode(np.round(rgb[keep] * 255).astype(np.uint8)),
            "instance": _encode(instance.astype(np.uint8 if len(table) < 256 else np.uint16)),
        },
        "objects": table,
        "target": index.get(int(target_id), -1) if target_id is not None else -1,
        "joints": _encode(j.astype(np.float32)),
        "affordance": None,
        "body": None,
        "segments": [],
        "paths": [],
    }
    for seg in segments:
        first, last = int(seg["first"]), int(seg["last"])
        if not 0 <= first <= last < t:
            raise ValueError(f"segment {seg} is outside the motion's {t} frames")
        label = seg.get("label") or f"{str(seg['action']).replace('_', ' ')} · object "\
            f"{seg['object']}"
        data["segments"].append({"first": first, "last": last, "label": str(label),
                                 "object": index.get(int(seg["object"]), -1)})
    for q in paths:
        q = np.asarray(q, np.float64)
        if q.ndim != 2 or q.shape[1] not in (2, 3) or len(q) < 2:
            raise ValueError(f"a path must be [M, 2] or [M, 3] with M >= 2, got {q.shape}")
        if q.shape[1] == 2:
            q = np.concatenate([q, np.full((len(q), 1), 0.02)], 1)
        data["paths"].append(np.round(q, 3).ravel().tolist())
    if affordance is not None:
        a = affordance_channels(affordance, len(xyz))[keep]
        if a.shape[1] == len(AFFORDANCE_JOINTS):
            names = [JOINT_NAMES[i] for i in AFFORDANCE_JOINTS]
        else:
            names = [f"channel {c}" for c in range(a.shape[1])] if a.shape[1] > 1 else ["map"]
        data["affordance"] = {
            "values": _encode(np.round(a * 255).astype(np.uint8)),
            "channels": names,
        }
    if smplx is not None:
        data["body"] = _body(smplx, model, k, t)

    payload = json.dumps(data, separators=(",", ":")).replace("<", "\\u003c")
    fields = {
        "TITLE": html.escape(f"jaxmotion: {text}" if text else "jaxmotion"),
        "CAPTION": html.escape(str(text)),
        "DATA": payload,
    }
    page = re.sub(r"__(TITLE|CAPTION|DATA)__", lambda m: fields[m.group(1)], PAGE)
    with atomic_open(path, "w") as fh:
        fh.write(page)
    return Path(path)
