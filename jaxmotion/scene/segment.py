"""Object discovery: an unlabelled room made a labelled one (host numpy + a small classifier).

A room without an object table (a phone scan, a mesh, a plain point cloud) is segmented once,
after levelling (:mod:`jaxmotion.scene.level`: metres, z-up, floor at z = 0), into the same
per-point ``semantic`` / ``instance`` labels and object table a labelled scan has, so that
everything after it (grounding, planning, the pipelines, the viewer, the video) runs unchanged:

1. **structure** (:func:`find_structure`): the floor (the points within
   :data:`FLOOR_BAND` of z = 0), the ceiling (a horizontal plane at the top holding at least
   2 % of the points, above 1.8 m) and the walls: vertical planes (RANSAC, two points and the
   vertical) that rise from near the floor to near the top of the room over at least 0.8 m of
   length; their points within :data:`PLANE_TOL` are structure, not objects. A real wall is
   thicker than that (plaster, skirting, a scan's drift and double surfaces, window
   recesses): of the points within :data:`WALL_BAND` in front of it or :data:`BEHIND_WALL`
   behind it, those that furniture standing against the wall does not claim are the wall's
   too (:func:`find_instances`); under a found ceiling, what hangs within
   :data:`HANGING_BAND` of it (no lower than :data:`HANGING`) is the ceiling's. Partial scans
   simply have fewer of them.
2. **instances** (:func:`find_components`): the remaining points above the floor, grouped by
   connectivity on a :data:`VOXEL` grid (26 neighbours); groups under :data:`MIN_POINTS`
   points are clutter (no object).
3. **categories** (:func:`object_features`, :mod:`jaxmotion.models.object_classifier`): each
   instance is described by its size, its height profile, its horizontal surfaces (heights and
   areas, from normals estimated on the points: :func:`~jaxmotion.scene.level.estimate_normals`)
   and its distance to the walls: shape, not colour, so that it transfers to scans whose
   colours differ from the synthetic rooms' or that have none. A small classifier trained on
   the synthetic rooms' instances found this way (``configs/objects.py``, shipped as
   ``jaxmotion/assets/objects.safetensors``) names it, with its probability as the object's
   ``confidence``; below :data:`MIN_CONFIDENCE`, or for a piece lower than :data:`MIN_TOP` or
   narrower than :data:`MIN_SIDE` (a fragment of a bed frame, a skirting board; doors, windows
   and pictures are thin and only need the height), the category is ``"object"``; so is a
   seat or bed name below :data:`SURE_SEAT` on an object with no surface to sit or lie on
   (step 4: the geometry contradicts a doubtful name, and "sit on the sofa" would end
   standing at it); a "bed" is something to lie on with little above its top: one with no
   surface to sit or lie on is an ``"object"``, one with a backrest (:data:`BACKREST` of its
   points well above its surface) a sofa (:func:`name_by_surfaces`).
4. **affordances** (:func:`support_surfaces`): a roughly flat surface 0.35–0.65 m high with
   room for a body is a seat, a long flat one 0.3–0.8 m high a place to lie: they are recorded
   as ``surface_height`` and ``affords`` (``["sit"]``, ``["sit", "lie"]``), so that "sit" and
   "lie" find a target whatever the category.

The output is a :class:`~jaxmotion.scene.Scene` with ``semantic`` (floor 2, wall 1, ceiling
22, an object's category id, −1 unknown), ``instance`` and ``objects`` (``id``, ``category``,
boxes, ``confidence``, ``points``, ``source = "segment"``, and the surfaces). :func:`
segment_scene` is deterministic for a given seed.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from jaxmotion.constants import STRUCTURE_IDS

__all__ = ["BACKREST", "BEHIND_WALL", "CEILING", "FLOOR", "FLOOR_BAND", "HANGING",
           "HANGING_BAND", "LIE_FILL", "MIN_CONFIDENCE", "MIN_POINTS", "MIN_SIDE", "MIN_TOP",
           "PLANE_TOL", "SEGMENT_VERSION", "SURE_SEAT", "VOXEL", "WALL", "WALL_BAND",
           "Discovery", "Structure", "discover", "find_components", "find_instances",
           "find_structure", "name_by_surfaces", "object_features", "segment_scene",
           "split_groups", "split_touching", "support_surfaces"]

SEGMENT_VERSION = "jm-segment-7"  # bump when the labels a room gets change (caches key on it)
FLOOR, WALL, CEILING = (STRUCTURE_IDS[k] for k in ("floor", "wall", "ceiling"))  # semantic ids
FLOOR_BAND = 0.03  # m above z = 0 that is floor
PLANE_TOL = 0.035  # m: a point this close to a wall / ceiling plane belongs to it
WALL_BAND = 0.15  # m: ... and, once the wall is found, a point this close to it may be (its band)
BEHIND_WALL = 0.5  # m: ... and behind it (a window's recess, the wall's far face)
HANGING_BAND = 0.6  # m under a found ceiling: what hangs there is the ceiling's ...
HANGING = 2.2  # m: ... but never lower than this
VOXEL = 0.05  # m: connectivity grid of the instances
MIN_POINTS = 40  # points of the smallest object
MIN_CONFIDENCE = 0.35  # below this the classifier's category is not used ("object")
SURE_SEAT = 0.5  # below this a seat or bed name needs a surface to sit or lie on (affords)
LIE_FILL = 0.4  # share of a lying surface's rectangle its points must fill
BACKREST = 0.2  # a "bed" with this share of its points 0.15 m above its surface is a sofa
MIN_TOP, MIN_SIDE = 0.3, 0.15  # m: lower, or narrower, than any furniture (a bed frame's sliver)
NUM_FEATURES = 28
_SAMPLE = 20_000
_TRIALS = 400
_SEAT = (0.33, 0.68)  # m: the height of a surface one sits on
_LIE = (0.25, 0.85)  # m: ... lies on (at least 1.5 m long and 0.6 m wide)


@dataclasses.dataclass(frozen=True)
class Structure:
    """Floor, walls and ceiling of a levelled room: ``label [N]`` (0 other, :data:`FLOOR`,
    :data:`WALL`, :data:`CEILING`), the wall planes ``walls [W, 3]`` as ``(nx, ny, d)`` with
    ``x nx + y ny = d``, ``top`` (the ceiling's height, or the room's 99th percentile z) and
    ``near_wall [N]`` (bool: other points within :data:`WALL_BAND` in front of a wall or
    :data:`BEHIND_WALL` behind it, along its length; None: not known)."""

    label: np.ndarray
    walls: np.ndarray
    top: float
    near_wall: np.ndarray | None = None


def find_structure(xyz: np.ndarray, seed: int = 0, max_walls: int = 12) -> Structure:
    """Floor, ceiling and walls of ``xyz [N, 3]`` (levelled, metres; module docstring)."""
    xyz = np.asarray(xyz, np.float64)
    n = len(xyz)
    label = np.zeros(n, np.int32)
    label[xyz[:, 2] <= FLOOR_BAND] = FLOOR
    rng = np.random.default_rng(seed)
    top = float(np.percentile(xyz[:, 2], 99)) if n else 0.0
    # the ceiling: the densest 5 cm layer near the top, when it is a plane of the room
    high = xyz[:, 2] >= top - 0.3
    if top >= 1.8 and high.any():
        z = xyz[high, 2]
        hist, edges = np.histogram(z, bins=np.arange(z.min(), z.max() + 0.05, 0.025))
        if len(hist):
            peak = edges[int(np.argmax(hist))] + 0.0125
            on = np.abs(xyz[:, 2] - peak) <= PLANE_TOL
            if on.sum() >= 0.02 * n:
                label[on & (label == 0)] = CEILING
                top = float(np.median(xyz[on, 2]))
    # walls: vertical planes from near the floor to near the top
    cand = np.flatnonzero((label == 0) & (xyz[:, 2] > 0.1))
    walls, spans = [], []
    for _ in range(max_walls):
        if len(cand) < 0.01 * n or len(cand) < 50:
            break
        sub = cand[rng.choice(len(cand), min(len(cand), _SAMPLE), replace=False)]
        pts = xyz[sub, :2]
        pairs = rng.integers(0, len(pts), (_TRIALS, 2))
        d = pts[pairs[:, 1]] - pts[pairs[:, 0]]
        length = np.linalg.norm(d, axis=1)
        ok = length > 0.3
        if not ok.any():
            break
        nrm = np.stack([-d[ok, 1], d[ok, 0]], 1) / length[ok, None]
        off = np.einsum("mc,mc->m", nrm, pts[pairs[ok, 0]])
        counts = (np.abs(pts @ nrm.T - off) <= PLANE_TOL).sum(0)
        best = int(np.argmax(counts))
        nb, ob = nrm[best], off[best]
        inl = cand[np.abs(xyz[cand, :2] @ nb - ob) <= PLANE_TOL]
        if len(inl) < 3:
            break
        c = xyz[inl, :2].mean(0)  # refit the line on its inliers
        w = np.linalg.eigh(np.cov((xyz[inl, :2] - c).T))[1][:, 0]
        nb, ob = w, float(c @ w)
        inl = cand[np.abs(xyz[cand, :2] @ nb - ob) <= PLANE_TOL]
        z = xyz[inl, 2]
        along = xyz[inl, :2] @ np.array([-nb[1], nb[0]])
        rises = (np.percentile(z, 97) >= 0.8 * top and np.percentile(z, 3) <= 0.5
                 and np.percentile(z, 97) - np.percentile(z, 3) >= min(1.2, 0.6 * top))
        long_enough = np.percentile(along, 98) - np.percentile(along, 2) >= 0.8
        if len(inl) < 0.01 * n:
            break
        if rises and long_enough:
            label[inl] = WALL
            walls.append((nb[0], nb[1], ob))
            spans.append((np.percentile(along, 1), np.percentile(along, 99)))
            # the rest of a thick wall's band is not tried again as another wall
            inl = cand[np.abs(xyz[cand, :2] @ nb - ob) <= WALL_BAND]
        # tried either way: a plane that is not a wall is not tried again
        cand = np.setdiff1d(cand, inl, assume_unique=True)
    # a real wall is not a plane to a centimetre (plaster, skirting, a scan's drift and its
    # double surfaces, window recesses): the points within WALL_BAND in front of a wall or
    # BEHIND_WALL behind it, along its length, are marked; find_instances tells the wall's
    # own from the furniture standing against it
    near = np.zeros(n, bool)
    rest = np.flatnonzero((label == 0) & (xyz[:, 2] > FLOOR_BAND))
    floor = xyz[label == FLOOR, :2] if (label == FLOOR).any() else xyz[:, :2]
    for (nx, ny, d), (a0, a1) in zip(walls, spans):
        p = xyz[rest, :2]
        along = p @ np.array([-ny, nx])
        inward = 1.0 if np.median(floor @ np.array([nx, ny])) >= d else -1.0
        depth = (p @ np.array([nx, ny]) - d) * inward  # > 0 on the room's side
        near[rest[(depth <= WALL_BAND) & (depth >= -BEHIND_WALL) & (along >= a0 - 0.1)
                  & (along <= a1 + 0.1)]] = True
    # what hangs just under the ceiling (soffits, beams, lights, curtain boxes) is the room's,
    # not furniture a body meets: left to the ceiling in a room of full height
    if (label == CEILING).any():
        label[(label == 0) & (xyz[:, 2] > max(HANGING, top - HANGING_BAND))] = CEILING
    return Structure(label, np.asarray(walls, np.float64).reshape(-1, 3), top,
                     near & (label == 0))


def find_components(xyz: np.ndarray, mask: np.ndarray, voxel: float = VOXEL,
                    min_points: int = MIN_POINTS) -> np.ndarray:
    """``[N]`` int: the connected group of each point of ``mask`` on a ``voxel`` grid (26
    neighbours), numbered from 0 by position (x, then y, of their centres); −1 for points
    outside ``mask`` or in groups under ``min_points`` points."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    out = np.full(len(xyz), -1, np.int64)
    idx = np.flatnonzero(mask)
    if not len(idx):
        return out
    cell = np.floor(np.asarray(xyz)[idx] / voxel).astype(np.int64)
    cell -= cell.min(0)
    dims = cell.max(0) + 3
    key = ((cell[:, 0] + 1) * dims[1] + cell[:, 1] + 1) * dims[2] + cell[:, 2] + 1
    cells, inverse = np.unique(key, return_inverse=True)
    rows, cols = [], []
    for dx in (-1, 0, 1):
        for dy in (-1, 0, 1):
            for dz in (-1, 0, 1):
                if (dx, dy, dz) <= (0, 0, 0):
                    continue  # each neighbour pair once
                other = cells + (dx * dims[1] + dy) * dims[2] + dz
                pos = np.searchsorted(cells, other)
                hit = (pos < len(cells)) & (cells[np.minimum(pos, len(cells) - 1)] == other)
                rows.append(np.flatnonzero(hit))
                cols.append(pos[hit])
    r, c = np.concatenate(rows), np.concatenate(cols)
    graph = coo_matrix((np.ones(len(r), np.int8), (r, c)), shape=(len(cells), len(cells)))
    _, comp = connected_components(graph, directed=False)
    point_comp = comp[inverse]
    sizes = np.bincount(point_comp)
    keep = np.flatnonzero(sizes >= min_points)
    if not len(keep):
        return out
    centres = np.stack([np.bincount(point_comp, np.asarray(xyz)[idx, a])[keep] / sizes[keep]
                        for a in range(2)], 1)
    order = keep[np.lexsort((np.round(centres[:, 1], 2), np.round(centres[:, 0], 2)))]
    new = np.full(len(sizes), -1, np.int64)
    new[order] = np.arange(len(order))
    out[idx] = new[point_comp]
    return out


