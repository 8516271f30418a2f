"""Real-data readers (jaxmotion.io): files written here in each exact format, read back and
compared with a reference computed independently (JAX ``smplx_joints``), plus bad input."""

from __future__ import annotations

import json
import pickle
from pathlib import Path

import jax
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from jaxmotion.geometry import (
    JOINT_NAMES,
    PARENTS,
    SMPLX_JOINT_NAMES,
    rest_joints_host,
    smplx_joints,
)
from jaxmotion.io import (
    Motion,
    MotionFormatError,
    caption_clips,
    load_amass,
    load_bvh,
    load_humanise,
    load_humanml3d,
    load_motion,
    load_split,
    smplx_joints_host,
)

T = 6
TOL = 1e-4  # metres: BVH text keeps 6 decimals of degrees and of the length unit
Z_TO_Y = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])  # (x, y, z) -> (x, z, -y)
_joints = jax.jit(smplx_joints)


def _params(seed=0, t=T):
    rng = np.random.default_rng(seed)
    return (rng.normal(size=(t, 3)) * 0.8, rng.normal(size=(t, 21, 3)) * 0.3,
            rng.normal(size=(t, 3)) + [0, 0, 1], rng.normal(size=10) * 0.8)


def _reference(go, bp, tr, betas):
    return np.asarray(_joints(*(np.asarray(x, np.float32) for x in (go, bp, tr, betas))))


# --------------------------------------------------------------------------- a BVH writer
def _smplx_skeleton(betas, names=SMPLX_JOINT_NAMES):
    """(name, parent index, offset, rotation source) of the SMPL-X tree; source = SMPL-X joint."""
    rest = rest_joints_host(betas)
    return [(names[j], PARENTS[j], np.zeros(3) if j == 0 else rest[j] - rest[PARENTS[j]], j)
            for j in range(22)]


def _cmu_skeleton(betas):
    """A CMU/cgspeed-named skeleton whose mapped joints sit exactly on SMPL-X's: zero-length
    pass-through joints (LHipJoint, LowerBack) and fingers added; SMPL-X's spine3 is 'Neck'
    and its collars 'LeftShoulder' (neither is in the CMU map, so the reader interpolates)."""
    rest = rest_joints_host(betas)
    sk = []

    def add(name, parent_name, smplx, offset_from=None):
        parent = next((i for i, s in enumerate(sk) if s[0] == parent_name), -1)
        if smplx is None:
            off = np.zeros(3) if offset_from is None else offset_from
        else:
            off = np.zeros(3) if parent < 0 else rest[smplx] - rest[_anchor(parent)]
        sk.append((name, parent, off, smplx))

    def _anchor(i):  # the SMPL-X joint a skeleton entry sits on
        while sk[i][3] is None:
            i = sk[i][1]
        return sk[i][3]

    add("Hips", None, 0)
    for side, s in (("Left", "l_"), ("Right", "r_")):
        add(f"{side[0]}HipJoint", "Hips", None)
        add(f"{side}UpLeg", f"{side[0]}HipJoint", JOINT_NAMES.index(s + "hip"))
        add(f"{side}Leg", f"{side}UpLeg", JOINT_NAMES.index(s + "knee"))
        add(f"{side}Foot", f"{side}Leg", JOINT_NAMES.index(s + "ankle"))
        add(f"{side}ToeBase", f"{side}Foot", JOINT_NAMES.index(s + "foot"))
    add("LowerBack", "Hips", None)
    add("Spine", "LowerBack", 3)
    add("Spine1", "Spine", 6)
    add("Neck", "Spine1", 9)
    add("Neck1", "Neck", 12)
    add("Head", "Neck1", 15)
    for side, s in (("Left", "l_"), ("Right", "r_")):
        add(f"{side}Shoulder", "Neck", JOINT_NAMES.index(s + "collar"))
        add(f"{side}Arm", f"{side}Shoulder", JOINT_NAMES.index(s + "shoulder"))
        add(f"{side}ForeArm", f"{side}Arm", JOINT_NAMES.index(s + "elbow"))
        add(f"{side}Hand", f"{side}ForeArm", JOINT_NAMES.index(s + "wrist"))
        add(f"{side}FingerBase", f"{side}Hand", None, np.array([0.05, 0.0, 0.0]))
    return sk


