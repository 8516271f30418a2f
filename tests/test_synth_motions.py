"""``jaxmotion synth --motions``: real clips placed in the synthetic rooms, fallbacks counted.

The motion library is made here from the procedural character itself, written as
AMASS-style ``.npz`` files (SMPL-X parameters, 30 fps), so nothing licensed is needed.
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from jaxmotion.cli import main
from jaxmotion.data.clip_placement import heading, transform_clip
from jaxmotion.data.format import DatasetError, load_sample
from jaxmotion.data.motion_library import (
    HOLD,
    action_windows,
    frame_states,
    label_from_name,
    load_library,
)
from jaxmotion.data.synth import SynthSettings, build_dataset
from jaxmotion.geometry import JOINT_NAMES
from jaxmotion.io import smplx_joints_host

JI = {n: i for i, n in enumerate(JOINT_NAMES)}
SETTINGS = SynthSettings(scenes=2, per_scene=3, seed=3, points_per_scene=2000)


def _procedural(action: str, i: int):
    from jaxmotion.motion import MotionError, synthesize
    from jaxmotion.scene.instructions import sample_task
    from jaxmotion.scene.rooms import sample_room

    for j in range(i, i + 40):
        room = sample_room(np.random.default_rng([100 + j]),
                           kind="bedroom" if action == "lie" else None)
        rng = np.random.default_rng([j, 5])
        try:
            _, info = sample_task(room, rng, action=action)
            return synthesize(action, room.floor_rects, room.objects, info["target_id"], rng)
        except (MotionError, ValueError):
            continue
    raise AssertionError(f"no procedural {action}")


def _write_amass(path: Path, m) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    np.savez(path, root_orient=m.global_orient, pose_body=m.body_pose.reshape(-1, 63),
             trans=m.transl, betas=m.betas, mocap_frame_rate=np.array(30.0))


@pytest.fixture(scope="module")
def motions(tmp_path_factory) -> dict:
    """Two procedural clips per action, as motions a user could have."""
    return {a: [_procedural(a, 10 * k) for k in range(2)]
            for a in ("walk", "sit", "stand_up", "lie")}


@pytest.fixture(scope="module")
def library(tmp_path_factory, motions) -> Path:
    """Named by action (folders and file names), one left for the geometry to label."""
    src = tmp_path_factory.mktemp("library")
    for a, ms in motions.items():
        _write_amass(src / a / f"take_{a}_0.npz", ms[0])
        _write_amass(src / "misc" / f"take{a}1.npz", ms[1])  # no action word in the name
    return src


@pytest.fixture(scope="module")
def built(tmp_path_factory, library) -> tuple[Path, dict]:
    out = tmp_path_factory.mktemp("built") / "ds"
    return out, build_dataset(out, SETTINGS, progress=False, stats=False, motions=library)


def _tree(root: Path) -> dict:
    return {p.relative_to(root).as_posix(): hashlib.sha1(p.read_bytes()).hexdigest()
            for p in sorted(root.rglob("*")) if p.is_file() and p.name != "manifest.json"}


def test_names_and_geometry_label_the_clips(library, motions):
    assert label_from_name("sit/chair_03.bvh") == "sit"
    assert label_from_name("07_lie_bed.npz") == "lie"
    assert label_from_name("x/stand_up_2.npz") == "stand_up"
    assert label_from_name("sit_to_stand_up.npz") is None  # ambiguous: the geometry decides
    assert label_from_name("misc/take1.npz") is None
    for a, ms in motions.items():  # the procedural clips show their action
        assert a in action_windows(ms[0].joints)
    lib = load_library(library)
    assert lib.counts()["sit"] >= 2 and lib.counts()["stand_up"] >= 2 and lib.counts()["lie"] >= 2
    assert lib.counts()["walk"] >= 1
    assert lib.report["labels"]["name"] >= 4 and lib.report["labels"]["geometry"] >= 4


def test_samples_are_placed_library_clips(built, library):
    out, manifest = built
    origin = manifest["samples_by_origin"]
    n = sum(manifest["samples"].values())
    assert n == SETTINGS.scenes * SETTINGS.per_scene
    assert origin["library_clips"] + origin["procedural_fallback"] == n
    assert origin["library_clips"] >= 1
    assert manifest["settings"]["motions"].startswith("sha1:")
    assert manifest["motion_library"]["path"] == str(library)
    lib = load_library(library)
    for f in sorted((out / "provenance").glob("*/*.json")):
        pv = json.loads(f.read_text())
        s = load_sample(out / "samples" / f.parent.name / f"{f.stem}.npz")
        if pv["source"] != "library":
            continue
        clip = next(c for c in lib.clips if c.source == pv["clip"] and c.action == s["action"]
                    and [c.start, c.stop] == pv["frames"])
        p = transform_clip(clip, pv["angle"], pv["shift"])
        np.testing.assert_allclose(s["joints"], p.joints, atol=1e-5)
        assert pv["shift"][2] == 0.0  # only turned and moved over the floor
        # the SMPL-X parameters moved with the joints
        fk = smplx_joints_host(s["global_orient"], s["body_pose"], s["transl"], s["betas"])
        np.testing.assert_allclose(fk, s["joints"], atol=1e-4)
        # pelvis path shape kept: distances between frames are the clip's
        np.testing.assert_allclose(np.diff(s["joints"][:, 0], axis=0),
                                   np.diff(clip.joints[:, 0], axis=0) @ _rz(pv["angle"]).T,
                                   atol=1e-5)


def _rz(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def test_transform_turns_heading():
    from jaxmotion.motion.kinematics import upright

    j = np.zeros((1, 22, 3))
    j[0, 1], j[0, 2] = [0.0, 0.1, 0.9], [0.0, -0.1, 0.9]  # left hip +y: facing +x
    assert heading(j[0]) == pytest.approx(0.0)
    assert np.allclose(upright(0.0)[:, 2], [1, 0, 0])  # the rest body faces +x when upright


def test_same_seed_same_files_and_resume(built, library, tmp_path):
    out, _ = built
    again = tmp_path / "again"
    build_dataset(again, SETTINGS, progress=False, stats=False, motions=library)
    assert _tree(again) == _tree(out)
    victim = min((again / "samples").rglob("*.npz"))
    victim.unlink()
    build_dataset(again, SETTINGS, progress=False, stats=False, motions=library)
    assert _tree(again) == _tree(out)


def test_fallback_is_the_procedural_sample(tmp_path, motions):
    """A library of walks only: every other sample falls back to the procedural character,
    byte for byte the sample of a build without --motions."""
    src = tmp_path / "walks"
    for k, m in enumerate(motions["walk"]):
        _write_amass(src / f"walk_{k}.npz", m)
    plain = tmp_path / "plain"
    build_dataset(plain, SETTINGS, progress=False, stats=False)
    out = tmp_path / "mixed"
    manifest = build_dataset(out, SETTINGS, progress=False, stats=False, motions=src)
    assert manifest["motion_library"]["clips"] == {"walk": 2, "sit": 0, "stand_up": 0, "lie": 0}
    assert not (plain / "provenance").exists() and "motions" not in json.loads(
        (plain / "manifest.json").read_text())["settings"]
    fallback = 0
    for f in sorted((out / "provenance").glob("*/*.json")):
        sample = Path("samples") / f.parent.name / f"{f.stem}.npz"
        if json.loads(f.read_text())["source"] == "procedural":
            fallback += 1
            assert (out / sample).read_bytes() == (plain / sample).read_bytes()
        else:
            assert load_sample(out / sample)["action"] == "walk"
    assert fallback == manifest["samples_by_origin"]["procedural_fallback"] >= 1
    # another library in the same folder is refused
    _write_amass(tmp_path / "one_walk" / "walk_0.npz", motions["walk"][0])
    with pytest.raises(DatasetError, match="built with"):
        build_dataset(out, SETTINGS, progress=False, stats=False, motions=tmp_path / "one_walk")


def test_clear_errors(tmp_path, capsys):
    out = tmp_path / "out"
    with pytest.raises(DatasetError, match="no such folder"):
        build_dataset(out, SETTINGS, progress=False, motions=tmp_path / "missing")
    (tmp_path / "empty").mkdir()
    with pytest.raises(DatasetError, match="no motion files"):
        build_dataset(out, SETTINGS, progress=False, motions=tmp_path / "empty")
    bad = tmp_path / "bad"
    bad.mkdir()
    (bad / "x.npz").write_bytes(b"not a zip")
    with pytest.raises(DatasetError, match="could be read"):
        build_dataset(out, SETTINGS, progress=False, motions=bad)
    still = tmp_path / "still"  # a person standing still: no action in it
    t = 40
    idle = SimpleNamespace(global_orient=np.tile([[np.pi / 2, 0.0, 0.0]], (t, 1)),
                           body_pose=np.zeros((t, 21, 3)), transl=np.zeros((t, 3)),
                           betas=np.zeros(10))
    _write_amass(still / "idle.npz", idle)
    with pytest.raises(DatasetError, match="no clip of walk, sit, stand_up or lie"):
        build_dataset(out, SETTINGS, progress=False, motions=still)
    assert not out.exists()  # refused before any work
    code = main(["synth", "--out", str(out), "--scenes", "2", "--motions",
                 str(tmp_path / "missing")])
    assert code == 2 and "--motions" in capsys.readouterr().err


def test_labels_file_overrides_names(tmp_path, motions):
    src = tmp_path / "lib"
    _write_amass(src / "sit_0.npz", motions["sit"][0])
    _write_amass(src / "sit_1.npz", motions["sit"][1])
    (src / "labels.json").write_text(json.dumps({"sit_0.npz": "walk", "sit_1.npz": None}))
    with pytest.raises(DatasetError, match="no clip"):
        load_library(src)
    (src / "labels.json").write_text(json.dumps({"sit_0.npz": "sit"}))
    lib = load_library(src)
    assert lib.counts()["sit"] == 2 and lib.report["labels"] == {"file": 1, "name": 1}


@pytest.mark.slow
def test_joint_only_files_get_fitted_smplx(tmp_path, motions):
    """A BVH library (joints only): SMPL-X parameters are fitted (analytic start, fit_iters=0),
    the samples keep the file's joints."""
    from jaxmotion.export import write_bvh

    src = tmp_path / "bvh"
    src.mkdir()
    for a in ("sit", "stand_up"):
        for k, m in enumerate(motions[a]):
            write_bvh(src / f"{a}_{k}.bvh", m.global_orient, m.body_pose, m.transl, m.betas, 30.0)
    out = tmp_path / "ds"
    manifest = build_dataset(out, SETTINGS, progress=False, stats=False, motions=src,
                             motions_fit_iters=0)
    lib = manifest["motion_library"]
    assert lib["fitted_clips"] == 4 and lib["smplx_fit_error_m"] < 0.08
    assert manifest["samples_by_origin"]["library_clips"] >= 1
    used = [json.loads(f.read_text()) for f in (out / "provenance").glob("*/*.json")]
    assert all(u["smplx_fitted"] for u in used if u["source"] == "library")


