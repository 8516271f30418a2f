"""Training data of the object classifier: the synthetic rooms' objects as segmentation finds
them in scans made to look real (host numpy).

Each room (``sample_room(seed)``) is scanned (:func:`~jaxmotion.scene.rooms.room_to_scene`)
and degraded as real scans are (:func:`degrade`): point density, sensor noise, holes, walls
missing from a partial scan, undersides and backs unseen, sizes varied; its normals are thrown
away and estimated from the points, as for a point cloud without them. Segmentation then runs
as on a user's room (:func:`jaxmotion.scene.segment.discover`), and each instance found gets
the category of the true object holding most of its points (``"object"`` when most are
clutter or structure) and its features (:func:`jaxmotion.scene.segment.object_features`).
Colour is never used.

:func:`build_object_features` writes ``features.npz`` (``features [M, F]``, ``labels [M]``,
``room [M]``, ``categories``) resumably, room by room; the same seeds give the same file.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from jaxmotion._atomic import atomic_open
from jaxmotion.scene.segment import NUM_FEATURES

__all__ = ["CATEGORIES", "FEATURES_VERSION", "build_object_features", "degrade",
           "room_objects"]

#: The classifier's categories: the synthetic world's objects, and "object" for the rest.
CATEGORIES = ("cabinet", "bed", "chair", "sofa", "table", "door", "window", "bookshelf",
              "picture", "desk", "fridge", "tv", "nightstand", "toilet", "sink", "lamp",
              "armchair", "coffee table", "stool", "object")
FEATURES_VERSION = "jm-object-features-1"


def degrade(scene, rng: np.random.Generator):
    """``scene`` (a synthetic room's scan) made to look like a real scan: 30k–80k points,
    noise of up to 1.5 cm, up to 6 holes of 0.2–0.6 m, a wall or two missing (one room in
    three), undersides unseen (one in two), sizes scaled by ±10 % per axis, no normals."""
    from jaxmotion.scene.io import Scene

    xyz, n = np.asarray(scene.xyz, np.float64), scene.num_points
    keep = np.ones(n, bool)
    if rng.random() < 0.5:  # a scanner rarely sees under tables and seats
        keep &= scene.normal[:, 2] > -0.5
    for _ in range(int(rng.integers(0, 7))):
        c = xyz[rng.integers(n)]
        keep &= np.linalg.norm(xyz - c, axis=1) > rng.uniform(0.2, 0.6)
    if rng.random() < 0.33:  # a partial scan: walls facing one or two directions missing
        wall = (scene.instance < 0) & (scene.semantic == 1)
        for _ in range(int(rng.integers(1, 3))):
            d = rng.normal(size=2)
            d /= np.linalg.norm(d)
            side = xyz[:, :2] @ d
            keep &= ~(wall & (side > np.percentile(side[wall], 90)))
    idx = np.flatnonzero(keep)
    count = int(min(len(idx), rng.integers(30_000, 80_001)))
    idx = np.sort(rng.choice(idx, count, replace=False))
    scale = rng.uniform(0.9, 1.1, 3)
    out = xyz[idx] * scale + rng.normal(0, rng.uniform(0.0, 0.015), (count, 3))
    out[:, 2] -= np.percentile(out[scene.semantic[idx] == 2, 2], 50) if (
        scene.semantic[idx] == 2).any() else 0.0
    return Scene(out, semantic=scene.semantic[idx], instance=scene.instance[idx],
                 objects=tuple(dict(o) for o in scene.objects), name=scene.name)


def room_objects(scene, seed: int = 0) -> tuple[np.ndarray, list[str], np.ndarray]:
    """Segment a (degraded) synthetic scan as a user's room is, and label what is found:
    ``(features [M, F], true categories [M], instance ids [N])``."""
    from jaxmotion.scene.segment import discover

    found = discover(scene.xyz, seed)
    names = {o["id"]: o["category"] for o in scene.objects}
    labels = []
    for sel in found.groups:
        ids, counts = np.unique(scene.instance[sel], return_counts=True)
        true = ids[np.argmax(counts)]
        cat = names.get(int(true), "object") if true >= 0 else "object"
        labels.append(cat if cat in CATEGORIES else "object")
    return found.features, labels, found.instance


def build_object_features(path, *, rooms: int, seed: int = 0, points: int = 80_000,
                          workers: int = 1, progress: bool = False) -> dict:
    """Write (or complete) ``path`` (``features.npz``) from ``rooms`` synthetic rooms of
    seeds ``seed .. seed + rooms - 1`` on ``workers`` processes (the same file with any
    number); returns its arrays. Resumable: the rooms already in the file are kept (the file
    is rewritten atomically every 20 rooms)."""
    path = Path(path)
    settings = {"version": FEATURES_VERSION, "seed": seed, "points": points}
    data = {"features": [], "labels": [], "room": []}
    if path.is_file():
        with np.load(path, allow_pickle=False) as z:
            if json.loads(str(z["settings"])) == settings:
                data = {"features": list(z["features"]), "labels": list(z["labels"]),
                        "room": list(z["room"])}
    done = set(int(r) for r in data["room"])
    start = max(done) + 1 if done else 0

    def save():
        with atomic_open(path, "wb") as f:
            np.savez(f, features=np.asarray(data["features"], np.float32).reshape(
                -1, NUM_FEATURES), labels=np.asarray(data["labels"], np.int64),
                room=np.asarray(data["room"], np.int64), categories=np.array(CATEGORIES),
                settings=np.array(json.dumps(settings)))

    import concurrent.futures as cf
    import multiprocessing as mp

    todo = list(range(start, rooms))
    pool = (cf.ProcessPoolExecutor(workers, mp_context=mp.get_context("spawn"))
            if workers > 1 and len(todo) > 1 else None)
    results = (pool.map(_one_room, [(seed, r, points) for r in todo]) if pool is not None
               else map(_one_room, [(seed, r, points) for r in todo]))
    for r, (feats, labels) in zip(todo, results):
        data["features"].extend(feats)
        data["labels"].extend(CATEGORIES.index(c) for c in labels)
        data["room"].extend([r] * len(labels))
        if (r + 1) % 20 == 0 or r == rooms - 1:
            save()
            if progress:
                print(f"  object features: {r + 1}/{rooms} rooms, {len(data['labels'])} objects",
                      flush=True)
    if pool is not None:
        pool.shutdown()
    if start >= rooms and not path.is_file():
        save()
    with np.load(path, allow_pickle=False) as z:
        keep = z["room"] < rooms  # a file built for more rooms serves fewer
        return {**{k: z[k][keep] for k in ("features", "labels", "room")},
                "categories": z["categories"]}


def _one_room(args) -> tuple[np.ndarray, list[str]]:
    """Features and true categories of room ``r`` (the unit of work of the workers)."""
    from jaxmotion.scene.rooms import room_to_scene, sample_room

    seed, r, points = args
    rng = np.random.default_rng([seed, r])
    scene = degrade(room_to_scene(sample_room(seed + r), points, rng), rng)
    feats, labels, _ = room_objects(scene, seed=r)
    return feats, labels
