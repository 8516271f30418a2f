"""Scene point clouds and their file I/O (host-side numpy only, no JAX).

A :class:`Scene` is a coloured, labelled point cloud in the jaxmotion world frame (metres,
z-up, floor at z = 0) plus an object table. :func:`load_scene` reads meshes and point
clouds through trimesh (PLY / OBJ / GLB / GLTF / OFF / STL; meshes are sampled on their
surface, area-weighted, :mod:`~jaxmotion.scene.meshes`), the ``.npz`` files written by
:func:`save_scene`, ScanNet scan folders and PROX scene meshes (:mod:`~jaxmotion.scene.scans`).
"""

from __future__ import annotations

import dataclasses
import json
import os
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from jaxmotion._atomic import atomic_open
from jaxmotion.errors import SceneError
from jaxmotion.scene.meshes import DEFAULT_MESH_POINTS, GREY, read_geometry
from jaxmotion.scene.scans import find_scan, read_scan

if TYPE_CHECKING:  # imported on use: ~0.2 s that loading a .npz scene does not need
    import trimesh

__all__ = ["DEFAULT_MESH_POINTS", "NPZ_KEYS", "SUPPORTED_EXTENSIONS", "Y_UP_TO_Z_UP", "Scene",
           "SceneError", "load_scene", "load_scene_and_notes", "save_scene", "save_scene_ply",
           "scene_to_trimesh_points"]

SUPPORTED_EXTENSIONS = (".ply", ".obj", ".glb", ".gltf", ".off", ".stl", ".npz")
NPZ_KEYS = ("xyz", "rgb", "normal", "semantic", "instance", "objects", "name")
# (x, y, z) -> (x, -z, y): a +90 degree rotation about x taking y-up files to z-up.
Y_UP_TO_Z_UP = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])
_UNIT_TOL = 1e-3


def _checked(name, value, n, width=None):
    """Validated private copy: float32 [n, width], or int32 [n] when width is None."""
    a, shape = np.asarray(value), (n, width) if width else (n,)
    fits = a.ndim == len(shape) and all(w in (None, s) for w, s in zip(shape, a.shape))
    if a.dtype.kind not in ("fiu" if width else "iu") or not fits:
        want = ["N" if n is None else n, *shape[1:]]
        raise ValueError(f"Scene.{name} must be a {'real' if width else 'integer'} array of "
                         f"shape {want}, got {a.dtype} {a.shape}")
    if not width and a.size and (a.min() < -(2**31) or a.max() >= 2**31):
        raise ValueError(f"Scene.{name} has values outside the int32 range")
    a = a.astype(np.float32 if width else np.int32)  # always a copy; overflow shows up as inf
    if width and (bad := ~np.isfinite(a).all(axis=1)).any():
        raise ValueError(f"Scene.{name} has {int(bad.sum())} rows with NaN/inf "
                         f"(first: row {int(np.argmax(bad))})")
    return a


def _normalise_object(i, obj):
    """Checked copy of one object-table entry, vectors as lists of 3 floats."""
    where = f"Scene.objects[{i}]"
    if not isinstance(obj, Mapping):
        raise ValueError(f"{where} must be a dict, got {type(obj).__name__}")
    if missing := [k for k in ("id", "category", "bbox_min", "bbox_max") if k not in obj]:
        raise ValueError(f"{where} is missing keys {missing}")
    out = {k: v for k, v in obj.items() if v is not None}
    if isinstance(obj["id"], bool) or not isinstance(obj["id"], (int, np.integer)):
        raise ValueError(f"{where}['id'] must be an int, got {obj['id']!r}")
    if not isinstance(obj["category"], str):
        raise ValueError(f"{where}['category'] must be a str, got {obj['category']!r}")
    out["id"] = int(obj["id"])
    for key in ("bbox_min", "bbox_max", "front", "surface_height"):
        if key in out:
            v = np.asarray(out[key])
            shape = () if key == "surface_height" else (3,)
            if v.dtype.kind not in "fiu" or v.shape != shape or not np.isfinite(v).all():
                raise ValueError(f"{where}[{key!r}] must be {len(shape) * 3 or 1} finite "
                                 f"number(s), got {out[key]!r}")
            out[key] = float(v) if key == "surface_height" else [float(x) for x in v]
    if any(lo > hi for lo, hi in zip(out["bbox_min"], out["bbox_max"])):
        raise ValueError(f"{where} has bbox_min {out['bbox_min']} above bbox_max {out['bbox_max']}")
    return out