def _pose(pelvis, neck, knees, ankles, half_hips=0.1):
    """Joints [22,3] with the ones frame_states reads placed (others at the pelvis); the
    body faces +x, its left is +y."""
    j = np.tile(np.asarray(pelvis, float), (22, 1))
    j[JI["l_hip"]] = np.add(pelvis, [0, half_hips, -0.03])
    j[JI["r_hip"]] = np.add(pelvis, [0, -half_hips, -0.03])
    j[JI["neck"]] = neck
    j[[JI["l_knee"], JI["r_knee"]]] = knees
    j[[JI["l_ankle"], JI["r_ankle"]]] = ankles
    return j


def test_kneeling_or_squatting_bent_forward_is_not_lying():
    lean30 = [0.39, 0.0, 0.48 + 0.22]  # the pelvis -> neck vector 30 deg from level
    kneel = _pose([0, 0, 0.48], lean30, [[0.4, 0.1, 0.45], [0.0, -0.1, 0.04]],
                  [[0.4, 0.1, 0.07], [-0.4, -0.1, 0.05]])  # right knee on the floor
    squat = _pose([0, 0, 0.40], [0.39, 0, 0.62], [[0.35, 0.1, 0.55], [0.35, -0.1, 0.55]],
                  [[0.2, 0.1, 0.07], [0.2, -0.1, 0.07]])  # feet under the body
    on_bed = _pose([0, 0, 0.55], [-0.45, 0, 0.6], [[0.4, 0.1, 0.57], [0.4, -0.1, 0.57]],
                   [[0.8, 0.1, 0.52], [0.8, -0.1, 0.52]])
    knees_up = _pose([0, 0, 0.55], [-0.45, 0, 0.6], [[0.3, 0.1, 0.8], [0.3, -0.1, 0.8]],
                     [[0.55, 0.1, 0.6], [0.55, -0.1, 0.6]])  # on the back, feet flat
    s = frame_states(np.stack([kneel, squat, on_bed, knees_up]))
    assert s["lying"].tolist() == [False, False, True, True]
    assert not s["seated"][:2].any() and not s["standing"][:2].any()
    # a stand -> kneel -> stand take (the MocapBank file's action) holds no lie window
    stand = _pose([0, 0, 0.95], [0, 0, 1.4], [[0, 0.1, 0.5], [0, -0.1, 0.5]],
                  [[0, 0.1, 0.07], [0, -0.1, 0.07]])
    take = np.stack([stand] * 40 + [kneel] * 60 + [stand] * 40)
    assert "lie" not in action_windows(take)


