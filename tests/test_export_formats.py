"""Export writers: BVH, GLB, GIF/MP4 and the HTML viewer, each checked by reading the file back."""

import base64
import importlib.util
import json
import re
import shutil
import struct
import subprocess
from html.parser import HTMLParser
from pathlib import Path

import jax
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from jaxmotion.body import body_forward, load_mannequin
from jaxmotion.export import (
    read_bvh,
    render_motion_video,
    write_bvh,
    write_glb,
    write_viewer_html,
)
from jaxmotion.geometry import PARENTS, SMPLX_JOINT_NAMES, smplx_joints

Y_UP = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])  # Rx(-90°)
_forward = jax.jit(body_forward, static_argnames="normals")
_joints = jax.jit(smplx_joints)


def _params(seed, t, k=None, scale=0.5):
    rng = np.random.default_rng(seed)
    lead = (t,) if k is None else (k, t)
    return (
        rng.normal(size=(*lead, 3)),
        rng.normal(size=(*lead, 21, 3)) * scale,
        rng.normal(size=(*lead, 3)),
    )


def _scene(seed, n):
    rng = np.random.default_rng(seed)
    return rng.uniform([-2, -2, 0], [2, 2, 2.5], size=(n, 3)), rng.uniform(size=(n, 3))


def _no_temp_files(folder: Path):
    assert not [p.name for p in folder.iterdir() if p.name.endswith(".tmp")]


# --------------------------------------------------------------------------- BVH


def _bvh_world_joints(bvh) -> np.ndarray:
    """Forward kinematics of a parsed BVH: ``[T, J, 3]`` in the file's frame and units."""
    t, num = len(bvh.frames), len(bvh.names)
    pos, rot = np.zeros((t, num, 3)), np.zeros((t, num, 3, 3))
    col = 0
    for j in range(num):
        ch = bvh.channels[j]
        values = bvh.frames[:, col : col + len(ch)]
        col += len(ch)
        local_pos = np.broadcast_to(bvh.offsets[j], (t, 3)).copy()
        order, angles = "", []
        for name, v in zip(ch, values.T):
            if name.endswith("position"):
                local_pos[:, "XYZ".index(name[0])] += v
            else:
                order += name[0]
                angles.append(v)
        local_rot = Rotation.from_euler(order, np.stack(angles, 1), degrees=True).as_matrix()
        p = bvh.parents[j]
        if p < 0:
            pos[:, j], rot[:, j] = local_pos, local_rot
        else:
            pos[:, j] = pos[:, p] + np.einsum("tab,tb->ta", rot[:, p], local_pos)
            rot[:, j] = rot[:, p] @ local_rot
    return pos


@pytest.mark.parametrize("with_betas", [False, True])
def test_bvh_round_trip_reproduces_smplx_joints(tmp_path, with_betas):
    go, bp, tr = _params(0, 7, scale=0.8)
    betas = np.random.default_rng(1).normal(size=10) if with_betas else None
    path = write_bvh(tmp_path / "m.bvh", go, bp, tr, betas, 30.0)
    bvh = read_bvh(path)
    names = SMPLX_JOINT_NAMES[:22]  # the SMPL-X add-on's bone names, as in motion.glb
    assert sorted(bvh.names) == sorted(names)
    order = [bvh.names.index(n) for n in names]
    assert [bvh.names[p] if p >= 0 else None for p in bvh.parents[order]] == [
        names[p] if p >= 0 else None for p in PARENTS
    ]
    assert bvh.frames.shape == (7, 6 + 21 * 3)
    assert bvh.frame_time == pytest.approx(1 / 30)
    world = _bvh_world_joints(bvh)[:, order] @ Y_UP  # y-up -> z-up (Y_UP is orthogonal)
    expected = np.asarray(_joints(go, bp, tr, betas), np.float64)
    np.testing.assert_allclose(world, expected, atol=1e-4)


def test_bvh_scale_and_y_up(tmp_path):
    go, bp, tr = _params(2, 3)
    m = read_bvh(write_bvh(tmp_path / "m.bvh", go, bp, tr, None, 20))
    cm = read_bvh(write_bvh(tmp_path / "cm.bvh", go, bp, tr, None, 20, scale=100))
    np.testing.assert_allclose(cm.offsets, 100 * m.offsets, atol=1e-4)
    np.testing.assert_allclose(_bvh_world_joints(cm), 100 * _bvh_world_joints(m), atol=1e-2)
    # the neutral rest pose stands along +y in the file: head above the pelvis
    head = m.offsets[m.names.index("head")]
    assert head[1] > 0


def test_bvh_rejects_bad_input(tmp_path):
    go, bp, tr = _params(3, 4)
    path = tmp_path / "m.bvh"
    path.write_text("old")
    with pytest.raises(ValueError, match="body_pose"):
        write_bvh(path, go, bp[:, :20], tr, None, 30)
    with pytest.raises(ValueError, match="fps"):
        write_bvh(path, go, bp, tr, None, 0)
    with pytest.raises(ValueError, match="non-finite"):
        write_bvh(path, go, bp, np.full_like(tr, np.nan), None, 30)
    with pytest.raises(ValueError, match="one motion"):
        write_bvh(path, np.stack([go, go]), np.stack([bp, bp]), np.stack([tr, tr]), None, 30)
    assert path.read_text() == "old"
    _no_temp_files(tmp_path)
    (tmp_path / "bad.bvh").write_text("HIERARCHY\nROOT a\n{\n OFFSET 0 0\n")
    with pytest.raises(ValueError, match="not a BVH"):
        read_bvh(tmp_path / "bad.bvh")


