"""Tests for jaxmotion.scene.io: every input file is made here with trimesh / numpy."""

from __future__ import annotations

import os
import tempfile

import numpy as np
import pytest
import trimesh
from hypothesis import given, settings
from hypothesis import strategies as st

from jaxmotion.scene import Scene, SceneError, load_scene, save_scene, scene_to_trimesh_points
from jaxmotion.scene import io as scene_io

LO, HI = np.array([-0.5, 1.0, 0.0]), np.array([0.5, 3.0, 1.5])  # a 1 x 2 x 1.5 m box


def coloured_box():
    """Box [LO, HI] whose vertex colour is the affine map (v - LO) / (HI - LO).

    Barycentric interpolation of an affine field is exact, so every surface point p must
    come back with colour (p - LO) / (HI - LO) whatever the triangulation.
    """
    mesh = trimesh.creation.box(bounds=np.stack([LO, HI]))
    rgb = np.round((mesh.vertices - LO) / (HI - LO) * 255).astype(np.uint8)
    mesh.visual.vertex_colors = np.concatenate([rgb, np.full((8, 1), 255, np.uint8)], 1)
    return mesh


def box_surface_distance(p, lo=LO, hi=HI):
    """Unsigned distance [N] from points to the surface of the box [lo, hi] (analytic)."""
    outside = np.linalg.norm(np.maximum(np.maximum(lo - p, p - hi), 0.0), axis=1)
    inside = np.minimum(p - lo, hi - p).min(axis=1)
    return np.where(outside > 0, outside, np.abs(inside))


def assert_outward_box_normals(xyz, normal, lo=LO, hi=HI):
    np.testing.assert_allclose(np.linalg.norm(normal, axis=1), 1.0, atol=1e-5)
    axis = np.argmax(np.abs(normal), axis=1)
    assert np.allclose(np.abs(normal).max(axis=1), 1.0, atol=1e-5)  # axis-aligned
    rows = np.arange(len(xyz))
    face = np.where(normal[rows, axis] > 0, hi[axis], lo[axis])  # the side it points out of
    np.testing.assert_allclose(xyz[rows, axis], face, atol=1e-5)


def write_ply(path, vertex_fields, vertex_data, faces=None, binary=True):
    """Write a PLY by hand: vertex_fields [(name, numpy dtype)], vertex_data structured array."""
    names = {"f4": "float", "u1": "uchar", "u2": "ushort", "i4": "int"}
    head = ["ply", f"format {'binary_little_endian' if binary else 'ascii'} 1.0",
            f"element vertex {len(vertex_data)}"]
    head += [f"property {names[t]} {n}" for n, t in vertex_fields]
    if faces is not None:
        head += [f"element face {len(faces)}", "property list uchar int vertex_indices"]
    with open(path, "wb") as f:
        f.write(("\n".join([*head, "end_header"]) + "\n").encode())
        if binary:
            f.write(vertex_data.astype([(n, "<" + t) for n, t in vertex_fields]).tobytes())
        else:
            for row in vertex_data:
                f.write((" ".join(str(row[n]) for n, _ in vertex_fields) + "\n").encode())
            for tri in faces if faces is not None else ():
                f.write(("3 " + " ".join(str(int(i)) for i in tri) + "\n").encode())
    return path


def labelled_cloud(n=300, seed=1):
    rng = np.random.default_rng(seed)
    fields = [("x", "f4"), ("y", "f4"), ("z", "f4"), ("nx", "f4"), ("ny", "f4"), ("nz", "f4"),
              ("red", "u1"), ("green", "u1"), ("blue", "u1"), ("label", "u2"), ("objectId", "i4")]
    data = np.zeros(n, dtype=[(k, t) for k, t in fields])
    xyz = rng.uniform(-2, 2, (n, 3)).astype(np.float32)
    nrm = rng.normal(size=(n, 3))
    nrm = (nrm / np.linalg.norm(nrm, axis=1, keepdims=True)).astype(np.float32)
    for i, c in enumerate("xyz"):
        data[c], data["n" + c] = xyz[:, i], nrm[:, i]
    for c in ("red", "green", "blue"):
        data[c] = rng.integers(0, 256, n)
    data["label"], data["objectId"] = rng.integers(0, 41, n), rng.integers(-1, 20, n)
    return fields, data


