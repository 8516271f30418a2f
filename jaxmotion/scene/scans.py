"""ScanNet scans and PROX scene meshes, read from the user's own copy (host-side numpy).

:func:`jaxmotion.scene.load_scene` comes here when its path is a scan (:func:`find_scan`):

- **ScanNet** (a scan folder ``scans/<scene>/``, or its ``<scene>_vh_clean_2.ply`` when the
  annotation files lie next to it): the mesh ``<scene>_vh_clean_2.ply``, its over-segmentation
  ``<scene>_vh_clean_2.0.010000.segs.json`` (``segIndices``, one segment id per vertex), the
  objects ``<scene>.aggregation.json`` (``segGroups``: ``objectId``, ``label``, ``segments``)
  and ``<scene>.txt`` (``axisAlignment = 16 numbers``, a row-major 4 × 4 matrix). The
  high-resolution set (``_vh_clean.ply``, ``_vh_clean.segs.json``,
  ``_vh_clean.aggregation.json``) is read the same way when it is the one given. Every
  segGroup is one object: its vertices get ``instance`` = its ``objectId`` and the category
  of its raw label (:func:`category_of`: jaxmotion's categories, such as ``armchair`` or
  ``coffee table``, else the NYU40 class, else the raw label itself; the NYU40 label of
  ``<scene>_vh_clean_2.labels.ply``, when present, names labels the table does not know).
  Walls, floors and ceilings are labelled but, as in the synthetic rooms, are no objects
  (instance −1). Points and boxes are moved by ``axisAlignment`` into the axis-aligned frame
  (z-up, metres; ScanNet's floor lies near z = 0 there and is not moved, so that HUMANISE
  motions, placed in this frame, still fit). The mesh is sampled as any mesh is (labels of
  the nearest face corner). A scan without its aggregation, segmentation or ``.txt`` is an
  error naming the missing file; the ``.ply`` given alone, without an aggregation beside it,
  loads as a plain mesh (no objects, not aligned).
- **PROX** (``scenes/<Name>.ply`` of the PROX release, next to ``cam2world/`` / ``sdf/``, or
  one of its 12 scene names): z-up meshes in metres whose floor lies 0.3–1.1 m below z = 0
  (public PROX tooling estimates it per scene). The floor is found (the lowest horizontal
  surface holding at least half as many up-facing points as the largest) and moved to
  z = 0; the shift is in the notes. PROX ships no object labels, so these scenes have no
  object table (a ``label`` vertex property, if a file has one, is read as for any PLY).
"""

from __future__ import annotations

import dataclasses
import json
import re
from pathlib import Path

import numpy as np

from jaxmotion.constants import STRUCTURE
from jaxmotion.errors import SceneError
from jaxmotion.scene.furniture import CATEGORY_IDS
from jaxmotion.scene.meshes import (
    DEFAULT_MESH_POINTS,
    load_meshes,
    read_geometry,
    sample_meshes,
    vertex_data,
)

__all__ = ["NYU40_CLASSES", "PROX_SCENES", "STRUCTURE", "ScanData", "ScanFiles",
           "category_of", "find_scan", "floor_height", "read_alignment", "read_scan"]

#: NYU40 class names in id order (id = index + 1), the ScanNet benchmark's label set.
NYU40_CLASSES = (
    "wall", "floor", "cabinet", "bed", "chair", "sofa", "table", "door", "window", "bookshelf",
    "picture", "counter", "blinds", "desk", "shelves", "curtain", "dresser", "pillow", "mirror",
    "floor mat", "clothes", "ceiling", "books", "fridge", "tv", "paper", "towel",
    "shower curtain", "box", "whiteboard", "person", "nightstand", "toilet", "sink", "lamp",
    "bathtub", "bag", "otherstructure", "otherfurniture", "otherprop",
)
OTHERPROP = 40
PROX_SCENES = ("BasementSittingBooth", "MPH11", "MPH112", "MPH16", "MPH1Library", "MPH8",
               "N0SittingBooth", "N0Sofa", "N3Library", "N3Office", "N3OpenArea", "Werkraum")
