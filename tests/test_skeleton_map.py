"""Automatic joint mapping (jaxmotion.io.skeleton_map): BVH skeletons named in the styles of
several studios and tools, written here from one body, read without a joint map.

Each convention below is one body (centimetres, y up, facing +z, left = +x) with the joint
names, helper bones and spine lengths of a naming style: the issue's 6-channel mocap style
(``UpperArm_L``), Unreal's Manny (``thigh_l``, ``spine_01..05``, twist bones), Unity's
humanoid (``LeftUpperLeg``), 3ds Max Biped (``Bip01_L_Thigh``), Blender's ``.L`` (``thigh.L``,
``shin.L``), MotionBuilder HumanIK (``Character1_LeftUpLeg``) and Rokoko (``LeftThigh``,
``LeftShin``). The names are written here from the conventions' public naming rules; no file
of theirs is copied.
"""

from __future__ import annotations

import numpy as np
import pytest

from jaxmotion.geometry import JOINT_NAMES
from jaxmotion.io import MotionFormatError, load_bvh
from jaxmotion.io.skeleton_map import auto_joint_map, parse_joint_name

J = {n: i for i, n in enumerate(JOINT_NAMES)}

# the body: role -> (parent role, offset cm); left side, the right mirrored in x
SPINE = [(0, 10, -1), (0, 12, 0), (0, 12, 1)]
LEFT = {"collar": ("top", (3, 10, 0)), "shoulder": ("collar", (12, 0, -1)),
        "elbow": ("shoulder", (26, 0, 0)), "wrist": ("elbow", (25, 0, 0)),
        "hip": ("pelvis", (9, -5, 0)), "knee": ("hip", (0, -42, 1)),
        "ankle": ("knee", (0, -40, -3)), "toe": ("ankle", (0, -7, 13))}


ROLES = ("collar", "shoulder", "elbow", "wrist", "hip", "knee", "ankle", "toe")


def _limbs(pattern, words):
    """``{role: (left name, right name)}``: ``pattern`` formatted with each role's word ``n``
    and the side as ``L`` (``L`` / ``R``), ``Left`` (``Left`` / ``Right``) or ``l``."""
    sides = ({"L": "L", "Left": "Left", "l": "l"}, {"L": "R", "Left": "Right", "l": "r"})
    return {r: tuple(pattern.format(n=n, **side) for side in sides)
            for r, n in zip(ROLES, words)}