def split_groups(xyz: np.ndarray, group: np.ndarray) -> np.ndarray:
    """``[N]`` instance ids from connected groups ``group [N]`` (−1: none): each group split
    where objects touch (:func:`split_touching`), parts under :data:`MIN_POINTS` points
    dropped (−1), the rest numbered from 0 in group order."""
    out, count = np.full(len(group), -1, np.int64), 0
    for g in np.unique(group[group >= 0]):
        sel = np.flatnonzero(group == g)
        part = split_touching(xyz[sel])
        sizes = np.bincount(part)
        keep = np.flatnonzero(sizes >= MIN_POINTS)
        remap = np.full(len(sizes), -1)
        remap[keep] = np.arange(count, count + len(keep))
        out[sel] = remap[part]
        count += len(keep)
    return out


#: A part narrower than this (m, its widest horizontal side), or whose top is lower than
#: ``FRAGMENT_TOP`` (m), is a fragment of an object when it lies under another part's
#: footprint (:func:`merge_fragments`).
FRAGMENT_WIDTH = 0.3
FRAGMENT_TOP = 0.35


def merge_fragments(xyz: np.ndarray, instance: np.ndarray, kind=None) -> np.ndarray:
    """``instance`` with the fragments of an object joined to it: a part narrower than
    :data:`FRAGMENT_WIDTH` or lower than :data:`FRAGMENT_TOP` whose centre lies (from above)
    within 10 cm of the footprint of a part that is neither and rises at least 10 cm higher
    (of the same ``kind [N]`` class, when given) is that part's (the largest such): an office
    chair's star base under its seat, a table's legs cut off by a scan's holes. Objects
    standing on others (a lamp on a desk) rise above them and are kept. With ``kind``, two
    parts of one class whose footprints overlap by at least :data:`SAME_FOOTPRINT` of the
    smaller one's and whose heights meet (within 10 cm) are one object too: a chair's seat
    and its back with its base, cut apart by a scan that barely saw the seat (upper and lower
    kitchen cabinets, a gap of half a metre between them, stay two). Ids are renumbered from
    0 in order."""
    xyz = np.asarray(xyz, np.float64)
    ids = np.unique(instance[instance >= 0])
    if len(ids) < 2:
        return instance
    lo = np.array([xyz[instance == i].min(0) for i in ids])
    hi = np.array([xyz[instance == i].max(0) for i in ids])
    count = np.array([(instance == i).sum() for i in ids])
    cls = (None if kind is None else
           np.array([np.bincount(np.asarray(kind)[instance == i] + 1).argmax() for i in ids]))
    width = (hi[:, :2] - lo[:, :2]).max(1)
    small = (width < FRAGMENT_WIDTH) | (hi[:, 2] < FRAGMENT_TOP)
    target = np.arange(len(ids))  # hosts are never small: a fragment joins a root at once
    for f in np.flatnonzero(small):
        c = (lo[f, :2] + hi[f, :2]) / 2
        host = ((np.all(c > lo[:, :2] - 0.1, 1)) & (np.all(c < hi[:, :2] + 0.1, 1))
                & (hi[:, 2] > hi[f, 2] + 0.1) & ~small)
        if cls is not None:
            host &= cls == cls[f]
        if host.any():
            target[f] = int(np.flatnonzero(host)[np.argmax(count[host])])
    if cls is not None:  # one object of a class per footprint
        target = _join_stacked(target, lo, hi, count, cls)
    roots = np.unique(target)
    new = np.full(int(ids.max()) + 1, -1)
    new[ids] = np.searchsorted(roots, target)
    out = instance.copy()
    out[instance >= 0] = new[instance[instance >= 0]]
    return out