def _write_bvh(path, skeleton, go, bp, tr, betas, *, scale=1.0, order="ZXY", six=False,
               up="y", frame_time="0.03333333"):
    """BVH text of an SMPL-X motion on ``skeleton`` (entries from the helpers above): the
    root carries the world turn and the pelvis position, joints their SMPL-X local rotation
    (identity for joints with no SMPL-X source), each as Euler angles in ``order``."""
    t = len(go)
    local = Rotation.from_rotvec(np.concatenate([go[:, None], bp], 1).reshape(-1, 3))
    local = local.as_matrix().reshape(t, 22, 3, 3)
    world = Z_TO_Y if up == "y" else np.eye(3)
    pelvis = (tr + rest_joints_host(betas)[0]) @ world.T * scale
    rot_ch = [f"{a}rotation" for a in order]
    pos_ch = ["Xposition", "Yposition", "Zposition"]
    lines, cols = ["HIERARCHY"], []

    def emit(i, pad):
        name, parent, off, src = skeleton[i]
        kids = [k for k, s in enumerate(skeleton) if s[1] == i]
        chans = pos_ch + rot_ch if (parent < 0 or six) else rot_ch
        lines.extend([f"{pad}{'ROOT' if parent < 0 else 'JOINT'} {name}", f"{pad}{{",
                      f"{pad}  OFFSET {' '.join(f'{v * scale:.6f}' for v in off)}",
                      f"{pad}  CHANNELS {len(chans)} {' '.join(chans)}"])
        r = np.broadcast_to(np.eye(3), (t, 3, 3)) if src is None else local[:, src]
        if parent < 0:
            r, pos = world @ r, pelvis
        else:
            pos = np.broadcast_to(off * scale, (t, 3))
        euler = Rotation.from_matrix(r).as_euler(order, degrees=True)
        cols.append(np.concatenate([pos, euler], 1) if len(chans) == 6 else euler)
        for k in kids:
            emit(k, pad + "  ")
        if not kids:
            lines.extend([f"{pad}  End Site", f"{pad}  {{",
                          f"{pad}    OFFSET 0.0 {scale * 0.05:.6f} 0.0", f"{pad}  }}"])
        lines.append(f"{pad}}}")

    emit(0, "")
    values = np.concatenate(cols, 1)
    lines += ["MOTION", f"Frames: {t}", f"Frame Time: {frame_time}"]
    lines += [" ".join(f"{v:.6f}" for v in row) for row in values]
    Path(path).write_text("\n".join(lines) + "\n")
    return Path(path)


@pytest.fixture()
def motion():
    go, bp, tr, betas = _params()
    return go, bp, tr, betas, _reference(go, bp, tr, betas)


# --------------------------------------------------------------------------- BVH
def test_smplx_joints_host_matches_jax(motion):
    go, bp, tr, betas, ref = motion
    np.testing.assert_allclose(smplx_joints_host(go, bp, tr, betas), ref, atol=1e-5)


@pytest.mark.parametrize("order,six,scale,up", [
    ("ZXY", False, 1.0, "y"),          # jaxmotion's own export layout
    ("ZYX", False, 1.0, "y"),          # CMU's channel order
    ("ZXY", True, 100.0, "y"),         # 6 channels on every joint, centimetres
    ("XYZ", True, 1.0, "z"),           # a z-up file
    ("YXZ", False, 1 / 0.056444, "y"),  # CMU length units
])
def test_bvh_round_trip(tmp_path, motion, order, six, scale, up):
    go, bp, tr, betas, ref = motion
    path = _write_bvh(tmp_path / "m.bvh", _smplx_skeleton(betas), go, bp, tr, betas,
                      scale=scale, order=order, six=six, up=up)
    m = load_motion(path, up=up)
    assert isinstance(m, Motion) and m.fps == 30.0 and not m.has_smplx and m.texts == ()
    assert m.info["joint_map"] == "smplx"
    assert m.info["unit"] == pytest.approx(1.0 / scale)
    np.testing.assert_allclose(m.joints, ref, atol=TOL)
    # an explicit unit gives the same; the wrong up axis does not
    np.testing.assert_allclose(load_bvh(path, up=up, unit=1 / scale).joints, ref, atol=TOL)


