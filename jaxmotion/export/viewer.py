"""A self-contained HTML page that plays the motion in its scene (WebGL2, no network, no library).

The page embeds everything: the JSON payload in a ``<script type="application/json"
id="jm-data">`` element, arrays as base64 of little-endian binary, each as
``{"dtype", "shape", "b64"}`` plus, for quantised arrays, per-axis ``"offset"`` and
``"step"`` (value = offset + q · step):

- ``scene.xyz``: ``[N, 3]`` uint16 quantised over the points' bounding box
  (error ≤ half a step: 0.08 mm for a 10 m room); ``scene.rgb``: ``[N, 3]`` uint8.
  At most ``max_points`` points (a seeded random subset).
- ``affordance.values``: ``[N, C]`` uint8 (value / 255) with the channel names.
- ``joints``: ``[K, T, 22, 3]`` float32; ``parents``, ``fps``, ``text``.
- ``body`` (when vertices are given): the mesh decimated by vertex clustering
  (cells of ``body_cell`` metres on the first frame of the first sample, split
  into mesh-connected pieces so that touching body parts stay apart; each
  cluster moves with the mean of its vertices), ``positions [K, T, C, 3]`` uint16
  quantised, ``faces [F, 3]`` uint32.

Controls: drag to orbit about a z-up world, right-drag or shift-drag to pan, wheel
to zoom, double-click to reset; a timeline slider, play/pause (space), ← → to
step; a body toggle; a menu colouring the scene by its colours or by the
affordance (maximum over the joints or one joint) as a heat layer. Samples get
the colours of ``PALETTE``. Size: about 1.1 MB for 50k points with a 6-channel
affordance map and T = 120, plus about 2.2 MB per sample with a body (the
mannequin decimates to about 2,200 clusters at 4 cm).
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


def _decimate(vertices: np.ndarray, faces: np.ndarray, cell: float):
    """Vertex-clustering decimation of an animated mesh ``[K, T, V, 3]`` with faces ``[F, 3]``.

    Returns cluster positions ``[K, T, C, 3]`` (mean of the members) and faces ``[F', 3]``.
    """
    from scipy.sparse import coo_matrix, csr_matrix
    from scipy.sparse.csgraph import connected_components

    num = vertices.shape[2]
    _, cell_id = np.unique(
        np.floor(vertices[0, 0] / cell).astype(np.int64), axis=0, return_inverse=True
    )
    cell_id = cell_id.reshape(-1)
    edges = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    edges = edges[cell_id[edges[:, 0]] == cell_id[edges[:, 1]]]
    graph = coo_matrix((np.ones(len(edges)), (edges[:, 0], edges[:, 1])), shape=(num, num))
    count, label = connected_components(graph, directed=False)
    f = label[faces]
    f = f[(f[:, 0] != f[:, 1]) & (f[:, 1] != f[:, 2]) & (f[:, 2] != f[:, 0])]
    _, first = np.unique(np.sort(f, axis=1), axis=0, return_index=True)
    f = f[np.sort(first)]
    used = np.unique(f)
    remap = np.full(count, -1)
    remap[used] = np.arange(len(used))
    size = np.bincount(label, minlength=count)
    mean = csr_matrix((1.0 / size[label], (label, np.arange(num))), shape=(count, num))[used]
    k, t = vertices.shape[:2]
    flat = vertices.transpose(2, 0, 1, 3).reshape(num, -1)
    pos = np.asarray(mean @ flat).reshape(len(used), k, t, 3).transpose(1, 2, 0, 3)
    return pos, remap[f]


def write_viewer_html(
    path,
    *,
    scene_xyz,
    scene_rgb,
    joints,
    fps: float,
    text: str = "",
    affordance=None,
    vertices=None,
    faces=None,
    max_points: int = 60_000,
    body_cell: float = 0.04,
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
      vertices: ``[(K,) T, V, 3]`` posed body vertices with faces ``[F, 3]``: the body
        mesh, decimated (see the module docstring); optional.
      max_points: scene points kept (seeded random subset); body_cell: decimation cell, m.
      seed: for the subset.
      segments: a story's steps, ``{"action", "object", "first", "last"}`` (optional
        ``"label"``): the current one is named beside the clock.
      paths: planned ground paths ``[M, 2]`` (or ``[M, 3]``), drawn on the floor.
    Returns:
      the path written.
    """
    if (vertices is None) != (faces is None):
        raise ValueError("give both vertices and faces for the body, or neither")
    xyz, rgb = scene_points(scene_xyz, scene_rgb)
    fps = check_fps(fps)
    j = np.asarray(joints, np.float64)
    j = check_array("joints", j[None] if j.ndim == 3 else j, (None, None, NUM_JOINTS, 3))
    k, t = j.shape[:2]
    if t == 0:
        raise ValueError("joints has no frame (T = 0)")
    if max_points < 1 or not body_cell > 0:
        raise ValueError(f"max_points must be ≥ 1 and body_cell > 0, got {max_points}, {body_cell}")
    keep = random_subset(len(xyz), max_points, seed)
    data: dict = {
        "text": str(text),
        "fps": fps,
        "num_samples": k,
        "num_frames": t,
        "parents": list(PARENTS),
        "joint_names": list(JOINT_NAMES),
        "palette": PALETTE.tolist(),
        "inferno": INFERNO.tolist(),
        "scene": {
            "xyz": _quantised(xyz[keep]),
            "rgb": _encode(np.round(rgb[keep] * 255).astype(np.uint8)),
        },
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
        data["segments"].append({"first": first, "last": last, "label": str(label)})
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
    if vertices is not None:
        v = np.asarray(vertices, np.float64)
        v = check_array("vertices", v[None] if v.ndim == 3 else v, (k, t, None, 3))
        f = check_array("faces", faces, (None, 3), np.int64)
        if f.size == 0 or f.min() < 0 or f.max() >= v.shape[2]:
            raise ValueError(f"faces must be a non-empty [F, 3] index array into [0, {v.shape[2]})")
        pos, f = _decimate(v, f, body_cell)
        data["body"] = {"positions": _quantised(pos), "faces": _encode(f.astype(np.uint32))}

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
