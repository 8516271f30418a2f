"""BVH files in the conventions of real mocap releases, written here by hand in miniature.

The layouts reproduce two public files the reader was checked on (docs/results.md, "Real
mocap through the BVH reader"): a Mixamo export (``mixamorig:`` names, ``Zrotation Yrotation
Xrotation`` on every joint, extra leaf joints such as ``HeadTop_End`` and the eyes, toes
ending in an ``End Site``, centimetres, ``Frame Time: 0.0333333``) and a MocapBank take
(``Hips, Chest, Chest2, LeftCollar, LeftShoulder, LeftElbow, LeftWrist, Neck, Head, LeftHip,
LeftKnee, LeftAnkle``, ``Zrotation Xrotation Yrotation``, no toe joint: the foot is the
ankle's ``End Site``, tab-separated ``Frames:``). Offsets are round numbers chosen here, and
the expected positions are worked out by hand from them.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from jaxmotion.data.clip_placement import heading
from jaxmotion.export import read_bvh
from jaxmotion.geometry import JOINT_NAMES
from jaxmotion.io import MotionFormatError, bvh_world_positions, load_bvh, load_motion

J = {n: i for i, n in enumerate(JOINT_NAMES)}


def _node(name, offset, children=(), end=None, channels=None):
    return {"name": name, "offset": offset, "children": list(children), "end": end,
            "channels": channels}


def _bvh_text(root, frames, frame_time, rot, root_channels, tab="\t", frames_sep=" "):
    """BVH text of the tree ``root``: the root has ``root_channels``, other joints the
    rotation channels ``rot`` (e.g. "ZXY"); ``frames`` are ``{joint name: values}`` rows
    (missing joints: zeros)."""
    lines, order = ["HIERARCHY"], []

    def emit(node, depth):
        pad = tab * depth
        chans = node["channels"] or (root_channels if depth == 0 else
                                     [f"{a}rotation" for a in rot])
        order.append((node["name"], len(chans)))
        lines.extend([f"{pad}{'ROOT' if depth == 0 else 'JOINT'} {node['name']}", f"{pad}{{",
                      f"{pad}{tab}OFFSET{tab}" + tab.join(f"{v:.4f}" for v in node["offset"]),
                      f"{pad}{tab}CHANNELS {len(chans)} {' '.join(chans)}"])
        for c in node["children"]:
            emit(c, depth + 1)
        if node["end"] is not None:
            lines.extend([f"{pad}{tab}End Site", f"{pad}{tab}{{",
                          f"{pad}{tab}{tab}OFFSET " + " ".join(f"{v:.4f}" for v in node["end"]),
                          f"{pad}{tab}}}"])
        lines.append(f"{pad}}}")

    emit(root, 0)
    lines += ["MOTION", f"Frames:{frames_sep}{len(frames)}", f"Frame Time:{frames_sep}{frame_time}"]
    for row in frames:
        vals = []
        for name, n in order:
            vals += list(row.get(name, [0.0] * n))
        lines.append(" ".join(f"{v:.4f}" for v in vals))
    return "\n".join(lines) + "\n"


# ----------------------------------------------------------------------------- MocapBank
def _mocapbank_tree(chest2=True, toes=False):
    """A MocapBank skeleton, centimetres, y up, facing +z (left = +x)."""
    def arm(side, s):
        return _node(f"{side}Collar", (0, 17, 0), [
            _node(f"{side}Shoulder", (s * 16, -3, 2), [
                _node(f"{side}Elbow", (s * 2, -25, 2), [
                    _node(f"{side}Wrist", (s * 2, -22, 1), end=(s * 1, -14, 1))])])])

    def leg(side, s):
        toe = [_node(f"{side}Toe", (s * 1, -6, 14), end=(0, 0, 5))] if toes else []
        return _node(f"{side}Hip", (s * 9 + (s < 0) * -1, 0, 3), [
            _node(f"{side}Knee", (0, -48, 0), [
                _node(f"{side}Ankle", (0, -38, -4), toe,
                      end=None if toes else (s * 1, -7, 18))])])

    upper = [arm("Left", 1), arm("Right", -1),
             _node("Neck", (0, 17, 0), [_node("Head", (0, 11, 5), end=(0, 18, 0))])]
    chest = (_node("Chest", (0, 10, 0), [_node("Chest2", (0, 16, -2), upper)]) if chest2 else
             _node("Chest", (0, 10, 0), upper))
    return _node("Hips", (0, 0, 0), [chest, leg("Left", 1), leg("Right", -1)])


MB_ROOT = ["Xposition", "Yposition", "Zposition", "Zrotation", "Xrotation", "Yrotation"]


def _mocapbank_file(path, frames, **tree):
    path.write_text(_bvh_text(_mocapbank_tree(**tree), frames, "0.033333", "ZXY", MB_ROOT,
                              tab="  ", frames_sep="\t"))
    return path


def _y_to_z(p):
    """A y-up point (cm) in the z-up world (m): (x, y, z) -> (x, -z, y)."""
    return np.array([p[0], -p[2], p[1]]) / 100.0


STAND = {"Hips": [0, 93, 0, 0, 0, 0]}
# the left ankle turned +90 deg about x (channels Z X Y): its toe End Site (1, -7, 18)
# becomes (1, -18, -7), the toe pointing down
ANKLE_X90 = {"Hips": [0, 93, 0, 0, 0, 0], "LeftAnkle": [0, 90, 0]}
# the root turned +90 deg about y: the body faces +x in the file and in the z-up world
TURNED = {"Hips": [0, 93, 0, 0, 0, 90]}


def test_read_bvh_keeps_end_sites(tmp_path):
    path = _mocapbank_file(tmp_path / "mb.bvh", [STAND])
    bvh = read_bvh(path)
    assert len(bvh.names) == 19 and len(bvh.end_sites) == 5
    ends = {bvh.names[p]: off for p, off in bvh.end_sites}
    assert ends["LeftAnkle"] == (1.0, -7.0, 18.0) and ends["Head"] == (0.0, 18.0, 0.0)
    pos = bvh_world_positions(bvh, end_sites=True)
    assert pos.shape == (1, 24, 3)
    np.testing.assert_allclose(bvh_world_positions(bvh), pos[:, :19])


def test_mocapbank_skeleton_reads_with_the_built_in_map(tmp_path):
    path = _mocapbank_file(tmp_path / "mb.bvh", [STAND, ANKLE_X90, TURNED])
    m = load_motion(path)
    assert m.info["joint_map"] == "mocapbank" and m.info["unit"] == pytest.approx(0.01)
    assert m.fps == 30.0 and m.joints.shape == (3, 22, 3)
    j = np.asarray(m.joints, np.float64)
    # standing: the feet are the ankles' End Sites (toe tips on the floor), the knees and
    # ankles the named joints
    np.testing.assert_allclose(j[0, J["l_foot"]], _y_to_z([10, 0, 17]), atol=1e-6)
    np.testing.assert_allclose(j[0, J["r_foot"]], _y_to_z([-11, 0, 17]), atol=1e-6)
    np.testing.assert_allclose(j[0, J["l_ankle"]], _y_to_z([9, 7, -1]), atol=1e-6)
    np.testing.assert_allclose(j[0, J["head"]], _y_to_z([0, 147, 3]), atol=1e-6)
    np.testing.assert_allclose(j[0, J["spine2"]], _y_to_z([0, 119, -2]), atol=1e-6)
    np.testing.assert_allclose(j[0, J["l_shoulder"]], _y_to_z([16, 133, 0]), atol=1e-6)
    # left is +x, the body faces -y (a y-up file's +z), toes forward of the ankles
    assert j[0, J["l_hip"], 0] > 0 > j[0, J["r_hip"], 0]
    assert heading(j[0]) == pytest.approx(-np.pi / 2, abs=1e-6)
    assert j[0, J["l_foot"], 1] < j[0, J["l_ankle"], 1]
    # the collars are not MocapBank's (which sit on the neck): filled in on their chain
    assert np.linalg.norm(j[0, J["l_collar"]] - j[0, J["neck"]]) > 0.03
    assert 0 < j[0, J["l_collar"], 0] < j[0, J["l_shoulder"], 0]
    # the End Site follows its joint's rotation
    np.testing.assert_allclose(j[1, J["l_foot"]], _y_to_z([10, -11, -8]), atol=1e-6)
    np.testing.assert_allclose(j[1, J["r_foot"]], j[0, J["r_foot"]], atol=1e-6)
    # the root's turn turns the facing
    assert heading(j[2]) == pytest.approx(0.0, abs=1e-6)
    # bone lengths do not change over frames
    from jaxmotion.geometry import PARENTS
    bones = np.linalg.norm(j[:, 1:] - j[:, list(PARENTS[1:])], axis=-1)
    assert np.ptp(bones, axis=0).max() < 1e-6


def test_mocapbank_variants(tmp_path):
    # no Chest2: spine2 is filled in between Chest and Neck
    m = load_bvh(_mocapbank_file(tmp_path / "a.bvh", [STAND], chest2=False))
    assert m.info["joint_map"] == "mocapbank"
    j = np.asarray(m.joints[0], np.float64)
    assert j[J["spine1"], 2] < j[J["spine2"], 2] < j[J["spine3"], 2] < j[J["neck"], 2]
    # toe joints: the foot is the toe joint, not its End Site
    m = load_bvh(_mocapbank_file(tmp_path / "b.bvh", [STAND], toes=True))
    np.testing.assert_allclose(m.joints[0, J["l_foot"]], _y_to_z([10, 1, 13]), atol=1e-6)
    # a user map may name an End Site: "<parent>_End"
    path = _mocapbank_file(tmp_path / "c.bvh", [STAND])
    mapping = {"pelvis": "Hips", "head": "Head_End", "l_foot": "LeftAnkle_End",
               "r_foot": "RightAnkle_End", "l_wrist": "LeftWrist", "r_wrist": "RightWrist"}
    (tmp_path / "map.json").write_text(json.dumps(mapping))
    m = load_bvh(path, joint_map=tmp_path / "map.json")
    np.testing.assert_allclose(m.joints[0, J["head"]], _y_to_z([0, 165, 3]), atol=1e-6)
    np.testing.assert_allclose(m.joints[0, J["l_foot"]], _y_to_z([10, 0, 17]), atol=1e-6)


def test_built_in_map_that_does_not_fit_names_what_is_missing(tmp_path):
    path = _mocapbank_file(tmp_path / "mb.bvh", [STAND])
    with pytest.raises(MotionFormatError, match="built-in joint map 'mixamo'.*not in the file"):
        load_bvh(path, joint_map="mixamo")


# ----------------------------------------------------------------------------- Mixamo
def _mixamo_tree(p="mixamorig:"):
    """A Mixamo export's skeleton (centimetres, y up, facing +z), with its extra leaves."""
    def arm(side, s):
        fingers = [_node(f"{p}{side}HandIndex1", (s * 12, -1, 4), end=(s * 3, -1, 0))]
        return _node(f"{p}{side}Shoulder", (s * 6, 9, 1), [
            _node(f"{p}{side}Arm", (s * 13, 0, -3), [
                _node(f"{p}{side}ForeArm", (s * 27, 0, -1), [
                    _node(f"{p}{side}Hand", (s * 28, 0, 2), fingers)])])])

    def leg(side, s):
        return _node(f"{p}{side}UpLeg", (s * 9, -7, 0), [
            _node(f"{p}{side}Leg", (0, -41, -2), [
                _node(f"{p}{side}Foot", (0, -42, -3), [
                    _node(f"{p}{side}ToeBase", (0, -10, 13), end=(0, 0, 10))])])])

    head = _node(f"{p}Head", (0, 10, 3), [
        _node(f"{p}HeadTop_End", (0, 18, 7), end=(0, 0, 0)),
        _node(f"{p}LeftEye", (3, 8, 9), end=(0, 0, 0)),
        _node(f"{p}RightEye", (-3, 8, 9), end=(0, 0, 0))])
    spine = _node(f"{p}Spine", (0, 10, -1), [_node(f"{p}Spine1", (0, 12, -1), [
        _node(f"{p}Spine2", (0, 13, -2), [_node(f"{p}Neck", (0, 15, 1), [head]),
                                          arm("Left", 1), arm("Right", -1)])])])
    return _node(f"{p}Hips", (0, 0, 0), [spine, leg("Right", -1), leg("Left", 1)])


