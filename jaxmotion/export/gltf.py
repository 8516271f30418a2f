"""Binary glTF 2.0 (``.glb``): the skinned, animated body in its scene (Blender, three.js, engines).

What the file holds
-------------------
- One **skinned body per sample**: the body mesh baked at its betas (``POSITION``,
  ``NORMAL``, ``JOINTS_0`` / ``WEIGHTS_0`` = the 4 strongest skinning weights per
  vertex, renormalised), and a skeleton of one node per joint, each named with
  its SMPL-X name (``jaxmotion.geometry.SMPLX_JOINT_NAMES``, the names of the
  SMPL-X model files and of the SMPL-X Blender add-on's armature: ``pelvis``,
  ``left_hip``, …, ``left_index1``, …, ``right_thumb3``; the joints that follow
  the 22 body joints are held at their fixed pose). The mannequin's skeleton has
  52 of SMPL-X's 55 joints: the 22 body joints and the 30 finger joints; it has no
  jaw and no eyes, and its two hand roots (on the wrists, never turned on their
  own) are folded into the wrists, which move exactly as they do
  (:func:`jaxmotion.body.model.joint_names`). A user's SMPL-X model gives all 55.
  Each sample's skeleton hangs under its own node ``sample{k}`` (Blender makes it
  one armature named ``sample{k}``, its bones named as above). Node translations
  are rest offsets (child − parent bind joint), rotations SMPL-X's local
  rotations; the inverse bind matrices are ``translate(−bind joint)``: the bind
  pose is SMPL-X's rest pose (y up, facing +z). Samples sharing betas share the
  vertex data.
- **One animation** ("motion") driving every sample together: per body joint a
  rotation channel (unit quaternions ``x, y, z, w``, sign-continuous over time),
  and the root's translation channel (``rest pelvis + transl``, SMPL-X turning
  the body about its rest pelvis), keyed at every frame (times ``t / fps``),
  ``LINEAR`` interpolation (slerp for rotations).
- Optionally **the scene**: a triangle mesh (``scene_faces`` given) or a point
  cloud (mode ``POINTS``, unlit), with ``COLOR_0`` vertex colours.

Frames
------
glTF is y-up: the joints and the scene hang under one root node ``world`` that
turns jaxmotion's z-up world into glTF's by Rx(−90°). The skinned mesh nodes
themselves are scene roots with identity transforms, as glTF asks (their own
transform is ignored; the joints place the skin). The posed mesh therefore
equals ``Rx(−90°) · jaxmotion.body.body_forward(...).vertices`` (exact for the
mannequin; for an SMPL-X model, pose-corrective blend shapes are dropped and
weights beyond the 4 strongest per vertex are folded into them).
"""

from __future__ import annotations

import json
import struct
from pathlib import Path

import numpy as np

from jaxmotion._atomic import atomic_open
from jaxmotion._version import __version__
from jaxmotion.export._common import (
    PALETTE,
    check_array,
    check_fps,
    scene_points,
    smplx_motion,
    strongest_influences,
    vertex_normals,
)
from jaxmotion.export.rotations import rotvec_to_quat
from jaxmotion.geometry.skeleton import NUM_JOINTS

__all__ = ["write_glb"]

_INFLUENCES = 4
_COMPONENT = {
    np.dtype(np.float32): 5126,
    np.dtype(np.uint32): 5125,
    np.dtype(np.uint16): 5123,
    np.dtype(np.uint8): 5121,
}
_TYPE = {1: "SCALAR", 2: "VEC2", 3: "VEC3", 4: "VEC4", 16: "MAT4"}
_ARRAY_BUFFER, _ELEMENT_ARRAY_BUFFER = 34962, 34963
_Y_UP_ROOT = [-np.sqrt(0.5), 0.0, 0.0, np.sqrt(0.5)]  # Rx(−90°) as x, y, z, w


