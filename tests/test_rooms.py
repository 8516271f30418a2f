"""Tests for the synthetic rooms: furniture builders, layouts, free floor, points, meshes."""

from __future__ import annotations

import dataclasses
import itertools

import numpy as np
import pytest
from scipy import ndimage

from jaxmotion.scene import furniture as F
from jaxmotion.scene import load_scene
from jaxmotion.scene._parts import moved, part, part_triangles
from jaxmotion.scene.rooms import (APPROACH_DISTANCE, ROOM_KINDS, Room, approach_points,
                                   free_space_grid, is_navigable, room_to_mesh, room_to_scene,
                                   sample_room)

# category: (min box size [x, y, z], max box size, surface-height range or None), metres.
# Object-local x is the width, y the depth (front = +y), z the height.
SIZES = {
    "chair": ((0.40, 0.40, 0.77), (0.50, 0.50, 1.00), (0.42, 0.50)),
    "armchair": ((0.66, 0.70, 0.75), (0.97, 0.90, 1.00), (0.40, 0.46)),
    "sofa": ((1.30, 0.80, 0.75), (2.55, 1.00, 0.95), (0.40, 0.45)),
    "bed": ((0.90, 1.95, 0.85), (1.80, 2.15, 1.20), (0.45, 0.60)),
    "table": ((0.75, 0.75, 0.72), (2.00, 1.20, 0.78), None),
    "desk": ((1.00, 0.55, 0.72), (1.60, 0.75, 0.76), None),
    "coffee table": ((0.80, 0.45, 0.38), (1.30, 0.70, 0.48), None),
    "cabinet": ((0.60, 0.40, 0.70), (1.60, 0.64, 2.10), None),
    "bookshelf": ((0.60, 0.25, 1.00), (1.20, 0.40, 2.00), None),
    "toilet": ((0.34, 0.66, 0.72), (0.46, 0.82, 0.82), (0.40, 0.44)),
    "stool": ((0.30, 0.30, 0.42), (0.40, 0.40, 0.65), (0.42, 0.65)),
    "nightstand": ((0.40, 0.35, 0.45), (0.55, 0.48, 0.65), None),
    "door": ((0.90, 0.04, 2.00), (1.10, 0.12, 2.20), None),
    "window": ((0.85, 0.05, 1.00), (1.70, 0.16, 1.55), None),
    "sink": ((0.50, 0.45, 1.00), (0.90, 0.60, 1.20), None),
    "fridge": ((0.60, 0.60, 1.60), (0.80, 0.80, 2.00), None),
    "lamp": ((0.20, 0.20, 0.30), (0.32, 0.32, 0.60), None),
    "tv": ((0.80, 0.10, 0.50), (1.30, 0.25, 0.85), None),
    "picture": ((0.40, 0.02, 0.30), (1.20, 0.05, 0.80), None),
}
FLOOR_STANDING = set(F.BUILDERS) - set(F.WALL_MOUNTED) - set(F.SMALL_OBJECTS)


def test_category_table():
    assert set(SIZES) == set(F.BUILDERS)
    actable = set(F.BUILDERS) - set(F.SMALL_OBJECTS) - {"picture"}
    assert len(actable) >= 11 and {"door", "window", "sink", "fridge"} <= actable
    ids = list(F.CATEGORY_IDS.values())
    assert len(set(ids)) == len(ids) and F.CATEGORY_IDS["floor"] != F.CATEGORY_IDS["wall"]
    assert all(1 <= F.NYU40_ID[c] <= 40 for c in F.CATEGORY_IDS)


@pytest.mark.parametrize("category", sorted(F.BUILDERS))
def test_builder_sizes_and_variety(category):
    lo_size, hi_size, surface = SIZES[category]
    sizes = []
    for seed in range(40):
        m = F.build(category, np.random.default_rng(seed))
        size = m.hi - m.lo
        assert np.all(size >= np.array(lo_size) - 1e-9), (seed, size)
        assert np.all(size <= np.array(hi_size) + 1e-9), (seed, size)
        np.testing.assert_allclose(m.lo[:2] + m.hi[:2], 0.0, atol=1e-9)  # centred in xy
        assert m.lo[2] >= -1e-9 and all(np.all(np.array(p.rgb) >= 0) for p in m.parts)
        if surface is None:
            assert m.surface_height is None
        else:
            assert surface[0] - 1e-9 <= m.surface_height <= surface[1] + 1e-9
            assert m.surface_height <= m.hi[2] + 1e-9
        sizes.append(size)
    assert np.ptp(np.array(sizes), axis=0).max() > 0.05  # visibly different shapes
    a = F.build(category, np.random.default_rng(3))
    assert a == F.build(category, np.random.default_rng(3))  # same seed, same piece


