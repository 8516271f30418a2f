"""glTF 2.0 skinned animations (``.glb``, ``.gltf``) read as the 22 SMPL-X body joints.

A character exported from Blender, Mixamo, Unreal, Unity or a capture app is a skin (its
joints are nodes) and an animation (per node, keyed translation / rotation / scale). This
reader:

- parses the file itself (GLB's JSON and binary chunks; a ``.gltf`` with its buffers in
  ``data:`` URIs or files beside it), reads the accessors it needs as NumPy arrays (every
  component type, normalised integers included, byte strides, no sparse accessors);
- takes one skin (``skin=``, default the one with the most joints) and one animation
  (``animation=``, default the first; a file without one is read as its rest pose, one
  frame), samples every channel at a uniform rate (the keys' own rate, or ``fps``):
  ``LINEAR`` (slerp for rotations), ``STEP`` and ``CUBICSPLINE`` (its values, Hermite
  tangents dropped);
- poses the whole node tree each frame (nodes' ``matrix`` or TRS, the animated channels
  replacing them), so that an armature's own transform (a scale of 0.01 from an FBX, a
  y-up turn) is applied as a viewer would;
- maps the skin's joints to SMPL-X's with the BVH reader's maps: the built-in name maps
  first, else the automatic mapping from the names and the skeleton's shape in its rest
  pose (:mod:`jaxmotion.io.skeleton_map`);
- puts the result in jaxmotion's frame: glTF is y-up and in metres; a body whose head is not
  above its pelvis along y is read z-up, and a body far from a person's size is rescaled
  with the BVH reader's unit detection (``unit=``, ``up=`` override both).
"""

from __future__ import annotations

import base64
import json
import struct
from pathlib import Path

import numpy as np

from jaxmotion.io.motion import Motion, MotionFormatError, y_up_to_z_up

__all__ = ["load_gltf"]

_COMPONENTS = {5120: np.int8, 5121: np.uint8, 5122: np.int16, 5123: np.uint16, 5125: np.uint32,
               5126: np.float32}
_WIDTH = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT2": 4, "MAT3": 9, "MAT4": 16}


def _read(path: Path) -> tuple[dict, list[bytes]]:
    """The glTF JSON and its buffers' bytes."""
    data = path.read_bytes()
    if data[:4] == b"glTF":
        if len(data) < 20:
            raise MotionFormatError(f"{path}: a truncated GLB file")
        _, _, total = struct.unpack_from("<III", data, 0)
        chunks, at = [], 12
        while at + 8 <= min(total, len(data)):
            n, kind = struct.unpack_from("<II", data, at)
            chunks.append((kind, data[at + 8: at + 8 + n]))
            at += 8 + n
        js = next((c for k, c in chunks if k == 0x4E4F534A), None)
        if js is None:
            raise MotionFormatError(f"{path}: a GLB file without its JSON chunk")
        gltf = json.loads(js.decode("utf-8"))
        binary = next((c for k, c in chunks if k == 0x004E4942), b"")
    else:
        try:
            gltf = json.loads(data.decode("utf-8"))
        except (UnicodeDecodeError, json.JSONDecodeError) as e:
            raise MotionFormatError(f"{path}: neither a GLB nor a glTF JSON file ({e})") from e
        binary = b""
    buffers = []
    for i, buf in enumerate(gltf.get("buffers", [])):
        uri = buf.get("uri")
        if uri is None:
            buffers.append(binary)
        elif uri.startswith("data:"):
            buffers.append(base64.b64decode(uri.partition(",")[2]))
        else:
            file = path.parent / uri
            if not file.is_file():
                raise MotionFormatError(f"{path}: buffer {i} names {uri}, which is not beside "
                                        "the file")
            buffers.append(file.read_bytes())
    return gltf, buffers


def _accessor(gltf: dict, buffers: list[bytes], i: int) -> np.ndarray:
    acc = gltf["accessors"][i]
    if "sparse" in acc:
        raise MotionFormatError("sparse glTF accessors are not read; re-export without them")
    dtype = np.dtype(_COMPONENTS[acc["componentType"]]).newbyteorder("<")
    width, count = _WIDTH[acc["type"]], acc["count"]
    if "bufferView" not in acc:
        return np.zeros((count, width), np.float32)
    view = gltf["bufferViews"][acc["bufferView"]]
    raw = buffers[view["buffer"]]
    start = view.get("byteOffset", 0) + acc.get("byteOffset", 0)
    stride = view.get("byteStride") or dtype.itemsize * width
    rows = np.ndarray((count, width), dtype, raw, start, (stride, dtype.itemsize))
    out = rows.astype(np.float64)
    if acc.get("normalized") and dtype.kind in "iu":
        out = np.maximum(out / np.iinfo(dtype).max, -1.0)
    return out