# --------------------------------------------------------------------------- GLB


def _read_glb(path):
    raw = Path(path).read_bytes()
    magic, version, length = struct.unpack_from("<III", raw)
    assert (magic, version, length) == (0x46546C67, 2, len(raw))
    json_len, json_type = struct.unpack_from("<II", raw, 12)
    bin_len, bin_type = struct.unpack_from("<II", raw, 20 + json_len)
    assert (json_type, bin_type) == (0x4E4F534A, 0x004E4942) and json_len % 4 == 0
    gltf = json.loads(raw[20 : 20 + json_len])
    binary = raw[28 + json_len : 28 + json_len + bin_len]
    assert gltf["buffers"][0]["byteLength"] == bin_len
    return gltf, binary


def _accessor(gltf, binary, index):
    acc = gltf["accessors"][index]
    view = gltf["bufferViews"][acc["bufferView"]]
    assert view["byteOffset"] % 4 == 0
    dtype = {5126: "<f4", 5125: "<u4", 5123: "<u2", 5121: "u1"}[acc["componentType"]]
    width = {"SCALAR": 1, "VEC3": 3, "VEC4": 4, "MAT4": 16}[acc["type"]]
    a = np.frombuffer(binary, dtype, acc["count"] * width, view["byteOffset"])
    return (a.reshape(acc["count"], width) if width > 1 else a).astype(np.float64)


def _world_matrices(gltf, binary, frame):
    """Every node's world matrix with the animation sampled at keyframe ``frame``."""
    nodes = [dict(n) for n in gltf["nodes"]]
    for anim in gltf["animations"]:
        for ch in anim["channels"]:
            sampler = anim["samplers"][ch["sampler"]]
            nodes[ch["target"]["node"]][ch["target"]["path"]] = _accessor(
                gltf, binary, sampler["output"]
            )[frame]
    parent = {c: i for i, n in enumerate(nodes) for c in n.get("children", [])}
    world = {}

    def matrix(i):
        if i not in world:
            n = nodes[i]
            m = np.eye(4)
            m[:3, :3] = Rotation.from_quat(n.get("rotation", [0, 0, 0, 1])).as_matrix()
            m[:3, :3] *= np.asarray(n.get("scale", [1, 1, 1]))
            m[:3, 3] = n.get("translation", [0, 0, 0])
            world[i] = m if i not in parent else matrix(parent[i]) @ m
        return world[i]

    return [matrix(i) for i in range(len(nodes))], parent


def _skinned_vertices(gltf, binary, frame):
    """glTF skinning of every skinned mesh node: ``{node: [V, 3]}`` in glTF's world."""
    world, parent = _world_matrices(gltf, binary, frame)
    out = {}
    for i, node in enumerate(gltf["nodes"]):
        if "skin" not in node:
            continue
        assert i not in parent and not {"translation", "rotation", "matrix"} & set(node)
        skin = gltf["skins"][node["skin"]]
        prim = gltf["meshes"][node["mesh"]]["primitives"][0]
        ibm = _accessor(gltf, binary, skin["inverseBindMatrices"]).reshape(-1, 4, 4)
        joint_mats = np.stack([world[j] for j in skin["joints"]]) @ ibm.transpose(0, 2, 1)
        v = _accessor(gltf, binary, prim["attributes"]["POSITION"])
        idx = _accessor(gltf, binary, prim["attributes"]["JOINTS_0"]).astype(int)
        w = _accessor(gltf, binary, prim["attributes"]["WEIGHTS_0"])
        np.testing.assert_allclose(w.sum(1), 1.0, atol=1e-6)
        blended = np.einsum("vk,vkab->vab", w, joint_mats[idx])
        out[i] = np.einsum("vab,vb->va", blended[:, :3, :3], v) + blended[:, :3, 3]
    return out


def test_glb_skin_and_animation_match_body_forward(tmp_path):
    import trimesh

    k, t, fps, spacing = 2, 4, 20.0, 1.5
    go, bp, tr = _params(4, t, k=k, scale=0.4)
    betas = np.random.default_rng(5).normal(size=10) * 0.5
    xyz, rgb = _scene(6, 300)
    path = write_glb(
        tmp_path / "m.glb",
        global_orient=go,
        body_pose=bp,
        transl=tr,
        fps=fps,
        betas=betas,
        scene_xyz=xyz,
        scene_rgb=rgb,
        spacing=spacing,
    )
    loaded = trimesh.load(path)
    assert {"body0", "body1", "scene"} <= set(loaded.geometry)
    assert len(loaded.geometry["scene"].vertices) == 300

    gltf, binary = _read_glb(path)
    assert gltf["asset"]["version"] == "2.0"
    assert len(gltf["skins"]) == k and len(gltf["skins"][0]["joints"]) == 52
    (anim,) = gltf["animations"]
    assert len(anim["channels"]) == k * 23
    assert {s["interpolation"] for s in anim["samplers"]} == {"LINEAR"}
    times = _accessor(gltf, binary, anim["samplers"][0]["input"])
    np.testing.assert_allclose(times, np.arange(t) / fps, atol=1e-6)
    scene_node = next(n for n in gltf["nodes"] if n.get("name") == "scene")
    scene_prim = gltf["meshes"][scene_node["mesh"]]["primitives"][0]
    assert scene_prim["mode"] == 0
    colours = _accessor(gltf, binary, scene_prim["attributes"]["COLOR_0"])[:, :3] / 255
    np.testing.assert_allclose(colours, rgb, atol=0.5 / 255 + 1e-9)

    model = load_mannequin(betas)
    expected = np.asarray(_forward(model, go, bp, tr, betas, normals=False).vertices, np.float64)
    body_nodes = [i for i, n in enumerate(gltf["nodes"]) if "skin" in n]
    for frame in (0, 2, 3):
        skinned = _skinned_vertices(gltf, binary, frame)
        for s, node in enumerate(body_nodes):
            want = (expected[s, frame] + [s * spacing, 0, 0]) @ Y_UP.T
            err = np.abs(skinned[node] - want).max()
            assert err < 1e-3, (frame, s, err)