# ------------------------------------------------------------------------ meshes
@pytest.mark.parametrize("ext", ["ply", "obj", "glb", "off", "stl"])
def test_mesh_samples_lie_on_surface_with_outward_normals_and_colours(tmp_path, ext):
    path = tmp_path / f"box.{ext}"
    coloured_box().export(path)
    scene = load_scene(path, num_points=3000, seed=3, up="z")
    assert scene.num_points == 3000 and scene.name == "box"
    assert scene.xyz.dtype == np.float32 and scene.semantic.dtype == np.int32
    assert box_surface_distance(scene.xyz.astype(np.float64)).max() < 1e-5
    assert_outward_box_normals(scene.xyz, scene.normal)
    if ext in ("ply", "obj", "glb"):
        np.testing.assert_allclose(scene.rgb, (scene.xyz - LO) / (HI - LO), atol=0.6 / 255 + 1e-5)
    else:  # STL has no colours; trimesh's OFF reader drops them
        np.testing.assert_array_equal(scene.rgb, 0.5)
    assert (scene.semantic == -1).all() and (scene.instance == -1).all()


def test_default_mesh_point_count(tmp_path):
    trimesh.creation.box().export(tmp_path / "b.stl")
    assert load_scene(tmp_path / "b.stl").num_points == scene_io.DEFAULT_MESH_POINTS


def test_area_weighting(tmp_path):
    # Unit square at z = 0 (area 1) and a 1 x 3 rectangle at z = 1 (area 3), two triangles each.
    v = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0],
                  [0, 0, 1], [1, 0, 1], [1, 3, 1], [0, 3, 1]], float)
    f = np.array([[0, 1, 2], [0, 2, 3], [4, 5, 6], [4, 6, 7]])
    trimesh.Trimesh(v, f, process=False).export(tmp_path / "two.ply")
    scene = load_scene(tmp_path / "two.ply", num_points=20_000, seed=0)
    small = np.mean(scene.xyz[:, 2] < 0.5)
    assert abs(small - 0.25) < 0.02  # binomial sd 0.003; per-face (unweighted) sampling gives 0.5


def test_face_colours(tmp_path):
    mesh = trimesh.creation.box(bounds=np.stack([LO, HI]))
    colours = np.zeros((12, 4), np.uint8)
    colours[:, 3] = 255
    axis = np.argmax(np.abs(mesh.face_normals), axis=1)
    colours[np.arange(12), axis] = 200  # red on x sides, green on y, blue on z
    mesh.visual.face_colors = colours
    mesh.export(tmp_path / "faces.ply")
    scene = load_scene(tmp_path / "faces.ply", num_points=2000)
    expected = np.eye(3)[np.argmax(np.abs(scene.normal), axis=1)] * 200 / 255
    np.testing.assert_allclose(scene.rgb, expected, atol=1e-6)


def test_glb_material_colour(tmp_path):
    mesh = trimesh.creation.box()
    material = trimesh.visual.material.PBRMaterial(baseColorFactor=[255, 51, 0, 255])
    mesh.visual = trimesh.visual.TextureVisuals(material=material)
    mesh.export(tmp_path / "red.glb")
    scene = load_scene(tmp_path / "red.glb", num_points=100)
    np.testing.assert_allclose(scene.rgb, np.broadcast_to([1.0, 0.2, 0.0], (100, 3)), atol=1e-6)


def test_glb_is_converted_from_y_up(tmp_path):
    # In the file the box is y-up: 3 m tall along +y, from y = 0.
    mesh = trimesh.creation.box(bounds=[[-0.5, 0.0, -1.0], [0.5, 3.0, 1.0]])
    mesh.export(tmp_path / "tall.glb")
    raw = load_scene(tmp_path / "tall.glb", num_points=500, up="z")
    auto = load_scene(tmp_path / "tall.glb", num_points=500)
    x, y, z = raw.xyz.T
    np.testing.assert_array_equal(auto.xyz, np.stack([x, -z, y], 1))
    lo, hi = auto.bounds()
    np.testing.assert_allclose(lo, [-0.5, -1.0, 0.0], atol=1e-6)
    np.testing.assert_allclose(hi, [0.5, 1.0, 3.0], atol=1e-6)  # now tall along +z
    assert_outward_box_normals(auto.xyz, auto.normal, np.array(lo, float), np.array(hi, float))
    forced = load_scene(tmp_path / "tall.glb", num_points=500, up="y")
    np.testing.assert_array_equal(forced.xyz, auto.xyz)