def test_mixamo_export_layout(tmp_path):
    root = ["Xposition", "Yposition", "Zposition", "Zrotation", "Yrotation", "Xrotation"]
    frames = [{"mixamorig:Hips": [0, 100, 0, 0, 0, 0]},
              {"mixamorig:Hips": [0, 100, 0, 0, 90, 0]}]  # Z Y X: turned +90 deg about y
    path = tmp_path / "mixamo.bvh"
    path.write_text(_bvh_text(_mixamo_tree(), frames, "0.0333333", "ZYX", root))
    m = load_motion(path)
    assert m.info["joint_map"] == "mixamo" and m.info["unit"] == pytest.approx(0.01)
    assert m.fps == 30.0
    j = np.asarray(m.joints, np.float64)
    # the feet are the ToeBase joints (not their End Sites), on the floor
    np.testing.assert_allclose(j[0, J["l_foot"]], _y_to_z([9, 0, 8]), atol=1e-6)
    np.testing.assert_allclose(j[0, J["head"]], _y_to_z([0, 160, 0]), atol=1e-6)
    assert heading(j[0]) == pytest.approx(-np.pi / 2, abs=1e-6)
    assert heading(j[1]) == pytest.approx(0.0, abs=1e-6)
    assert j[0, J["l_collar"], 0] > 0 and j[0, J["l_wrist"], 0] > 0.5