def test_bvh_export_round_trip(tmp_path, motion):
    from jaxmotion.export import write_bvh

    go, bp, tr, betas, ref = motion
    write_bvh(tmp_path / "e.bvh", go, bp, tr, betas, 30.0, scale=100)
    m = load_motion(tmp_path / "e.bvh")
    assert m.info["joint_map"] == "smplx"
    np.testing.assert_allclose(m.joints, ref, atol=TOL)
    # files from before the export took SMPL-X's names (l_hip, ...) still read
    path = _write_bvh(tmp_path / "old.bvh", _smplx_skeleton(betas, JOINT_NAMES), go, bp, tr,
                      betas)
    old = load_motion(path)
    assert old.info["joint_map"] == "jaxmotion"
    np.testing.assert_allclose(old.joints, ref, atol=TOL)


def test_bvh_cmu_skeleton_maps_and_fills(tmp_path, motion):
    go, bp, tr, betas, ref = motion
    path = _write_bvh(tmp_path / "cmu.bvh", _cmu_skeleton(betas), go, bp, tr, betas,
                      scale=1 / 0.056444, order="ZYX", frame_time="0.008333")
    m = load_bvh(path)
    assert m.info["joint_map"] == "cmu" and m.info["unit"] == pytest.approx(0.056444)
    assert m.fps == 120.0
    mapped = [JOINT_NAMES.index(n) for n in JOINT_NAMES if n not in ("spine3", "l_collar",
                                                                      "r_collar")]
    np.testing.assert_allclose(m.joints[:, mapped], ref[:, mapped], atol=TOL)
    # spine3: on the spine2 -> neck line at the rest-length fraction; collars near the truth
    rest = rest_joints_host()
    f = np.linalg.norm(rest[9] - rest[6]) / (np.linalg.norm(rest[9] - rest[6])
                                             + np.linalg.norm(rest[12] - rest[9]))
    np.testing.assert_allclose(m.joints[:, 9], ref[:, 6] + f * (ref[:, 12] - ref[:, 6]), atol=TOL)
    assert np.linalg.norm(m.joints[:, 13:15] - ref[:, 13:15], axis=-1).max() < 0.08
    # resampling to 30 fps keeps every 4th frame
    np.testing.assert_allclose(load_bvh(path, fps=30).joints, m.joints[::4], atol=1e-6)


@pytest.mark.parametrize("prefix", ["mixamorig:", ""])
def test_bvh_mixamo_names(tmp_path, motion, prefix):
    go, bp, tr, betas, ref = motion
    names = {"pelvis": "Hips", "spine1": "Spine", "spine2": "Spine1", "spine3": "Spine2",
             "neck": "Neck", "head": "Head"}
    limbs = {"hip": "UpLeg", "knee": "Leg", "ankle": "Foot", "foot": "ToeBase",
             "collar": "Shoulder", "shoulder": "Arm", "elbow": "ForeArm", "wrist": "Hand"}
    for s, side in (("l_", "Left"), ("r_", "Right")):
        names.update({s + k: side + v for k, v in limbs.items()})
    sk = _smplx_skeleton(betas, [prefix + names[n] for n in JOINT_NAMES])
    path = _write_bvh(tmp_path / "mixamo.bvh", sk, go, bp, tr, betas, scale=100.0, six=True)
    m = load_motion(path)
    assert m.info["joint_map"] == "mixamo" and m.info["unit"] == pytest.approx(0.01)
    np.testing.assert_allclose(m.joints, ref, atol=TOL)


def test_bvh_user_joint_map(tmp_path, motion):
    go, bp, tr, betas, ref = motion
    sk = _smplx_skeleton(betas, [f"bone{j:02d}" for j in range(22)])
    path = _write_bvh(tmp_path / "u.bvh", sk, go, bp, tr, betas)
    # names that say nothing: mapped by the skeleton's shape alone, the same body
    auto = load_bvh(path)
    assert auto.info["joint_map"] == "automatic" and auto.info["joint_map_confidence"] < 0.9
    np.testing.assert_allclose(auto.joints, ref, atol=TOL)
    full = {n: f"bone{j:02d}" for j, n in enumerate(JOINT_NAMES)}
    (tmp_path / "map.json").write_text(json.dumps(full))
    np.testing.assert_allclose(load_bvh(path, joint_map=tmp_path / "map.json").joints, ref,
                               atol=TOL)
    # a map that leaves out interior joints: they are filled on their chain
    part = {k: v for k, v in full.items() if k not in ("spine2", "l_elbow")}
    m = load_bvh(path, joint_map=part)
    keep = [j for j, n in enumerate(JOINT_NAMES) if n not in ("spine2", "l_elbow")]
    np.testing.assert_allclose(m.joints[:, keep], ref[:, keep], atol=TOL)
    assert np.isfinite(m.joints).all()
    with pytest.raises(MotionFormatError, match="leaves out"):
        load_bvh(path, joint_map={k: v for k, v in full.items() if k != "head"})
    with pytest.raises(MotionFormatError, match="not in the file"):
        load_bvh(path, joint_map={**full, "neck": "Nope"})
    with pytest.raises(MotionFormatError, match="both strings"):
        load_bvh(path, joint_map={**full, "neck": 3})
    with pytest.raises(MotionFormatError, match="not SMPL-X body joints"):
        load_bvh(path, joint_map={**full, "jaw": "bone00"})