def test_seat_categories_face_forward():
    for c in ("chair", "armchair", "sofa", "toilet"):
        m = F.build(c, np.random.default_rng(0))
        assert m.fronts == ((0.0, 1.0),)
        back = max(m.parts, key=lambda p: p.hi[2])  # the highest part is at the back
        assert back.lo[1] < 0.0
    assert set(F.build("bed", np.random.default_rng(0)).fronts) == {(1.0, 0.0), (-1.0, 0.0)}


def _feet(room):
    return {o["id"]: (*o["bbox_min"][:2], *o["bbox_max"][:2]) for o in room.objects}


def rect_overlap(a, b):
    return max(0, min(a[2], b[2]) - max(a[0], b[0])) * max(0, min(a[3], b[3]) - max(a[1], b[1]))


def _xy_gap(a, b):
    return np.hypot(max(0, b[0] - a[2], a[0] - b[2]), max(0, b[1] - a[3], a[1] - b[3]))


def check_room(room: Room):
    """Every structural promise of sample_room, checked independently."""
    objs = room.objects
    assert [o["id"] for o in objs] == list(range(len(objs)))
    cats = [o["category"] for o in objs]
    assert cats.count("door") == 1 and cats.count("window") <= 2
    n_furniture = sum(c in FLOOR_STANDING for c in cats)
    assert 4 <= n_furniture <= 10
    rects = np.array(room.floor_rects)
    for r1, r2 in itertools.combinations(rects, 2):  # floor rectangles are disjoint
        assert rect_overlap(r1, r2) <= 1e-9
    side = np.concatenate([rects[:, 2:] - rects[:, :2]]).max()
    assert 1.5 <= side <= 7.0 + 1e-9
    feet = _feet(room)
    for o in objs:
        lo, hi = np.array(o["bbox_min"]), np.array(o["bbox_max"])
        assert np.all(hi > lo) and lo[2] >= -1e-9 and hi[2] <= room.wall_height + 1e-9
        f = feet[o["id"]]
        covered = sum(rect_overlap(f, r) for r in rects)
        assert covered >= (f[2] - f[0]) * (f[3] - f[1]) - 1e-9  # on the floor
        if "front" in o:
            fr = np.array(o["front"])
            assert fr[2] == 0 and sorted(np.abs(fr).tolist()) == [0.0, 0.0, 1.0]  # axis-aligned
        if o["category"] in F.SEAT_CATEGORIES:
            assert lo[2] < o["surface_height"] <= hi[2]
            assert "front" in o or o["category"] == "stool"
        else:
            assert "surface_height" not in o
        if o["category"] == "bed":
            assert np.dot(o["head"], o["front"]) == 0
        if "parent" in o:
            parent = objs[o["parent"]]
            assert o["category"] in ("lamp", "tv", "picture")
            assert lo[2] >= parent["bbox_max"][2] - 1e-9
    for a, b in itertools.combinations(objs, 2):  # no two boxes share volume
        inter = np.minimum(a["bbox_max"], b["bbox_max"]) - np.maximum(a["bbox_min"], b["bbox_min"])
        assert not np.all(inter > 1e-9), (a, b)
        if a["category"] in FLOOR_STANDING and b["category"] in FLOOR_STANDING:
            assert _xy_gap(feet[a["id"]], feet[b["id"]]) >= 0.05 - 1e-9, (a, b)
    # Navigable: every object's approach point in the door's free component (checked here
    # with 8-connectivity off, i.e. scipy's default 4-connected labelling).
    free, origin, res = free_space_grid(room)
    labels, _ = ndimage.label(free)

    def comps(pts):
        cells = np.floor((pts - origin) / res).astype(int)  # points off the grid are walls
        return {labels[iy, ix] for ix, iy in cells
                if 0 <= ix < free.shape[1] and 0 <= iy < free.shape[0]} - {0}

    door = comps(approach_points(room, cats.index("door")))
    assert len(door) == 1
    for o in objs:
        assert door & comps(approach_points(room, o["id"])), o
    assert is_navigable(room)


@pytest.mark.parametrize("kind", ROOM_KINDS)
@pytest.mark.parametrize("shape", ["rect", "L"])
def test_sampled_rooms_are_valid(kind, shape):
    for seed in range(3):
        room = sample_room(np.random.default_rng([seed, len(kind)]), kind=kind, shape=shape)
        assert room.kind == kind and room.shape == shape
        assert len(room.floor_rects) == (1 if shape == "rect" else 2)
        assert len(room.walls) == (4 if shape == "rect" else 6)
        check_room(room)


