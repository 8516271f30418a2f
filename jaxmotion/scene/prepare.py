"""A room made ready for every later stage: loaded, levelled, and labelled (host numpy).

``generate``, stories, ``scene info`` and ``scene segment`` all start here, so that every stage
after it receives one :class:`~jaxmotion.scene.Scene` with its object table and no stage reads
the file again or derives its own table::

    load (scene.io) → level (scene.level: unit, up axis, floor; plain mesh / cloud files)
        → label (when the file has no object table):
            per-point classes without instance ids (a ScanNet ``*.labels.ply``):
                split into instances per class (:func:`instances_from_classes`)
            no labels at all (a phone scan, a mesh, a point cloud):
                object discovery (:func:`jaxmotion.scene.segment.segment_scene`)

The labelled room is cached per file (its content, the options, the segmentation's version
and the classifier's weights: ``$JAXMOTION_CACHE/rooms/``, ``JAXMOTION_CACHE=off`` for none),
so a second run on the same file does not segment it again. Notes say what was done (unit,
turn, floor shift, objects found).
"""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import json
import os
from pathlib import Path

import numpy as np

from jaxmotion.errors import SceneError

__all__ = ["PreparedRoom", "instances_from_classes", "prepare_room", "room_cache_dir"]

_PLAIN = (".ply", ".obj", ".glb", ".gltf", ".off", ".stl")
_LABELLED_SHARE = 0.5  # a file whose points are at least this labelled has classes of its own


@dataclasses.dataclass(frozen=True)
class PreparedRoom:
    """``scene`` (levelled, labelled), ``notes`` for the user, and whether it was read from
    the cache (``cached``) and how its objects came (``labels``: ``"file"``, ``"classes"``,
    ``"segment"`` or ``"none"``)."""

    scene: object
    notes: tuple[str, ...]
    labels: str
    cached: bool = False


def room_cache_dir() -> Path | None:
    """Where labelled rooms are kept (None when caching is off)."""
    setting = os.environ.get("JAXMOTION_CACHE", "")
    if setting.strip().lower() in ("off", "0", "none", "false"):
        return None
    return Path(setting or Path.home() / ".cache/jaxmotion/xla") / "rooms"


def instances_from_classes(scene):
    """``scene`` with instance ids and its object table for per-point classes without them:
    each class's points (structure and unknown aside) split into connected groups and where
    objects touch (:func:`jaxmotion.scene.segment.find_components`, :func:`~jaxmotion.scene.
    segment.split_groups`), an object's fragments under it joined to it
    (:func:`~jaxmotion.scene.segment.merge_fragments`)."""
    from jaxmotion.constants import STRUCTURE
    from jaxmotion.scene.objects import category_names
    from jaxmotion.scene.segment import (FLOOR_BAND, find_components, merge_fragments,
                                         split_groups)

    names = category_names()
    xyz = np.asarray(scene.xyz, np.float64)
    group, offset = np.full(scene.num_points, -1, np.int64), 0
    for cls in np.unique(scene.semantic[scene.semantic >= 0]):
        if names.get(int(cls)) in STRUCTURE:
            continue
        comp = find_components(xyz, (scene.semantic == cls) & (xyz[:, 2] > FLOOR_BAND))
        group[comp >= 0] = comp[comp >= 0] + offset
        offset += int(comp.max()) + 1
    instance = merge_fragments(xyz, split_groups(xyz, group), scene.semantic)
    return dataclasses.replace(scene, instance=instance, objects=())  # table derived on build


def _digest(path: Path, options: dict) -> str:
    h = hashlib.sha256(json.dumps(options, sort_keys=True).encode())
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()[:24]


def _cached(path: Path, options: dict):
    """``(key, PreparedRoom or None)``: the cache entry of ``path`` (a scene ``.npz`` written
    by :func:`~jaxmotion.scene.save_scene` and a ``.json`` beside it with the notes, written
    last), and the room it holds when both are there and readable."""
    root = room_cache_dir()
    if root is None:
        return None, None
    key = root / f"{_digest(path, options)}.npz"
    try:
        extra = json.loads(key.with_suffix(".json").read_text())
        from jaxmotion.scene.io import load_scene

        return key, PreparedRoom(load_scene(key), tuple(extra["notes"]), extra["labels"],
                                 cached=True)
    except (OSError, ValueError, KeyError, TypeError, SceneError):
        return key, None  # absent or damaged: made (again)