def test_mesh_vertex_labels_follow_nearest_corner(tmp_path):
    box = trimesh.creation.box(bounds=[[0, 0, 0], [1, 1, 1]])
    fields = [("x", "f4"), ("y", "f4"), ("z", "f4"), ("label", "u2"), ("instance_id", "i4")]
    data = np.zeros(8, dtype=[(n, t) for n, t in fields])
    for i, c in enumerate("xyz"):
        data[c] = box.vertices[:, i]
    data["label"], data["instance_id"] = np.arange(8) + 10, np.arange(8) * 3
    path = write_ply(tmp_path / "labelled.ply", fields, data, faces=box.faces, binary=False)
    scene = load_scene(path, num_points=4000, seed=5)
    corner = scene.semantic - 10
    assert set(np.unique(corner)) <= set(range(8)) and (scene.instance == corner * 3).all()
    # The labelled corner lies on the same box side as the point ...
    same_side = np.isclose(box.vertices[corner], scene.xyz, atol=1e-5).any(axis=1)
    assert same_side.all()
    # ... and points right next to a corner carry that corner's label.
    d = np.linalg.norm(scene.xyz[:, None] - box.vertices[None], axis=2)
    near = d.min(axis=1) < 0.2
    assert near.sum() > 20
    np.testing.assert_array_equal(corner[near], np.argmin(d, axis=1)[near])


# ------------------------------------------------------------------- point clouds
@pytest.mark.parametrize("binary", [True, False])
def test_point_cloud_ply_keeps_all_properties(tmp_path, binary):
    fields, data = labelled_cloud()
    path = write_ply(tmp_path / "cloud.ply", fields, data, binary=binary)
    scene = load_scene(path)
    assert scene.num_points == len(data)
    np.testing.assert_array_equal(scene.xyz, np.stack([data[c] for c in "xyz"], 1))
    np.testing.assert_allclose(scene.normal, np.stack([data["n" + c] for c in "xyz"], 1), atol=1e-6)
    rgb = np.stack([data[c] for c in ("red", "green", "blue")], 1) / 255
    np.testing.assert_allclose(scene.rgb, rgb, atol=1e-7)
    # NYU40's label 0 is "unannotated": unknown (-1); object ids are kept as they are
    label = data["label"].astype(int)
    np.testing.assert_array_equal(scene.semantic, np.where(label == 0, -1, label))
    np.testing.assert_array_equal(scene.instance, data["objectId"])


def test_point_cloud_without_normals_or_colours(tmp_path):
    xyz = np.random.default_rng(0).normal(size=(50, 3))
    trimesh.PointCloud(xyz).export(tmp_path / "bare.ply")
    scene = load_scene(tmp_path / "bare.ply")
    np.testing.assert_allclose(scene.xyz, xyz, atol=1e-6)
    assert (scene.normal == 0).all() and (scene.rgb == 0.5).all() and (scene.semantic == -1).all()


def test_point_cloud_subset_is_seeded_rows_of_the_file(tmp_path):
    fields, data = labelled_cloud(n=400)
    path = write_ply(tmp_path / "cloud.ply", fields, data)
    full = load_scene(path)
    a, b = load_scene(path, num_points=100, seed=7), load_scene(path, num_points=100, seed=7)
    c = load_scene(path, num_points=100, seed=8)
    assert a.num_points == 100
    np.testing.assert_array_equal(a.xyz, b.xyz)
    assert not np.array_equal(a.xyz, c.xyz)
    rows = [np.flatnonzero((full.xyz == p).all(axis=1))[0] for p in a.xyz]
    assert len(set(rows)) == 100 and rows == sorted(rows)
    np.testing.assert_array_equal(a.semantic, full.semantic[rows])
    assert load_scene(path, num_points=10_000).num_points == 400  # never upsampled


def test_mesh_sampling_is_deterministic_per_seed(tmp_path):
    coloured_box().export(tmp_path / "box.ply")
    a, b = (load_scene(tmp_path / "box.ply", num_points=500, seed=11) for _ in range(2))
    c = load_scene(tmp_path / "box.ply", num_points=500, seed=12)
    for key in ("xyz", "rgb", "normal"):
        np.testing.assert_array_equal(getattr(a, key), getattr(b, key))
    assert not np.array_equal(a.xyz, c.xyz)


