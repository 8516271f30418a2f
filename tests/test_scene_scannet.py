"""ScanNet scans and PROX scene meshes (jaxmotion.scene.scans): every file is written here in
the datasets' exact formats (binary PLY with rgba vertices, segs.json, aggregation.json, the
scene .txt with its axisAlignment) from boxes whose aligned positions are known."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import trimesh

from jaxmotion.cli import main
from jaxmotion.errors import GenerateError
from jaxmotion.scene import SceneError, load_scene, load_scene_and_notes
from jaxmotion.scene.scans import category_of, find_scan, floor_height, read_alignment

SID = "scene0042_00"
# (raw label, aligned box [lo, hi]); None: a box no segGroup covers
BOXES = [
    ("floor", [[-0.5, -0.5, -0.02], [4.5, 3.5, 0.0]]),
    ("office chair", [[0.5, 0.5, 0.0], [1.0, 1.0, 0.9]]),
    ("couch", [[2.0, 0.2, 0.0], [4.0, 1.1, 0.8]]),
    ("coffee table", [[2.4, 1.6, 0.0], [3.6, 2.2, 0.45]]),
    ("kitchen cabinets", [[0.0, 3.0, 0.0], [1.5, 3.4, 0.9]]),
    ("trash can", [[4.0, 3.0, 0.0], [4.3, 3.3, 0.5]]),
    (None, [[1.2, 2.0, 0.0], [1.4, 2.2, 0.3]]),
]
OBJECT_IDS = [3, 0, 5, 1, 2, 4]  # objectId of each labelled box, not in file order
WANT = {0: ("chair", 5), 5: ("sofa", 6), 1: ("coffee table", 42), 2: ("cabinet", 3),
        4: ("trash can", 40)}  # objectId -> (category, semantic id); 3 is the floor


def _alignment(degrees=30.0, t=(2.0, -1.0, 0.03)):
    c, s = np.cos(np.deg2rad(degrees)), np.sin(np.deg2rad(degrees))
    a = np.eye(4)
    a[:3, :3] = [[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]
    a[:3, 3] = t
    return a


def write_ply(path, xyz, faces, rgba=None, label=None):
    """A binary little-endian PLY as ScanNet writes it: float x y z, uchar red green blue
    alpha (and ushort label for _vh_clean_2.labels.ply), faces as uchar-int lists."""
    n = len(xyz)
    rgba = np.full((n, 4), 200, np.uint8) if rgba is None else rgba
    fields = [("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("red", "u1"), ("green", "u1"),
              ("blue", "u1"), ("alpha", "u1")] + ([("label", "<u2")] if label is not None else [])
    v = np.zeros(n, fields)
    for i, c in enumerate("xyz"):
        v[c] = xyz[:, i]
    for i, c in enumerate(("red", "green", "blue", "alpha")):
        v[c] = rgba[:, i]
    if label is not None:
        v["label"] = label
    f = np.zeros(len(faces), [("n", "u1"), ("i", "<i4", (3,))])
    f["n"], f["i"] = 3, faces
    types = {"<f4": "float", "u1": "uchar", "<u2": "ushort"}
    head = ["ply", "format binary_little_endian 1.0", f"element vertex {n}",
            *(f"property {types[t]} {k}" for k, t in fields), f"element face {len(faces)}",
            "property list uchar int vertex_indices", "end_header"]
    Path(path).write_bytes(("\n".join(head) + "\n").encode() + v.tobytes() + f.tobytes())


def make_scan(folder: Path, *, align=None, labels_ply=False, with_txt=True, sid=SID):
    """A ScanNet scan ``sid`` of BOXES in ``folder``; returns (raw float32 vertices [V, 3], box
    index per vertex, its axisAlignment A)."""
    a = _alignment() if align is None else align
    folder.mkdir(parents=True, exist_ok=True)
    verts, faces, owner = [], [], []
    for k, (_, (lo, hi)) in enumerate(BOXES):
        box = trimesh.creation.box(bounds=np.array([lo, hi]))
        faces.append(np.asarray(box.faces) + 8 * k)
        verts.append(np.asarray(box.vertices))
        owner += [k] * 8
    aligned = np.concatenate(verts)
    raw = ((aligned - a[:3, 3]) @ a[:3, :3]).astype(np.float32)  # the inverse of A
    faces = np.concatenate(faces)
    rng = np.random.default_rng(0)
    write_ply(folder / f"{sid}_vh_clean_2.ply", raw, faces,
              np.concatenate([rng.integers(0, 256, (len(raw), 3)),
                              np.full((len(raw), 1), 255)], 1).astype(np.uint8))
    # two segments per box (its first and last four vertices), ids as ScanNet's: sparse ints
    seg = np.array([1000 + 37 * (2 * k + (j >= 4)) for k in range(len(BOXES)) for j in range(8)])
    (folder / f"{sid}_vh_clean_2.0.010000.segs.json").write_text(json.dumps(
        {"params": {"kThresh": "0.0001", "segMinVerts": "20"}, "sceneId": sid,
         "segIndices": seg.tolist()}))
    groups = [{"id": oid, "objectId": oid, "segments": [1000 + 74 * k, 1000 + 74 * k + 37],
               "label": BOXES[k][0]} for k, oid in enumerate(OBJECT_IDS)]
    (folder / f"{sid}.aggregation.json").write_text(json.dumps(
        {"sceneId": f"scannet.{sid}", "appId": "Aggregator.v2", "segGroups": groups,
         "segmentsFile": f"scannet.{sid}_vh_clean_2.0.010000.segs.json"}))
    if with_txt:
        (folder / f"{sid}.txt").write_text(
            "axisAlignment = " + " ".join(f"{v:.9f}" for v in a.reshape(-1)) + "\n"
            "colorHeight = 968\ncolorWidth = 1296\nnumColorFrames = 5578\n")
    if labels_ply:  # NYU40 per vertex: 39 (otherfurniture) on the trash can
        lab = np.array([{0: 2, 5: 39}.get(k, 0) for k in owner], np.uint16)
        write_ply(folder / f"{sid}_vh_clean_2.labels.ply", raw, faces, label=lab)
    return raw, np.array(owner), a


def _box_distance(p, lo, hi):
    """Unsigned distance [N] from points to the surface of the box [lo, hi]."""
    lo, hi = np.asarray(lo), np.asarray(hi)
    outside = np.linalg.norm(np.maximum(np.maximum(lo - p, p - hi), 0.0), axis=1)
    inside = np.minimum(p - lo, hi - p).min(axis=1)
    return np.where(outside > 0, outside, np.abs(inside))


def test_scan_folder_objects_categories_and_alignment(tmp_path):
    folder = tmp_path / "scans" / SID
    raw, owner, a = make_scan(folder)
    scene, notes = load_scene_and_notes(folder, num_points=4000, seed=1)
    assert scene.name == SID and scene.num_points == 4000
    assert "5 objects" in notes[0] and f"{SID}.txt" in notes[0]
    assert "trash can" in notes[1]  # kept as its own category, and said so
    got = {o["id"]: (o["category"], o["label"]) for o in scene.objects}
    assert got == {oid: (WANT[oid][0], BOXES[OBJECT_IDS.index(oid)][0]) for oid in WANT}
    aligned = raw.astype(np.float64) @ a[:3, :3].T + a[:3, 3]  # brute force, per vertex
    for o in scene.objects:
        k = OBJECT_IDS.index(o["id"])
        np.testing.assert_allclose(o["bbox_min"], aligned[owner == k].min(0), atol=1e-7)
        np.testing.assert_allclose(o["bbox_max"], aligned[owner == k].max(0), atol=1e-7)
        np.testing.assert_allclose([o["bbox_min"], o["bbox_max"]], BOXES[k][1], atol=1e-5)
    # every sampled point lies on its box's surface in the aligned frame, with its labels
    xyz = scene.xyz.astype(np.float64)
    on_box = np.stack([_box_distance(xyz, lo, hi) < 1e-4 for _, (lo, hi) in BOXES], 1)
    assert on_box.any(1).all()
    only = on_box & (on_box.sum(1, keepdims=True) == 1)  # on one box's surface alone
    assert (scene.semantic[only[:, 0]] == 2).all() and (scene.instance[only[:, 0]] == -1).all()
    assert (scene.semantic[only[:, -1]] == -1).all() and (scene.instance[only[:, -1]] == -1).all()
    for k, oid in enumerate(OBJECT_IDS[1:], start=1):
        on = scene.instance == oid
        assert on.sum() > 20 and on_box[on, k].all() and on[only[:, k]].all()
        assert (scene.semantic[on] == WANT[oid][1]).all()
    np.testing.assert_allclose(np.linalg.norm(scene.normal, axis=1), 1.0, atol=1e-5)
    inner = (np.abs(xyz[:, :2] - [2.0, 1.5]) < [2.49, 1.99]).all(1)
    top = only[:, 0] & inner & (xyz[:, 2] > -1e-3)  # the floor's top: flat once aligned
    assert top.sum() > 500 and np.abs(scene.normal[top, 2]).min() > 0.999
    # the _vh_clean_2.ply itself, with its annotations beside it, is the same scan
    same = load_scene(folder / f"{SID}_vh_clean_2.ply", num_points=4000, seed=1)
    np.testing.assert_array_equal(same.xyz, scene.xyz)
    assert same.objects == scene.objects


def test_category_of_raw_labels():
    cases = {"office chair": ("chair", 5), "Couch": ("sofa", 6), "armchair": ("armchair", 41),
             "sofa chair": ("armchair", 41), "kitchen cabinets": ("cabinet", 3),
             "coffee table": ("coffee table", 42), "end table": ("table", 7),
             "boxes": ("box", 29), "shelves": ("shelves", 15), "refrigerator": ("fridge", 24),
             "toilet": ("toilet", 33), "desk": ("desk", 14), "nightstand": ("nightstand", 32),
             "ottoman": ("stool", 43), "wall": ("wall", 1), "bed": ("bed", 4)}
    for raw, want in cases.items():
        assert category_of(raw) == want, raw
    assert category_of("trash can") is None and category_of("") is None


def test_labels_ply_names_what_the_table_does_not_know(tmp_path):
    make_scan(tmp_path / SID, labels_ply=True)
    scene = load_scene(tmp_path / SID, num_points=2000)
    can = next(o for o in scene.objects if o["id"] == 4)
    assert can["category"] == "otherfurniture" and can["label"] == "trash can"
    assert (scene.semantic[scene.instance == 4] == 39).all()


def test_read_alignment_checks_the_matrix(tmp_path):
    txt = tmp_path / "s.txt"
    a = _alignment()
    txt.write_text("sceneType = Bedroom\naxisAlignment = " + " ".join(map(str, a.ravel())) + "\n")
    np.testing.assert_allclose(read_alignment(txt), a)
    for text, match in (("colorHeight = 968\n", "no 'axisAlignment"),
                        ("axisAlignment = 1 0 0\n", "16 numbers"),
                        ("axisAlignment = " + " ".join(["2"] + ["0"] * 4 + ["1"] + ["0"] * 4
                                                       + ["1"] + ["0"] * 4 + ["1"]) + "\n",
                         "not a rotation")):
        txt.write_text(text)
        with pytest.raises(SceneError, match=match):
            read_alignment(txt)


def test_missing_or_broken_annotation_files_are_named(tmp_path):
    folder = tmp_path / SID
    make_scan(folder)
    agg = folder / f"{SID}.aggregation.json"
    saved = agg.read_text()
    agg.unlink()
    with pytest.raises(SceneError, match=rf"no {SID}\.aggregation\.json.*download") as err:
        load_scene(folder)
    assert str(folder) in str(err.value)
    # the mesh given alone, without an aggregation beside it, is a plain (unaligned) mesh
    plain = load_scene(folder / f"{SID}_vh_clean_2.ply", num_points=500)
    assert plain.objects == () and (plain.instance == -1).all()
    agg.write_text(saved)
    segs = folder / f"{SID}_vh_clean_2.0.010000.segs.json"
    good_segs = segs.read_text()
    segs.unlink()
    with pytest.raises(SceneError, match=r"_vh_clean_2\.0\.010000\.segs\.json"):
        load_scene(folder)
    segs.write_text(json.dumps({"segIndices": json.loads(good_segs)["segIndices"][:-3]}))
    with pytest.raises(SceneError, match="different meshes"):
        load_scene(folder)
    segs.write_text("{not json")
    with pytest.raises(SceneError, match="not a readable ScanNet segmentation JSON"):
        load_scene(folder)
    segs.write_text(good_segs)
    agg.write_text(saved.replace("[1000, 1037]", "[1000, 99999]"))
    with pytest.raises(SceneError, match=r"segments \[99999\]"):
        load_scene(folder)
    agg.write_text(json.dumps({"segGroups": [{"label": "chair", "segments": [1]}]}))
    with pytest.raises(SceneError, match="objectId"):
        load_scene(folder)
    agg.write_text(saved)
    (folder / f"{SID}.txt").unlink()
    with pytest.raises(SceneError, match=rf"no {SID}\.txt.*axisAlignment"):
        load_scene(folder)
    with pytest.raises(SceneError, match="without a ScanNet mesh"):
        load_scene(tmp_path)
    with pytest.raises(SceneError, match="z-up"):
        load_scene(folder, up="y")


def test_scene_info_and_generate_arguments_on_a_scan_folder(tmp_path, capsys):
    from jaxmotion.scene.demo import load_scene_arg

    folder = tmp_path / "scans" / SID
    make_scan(folder)
    assert main(["scene", "info", str(folder), "--points", "3000"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["name"] == SID and info["points"] == 3000 and info["objects"] == 5
    assert sorted(o["category"] for o in info["object_table"]) == [
        "cabinet", "chair", "coffee table", "sofa", "trash can"]
    chair = next(o for o in info["object_table"] if o["id"] == 0)
    np.testing.assert_allclose(chair["centre"], [0.75, 0.75, 0.45], atol=1e-3)
    assert "axis-aligned" in info["notes"][0]
    assert load_scene_arg(str(folder), 1000).objects[0]["id"] == 0  # what generate loads
    (folder / f"{SID}.aggregation.json").unlink()
    assert main(["scene", "info", str(folder)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "aggregation.json" in err[0] and "Traceback" not in err[0]
    with pytest.raises(GenerateError, match="aggregation"):
        load_scene_arg(str(folder))


def _prox_room(path: Path, floor_z: float):
    """A PROX-like scene mesh: a 4 x 3 m floor slab at z = floor_z and a 0.45 m high seat."""
    floor = trimesh.creation.box(bounds=[[0, 0, floor_z - 0.05], [4, 3, floor_z]])
    seat = trimesh.creation.box(bounds=[[1, 1, floor_z], [1.6, 1.5, floor_z + 0.45]])
    path.parent.mkdir(parents=True, exist_ok=True)
    trimesh.util.concatenate([floor, seat]).export(path)


def test_prox_scene_floor_moved_to_zero_and_unlabelled(tmp_path, capsys):
    path = tmp_path / "PROX" / "scenes" / "MPH16.ply"
    _prox_room(path, -0.841)
    assert find_scan(path).layout == "prox"
    scene, notes = load_scene_and_notes(path, num_points=5000)
    assert scene.objects == () and (scene.instance == -1).all()
    top = scene.xyz[scene.normal[:, 2] > 0.9]
    assert np.abs(top[:, 2]).min() < 1e-6  # the floor's top is at z = 0
    np.testing.assert_allclose(np.sort(np.unique(np.round(top[:, 2], 4))), [0.0, 0.45])
    assert "-0.841" in notes[0] and "no object labels" in notes[1]
    assert main(["scene", "info", str(path), "--points", "2000"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["objects"] == 0 and "object_table" not in info
    assert any("cannot be picked with --object" in n for n in info["notes"])
    # another name in a PROX release's scenes/ (next to cam2world/) is PROX too; elsewhere not
    other = tmp_path / "PROX" / "scenes" / "MyRoom.ply"
    _prox_room(other, -0.5)
    assert find_scan(other) is None
    (tmp_path / "PROX" / "cam2world").mkdir()
    assert find_scan(other).layout == "prox"
    loose = tmp_path / "MPH16.ply"
    _prox_room(loose, -0.5)
    assert find_scan(loose) is None and load_scene(loose, num_points=200).xyz[:, 2].min() < -0.5


def test_floor_height_picks_the_lowest_large_surface():
    rng = np.random.default_rng(0)
    floor = np.c_[rng.uniform(0, 4, (3000, 2)), np.full(3000, -0.7)]
    table = np.c_[rng.uniform(0, 1, (900, 2)), np.full(900, 0.05)]  # smaller, higher
    junk = np.c_[rng.uniform(0, 4, (30, 2)), np.full(30, -1.3)]  # a few stray points below
    xyz = np.concatenate([floor, table, junk])
    up = np.tile([0.0, 0.0, 1.0], (len(xyz), 1))
    assert floor_height(xyz, up) == pytest.approx(-0.7, abs=1e-9)
    assert floor_height(xyz, np.zeros_like(xyz)) == pytest.approx(np.percentile(xyz[:, 2], 2))