@dataclasses.dataclass(frozen=True, eq=False, repr=False)
class Scene:
    """A scene as a point cloud in metres, z-up; arrays are read-only private copies.

    Attributes:
      xyz: [N, 3] float32 point positions (m).
      rgb: [N, 3] float32 colours in [0, 1] (default grey 0.5).
      normal: [N, 3] float32 unit normals, zero rows where unknown (default zeros).
      semantic: [N] int32 semantic class id (e.g. NYU40), -1 = unknown (default).
      instance: [N] int32 object instance id, -1 = none (default).
      objects: object table; dicts with ``id`` int, ``category`` str, ``bbox_min`` /
        ``bbox_max`` [3] lists (m, axis-aligned), optional ``surface_height`` float (m)
        and ``front`` [3] list. Extra JSON-serialisable keys are kept. When none is given
        and points carry ``instance`` ids, it is derived from the labels
        (:func:`jaxmotion.scene.objects.table_from_labels`): the one table every stage uses.
      name: free-form scene name.
    """

    xyz: np.ndarray
    rgb: np.ndarray | None = None
    normal: np.ndarray | None = None
    semantic: np.ndarray | None = None
    instance: np.ndarray | None = None
    objects: tuple[dict, ...] = ()
    name: str = ""

    def __post_init__(self):
        xyz = _checked("xyz", self.xyz, None, 3)
        n = len(xyz)
        rgb = _checked("rgb", np.full((n, 3), GREY) if self.rgb is None else self.rgb, n, 3)
        if rgb.size and (rgb.min() < 0.0 or rgb.max() > 1.0):
            raise ValueError(f"Scene.rgb must lie in [0, 1], got [{rgb.min()}, {rgb.max()}]")
        normal = _checked("normal", np.zeros((n, 3)) if self.normal is None else self.normal, n, 3)
        norms = np.linalg.norm(normal, axis=1)
        bad = (norms > _UNIT_TOL) & (np.abs(norms - 1.0) > _UNIT_TOL)
        if bad.any():
            raise ValueError(f"Scene.normal: {int(bad.sum())} rows are neither unit length nor 0")
        unknown = np.full(n, -1)
        semantic = _checked("semantic", unknown if self.semantic is None else self.semantic, n)
        instance = _checked("instance", unknown if self.instance is None else self.instance, n)
        objects = tuple(_normalise_object(i, o) for i, o in enumerate(self.objects))
        if not objects and (instance >= 0).any():  # labelled points without a table: derive it
            from jaxmotion.scene.objects import table_from_labels

            objects = table_from_labels(xyz, semantic, instance)
        ids = [o["id"] for o in objects]
        if len(set(ids)) != len(ids):
            raise ValueError(f"Scene.objects has duplicate ids: {sorted(ids)}")
        if not isinstance(self.name, str):
            raise ValueError(f"Scene.name must be a str, got {type(self.name).__name__}")
        arrays = dict(xyz=xyz, rgb=rgb, normal=normal, semantic=semantic, instance=instance)
        for key, value in arrays.items():
            value.setflags(write=False)
            object.__setattr__(self, key, value)
        object.__setattr__(self, "objects", objects)

    def __repr__(self):
        return f"Scene({self.name!r}, num_points={self.num_points}, objects={len(self.objects)})"

    @property
    def num_points(self) -> int:
        """N, the number of points."""
        return len(self.xyz)

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Axis-aligned bounds of the points: (min [3], max [3]) float32, metres."""
        if self.num_points == 0:
            raise ValueError(f"scene {self.name!r} has no points, so no bounds")
        return self.xyz.min(axis=0), self.xyz.max(axis=0)

    def object(self, object_id: int) -> dict:
        """The object-table entry with ``id == object_id`` (KeyError naming valid ids)."""
        for obj in self.objects:
            if obj["id"] == object_id:
                return dict(obj)  # a copy: the table inside a frozen Scene stays as built
        valid = [o["id"] for o in self.objects]
        raise KeyError(f"scene {self.name!r} has no object {object_id!r}; valid ids: {valid}")

    def subset(self, selection) -> Scene:
        """Points picked by a bool mask [N] or int indices [M]; the object table is kept."""
        sel, n = np.asarray(selection), self.num_points
        if sel.dtype == bool and sel.shape == (n,):
            sel = np.flatnonzero(sel)
        elif sel.dtype.kind not in "iu" or sel.ndim != 1:
            raise ValueError(f"subset takes a bool mask [{n}] or int indices [M], "
                             f"got {sel.dtype} {sel.shape}")
        elif sel.size and (sel.min() < -n or sel.max() >= n):
            raise IndexError(f"indices out of range for a scene of {n} points")
        return dataclasses.replace(self, xyz=self.xyz[sel], rgb=self.rgb[sel],
                                   normal=self.normal[sel], semantic=self.semantic[sel],
                                   instance=self.instance[sel])

    def transformed(self, rotation, translation=(0.0, 0.0, 0.0)) -> Scene:
        """Apply ``x -> R x + t`` (R [3, 3] proper rotation, t [3] metres).

        Normals and object ``front`` vectors are rotated; boxes become the axis-aligned box
        of their 8 moved corners (conservative). ``surface_height`` moves with t_z when R
        keeps the z axis, and is dropped otherwise (it no longer means a height).
        """
        r, t = np.asarray(rotation, np.float64), np.asarray(translation, np.float64)
        if r.shape != (3, 3) or t.shape != (3,):
            raise ValueError(f"rotation must be [3, 3], translation [3]; got {r.shape}, {t.shape}")
        if not (np.allclose(r @ r.T, np.eye(3), atol=1e-4) and np.linalg.det(r) > 0):
            raise ValueError("rotation must be a proper rotation matrix (orthonormal, det +1)")
        objects = []
        for obj in self.objects:
            box = np.array([obj["bbox_min"], obj["bbox_max"]])
            corners = np.array([[box[k >> a & 1, a] for a in range(3)] for k in range(8)]) @ r.T + t
            new = dict(obj, bbox_min=corners.min(0).tolist(), bbox_max=corners.max(0).tolist())
            if "front" in obj:
                new["front"] = (r @ np.array(obj["front"])).tolist()
            if new.pop("surface_height", None) is not None and abs(r[2, 2] - 1.0) < 1e-6:
                new["surface_height"] = obj["surface_height"] + float(t[2])
            objects.append(new)
        return dataclasses.replace(self, xyz=self.xyz.astype(np.float64) @ r.T + t,
                                   normal=self.normal.astype(np.float64) @ r.T,
                                   objects=tuple(objects))

    def translated(self, translation) -> Scene:
        """Shift points and boxes by t [3] metres."""
        return self.transformed(np.eye(3), translation)


# ------------------------------------------------------------------------------ loading
def _load_npz(path):
    try:
        with np.load(path, allow_pickle=False) as z:
            if missing := [k for k in NPZ_KEYS if k not in z.files]:
                raise SceneError(f"{path}: scene .npz is missing keys {missing} (needs "
                                 f"{list(NPZ_KEYS)}); write it with jaxmotion.scene.save_scene")
            data = {k: z[k] for k in NPZ_KEYS}
        objects, name = json.loads(str(data.pop("objects"))), str(data.pop("name"))
        if not isinstance(objects, list):
            raise ValueError("'objects' must be a JSON list")
        return Scene(**data, objects=tuple(objects), name=name)
    except SceneError:
        raise
    except Exception as e:
        raise SceneError(f"{path}: not a valid scene .npz ({type(e).__name__}: {e}); "
                         "re-create it with jaxmotion.scene.save_scene") from e


def load_scene(path, *, num_points: int | None = None, seed: int = 0, up: str = "auto") -> Scene:
    """Load a scene file or scan as a z-up :class:`Scene` (metres).

    Meshes (any faces) give ``num_points`` area-weighted surface samples (default 100_000)
    with face normals, barycentric-interpolated colours (vertex, texture or face colours;
    grey 0.5 when none) and the labels of the nearest face corner. Point clouds
    (no faces) keep every point, or a seeded random subset of ``num_points`` when smaller,
    with their colours and PLY ``nx ny nz`` normals (zeros when absent). PLY vertex
    properties ``label`` -> ``semantic``; ``instance`` / ``objectId`` / ``instance_id`` ->
    ``instance``. ``.npz`` files from :func:`save_scene` load exactly (subset as above).
    A ScanNet scan folder (or its ``_vh_clean_2.ply`` with the annotations beside it) gives
    its objects and categories in the axis-aligned frame; a PROX ``scenes/<Name>.ply`` has
    its floor moved to z = 0 (:mod:`jaxmotion.scene.scans`, :func:`load_scene_and_notes`).

    Args:
      path: file path, one of :data:`SUPPORTED_EXTENSIONS` (case-insensitive), or a ScanNet
        scan folder.
      num_points: number of points wanted (> 0), see above.
      seed: sampling seed; the same seed gives identical points.
      up: ``'z'`` (file is z-up), ``'y'`` (rotate (x, y, z) -> (x, -z, y)) or ``'auto'``:
        ``'y'`` for .glb/.gltf (y-up by the glTF spec), ``'z'`` otherwise.
    Raises SceneError (missing/unknown/unparsable file, no geometry, NaN/inf, zero area, a
    scan missing its annotation files).
    """
    return load_scene_and_notes(path, num_points=num_points, seed=seed, up=up)[0]


def load_scene_and_notes(path, *, num_points: int | None = None, seed: int = 0,
                         up: str = "auto") -> tuple[Scene, tuple[str, ...]]:
    """:func:`load_scene`, and notes for the user on what a scan held (empty for a plain
    file): the objects read and the alignment applied (ScanNet), the floor shift and the
    missing labels (PROX)."""
    path, ext = Path(path), Path(path).suffix.lower()
    if up not in ("auto", "y", "z"):
        raise ValueError(f"up must be 'auto', 'y' or 'z', got {up!r}")
    if num_points is not None and (not isinstance(num_points, (int, np.integer))
                                   or isinstance(num_points, bool) or num_points <= 0):
        raise SceneError(f"{path}: num_points must be a positive int or None, got {num_points!r}")
    scan, notes = find_scan(path), ()
    if scan is not None and up == "y":
        raise SceneError(f"{path}: {scan.layout} scans are z-up; leave out up='y' (--up y)")
    if scan is None and not path.is_file():
        raise SceneError(f"{path}: no such file; check the path (cwd is {os.getcwd()})")
    if scan is None and ext not in SUPPORTED_EXTENSIONS:
        raise SceneError(f"{path}: unsupported extension {ext!r}; supported: "
                         f"{', '.join(SUPPORTED_EXTENSIONS)}; convert the file (e.g. in Blender)")
    if scan is not None:
        data = read_scan(scan, num_points, seed)
        notes = data.notes
        try:
            scene = Scene(**data.arrays, objects=data.objects, name=data.name)
        except ValueError as e:
            raise SceneError(f"{path}: unusable data in the scan: {e}") from e
    elif ext == ".npz":
        scene = _load_npz(path)
    else:
        try:
            scene = Scene(**read_geometry(path, ext, num_points, seed), name=path.stem)
        except SceneError:
            raise
        except ValueError as e:
            raise SceneError(f"{path}: unusable data in the file: {e}") from e
    if num_points is not None and scene.num_points > num_points:  # point clouds and npz
        keep = np.random.default_rng(seed).choice(scene.num_points, num_points, replace=False)
        scene = scene.subset(np.sort(keep))
    if up == "y" or (up == "auto" and ext in (".glb", ".gltf")):
        scene = scene.transformed(Y_UP_TO_Z_UP)
    return scene, notes


def save_scene(scene: Scene, path) -> Path:
    """Write ``scene`` to a ``.npz`` file atomically (temp file + ``os.replace``).

    Keys: ``xyz rgb normal semantic instance`` arrays, ``objects`` (JSON string of the
    object list) and ``name``; readable with ``np.load(..., allow_pickle=False)``. Returns path.
    """
    path = Path(path)
    if path.suffix.lower() != ".npz":
        raise SceneError(f"{path}: save_scene writes .npz files; give a path ending in .npz")
    if not path.parent.is_dir():
        raise SceneError(f"{path}: folder {path.parent} does not exist; create it first")
    try:
        objects = json.dumps(list(scene.objects))
    except (TypeError, ValueError) as e:
        raise SceneError(f"{path}: the object table is not JSON-serialisable ({e})") from e
    with atomic_open(path, "wb") as f:  # interrupted or failed: no half-written file
        np.savez(f, xyz=scene.xyz, rgb=scene.rgb, normal=scene.normal,
                 semantic=scene.semantic, instance=scene.instance,
                 objects=np.array(objects), name=np.array(scene.name))
    return path


def save_scene_ply(scene: Scene, path) -> Path:
    """Write ``scene`` as a binary PLY point cloud atomically: ``x y z`` and ``nx ny nz``
    float, ``red green blue`` uchar, ``label`` ushort (the semantic id; 0 = unknown, as
    ScanNet's unannotated) and ``instance`` int (−1 = none), which :func:`load_scene` (and
    ScanNet-style tools) read back; the object table is derived again from the labels on
    loading (categories from the ids; confidences and surfaces live in the ``.npz``)."""
    path = Path(path)
    if path.suffix.lower() != ".ply":
        raise SceneError(f"{path}: save_scene_ply writes .ply files; give a path ending in .ply")
    if not path.parent.is_dir():
        raise SceneError(f"{path}: folder {path.parent} does not exist; create it first")
    fields = [("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("nx", "<f4"), ("ny", "<f4"),
              ("nz", "<f4"), ("red", "u1"), ("green", "u1"), ("blue", "u1"), ("label", "<u2"),
              ("instance", "<i4")]
    v = np.empty(scene.num_points, np.dtype(fields))
    for i, c in enumerate("xyz"):
        v[c], v["n" + c] = scene.xyz[:, i], scene.normal[:, i]
    for i, c in enumerate(("red", "green", "blue")):
        v[c] = np.round(scene.rgb[:, i] * 255)
    v["label"] = np.clip(scene.semantic, 0, 65535)
    v["instance"] = scene.instance
    kinds = {"<f4": "float", "u1": "uchar", "<u2": "ushort", "<i4": "int"}
    header = "".join(["ply\nformat binary_little_endian 1.0\n",
                      f"element vertex {len(v)}\n",
                      *(f"property {kinds[t]} {n}\n" for n, t in fields), "end_header\n"])
    with atomic_open(path, "wb") as f:
        f.write(header.encode() + v.tobytes())
    return path


def scene_to_trimesh_points(scene: Scene) -> trimesh.PointCloud:
    """The scene's points as a ``trimesh.PointCloud`` with RGBA uint8 colours, for export."""
    import trimesh

    rgba = np.concatenate([np.round(scene.rgb * 255.0), np.full((scene.num_points, 1), 255.0)], 1)
    return trimesh.PointCloud(scene.xyz.astype(np.float64), colors=rgba.astype(np.uint8),
                              metadata={"name": scene.name})
