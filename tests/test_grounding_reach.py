"""Choosing among objects by the room's free floor (jaxmotion.grounding.reach), against
brute-force NumPy, and through find_region: no model runs on the default grounding."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from jaxmotion.data.crop import CropSpec
from jaxmotion.grounding import find_region
from jaxmotion.grounding.reach import approach_areas, most_reachable, wander_target
from jaxmotion.motion.planner import BODY_TOP, CELL
from jaxmotion.planning.paths import (END_RADIUS, SIT_REACH, WALK_REACH, approach_area,
                                      floor_points, nearest_distances, point_grid)

STEP = 0.06  # point spacing of the test rooms (m)


def _grid(lo, hi, step=STEP):
    axes = [np.arange(a, b + 1e-9, step) for a, b in zip(lo, hi, strict=True)]
    return np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, len(lo))


def _box_points(lo, hi):
    """Points on the sides and top of an axis-aligned box (xyz lo, hi)."""
    (x0, y0, z0), (x1, y1, z1) = lo, hi
    faces = [_grid((x0, y0), (x1, y1)), _grid((x0, z0), (x1, z1)), _grid((y0, z0), (y1, z1))]
    top = np.c_[faces[0], np.full(len(faces[0]), z1)]
    front = np.c_[faces[1][:, 0], np.full(len(faces[1]), y0), faces[1][:, 1]]
    back = front + [0.0, y1 - y0, 0.0]
    left = np.c_[np.full(len(faces[2]), x0), faces[2]]
    right = left + [x1 - x0, 0.0, 0.0]
    return np.concatenate([top, front, back, left, right])


def make_room(size, boxes):
    """A floor of ``size`` (xy, m) with walls, and ``boxes``: ``(id, category, lo, hi, front)``;
    the walls are object 99 (structure)."""
    w, d = size
    floor = np.c_[_grid((0, 0), (w, d)), np.zeros(len(_grid((0, 0), (w, d))))]
    walls = np.concatenate([_box_points((0, 0, 0), (w, 0.01, 2.4)),
                            _box_points((0, d - 0.01, 0), (w, d, 2.4)),
                            _box_points((0, 0, 0), (0.01, d, 2.4)),
                            _box_points((w - 0.01, 0, 0), (w, d, 2.4))])
    xyz, inst = [floor, walls], [np.full(len(floor), -1), np.full(len(walls), 99)]
    objects = [{"id": 99, "category": "wall", "bbox_min": [0, 0, 0], "bbox_max": [w, d, 2.4]}]
    for i, cat, lo, hi, front in boxes:
        p = _box_points(lo, hi)
        xyz.append(p)
        inst.append(np.full(len(p), i))
        o = {"id": i, "category": cat, "bbox_min": list(lo), "bbox_max": list(hi)}
        if front is not None:
            o["front"] = [*front, 0.0]
        objects.append(o)
    xyz = np.concatenate(xyz)
    return SimpleNamespace(xyz=xyz, instance=np.concatenate(inst), objects=objects,
                           rgb=np.full_like(xyz, 0.5), num_points=len(xyz))


def brute_area(room, obj_id, reach, front=None, radius=END_RADIUS):
    """approach_area from its definition, with dense distance matrices."""
    xyz = room.xyz
    floor = xyz[xyz[:, 2] < 0.05, :2]
    obstacles = xyz[(xyz[:, 2] >= 0.1) & (xyz[:, 2] <= BODY_TOP), :2]
    lo, hi = floor.min(0), floor.max(0)
    n = np.floor((hi - lo) / CELL).astype(int) + 1
    origin = lo + 0.5 * ((hi - lo) - CELL * (n - 1))
    ij = np.stack(np.meshgrid(np.arange(n[0]), np.arange(n[1]), indexing="ij"), -1).reshape(-1, 2)
    c = origin + CELL * ij
    def dist(a, b):  # nearest distance from each of a to b, in chunks of a
        return np.concatenate([np.sqrt(((a[i:i + 256, None] - b[None]) ** 2).sum(-1)).min(1)
                               for i in range(0, len(a), 256)])

    on_floor = dist(c, floor) <= 0.15
    clearance = np.where(on_floor, np.minimum(dist(c, obstacles), 10.0), -1.0)
    target = xyz[room.instance == obj_id, :2]
    d = dist(c, target)
    goal = (clearance >= radius) & (d >= reach[0]) & (d <= reach[1])
    if front is not None:
        f = np.asarray(front, float)[:2] / np.linalg.norm(front[:2])
        ahead = (c - target.mean(0)) @ f > ((target - target.mean(0)) @ f).max()
        if (goal & ahead).any():
            goal &= ahead
    return goal.sum() * CELL * CELL


def two_stools():
    """Stool 1 in the open; stool 2 in a corner with a cabinet and a shelf around it; a chair
    facing +x against the west wall."""
    return make_room((3.0, 2.4), [
        (1, "stool", (1.3, 1.0, 0), (1.65, 1.35, 0.5), None),
        (2, "stool", (2.45, 1.95, 0), (2.8, 2.3, 0.5), None),
        (3, "cabinet", (2.0, 1.7, 0), (2.35, 2.39, 1.6), None),
        (4, "bookshelf", (2.4, 1.45, 0), (2.99, 1.85, 1.8), None),
        (5, "chair", (0.05, 0.2, 0), (0.5, 0.65, 0.9), (1.0, 0.0)),
    ])


@pytest.mark.parametrize("obj_id, reach, front", [(1, WALK_REACH, None), (2, WALK_REACH, None),
                                                  (1, SIT_REACH, None), (5, SIT_REACH, (1, 0)),
                                                  (5, WALK_REACH, (0, 1))])
@pytest.mark.parametrize("grids", [point_grid, floor_points])
def test_approach_area_matches_brute_force(obj_id, reach, front, grids):
    room = two_stools()
    grid = grids(room.xyz, room.instance)
    target = room.xyz[room.instance == obj_id, :2]
    got = approach_area(grid, target, reach=reach,
                        front=None if front is None else [*front, 0.0])
    want = brute_area(room, obj_id, reach, None if front is None else np.array(front, float))
    assert got == pytest.approx(want, abs=1e-9) and got > 0


def test_floor_points_free_cells_are_the_grids():
    """FloorPoints.free (the points near a window, no tree) marks the cells PointGrid's
    clearance does, on a room with holes in its floor and points on the cells' edges; and
    nearest_distances is the brute-force nearest distance within its bound."""
    rng = np.random.default_rng(3)
    room = two_stools()
    keep = ~((room.xyz[:, 2] < 0.05) & (np.abs(room.xyz[:, 0] - 0.9) < 0.25)
             & (room.xyz[:, 1] > 1.2))  # a hole in the floor
    jitter = rng.normal(0, 0.02, (int(keep.sum()), 3)) * [1, 1, 0]
    xyz = room.xyz[keep] + np.where(rng.random((int(keep.sum()), 1)) < 0.5, jitter, 0.0)
    inst = room.instance[keep]
    full, near = point_grid(xyz, inst), floor_points(xyz, inst)
    assert near.shape == full.shape
    np.testing.assert_array_equal(near.origin, full.origin)
    nx, ny = full.shape
    for radius in (END_RADIUS, 0.3):
        for i0, i1, j0, j1 in ((0, nx, 0, ny), (3, 17, 20, ny), (nx - 9, nx, 0, 5)):
            np.testing.assert_array_equal(near.free(i0, i1, j0, j1, radius),
                                          full.free(i0, i1, j0, j1, radius))
    known = near.measured(END_RADIUS)  # the whole grid once, then windows cut from it
    for _ in range(2):  # a window handed out is the caller's to change
        cut = known.free(3, 17, 20, ny, END_RADIUS)
        np.testing.assert_array_equal(cut, full.free(3, 17, 20, ny, END_RADIUS))
        cut[:] = False
    # many objects (measured once) and few (window by window): PointGrid's areas
    objects = [o for o in room.objects if o["id"] != 99]
    room_ns = SimpleNamespace(xyz=xyz, instance=inst)
    for objs in (objects, objects[:2]):
        want = [approach_area(full, xyz[inst == o["id"], :2], reach=SIT_REACH,
                              front=o.get("front")) for o in objs]
        np.testing.assert_array_equal(approach_areas(room_ns, objs, "sit"), want)
    q, pts = rng.uniform(0, 3, (200, 2)), rng.uniform(0, 3, (300, 2))
    d = np.sqrt(((q[:, None] - pts[None]) ** 2).sum(-1)).min(1)
    got = nearest_distances(q, pts, 0.2)
    np.testing.assert_array_equal(got[d <= 0.2], d[d <= 0.2])
    assert np.all(got[d > 0.2] > 0.2)


def test_the_open_stool_is_chosen_and_ties_go_to_the_lowest_id():
    room = two_stools()
    stools = [o for o in room.objects if o["category"] == "stool"]
    areas = approach_areas(room, stools, "sit")
    assert areas[0] > 2 * areas[1] > 0
    assert stools[most_reachable(room, stools, "sit")]["id"] == 1
    back = stools[::-1]
    assert back[most_reachable(room, back, "sit")]["id"] == 1  # the order does not matter


def test_ties_go_to_the_lowest_id(monkeypatch):
    import jaxmotion.grounding.reach as reach

    room = two_stools()
    by_id = {o["id"]: o for o in room.objects}
    pair = [by_id[5], by_id[3]]  # chair 5 listed before cabinet 3
    monkeypatch.setattr(reach, "approach_areas", lambda *a, **k: np.array([0.5, 0.5]))
    assert pair[most_reachable(room, pair)]["id"] == 3
    monkeypatch.setattr(reach, "approach_areas", lambda *a, **k: np.array([0.6, 0.5]))
    assert pair[most_reachable(room, pair)]["id"] == 5


def test_a_wander_is_drawn_with_the_seed_in_proportion_to_free_floor():
    room = two_stools()
    pool = room.objects[1:]  # the furniture: the walls are object 99
    areas = approach_areas(room, pool)
    draws = [wander_target(room, room.objects, s)["id"] for s in range(600)]
    assert draws[:20] == [wander_target(room, room.objects, s)["id"] for s in range(20)]
    assert 99 not in draws  # the walls are never a destination
    freq = np.array([draws.count(o["id"]) for o in pool]) / len(draws)
    np.testing.assert_allclose(freq, areas / areas.sum(), atol=0.055)  # > 3 sigma
    hemmed = make_room((1.0, 1.0), [(1, "stool", (0.1, 0.1, 0), (0.9, 0.9, 0.5), None)])
    assert wander_target(hemmed, hemmed.objects, 0) is None  # no free floor: the ADM decides
    door = (8, "door", (1.0, 2.3, 0), (1.9, 2.39, 2.0), (0.0, -1.0))
    with_door = make_room((3.0, 2.4), [*[(o["id"], o["category"], o["bbox_min"], o["bbox_max"],
                                          None) for o in room.objects[1:]], door])
    assert 8 not in {wander_target(with_door, with_door.objects, s)["id"] for s in range(30)}


def test_a_wander_goes_to_a_door_only_when_no_furniture_has_free_floor(monkeypatch):
    import jaxmotion.grounding.reach as reach

    door = (8, "door", (1.0, 2.3, 0), (1.9, 2.39, 2.0), (0.0, -1.0))
    room = make_room((3.0, 2.4), [(1, "stool", (1.3, 1.0, 0), (1.65, 1.35, 0.5), None), door])
    assert wander_target(room, room.objects, 0)["id"] == 1
    monkeypatch.setattr(reach, "approach_areas", lambda r, pool, action=None: np.array(
        [float(o["category"] == "door") for o in pool]))  # the stool hemmed in
    assert wander_target(room, room.objects, 0)["id"] == 8


class _NoADM:
    """An AdmChooser stand-in that fails the test if the ADM is asked to run."""

    seed = 0

    def __getattr__(self, name):
        raise AssertionError(f"the ADM ran ({name})")


def test_find_region_chooses_by_free_floor_without_running_the_adm():
    room = two_stools()
    spec = CropSpec(size=4.0, num_points=256)
    centre, chosen, how = find_region(room, "sit on the stool", "auto", spec, adm=_NoADM())
    assert (chosen, how) == (1, "reach")
    np.testing.assert_allclose(centre, [1.5, 1.2])  # the room is smaller than the square
    _, chosen, how = find_region(room, "wander around for a bit", "auto", spec, adm=_NoADM(),
                                 seed=3)
    assert how == "wander" and chosen == wander_target(room, room.objects, 3)["id"]
    _, chosen, how = find_region(room, "sit on the stool next to the bookshelf", "auto", spec,
                                 adm=_NoADM())
    assert (chosen, how) == (2, "scene graph")  # the words first
    with pytest.raises(AssertionError, match="the ADM ran"):  # asked for: the ADM chooses
        find_region(room, "sit on the stool", "adm", spec, adm=_NoADM())
    big = make_room((9.0, 3.0), [])  # wider than the square: tiles for the ADM to choose among
    unlabelled = SimpleNamespace(**{**vars(big), "objects": [],
                                    "instance": np.full(len(big.xyz), -1),
                                    "semantic": np.full(len(big.xyz), -1)})
    with pytest.raises(AssertionError, match="the ADM ran"):  # no labels: only the ADM can
        find_region(unlabelled, "wander around", "auto", spec, adm=_NoADM())