def _body(shank, thigh, lean, heel=0.0, feet_z=0.0, reach=False):
    """Joints [22,3] of a stick body facing +x (its left +y), its feet flat at x = 0 (ankles)
    .. 0.14 (toes): ``shank`` the shanks' tilt from vertical, knees forward (deg); ``thigh``
    the thighs' angle from hanging straight down (deg; 90 level, the hips behind the knees);
    ``lean`` the torso's tilt forward (deg); ``heel`` the heels raised onto the toes (m);
    ``feet_z`` the feet lifted off the floor (legs hanging); ``reach`` arms held forward."""
    s, t, g = np.radians([shank, thigh, lean])
    j = np.zeros((22, 3))
    for side, w in (("l", 0.1), ("r", -0.1)):
        toe = np.array([0.14, w, 0.025 + feet_z])
        ankle = toe + [-np.sqrt(0.14**2 - heel * (heel + 0.11)), 0, 0.055 + heel]
        knee = ankle + 0.42 * np.array([np.sin(s), 0, np.cos(s)])
        j[JI[f"{side}_foot"]], j[JI[f"{side}_ankle"]], j[JI[f"{side}_knee"]] = toe, ankle, knee
        j[JI[f"{side}_hip"]] = knee - 0.42 * np.array([np.sin(t), 0, -np.cos(t)])
    pelvis = j[[JI["l_hip"], JI["r_hip"]]].mean(0) + [0, 0, 0.05]
    up = np.array([np.sin(g), 0, np.cos(g)])
    for name, r in (("pelvis", 0), ("spine1", 0.12), ("spine2", 0.25), ("spine3", 0.38),
                    ("neck", 0.52), ("head", 0.64)):
        j[JI[name]] = pelvis + r * up
    arm = np.array([1, 0, 0] if reach else [0, 0, -1])
    for side, w in (("l", 1), ("r", -1)):
        j[JI[f"{side}_collar"]] = pelvis + 0.47 * up + [0, 0.07 * w, 0]
        j[JI[f"{side}_shoulder"]] = sh = pelvis + 0.47 * up + [0, 0.18 * w, 0]
        j[JI[f"{side}_elbow"]], j[JI[f"{side}_wrist"]] = sh + 0.28 * arm, sh + 0.53 * arm
    return j