#: Two parts of one class whose top-view boxes overlap by this share of the smaller one's
#: area (and whose heights meet) are one object (:func:`merge_fragments`).
SAME_FOOTPRINT = 0.5


def _join_stacked(target, lo, hi, count, cls) -> np.ndarray:
    """``target`` (each part's root) with roots of one class joined where their top-view
    boxes overlap by :data:`SAME_FOOTPRINT` of the smaller and their heights meet: each into
    the one of more points; the boxes of joined roots grow as they join."""
    target = target.copy()
    roots = [int(r) for r in np.unique(target)]
    box_lo = {r: lo[target == r].min(0) for r in roots}
    box_hi = {r: hi[target == r].max(0) for r in roots}
    size = {r: int(count[target == r].sum()) for r in roots}
    joined = True
    while joined:
        joined = False
        for i, a in enumerate(roots):
            for b in roots[i + 1:]:
                if cls[a] != cls[b]:
                    continue
                over = np.clip(np.minimum(box_hi[a][:2], box_hi[b][:2])
                               - np.maximum(box_lo[a][:2], box_lo[b][:2]), 0, None).prod()
                area = min(np.prod(box_hi[r][:2] - box_lo[r][:2]) for r in (a, b))
                meet = (min(box_hi[a][2], box_hi[b][2])
                        - max(box_lo[a][2], box_lo[b][2])) > -0.1
                if area > 0 and over >= SAME_FOOTPRINT * area and meet:
                    keep, gone = (a, b) if size[a] >= size[b] else (b, a)
                    target[target == gone] = keep
                    box_lo[keep] = np.minimum(box_lo[keep], box_lo[gone])
                    box_hi[keep] = np.maximum(box_hi[keep], box_hi[gone])
                    size[keep] += size.pop(gone)
                    roots.remove(gone)
                    joined = True
                    break
            if joined:
                break
    return target