def _quat_matrix(q: np.ndarray) -> np.ndarray:
    """``[..., 4]`` (x, y, z, w) -> ``[..., 3, 3]``."""
    q = q / np.maximum(np.linalg.norm(q, axis=-1, keepdims=True), 1e-12)
    x, y, z, w = np.moveaxis(q, -1, 0)
    return np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w),
                     2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w),
                     2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
                    -1).reshape(*q.shape[:-1], 3, 3)


def _slerp(a, b, t):
    dot = np.sum(a * b, -1, keepdims=True)
    b = np.where(dot < 0, -b, b)
    dot = np.abs(dot)
    theta = np.arccos(np.clip(dot, -1.0, 1.0))
    small = theta < 1e-6
    s = np.sin(theta)
    wa = np.where(small, 1 - t, np.sin((1 - t) * theta) / np.where(small, 1, s))
    wb = np.where(small, t, np.sin(t * theta) / np.where(small, 1, s))
    return wa * a + wb * b


def _sample(times, values, interpolation, at, rotation):
    """A channel's values at the times ``at``."""
    if interpolation == "CUBICSPLINE":  # (in-tangent, value, out-tangent) per key
        values = values.reshape(len(times), 3, -1)[:, 1]
    i = np.clip(np.searchsorted(times, at, side="right") - 1, 0, len(times) - 1)
    j = np.minimum(i + 1, len(times) - 1)
    if interpolation == "STEP" or len(times) == 1:
        return values[i]
    span = np.where(j > i, times[j] - times[i], 1.0)
    t = np.clip((at - times[i]) / span, 0.0, 1.0)[:, None]
    if rotation:
        return _slerp(values[i], values[j], t)
    return values[i] + t * (values[j] - values[i])


def _local(node):
    """A node's rest transform ``(T [3], R [3, 3], S [3])`` or its ``matrix``."""
    if "matrix" in node:
        return np.asarray(node["matrix"], np.float64).reshape(4, 4).T  # column-major
    return (np.asarray(node.get("translation", [0, 0, 0]), np.float64),
            _quat_matrix(np.asarray(node.get("rotation", [0, 0, 0, 1]), np.float64)),
            np.asarray(node.get("scale", [1, 1, 1]), np.float64))