def _convention(style):
    """``(spine names bottom-up, neck names, head, pelvis, {role: (left, right)}, root
    above the pelvis or None, helper bones [(parent role, name)], 6 channels everywhere)``."""
    if style == "issue":  # the example
        names = _limbs("{n}_{L}", ("Shoulder", "UpperArm", "LowerArm", "Hand", "UpperLeg",
                                   "LowerLeg", "Foot", "Toes"))
        return ["Spine", "Chest"], ["Neck"], "Head", "Hips", names, None, [], True
    if style == "ue5":
        names = _limbs("{n}_{l}", ("clavicle", "upperarm", "lowerarm", "hand", "thigh", "calf",
                                   "foot", "ball"))
        helpers = [("shoulder", "upperarm_twist_01_l"), ("elbow", "lowerarm_twist_01_l"),
                   ("hip", "thigh_twist_01_l"), ("knee", "calf_twist_01_l"),
                   ("shoulder_r", "upperarm_twist_01_r"), ("hip_r", "thigh_twist_01_r")]
        return ([f"spine_0{i}" for i in range(1, 6)], ["neck_01", "neck_02"], "head", "pelvis",
                names, "root", helpers, False)
    if style == "unity":
        names = _limbs("{Left}{n}", ("Shoulder", "UpperArm", "LowerArm", "Hand", "UpperLeg",
                                     "LowerLeg", "Foot", "Toes"))
        return ["Spine", "Chest", "UpperChest"], ["Neck"], "Head", "Hips", names, None, [], False
    if style == "biped":
        names = _limbs("Bip01_{L}_{n}", ("Clavicle", "UpperArm", "Forearm", "Hand", "Thigh",
                                         "Calf", "Foot", "Toe0"))
        return (["Bip01_Spine", "Bip01_Spine1", "Bip01_Spine2"], ["Bip01_Neck"], "Bip01_Head",
                "Bip01_Pelvis", names, "Bip01", [], False)
    if style == "blender":
        names = _limbs("{n}.{L}", ("shoulder", "upper_arm", "forearm", "hand", "thigh", "shin",
                                   "foot", "toe"))
        return ["spine", "chest"], ["neck"], "head", "hips", names, None, [], False
    if style == "humanik":
        names = _limbs("Character1_{Left}{n}", ("Shoulder", "Arm", "ForeArm", "Hand", "UpLeg",
                                                "Leg", "Foot", "ToeBase"))
        return (["Character1_Spine", "Character1_Spine1"], ["Character1_Neck"],
                "Character1_Head", "Character1_Hips", names, None, [], False)
    if style == "rokoko":
        names = _limbs("{Left}{n}", ("Shoulder", "Arm", "ForeArm", "Hand", "Thigh", "Shin",
                                     "Foot", "Toe"))
        return ["Spine1", "Spine2", "Spine3", "Spine4"], ["Neck"], "Head", "Hips", names, None, \
            [], False
    if style == "smplx":  # the reference: SMPL-X's own names (a built-in map)
        from jaxmotion.geometry import SMPLX_JOINT_NAMES

        sx = dict(zip(JOINT_NAMES, SMPLX_JOINT_NAMES))
        names = {r: (sx[f"l_{r}" if r != "toe" else "l_foot"],
                     sx[f"r_{r}" if r != "toe" else "r_foot"]) for r in LEFT}
        return [sx["spine1"], sx["spine2"], sx["spine3"]], [sx["neck"]], sx["head"], \
            sx["pelvis"], names, None, [], False
    raise KeyError(style)


STYLES = ("issue", "ue5", "unity", "biped", "blender", "humanik", "rokoko")


def _write(path, style, swap=False):
    spines, necks, head, pelvis, names, root, helpers, six = _convention(style)
    if swap:  # left and right names exchanged: a mirrored / mislabelled file
        names = {r: (b, a) for r, (a, b) in names.items()}
    lines, order = ["HIERARCHY"], []

    def chans(is_root):
        if is_root or six:
            return ["Xposition", "Yposition", "Zposition", "Zrotation", "Xrotation", "Yrotation"]
        return ["Zrotation", "Xrotation", "Yrotation"]

    children: dict[str, list] = {}

    def add(parent, name, offset, end=None):
        children.setdefault(parent, []).append((name, offset, end))

    spine_steps = np.linspace(0, 1, len(spines) + 1)[1:]
    total = np.sum(SPINE, axis=0)
    prev, done = pelvis, np.zeros(3)
    for k, n in enumerate(spines):  # spread the body's spine over the style's joints
        at = total * spine_steps[k]
        add(prev, n, tuple(at - done))
        prev, done = n, at
    top = prev
    add(prev, necks[0], (0, 14, 0))  # the neck's base; more neck joints share the way up
    prev = necks[0]
    up = np.array([0, 10, 1]) / len(necks)
    for n in necks[1:]:
        add(prev, n, tuple(up))
        prev = n
    add(prev, head, tuple(up), end=(0, 15, 0))
    where = {"top": top, "pelvis": pelvis}
    for s, sign in ((0, 1), (1, -1)):
        for role, (parent, off) in LEFT.items():
            par = where[parent] if parent in ("top", "pelvis") else names[parent][s]
            end = {"wrist": (sign * 8, 0, 0), "toe": (0, 0, 5)}.get(role)
            add(par, names[role][s], (sign * off[0], off[1], off[2]), end)
    for parent_role, name in helpers:  # twist bones: leaves beside the chain
        role, s = (parent_role[:-2], 1) if parent_role.endswith("_r") else (parent_role, 0)
        add(names[role][s], name, (0, -5, 0), end=(0, -5, 0))
    offsets = {}

    def emit(name, offset, end, depth):
        pad = "  " * depth
        c = chans(depth == 0)
        order.append((name, c, offset))
        lines.extend([f"{pad}{'ROOT' if depth == 0 else 'JOINT'} {name}", pad + "{",
                      f"{pad}  OFFSET " + " ".join(f"{v:.3f}" for v in offset),
                      f"{pad}  CHANNELS {len(c)} {' '.join(c)}"])
        offsets[name] = offset
        for child in children.get(name, []):
            emit(*child, depth + 1)
        if end is not None:
            lines.extend([f"{pad}  End Site", pad + "  {",
                          f"{pad}    OFFSET " + " ".join(f"{v:.3f}" for v in end), pad + "  }"])
        lines.append(pad + "}")

    if root is not None:
        children[root] = [(pelvis, (0, 95, 0), None)]
        emit(root, (0, 0, 0), None, 0)
    else:
        emit(pelvis, (0, 95, 0), None, 0)
    lines += ["MOTION", "Frames: 3", "Frame Time: 0.0333333"]
    for f in range(3):
        vals = []
        for i, (name, c, offset) in enumerate(order):
            for ch in c:
                if ch.endswith("position"):
                    v = offset["XYZ".index(ch[0])]
                    vals.append(v + (2.0 * f if i == 0 and ch[0] == "Z" else 0.0))
                else:
                    vals.append(0.0)
        lines.append(" ".join(f"{v:.3f}" for v in vals))
    path.write_text("\n".join(lines) + "\n")
    return path