def test_glb_single_motion_with_scene_mesh(tmp_path):
    import trimesh

    go, bp, tr = _params(7, 3)
    xyz = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1.0]])
    faces = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
    path = write_glb(
        tmp_path / "m.glb",
        global_orient=go,
        body_pose=bp,
        transl=tr,
        fps=30,
        scene_xyz=xyz,
        scene_faces=faces,
    )
    scene = trimesh.load(path).geometry["scene"]
    assert isinstance(scene, trimesh.Trimesh) and len(scene.faces) == 4
    gltf, binary = _read_glb(path)
    assert len(gltf["skins"]) == 1
    expected = np.asarray(_forward(load_mannequin(), go, bp, tr, normals=False).vertices)
    (skinned,) = _skinned_vertices(gltf, binary, 2).values()
    assert np.abs(skinned - expected[2] @ Y_UP.T).max() < 1e-3
    with pytest.raises(ValueError, match="scene_faces"):
        write_glb(
            tmp_path / "m.glb",
            global_orient=go,
            body_pose=bp,
            transl=tr,
            fps=30,
            scene_xyz=xyz,
            scene_faces=faces + 4,
        )
    with pytest.raises(ValueError, match="transl"):
        write_glb(tmp_path / "m.glb", global_orient=go, body_pose=bp, transl=tr[:2], fps=30)
    with pytest.raises(ValueError, match="scene_rgb"):
        write_glb(
            tmp_path / "m.glb",
            global_orient=go,
            body_pose=bp,
            transl=tr,
            fps=30,
            scene_xyz=xyz,
            scene_rgb=np.full((4, 3), 255.0),
        )
    assert len(trimesh.load(path).geometry) == 2  # the earlier file is intact
    _no_temp_files(tmp_path)


# --------------------------------------------------------------------------- video


def _motion_joints(seed, k, t):
    rng = np.random.default_rng(seed)
    return rng.normal(size=(k, t, 22, 3)) * 0.3 + [0.0, 0.0, 1.0]


def test_gif_frames_size_and_subsampling(tmp_path):
    import imageio.v3 as iio

    xyz, rgb = _scene(8, 500)
    joints = _motion_joints(9, 2, 7)
    # a tetrahedron per sample and frame stands in for the body mesh
    verts = joints[:, :, :4] + [0.1, 0.0, 0.0]
    faces = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
    path = render_motion_video(
        tmp_path / "m.gif",
        xyz,
        rgb,
        joints,
        30,
        vertices=verts,
        faces=faces,
        affordance=np.linspace(0, 1, 500),
        text="walk",
        size=(96, 64),
        max_frames=3,
    )
    frames = iio.imread(path)
    assert frames.shape == (3, 64, 96, 3)  # 7 frames at stride 3: 0, 3, 6
    assert frames.std() > 0
    meta = iio.immeta(path)
    assert meta["duration"] == pytest.approx(100, abs=10)  # 3 frames of 1/10 s


@pytest.mark.skipif(
    importlib.util.find_spec("imageio_ffmpeg") is None, reason="imageio-ffmpeg not installed"
)
def test_mp4_frames_and_size(tmp_path):
    import imageio.v3 as iio

    xyz, rgb = _scene(10, 300)
    path = render_motion_video(
        tmp_path / "m.mp4", xyz, rgb, _motion_joints(11, 1, 5)[0], 20, size=(64, 48)
    )
    frames = iio.imread(path, plugin="FFMPEG")
    assert frames.shape == (5, 48, 64, 3)


def test_video_rejects_bad_requests(tmp_path, monkeypatch):
    xyz, rgb = _scene(12, 50)
    joints = _motion_joints(13, 1, 2)
    with pytest.raises(ValueError, match=".gif or .mp4"):
        render_motion_video(tmp_path / "m.avi", xyz, rgb, joints, 30)
    with pytest.raises(ValueError, match="joints"):
        render_motion_video(tmp_path / "m.gif", xyz, rgb, joints[..., :2], 30)
    with pytest.raises(ValueError, match="affordance"):
        render_motion_video(tmp_path / "m.gif", xyz, rgb, joints, 30, affordance=np.full(50, 2.0))
    with pytest.raises(ValueError, match="even"):
        render_motion_video(tmp_path / "m.mp4", xyz, rgb, joints, 30, size=(65, 48))
    find_spec = importlib.util.find_spec
    monkeypatch.setattr(
        importlib.util,
        "find_spec",
        lambda name, *a: None if name == "imageio_ffmpeg" else find_spec(name, *a),
    )
    with pytest.raises(ValueError, match="pip install"):
        render_motion_video(tmp_path / "m.mp4", xyz, rgb, joints, 30)
    assert not list(tmp_path.iterdir())