def test_bvh_bad_input(tmp_path, motion):
    go, bp, tr, betas, _ = motion
    good = _write_bvh(tmp_path / "g.bvh", _smplx_skeleton(betas), go, bp, tr, betas).read_text()
    cases = {
        "text.bvh": ("hello world", "not a BVH"),
        "short.bvh": (good.rsplit("\n", 3)[0], "motion values"),
        "chan.bvh": (good.replace("Zrotation", "Wrotation", 1), "unknown channel"),
        "time.bvh": (good.replace("Frame Time: 0.03333333", "Frame Time: 0"), "Frame Time"),
        "tiny.bvh": (None, "length unit"),
    }
    for name, (text, match) in cases.items():
        path = tmp_path / name
        if text is None:  # a 2 mm person: no unit makes sense
            _write_bvh(path, _smplx_skeleton(betas), go, bp, tr, betas, scale=0.002)
        else:
            path.write_text(text)
        with pytest.raises(MotionFormatError, match=match) as err:
            load_motion(path)
        assert str(path) in str(err.value)
    (tmp_path / "bin.bvh").write_bytes(b"\xff\xfe\x00\x81" * 10)
    with pytest.raises(MotionFormatError, match="not a BVH"):
        load_bvh(tmp_path / "bin.bvh")
    with pytest.raises(MotionFormatError, match="up must be"):
        load_bvh(tmp_path / "g.bvh", up="x")
    with pytest.raises(MotionFormatError, match="unit must be"):
        load_bvh(tmp_path / "g.bvh", unit=-1)


# --------------------------------------------------------------------------- HumanML3D
def _humanml3d(root: Path, ref: np.ndarray) -> Path:
    (root / "new_joints").mkdir(parents=True)
    (root / "texts").mkdir()
    for mid, j in (("000001", ref), ("M000001", ref * [-1, 1, 1])):
        np.save(root / "new_joints" / f"{mid}.npy", (j @ Z_TO_Y.T).astype(np.float32))
    (root / "texts" / "000001.txt").write_text(
        "a person walks forward.#a/DET person/NOUN walk/VERB forward/ADV#0.0#0.0\n"
        "someone strides ahead#someone/PRON stride/VERB ahead/ADV#0.0#0.0\n"
        "\n"
        "the person raises a hand#the/DET person/NOUN raise/VERB a/DET hand/NOUN#0.05#0.2\n")
    (root / "train.txt").write_text("000001\nM000001\n")
    (root / "test.txt").write_text("\n")
    return root


def test_humanml3d(tmp_path):
    rng = np.random.default_rng(1)
    ref = rng.normal(size=(T, 22, 3)).astype(np.float32)
    root = _humanml3d(tmp_path / "HumanML3D", ref)
    m = load_motion(root / "new_joints" / "000001.npy")
    assert m.fps == 20.0 and m.info["id"] == "000001" and not m.has_smplx
    np.testing.assert_allclose(m.joints, ref, atol=1e-6)
    assert m.texts == ("a person walks forward.", "someone strides ahead",
                       "the person raises a hand")
    assert m.text_spans == ((0.0, 0.25), (0.0, 0.25), (0.05, 0.2))
    same = load_motion(root, format="humanml3d", motion_id="000001")
    np.testing.assert_array_equal(same.joints, m.joints)
    mirrored = load_humanml3d(root / "new_joints" / "M000001.npy")
    assert mirrored.texts == ()  # no caption file: no captions
    clips = caption_clips(m)
    assert [c.texts for c in clips] == [m.texts[:2], m.texts[2:]]
    assert clips[0].num_frames == T and clips[1].num_frames == 3  # frames [1, 4)
    np.testing.assert_array_equal(clips[1].joints, m.joints[1:4])
    up = load_humanml3d(root / "new_joints" / "000001.npy", fps=40)
    assert up.num_frames == 2 * T - 1
    np.testing.assert_allclose(up.joints[1], (ref[0] + ref[1]) / 2, atol=1e-6)
    assert load_split(root, "train") == ["000001", "M000001"] and load_split(root, "test") == []