# ----------------------------------------------------------------------------- Character Creator
# Reallusion Character Creator / iClone exports (the CMU takes retargeted in iClone are
# published so): ``CC_Base_`` names, twist, share, toe and face bones, 60 fps
# (``Frame Time: 0.016667``), centimetres. Two layouts: the hip as the root (y up), or a
# ``RL_BoneRoot`` root turned -90 deg about x over a z-up rig whose hip has no position
# channels.
def _cc_tree(rl_root=False):
    """A CC skeleton (cm, facing +z, left = +x); with ``rl_root`` the same body in a z-up rig
    under ``RL_BoneRoot`` (every offset (a, b, c) written (a, -c, b))."""
    def o(a, b, c):
        return (a, -c, b) if rl_root else (a, b, c)

    def arm(s, x):
        return _node(f"CC_Base_{s}_Clavicle", o(x * 6, 21, 0), [
            _node(f"CC_Base_{s}_Upperarm", o(x * 12, 0, 0), [
                _node(f"CC_Base_{s}_UpperarmTwist01", o(x * 10, 0, 0), end=o(x * 10, 0, 0)),
                _node(f"CC_Base_{s}_Forearm", o(x * 26, 0, 0), [
                    _node(f"CC_Base_{s}_Hand", o(x * 25, 0, 0), [
                        _node(f"CC_Base_{s}_Mid1", o(x * 8, 0, 0), end=o(x * 4, 0, 0))])])])])

    def leg(s, x):
        return _node(f"CC_Base_{s}_Thigh", o(x * 10, -2, 0), [
            _node(f"CC_Base_{s}_ThighTwist01", o(0, -10, 0), end=o(0, -10, 0)),
            _node(f"CC_Base_{s}_Calf", o(0, -45, 0), [
                _node(f"CC_Base_{s}_Foot", o(0, -45, 0), [
                    _node(f"CC_Base_{s}_ToeBaseShareBone", o(0, -8, 12), end=o(0, 0, 2)),
                    _node(f"CC_Base_{s}_ToeBase", o(0, -8, 12), [
                        _node(f"CC_Base_{s}_BigToe1", o(x * -2, 0, 3), end=o(0, 0, 2))])])])])

    head = _node("CC_Base_Head", o(0, 4, 0), [
        _node("CC_Base_FacialBone", o(0, 5, 3), end=o(0, 5, 0))])
    spine = _node("CC_Base_Waist", o(0, 8, 0), [_node("CC_Base_Spine01", o(0, 5, 0), [
        _node("CC_Base_Spine02", o(0, 14, 0), [
            _node("CC_Base_NeckTwist01", o(0, 27, 0), [
                _node("CC_Base_NeckTwist02", o(0, 4, 0), [head])]),
            arm("L", 1), arm("R", -1)])])])
    pelvis = _node("CC_Base_Pelvis", (0, 0, 0), [leg("L", 1), leg("R", -1)])
    rot = ["Zrotation", "Yrotation", "Xrotation"]
    if not rl_root:
        return _node("CC_Base_Hip", (0, 100, 0), [pelvis, spine])
    hip = _node("CC_Base_Hip", o(0, 100, 0), [pelvis, spine], channels=rot)
    return _node("RL_BoneRoot", (0, 0, 0), [hip])