_PROX_SIBLINGS = ("cam2world", "sdf", "recordings", "fittings", "body_segments")
# raw ScanNet labels (or their last words) that are not already a class name
_ALIASES = {
    "couch": "sofa", "sofa chair": "armchair", "arm chair": "armchair", "recliner": "armchair",
    "easy chair": "armchair", "lounge chair": "armchair", "ottoman": "stool",
    "footstool": "stool", "foot stool": "stool", "night stand": "nightstand",
    "bedside table": "nightstand", "end table": "table", "side table": "table",
    "bookcase": "bookshelf", "book shelf": "bookshelf", "bookshelves": "bookshelf",
    "shelf": "shelves", "refrigerator": "fridge", "mini fridge": "fridge",
    "television": "tv", "tv stand": "cabinet", "wardrobe": "cabinet", "closet": "cabinet",
    "cupboard": "cabinet", "file cabinet": "cabinet", "kitchen counter": "counter",
    "countertop": "counter", "doorframe": "door", "door frame": "door", "tub": "bathtub",
    "backpack": "bag", "suitcase": "bag", "book": "books", "rug": "floor mat",
    "carpet": "floor mat", "mat": "floor mat", "cushion": "pillow", "drapes": "curtain",
    "blind": "blinds", "bunk bed": "bed", "mattress": "bed", "bathroom vanity": "sink",
}
_KNOWN = {**{c: c for c in (*NYU40_CLASSES, *CATEGORY_IDS)}, **_ALIASES}


def category_of(label: str) -> tuple[str, int] | None:
    """(jaxmotion category, semantic id) of a raw ScanNet label, or None when unknown.

    Tries the whole label, then without a plural ``s`` / ``es``, then its last two words and
    its last word ("office chair" -> chair, "kitchen cabinets" -> cabinet). Ids are
    jaxmotion's (:data:`jaxmotion.scene.CATEGORY_IDS`, e.g. armchair 41) where it has the
    class, NYU40 ids otherwise.
    """
    words = re.sub(r"[^a-z0-9]+", " ", str(label).lower()).split()
    for tail in (words, words[-2:], words[-1:]):
        name = " ".join(tail)
        for cand in (name, name[:-1] if name.endswith("s") else "",
                     name[:-2] if name.endswith("es") else ""):
            if cand in _KNOWN:
                cat = _KNOWN[cand]
                return cat, CATEGORY_IDS.get(cat) or NYU40_CLASSES.index(cat) + 1
    return None


@dataclasses.dataclass(frozen=True)
class ScanFiles:
    """The files of one scan. ``layout``: ``"scannet"`` or ``"prox"``; ScanNet's annotation
    files are None where absent (:func:`read_scan` says which are needed)."""

    layout: str
    mesh: Path
    name: str
    segs: Path | None = None
    aggregation: Path | None = None
    alignment: Path | None = None
    labels: Path | None = None


@dataclasses.dataclass(frozen=True)
class ScanData:
    """What :func:`read_scan` returns: Scene arrays (``xyz rgb normal semantic instance``),
    the object table, the scene name and notes for the user (what was read, what lacks)."""

    arrays: dict
    objects: tuple[dict, ...]
    name: str
    notes: tuple[str, ...]


def _scannet_files(folder: Path, mesh: Path) -> ScanFiles:
    hires = mesh.name.endswith("_vh_clean.ply")
    sid = mesh.name[: -len("_vh_clean.ply" if hires else "_vh_clean_2.ply")]
    segs = folder / (f"{sid}_vh_clean.segs.json" if hires else f"{sid}_vh_clean_2.0.010000.segs.json")
    names = ((f"{sid}_vh_clean.aggregation.json", f"{sid}.aggregation.json") if hires
             else (f"{sid}.aggregation.json", f"{sid}_vh_clean.aggregation.json"))
    agg = next((folder / n for n in names if (folder / n).is_file()), None)
    labels = folder / f"{sid}_vh_clean_2.labels.ply"
    txt = folder / f"{sid}.txt"
    return ScanFiles("scannet", mesh, sid, segs if segs.is_file() else None, agg,
                     txt if txt.is_file() else None,
                     labels if labels.is_file() and not hires else None)