def test_humanml3d_bad_input(tmp_path):
    root = _humanml3d(tmp_path / "h", np.zeros((T, 22, 3), np.float32))
    np.save(root / "new_joints" / "vecs.npy", np.zeros((T, 263), np.float32))
    with pytest.raises(MotionFormatError, match="new_joint_vecs"):
        load_motion(root / "new_joints" / "vecs.npy")
    (root / "texts" / "000001.txt").write_text("just a caption without tags\n")
    with pytest.raises(MotionFormatError, match=r"000001.txt:1: expected"):
        load_motion(root / "new_joints" / "000001.npy")
    with pytest.raises(MotionFormatError, match="no such split list"):
        load_split(root, "val")
    with pytest.raises(MotionFormatError, match="no such file"):
        load_humanml3d(root, "999999")
    (root / "new_joints" / "bad.npy").write_bytes(b"not numpy")
    with pytest.raises(MotionFormatError, match="not a readable"):
        load_motion(root / "new_joints" / "bad.npy")


# --------------------------------------------------------------------------- AMASS
def test_amass_smplh_and_smplx(tmp_path, motion):
    go, bp, tr, betas, ref = motion
    rng = np.random.default_rng(2)
    betas16 = np.concatenate([betas, rng.normal(size=6)])
    hands = rng.normal(size=(T, 90))
    smplh = tmp_path / "01_01_poses.npz"
    np.savez(smplh, poses=np.concatenate([go, bp.reshape(T, 63), hands], 1), trans=tr,
             betas=betas16, mocap_framerate=np.array(120.0), gender=np.array("male"))
    m = load_motion(smplh)
    assert m.fps == 120.0 and m.info["model"] == "SMPL+H" and m.info["gender"] == "male"
    np.testing.assert_allclose(m.joints, ref, atol=TOL)
    np.testing.assert_allclose(m.body_pose, bp, atol=1e-6)
    np.testing.assert_allclose(m.betas, betas, atol=1e-6)
    np.testing.assert_allclose(load_amass(smplh, fps=40).joints, ref[::3], atol=TOL)

    smplx = tmp_path / "walk_stageii.npz"
    poses = np.concatenate([go, bp.reshape(T, 63), rng.normal(size=(T, 99))], 1)
    np.savez(smplx, poses=poses, root_orient=go, pose_body=bp.reshape(T, 63), trans=tr,
             betas=betas16, mocap_frame_rate=np.array(60.0), gender=np.array(b"female"))
    m = load_motion(smplx)
    assert m.fps == 60.0 and m.info["model"] == "SMPL-X" and m.info["gender"] == "female"
    np.testing.assert_allclose(m.joints, ref, atol=TOL)
    only_poses = tmp_path / "p.npz"
    np.savez(only_poses, poses=poses, trans=tr, betas=betas16, mocap_frame_rate=60)
    np.testing.assert_allclose(load_amass(only_poses).joints, ref, atol=TOL)
    # resampling interpolates the rotations too: the half-way frame is a valid body
    half = load_amass(only_poses, fps=90)
    assert half.num_frames == 1 + (T - 1) * 3 // 2
    np.testing.assert_allclose(half.joints[::3], ref[::2], atol=TOL)


def test_amass_bad_input(tmp_path, motion):
    _go, _bp, tr, betas, _ = motion
    cases = {
        "shape.npz": ({"betas": betas, "gender": np.array("male")}, "subject shape file"),
        "w.npz": ({"poses": np.zeros((T, 100)), "trans": tr, "mocap_framerate": 30}, "156"),
        "r.npz": ({"poses": np.zeros((T, 156)), "trans": tr}, "frame rate"),
        "n.npz": ({"poses": np.full((T, 156), np.nan), "trans": tr, "mocap_framerate": 30}, "NaN"),
        "t.npz": ({"poses": np.zeros((T, 156)), "trans": tr[:2], "mocap_framerate": 30}, "156"),
    }
    for name, (arrays, match) in cases.items():
        np.savez(tmp_path / name, **arrays)
        with pytest.raises(MotionFormatError, match=match) as err:
            load_motion(tmp_path / name)
        assert name in str(err.value)
    # an object array (needs pickle) where only the gender would be: read without it
    np.savez(tmp_path / "o.npz", poses=np.zeros((T, 156)), trans=tr, mocap_framerate=30,
             gender=np.array([{"x": 1}], dtype=object))
    assert "gender" not in load_amass(tmp_path / "o.npz").info
    (tmp_path / "z.npz").write_bytes(b"PK not a zip")
    with pytest.raises(MotionFormatError, match="not a readable"):
        load_motion(tmp_path / "z.npz")