def test_character_creator_layouts_read_with_the_built_in_map(tmp_path):
    root = ["Xposition", "Yposition", "Zposition", "Zrotation", "Yrotation", "Xrotation"]
    hip_root = tmp_path / "hip_root.bvh"
    hip_root.write_text(_bvh_text(_cc_tree(), [{"CC_Base_Hip": [0, 100, 0, 0, 0, 0]}] * 2,
                                  "0.016667", "ZYX", root, tab="    "))
    rl_root = tmp_path / "rl_root.bvh"
    rl_root.write_text(_bvh_text(_cc_tree(rl_root=True), [{"RL_BoneRoot": [0, 0, 0, 0, 0, -90]}]
                                 * 2, "0.016667", "ZYX", root, tab="    "))
    for path in (hip_root, rl_root):
        m = load_motion(path)
        assert m.info["joint_map"] == "cc" and m.info["unit"] == pytest.approx(0.01)
        assert m.fps == 60.0 and m.joints.shape == (2, 22, 3)
        j = np.asarray(m.joints[0], np.float64)
        # the foot is the ToeBase joint (not the share bone's or the big toe's End Site)
        expected = {"pelvis": (0, 100, 0), "l_hip": (10, 98, 0), "l_knee": (10, 53, 0),
                    "l_ankle": (10, 8, 0), "l_foot": (10, 0, 12), "r_foot": (-10, 0, 12),
                    "spine1": (0, 113, 0), "spine2": (0, 127, 0), "neck": (0, 154, 0),
                    "head": (0, 162, 0), "l_collar": (6, 148, 0), "l_shoulder": (18, 148, 0),
                    "l_elbow": (44, 148, 0), "l_wrist": (69, 148, 0),
                    "r_wrist": (-69, 148, 0)}
        for name, y_up in expected.items():
            np.testing.assert_allclose(j[J[name]], _y_to_z(list(y_up)), atol=1e-6,
                                       err_msg=f"{path.name}: {name}")
        # spine3 has no CC joint: filled in between Spine02 and the neck
        assert j[J["spine2"], 2] < j[J["spine3"], 2] < j[J["neck"], 2]
        # left is +x and the body faces -y (the file's +z): not mirrored
        assert heading(j) == pytest.approx(-np.pi / 2, abs=1e-6)
        assert not m.info["rest_frame_dropped"]