@pytest.mark.slow
def test_many_random_rooms_are_valid():
    for seed in range(300):
        check_room(sample_room(seed))


def test_rooms_have_variety():
    rooms = [sample_room(s) for s in range(40)]
    cats = {o["category"] for r in rooms for o in r.objects}
    assert cats == set(F.BUILDERS)  # every category shows up
    assert {r.kind for r in rooms} == set(ROOM_KINDS) and {r.shape for r in rooms} == {"rect", "L"}
    assert len({round(r.bounds()[1][0], 6) for r in rooms}) == 40


def test_determinism():
    a, b, c = sample_room(11), sample_room(11), sample_room(12)
    assert a == b and a != c
    sa, sb = room_to_scene(a, 3000, 5), room_to_scene(b, 3000, np.random.default_rng(5))
    for key in ("xyz", "rgb", "normal", "semantic", "instance"):
        np.testing.assert_array_equal(getattr(sa, key), getattr(sb, key))
    assert not np.array_equal(sa.xyz, room_to_scene(a, 3000, 6).xyz)
    with pytest.raises(TypeError):
        sample_room(None)
    with pytest.raises(ValueError):
        sample_room(0, kind="garage")


def test_walls_and_floor_plan():
    room = sample_room(4, shape="L")
    area = sum((r[2] - r[0]) * (r[3] - r[1]) for r in room.floor_rects)
    w = np.array(room.walls)
    shoelace = 0.5 * np.sum(w[:, 0] * w[:, 3] - w[:, 2] * w[:, 1])
    assert np.isclose(shoelace, area)  # walls trace the floor counter-clockwise
    assert np.allclose(w[:, 2:], np.roll(w[:, :2], -1, axis=0))  # a closed loop


def test_point_labels_match_boxes():
    room = sample_room(21, kind="bedroom")
    scene = room_to_scene(room, 20000, 0)
    assert scene.num_points == 20000 and len(scene.objects) == len(room.objects)
    xyz, sem, ins = scene.xyz.astype(float), scene.semantic, scene.instance
    np.testing.assert_allclose(np.linalg.norm(scene.normal, axis=1), 1.0, atol=1e-5)
    for o in room.objects:
        m = ins == o["id"]
        assert m.sum() > 0, o["category"]
        assert np.all(sem[m] == F.CATEGORY_IDS[o["category"]])
        assert np.all(xyz[m] >= np.array(o["bbox_min"]) - 1e-4)
        assert np.all(xyz[m] <= np.array(o["bbox_max"]) + 1e-4)
    floor, wall = sem == F.CATEGORY_IDS["floor"], sem == F.CATEGORY_IDS["wall"]
    assert np.all(ins[floor | wall] == -1) and np.all(floor | wall | (ins >= 0))
    np.testing.assert_allclose(xyz[floor, 2], 0.0, atol=1e-5)
    assert np.all(scene.normal[floor, 2] > 0.99)
    seg = np.array(room.walls)
    p0, d = seg[:, :2], seg[:, 2:] - seg[:, :2]
    rel = xyz[wall, None, :2] - p0[None]
    t = np.clip(np.einsum("nwc,wc->nw", rel, d) / np.einsum("wc,wc->w", d, d), 0, 1)
    dist = np.linalg.norm(rel - t[..., None] * d[None], axis=-1).min(1)
    assert dist.max() < 1e-4 and np.all(xyz[wall, 2] >= 0)
    assert np.all(xyz[wall, 2] <= room.wall_height + 1e-6)
    # Hidden surfaces are not sampled: no point lies in or on a box of another object
    # (floor under furniture, wall behind a door, window or picture).
    for p in room.parts:
        if p.instance >= 0 and p.shape == "box":
            inside = np.all((xyz >= np.array(p.lo) - 1e-5) & (xyz <= np.array(p.hi) + 1e-5), 1)
            assert not (inside & (ins != p.instance)).any()
    # No point of the floor shows under a floor-standing box that rests on the floor.
    for p in room.parts:
        if p.instance >= 0 and p.lo[2] <= 1e-9 and p.shape == "box":
            lo, hi = np.array(p.lo[:2]) + 1e-3, np.array(p.hi[:2]) - 1e-3
            assert not (floor & np.all((xyz[:, :2] > lo) & (xyz[:, :2] < hi), 1)).any()