def _store(key: Path | None, room: PreparedRoom) -> None:
    if key is None:
        return
    from jaxmotion._atomic import atomic_open
    from jaxmotion.scene.io import save_scene

    try:
        key.parent.mkdir(parents=True, exist_ok=True)
        save_scene(room.scene, key)
        with atomic_open(key.with_suffix(".json"), "w") as f:
            json.dump({"notes": list(room.notes), "labels": room.labels}, f)
    except (OSError, SceneError):
        pass  # a read-only cache: prepared again next time


def _label(scene, notes: tuple, *, segment: bool, seed: int):
    """``(scene, notes, labels)``: the scene given its object table when it has none."""
    if scene.objects:
        return scene, notes, "file"
    labelled = float(np.mean(scene.semantic >= 0)) if scene.num_points else 0.0
    if labelled >= _LABELLED_SHARE:
        out = instances_from_classes(scene)
        return out, notes + (f"the file has per-point classes but no objects: split into "
                             f"{len(out.objects)} objects by class and connectivity",), "classes"
    if not segment:
        return scene, notes, "none"
    from jaxmotion.scene.segment import segment_scene

    out, more = segment_scene(scene, seed=seed)
    return out, notes + tuple(more), "segment"


def prepare_room(source, *, num_points: int | None = None, up: str = "auto",
                 unit: str = "auto", segment: bool = True, seed: int = 0,
                 cache: bool = True) -> PreparedRoom:
    """The room ``source`` ready for grounding: a path (any file or scan
    :func:`jaxmotion.scene.load_scene` reads) or a :class:`~jaxmotion.scene.Scene` (the
    demo room is one: :func:`jaxmotion.scene.demo.demo_scene`).

    Args:
      num_points: points sampled from a mesh / kept of a cloud (as :func:`load_scene`).
      up: ``"auto"`` (found from the floor, :mod:`jaxmotion.scene.level`), ``"z"`` or ``"y"``.
      unit: ``"auto"`` (from the room's size) or ``"m"``, ``"cm"``, ``"mm"``, ``"ft"``, ``"in"``.
      segment: find objects in a room without labels (False: leave it unlabelled).
      seed: the sampling and segmentation seed; cache: read / write the labelled room.
    Raises :class:`SceneError` (unreadable file, no unit that makes a room, no points).
    """
    from jaxmotion.scene.io import Scene, load_scene_and_notes

    if isinstance(source, Scene):
        scene, notes, labels = _label(source, (), segment=segment, seed=seed)
        return PreparedRoom(scene, notes, labels)
    path = Path(source)
    from jaxmotion.scene.scans import find_scan

    plain = find_scan(path) is None and path.suffix.lower() in _PLAIN
    options = {"num_points": num_points, "up": up, "unit": unit, "segment": segment,
               "seed": seed, "version": _version()}
    key = None
    if cache and path.is_file():  # a scan folder carries its labels: nothing to keep
        key, hit = _cached(path, options)
        if hit is not None:
            return hit
    if plain:
        raw, notes = load_scene_and_notes(path, num_points=num_points, seed=seed,
                                          up="z" if up == "auto" else up)
        if raw.num_points == 0:
            raise SceneError(f"{path}: the file holds no points")
        from jaxmotion.scene.level import level_scene

        prior = "y" if path.suffix.lower() in (".glb", ".gltf") else "z"
        scene, more = level_scene(raw, up="auto" if up == "auto" else "z", prior=prior,
                                  unit=unit, seed=seed)
        notes = tuple(notes) + tuple(more)
    else:
        scene, notes = load_scene_and_notes(path, num_points=num_points, seed=seed, up=up)
    scene, notes, labels = _label(scene, tuple(notes), segment=segment, seed=seed)
    room = PreparedRoom(scene, notes, labels)
    if labels in ("segment", "classes") or (plain and notes):  # work worth keeping
        _store(key, room)
    return room


@functools.lru_cache(maxsize=1)
def _version() -> str:
    """What a cached labelled room depends on besides the file: the segmentation's version
    and the shipped classifier's weights."""
    from jaxmotion.models.object_classifier import OBJECTS_VERSION, shipped_object_classifier
    from jaxmotion.scene.segment import SEGMENT_VERSION

    weights = shipped_object_classifier()
    digest = hashlib.sha256(weights.read_bytes()).hexdigest()[:12] if weights.is_file() else ""
    return f"{SEGMENT_VERSION}/{OBJECTS_VERSION}/{digest}"
