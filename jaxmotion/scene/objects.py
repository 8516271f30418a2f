"""The object table of a labelled point cloud, derived from its per-point labels (host numpy).

A scene's object table (``Scene.objects``) is the one list of objects every stage uses:
grounding, planning, the viewer, the video and ``jaxmotion scene info``. Synthetic rooms,
jaxmotion ``.npz`` files and ScanNet scan folders carry it; a file that has per-point
``instance`` ids but no table (a PLY with ``instance`` / ``objectId`` vertex properties, the
layout ScanNet tools such as VoteNet's preprocessing write) gets it here, once, when its
:class:`~jaxmotion.scene.Scene` is built: one object per instance id ≥ 0, its axis-aligned box,
the category of its most common semantic id (jaxmotion's categories for their ids, else the
NYU40 classes, else ``"object"``) and its point count. Walls, floors and ceilings are
structure, not objects.
"""

from __future__ import annotations

import numpy as np

from jaxmotion.constants import STRUCTURE

__all__ = ["category_ids", "category_names", "table_from_labels"]


def category_names() -> dict[int, str]:
    """Semantic id → category name: NYU40 (ScanNet's label ids), with jaxmotion's own
    categories (:data:`jaxmotion.scene.CATEGORY_IDS`) taking precedence for their ids."""
    from jaxmotion.scene.furniture import CATEGORY_IDS
    from jaxmotion.scene.scans import NYU40_CLASSES

    names = {i + 1: n for i, n in enumerate(NYU40_CLASSES)}
    names.update({v: k for k, v in CATEGORY_IDS.items()})
    return names


def table_from_labels(xyz: np.ndarray, semantic: np.ndarray,
                      instance: np.ndarray) -> tuple[dict, ...]:
    """The object table of per-point labels, in increasing id order.

    Args:
      xyz: ``[N, 3]`` points (metres); semantic: ``[N]`` class ids (−1 unknown);
      instance: ``[N]`` object ids (−1 none).
    Returns:
      one dict per instance id ≥ 0 whose majority class is not structure (wall, floor,
      ceiling): ``id``, ``category``, ``bbox_min`` / ``bbox_max`` (lists of 3 floats) and
      ``points`` (its point count).
    """
    keep = np.flatnonzero(np.asarray(instance) >= 0)
    if not len(keep):
        return ()
    names = category_names()
    inst, sem = np.asarray(instance)[keep], np.asarray(semantic)[keep]
    order = np.argsort(inst, kind="stable")
    inst, sem, pts = inst[order], sem[order], np.asarray(xyz)[keep[order]]
    ids, starts, counts = np.unique(inst, return_index=True, return_counts=True)
    lo = np.minimum.reduceat(pts, starts, axis=0)
    hi = np.maximum.reduceat(pts, starts, axis=0)
    out = []
    for i, (oid, s, c) in enumerate(zip(ids, starts, counts)):
        labels = sem[s:s + c]
        labels = labels[labels >= 0]
        cat = names.get(int(np.bincount(labels).argmax()), "object") if len(labels) else "object"
        if cat in STRUCTURE:
            continue
        out.append({"id": int(oid), "category": cat,
                    "bbox_min": [float(v) for v in lo[i]], "bbox_max": [float(v) for v in hi[i]],
                    "points": int(c)})
    return tuple(out)


def category_ids() -> dict[str, int]:
    """Category name → semantic id, the inverse of :func:`category_names` (jaxmotion's ids
    for its categories, NYU40's for the others)."""
    return {name: i for i, name in category_names().items()}  # the names are unique