def find_scan(path) -> ScanFiles | None:
    """The scan at ``path``: a ScanNet scan folder, a ``<scene>_vh_clean_2.ply`` (or
    ``_vh_clean.ply``) with its aggregation beside it, or a PROX
    ``scenes/<Name>.ply``; None for any other file (or no such path). SceneError for a
    folder that holds no ScanNet mesh."""
    path = Path(path)
    if path.is_dir():
        for pattern in ("*_vh_clean_2.ply", "*_vh_clean.ply"):
            meshes = sorted(p for p in path.glob(pattern) if p.is_file())
            if len(meshes) == 1:
                return _scannet_files(path, meshes[0])
            if len(meshes) > 1:
                raise SceneError(f"{path}: holds {len(meshes)} ScanNet meshes "
                                 f"({', '.join(p.name for p in meshes)}); give one scan folder "
                                 "(scans/<scene>) or one of the .ply files")
        raise SceneError(f"{path}: a folder without a ScanNet mesh (<scene>_vh_clean_2.ply); give "
                         "a ScanNet scan folder such as scans/scene0000_00, or a mesh / point-"
                         "cloud file (PLY / OBJ / GLB / GLTF / OFF / STL / NPZ)")
    if not path.is_file():
        return None
    if path.name.endswith(("_vh_clean_2.ply", "_vh_clean.ply")):
        files = _scannet_files(path.parent, path)
        return files if files.aggregation else None
    if path.suffix.lower() == ".ply" and path.parent.name == "scenes" and (
            path.stem in PROX_SCENES
            or any((path.parent.parent / d).is_dir() for d in _PROX_SIBLINGS)):
        return ScanFiles("prox", path, path.stem)
    return None


