"""What a Blender user opens: SMPL-X bone names in motion.glb and the AMASS-style motion_smplx.npz."""

import json
import struct
from importlib import resources
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from jaxmotion.body import joint_names, load_mannequin, load_smplx
from jaxmotion.export import AMASS_KEYS, write_amass_npz, write_glb
from jaxmotion.geometry import (
    NUM_JOINTS,
    SMPLX_JOINT_NAMES,
    SMPLX_PARENTS,
    rest_joints_host,
    smplx_joints,
)
from jaxmotion.io import load_motion
from jaxmotion.result import OUTPUT_FILES, Generation
from jaxmotion.scene import Scene


def _params(seed, t, scale=0.4):
    rng = np.random.default_rng(seed)
    return (rng.normal(size=(t, 3)), rng.normal(size=(t, 21, 3)) * scale,
            rng.normal(size=(t, 3)), rng.normal(size=10) * 0.5)


def _gltf_json(path) -> dict:
    raw = Path(path).read_bytes()
    length, kind = struct.unpack_from("<II", raw, 12)
    assert kind == 0x4E4F534A  # "JSON", the first chunk
    return json.loads(raw[20 : 20 + length])


def _skeletons(gltf) -> list[tuple[list[str], list[str | None]]]:
    """Per skin: its joint nodes' names, and each joint's parent's name (None for the root)."""
    nodes = gltf["nodes"]
    parent = {c: i for i, n in enumerate(nodes) for c in n.get("children", [])}
    out = []
    for skin in gltf["skins"]:
        joints = skin["joints"]
        names = [nodes[j]["name"] for j in joints]
        parents = [nodes[parent[j]]["name"] if parent[j] in joints else None for j in joints]
        out.append((names, parents))
    return out


# --------------------------------------------------------------------------- names


def test_smplx_names_are_the_standard_55():
    assert len(SMPLX_JOINT_NAMES) == len(set(SMPLX_JOINT_NAMES)) == len(SMPLX_PARENTS) == 55
    assert SMPLX_JOINT_NAMES[:3] == ("pelvis", "left_hip", "right_hip")
    assert SMPLX_JOINT_NAMES[20:28] == ("left_wrist", "right_wrist", "jaw", "left_eye_smplhf",
                                        "right_eye_smplhf", "left_index1", "left_index2",
                                        "left_index3")
    assert SMPLX_JOINT_NAMES[-1] == "right_thumb3" and SMPLX_JOINT_NAMES[40] == "right_index1"
    named = dict(zip(SMPLX_JOINT_NAMES, SMPLX_PARENTS))
    assert named["jaw"] == named["left_eye_smplhf"] == SMPLX_JOINT_NAMES.index("head")
    assert SMPLX_JOINT_NAMES[named["right_thumb1"]] == "right_wrist"
    assert SMPLX_JOINT_NAMES[named["left_pinky3"]] == "left_pinky2"


def test_mannequin_joint_names_agree_with_its_own_assets():
    """mannequin-x names its joints L_Index1, ...: the same joints as SMPL-X's left_index1."""
    with (resources.files("mannequin") / "assets" / "wooden.npz").open("rb") as f:
        own = [str(n) for n in np.load(f)["joint_names"]]
    names = joint_names(load_mannequin())
    assert len(names) == len(own) == 54
    for mine, theirs in zip(names[NUM_JOINTS:], own[NUM_JOINTS:]):
        if theirs in ("L_Hand", "R_Hand"):
            assert mine is None  # a hand root: no SMPL-X joint
        else:
            side = {"L": "left", "R": "right"}[theirs[0]]
            assert mine == f"{side}_{theirs[2:].lower()}"


def test_glb_bones_carry_unique_smplx_names(tmp_path):
    go, bp, tr, betas = _params(0, 3)
    k = 2
    path = write_glb(tmp_path / "m.glb", global_orient=np.stack([go, go]),
                     body_pose=np.stack([bp, bp]), transl=np.stack([tr, tr]), fps=30,
                     betas=betas)
    gltf = _gltf_json(path)
    skeletons = _skeletons(gltf)
    assert len(skeletons) == k
    want = SMPLX_JOINT_NAMES[:NUM_JOINTS] + SMPLX_JOINT_NAMES[25:]  # no jaw, no eyes
    for s, (names, parents) in enumerate(skeletons):
        assert len(names) == len(set(names)) == 52  # unique within the armature
        assert tuple(names) == want  # the 22 body joints first, then the fingers
        for name, parent in zip(names, parents):  # the SMPL-X tree, hand roots folded away
            p = SMPLX_PARENTS[SMPLX_JOINT_NAMES.index(name)]
            assert parent == (None if p < 0 else SMPLX_JOINT_NAMES[p])
        holder = next(n for n in gltf["nodes"] if n.get("name") == f"sample{s}")
        assert [gltf["nodes"][c]["name"] for c in holder["children"]] == ["pelvis"]
    assert not [n["name"] for n in gltf["nodes"] if n.get("name", "").startswith("joint")]