def test_names_are_read_in_any_side_style():
    assert parse_joint_name("UpperArm_L") == ("l", "upperarm", False)
    assert parse_joint_name("mixamorig:LeftForeArm") == ("l", "forearm", False)
    assert parse_joint_name("thigh_twist_01_r") == ("r", "thightwist", True)
    assert parse_joint_name("Bip01_L_Thigh") == ("l", "thigh", False)
    assert parse_joint_name("shin.R") == ("r", "shin", False)
    assert parse_joint_name("l_knee") == ("l", "knee", False)
    assert parse_joint_name("CC_Base_R_Upperarm") == ("r", "upperarm", False)
    assert parse_joint_name("Character1_LeftUpLeg") == ("l", "upleg", False)
    assert parse_joint_name("Spine2") == (None, "spine", False)
    assert parse_joint_name("Hips") == (None, "hips", False)


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    m = load_bvh(_write(tmp_path_factory.mktemp("ref") / "smplx.bvh", "smplx"))
    assert m.info["joint_map"] == "smplx"
    return m


@pytest.mark.parametrize("style", STYLES)
def test_every_style_reads_as_the_same_body_without_a_map(tmp_path, style, reference):
    m = load_bvh(_write(tmp_path / f"{style}.bvh", style))
    assert m.info["joint_map"] == "automatic"
    assert 0.8 <= m.info["joint_map_confidence"] <= 1.0
    assert m.fps == 30 and m.joints.shape == (3, 22, 3)
    assert m.info["unit"] == pytest.approx(0.01)
    ref = reference.joints
    limbs = [n for n in JOINT_NAMES if not n.startswith("spine")]
    for n in limbs:  # the same body: pelvis, legs, arms, collars, neck, head
        np.testing.assert_allclose(m.joints[:, J[n]], ref[:, J[n]], atol=0.02, err_msg=n)
    # feet on the floor, the body's height right (head 1.58 m, pelvis 0.95 m)
    assert abs(m.joints[0, [J["l_foot"], J["r_foot"]], 2].min() - 0.01) < 0.02
    assert m.joints[0, J["head"], 2] == pytest.approx(ref[0, J["head"], 2], abs=0.02)
    spine = m.joints[0, [J["spine1"], J["spine2"], J["spine3"]], 2]
    assert m.joints[0, J["pelvis"], 2] < spine[0] < spine[1] < spine[2] < m.joints[0, J["neck"], 2]
    # the file's own joints are recorded
    assert m.info["joints_from"]["l_hip"] in {_convention(style)[4]["hip"][0]}