def _down_and_up(pose):
    """Standing 40 frames, 15 frames down to ``pose``, held 45 (frames 55-99), back up."""
    stand = _body(0, 0, 0)
    way = stand + (pose - stand) * np.linspace(0, 1, 15)[:, None, None]
    return np.concatenate([[stand] * 40, way, [pose] * 45, way[::-1], [stand] * 40])


def test_a_squat_is_not_seated():
    """A squat balances its centre of mass over its feet (each torso lean below puts it 2-4 cm
    ahead of the ankles); a seat carries a seated body's weight behind them. The squats hold
    the seated pose's other marks (pelvis > 30 cm and 10 % low, torso > 45 deg, thighs bent),
    as CMU 14_14's free-standing squat did, but make no sit or stand_up clip."""
    squats = {
        "deep, feet flat, leaning": _body(35, 105, 35),
        "deep, on the toes, upright": _body(45, 110, 15, heel=0.07),
        "half, feet flat, arms forward": _body(30, 90, 35, reach=True),
        "half, on the toes, arms forward": _body(30, 90, 40, heel=0.06, reach=True),
    }
    for name, pose in squats.items():
        torso, thighs = pose[JI["neck"]] - pose[JI["pelvis"]], pose[[4, 5]] - pose[[1, 2]]
        assert 0.3 < pose[0, 2] < 0.85 and torso[2] > np.linalg.norm(torso) * np.sin(np.pi / 4)
        assert (-thighs[:, 2] < np.linalg.norm(thighs, axis=1) * np.cos(np.pi / 4)).all()
        take = _down_and_up(pose)
        assert not frame_states(take)["seated"].any(), name
        assert not {"sit", "stand_up"} & set(action_windows(take)), name


