"""Reading mesh and point-cloud files into Scene arrays (host-side numpy and trimesh, no JAX).

:func:`read_geometry` turns one file into the per-point arrays of a
:class:`~jaxmotion.scene.Scene` (``xyz rgb normal semantic instance``): meshes are sampled on
their surface (area-weighted, :func:`sample_meshes`), point clouds keep every point. The
scene readers (:func:`jaxmotion.scene.load_scene`, :mod:`jaxmotion.scene.scans`) build on it.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from jaxmotion.constants import STRUCTURE_IDS
from jaxmotion.errors import SceneError

__all__ = ["DEFAULT_MESH_POINTS", "GREY", "INSTANCE_PROPERTIES", "SEMANTIC_PROPERTIES",
           "concatenate", "load_meshes", "read_geometry", "sample_meshes", "vertex_data"]

DEFAULT_MESH_POINTS = 100_000
SEMANTIC_PROPERTIES = ("label",)  # ScanNet / NYU40 per-vertex semantic id
INSTANCE_PROPERTIES = ("instance", "objectId", "instance_id")
GREY = 0.5  # the colour of points whose file has none


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


def _unlabelled_group(sem: np.ndarray) -> bool:
    """Whether the points of one instance id are mostly unannotated or structure (wall,
    floor, ceiling): the "no object" id of files that count their objects from 1."""
    other = (sem < 0) | np.isin(sem, list(STRUCTURE_IDS.values()))
    return bool(other.mean() >= 0.5)


def vertex_data(geom) -> dict:
    """Per-vertex Scene arrays of one mesh / point cloud (grey, zero normals, -1 if unknown):
    PLY ``label`` -> semantic (0, NYU40's "unannotated", -> -1), ``instance`` / ``objectId``
    / ``instance_id`` -> instance (0 -> -1 when the file has no negative id and its points
    are mostly unannotated or structure: the "none" of files that count objects from 1)."""
    n = len(geom.vertices)
    rgb = _vertex_colors(geom, n)
    labels = [_ply_vertex_property(geom, p, n) for p in (SEMANTIC_PROPERTIES, INSTANCE_PROPERTIES)]
    sem, ins = (np.full(n, -1, np.int64) if v is None else v.astype(np.int64) for v in labels)
    if labels[0] is not None:
        sem[sem == 0] = -1  # NYU40 / ScanNet label 0: unannotated
    if labels[1] is not None and (zero := ins == 0).any() and not (ins < 0).any() \
            and _unlabelled_group(sem[zero]):
        ins[zero] = -1  # instance 0 as "none" (ScanNet exports count objects from 1)
    normal = [_ply_vertex_property(geom, (c,), n) for c in ("nx", "ny", "nz")]
    normal = np.zeros((n, 3)) if any(c is None for c in normal) else np.stack(normal, 1)
    normal, norms = normal.astype(np.float64), np.linalg.norm(normal, axis=1, keepdims=True)
    return dict(xyz=np.asarray(geom.vertices, np.float64),
                rgb=np.full((n, 3), GREY) if rgb is None else rgb,
                normal=np.where(norms > 1e-8, normal / np.maximum(norms, 1e-8), 0.0),
                semantic=sem, instance=ins)


def concatenate(parts: list[dict]) -> dict:
    """The per-point arrays of several parts, one after the other."""
    return {k: np.concatenate([p[k] for p in parts]) for k in parts[0]}


def sample_meshes(meshes, count: int, seed: int, labels=None) -> dict | None:
    """Area-weighted surface samples of all meshes in one draw -> Scene arrays (or None when
    the meshes have no area). Face normals (oriented by file normals where present),
    barycentric colours, and the labels of the nearest face corner: the files' own, or
    ``labels = (semantic [V], instance [V])`` over the meshes' vertices in order."""
    import trimesh

    parts = [vertex_data(m) for m in meshes]
    offsets = np.cumsum([0] + [len(m.vertices) for m in meshes])
    faces = np.concatenate([np.asarray(m.faces, np.int64) + o for m, o in zip(meshes, offsets)])
    corners = np.concatenate([  # RGB at each face corner [F, 3, 3]
        np.repeat(np.asarray(m.visual.face_colors)[:, None, :3] / 255.0, 3, axis=1)
        if m.visual.kind == "face" else p["rgb"][m.faces] for m, p in zip(meshes, parts)])
    v = concatenate(parts)
    if labels is not None:
        v["semantic"], v["instance"] = (np.asarray(a, np.int64) for a in labels)
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


def load_meshes(path, ext: str) -> tuple[list, list]:
    """(meshes with faces, point clouds) of a file read by trimesh, vertex order kept;
    SceneError when it cannot be parsed, holds no geometry or has NaN/inf vertices."""
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
    return meshes, clouds


def read_geometry(path, ext: str, num_points: int | None, seed: int) -> dict:
    """Scene arrays of a mesh / point-cloud file read by trimesh: ``num_points`` surface
    samples (default :data:`DEFAULT_MESH_POINTS`) of its meshes, or every point of a file
    without faces."""
    meshes, clouds = load_meshes(path, ext)
    if not meshes:  # point clouds: every point kept
        return concatenate([vertex_data(g) for g in clouds])
    # A surface is present: stray point clouds in the same file are ignored.
    arrays = sample_meshes(meshes, num_points or DEFAULT_MESH_POINTS, seed)
    if arrays is None:
        raise SceneError(f"{path}: the mesh has zero surface area (all faces degenerate), so no "
                         "points can be sampled; check the file's faces and units")
    return arrays