@pytest.mark.parametrize("size", [(96, 64), (50, 80)])
def test_video_camera_is_mplot3ds(size):
    """The numpy camera puts points on the pixels where matplotlib's mplot3d drew them."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    from mpl_toolkits.mplot3d import proj3d

    from jaxmotion.export.video import SUPERSAMPLE, Camera

    width, height = size
    joints = _motion_joints(14, 2, 4) + [1.0, -2.0, 0.0]
    cam = Camera(joints, width, height)
    fig = Figure(figsize=(width / 100, height / 100), dpi=100)
    FigureCanvasAgg(fig)
    side = max(width, height)
    ax = fig.add_axes(
        ((1 - side / width) / 2, (1 - side / height) / 2, side / width, side / height),
        projection="3d",
    )
    lo, hi = cam.centre - cam.half, cam.centre + cam.half
    ax.set_xlim(lo[0], hi[0])
    ax.set_ylim(lo[1], hi[1])
    ax.set_zlim(lo[2], hi[2])
    ax.set_box_aspect((1, 1, 1))
    ax.view_init(elev=30, azim=-60)
    fig.canvas.draw()
    pts = np.concatenate([joints.reshape(-1, 3), _scene(15, 20)[0] + cam.centre])
    x, y, _ = proj3d.proj_transform(*pts.T, ax.get_proj())
    px = ax.transData.transform(np.stack([x, y], axis=1))
    np.testing.assert_allclose(
        cam.project(pts)[0] / SUPERSAMPLE, np.stack([px[:, 0], height - px[:, 1]], 1), atol=1e-6
    )


def _gif_frames(path) -> np.ndarray:
    import imageio.v3 as iio

    return iio.imread(path)[..., :3]


def test_gif_still_scene_palette_and_timing(tmp_path):
    from PIL import Image

    xyz, rgb = _scene(16, 3000)
    joints = _motion_joints(17, 1, 45) * 0.3 + [0.0, 0.0, 0.7]
    path = render_motion_video(tmp_path / "m.gif", xyz, rgb, joints, 30, size=(120, 90))
    with Image.open(path) as im:
        durations = []
        for i in range(im.n_frames):
            im.seek(i)
            durations.append(im.info["duration"])
    assert len(durations) == 23  # 45 frames at stride 2 (max_frames=40)
    assert sum(durations) == pytest.approx(1000 * 23 / 15, abs=10)  # the clip's duration
    assert set(durations) <= {60, 70}  # 1/15 s in whole hundredths, rounded as it runs
    frames = _gif_frames(path)
    assert (frames[0] == 255).all(-1).mean() > 0.2  # the white background stays white
    changed = (frames != frames[:1]).any(-1).any(0)
    assert 0 < changed.mean() < 0.3  # only the skeleton and the clock move
    # GIFs stay at ≤ 50 frames per second: 120 fps is shown at 40 (stride 3)
    path = render_motion_video(tmp_path / "f.gif", xyz, rgb, joints[:, :10], 120, size=(32, 32))
    assert len(_gif_frames(path)) == 4


def test_render_frame_png(tmp_path):
    import imageio.v3 as iio

    from jaxmotion.export import render_frame

    xyz, rgb = _scene(18, 2000)
    joints = _motion_joints(19, 2, 12) * 0.3 + [0.0, 0.0, 0.7]
    path = render_frame(tmp_path / "m.png", xyz, rgb, joints, size=(200, 120), text="sit down")
    img = iio.imread(path)
    assert img.shape == (120, 200, 3) and img.dtype == np.uint8
    blue = (np.abs(img.astype(int) - [31, 119, 180]).sum(-1) < 30).sum()  # sample 0, bold
    orange = (np.abs(img.astype(int) - [255, 127, 14]).sum(-1) < 30).sum()  # sample 1
    assert blue > 20 and orange > 20
    again = render_frame(
        tmp_path / "m.png", xyz, None, joints[0], frame=3, affordance=np.linspace(0, 1, 2000)
    )
    assert iio.imread(again).shape == (540, 960, 3)  # the default size
    with pytest.raises(ValueError, match=".png"):
        render_frame(tmp_path / "m.jpg", xyz, rgb, joints)
    with pytest.raises(ValueError, match="frame"):
        render_frame(tmp_path / "m.png", xyz, rgb, joints, frame=12)
    with pytest.raises(ValueError, match="joints"):
        render_frame(tmp_path / "m.png", xyz, rgb, joints[..., :2])
    _no_temp_files(tmp_path)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["m.png"]


# --------------------------------------------------------------------------- HTML viewer


class _Tags(HTMLParser):
    def __init__(self):
        super().__init__()
        self.tags, self.attrs = [], []

    def handle_starttag(self, tag, attrs):
        self.tags.append(tag)
        self.attrs += attrs


def _payload(page: str) -> dict:
    m = re.search(r'<script type="application/json" id="jm-data">(.*?)</script>', page, re.DOTALL)
    return json.loads(m.group(1))


def _decode(e: dict) -> np.ndarray:
    a = np.frombuffer(base64.b64decode(e["b64"]), np.dtype(e["dtype"]).newbyteorder("<"))
    a = a.reshape(e["shape"]).astype(np.float64)
    if "offset" in e:
        a = np.asarray(e["offset"]) + a * np.asarray(e["step"])
    return a


def test_viewer_page_is_self_contained_and_embeds_the_data(tmp_path):
    xyz, rgb = _scene(14, 400)
    joints = _motion_joints(15, 2, 5)
    aff = np.random.default_rng(16).uniform(size=(400, 6))
    text = 'sit on the <b>chair</b> & "rest" </script>'
    path = write_viewer_html(
        tmp_path / "v.html",
        scene_xyz=xyz,
        scene_rgb=rgb,
        joints=joints,
        fps=30,
        text=text,
        affordance=aff,
    )
    page = path.read_text()
    parser = _Tags()
    parser.feed(page)
    parser.close()
    assert {"html", "canvas", "script"} <= set(parser.tags)
    assert not [v for k, v in parser.attrs if k in ("src", "href")]
    assert "http://" not in page and "https://" not in page
    assert page.count("</script>") == 3  # the text cannot close the data element
    data = _payload(page)
    assert data["text"] == text and data["num_samples"] == 2 and data["num_frames"] == 5
    step = np.asarray(data["scene"]["xyz"]["step"])
    np.testing.assert_allclose(_decode(data["scene"]["xyz"]), xyz, atol=float(step.max()))
    np.testing.assert_allclose(_decode(data["scene"]["rgb"]) / 255, rgb, atol=0.5 / 255 + 1e-9)
    np.testing.assert_array_equal(_decode(data["joints"]), joints.astype(np.float32))
    affordance = _decode(data["affordance"]["values"]) / 255
    np.testing.assert_allclose(affordance, aff, atol=0.5 / 255 + 1e-9)
    assert data["affordance"]["channels"] == [
        "pelvis",
        "l_foot",
        "r_foot",
        "neck",
        "l_wrist",
        "r_wrist",
    ]
    assert data["segments"] == [] and data["paths"] == [] and data["body"] is None
    assert data["objects"] == [] and data["target"] == -1
    assert not _decode(data["scene"]["instance"]).any()


def _objects_scene(seed, n):
    """Points with two boxes: object 7 (a chair) and object 3 (a table); the rest on none."""
    xyz, rgb = _scene(seed, n)
    instance = np.full(n, -1)
    instance[: n // 4], instance[n // 4 : n // 2] = 7, 3
    xyz[: n // 4] = xyz[: n // 4] * [0.1, 0.1, 0.36] + [1.0, 1.0, 0.0]
    xyz[n // 4 : n // 2] = xyz[n // 4 : n // 2] * [0.2, 0.2, 0.3] + [-1.5, -1.5, 0.0]
    objects = [{"id": 3, "category": "table", "bbox_min": [-1.9, -1.9, 0.0],
                "bbox_max": [-1.1, -1.1, 0.75]},
               {"id": 7, "category": "chair", "bbox_min": [0.8, 0.8, 0.0],
                "bbox_max": [1.2, 1.2, 0.9]}]
    return xyz, rgb, instance, objects


def test_viewer_embeds_objects_target_and_lit_colours(tmp_path):
    xyz, rgb, instance, objects = _objects_scene(21, 400)
    normal = np.zeros_like(xyz)
    normal[:100] = [0.0, 0.0, 1.0]
    page = write_viewer_html(tmp_path / "o.html", scene_xyz=xyz, scene_rgb=rgb,
                             joints=_motion_joints(22, 1, 3), fps=30, scene_normal=normal,
                             scene_instance=instance, objects=objects, target_id=7,
                             max_points=300).read_text()
    data = _payload(page)
    assert [(o["id"], o["category"]) for o in data["objects"]] == [(3, "table"), (7, "chair")]
    assert data["objects"][1]["lo"] == [0.8, 0.8, 0.0] and data["target"] == 1
    keep = np.sort(np.random.default_rng(0).choice(400, 300, replace=False))
    want = np.select([instance[keep] == 3, instance[keep] == 7], [1, 2], 0)
    np.testing.assert_array_equal(_decode(data["scene"]["instance"]), want)
    # points with a normal are lit by the fixed light, the others keep their colour
    shade = 0.55 + 0.45 * abs(np.array([0.35, -0.45, 0.82]) @ [0, 0, 1]) / np.linalg.norm(
        [0.35, -0.45, 0.82])
    lit = np.where((keep < 100)[:, None], rgb[keep] * shade, rgb[keep])
    np.testing.assert_allclose(_decode(data["scene"]["rgb"]) / 255, lit, atol=0.5 / 255 + 1e-9)
    with pytest.raises(ValueError, match="target_id 5 is not in objects"):
        write_viewer_html(tmp_path / "x.html", scene_xyz=xyz, scene_rgb=rgb,
                          joints=_motion_joints(22, 1, 3), fps=30, scene_instance=instance,
                          objects=objects, target_id=5)


def test_viewer_carries_a_storys_steps_and_paths(tmp_path):
    xyz, rgb, instance, objects = _objects_scene(19, 300)
    joints = _motion_joints(20, 1, 6)
    steps = [{"action": "stand_up", "object": 7, "first": 0, "last": 2},
             {"action": "walk", "object": 3, "first": 3, "last": 5, "label": "walk · table 3"}]
    path = [[0.0, 0.0], [1.0, 0.5], [2.0, 0.5]]
    page = write_viewer_html(tmp_path / "s.html", scene_xyz=xyz, scene_rgb=rgb, joints=joints,
                             fps=30, segments=steps, paths=[path], scene_instance=instance,
                             objects=objects).read_text()
    data = _payload(page)
    assert data["segments"] == [{"first": 0, "last": 2, "label": "stand up · object 7", "object": 1},
                                {"first": 3, "last": 5, "label": "walk · table 3", "object": 0}]
    np.testing.assert_allclose(np.reshape(data["paths"][0], (3, 3)),
                               np.c_[path, np.full(3, 0.02)])
    with pytest.raises(ValueError, match="outside the motion's 6 frames"):
        write_viewer_html(tmp_path / "x.html", scene_xyz=xyz, scene_rgb=rgb, joints=joints,
                          fps=30, segments=[{**steps[0], "last": 6}])
    with pytest.raises(ValueError, match="a path must be"):
        write_viewer_html(tmp_path / "x.html", scene_xyz=xyz, scene_rgb=rgb, joints=joints,
                          fps=30, paths=[[[0.0, 0.0]]])


def _body_page(tmp_path, k=1, t=3, n=2000):
    go, bp, tr = _params(17, t, k=k, scale=0.2)
    model = load_mannequin()
    out = _forward(model, go, bp, tr, normals=False)
    xyz, rgb, instance, objects = _objects_scene(18, n)
    path = write_viewer_html(
        tmp_path / "b.html",
        scene_xyz=xyz,
        scene_rgb=rgb,
        joints=np.asarray(out.joints)[..., :22, :],
        fps=30,
        text="walk",
        smplx={"global_orient": go, "body_pose": bp, "transl": tr},
        affordance=np.linspace(0, 1, n),
        scene_instance=instance,
        objects=objects,
        target_id=7,
        max_points=500,
    )
    return path, np.asarray(out.vertices, np.float64), model


def test_viewer_body_is_the_skinned_mannequin(tmp_path):
    path, vertices, model = _body_page(tmp_path, k=2)
    data = _payload(path.read_text())
    assert data["scene"]["xyz"]["shape"] == [500, 3]
    assert data["affordance"]["channels"] == ["map"]
    body = data["body"]
    np.testing.assert_array_equal(_decode(body["faces"]), np.asarray(model.faces))
    assert body["shape_of"] == [0, 0] and len(body["shapes"]) == 1  # one shape: the neutral body
    rest = _decode(body["shapes"][0]["positions"])
    normals = _decode(body["shapes"][0]["normals"]) / 127
    assert np.allclose(np.linalg.norm(normals, axis=1), 1, atol=0.02)
    idx = _decode(body["joints"]).astype(int)
    w = _decode(body["weights"]) / 255
    bones = _decode(body["bones"])
    assert bones.shape == (2, 3, model.num_joints, 12) and idx.max() < model.num_joints
    # linear blend skinning of the page's arrays gives the posed mannequin (body_forward)
    maps = bones.reshape(2, 3, -1, 3, 4)[:, :, idx]  # [K, T, V, 4, 3, 4]
    blended = np.einsum("vi,ktviab->ktvab", w, maps) / w.sum(1)[:, None, None]
    posed = np.einsum("ktvab,vb->ktva", blended[..., :3], rest) + blended[..., 3]
    err = np.linalg.norm(posed - vertices, axis=-1)
    assert err.max() < 1e-3, (err.max(), err.mean())  # 0.2 mm: the quantisation
    with pytest.raises(ValueError, match="samples and frames"):
        write_viewer_html(tmp_path / "x.html", scene_xyz=vertices[0, 0], scene_rgb=None,
                          joints=np.zeros((1, 22, 3)), fps=30,
                          smplx={"global_orient": np.zeros((2, 3)),
                                 "body_pose": np.zeros((2, 21, 3)), "transl": np.zeros((2, 3))})
    assert not (tmp_path / "x.html").exists()


# JS harness: runs the page's script in Node with a stub DOM and a stub WebGL2 context,
# fires its controls, sweeps the pointer over the canvas (the hover labels it shows), and
# fails on any exception (syntax, reference or type errors).
_NODE_HARNESS = r"""
const fs = require("fs");
const page = fs.readFileSync(process.argv[2], "utf8");
const blocks = [...page.matchAll(/<script([^>]*)>([\s\S]*?)<\/script>/g)];
const dataText = blocks.find((b) => b[1].includes("jm-data"))[2];
const code = blocks[blocks.length - 1][2];
const calls = {};
const gl = new Proxy({}, { get(_, prop) {
  if (typeof prop === "string" && /^[A-Z0-9_]+$/.test(prop)) return prop === "NO_ERROR" ? 0 : 1;
  return (...args) => { calls[prop] = (calls[prop] || 0) + 1;
    if (prop === "getError") return 0;
    return prop.startsWith("get") && prop.endsWith("Parameter") ? true : {}; };
} });
const listeners = {};
function element(id) {
  return { id, style: {}, textContent: "", innerHTML: "", value: "0", checked: true,
    clientWidth: 640, clientHeight: 480, width: 0, height: 0, max: "0", offsetWidth: 60,
    offsetHeight: 16, className: "",
    addEventListener(type, fn) { listeners[id + ":" + type] = fn; },
    appendChild() {}, setPointerCapture() {},
    getBoundingClientRect() { return id === "info" ? { left: 0, right: 200, top: 0, bottom: 60 }
      : { left: 0, right: 640, top: 450, bottom: 480 }; },
    getContext(kind) { return kind === "webgl2" ? gl : null; } };
}
const elements = {};
globalThis.document = {
  getElementById(id) { return id === "jm-data" ? { textContent: dataText } : (elements[id] ||= element(id)); },
  querySelector(sel) { return element(sel); },
  createElement() { return element("new"); }, createTextNode() { return {}; },
  documentElement: { setAttribute() {} },
};
globalThis.location = { hash: "" };
let queue = [];
globalThis.window = { devicePixelRatio: 1, addEventListener(type, fn) { listeners["window:" + type] = fn; } };
globalThis.requestAnimationFrame = (cb) => queue.push(cb);
function flush(rounds) {
  for (let i = 0; i < rounds && queue.length; i++) {
    const q = queue; queue = []; q.forEach((cb) => cb(performance.now() + 1000 * i));
  }
}
new Function(code)();
flush(3);
const ev = { clientX: 10, clientY: 10, button: 0, shiftKey: false, pointerId: 1, deltaY: 100,
  preventDefault() {} };