def test_helper_bones_and_an_extra_root_are_never_mapped(tmp_path):
    m = load_bvh(_write(tmp_path / "ue5.bvh", "ue5"))
    used = {v for v in m.info["joints_from"].values() if v}
    assert not any("twist" in v for v in used) and "root" not in used
    assert m.info["joints_from"]["l_knee"] == "calf_l"
    assert m.info["joints_from"]["l_foot"] == "ball_l"
    assert m.info["joints_from"]["neck"] == "neck_01"


def test_swapped_sides_are_an_error_that_shows_the_mapping(tmp_path):
    with pytest.raises(MotionFormatError, match="left and right are swapped") as e:
        load_bvh(_write(tmp_path / "swapped.bvh", "issue", swap=True))
    assert "UpperLeg_R" in str(e.value) and "joint_map=" in str(e.value)


def test_a_skeleton_that_is_no_body_is_an_error_that_lists_the_joints():
    names = [f"j{i}" for i in range(5)]
    with pytest.raises(ValueError, match="nor the shape .* show a body; the joints are"):
        auto_joint_map(names, [-1, 0, 0, 1, 2], np.zeros((5, 3)))


def test_an_explicit_map_keeps_priority(tmp_path):
    path = _write(tmp_path / "issue.bvh", "issue")
    mapping = {"pelvis": "Hips", "l_hip": "UpperLeg_R", "r_hip": "UpperLeg_L",
               "l_knee": "LowerLeg_L", "r_knee": "LowerLeg_R", "l_ankle": "Foot_L",
               "r_ankle": "Foot_R", "l_foot": "Toes_L", "r_foot": "Toes_R", "head": "Head",
               "l_wrist": "Hand_L", "r_wrist": "Hand_R"}
    m = load_bvh(path, joint_map=mapping)
    auto = load_bvh(path)
    assert m.info["joint_map"] == "custom" and m.info["joint_map_confidence"] == 1.0
    np.testing.assert_allclose(m.joints[:, J["l_hip"]], auto.joints[:, J["r_hip"]], atol=1e-6)


def test_data_inspect_prints_the_mapping_and_refuses_an_unsure_one(tmp_path, capsys):
    import json

    from jaxmotion.cli import main

    assert main(["data", "inspect", str(_write(tmp_path / "biped.bvh", "biped"))]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["joint_map"] == "automatic" and out["joint_map_confidence"] >= 0.9
    assert out["joints_from"]["l_knee"] == "Bip01_L_Calf" and out["fps"] == 30.0
    assert out["unit"] == pytest.approx(0.01) and out["up"] == "y"
    assert 1.5 < out["body_height_m"] < 1.8 and abs(out["lowest_foot_m"] - 0.01) < 0.02
    assert main(["data", "inspect", str(_write(tmp_path / "s.bvh", "unity", swap=True))]) == 2
    err = capsys.readouterr().err
    assert "left and right are swapped" in err and "LeftUpperLeg" in err


def test_a_skeleton_whose_names_say_nothing_is_read_by_its_shape(tmp_path, reference):
    path = _write(tmp_path / "issue.bvh", "issue")
    text = path.read_text()
    names = [line.split()[1] for line in text.splitlines()
             if line.strip().startswith(("ROOT", "JOINT"))]
    for i, n in sorted(enumerate(names), key=lambda x: -len(x[1])):  # longest first
        text = text.replace(f" {n}\n", f" Bone{i:02d}\n")
    (tmp_path / "bones.bvh").write_text(text)
    m = load_bvh(tmp_path / "bones.bvh")
    assert m.info["joint_map"] == "automatic" and m.info["joint_map_confidence"] < 0.9
    for n in ("pelvis", "l_hip", "r_knee", "l_ankle", "r_foot", "l_wrist", "r_elbow", "head"):
        np.testing.assert_allclose(m.joints[:, J[n]], reference.joints[:, J[n]], atol=0.02,
                                   err_msg=n)