def test_sitting_on_a_seat_stays_seated():
    seats = {
        "chair": _body(0, 90, 5),
        "chair, feet tucked back": _body(15, 85, 10),
        "low sofa, feet forward, leaning back": _body(-10, 110, -10),
        "bar stool, legs hanging": _body(10, 90, 0, feet_z=0.3),
    }
    for name, pose in seats.items():
        take = _down_and_up(pose)
        s = frame_states(take)
        assert s["seated"][55:100].all(), name
        assert {"sit", "stand_up"} <= set(action_windows(take)), name
    # rising, the body first leans its weight over its feet, the pelvis still at the seat:
    # as a moment of the sit these frames stay seated (held alone it is a squat, not seated)
    chair, seat_off = seats["chair"], _body(25, 80, 40, reach=True)
    lean = chair + (seat_off - chair) * np.linspace(0, 1, 8)[:, None, None]
    take = np.concatenate([_down_and_up(chair)[:100], lean, [seat_off] * 6,
                           _down_and_up(seat_off)[100:]])
    s = frame_states(take)
    assert s["seated"][55:114].all() and not s["seated"][125:].any()
    assert action_windows(take)["stand_up"][0] >= 114 - HOLD  # the run ends after the lean
    assert not frame_states(_down_and_up(seat_off))["seated"].any()


def test_a_walk_there_and_back_ends_where_it_is_farthest(motions):
    """A real clip walked 0.9 m, turned round and walked back to where it began: as a walk
    to a target it ends at its farthest point, not back beside its start."""
    j = np.asarray(motions["walk"][1].joints)[:45]
    assert np.linalg.norm(j[-1, 0, :2] - j[0, 0, :2]) > 0.5
    there_and_back = np.concatenate([j, j[::-1]])
    assert action_windows(there_and_back)["walk"] == (0, 45)
    # on the spot (no farther than 0.5 m from the start): no walk
    assert "walk" not in action_windows(np.concatenate([j[:12], j[:12][::-1]] * 3))