# --------------------------------------------------------------------------- HUMANISE
def _rot_z(a):
    return np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]])


def test_humanise_original_layout(tmp_path, motion):
    go, bp, tr, betas, ref = motion
    rng = np.random.default_rng(3)
    root = tmp_path / "HUMANISE"
    mfile = root / "pure_motion" / "sit" / "00007" / "motion.pkl"
    mfile.parent.mkdir(parents=True)
    joints127 = np.concatenate([ref, np.zeros((T, 105, 3))], 1)
    with open(mfile, "wb") as f:
        pickle.dump(("neutral", tr, go, np.r_[betas, np.zeros(6)], bp.reshape(T, 63),
                     rng.normal(size=(T, 90)), np.zeros((T, 3)), np.zeros((T, 6)), joints127), f)
    anno = root / "align_data_release" / "sit" / "scene0001_00_7" / "anno.pkl"
    anno.parent.mkdir(parents=True)
    entries = [{"action": "sit", "motion": "/their/disk/HUMANISE/pure_motion/sit/00007/motion.pkl",
                    "scene": "scene0001_00", "scene_translation": np.array([-1.0, -2.0, 0.0]),
                    "translation": np.array([1.5, 0.5, 0.1]), "rotation": np.float64(0.7),
                    "utterance": "sit on the chair near the desk", "object_id": np.int64(12),
                    "object_label": "chair", "object_semantic_label": 5}]
    with open(anno, "wb") as f:
        pickle.dump(entries, f)
    m = load_motion(anno)
    p = np.r_[ref[-1, 0, :2], 0.0]  # sit: the anchor is the last frame
    want = (ref - p) @ _rot_z(0.7).T + [1.5, 0.5, 0.1]
    np.testing.assert_allclose(m.joints, want, atol=TOL)
    np.testing.assert_allclose(smplx_joints_host(m.global_orient, m.body_pose, m.transl, m.betas),
                               want, atol=TOL)
    assert m.texts == ("sit on the chair near the desk",) and m.fps == 30.0
    assert m.info["object_id"] == 12 and m.info["scene"] == "scene0001_00"
    assert m.info["scene_translation"] == [-1.0, -2.0, 0.0]
    raw = load_humanise(mfile)
    np.testing.assert_allclose(raw.joints, ref, atol=TOL)
    with pytest.raises(MotionFormatError, match="index=3"):
        load_humanise(anno, index=3)


def test_humanise_reformatted_layout(tmp_path, motion):
    go, bp, tr, betas, ref = motion
    (tmp_path / "motions").mkdir()
    arr = np.concatenate([tr, go, bp.reshape(T, 63), np.zeros((T, 90))], 1)
    with open(tmp_path / "motions" / "000003.pkl", "wb") as f:
        pickle.dump((arr.astype(np.float32), betas.astype(np.float32)), f)
    (tmp_path / "annotation.csv").write_text(
        "motion_id,scene_id,scene_trans_x,scene_trans_y,scene_trans_z,object_id,object_label,"
        "object_semantic_label,action,text\n"
        "3,scene0002_00,-1.5,-2,0,4,bed,4,lie,lie down on the bed\n")
    m = load_motion(tmp_path / "motions" / "000003.pkl")
    np.testing.assert_allclose(m.joints, ref, atol=TOL)
    assert m.texts == ("lie down on the bed",) and m.info["action"] == "lie"
    assert m.info["scene_translation"] == [-1.5, -2.0, 0.0] and m.info["scene_id"] == "scene0002_00"