def test_glb_of_an_smplx_model_names_all_55_joints(tmp_path):
    """A user's SMPL-X model (a tiny stand-in with SMPL-X's tree) gives every SMPL-X bone."""
    rng = np.random.default_rng(1)
    j, v = 55, 80
    joints = np.zeros((j, 3))
    joints[:NUM_JOINTS] = rest_joints_host(None)
    for c in range(NUM_JOINTS, j):
        joints[c] = joints[SMPLX_PARENTS[c]] + rng.normal(size=3) * 0.03
    owner = np.concatenate([np.arange(j), rng.integers(0, j, size=v - j)])
    verts = joints[owner] + rng.normal(size=(v, 3)) * 0.02
    verts[:j] = joints  # vertex c sits on joint c: the regressor picks it
    model = load_smplx({
        "v_template": verts, "shapedirs": np.zeros((v, 3, 10)), "J_regressor": np.eye(j, v),
        "weights": np.eye(j)[owner], "f": rng.integers(0, v, size=(100, 3)),
        "kintree_table": np.stack([np.array([2**32 - 1, *SMPLX_PARENTS[1:]]), np.arange(j)]),
    })
    assert joint_names(model) == SMPLX_JOINT_NAMES
    go, bp, tr, _ = _params(2, 2)
    gltf = _gltf_json(write_glb(tmp_path / "x.glb", global_orient=go, body_pose=bp,
                                transl=tr, fps=30, model=model))
    ((names, parents),) = _skeletons(gltf)
    assert tuple(names) == SMPLX_JOINT_NAMES
    assert parents == [None if p < 0 else SMPLX_JOINT_NAMES[p] for p in SMPLX_PARENTS]


def test_joint_names_refuse_an_unknown_tree():
    m = load_mannequin()
    odd = SimpleNamespace(parents=m.parents[:30], num_joints=30)
    with pytest.raises(ValueError, match="no SMPL-X names for a body of 30 joints"):
        joint_names(odd)


# --------------------------------------------------------------------------- AMASS npz


def test_amass_npz_has_amass_keys_shapes_and_types(tmp_path):
    go, bp, tr, betas = _params(3, 5)
    path = write_amass_npz(tmp_path / "m.npz", go, bp, tr, betas, 30.0)
    with np.load(path, allow_pickle=False) as d:  # plain arrays: no pickle needed
        assert sorted(d.files) == sorted(AMASS_KEYS) == sorted(
            ["trans", "poses", "betas", "gender", "mocap_frame_rate", "surface_model_type",
             "root_orient", "pose_body", "pose_hand", "pose_jaw", "pose_eye"])
        shapes = {k: d[k].shape for k in d.files if d[k].dtype.kind == "f"}
        assert shapes == {"trans": (5, 3), "poses": (5, 165), "root_orient": (5, 3),
                          "pose_body": (5, 63), "pose_jaw": (5, 3), "pose_eye": (5, 6),
                          "pose_hand": (5, 90), "betas": (10,), "mocap_frame_rate": ()}
        assert all(d[k].dtype == np.float64 for k in shapes)
        assert str(d["gender"]) == "neutral" and str(d["surface_model_type"]) == "smplx"
        assert d["gender"].dtype.kind == "U" and float(d["mocap_frame_rate"]) == 30.0
        poses = d["poses"]
        np.testing.assert_array_equal(poses[:, :3], d["root_orient"])
        np.testing.assert_array_equal(poses[:, 3:66], d["pose_body"])
        np.testing.assert_array_equal(poses[:, 66:69], d["pose_jaw"])
        np.testing.assert_array_equal(poses[:, 69:75], d["pose_eye"])
        np.testing.assert_array_equal(poses[:, 75:], d["pose_hand"])
        assert not poses[:, 66:].any()  # no jaw, eye or finger motion in a generated motion
        np.testing.assert_allclose(d["pose_body"], bp.reshape(5, 63))
        np.testing.assert_allclose(d["trans"], tr)
        np.testing.assert_allclose(d["betas"], betas)


