"""glTF skinned animations read as motion (jaxmotion.io.load_gltf): jaxmotion's own GLB read
back, the same file with its joints renamed in another rig's style (mapped automatically),
as a ``.gltf`` with its buffer in a data URI, and bad files."""

import base64
import json
import struct

import numpy as np
import pytest

from jaxmotion.export import write_glb
from jaxmotion.geometry import SMPLX_JOINT_NAMES, smplx_joints
from jaxmotion.io import MotionFormatError, load_gltf, load_motion

T = 8


@pytest.fixture(scope="module")
def glb(tmp_path_factory):
    rng = np.random.default_rng(0)
    go = rng.normal(0, 0.3, (T, 3)).astype(np.float32)
    bp = rng.normal(0, 0.25, (T, 21, 3)).astype(np.float32)
    tr = np.cumsum(rng.normal(0, 0.02, (T, 3)), 0).astype(np.float32) + [1.0, 2.0, 0.0]
    path = tmp_path_factory.mktemp("glb") / "motion.glb"
    write_glb(path, global_orient=go, body_pose=bp, transl=tr, fps=20.0)
    joints = np.asarray(smplx_joints(go, bp, tr), np.float64)
    return path, joints


def _chunks(path):
    data = path.read_bytes()
    n = struct.unpack_from("<I", data, 12)[0]
    gltf = json.loads(data[20:20 + n])
    rest = data[20 + n:]
    m = struct.unpack_from("<I", rest, 0)[0]
    return gltf, rest[8:8 + m]


def _glb(gltf, binary):
    js = json.dumps(gltf).encode()
    js += b" " * (-len(js) % 4)
    binary += b"\0" * (-len(binary) % 4)
    body = (struct.pack("<II", len(js), 0x4E4F534A) + js
            + struct.pack("<II", len(binary), 0x004E4942) + binary)
    return b"glTF" + struct.pack("<II", 2, 12 + len(body)) + body


def test_jaxmotions_own_glb_reads_back_as_its_joints(glb):
    path, joints = glb
    m = load_motion(path)
    assert m.info["format"] == "gltf" and m.info["joint_map"] == "smplx"
    assert m.fps == 20.0 and m.joints.shape == (T, 22, 3) and m.info["up"] == "y"
    np.testing.assert_allclose(m.joints, joints, atol=1e-4)


UNITY = {"pelvis": "Hips", "spine1": "Spine", "spine2": "Chest", "spine3": "UpperChest",
         "neck": "Neck", "head": "Head"}
for _s, _side in (("left", "Left"), ("right", "Right")):
    UNITY.update({f"{_s}_hip": f"{_side}UpperLeg", f"{_s}_knee": f"{_side}LowerLeg",
                  f"{_s}_ankle": f"{_side}Foot", f"{_s}_foot": f"{_side}Toes",
                  f"{_s}_collar": f"{_side}Shoulder", f"{_s}_shoulder": f"{_side}UpperArm",
                  f"{_s}_elbow": f"{_side}LowerArm", f"{_s}_wrist": f"{_side}Hand"})


def test_a_rig_named_another_way_is_mapped_automatically(glb, tmp_path):
    path, joints = glb
    gltf, binary = _chunks(path)
    for node in gltf["nodes"]:
        name = node.get("name", "")
        if name in UNITY:
            node["name"] = UNITY[name]
        elif name.startswith(("left_", "right_")) and name not in SMPLX_JOINT_NAMES[:22]:
            side, _, finger = name.partition("_")  # left_index1 -> LeftHandIndex1
            node["name"] = f"{side.capitalize()}Hand{finger.capitalize()}"
    renamed = tmp_path / "unity.glb"
    renamed.write_bytes(_glb(gltf, binary))
    m = load_gltf(renamed)
    assert m.info["joint_map"] == "automatic" and m.info["joint_map_confidence"] >= 0.9
    assert m.info["joints_from"]["l_wrist"] == "LeftHand"
    np.testing.assert_allclose(m.joints, joints, atol=1e-4)