def test_humanise_pickle_is_restricted(tmp_path):
    import collections

    path = tmp_path / "motions" / "000001.pkl"
    path.parent.mkdir()
    with open(path, "wb") as f:
        pickle.dump((collections.Counter(), np.zeros(10)), f)
    with pytest.raises(MotionFormatError, match="only NumPy arrays"):
        load_motion(path)
    with pytest.raises(MotionFormatError, match=r"\[L, 159\]"):
        load_humanise(path, trust_pickle=True)
    path.write_bytes(b"not a pickle at all")
    with pytest.raises(MotionFormatError, match="not a readable pickle"):
        load_motion(path)
    with open(path, "wb") as f:
        pickle.dump([{"action": "sit"}], f)
    anno = tmp_path / "anno.pkl"
    path.rename(anno)
    with pytest.raises(MotionFormatError, match="lacks"):
        load_motion(anno)


# --------------------------------------------------------------------------- load_motion
def test_load_motion_dispatch_errors(tmp_path):
    (tmp_path / "a.fbx").write_text("x")
    with pytest.raises(MotionFormatError, match="unknown motion file type"):
        load_motion(tmp_path / "a.fbx")
    with pytest.raises(MotionFormatError, match="a folder"):
        load_motion(tmp_path)
    with pytest.raises(MotionFormatError, match="unknown format"):
        load_motion(tmp_path / "a.fbx", format="fbx")
    with pytest.raises(MotionFormatError, match=r"\['unit'\] do not apply to amass"):
        load_motion(tmp_path / "a.npz", unit=0.01)
    with pytest.raises(MotionFormatError, match="no such file"):
        load_motion(tmp_path / "missing.bvh")


def test_motion_validation_and_slicing():
    j = np.zeros((4, 22, 3))
    with pytest.raises(ValueError, match="together"):
        Motion(joints=j, fps=30, global_orient=np.zeros((4, 3)))
    with pytest.raises(ValueError, match="fps"):
        Motion(joints=j, fps=0)
    with pytest.raises(ValueError, match=r"\[T >= 1, 22, 3\]"):
        Motion(joints=np.zeros((4, 24, 3)), fps=30)
    m = Motion(joints=j, fps=2, texts=("all", "part"), text_spans=((0, 1.5), (1.0, 1.5)))
    assert m.joints.flags.writeable is False and m.duration == 1.5
    assert m.frames(2, 4).texts == ("all", "part") and m.frames(0, 2).texts == ("all",)


# --------------------------------------------------------------------------- convert
def _walk(t, fps, seed=0):
    """A smooth upright SMPL-X motion (z-up, walking along x at 1 m/s, neutral body)."""
    rng = np.random.default_rng(seed)
    s = np.arange(t)[:, None] / fps
    go = np.tile([np.pi / 2, 0.0, 0.0], (t, 1))  # stand up, facing -y
    bp = 0.2 * np.sin(2 * np.pi * s[..., None] + rng.uniform(0, 6, (1, 21, 3)))
    tr = np.concatenate([s, 0 * s, 0 * s + 0.5], 1)
    return go, bp, tr


def _mtimes(root):
    return {p: p.stat().st_mtime_ns for p in sorted((root / "samples").rglob("*.npz"))}


def test_convert_humanml3d_resumable(tmp_path):
    from jaxmotion.data import Dataset, DatasetError, load_sample
    from jaxmotion.io.convert import convert

    src = tmp_path / "HumanML3D"
    (src / "new_joints").mkdir(parents=True)
    (src / "texts").mkdir()
    joints = {}
    for mid, t in (("000001", 150), ("000002", 60)):
        joints[mid] = smplx_joints_host(*_walk(t, 20.0))
        np.save(src / "new_joints" / f"{mid}.npy", (joints[mid] @ Z_TO_Y.T).astype(np.float32))
    (src / "texts" / "000001.txt").write_text("a person walks#a/DET person/NOUN#0.0#0.0\n"
                                              "someone walks#someone/PRON#0.0#0.0\n")
    (src / "texts" / "000002.txt").write_text("walk forward#walk/VERB#0.0#0.0\n"
                                              "take a step#take/VERB#0.5#2.0\n")
    (src / "train.txt").write_text("000001\n")
    (src / "test.txt").write_text("000002\n")
    out = tmp_path / "data"
    m = convert("humanml3d", src, out, fit_iters=0, stats=False, progress=False)
    # 000001: 7.45 s -> 224 frames at 30 fps -> two clips; 000002: the whole clip + the span
    assert m["samples"] == {"train": 2, "val": 0, "test": 2} and m["sources"]["failed"] == 0
    assert m["smplx_fit_error_m"] < 1e-3 and "walk" in m["rules"]["action"]
    ds = Dataset(out, "train")
    ex = ds.host_batch([0, 1], np.random.default_rng(0))
    assert ex["joints"].shape == (2, 120, 22, 3) and ex["mask"].sum() == 224
    assert ex["text"] == ["a person walks"] * 2
    s = load_sample(ds.files[0])
    assert s["fps"] == 30.0 and s["action"] == "walk" and s["target_id"] == -1
    src30 = Motion(joints=joints["000001"], fps=20.0).resampled(30.0).joints[:112]
    np.testing.assert_allclose(s["joints"] - s["joints"][0, 0], src30 - src30[0, 0], atol=1e-5)
    feet = min(load_sample(f)["joints"][:, 10:12, 2].min() for f in ds.files)
    assert feet == pytest.approx(0.025, abs=1e-6)  # the motion's lowest foot joint, as synth
    fk = smplx_joints_host(s["global_orient"], s["body_pose"], s["transl"], s["betas"])
    np.testing.assert_allclose(fk, s["joints"], atol=5e-3)  # 20 -> 30 fps lerp shortens bones
    test = sorted(load_sample(f)["text"] for f in Dataset(out, "test").files)
    assert test == ["take a step", "walk forward"]
    # resuming writes nothing new; other settings are refused
    before = _mtimes(out)
    again = convert("humanml3d", src, out, fit_iters=0, stats=False, progress=False)
    assert again["sources"]["converted_this_run"] == 0 and again["samples"] == m["samples"]
    assert _mtimes(out) == before
    with pytest.raises(DatasetError, match="other settings"):
        convert("humanml3d", src, out, fit_iters=0, action="sit", stats=False, progress=False)