# ----------------------------------------------------------------------------- CMU rest frame
# CMU conversions that put the rest pose (a T-pose: whole-number rotations, the root where the
# capture starts) before the capture as frame 0, in the cgspeed skeleton (``Hips, LHipJoint,
# LeftUpLeg, ..., LowerBack, Spine, Spine1, Neck, Neck1, Head, LeftShoulder, LeftArm, ...``,
# ``Zrotation Yrotation Xrotation``, CMU units, ``Frame Time: .0083333`` without a leading 0).
def _cgspeed_tree():
    """A cgspeed-style CMU skeleton in CMU units (~5.6 cm), y up, facing +z (left = +x)."""
    def arm(side, s):
        return _node(f"{side}Shoulder", (0, 0, 0), [
            _node(f"{side}Arm", (s * 3, 1, 0), [_node(f"{side}ForeArm", (s * 5, 0, 0), [
                _node(f"{side}Hand", (s * 3, 0, 0), end=(s * 1, 0, 0))])])])

    def leg(side, s):
        return _node(f"{side[0]}HipJoint", (0, 0, 0), [
            _node(f"{side}UpLeg", (s * 2, -1, 0), [_node(f"{side}Leg", (0, -7, 0), [
                _node(f"{side}Foot", (0, -7, 0), [
                    _node(f"{side}ToeBase", (0, -1, 2), end=(0, 0, 1))])])])])

    neck = _node("Neck", (0, 0, 0), [_node("Neck1", (0, 2, 0), [
        _node("Head", (0, 2, 0), end=(0, 2, 0))])])
    back = _node("LowerBack", (0, 0, 0), [_node("Spine", (0, 2, 0), [
        _node("Spine1", (0, 2, 0), [neck, arm("Left", 1), arm("Right", -1)])])])
    return _node("Hips", (0, 0, 0), [leg("Left", 1), leg("Right", -1), back])


