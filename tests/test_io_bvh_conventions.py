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