def find_instances(xyz: np.ndarray, structure: Structure, split: bool = True) -> np.ndarray:
    """``[N]`` instance ids of a levelled room (−1: none): :func:`find_components` of the
    points that are not structure, each split where objects touch (:func:`split_groups`,
    unless ``split`` is False), then the wall points an object stands against given back to
    it (inside its box grown by 4 cm and within 15 cm of its points: the back of a cabinet or
    a bookshelf, which lies in the wall's plane)."""
    from scipy.spatial import cKDTree

    xyz = np.asarray(xyz, np.float64)
    free = (structure.label == 0) & (xyz[:, 2] > FLOOR_BAND)
    instance = find_components(xyz, free)
    if structure.near_wall is not None and structure.near_wall.any():
        free &= ~_wall_residue(xyz, instance, structure.near_wall)
        instance = find_components(xyz, free)  # pieces joined only through a wall come apart
    if split:  # objects that touch, told apart from above
        instance = split_groups(xyz, instance)
    instance = merge_fragments(xyz, instance)
    wall = np.flatnonzero(structure.label == WALL)
    mine = np.flatnonzero(instance >= 0)
    if not len(wall) or not len(mine):
        return instance
    d, j = cKDTree(xyz[mine]).query(xyz[wall], distance_upper_bound=0.15)
    near = np.isfinite(d)
    cand, owner = wall[near], instance[mine[j[near]]]
    count = int(instance.max()) + 1
    lo = np.full((count, 3), np.inf)
    hi = np.full((count, 3), -np.inf)
    np.minimum.at(lo, instance[mine], xyz[mine])
    np.maximum.at(hi, instance[mine], xyz[mine])
    inside = np.all((xyz[cand] >= lo[owner] - 0.04) & (xyz[cand] <= hi[owner] + 0.04), axis=1)
    instance[cand[inside]] = owner[inside]
    return instance