if (listeners["colouring:change"]) { elements.colouring.value = "max"; listeners["colouring:change"](); }
const tips = new Set();
for (let x = 0; x < 640; x += 16) for (let y = 0; y < 480; y += 16) {
  listeners["view:pointermove"]({ offsetX: x, offsetY: y });
  flush(1);
  if (elements.tip.style.display === "block") tips.add(elements.tip.textContent);
}
listeners["view:pointerleave"]();
listeners["view:pointerdown"](ev);
listeners["view:pointermove"](Object.assign({}, ev, { clientX: 30 }));
listeners["view:pointerup"](ev);
listeners["view:pointerdown"](Object.assign({}, ev, { button: 2 }));
listeners["view:pointermove"](Object.assign({}, ev, { clientY: 40 }));
listeners["view:wheel"](ev);
listeners["view:dblclick"](ev);
listeners["play:click"]();
flush(5);
elements.time.value = "1";
listeners["time:input"]();
flush(3);
console.log(JSON.stringify({ viewer: window.jaxmotionViewer, calls, tips: [...tips].sort() }));
"""


@pytest.mark.skipif(shutil.which("node") is None, reason="Node.js not installed")
def test_viewer_script_runs_in_node_with_stub_webgl(tmp_path):
    path, _, _ = _body_page(tmp_path, k=1, t=3, n=300)
    harness = tmp_path / "harness.js"
    harness.write_text(_NODE_HARNESS)
    run = subprocess.run(
        ["node", str(harness), str(path)], check=False, capture_output=True, text=True, timeout=60
    )
    assert run.returncode == 0, run.stderr
    result = json.loads(run.stdout)
    assert result["viewer"] == {"ready": True, "frame": 1, "frames": 3, "samples": 1,
                                "body": True}
    assert result["calls"]["drawElements"] >= 1 and result["calls"]["drawArrays"] >= 4
    assert result["tips"] == ["chair 7 · target", "table 3"]


_CHROMIUM = shutil.which("chromium") or "/usr/bin/chromium"
_BACKGROUND = np.array([30, 33, 40])  # the page's clear colour


def _chromium(tmp_path, url: str, name: str, size=(800, 600)):
    """Headless Chromium with software WebGL (SwiftShader): the page's DOM after its first
    draws and a screenshot ``[H, W, 3]`` int."""
    from PIL import Image

    png = tmp_path / f"{name}.png"
    run = subprocess.run(
        [_CHROMIUM, "--headless=new", "--no-sandbox", "--disable-gpu", "--use-angle=swiftshader",
         "--enable-unsafe-swiftshader", "--no-first-run", "--hide-scrollbars",
         "--disable-dev-shm-usage",
         f"--user-data-dir={tmp_path / 'profile'}", f"--window-size={size[0]},{size[1]}",
         "--virtual-time-budget=10000", f"--screenshot={png}", "--dump-dom", url],
        check=False, capture_output=True, text=True, timeout=120)
    assert run.returncode == 0 and png.is_file(), run.stderr[-2000:]
    return run.stdout, np.asarray(Image.open(png).convert("RGB"), np.int64)


@pytest.mark.skipif(not Path(_CHROMIUM).is_file(),
                    reason="no Chromium (/usr/bin/chromium): .ci/run installs Debian's "
                    "chromium package when it runs as root with apt-get")
def test_viewer_draws_the_body_in_headless_chromium(tmp_path):
    from jaxmotion.scene.demo import demo_scene

    scene = demo_scene()
    t = 3
    go = np.tile([np.pi / 2, 0.0, 0.0], (1, t, 1))  # SMPL-X's y-up rest pose stood up in z-up
    bp = np.zeros((1, t, 21, 3))
    tr = np.zeros((1, t, 3))
    model = load_mannequin()
    out = _forward(model, go, bp, tr, normals=False)
    tr += [1.0, 1.4, -float(np.asarray(out.vertices)[..., 2].min())]
    tr[0, :, 0] += np.linspace(0.0, 0.1, t)
    joints = np.asarray(_forward(model, go, bp, tr, normals=False).joints)[..., :22, :]
    page = write_viewer_html(
        tmp_path / "v.html", scene_xyz=scene.xyz, scene_rgb=scene.rgb, joints=joints, fps=30,
        text="stand in the room", smplx={"global_orient": go, "body_pose": bp, "transl": tr},
        scene_normal=scene.normal, scene_instance=scene.instance, objects=scene.objects,
        target_id=4, affordance=np.linspace(0, 1, scene.num_points))
    with_body, shot = _chromium(tmp_path, page.as_uri() + "#frame=2", "body")
    without_body, bare = _chromium(tmp_path, page.as_uri() + "#frame=2&body=0", "bare")
    for dom in (with_body, without_body):  # drawn, and no error nor console.error
        tag = re.search(r"<html[^>]*>", dom).group(0)
        assert 'data-frame="2"' in tag and "data-errors" not in tag, tag
        # the target's label is shown
        assert re.search(r'class="label target" style="display: block;[^"]*">chair 4 · target<',
                         dom), re.findall(r'<div class="label[^<]*<', dom)
    # the target (chair 4) is tinted amber
    amber = (bare[..., 0] > 190) & (bare[..., 1] > 100) & (bare[..., 1] < 190) & (bare[..., 2] < 90)
    assert amber.sum() > 2000, amber.sum()  # about 5,000 here; a few hundred without the tint
    # WebGL drew the room: much of the canvas above the bar is not the clear colour
    canvas = np.abs(bare[100:540] - _BACKGROUND).sum(-1) > 30
    assert canvas.mean() > 0.3, canvas.mean()
    # the body: pixels that change when it is hidden, light blue (sample 0's colour), in the
    # middle of the picture where the camera looks
    body = np.abs(shot - bare).sum(-1) > 60
    rows, cols = np.nonzero(body)
    assert body.sum() > 2000, body.sum()
    r, g, b = shot[body].T
    assert np.median(b - r) > 20 and np.median(g - r) > 5, (np.median(r), np.median(g),
                                                           np.median(b))
    assert abs(np.median(rows) - 300) < 120 and abs(np.median(cols) - 400) < 120


@pytest.mark.parametrize("skeleton", ["mixamo", "ue5"])
def test_bvh_of_another_rig_poses_the_same_body(tmp_path, skeleton):
    from jaxmotion.eval.skating import foot_skating
    from jaxmotion.export.bvh import rig_bones
    from jaxmotion.io import load_bvh

    go, bp, tr = _params(3, 9, scale=0.8)
    betas = np.random.default_rng(4).normal(size=10)
    bvh = read_bvh(write_bvh(tmp_path / "m.bvh", go, bp, tr, betas, 30.0, skeleton=skeleton))
    bones = rig_bones(skeleton)
    assert list(bvh.names) == [b[0] for b in bones]  # the rig's names, depth first
    parents = {b[0]: (bones[b[1]][0] if b[1] >= 0 else None) for b in bones}
    assert [bvh.names[p] if p >= 0 else None for p in bvh.parents] == [
        parents[n] for n in bvh.names]
    if skeleton == "mixamo":
        assert all(n.startswith("mixamorig:") for n in bvh.names) and len(bvh.names) == 22
        assert parents["mixamorig:LeftArm"] == "mixamorig:LeftShoulder"
        assert parents["mixamorig:LeftShoulder"] == "mixamorig:Spine2"
    else:
        assert bvh.names[:2] == ("root", "pelvis")
        assert [parents[f"spine_0{i}"] for i in range(1, 6)] == [
            "pelvis", "spine_01", "spine_02", "spine_03", "spine_04"]
        assert parents["neck_02"] == "neck_01" and parents["head"] == "neck_02"
        assert parents["clavicle_l"] == "spine_05" and parents["ball_r"] == "foot_r"
        assert len(bvh.names) == 26
    # every SMPL-X joint where the SMPL-X export puts it (centimetres, y up)
    world = _bvh_world_joints(bvh) @ Y_UP / 100.0
    at = {b[2]: i for i, b in enumerate(bones) if b[2] is not None}
    expected = np.asarray(_joints(go, bp, tr, betas), np.float64)
    np.testing.assert_allclose(world[:, [at[j] for j in range(22)]], expected, atol=1e-4)
    # read back without a map (Mixamo's built-in one, UE5's automatic): the same joints,
    # so the same foot skating
    m = load_bvh(tmp_path / "m.bvh", first_frame="keep")
    assert m.info["joint_map"] == ("mixamo" if skeleton == "mixamo" else "automatic")
    np.testing.assert_allclose(m.joints, expected, atol=1e-4)
    a = foot_skating(np.asarray(m.joints, np.float32))
    b = foot_skating(np.asarray(expected, np.float32))
    for key in a:
        np.testing.assert_allclose(np.asarray(a[key]), np.asarray(b[key]), rtol=1e-5, atol=1e-6)


def test_retarget_command_writes_each_rig_from_generate_and_amass_files(tmp_path, capsys):
    from jaxmotion.cli import main
    from jaxmotion.export import write_amass_npz

    go, bp, tr = _params(5, 6, k=2)
    betas = np.zeros((2, 10), np.float32)
    np.savez(tmp_path / "motion.npz", global_orient=go, body_pose=bp, transl=tr, betas=betas,
             fps=np.float32(30), joints=np.zeros((2, 6, 22, 3), np.float32))
    write_amass_npz(tmp_path / "motion_smplx.npz", go[1], bp[1], tr[1], betas[1], 30.0)
    assert main(["retarget", str(tmp_path / "motion.npz"), "--skeleton", "ue5", "--sample", "1",
                 "--out", str(tmp_path / "a.bvh")]) == 0
    assert main(["retarget", str(tmp_path / "motion_smplx.npz"), "--skeleton", "ue5",
                 "--out", str(tmp_path / "b.bvh")]) == 0
    a, b = read_bvh(tmp_path / "a.bvh"), read_bvh(tmp_path / "b.bvh")
    assert a.names[:2] == ("root", "pelvis") and a.names == b.names
    np.testing.assert_allclose(a.frames, b.frames, atol=1e-3)  # the same sample, two files
    assert main(["retarget", str(tmp_path / "motion.npz"), "--skeleton", "mixamo",
                 "--out", str(tmp_path / "c.bvh")]) == 0
    assert read_bvh(tmp_path / "c.bvh").names[0] == "mixamorig:Hips"
    capsys.readouterr()
    assert main(["retarget", str(tmp_path / "motion.npz"), "--skeleton", "mixamo",
                 "--sample", "2", "--out", str(tmp_path / "d.bvh")]) == 2
    assert "samples 0..1" in capsys.readouterr().err and not (tmp_path / "d.bvh").exists()
    assert main(["retarget", str(tmp_path / "motion.npz"), "--skeleton", "ue5",
                 "--out", str(tmp_path / "e.fbx")]) == 2
