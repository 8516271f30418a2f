"""Scene point clouds and their file I/O (host-side numpy only, no JAX).

A :class:`Scene` is a coloured, labelled point cloud in the jaxmotion world frame (metres,
z-up, floor at z = 0) plus an object table. :func:`load_scene` reads meshes and point
clouds through trimesh (PLY / OBJ / GLB / GLTF / OFF / STL; meshes are sampled on their
surface, area-weighted) or the ``.npz`` files written by :func:`save_scene`.
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

if TYPE_CHECKING:  # imported on use: ~0.2 s that loading a .npz scene does not need
    import trimesh

SUPPORTED_EXTENSIONS = (".ply", ".obj", ".glb", ".gltf", ".off", ".stl", ".npz")
NPZ_KEYS = ("xyz", "rgb", "normal", "semantic", "instance", "objects", "name")
DEFAULT_MESH_POINTS = 100_000
SEMANTIC_PROPERTIES = ("label",)  # ScanNet / NYU40 per-vertex semantic id
INSTANCE_PROPERTIES = ("instance", "objectId", "instance_id")
# (x, y, z) -> (x, -z, y): a +90 degree rotation about x taking y-up files to z-up.
Y_UP_TO_Z_UP = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])
_GREY = 0.5
_UNIT_TOL = 1e-3


class SceneError(ValueError):
    """A scene file is missing, unsupported, unreadable or holds no usable geometry."""


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
        and ``front`` [3] list. Extra JSON-serialisable keys are kept.
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
        rgb = _checked("rgb", np.full((n, 3), _GREY) if self.rgb is None else self.rgb, n, 3)
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
def _ply_vertex_property(geom, names, n):
    """A raw PLY vertex property [n] (first of ``names`` present), or None."""
    raw = geom.metadata.get("_ply_raw") or {}  # trimesh keeps the parsed PLY elements here
    data = raw.get("vertex", {}).get("data") if isinstance(raw, Mapping) else None
    keys = () if data is None else data.keys() if isinstance(data, Mapping) else data.dtype.names
    for name in names:
        if name in (keys or ()):
            value = np.asarray(data[name]).reshape(-1)  # ASCII PLY columns come as [n, 1]
            return value if len(value) == n else None
    return None


def _vertex_colors(geom, n):
    """Per-vertex RGB [n, 3] in [0, 1] of a mesh or point cloud, or None when undefined."""
    import trimesh

    if isinstance(geom, trimesh.PointCloud):
        c = np.asarray(geom.colors)
    elif geom.visual.kind == "vertex":
        c = np.asarray(geom.visual.vertex_colors)
    elif geom.visual.kind == "texture":
        try:  # image textures need PIL; a plain material colour works without
            c = np.asarray(geom.visual.to_color().vertex_colors)
        except Exception:
            c = np.asarray(getattr(geom.visual.material, "main_color", None))
    else:
        return None
    if c.ndim == 1 and c.shape[0] in (3, 4):  # one colour for the whole material
        c = np.broadcast_to(c, (n, c.shape[0]))
    if c.ndim != 2 or c.shape[0] != n or c.shape[1] < 3:
        return None
    return c[:, :3].astype(np.float64) / (255.0 if c.dtype.kind in "iu" else 1.0)


def _vertex_data(geom):
    """Per-vertex Scene arrays of one mesh / point cloud (grey, zero normals, -1 if unknown)."""
    n = len(geom.vertices)
    rgb = _vertex_colors(geom, n)
    labels = [_ply_vertex_property(geom, p, n) for p in (SEMANTIC_PROPERTIES, INSTANCE_PROPERTIES)]
    sem, ins = (np.full(n, -1, np.int64) if v is None else v.astype(np.int64) for v in labels)
    normal = [_ply_vertex_property(geom, (c,), n) for c in ("nx", "ny", "nz")]
    normal = np.zeros((n, 3)) if any(c is None for c in normal) else np.stack(normal, 1)
    normal, norms = normal.astype(np.float64), np.linalg.norm(normal, axis=1, keepdims=True)
    return dict(xyz=np.asarray(geom.vertices, np.float64),
                rgb=np.full((n, 3), _GREY) if rgb is None else rgb,
                normal=np.where(norms > 1e-8, normal / np.maximum(norms, 1e-8), 0.0),
                semantic=sem, instance=ins)


def _concatenate(parts):
    return {k: np.concatenate([p[k] for p in parts]) for k in parts[0]}


def _sample_meshes(meshes, count, seed):
    """Area-weighted surface samples of all meshes in one draw -> Scene arrays (or None)."""
    import trimesh

    parts = [_vertex_data(m) for m in meshes]
    offsets = np.cumsum([0] + [len(m.vertices) for m in meshes])
    faces = np.concatenate([np.asarray(m.faces, np.int64) + o for m, o in zip(meshes, offsets)])
    corners = np.concatenate([  # RGB at each face corner [F, 3, 3]
        np.repeat(np.asarray(m.visual.face_colors)[:, None, :3] / 255.0, 3, axis=1)
        if m.visual.kind == "face" else p["rgb"][m.faces] for m, p in zip(meshes, parts)])
    v = _concatenate(parts)
    mesh = trimesh.Trimesh(v["xyz"], faces, process=False)
    if not mesh.area_faces.sum() > 0:
        return None
    xyz, fi, bary = trimesh.sample.sample_surface(mesh, count, return_barycentric=True, seed=seed)
    tri = faces[fi]
    normal = np.asarray(mesh.face_normals)[fi]
    # Face normals are exact on flat faces; file normals (PLY nx ny nz) only fix their sign.
    hint = np.einsum("nk,nkc->nc", bary, v["normal"][tri])
    normal = np.where((np.einsum("nc,nc->n", hint, normal) < 0)[:, None], -normal, normal)
    rgb = np.clip(np.einsum("nk,nkc->nc", bary, corners[fi]), 0.0, 1.0)
    nearest = tri[np.arange(len(tri)), np.argmax(bary, axis=1)]  # closest corner's labels
    return dict(xyz=xyz, rgb=rgb, normal=normal,
                semantic=v["semantic"][nearest], instance=v["instance"][nearest])


def _load_geometry(path, ext, num_points, seed):
    """Scene arrays of a mesh / point-cloud file read by trimesh."""
    import trimesh

    try:  # process=False keeps vertex order, so raw PLY vertex properties still line up
        geoms = trimesh.load_scene(str(path), process=False).dump()  # node transforms baked in
    except Exception as e:
        raise SceneError(f"{path}: trimesh could not parse this {ext} file ({type(e).__name__}: "
                         f"{e}); check that it is complete and really a valid {ext} file") from e
    has_faces = [isinstance(g, trimesh.Trimesh) and len(g.faces) > 0 for g in geoms]
    meshes = [g for g, f in zip(geoms, has_faces) if f]
    clouds = [g for g, f in zip(geoms, has_faces) if not f and len(getattr(g, "vertices", ())) and
              isinstance(g, (trimesh.Trimesh, trimesh.PointCloud))]
    if not meshes and not clouds:
        raise SceneError(f"{path}: the file holds no points or faces; export geometry into it")
    if not all(np.isfinite(np.asarray(g.vertices, np.float64)).all() for g in meshes + clouds):
        raise SceneError(f"{path}: the geometry has NaN/inf vertex coordinates; fix or remove them")
    if not meshes:  # point clouds: every point kept
        return _concatenate([_vertex_data(g) for g in clouds])
    # A surface is present: stray point clouds in the same file are ignored.
    arrays = _sample_meshes(meshes, num_points or DEFAULT_MESH_POINTS, seed)
    if arrays is None:
        raise SceneError(f"{path}: the mesh has zero surface area (all faces degenerate), so no "
                         "points can be sampled; check the file's faces and units")
    return arrays


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
    """Load a scene file as a z-up :class:`Scene` (metres).

    Meshes (any faces) give ``num_points`` area-weighted surface samples (default 100_000)
    with face normals, barycentric-interpolated colours (vertex, texture or face colours;
    grey 0.5 when none) and the labels of the nearest face corner. Point clouds
    (no faces) keep every point, or a seeded random subset of ``num_points`` when smaller,
    with their colours and PLY ``nx ny nz`` normals (zeros when absent). PLY vertex
    properties ``label`` -> ``semantic``; ``instance`` / ``objectId`` / ``instance_id`` ->
    ``instance``. ``.npz`` files from :func:`save_scene` load exactly (subset as above).

    Args:
      path: file path, one of :data:`SUPPORTED_EXTENSIONS` (case-insensitive).
      num_points: number of points wanted (> 0), see above.
      seed: sampling seed; the same seed gives identical points.
      up: ``'z'`` (file is z-up), ``'y'`` (rotate (x, y, z) -> (x, -z, y)) or ``'auto'``:
        ``'y'`` for .glb/.gltf (y-up by the glTF spec), ``'z'`` otherwise.
    Raises SceneError (missing/unknown/unparsable file, no geometry, NaN/inf, zero area).
    """
    path, ext = Path(path), Path(path).suffix.lower()
    if up not in ("auto", "y", "z"):
        raise ValueError(f"up must be 'auto', 'y' or 'z', got {up!r}")
    if num_points is not None and (not isinstance(num_points, (int, np.integer))
                                   or isinstance(num_points, bool) or num_points <= 0):
        raise SceneError(f"{path}: num_points must be a positive int or None, got {num_points!r}")
    if not path.is_file():
        raise SceneError(f"{path}: no such file; check the path (cwd is {os.getcwd()})")
    if ext not in SUPPORTED_EXTENSIONS:
        raise SceneError(f"{path}: unsupported extension {ext!r}; supported: "
                         f"{', '.join(SUPPORTED_EXTENSIONS)}; convert the file (e.g. in Blender)")
    if ext == ".npz":
        scene = _load_npz(path)
    else:
        try:
            scene = Scene(**_load_geometry(path, ext, num_points, seed), name=path.stem)
        except SceneError:
            raise
        except ValueError as e:
            raise SceneError(f"{path}: unusable data in the file: {e}") from e
    if num_points is not None and scene.num_points > num_points:  # point clouds and npz
        keep = np.random.default_rng(seed).choice(scene.num_points, num_points, replace=False)
        scene = scene.subset(np.sort(keep))
    if up == "y" or (up == "auto" and ext in (".glb", ".gltf")):
        scene = scene.transformed(Y_UP_TO_Z_UP)
    return scene


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


def scene_to_trimesh_points(scene: Scene) -> trimesh.PointCloud:
    """The scene's points as a ``trimesh.PointCloud`` with RGBA uint8 colours, for export."""
    import trimesh

    rgba = np.concatenate([np.round(scene.rgb * 255.0), np.full((scene.num_points, 1), 255.0)], 1)
    return trimesh.PointCloud(scene.xyz.astype(np.float64), colors=rgba.astype(np.uint8),
                              metadata={"name": scene.name})