def _cgspeed_file(path, frames):
    root = ["Xposition", "Yposition", "Zposition", "Zrotation", "Yrotation", "Xrotation"]
    text = _bvh_text(_cgspeed_tree(), frames, "0.0083333", "ZYX", root)
    path.write_text(text.replace("Frame Time: 0.0083333", "Frame Time: .0083333"))
    return path


# seated: thighs forward (-90 deg about x), shins down (+90), the captured values have decimals
SEATED = {"Hips": [0.2, 9.1, 0.3, 0.0, 0.0, 0.0], "LeftUpLeg": [0.0, 0.0, -90.1],
          "RightUpLeg": [0.0, 0.0, -89.9], "LeftLeg": [0.0, 0.0, 90.2],
          "RightLeg": [0.0, 0.0, 89.8]}
# the rest pose before it: legs straight, arms down (whole numbers), at the seated root
REST = {"Hips": [0.2, 9.1, 0.3, 0, 0, 0], "LeftArm": [-80, 0, 0], "RightArm": [80, 0, 0]}


def _moved(row, dx):
    out = {k: list(v) for k, v in row.items()}
    out["Hips"][0] += dx
    return out


def test_leading_rest_pose_frame_is_dropped(tmp_path):
    capture = [SEATED, _moved(SEATED, 0.01), _moved(SEATED, 0.02)]
    path = _cgspeed_file(tmp_path / "111_10.bvh", [REST] + capture)
    m = load_motion(path)
    assert m.info["joint_map"] == "cmu" and m.info["unit"] == pytest.approx(0.056444)
    assert m.fps == 120.0 and m.info["rest_frame_dropped"] and m.num_frames == 3
    j = np.asarray(m.joints, np.float64)
    # the seated capture: hips at 9.1 units, thigh forward 7, shin down 7, toe 1 lower and 2
    # forward: the toe (2.2, 0.1, 9.3) units, on the floor (the rest pose's straight legs
    # reach 6.9 units, 39 cm, below it); the knees at seat height in front of the hips
    np.testing.assert_allclose(j[0, J["l_foot"]], _y_to_z([2.2, 0.11, 9.3]) * 5.6444,
                               atol=1e-3)
    assert j[0, J["l_knee"], 2] == pytest.approx(j[0, J["l_hip"], 2], abs=1e-3)
    assert j[0, J["l_knee"], 1] < j[0, J["l_hip"], 1] - 0.3
    # keep: every frame, the rest pose first (legs straight down, below the floor)
    kept = load_motion(path, first_frame="keep")
    assert kept.num_frames == 4 and not kept.info["rest_frame_dropped"]
    np.testing.assert_allclose(kept.joints[1:], m.joints, atol=1e-6)
    assert kept.joints[0, J["l_foot"], 2] < -0.05
    with pytest.raises(MotionFormatError, match="first_frame must be 'auto'.*or 'keep'"):
        load_motion(path, first_frame="drop")


def test_rest_frame_rule_keeps_real_first_frames(tmp_path):
    # every frame whole numbers (keyframed files, the tests' own): nothing dropped
    whole = [REST, {"Hips": [0, 16, 0, 0, 0, 0]}, {"Hips": [0, 16, 0, 0, 0, 5]}]
    assert load_motion(_cgspeed_file(tmp_path / "a.bvh", whole)).num_frames == 3
    # an animation that starts at the rest pose and moves on smoothly: frame 0 -> 1 is no jump
    smooth = [REST, {**REST, "LeftArm": [-79.7, 0.0, 0.0]}, {**REST, "LeftArm": [-79.4, 0.0, 0.0]}]
    m = load_motion(_cgspeed_file(tmp_path / "b.bvh", smooth))
    assert m.num_frames == 3 and not m.info["rest_frame_dropped"]
    # two frames: no second step to compare the jump with
    assert load_motion(_cgspeed_file(tmp_path / "c.bvh", [REST, SEATED])).num_frames == 2