def load_gltf(path, *, skin: int | None = None, animation: int = 0, fps: float | None = None,
              joint_map="auto", unit="auto", up: str = "auto") -> Motion:
    """Read a glTF skinned animation as a :class:`~jaxmotion.io.Motion` (module docstring).

    Args:
      path: ``.glb`` or ``.gltf``.
      skin: which skin (default: the one with the most joints).
      animation: which animation (default the first).
      fps: the rate to sample the animation at (default: its keys' own).
      joint_map: as :func:`~jaxmotion.io.load_bvh` (``"auto"``, a built-in map, a dict or a
        JSON file) over the skin's joint names.
      unit: metres per file unit after the nodes' own transforms, or ``"auto"``.
      up: ``"auto"``, ``"y"`` (glTF's) or ``"z"``.
    Returns:
      joints ``[T, 22, 3]`` metres, z-up; ``info`` records the skin, the animation, the joint
      map and its confidence and the joint each SMPL-X joint is read from.
    Raises MotionFormatError naming the file and the fix.
    """
    from jaxmotion.geometry.skeleton import JOINT_NAMES, NUM_JOINTS
    from jaxmotion.io.bvh import detect_unit, fill_missing_joints, resolve_joint_map

    path = Path(path)
    where = str(path)
    if up not in ("auto", "y", "z"):
        raise MotionFormatError(f"{where}: up must be 'auto', 'y' or 'z', got {up!r}")
    if not path.is_file():
        raise MotionFormatError(f"{where}: no such file")
    try:
        gltf, buffers = _read(path)
        nodes = gltf.get("nodes", [])
        skins = gltf.get("skins", [])
        if not skins:
            raise MotionFormatError(f"{where}: the file has no skin (no skeleton); give a "
                                    "character with an armature")
        if skin is None:
            skin = max(range(len(skins)), key=lambda k: len(skins[k]["joints"]))
        if not 0 <= skin < len(skins):
            raise MotionFormatError(f"{where}: skin {skin} does not exist (0..{len(skins) - 1})")
        joints = list(skins[skin]["joints"])
        parent = np.full(len(nodes), -1)
        for i, n in enumerate(nodes):
            for c in n.get("children", []):
                parent[c] = i
        anims = gltf.get("animations", [])
        channels = {}
        times_all = []
        if anims:
            if not 0 <= animation < len(anims):
                raise MotionFormatError(f"{where}: animation {animation} does not exist "
                                        f"(0..{len(anims) - 1})")
            anim = anims[animation]
            for ch in anim.get("channels", []):
                target = ch.get("target", {})
                if "node" not in target or target.get("path") not in ("translation",
                                                                       "rotation", "scale"):
                    continue
                smp = anim["samplers"][ch["sampler"]]
                times = _accessor(gltf, buffers, smp["input"])[:, 0]
                values = _accessor(gltf, buffers, smp["output"])
                channels[(target["node"], target["path"])] = (
                    times, values, smp.get("interpolation", "LINEAR"))
                times_all.append(times)
    except (KeyError, IndexError, ValueError, struct.error) as e:
        if isinstance(e, MotionFormatError):
            raise
        raise MotionFormatError(f"{where}: not a readable glTF file ({type(e).__name__}: {e})"
                                ) from e
    if times_all:
        keys = np.unique(np.concatenate(times_all))
        start, end = float(keys.min()), float(keys.max())
        if fps is None:
            steps = np.diff(keys)
            steps = steps[steps > 1e-6]
            fps = float(np.round(1.0 / np.median(steps), 3)) if len(steps) else 30.0
        at = start + np.arange(int(np.floor((end - start) * fps + 1e-6)) + 1) / fps
    else:
        fps = 30.0 if fps is None else float(fps)
        at = np.zeros(1)
    if not (np.isfinite(fps) and fps > 0):
        raise MotionFormatError(f"{where}: fps must be a positive number, got {fps}")

    def pose(at_times, animated=True):
        """World positions ``[T, len(nodes), 3]`` of every node."""
        t = len(at_times)
        world = [None] * len(nodes)

        def place(i):
            if world[i] is not None:
                return world[i]
            rest = _local(nodes[i])
            if isinstance(rest, np.ndarray):  # a matrix: not animatable by the spec
                m = np.broadcast_to(rest, (t, 4, 4)).copy()
            else:
                tr, rot, sc = (np.broadcast_to(x, (t, *x.shape)).copy() for x in rest)
                if animated:
                    if (i, "translation") in channels:
                        tr = _sample(*channels[(i, "translation")], at_times, False)
                    if (i, "rotation") in channels:
                        rot = _quat_matrix(_sample(*channels[(i, "rotation")], at_times, True))
                    if (i, "scale") in channels:
                        sc = _sample(*channels[(i, "scale")], at_times, False)
                m = np.zeros((t, 4, 4))
                m[:, :3, :3] = rot * sc[:, None, :]
                m[:, :3, 3] = tr
                m[:, 3, 3] = 1.0
            world[i] = m if parent[i] < 0 else place(parent[i]) @ m
            return world[i]

        return np.stack([place(j)[:, :3, 3] for j in joints], axis=1)

    names = [nodes[j].get("name", f"node{j}") for j in joints]
    index_of = {j: k for k, j in enumerate(joints)}
    parents = []
    for j in joints:  # the nearest ancestor that is a joint of the skin
        p = parent[j]
        while p >= 0 and p not in index_of:
            p = parent[p]
        parents.append(index_of.get(p, -1))
    if any(parents[k] >= k for k in range(len(parents)) if parents[k] >= 0):
        order = _parents_first(parents)
        joints = [joints[k] for k in order]
        names = [names[k] for k in order]
        remap = {old: new for new, old in enumerate(order)}
        parents = [remap[parents[k]] if parents[k] >= 0 else -1 for k in order]
    rest = pose(np.zeros(1), animated=False)[0]
    world = pose(at)
    report: dict = {}
    map_name, index = resolve_joint_map(names, joint_map, where=where,
                                        parents=np.asarray(parents), positions=rest,
                                        report=report)
    out = np.zeros((world.shape[0], NUM_JOINTS, 3))
    out[:, index >= 0] = world[:, index[index >= 0]]
    out = fill_missing_joints(out, index)
    if up == "auto":  # glTF is y-up; a file whose body stands along z says otherwise
        d = np.median(out[:, 15] - out[:, 0], axis=0)
        up = "z" if d[2] > abs(d[1]) and d[2] > abs(d[0]) else "y"
    scale = detect_unit(out[0], where) if unit == "auto" else float(unit)
    if not (np.isfinite(scale) and scale > 0):
        raise MotionFormatError(f"{where}: unit must be 'auto' or a positive number, got {unit!r}")
    out = out * scale
    if up == "y":
        out = y_up_to_z_up(out)
    return Motion(joints=out, fps=float(fps), source=where,
                  info={"format": "gltf", "skin": int(skin), "animation": int(animation)
                        if anims else None, "joint_map": map_name,
                        "joint_map_confidence": report["confidence"], "unit": scale, "up": up,
                        "joints_from": {n: (names[i] if i >= 0 else None)
                                        for n, i in zip(JOINT_NAMES, index)}})


def _parents_first(parents) -> list[int]:
    """An order of the joints with every parent before its children."""
    children = {k: [] for k in range(-1, len(parents))}
    for k, p in enumerate(parents):
        children[p].append(k)
    order, stack = [], list(reversed(children[-1]))
    while stack:
        k = stack.pop()
        order.append(k)
        stack.extend(reversed(children[k]))
    return order