# ---------------------------------------------------------------------------- npz
def random_scene(rng, n, name="room"):
    normal = rng.normal(size=(n, 3))
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    normal[: n // 3] = 0.0
    objects = ({"id": 3, "category": "chair", "bbox_min": [0, 0, 0], "bbox_max": [0.5, 0.5, 0.9],
                "surface_height": 0.45, "front": [1.0, 0.0, 0.0]},
               {"id": 7, "category": "table", "bbox_min": [1, 1, 0], "bbox_max": [2.0, 1.7, 0.75]})
    return Scene(xyz=rng.normal(size=(n, 3)), rgb=rng.uniform(size=(n, 3)), normal=normal,
                 semantic=rng.integers(-1, 40, n), instance=rng.integers(-1, 10, n),
                 objects=objects, name=name)


@settings(max_examples=25, deadline=None)
@given(n=st.integers(0, 60), seed=st.integers(0, 2**31 - 1), name=st.text(max_size=12))
def test_npz_round_trip_is_exact(n, seed, name):
    scene = random_scene(np.random.default_rng(seed), n, name)
    with tempfile.TemporaryDirectory() as folder:
        path = save_scene(scene, os.path.join(folder, "s.npz"))
        back = load_scene(path)
        assert os.listdir(folder) == ["s.npz"]
    for key in ("xyz", "rgb", "normal", "semantic", "instance"):
        assert getattr(back, key).dtype == getattr(scene, key).dtype
        np.testing.assert_array_equal(getattr(back, key), getattr(scene, key))
    assert back.objects == scene.objects and back.name == name


def test_atomic_save_leaves_old_file_and_no_temp(tmp_path, monkeypatch):
    rng = np.random.default_rng(0)
    path = tmp_path / "scene.npz"
    old = random_scene(rng, 20)
    save_scene(old, path)
    before = path.read_bytes()

    def interrupted(file, **arrays):
        file.write(b"PK\x03\x04 half a zip")
        raise KeyboardInterrupt

    monkeypatch.setattr(scene_io.np, "savez", interrupted)
    with pytest.raises(KeyboardInterrupt):
        save_scene(random_scene(rng, 30), path)
    monkeypatch.undo()
    assert path.read_bytes() == before and os.listdir(tmp_path) == ["scene.npz"]
    np.testing.assert_array_equal(load_scene(path).xyz, old.xyz)


def test_npz_missing_keys_are_listed(tmp_path):
    np.savez(tmp_path / "partial.npz", xyz=np.zeros((3, 3), np.float32), name=np.array("x"))
    with pytest.raises(SceneError, match="partial.npz") as info:
        load_scene(tmp_path / "partial.npz")
    for key in ("rgb", "normal", "semantic", "instance", "objects"):
        assert key in str(info.value)


# ------------------------------------------------------------------------- errors
def _make_error_file(tmp_path, kind):
    files = {
        "missing": ("nothere.ply", None),
        "extension": ("room.xyz", b"1 2 3\n"),
        "unparsable": ("broken.ply", b"this is not a ply file\n"),
        "unparsable_glb": ("broken.glb", b"glTF garbage"),
        "empty": ("empty.ply", b"ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\n"
                               b"property float y\nproperty float z\nend_header\n"),
        "nonfinite": ("nan.off", b"OFF\n3 1 0\n0 0 0\nnan 1 0\n0 1 1\n3 0 1 2\n"),
        "zero_area": ("flat.off", b"OFF\n3 1 0\n0 0 0\n1 1 1\n2 2 2\n3 0 1 2\n"),
        "bad_npz": ("bad.npz", b"not a zip"),
    }
    name, content = files[kind]
    if content is not None:
        (tmp_path / name).write_bytes(content)
    return tmp_path / name


@pytest.mark.parametrize("kind", ["missing", "extension", "unparsable", "unparsable_glb",
                                  "empty", "nonfinite", "zero_area", "bad_npz"])
def test_errors_name_the_file(tmp_path, kind):
    path = _make_error_file(tmp_path, kind)
    with pytest.raises(SceneError) as info:
        load_scene(path)
    assert path.name in str(info.value)
    assert isinstance(info.value, ValueError)
    if kind == "extension":
        assert all(e in str(info.value) for e in (".ply", ".obj", ".glb", ".npz"))


def test_bad_arguments(tmp_path):
    trimesh.creation.box().export(tmp_path / "b.stl")
    with pytest.raises(SceneError, match="num_points"):
        load_scene(tmp_path / "b.stl", num_points=0)
    with pytest.raises(ValueError, match="up"):
        load_scene(tmp_path / "b.stl", up="x")
    with pytest.raises(SceneError, match=".npz"):
        save_scene(Scene(np.zeros((1, 3))), tmp_path / "s.ply")


# -------------------------------------------------------------------------- Scene
@pytest.mark.parametrize("kwargs, message", [
    (dict(xyz=np.zeros((4, 2))), "xyz must be"),
    (dict(xyz=np.full((2, 3), np.nan)), "NaN"),
    (dict(xyz=np.zeros((2, 3)), rgb=np.full((2, 3), 1.5)), r"\[0, 1\]"),
    (dict(xyz=np.zeros((2, 3)), normal=np.full((2, 3), 0.5)), "unit"),
    (dict(xyz=np.zeros((2, 3)), semantic=np.zeros(2, np.float32)), "integer"),
    (dict(xyz=np.zeros((2, 3)), instance=np.zeros(3, np.int32)), "instance"),
    (dict(xyz=np.zeros((2, 3)), objects=[{"id": 1, "category": "bed"}]), "bbox_min"),
    (dict(xyz=np.zeros((2, 3)), objects=[{"id": 1, "category": "bed", "bbox_min": [1, 0, 0],
                                          "bbox_max": [0, 1, 1]}]), "above"),
    (dict(xyz=np.zeros((2, 3)), objects=[{"id": 1, "category": "a", "bbox_min": [0, 0, 0],
                                          "bbox_max": [1, 1, 1]}] * 2), "duplicate"),
])
def test_scene_validation(kwargs, message):
    with pytest.raises(ValueError, match=message):
        Scene(**kwargs)


def test_scene_helpers():
    scene = random_scene(np.random.default_rng(1), 40)
    assert scene.object(7)["category"] == "table"
    with pytest.raises(KeyError, match=r"\[3, 7\]"):
        scene.object(5)
    with pytest.raises(ValueError):
        scene.xyz[0, 0] = 1.0  # arrays are read-only
    mask = scene.xyz[:, 0] > 0
    part = scene.subset(mask)
    np.testing.assert_array_equal(part.semantic, scene.semantic[mask])
    np.testing.assert_array_equal(scene.subset([2, 0]).xyz, scene.xyz[[2, 0]])
    moved = scene.translated([1.0, 2.0, 3.0])
    np.testing.assert_allclose(moved.xyz, scene.xyz + [1, 2, 3], atol=1e-6)
    assert moved.object(3)["surface_height"] == pytest.approx(3.45)
    assert moved.object(3)["bbox_max"] == pytest.approx([1.5, 2.5, 3.9])
    lo, hi = scene.bounds()
    np.testing.assert_array_equal(lo, scene.xyz.min(0))


@settings(max_examples=30, deadline=None)
@given(quat=st.lists(st.floats(-1, 1), min_size=4, max_size=4).filter(
    lambda q: np.linalg.norm(q) > 0.1), t=st.lists(st.floats(-5, 5), min_size=3, max_size=3))
def test_transformed_keeps_points_in_boxes(quat, t):
    r = trimesh.transformations.quaternion_matrix(np.array(quat) / np.linalg.norm(quat))[:3, :3]
    rng = np.random.default_rng(0)
    inside = rng.uniform([0, 0, 0], [0.5, 0.5, 0.9], (50, 3))
    scene = Scene(inside, normal=np.tile([0.0, 0.0, 1.0], (50, 1)),
                  objects=random_scene(rng, 1).objects)
    moved = scene.transformed(r, t)
    box = moved.object(3)
    assert (moved.xyz >= np.array(box["bbox_min"]) - 1e-5).all()
    assert (moved.xyz <= np.array(box["bbox_max"]) + 1e-5).all()
    np.testing.assert_allclose(moved.normal, np.tile(r[:, 2], (50, 1)), atol=1e-5)
    np.testing.assert_allclose(box["front"], r[:, 0], atol=1e-9)
    back = moved.transformed(r.T, -r.T @ np.array(t))
    np.testing.assert_allclose(back.xyz, scene.xyz, atol=1e-4)
    with pytest.raises(ValueError, match="rotation"):
        scene.transformed(-np.eye(3))


def test_scene_to_trimesh_points_exports(tmp_path):
    scene = random_scene(np.random.default_rng(2), 64)
    cloud = scene_to_trimesh_points(scene)
    assert isinstance(cloud, trimesh.PointCloud) and cloud.colors.dtype == np.uint8
    cloud.export(tmp_path / "out.ply")
    back = load_scene(tmp_path / "out.ply")
    np.testing.assert_allclose(back.xyz, scene.xyz, atol=1e-6)
    np.testing.assert_allclose(back.rgb, scene.rgb, atol=0.51 / 255)


def test_loading_an_npz_scene_does_not_import_trimesh(tmp_path):
    """trimesh costs ~0.2 s of every `jaxmotion generate` start; .npz scenes do not need it."""
    import subprocess
    import sys

    rng = np.random.default_rng(0)
    save_scene(Scene(xyz=rng.uniform(size=(50, 3)), rgb=rng.uniform(size=(50, 3))),
               tmp_path / "s.npz")
    code = ("import sys, jaxmotion.generation, jaxmotion.scene as s; "
            f"s.load_scene({str(tmp_path / 's.npz')!r}); print('trimesh' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"