# ----------------------------------------------------------------------------- z-up, inches
# A Vicon Shogun-style export (the layout of real 119.88 Hz captures: ``Hips, Spine, Spine1,
# Spine2, Spine3, Neck, Head, LeftShoulder, LeftArm, ..., LeftUpLeg, LeftLeg, LeftFoot,
# LeftToeBase``, ``Xrotation Yrotation Zrotation``, **z up**, **inches**, ``Frame Time:
# 0.008342``). Before, it was read y-up (lying on its back) and its size (61 inches from ankle
# to head) matched no unit.
def _shogun_tree():
    """Inches, z up, facing -y (left = +x): the y-up skeletons' body turned +90 deg about x."""
    def arm(side, s):
        return _node(f"{side}Shoulder", (s * 1, 0, 6), [
            _node(f"{side}Arm", (s * 5, 0, 0), [_node(f"{side}ForeArm", (s * 10, 0, 0), [
                _node(f"{side}Hand", (s * 9, 0, 0), end=(s * 3, 0, 0))])])])

    def leg(side, s):
        return _node(f"{side}UpLeg", (s * 3.5, 0, -2), [_node(f"{side}Leg", (0, 0, -17), [
            _node(f"{side}Foot", (0, 0, -16), [
                _node(f"{side}ToeBase", (0, -5, -2), end=(0, -2, 0))])])])

    neck = _node("Neck", (0, 0, 8), [_node("Head", (0, 0, 4), end=(0, 0, 5))])
    spine3 = _node("Spine3", (0, 0, 3), [neck, arm("Left", 1), arm("Right", -1)])
    spine = _node("Spine", (0, 0, 3), [_node("Spine1", (0, 0, 3), [
        _node("Spine2", (0, 0, 3), [spine3])])])
    return _node("Hips", (0, 0, 0), [spine, leg("Left", 1), leg("Right", -1)])


def test_z_up_inches_export(tmp_path):
    root = ["Xposition", "Yposition", "Zposition", "Xrotation", "Yrotation", "Zrotation"]
    rows = [{"Hips": [1.0, 2.0, 37.0, 0, 0, 0]}, {"Hips": [1.1, 2.0, 37.0, 0, 0, 45.0]},
            {"Hips": [1.2, 2.0, 37.0, 0, 0, 90.0]}]
    path = tmp_path / "tantrum.bvh"
    path.write_text(_bvh_text(_shogun_tree(), rows, "0.008342", "XYZ", root, tab="\t"))
    m = load_motion(path)
    assert m.info["up"] == "z" and m.info["unit"] == pytest.approx(0.0254)
    assert m.info["joint_map"] == "mixamo" and m.fps == pytest.approx(1 / 0.008342)
    j = np.asarray(m.joints, np.float64) / 0.0254  # back to inches, the file's axes kept
    # frame 0: pelvis at the root; toe 3.5 left, 5 forward (-y), 37 below the pelvis: on the
    # floor; head 24 above it; left wrist 25 to the left, 18 up
    np.testing.assert_allclose(j[0, J["pelvis"]], [1, 2, 37], atol=1e-3)
    np.testing.assert_allclose(j[0, J["l_foot"]], [4.5, -3, 0], atol=1e-3)
    np.testing.assert_allclose(j[0, J["head"]], [1, 2, 61], atol=1e-3)
    np.testing.assert_allclose(j[0, J["l_wrist"]], [26, 2, 55], atol=1e-3)
    # frame 2: the root turned 90 deg about z (up): the left wrist now on +y, the toes on +x
    np.testing.assert_allclose(j[2, J["l_wrist"]], [1.2, 27, 55], atol=1e-3)
    np.testing.assert_allclose(j[2, J["l_foot"]], [6.2, 5.5, 0], atol=1e-3)
    # up is detected, not assumed: the same body in a y-up file is still read y-up
    seated = load_motion(_cgspeed_file(tmp_path / "y.bvh", [SEATED, _moved(SEATED, 0.01)]))
    assert seated.info["up"] == "y"
    # up="y" given by hand is kept (the body then lies on its back, 1.55 m along -y)
    lying = load_motion(path, up="y")
    assert lying.info["up"] == "y"
    d = np.asarray(lying.joints[0, J["head"]] - lying.joints[0, J["pelvis"]])
    np.testing.assert_allclose(d, [0, -24 * 0.0254, 0], atol=1e-6)
    with pytest.raises(MotionFormatError, match="up must be 'auto', 'y' or 'z'"):
        load_motion(path, up="x")