def test_amass_npz_round_trips_through_the_amass_reader(tmp_path):
    """``trans`` is SMPL-X's translation: the reader's forward kinematics puts the joints back
    where the parameters put them (float64 file; jax float32 FK: 1e-5 m)."""
    go, bp, tr, betas = _params(4, 6, scale=0.8)
    path = write_amass_npz(tmp_path / "m.npz", go, bp, tr, betas, 20.0)
    m = load_motion(path)
    assert m.info["model"] == "SMPL-X" and m.info["gender"] == "neutral" and m.fps == 20.0
    np.testing.assert_allclose(m.transl, tr, atol=1e-12)
    np.testing.assert_allclose(m.betas, betas, atol=1e-12)
    np.testing.assert_allclose(m.joints, np.asarray(smplx_joints(go, bp, tr, betas)), atol=1e-5)
    # the pelvis is the rest pelvis of the shape plus trans, not trans itself
    np.testing.assert_allclose(m.joints[:, 0], rest_joints_host(betas)[0] + tr, atol=1e-5)


def test_amass_npz_rejects_bad_input(tmp_path):
    go, bp, tr, betas = _params(5, 4)
    path = tmp_path / "m.npz"
    path.write_bytes(b"old")
    with pytest.raises(ValueError, match="one motion"):
        write_amass_npz(path, np.stack([go, go]), np.stack([bp, bp]), np.stack([tr, tr]),
                        betas, 30)
    with pytest.raises(ValueError, match="body_pose"):
        write_amass_npz(path, go, bp[:, :20], tr, betas, 30)
    with pytest.raises(ValueError, match="fps"):
        write_amass_npz(path, go, bp, tr, betas, -1)
    with pytest.raises(ValueError, match="betas"):
        write_amass_npz(path, go, bp, tr, np.full(10, np.nan), 30)
    with pytest.raises(ValueError, match="gender"):
        write_amass_npz(path, go, bp, tr, betas, 30, gender="robot")
    assert path.read_bytes() == b"old"  # a refused write leaves the old file
    assert [p.name for p in tmp_path.iterdir()] == ["m.npz"]
    with np.load(write_amass_npz(path, go, bp, tr, None, 30)) as d:
        np.testing.assert_array_equal(d["betas"], np.zeros(10))


def _small_generation(k=2, t=12):
    """A Generation as ``generate`` returns it, without the models: fitted parameters, and
    'generated' joints 1-2 cm off the fitted body (a fit's typical error)."""
    rng = np.random.default_rng(6)
    gos, bps, trs, betas = [], [], [], []
    for s in range(k):
        go, bp, tr, b = _params(10 + s, t)
        gos.append(go), bps.append(bp), trs.append(tr + [0, 0, 1]), betas.append(b)
    smplx = {"global_orient": np.array(gos, np.float32), "body_pose": np.array(bps, np.float32),
             "transl": np.array(trs, np.float32), "betas": np.array(betas, np.float32)}
    fitted = np.stack([np.asarray(smplx_joints(smplx["global_orient"][s], smplx["body_pose"][s],
                                               smplx["transl"][s], smplx["betas"][s]))
                       for s in range(k)])
    joints = (fitted + rng.normal(size=fitted.shape) * 0.01).astype(np.float32)
    xyz = rng.uniform([-2, -2, 0], [2, 2, 2], size=(200, 3)).astype(np.float32)
    scene = Scene(xyz=xyz, rgb=np.full_like(xyz, 0.5), name="tiny")
    return Generation(
        text="sit on the chair", scene=scene, joints=joints, fps=30.0,
        mask=np.ones(t, bool), smplx=smplx,
        fit_error=np.linalg.norm(joints - fitted, axis=-1).mean(axis=(1, 2)),
        crop_xyz=xyz[:50], crop_rgb=np.full((50, 3), 0.5, np.float32),
        affordance=np.zeros((k, 50, 6), np.float32), rotation=np.eye(3, dtype=np.float32),
        shift=np.zeros(3, np.float32), object_id=None, target_id=None, seed=0, steps=2,
        timings={}), fitted


def test_generate_folder_writes_the_amass_npz_beside_the_others(tmp_path):
    """The file carries the fitted body of the BVH's sample: read back it gives the fitted
    joints to float rounding (1e-5 m), and the result's joints to within the fit's own error
    (the result's ``fit_error``, its mean joint distance to the fitted body)."""
    res, fitted = _small_generation()
    files = res.save(tmp_path / "out", video=None, bvh_sample=1)
    assert "motion_smplx.npz" in files and "motion_smplx.npz" in OUTPUT_FILES
    m = load_motion(files["motion_smplx.npz"])
    assert m.fps == 30.0 and m.joints.shape == (12, 22, 3)
    np.testing.assert_allclose(m.joints, fitted[1], atol=1e-5)
    dist = np.linalg.norm(m.joints - res.joints[1], axis=-1).mean()
    assert dist == pytest.approx(res.fit_error[1], abs=1e-5)
    with np.load(files["motion_smplx.npz"]) as d:
        np.testing.assert_allclose(d["betas"], res.smplx["betas"][1], atol=1e-7)
    assert not [p for p in (tmp_path / "out").iterdir() if p.name.startswith(".")]