class _Buffer:
    """The BIN chunk with its bufferViews and accessors (one view per accessor)."""

    def __init__(self):
        self.parts: list[bytes] = []
        self.size = 0
        self.views: list[dict] = []
        self.accessors: list[dict] = []

    def add(self, array: np.ndarray, *, target=None, normalized=False, bounds=False) -> int:
        array = np.ascontiguousarray(array)
        data = array.astype(array.dtype.newbyteorder("<"), copy=False).tobytes()
        view = {"buffer": 0, "byteOffset": self.size, "byteLength": len(data)}
        if target is not None:
            view["target"] = target
        self.views.append(view)
        self.parts.append(data + b"\0" * (-len(data) % 4))  # 4-byte aligned views
        self.size += len(self.parts[-1])
        width = 1 if array.ndim == 1 else array.shape[1]
        acc = {
            "bufferView": len(self.views) - 1,
            "componentType": _COMPONENT[array.dtype],
            "count": int(array.shape[0]),
            "type": _TYPE[width],
        }
        if normalized:
            acc["normalized"] = True
        if bounds:
            lo, hi = array.min(axis=0), array.max(axis=0)
            acc["min"], acc["max"] = np.atleast_1d(lo).tolist(), np.atleast_1d(hi).tolist()
        self.accessors.append(acc)
        return len(self.accessors) - 1


def _continuous(q: np.ndarray) -> np.ndarray:
    """Flip quaternions ``[T, ..., 4]`` so consecutive frames have a non-negative dot (short slerp)."""
    dots = np.sum(q[1:] * q[:-1], axis=-1)
    signs = np.cumprod(np.where(dots < 0, -1.0, 1.0), axis=0)
    return np.concatenate([q[:1], q[1:] * signs[..., None]], axis=0)


def _named_joints(model) -> tuple[list[int], list[int], np.ndarray, list[str]]:
    """The joints written: ``keep`` (the model's joints with an SMPL-X name), the parent
    of each among them (−1 for the root), the column ``[J]`` each model joint's skin weights
    go to, and the names. A joint without an SMPL-X name (the mannequin's hand roots) is
    folded into its parent: with no rotation of its own it has its parent's skinning
    transform, and its children's offsets measured from the parent place them the same."""
    from jaxmotion.body.model import joint_names

    names = joint_names(model)
    fixed = np.asarray(model.fixed_pose, np.float64)
    column = np.zeros(model.num_joints, np.int64)
    keep: list[int] = []
    for j, name in enumerate(names):
        if name is None:
            if np.any(fixed[j] != 0):
                raise ValueError(f"joint {j} has no SMPL-X name but a fixed rotation "
                                 f"{fixed[j].tolist()}: it cannot be folded into its parent")
            column[j] = column[model.parents[j]]
        else:
            column[j] = len(keep)
            keep.append(j)
    parents = [-1 if model.parents[j] < 0 else int(column[model.parents[j]]) for j in keep]
    return keep, parents, column, [names[j] for j in keep]


def _sample_betas(betas, k: int) -> np.ndarray | None:
    if betas is None:
        return None
    b = np.asarray(betas, np.float64)
    b = check_array("betas", np.broadcast_to(b, (k, b.shape[-1])) if b.ndim == 1 else b, (k, None))
    return b