def test_convert_amass_and_bvh_from_the_command_line(tmp_path, capsys):
    from jaxmotion.cli import main
    from jaxmotion.data import Dataset, load_manifest, load_sample
    from jaxmotion.export import write_bvh

    amass = tmp_path / "amass" / "CMU" / "01"
    amass.mkdir(parents=True)
    go, bp, tr = _walk(200, 120.0)
    betas = np.r_[np.linspace(-1, 1, 10), np.zeros(6)]
    np.savez(amass / "01_01_poses.npz", poses=np.concatenate([go, bp.reshape(200, 63),
                                                              np.zeros((200, 90))], 1),
             trans=tr, betas=betas, mocap_framerate=120.0, gender="male")
    np.savez(amass / "shape.npz", betas=betas, gender="male")  # a subject's shape: skipped
    out = tmp_path / "amass_data"
    rc = main(["data", "convert", "--from", "amass", str(tmp_path / "amass"), "--out", str(out),
               "--split", "train", "--no-stats"])
    assert rc == 0, capsys.readouterr().err
    man = load_manifest(out)
    assert man["samples"]["train"] == 1 and man["sources"]["total"] == 1
    s = load_sample(Dataset(out, "train").files[0])
    assert s["joints"].shape == (50, 22, 3) and s["text"] == ""
    np.testing.assert_allclose(s["body_pose"], bp[::4], atol=1e-6)
    np.testing.assert_allclose(s["betas"], betas[:10], atol=1e-6)
    np.testing.assert_allclose(smplx_joints_host(s["global_orient"], s["body_pose"], s["transl"],
                                                 s["betas"]), s["joints"], atol=TOL)

    bvh_dir = tmp_path / "bvh"
    go, bp, tr = _walk(90, 30.0)
    write_bvh(bvh_dir / "a.bvh", go, bp, tr, None, 30.0, scale=100)
    out = tmp_path / "bvh_data"
    rc = main(["data", "convert", "--from", "bvh", str(bvh_dir), "--out", str(out), "--split",
               "val", "--fit-iters", "0", "--action", "sit", "--no-stats"])
    assert rc == 0, capsys.readouterr().err
    s = load_sample(Dataset(out, "val").files[0])
    assert s["action"] == "sit" and s["joints"].shape == (90, 22, 3)
    np.testing.assert_allclose(s["joints"] - s["joints"][0, 0],
                               smplx_joints_host(go, bp, tr) - smplx_joints_host(go, bp, tr)[0, 0],
                               atol=TOL)
    capsys.readouterr()
    assert main(["data", "convert", "--from", "bvh", str(tmp_path / "nope"), "--out",
                 str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "no such file or folder" in err[0]
    assert main(["data", "convert", "--from", "amass", str(bvh_dir), "--out", str(out),
                 "--unit", "0.01"]) == 2
    assert "BVH and glTF files only" in capsys.readouterr().err