# ------------------------------------------------------------------------------ ScanNet files
def _json(path: Path, what: str):
    try:
        return json.loads(path.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as e:
        raise SceneError(f"{path}: not a readable {what} JSON file ({type(e).__name__}: {e}); "
                         "download it again from ScanNet") from e


def read_alignment(path) -> np.ndarray:
    """The ``axisAlignment`` matrix [4, 4] of a ScanNet ``<scene>.txt`` (row-major, applied as
    ``x -> R x + t``); SceneError unless it is a rigid motion."""
    path = Path(path)
    try:
        text = path.read_text()
    except (OSError, UnicodeDecodeError) as e:
        raise SceneError(f"{path}: unreadable ({e}); download <scene>.txt again") from e
    m = re.search(r"^\s*axisAlignment\s*=\s*(.*)$", text, re.MULTILINE)
    if m is None:
        raise SceneError(f"{path}: no 'axisAlignment = ...' line (ScanNet's test scans have "
                         "none); without it the room cannot be axis-aligned")
    try:
        a = np.array([float(v) for v in m.group(1).split()], np.float64)
    except ValueError:
        a = np.zeros(0)
    if a.shape != (16,) or not np.isfinite(a).all():
        raise SceneError(f"{path}: axisAlignment must be 16 numbers (a row-major 4 x 4 matrix), "
                         f"got {m.group(1).strip()[:80]!r}")
    a = a.reshape(4, 4)
    r = a[:3, :3]
    if not (np.allclose(a[3], [0, 0, 0, 1], atol=1e-6) and np.allclose(r @ r.T, np.eye(3), atol=1e-4)
            and np.linalg.det(r) > 0):
        raise SceneError(f"{path}: axisAlignment is not a rotation plus translation (last row "
                         "0 0 0 1, orthonormal rotation); check the file")
    return a


def _groups(path: Path) -> list[tuple[int, str, list[int]]]:
    """(objectId, raw label, segment ids) of every segGroup of an aggregation file."""
    data = _json(path, "ScanNet aggregation")
    groups = data.get("segGroups") if isinstance(data, dict) else None
    if not isinstance(groups, list):
        raise SceneError(f"{path}: a ScanNet aggregation file is a JSON object with a "
                         "'segGroups' list; download it again")
    out, seen = [], set()
    for i, g in enumerate(groups):
        oid = g.get("objectId", g.get("id")) if isinstance(g, dict) else None
        segs = g.get("segments") if isinstance(g, dict) else None
        if (not isinstance(oid, int) or isinstance(oid, bool) or oid < 0
                or not isinstance(segs, list) or not all(isinstance(s, int) for s in segs)):
            raise SceneError(f"{path}: segGroups[{i}] needs an int 'objectId' >= 0 and a list "
                             "of int 'segments'; download the file again")
        if oid in seen:
            raise SceneError(f"{path}: objectId {oid} appears twice in segGroups")
        seen.add(oid)
        out.append((oid, str(g.get("label", "")).strip(), segs))
    return out


def _segments(path: Path, n: int, mesh: Path) -> np.ndarray:
    data = _json(path, "ScanNet segmentation")
    seg = data.get("segIndices") if isinstance(data, dict) else None
    try:
        seg = np.asarray(seg, np.int64)
    except (TypeError, ValueError):
        seg = np.zeros((0, 0))
    if seg.ndim != 1:
        raise SceneError(f"{path}: a ScanNet segmentation file is a JSON object with a "
                         "'segIndices' list of ints; download it again")
    if len(seg) != n:
        raise SceneError(f"{path}: {len(seg)} segIndices but {mesh.name} has {n} vertices; the "
                         "two files belong to different meshes (the _vh_clean_2 files go "
                         "together, the _vh_clean ones too)")
    return seg


def _missing(files: ScanFiles) -> str | None:
    sid, where = files.name, files.mesh.parent
    if files.aggregation is None:
        return (f"{where}: no {sid}.aggregation.json (nor {sid}_vh_clean.aggregation.json) next "
                f"to {files.mesh.name}, so the scan's objects are unknown; download it with the "
                "scan (ScanNet's download script, --type .aggregation.json; test scans have "
                f"none), or give the file {files.mesh} itself to load it as a plain mesh (no "
                "objects, not axis-aligned)")
    if files.segs is None:
        hires = files.mesh.name.endswith("_vh_clean.ply")
        want = f"{sid}_vh_clean.segs.json" if hires else f"{sid}_vh_clean_2.0.010000.segs.json"
        return (f"{where}: no {want}, the segmentation that {files.aggregation.name}'s segments "
                f"refer to; download it with the scan (--type {want[len(sid):]})")
    if files.alignment is None:
        return (f"{where}: no {sid}.txt, whose axisAlignment turns the scan into its "
                "axis-aligned frame; download it with the scan (--type .txt)")
    return None


def _read_scannet(files: ScanFiles, num_points: int | None, seed: int) -> ScanData:
    if (problem := _missing(files)) is not None:
        raise SceneError(problem)
    align = read_alignment(files.alignment)
    groups = _groups(files.aggregation)
    meshes, _ = load_meshes(files.mesh, ".ply")
    if not meshes:
        raise SceneError(f"{files.mesh}: holds no faces; a ScanNet _vh_clean_2.ply is a mesh")
    verts = np.concatenate([np.asarray(m.vertices, np.float64) for m in meshes])
    seg = _segments(files.segs, len(verts), files.mesh)
    nyu = None
    if files.labels is not None:
        lab_meshes, lab_clouds = load_meshes(files.labels, ".ply")
        lab = np.concatenate([vertex_data(g)["semantic"] for g in lab_meshes or lab_clouds])
        nyu = lab if len(lab) == len(verts) else None
    semantic = np.full(len(verts), -1, np.int64) if nyu is None else nyu.copy()
    instance = np.full(len(verts), -1, np.int64)
    owner = {}  # segment id -> group index (a segment in two groups: the later one)
    for gi, (_, _, segments) in enumerate(groups):
        owner.update(dict.fromkeys(segments, gi))
    uniq, inverse = np.unique(seg, return_inverse=True)
    group_of = np.array([owner.get(int(s), -1) for s in uniq], np.int64)[inverse]
    if unknown := sorted({s for _, _, segs in groups for s in segs} - set(uniq.tolist()))[:5]:
        raise SceneError(f"{files.aggregation}: segments {unknown} are not in {files.segs.name}; "
                         "the aggregation belongs to another mesh resolution or scan")
    aligned = verts @ align[:3, :3].T + align[:3, 3]
    objects, unmapped = [], []
    for gi, (oid, label, _) in enumerate(groups):
        sel = group_of == gi
        mapped = category_of(label)
        if mapped is None and nyu is not None and (sel & (nyu > 0)).any():
            k = int(np.bincount(nyu[sel & (nyu > 0)]).argmax())
            mapped = (NYU40_CLASSES[k - 1], k) if k <= len(NYU40_CLASSES) else None
        if mapped is None:
            unmapped.append(label)
            mapped = (label or "object", OTHERPROP)
        cat, sem = mapped
        semantic[sel] = sem
        if cat in STRUCTURE or not sel.any():
            continue
        instance[sel] = oid
        pts = aligned[sel]
        objects.append({"id": oid, "category": cat, "label": label,
                        "bbox_min": pts.min(0).tolist(), "bbox_max": pts.max(0).tolist()})
    arrays = sample_meshes(meshes, num_points or DEFAULT_MESH_POINTS, seed, (semantic, instance))
    if arrays is None:
        raise SceneError(f"{files.mesh}: the mesh has zero surface area; download it again")
    arrays["xyz"] = arrays["xyz"] @ align[:3, :3].T + align[:3, 3]
    arrays["normal"] = arrays["normal"] @ align[:3, :3].T
    notes = [(f"ScanNet scan {files.name}: {len(objects)} objects from "
              f"{files.aggregation.name}, axis-aligned by {files.alignment.name}")]
    if unmapped:
        notes.append(f"{len(unmapped)} raw labels match no NYU40 or jaxmotion class and are kept "
                     f"as their own categories: {', '.join(sorted(set(unmapped))[:8])}")
    return ScanData(arrays, tuple(sorted(objects, key=lambda o: o["id"])), files.name,
                    tuple(notes))


# ------------------------------------------------------------------------------ PROX
def floor_height(xyz, normal) -> float:
    """The floor's z (m): the lowest 2 cm band of up-facing points (normal z > 0.9) holding
    at least half as many as the fullest band, their median z; the 2nd percentile of z when
    fewer than 100 points face up."""
    xyz, normal = np.asarray(xyz, np.float64), np.asarray(normal, np.float64)
    z = xyz[normal[:, 2] > 0.9, 2]
    if len(z) < 100:
        return float(np.percentile(xyz[:, 2], 2)) if len(xyz) else 0.0
    edges = np.arange(z.min(), z.max() + 0.04, 0.02)
    counts, edges = np.histogram(z, edges)
    k = int(np.flatnonzero(counts >= 0.5 * counts.max())[0])
    return float(np.median(z[(z >= edges[k]) & (z <= edges[k + 1])]))


def _read_prox(files: ScanFiles, num_points: int | None, seed: int) -> ScanData:
    arrays = read_geometry(files.mesh, ".ply", num_points, seed)
    floor = floor_height(arrays["xyz"], arrays["normal"])
    arrays["xyz"] = arrays["xyz"] - [0.0, 0.0, floor]
    notes = [(f"PROX scene {files.name}: its floor (z = {floor:.3f} m in the file) is moved to "
              f"z = 0 (subtract {floor:.3f} m from the z of anything in PROX's frame to match)")]
    if (arrays["instance"] < 0).all():
        notes.append("PROX ships no object labels: the scene has no object table, so objects "
                     "cannot be picked with --object or found by name; generate finds the "
                     "region from the text (the ADM's map)")
    return ScanData(arrays, (), files.name, tuple(notes))


def read_scan(files: ScanFiles, num_points: int | None = None, seed: int = 0) -> ScanData:
    """Read a scan found by :func:`find_scan` (see the module docstring): ``num_points``
    surface samples (default 100_000, seeded), the object table and notes."""
    if files.layout == "prox":
        return _read_prox(files, num_points, seed)
    return _read_scannet(files, num_points, seed)