def _wall_residue(xyz: np.ndarray, group: np.ndarray, near: np.ndarray) -> np.ndarray:
    """``[N]`` bool: the points of the connected groups ``group [N]`` that belong to a wall.

    ``near [N]``: the points near a wall (:attr:`Structure.near_wall`). A group lying in the
    band (fewer than a tenth of its points off it) is the wall's: the wall's own surface, or
    something flat on it (a picture, a door, a window; the classifier's wall-mounted classes,
    which a body does not meet). A group standing out of the band keeps the band points within
    the band's width (and 4 cm) of its other points (its back against the wall); its other
    band points are the wall's (a wall's surface running on beside it, which otherwise joins
    whatever stands along the wall into one object)."""
    from scipy.spatial import cKDTree

    out = np.zeros(len(xyz), bool)
    for g in np.unique(group[group >= 0]):
        sel = np.flatnonzero(group == g)
        on = near[sel]
        if not on.any():
            continue
        off = sel[~on]
        if len(off) < 0.1 * len(sel):
            out[sel] = True
            continue
        band = sel[on]
        dist, _ = cKDTree(xyz[off]).query(xyz[band], distance_upper_bound=WALL_BAND + 0.04)
        out[band[~np.isfinite(dist)]] = True
    return out


def split_touching(xyz: np.ndarray, cell: float = VOXEL, step: float = 0.08,
                   thin: float = 0.25, small: float = 0.06) -> np.ndarray:
    """``[M]`` part ids of one connected group's points ``xyz [M, 3]``: objects that touch
    (a chair against a table, a sofa against a bookshelf, a toilet against a sink) told
    apart from above. The group's top-view cells (``cell`` m) are joined where their top
    heights differ by at most ``step``; then a part thinner than ``thin`` m (a backrest, an
    armrest, a headboard, a cistern: twice its largest inscribed radius) joins the lower
    part it shares the longest border with (the seat it rises from), and a part under
    ``small`` m² the part it shares the longest border with. One object gives one part."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    xyz = np.asarray(xyz, np.float64)
    ij = np.floor(xyz[:, :2] / cell).astype(np.int64)
    ij -= ij.min(0)
    width = int(ij[:, 1].max()) + 3
    key = (ij[:, 0] + 1) * width + ij[:, 1] + 1
    cells, inverse = np.unique(key, return_inverse=True)
    if len(cells) < 8:
        return np.zeros(len(xyz), np.int64)
    top = np.full(len(cells), -np.inf)
    np.maximum.at(top, inverse, xyz[:, 2])
    pairs = []
    for dx, dy in ((1, -1), (1, 0), (1, 1), (0, 1)):
        other = cells + dx * width + dy
        pos = np.searchsorted(cells, other)
        hit = (pos < len(cells)) & (cells[np.minimum(pos, len(cells) - 1)] == other)
        pairs.append(np.stack([np.flatnonzero(hit), pos[hit]], 1))
    pairs = np.concatenate(pairs)
    close = np.abs(top[pairs[:, 0]] - top[pairs[:, 1]]) <= step
    g = coo_matrix((np.ones(close.sum()), (pairs[close, 0], pairs[close, 1])),
                   shape=(len(cells),) * 2)
    region = connected_components(g, directed=False)[1]

    grid = np.stack([cells // width, cells % width], 1)

    def stats(members):
        """(top, area m², width m: twice the largest distance from a cell to the outside)"""
        from scipy.ndimage import distance_transform_edt

        g = grid[members]
        lo = g.min(0)
        mask = np.zeros(tuple(g.max(0) - lo + 3), bool)
        mask[tuple((g - lo + 1).T)] = True
        w = 2.0 * float(distance_transform_edt(mask).max()) * cell
        return float(np.median(top[members])), len(g) * cell * cell, w

    # parts, their neighbours (border lengths in cell pairs) and their figures, kept up to
    # date as parts merge (each merge recomputes the figures of the one part that grew)
    order = np.argsort(region, kind="stable")
    starts = np.flatnonzero(np.r_[True, np.diff(region[order]) != 0])
    members = {int(region[order[s]]): order[s:e]
               for s, e in zip(starts, np.r_[starts[1:], len(order)])}
    # nb[x][y] = [border, first]: ``first`` the first cell pair between them, which breaks
    # ties between equal borders (the order the pairs were found in)
    nb: dict = {r: {} for r in members}
    a, b = region[pairs[:, 0]], region[pairs[:, 1]]
    cross = np.flatnonzero(a != b)
    if len(cross):
        lo_, hi_ = np.minimum(a[cross], b[cross]), np.maximum(a[cross], b[cross])
        uniq, first, counts = np.unique(np.stack([lo_, hi_], 1), axis=0, return_index=True,
                                        return_counts=True)
        for (x, y), f, c in zip(uniq.tolist(), first.tolist(), counts.tolist()):
            nb[x][y] = [c, f]
            nb[y][x] = [c, f]
    info = {r: stats(m) for r, m in members.items()}
    while len(members) > 1:
        into = None
        # the smallest offending part first: tiny fragments, then thin parts
        for r in sorted(members, key=lambda r: info[r][1]):
            if not nb[r]:
                continue
            border = {y: c for y, (c, _) in sorted(nb[r].items(), key=lambda kv: kv[1][1])}
            h, area, w = info[r]
            if area < small:
                into = max(border, key=lambda y: border[y])
            elif w <= thin and (lower := [y for y in border if info[y][0] < h]):
                into = max(lower, key=lambda y: (border[y], -info[y][0]))
            else:
                continue
            break
        if into is None:
            break
        for y, (c, f) in nb.pop(r).items():
            del nb[y][r]
            if y != into:
                old = nb[into].get(y, [0, f])
                nb[into][y] = nb[y][into] = [old[0] + c, min(old[1], f)]
        members[into] = np.sort(np.concatenate([members[into], members.pop(r)]))
        region[members[into]] = into
        del info[r]
        info[into] = stats(members[into])
    return np.unique(region, return_inverse=True)[1][inverse]


def _layers(z: np.ndarray, xy: np.ndarray, cell: float = VOXEL) -> list[tuple[float, float]]:
    """Horizontal layers of up-facing points: ``(height, area m²)`` of the 2 cm bins that hold
    the most xy cells, largest first (at most 2, 10 cm apart)."""
    if not len(z):
        return []
    bins = np.round(z / 0.02).astype(np.int64)
    cells = np.floor(xy / cell).astype(np.int64)
    key = np.unique(np.stack([bins, cells[:, 0], cells[:, 1]], 1), axis=0)
    b, counts = np.unique(key[:, 0], return_counts=True)
    # a layer is a bin with its neighbours (a seat cushion is not perfectly flat)
    smooth = np.array([counts[np.abs(b - x) <= 1].sum() for x in b])
    out = []
    for i in np.argsort(-smooth, kind="stable"):
        h = float(b[i] * 0.02)
        if all(abs(h - o[0]) >= 0.1 for o in out):
            out.append((h, float(smooth[i] * cell * cell)))
        if len(out) == 2:
            break
    return out


def object_features(xyz: np.ndarray, normal: np.ndarray, walls: np.ndarray,
                    top: float) -> np.ndarray:
    """The :data:`NUM_FEATURES` shape descriptors of one object's points ``xyz [M, 3]`` with
    their normals ``[M, 3]`` in a levelled room whose wall planes are ``walls [W, 3]`` and top
    ``top`` (metres): box (heights, footprint's principal extents, area), height profile,
    horizontal surfaces (the two largest up-facing layers), share of vertical surfaces, distance
    to the nearest wall. Float32."""
    xyz = np.asarray(xyz, np.float64)
    z = xyz[:, 2]
    zmin, zmax = float(np.percentile(z, 1)), float(np.percentile(z, 99))
    xy = xyz[:, :2] - xyz[:, :2].mean(0)
    if len(xy) >= 3:
        axes = np.linalg.eigh(np.cov(xy.T) + 1e-9 * np.eye(2))[1][:, ::-1]
    else:
        axes = np.eye(2)
    proj = xy @ axes
    ext = np.percentile(proj, 98, 0) - np.percentile(proj, 2, 0)
    long, short = float(max(ext)), float(min(ext))
    cells = np.unique(np.floor(xyz[:, :2] / VOXEL).astype(np.int64), axis=0)
    area = len(cells) * VOXEL * VOXEL
    edges = np.array([0.0, 0.2, 0.4, 0.6, 0.8, 1.0, 1.3, 1.7, np.inf])
    prof = np.histogram(z, edges)[0] / len(z)
    nz = np.asarray(normal)[:, 2]
    up = nz >= 0.8
    layers = _layers(z[up], xyz[up, :2]) + [(0.0, 0.0)] * 2
    side = float(np.mean(np.abs(nz) < 0.3))
    if len(walls):
        dist = np.abs(xyz[:, :2] @ walls[:, :2].T - walls[:, 2])
        near_wall = float(min(dist.min(), 3.0))
        centre_wall = float(min(np.abs(xyz[:, :2].mean(0) @ walls[:, :2].T - walls[:, 2]).min(),
                                3.0))
    else:
        near_wall = centre_wall = 3.0
    top_share = float(np.mean(z >= zmax - 0.05))
    com = float((z.mean() - zmin) / max(zmax - zmin, 1e-3))
    return np.array([
        zmin, zmax, zmax - zmin, long, short, long * short, area,
        area / max(long * short, 1e-3), short / max(long, 1e-3), *prof,
        float(up.mean()), side, layers[0][0], layers[0][1], layers[1][0], layers[1][1],
        near_wall, centre_wall, top_share, com, min(top, 4.0)], np.float32)


def support_surfaces(xyz: np.ndarray, normal: np.ndarray) -> dict:
    """What an object's points afford: ``{"surface_height": h, "affords": [...],
    "above_share": s}`` for a surface one can sit on (a layer of up-facing points 0.33–0.68 m
    high with a 0.35 m square of it) or lie on (0.25–0.85 m, 1.5 m × 0.6 m, and filled: at
    least :data:`LIE_FILL` of that rectangle's 5 cm cells hold points — the tops of an
    L-shaped sofa's back and arms make a large layer but a ring, not a bed), else ``{}``.
    ``above_share``: the share of the object's points more than 0.15 m above the surface (a
    backrest, arms; a bed's top has little above it)."""
    xyz = np.asarray(xyz)
    up = np.asarray(normal)[:, 2] >= 0.8
    out: dict = {}
    for h, _area in _layers(xyz[up, 2], xyz[up, :2]):
        layer = up & (np.abs(xyz[:, 2] - h) <= 0.04)
        pts = xyz[layer, :2]
        if len(pts) < 10:
            continue
        c = pts - pts.mean(0)
        axes = np.linalg.eigh(np.cov(c.T) + 1e-9 * np.eye(2))[1]
        ext = np.sort(np.percentile(c @ axes, 95, 0) - np.percentile(c @ axes, 5, 0))
        cells = len(np.unique(np.floor(pts / VOXEL).astype(np.int64), axis=0)) * VOXEL ** 2
        affords = []
        if _SEAT[0] <= h <= _SEAT[1] and ext[0] >= 0.3:
            affords.append("sit")
        if (_LIE[0] <= h <= _LIE[1] and ext[1] >= 1.5 and ext[0] >= 0.6
                and cells >= LIE_FILL * ext[0] * ext[1]):
            affords.append("lie")
        if affords:
            out = {"surface_height": round(float(h), 3), "affords": affords,
                   "above_share": round(float(np.mean(xyz[:, 2] > h + 0.15)), 3)}
            break
    return out


def name_by_surfaces(category: str, confidence: float, surfaces: dict) -> str:
    """The classifier's ``category`` (of probability ``confidence``) checked against what the
    object's :func:`support_surfaces` afford: a doubtful (below :data:`SURE_SEAT`) seat or bed
    name on an object with nothing to sit or lie on is an ``"object"``; a ``"bed"`` must be
    something to lie on with little above its top: with no surface to sit or lie on it is an
    ``"object"``, with a backrest (``above_share`` at least :data:`BACKREST`) a ``"sofa"``.
    Other names are kept. (On synthetic rooms of an unseen seed a sofa's seat has 22–40 % of
    its points 0.15 m above it and a bed's top 1–9 %; on real scans 56–67 % and 5–11 %.)"""
    from jaxmotion.scene.furniture import SEAT_CATEGORIES

    affords = surfaces.get("affords") or []
    if category in SEAT_CATEGORIES and confidence < SURE_SEAT and not affords:
        return "object"
    if category == "bed":
        if not affords:
            return "object"  # a bed's name on a cabinet, a wall's piece
        if surfaces.get("above_share", 0.0) >= BACKREST:
            return "sofa"  # a seat with a backrest and arms
    return category


@dataclasses.dataclass(frozen=True)
class Discovery:
    """What :func:`discover` finds in a levelled room: estimated ``normal [N, 3]``, the
    :class:`Structure`, ``instance [N]`` ids (−1: none), each instance's point indices
    (``groups``) and its descriptors (``features [K, F]``, :func:`object_features`)."""

    normal: np.ndarray
    structure: Structure
    instance: np.ndarray
    groups: tuple
    features: np.ndarray


def discover(xyz: np.ndarray, seed: int = 0) -> Discovery:
    """Structure, instances and their descriptors of a levelled room ``xyz [N, 3]``: the
    unnamed half of object discovery, shared by :func:`segment_scene` and the classifier's
    training data (:mod:`jaxmotion.data.object_features`)."""
    from jaxmotion.scene.level import estimate_normals

    xyz = np.asarray(xyz, np.float64)
    normal = estimate_normals(xyz)
    structure = find_structure(xyz, seed)
    instance = find_instances(xyz, structure)
    groups = tuple(np.flatnonzero(instance == i) for i in range(int(instance.max()) + 1))
    feats = np.stack([object_features(xyz[g], normal[g], structure.walls, structure.top)
                      for g in groups]) if groups else np.zeros((0, NUM_FEATURES), np.float32)
    return Discovery(normal, structure, instance, groups, feats)


def segment_scene(scene, *, seed: int = 0, classifier=None):
    """``scene`` (levelled) with discovered labels and object table, and notes for the user.

    Args:
      scene: a :class:`~jaxmotion.scene.Scene` in metres, z-up, floor at z = 0.
      seed: the planes' random draws.
      classifier: a callable ``features [M, F] -> probabilities [M, C]`` with a
        ``categories`` tuple, or None for the shipped one
        (:func:`jaxmotion.models.object_classifier.load_object_classifier`).
    Returns ``(scene, notes)``.
    """
    from jaxmotion.scene.objects import category_ids

    xyz = np.asarray(scene.xyz, np.float64)
    if scene.num_points < 50:
        return scene, ("the room has too few points to find objects in",)
    found = discover(xyz, seed)
    normal, structure, instance, feats = (found.normal, found.structure, found.instance,
                                          found.features)
    count = len(found.groups)
    if classifier is None:
        from jaxmotion.models.object_classifier import load_object_classifier

        classifier = load_object_classifier()
    probs = classifier(feats) if count else np.zeros((0, len(classifier.categories)))
    ids = category_ids()
    semantic = np.where(structure.label > 0, structure.label, -1).astype(np.int64)
    objects, named = [], 0
    for i, sel in enumerate(found.groups):
        best = int(np.argmax(probs[i]))
        conf = float(probs[i, best])
        cat = classifier.categories[best]
        flat = cat in ("door", "window", "picture")  # thin by nature: only their height counts
        small = feats[i, 1] < MIN_TOP or (feats[i, 4] < MIN_SIDE and not flat)  # zmax, short side
        if conf < MIN_CONFIDENCE or cat == "object" or small:
            cat = "object"
        else:
            named += 1
        pts = xyz[sel]
        surfaces = support_surfaces(pts, normal[sel])
        if cat != "object":
            cat = name_by_surfaces(cat, conf, surfaces)
            named -= cat == "object"
        surfaces.pop("above_share", None)
        semantic[sel] = ids.get(cat, -1)
        obj = {"id": i, "category": cat, "bbox_min": pts.min(0).tolist(),
               "bbox_max": pts.max(0).tolist(), "confidence": round(conf, 3),
               "points": len(sel), "source": "segment", **surfaces}
        objects.append(obj)
    notes = (f"objects found in the unlabelled room: {count} ({named} named by the shape "
             f"classifier; floor, {len(structure.walls)} wall plane(s)"
             f"{', ceiling' if (structure.label == CEILING).any() else ''})",)
    unnamed = [o for o in objects if o["category"] == "object" and o.get("affords")]
    if unnamed:
        notes += (f"{len(unnamed)} unnamed object(s) afford sitting or lying (a flat surface "
                  "at seat or bed height): they can be the target of 'sit' / 'lie'",)
    out = dataclasses.replace(scene, normal=np.where(
        (np.abs(scene.normal).sum(1) > 0)[:, None], scene.normal, normal),
        semantic=semantic, instance=instance, objects=tuple(objects))
    return out, notes