def test_a_gltf_with_its_buffer_in_a_data_uri(glb, tmp_path):
    path, joints = glb
    gltf, binary = _chunks(path)
    gltf["buffers"][0]["uri"] = ("data:application/octet-stream;base64,"
                                 + base64.b64encode(binary).decode())
    (tmp_path / "m.gltf").write_text(json.dumps(gltf))
    np.testing.assert_allclose(load_motion(tmp_path / "m.gltf").joints, joints, atol=1e-4)
    gltf["buffers"][0]["uri"] = "missing.bin"
    (tmp_path / "n.gltf").write_text(json.dumps(gltf))
    with pytest.raises(MotionFormatError, match="not beside the file"):
        load_gltf(tmp_path / "n.gltf")


def test_bad_gltf_files_are_refused_with_the_fix(glb, tmp_path):
    path, _ = glb
    gltf, binary = _chunks(path)
    with pytest.raises(MotionFormatError, match="animation 3 does not exist"):
        load_gltf(path, animation=3)
    del gltf["skins"]
    (tmp_path / "noskin.glb").write_bytes(_glb(gltf, binary))
    with pytest.raises(MotionFormatError, match="no skin"):
        load_gltf(tmp_path / "noskin.glb")
    (tmp_path / "junk.glb").write_bytes(b"hello")
    with pytest.raises(MotionFormatError, match="neither a GLB nor a glTF"):
        load_gltf(tmp_path / "junk.glb")


@pytest.mark.parametrize("skeleton, first, map_name", [("mixamo", "mixamorig:Hips", "mixamo"),
                                                       ("ue5", "pelvis", "automatic")])
def test_a_glb_in_a_rigs_names_reads_back_as_the_same_body(glb, tmp_path, skeleton, first,
                                                           map_name):
    _, joints = glb
    rng = np.random.default_rng(0)  # the fixture's motion again
    go = rng.normal(0, 0.3, (T, 3)).astype(np.float32)
    bp = rng.normal(0, 0.25, (T, 21, 3)).astype(np.float32)
    tr = np.cumsum(rng.normal(0, 0.02, (T, 3)), 0).astype(np.float32) + [1.0, 2.0, 0.0]
    path = write_glb(tmp_path / "rig.glb", global_orient=go, body_pose=bp, transl=tr, fps=20.0,
                     skeleton=skeleton)
    gltf, _ = _chunks(path)
    names = [gltf["nodes"][j]["name"] for j in gltf["skins"][0]["joints"]]
    assert names[0] == first and len(names) == 52
    assert ("mixamorig:LeftHandIndex1" if skeleton == "mixamo" else "index_01_l") in names
    m = load_gltf(path)
    assert m.info["joint_map"] == map_name
    np.testing.assert_allclose(m.joints, joints, atol=1e-4)
    with pytest.raises(ValueError, match="skeleton must be one of"):
        write_glb(tmp_path / "x.glb", global_orient=go, body_pose=bp, transl=tr, fps=20.0,
                  skeleton="maya")


def test_data_convert_reads_a_folder_of_glb_files(glb, tmp_path, capsys):
    from jaxmotion.cli import main
    from jaxmotion.data import Dataset, load_sample

    path, joints = glb
    src = tmp_path / "takes"
    (src / "sub").mkdir(parents=True)
    (src / "sub" / "a.glb").write_bytes(path.read_bytes())
    out = tmp_path / "data"
    assert main(["data", "convert", "--from", "gltf", str(src), "--out", str(out), "--split",
                 "val", "--fit-iters", "0", "--min-frames", "4", "--fps", "20",
                 "--keep-height", "--no-stats"]) == 0, capsys.readouterr().err
    s = load_sample(Dataset(out, "val").files[0])
    assert s["joints"].shape == (T, 22, 3)
    # the clip is moved to the origin, as every converted clip is
    np.testing.assert_allclose(s["joints"] - s["joints"][0, 0], joints - joints[0, 0],
                               atol=1e-3)