def write_glb(
    path,
    *,
    global_orient,
    body_pose,
    transl,
    fps: float,
    betas=None,
    model=None,
    scene_xyz=None,
    scene_rgb=None,
    scene_faces=None,
    spacing: float = 0.0,
    skeleton: str = "smplx",
) -> Path:
    """Write the skinned, animated body (one per sample) and the scene as ``.glb``, atomically.

    Args:
      path: the ``.glb`` file to write.
      global_orient: ``[T, 3]`` or ``[K, T, 3]`` axis-angle, radians (K samples).
      body_pose: ``[(K,) T, 21, 3]``; transl: ``[(K,) T, 3]`` metres, z-up world.
      fps: frames per second of the motion.
      betas: ``[B]`` shared or ``[K, B]`` per sample, or None (neutral body).
      model: a :class:`jaxmotion.body.BodyModel`; default: the mannequin built at
        each sample's betas (exact mesh).
      scene_xyz: ``[N, 3]`` scene vertices or points (z-up, metres), optional;
        scene_rgb: ``[N, 3]`` in [0, 1] (default grey); scene_faces: ``[F, 3]``
        vertex indices: a triangle mesh, else a point cloud.
      spacing: sample k is moved by ``k · spacing`` metres along world x (0 keeps
        every sample where it was generated, in the scene).
      skeleton: the bones' names: SMPL-X's (default), Mixamo's (``mixamorig:Hips``, …,
        ``mixamorig:LeftHandIndex1``) or Unreal Engine 5's (``pelvis``, ``thigh_l``, …,
        ``index_01_l``) (:func:`jaxmotion.export.bvh.rig_name`); the hierarchy stays the
        body's (UE5's extra ``root``, ``spine_02``, ``spine_04`` and ``neck_02`` are in its
        BVH only).
    Returns:
      the path written. See the module docstring for the file's layout.
    """
    from jaxmotion.body.model import load_mannequin, shaped_rest_host
    from jaxmotion.export.bvh import check_skeleton, rig_name

    check_skeleton(skeleton)  # refused before any work
    go, bp, tr = smplx_motion(global_orient, body_pose, transl)
    k, t = go.shape[:2]
    fps = check_fps(fps)
    if not np.isfinite(spacing):
        raise ValueError(f"spacing must be finite, got {spacing}")
    betas = _sample_betas(betas, k)
    if scene_xyz is not None:
        xyz, rgb = scene_points(scene_xyz, scene_rgb)
        if scene_faces is not None:
            scene_faces = check_array("scene_faces", scene_faces, (None, 3), np.int64)
            if scene_faces.size and (scene_faces.min() < 0 or scene_faces.max() >= len(xyz)):
                raise ValueError(f"scene_faces index vertices outside [0, {len(xyz)})")
    elif scene_rgb is not None or scene_faces is not None:
        raise ValueError("scene_rgb / scene_faces given without scene_xyz")
    buf = _Buffer()
    gltf: dict = {
        "asset": {"version": "2.0", "generator": f"jaxmotion {__version__}"},
        "scene": 0,
        "nodes": [{"name": "world", "rotation": _Y_UP_ROOT, "children": []}],
        "meshes": [],
        "materials": [],
        "skins": [],
    }
    nodes, world = gltf["nodes"], gltf["nodes"][0]
    body_nodes = []

    # --- the body mesh of each distinct shape
    shapes: dict[tuple, dict] = {}
    for s in range(k):
        key = () if betas is None else tuple(betas[s])
        if key in shapes:
            continue
        m = model if model is not None else load_mannequin(None if betas is None else betas[s])
        v_rest, j_rest = shaped_rest_host(m, None if betas is None else betas[s])
        keep, parents, column, names = _named_joints(m)
        names = [rig_name(n, skeleton) for n in names]
        faces = np.asarray(m.faces, np.int64)
        normals = vertex_normals(v_rest, faces)
        normals[~np.any(normals, axis=1)] = [0.0, 1.0, 0.0]  # glTF wants unit normals everywhere
        folded = np.asarray(m.weights, np.float64) @ np.eye(len(keep))[column]
        joint_idx, weights = strongest_influences(folded, _INFLUENCES)
        ibm = np.tile(np.eye(4), (len(keep), 1, 1))
        ibm[:, :3, 3] = -j_rest[keep]
        shapes[key] = {
            "model": m,
            "j_rest": j_rest,
            "keep": keep,
            "parents": parents,
            "names": names,
            "attributes": {
                "POSITION": buf.add(v_rest.astype(np.float32), target=_ARRAY_BUFFER, bounds=True),
                "NORMAL": buf.add(normals.astype(np.float32), target=_ARRAY_BUFFER),
                "JOINTS_0": buf.add(
                    joint_idx.astype(np.uint8 if len(keep) <= 256 else np.uint16),
                    target=_ARRAY_BUFFER,
                ),
                "WEIGHTS_0": buf.add(weights.astype(np.float32), target=_ARRAY_BUFFER),
            },
            "indices": buf.add(
                faces.reshape(-1).astype(np.uint16 if len(v_rest) <= 65535 else np.uint32),
                target=_ELEMENT_ARRAY_BUFFER,
            ),
            # column-major 4x4, as glTF stores matrices
            "ibm": buf.add(ibm.transpose(0, 2, 1).reshape(-1, 16).astype(np.float32)),
        }

    # --- one skeleton, skin, material and mesh node per sample
    animation = {"name": "motion", "channels": [], "samplers": []}
    times = buf.add((np.arange(t) / fps).astype(np.float32), bounds=True)

    def animate(node: int, path_: str, values: np.ndarray) -> None:
        sampler = buf.add(values.astype(np.float32))
        animation["samplers"].append({"input": times, "output": sampler, "interpolation": "LINEAR"})
        animation["channels"].append(
            {"sampler": len(animation["samplers"]) - 1, "target": {"node": node, "path": path_}}
        )

    for s in range(k):
        shape = shapes[() if betas is None else tuple(betas[s])]
        m, j_rest = shape["model"], shape["j_rest"]
        num = m.num_joints
        aa = np.concatenate(
            [
                np.concatenate([go[s][:, None], bp[s]], axis=1),
                np.broadcast_to(
                    np.asarray(m.fixed_pose, np.float64)[NUM_JOINTS:], (t, num - NUM_JOINTS, 3)
                ),
            ],
            axis=1,
        )
        keep, parents, names = shape["keep"], shape["parents"], shape["names"]
        quat = rotvec_to_quat(aa[:, keep].reshape(-1, 3))
        quat = _continuous(quat.reshape(t, len(keep), 4))
        root_pos = j_rest[0] + tr[s] + [s * spacing, 0.0, 0.0]
        base = len(nodes) + 1  # after the sample's own node
        world["children"].append(len(nodes))
        nodes.append({"name": f"sample{s}", "children": [base]})
        for i, j in enumerate(keep):
            offset = root_pos[0] if i == 0 else j_rest[j] - j_rest[keep[parents[i]]]
            node = {"name": names[i], "translation": offset.tolist(), "rotation": quat[0, i].tolist()}
            children = [base + c for c in range(len(keep)) if parents[c] == i]
            if children:
                node["children"] = children
            nodes.append(node)
        animate(base, "translation", root_pos)
        for i in range(NUM_JOINTS):  # the body joints come first, in SMPL-X's order
            animate(base + i, "rotation", quat[:, i])
        gltf["skins"].append(
            {
                "name": f"sample{s}",
                "joints": list(range(base, base + len(keep))),
                "inverseBindMatrices": shape["ibm"],
                "skeleton": base,
            }
        )
        gltf["materials"].append(
            {
                "name": f"body{s}",
                "pbrMetallicRoughness": {
                    "baseColorFactor": [*PALETTE[s % len(PALETTE)], 1.0],
                    "metallicFactor": 0.0,
                    "roughnessFactor": 0.7,
                },
            }
        )
        gltf["meshes"].append(
            {
                "name": f"body{s}",
                "primitives": [
                    {
                        "attributes": shape["attributes"],
                        "indices": shape["indices"],
                        "material": len(gltf["materials"]) - 1,
                        "mode": 4,
                    }
                ],
            }
        )
        body_nodes.append(len(nodes))
        nodes.append({"name": f"body{s}", "mesh": len(gltf["meshes"]) - 1, "skin": s})
    gltf["animations"] = [animation]

    # --- the scene, under the z-up -> y-up root
    if scene_xyz is not None:
        rgba = np.concatenate([np.round(rgb * 255), np.full((len(xyz), 1), 255)], axis=1)
        prim = {
            "attributes": {
                "POSITION": buf.add(xyz.astype(np.float32), target=_ARRAY_BUFFER, bounds=True),
                "COLOR_0": buf.add(rgba.astype(np.uint8), target=_ARRAY_BUFFER, normalized=True),
            }
        }
        material = {
            "name": "scene",
            "pbrMetallicRoughness": {"metallicFactor": 0.0, "roughnessFactor": 1.0},
        }
        if scene_faces is not None:
            prim["indices"] = buf.add(
                scene_faces.reshape(-1).astype(np.uint32), target=_ELEMENT_ARRAY_BUFFER
            )
            prim["mode"] = 4
            material["doubleSided"] = True  # scans are not consistently oriented
        else:
            prim["mode"] = 0
            material["extensions"] = {"KHR_materials_unlit": {}}
            gltf["extensionsUsed"] = ["KHR_materials_unlit"]
        gltf["materials"].append(material)
        prim["material"] = len(gltf["materials"]) - 1
        gltf["meshes"].append({"name": "scene", "primitives": [prim]})
        world["children"].append(len(nodes))
        nodes.append({"name": "scene", "mesh": len(gltf["meshes"]) - 1})

    gltf["scenes"] = [{"name": "jaxmotion", "nodes": [0, *body_nodes]}]
    gltf["accessors"], gltf["bufferViews"] = buf.accessors, buf.views
    gltf["buffers"] = [{"byteLength": buf.size}]
    header = json.dumps(gltf, separators=(",", ":")).encode()
    header += b" " * (-len(header) % 4)
    binary = b"".join(buf.parts)
    total = 12 + 8 + len(header) + 8 + len(binary)
    with atomic_open(path, "wb") as f:
        f.write(struct.pack("<III", 0x46546C67, 2, total))  # "glTF", version 2
        f.write(struct.pack("<II", len(header), 0x4E4F534A) + header)  # "JSON"
        f.write(struct.pack("<II", len(binary), 0x004E4942))  # "BIN\0"
        f.write(binary)
    return Path(path)