def _hand_room(objects, parts=()):
    walls = ((0.0, 0.0, 4.0, 0.0), (4.0, 0.0, 4.0, 3.0), (4.0, 3.0, 0.0, 3.0), (0.0, 3.0, 0.0, 0.0))
    return Room("hand", "office", "rect", ((0.0, 0.0, 4.0, 3.0),), 2.5, walls, tuple(objects),
                tuple(parts))


def test_free_space_grid_and_navigability():
    door = dict(id=0, category="door", bbox_min=[0.0, 1.0, 0.0], bbox_max=[0.09, 2.0, 2.1],
                front=[1.0, 0.0, 0.0])
    chair = dict(id=1, category="chair", bbox_min=[3.0, 1.3, 0.0], bbox_max=[3.45, 1.75, 0.9],
                 front=[-1.0, 0.0, 0.0], surface_height=0.45)
    room = _hand_room([door, chair])
    free, origin, res = free_space_grid(room, resolution=0.05, clearance=0.2)
    assert free.shape == (60, 80) and np.allclose(origin, 0.0) and res == 0.05
    cell = lambda x, y: free[int(y / res), int(x / res)]  # noqa: E731
    assert cell(2.0, 1.5) and not cell(0.1, 0.5) and not cell(3.9, 2.0)  # walls
    assert not cell(2.87, 1.5) and cell(2.72, 1.5)  # 0.13 vs 0.28 m from the chair
    np.testing.assert_allclose(approach_points(room, 1), [[3.0 - APPROACH_DISTANCE, 1.525]])
    assert len(approach_points(room, 0)) == 1 and is_navigable(room)
    # A wall-to-wall cabinet between the door and the chair cuts the room in two.
    cab = dict(id=2, category="cabinet", bbox_min=[1.8, 0.0, 0.0], bbox_max=[2.3, 3.0, 2.0],
               front=[1.0, 0.0, 0.0])
    assert not is_navigable(_hand_room([door, chair, cab]))
    table = dict(id=1, category="table", bbox_min=[1.0, 1.0, 0.0], bbox_max=[2.0, 2.0, 0.75])
    assert len(approach_points(_hand_room([door, table]), 1)) == 4


def test_mesh_export_round_trip(tmp_path):
    room = sample_room(5)
    mesh = room_to_mesh(room)
    lo, hi = room.bounds()
    assert np.all(mesh.vertices.min(0) >= [*lo - 0.11, -1e-9])
    assert mesh.vertices.max(0)[2] <= room.wall_height + 1e-9
    assert mesh.visual.kind == "vertex" and len(mesh.faces) > 100
    mesh.export(tmp_path / "room.ply")
    ply = load_scene(tmp_path / "room.ply", num_points=2000, seed=0)
    glb_path = tmp_path / "room.glb"
    room_to_mesh(room, up="y").export(glb_path)
    glb = load_scene(glb_path, num_points=2000, seed=0)  # .glb is read as y-up, turned z-up
    for scene in (ply, glb):
        smin, smax = scene.bounds()
        assert smin[2] >= -1e-4 and smax[2] <= room.wall_height + 1e-4
        assert np.all(smin[:2] >= lo - 0.11) and np.all(smax[:2] <= hi + 0.11)
        assert scene.rgb.std() > 0.01  # colours survived
    with pytest.raises(ValueError):
        room_to_mesh(room, up="x")


def test_object_parts_are_labelled():
    room = sample_room(8)
    for p in room.parts:
        if p.instance >= 0:
            o = room.objects[p.instance]
            assert p.semantic == F.CATEGORY_IDS[o["category"]]
            assert np.all(np.array(p.lo) >= np.array(o["bbox_min"]) - 1e-9)
            assert np.all(np.array(p.hi) <= np.array(o["bbox_max"]) + 1e-9)
        else:
            assert p.semantic in (F.CATEGORY_IDS["floor"], F.CATEGORY_IDS["wall"])


def test_quarter_turns_keep_boxes_and_faces():
    only_front = (False, False, False, True, False, False)
    p = dataclasses.replace(part(0.0, 1.0, 0.0, 2.0, 0.0, 0.5, (1, 0, 0)), faces=only_front)
    q = moved(p, 1, (10.0, 0.0, 0.0))  # +90 deg about z: (x, y) -> (-y, x), then shift
    np.testing.assert_allclose(q.lo, (8.0, 0.0, 0.0))
    np.testing.assert_allclose(q.hi, (10.0, 1.0, 0.5))
    assert q.faces == (True,) + (False,) * 5  # the +y face now points to -x
    tri, normal = part_triangles(q)
    assert len(tri) == 2 and np.allclose(normal, [-1.0, 0.0, 0.0])
