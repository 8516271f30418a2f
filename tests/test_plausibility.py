"""Plausibility metrics: hand-made motions with known answers, a brute-force numpy
reference on random masked motions, jit / vmap consistency, and the table summary."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxmotion.eval.plausibility import (
    PLAUSIBILITY_KEYS,
    TELEPORT_JOINT_SPEED,
    TELEPORT_PELVIS_SPEED,
    plausibility,
    summarize_plausibility,
    teleports,
)
from jaxmotion.eval.skating import foot_skating
from jaxmotion.geometry.skeleton import PARENTS, rest_joints_host

FPS = 30.0
# The rest skeleton stood up (SMPL-X y-up -> z-up, facing -y), lowest joint 2 cm up.
_R = np.array([[1.0, 0, 0], [0, 0, -1.0], [0, 1.0, 0]])
POSE = rest_joints_host() @ _R.T
POSE = (POSE - [0, 0, POSE[:, 2].min() - 0.02]).astype(np.float32)


def still(t=6):
    return np.repeat(POSE[None], t, 0)


def moving(velocity, t=8, fps=FPS):
    """The pose translated at a constant ``velocity`` [3] (m/s)."""
    return still(t) + (np.arange(t)[:, None, None] / fps) * np.asarray(velocity, np.float32)


def values(out):
    return {k: float(v) for k, v in out.items()}


def test_still_pose_is_all_zeros():
    r = values(plausibility(still()))
    assert set(r) == set(PLAUSIBILITY_KEYS)
    for k in ("pelvis_speed_max", "joint_speed_max", "jerk_mean", "floor_penetration",
              "skate_ratio", "bone_length_spread", "teleport"):  # fmt: skip
        assert r[k] == 0.0, k
    assert r["valid_frames"] == 6


def test_constant_walk_speed():
    r = values(plausibility(moving([1.2, 0.0, 0.0])))
    np.testing.assert_allclose(r["pelvis_speed_max"], 1.2, rtol=1e-4)
    np.testing.assert_allclose(r["joint_speed_max"], 1.2, rtol=1e-4)
    assert not r["teleport"] and r["jerk_mean"] < 0.05 and r["bone_length_spread"] < 1e-5
    # Diagonal in xy, and vertical motion does not count as horizontal pelvis speed.
    r = values(plausibility(moving([0.6, 0.8, 0.5])))
    np.testing.assert_allclose(r["pelvis_speed_max"], 1.0, rtol=1e-4)
    np.testing.assert_allclose(r["joint_speed_max"], np.sqrt(1.25), rtol=1e-4)


def test_one_frame_jump_is_a_teleport():
    j = still(6)
    j[3:, :, 0] += 0.5  # 0.5 m in one frame
    r = values(plausibility(j, fps=FPS))
    np.testing.assert_allclose(r["joint_speed_max"], 0.5 * FPS, rtol=1e-4)
    np.testing.assert_allclose(r["pelvis_speed_max"], 0.5 * FPS, rtol=1e-4)
    assert r["teleport"]
    # The same jump at 1 fps is 0.5 m/s: no teleport.
    assert not values(plausibility(j, fps=1.0))["teleport"]


@pytest.mark.parametrize("speed,teleport", [(2.9, False), (3.1, True)])
def test_pelvis_speed_threshold_is_three_d(speed, teleport):
    r = values(plausibility(moving([0.0, 0.0, speed])))  # straight up: xy speed 0
    assert r["pelvis_speed_max"] < 1e-6
    np.testing.assert_allclose(r["joint_speed_max"], speed, rtol=1e-4)
    assert r["joint_speed_max"] < TELEPORT_JOINT_SPEED
    assert (speed > TELEPORT_PELVIS_SPEED) == teleport == bool(r["teleport"])
    # Thresholds are keyword arguments.
    relaxed = plausibility(moving([0.0, 0.0, speed]), teleport_pelvis_speed=3.2)
    assert not bool(relaxed["teleport"])


def test_joint_speed_threshold():
    j = still(5)
    j[2:, 20, 0] += 9.5 / FPS  # a wrist at 9.5 m/s for one frame pair (bone stretched too)
    r = values(plausibility(j))
    np.testing.assert_allclose(r["joint_speed_max"], 9.5, rtol=1e-4)
    assert r["teleport"] and r["pelvis_speed_max"] == 0.0
    assert not values(plausibility(j, teleport_joint_speed=10.0))["teleport"]


def test_padded_garbage_is_ignored():
    clean = moving([1.2, 0.3, 0.0], t=7)
    for junk in (np.nan, 1e6, -50.0):
        j = np.concatenate([clean, np.full((5, 22, 3), junk, np.float32)])
        mask = np.r_[np.ones(7, bool), np.zeros(5, bool)]
        got, want = values(plausibility(j, mask)), values(plausibility(clean))
        assert got == pytest.approx(want, rel=1e-5, abs=1e-6), junk
    # Garbage in the middle: pairs touching it do not count, the rest do.
    j = clean.copy()
    j[3] = 1e3
    mask = np.ones(7, bool)
    mask[3] = False
    r = values(plausibility(j, mask))
    np.testing.assert_allclose(r["pelvis_speed_max"], np.hypot(1.2, 0.3), rtol=1e-4)
    assert not r["teleport"] and r["floor_penetration"] == 0.0 and r["jerk_mean"] == 0.0


def test_fewer_than_two_valid_frames():
    j = still(5)
    j[1:] += np.random.default_rng(0).normal(size=(4, 22, 3)).astype(np.float32)
    r = values(plausibility(j, np.array([True, False, False, False, False])))
    assert r["teleport"] == 0.0 and r["valid_frames"] == 1
    for k in ("pelvis_speed_max", "joint_speed_max", "jerk_mean", "skate_ratio",
              "bone_length_spread", "floor_penetration"):  # fmt: skip
        assert r[k] == 0.0, k
    none = values(plausibility(j, np.zeros(5, bool)))
    assert all(v == 0.0 for v in none.values())
    one = values(plausibility(still(1)))  # a single frame (padded internally)
    assert one["valid_frames"] == 1 and one["joint_speed_max"] == 0.0


def test_floor_penetration():
    j = still(6)
    j[2:4, :, 2] -= POSE[:, 2].min() + 0.04  # the body dips, its lowest joint 4 cm below
    np.testing.assert_allclose(float(plausibility(j)["floor_penetration"]), 0.04, atol=1e-6)
    assert float(plausibility(still())["floor_penetration"]) == 0.0


def test_bone_stretch():
    j = still(6)
    bone = POSE[20] - POSE[18]  # elbow -> wrist (the wrist is a leaf: one bone changes)
    j[3, 20] += 0.02 * bone / np.linalg.norm(bone)
    np.testing.assert_allclose(float(plausibility(j)["bone_length_spread"]), 0.02, atol=1e-5)


@pytest.mark.parametrize("fps,rtol", [(10.0, 1e-3), (30.0, 2e-2)])
def test_jerk_of_a_cubic(fps, rtol):
    c = 0.5  # x(t) = c t^3: jerk 6c = 3 m/s^3 everywhere
    t = np.arange(9) / fps
    j = still(9) + np.stack([c * t**3, 0 * t, 0 * t], -1)[:, None, :].astype(np.float32)
    np.testing.assert_allclose(float(plausibility(j, fps=fps)["jerk_mean"]), 6 * c, rtol=rtol)


def test_skate_ratio_is_foot_skating():
    rng = np.random.default_rng(1)
    j = moving([0.9, 0.0, 0.0], t=10) + rng.normal(0, 0.004, (10, 22, 3)).astype(np.float32)
    j[..., 2] = np.maximum(j[..., 2], 0.0)
    mask = np.r_[np.ones(8, bool), np.zeros(2, bool)]
    want = float(foot_skating(j, mask, fps=FPS)["skate_ratio"])
    assert want > 0
    np.testing.assert_allclose(float(plausibility(j, mask)["skate_ratio"]), want, rtol=1e-6)


def reference(joints, mask, fps):
    """Brute force in float64 numpy with explicit loops over frame pairs and windows."""
    x = joints.astype(np.float64)
    t = len(x)
    pel, pel3, jmax, jerk, n_jerk = 0.0, 0.0, 0.0, 0.0, 0
    for i in range(t - 1):
        if mask[i] and mask[i + 1]:
            pel = max(pel, np.linalg.norm(x[i + 1, 0, :2] - x[i, 0, :2]) * fps)
            pel3 = max(pel3, np.linalg.norm(x[i + 1, 0] - x[i, 0]) * fps)
            jmax = max(jmax, np.linalg.norm(x[i + 1] - x[i], axis=1).max() * fps)
    for i in range(t - 3):
        if mask[i : i + 4].all():
            d3 = x[i + 3] - 3 * x[i + 2] + 3 * x[i + 1] - x[i]
            jerk += np.linalg.norm(d3, axis=1).sum() * fps**3
            n_jerk += x.shape[1]
    valid = x[mask]
    lengths = np.linalg.norm(valid[:, 1:] - valid[:, list(PARENTS[1:])], axis=-1)
    return {
        "pelvis_speed_max": pel,
        "joint_speed_max": jmax,
        "jerk_mean": jerk / max(n_jerk, 1),
        "floor_penetration": max(0.0, -valid[..., 2].min()),
        "bone_length_spread": (lengths.max(0) - lengths.min(0)).max(),
        "teleport": float(jmax > TELEPORT_JOINT_SPEED or pel3 > TELEPORT_PELVIS_SPEED),
    }


def random_batch(seed=0, b=4, t=12):
    rng = np.random.default_rng(seed)
    walk = rng.normal(0, 0.03, (b, t, 1, 3)).cumsum(1)
    joints = (POSE[None, None] + walk + rng.normal(0, 0.01, (b, t, 22, 3))).astype(np.float32)
    joints[..., 2] -= 0.05  # some joints below the floor
    joints[1, 5:, :, 0] += 0.5  # motion 1 teleports between frames 4 and 5
    mask = rng.random((b, t)) > 0.2
    mask[:, :3] = True
    mask[1, 4:6] = True
    joints[~mask] = np.nan  # padded frames hold garbage
    return joints, mask


def test_matches_brute_force_reference():
    joints, mask = random_batch()
    out = plausibility(joints, mask, fps=20.0)
    for i in range(len(joints)):
        ref = reference(joints[i], mask[i], 20.0)
        for k, v in ref.items():
            np.testing.assert_allclose(float(out[k][i]), v, rtol=1e-3, atol=1e-5, err_msg=k)
    assert 0 < float(np.mean(out["teleport"])) < 1  # both cases occur in this batch
    # the flag alone (generate's candidate choice) is the same flag
    np.testing.assert_array_equal(np.asarray(teleports(joints, mask, fps=20.0)),
                                  np.asarray(out["teleport"]))
    assert bool(teleports(joints[0], mask[0], fps=20.0)) == bool(out["teleport"][0])


def test_jit_and_vmap_agree():
    joints, mask = random_batch(seed=3, b=3, t=9)
    eager = plausibility(joints, mask, fps=FPS)
    jitted = jax.jit(lambda j, m, f: plausibility(j, m, fps=f))(joints, mask, FPS)
    mapped = jax.vmap(lambda j, m: plausibility(j, m, fps=FPS))(jnp.asarray(joints), mask)
    singles = [plausibility(joints[i], mask[i], fps=FPS) for i in range(3)]
    for k in PLAUSIBILITY_KEYS:
        np.testing.assert_allclose(np.asarray(jitted[k]), np.asarray(eager[k]), rtol=1e-6)
        np.testing.assert_allclose(np.asarray(mapped[k]), np.asarray(eager[k]), rtol=1e-6)
        np.testing.assert_allclose([float(s[k]) for s in singles], np.asarray(eager[k]), rtol=1e-6)


def test_shape_errors():
    with pytest.raises(ValueError):
        plausibility(np.zeros((4, 21, 3)))
    with pytest.raises(ValueError):
        plausibility(np.zeros((2, 4, 22, 3)), np.ones((2, 5), bool))
    with pytest.raises(ValueError):
        teleports(np.zeros((2, 4, 22, 3)), np.ones((2, 5), bool))


def test_summary():
    per = {
        "pelvis_speed_max": np.array([1.0, 2.0, 3.0, 9.0]),
        "joint_speed_max": np.array([2.0, 2.0, 2.0, 99.0]),
        "teleport": np.array([False, True, False, True]),
        "jerk_mean": np.array([1.0, 2.0, 3.0, 1e9]),
        "floor_penetration": np.array([0.0, 0.02, 0.04, 1.0]),
        "skate_ratio": np.array([0.0, 0.5, 0.25, 1.0]),
        "bone_length_spread": np.array([0.0, 0.0, 0.03, 1.0]),
        "valid_frames": np.array([10, 10, 10, 1]),  # the last one is left out
    }
    s = summarize_plausibility(per, percentiles=(50, 99.5))
    assert s["motions"] == 3 and s["teleport_rate"] == pytest.approx(1 / 3)
    assert s["pelvis_speed_p50"] == pytest.approx(2.0)
    assert s["pelvis_speed_p99.5"] == pytest.approx(np.percentile([1.0, 2.0, 3.0], 99.5))
    assert s["pelvis_speed_max"] == 3.0 and s["joint_speed_p50"] == 2.0
    assert s["jerk_mean"] == pytest.approx(2.0) and s["skate_ratio_mean"] == pytest.approx(0.25)
    assert s["floor_penetration_mean"] == pytest.approx(0.02)
    assert s["floor_penetration_max"] == pytest.approx(0.04)
    assert s["bone_length_spread_max"] == pytest.approx(0.03)
    # Straight from plausibility(); nothing counted -> NaN.
    s = summarize_plausibility(plausibility(np.stack([still(), moving([1.0, 0, 0], t=6)])))
    assert s["motions"] == 2 and s["pelvis_speed_p99"] == pytest.approx(0.99, rel=1e-3)
    empty = summarize_plausibility({**per, "valid_frames": np.zeros(4, int)})
    assert empty["motions"] == 0 and np.isnan(empty["teleport_rate"])


def test_select_motion_prefers_plausible_then_unhurried_then_closest():
    """Best of M: a teleporting candidate loses to a smooth one, a brisk one (pelvis faster than
    ``brisk_pelvis_speed``) to an unhurried one, and among equals the one nearest the target."""
    from jaxmotion.pipelines.affordance import select_motion

    t = 30
    base = np.zeros((t, 22, 3), np.float32)
    base[:, :, 2] = np.linspace(0.0, 1.6, 22)[None]  # a standing column of joints

    def walk(speed, end_x, jump=False):
        x = end_x - speed * (t - 1 - np.arange(t)) / 30.0
        m = base.copy()
        m[:, :, 0] += x[:, None]
        if jump:
            m[15:, :, 0] += 0.5  # one 0.5 m jump at frame 15: 15 m/s
        return m

    points = np.array([[1.0, 0.0, 0.5], [9.0, 9.0, 0.0]], np.float32)  # the target, something else
    target = np.array([True, False])
    mask = np.ones(t, bool)
    near_fast = walk(2.5, 0.95)  # ends 5 cm from the target, but at 2.5 m/s
    far_slow = walk(1.0, 0.7)  # ends 30 cm away at 1 m/s
    near_jump = walk(1.0, 0.45, jump=True)  # ends 5 cm away (after the jump), teleports
    cands = np.stack([near_jump, near_fast, far_slow])[None]
    args = (points[None], target[None], mask[None])
    pick = lambda c, **kw: np.asarray(select_motion(jnp.asarray(c), *args, **kw))[0]
    np.testing.assert_array_equal(pick(cands), near_fast)  # no envelope: the nearest smooth one
    np.testing.assert_array_equal(pick(cands, brisk_pelvis_speed=2.0), far_slow)
    np.testing.assert_array_equal(pick(cands[:, :2], brisk_pelvis_speed=2.0), near_fast)
    np.testing.assert_array_equal(pick(cands[:, :1], brisk_pelvis_speed=2.0), near_jump)


def test_furniture_frames_counts_frames_with_a_joint_inside_a_box():
    """A body walking through a table's box (shrunk 5 cm) for a known stretch; the target
    excluded, passable objects and padded frames ignored; checked against a frame loop."""
    from jaxmotion.eval.furniture import furniture_frames

    t = 40
    joints = np.zeros((t, 22, 3))
    joints[:, :, 0] = np.linspace(0.0, 4.0, t)[:, None]  # along x, 0.1 m per frame
    joints[:, :, 1] = 0.5
    joints[:, :, 2] = np.linspace(0.1, 1.6, 22)[None]
    table = {"id": 3, "category": "table", "bbox_min": [1.0, 0.0, 0.0],
             "bbox_max": [2.0, 1.0, 0.75]}
    door = {"id": 0, "category": "door", "bbox_min": [-1, -1, 0], "bbox_max": [5, 5, 2]}
    thin = {"id": 5, "category": "picture", "bbox_min": [3, 0, 0], "bbox_max": [3.05, 1, 2]}
    x = joints[:, 0, 0]
    want = np.mean((x > 1.05) & (x < 1.95))
    got = furniture_frames(joints, [table, door, thin])
    assert got == pytest.approx(want) and 0.2 < got < 0.25
    assert furniture_frames(joints, [table], exclude=[3]) == 0.0
    mask = np.arange(t) < 20  # frames 0-19: x up to 1.95
    assert furniture_frames(joints, [table], mask=mask) == pytest.approx(
        np.mean(((x > 1.05) & (x < 1.95))[:20]))
    both = furniture_frames(np.stack([joints, joints + [0, 5, 0]]), [table])
    np.testing.assert_allclose(both, [want, 0.0])
    with pytest.raises(ValueError, match="joints must be"):
        furniture_frames(joints[0], [table])


def test_contact_frames_matches_brute_force_distances():
    """Frames with a joint within 4 cm of another object's points, against a loop over every
    joint and point; the target, passable objects and structure excluded; masks and leading
    axes as furniture_frames."""
    from jaxmotion.eval.furniture import contact_frames

    rng = np.random.default_rng(0)
    xyz = rng.uniform([0, 0, 0], [3, 3, 1], (400, 3))
    instance = rng.integers(0, 4, 400)
    objects = [{"id": 0, "category": "floor"}, {"id": 1, "category": "chair"},
               {"id": 2, "category": "table"}, {"id": 3, "category": "door"}]
    joints = rng.uniform([0, 0, 0], [3, 3, 1], (2, 30, 22, 3))

    def brute(j, exclude):
        keep = np.isin(instance, [1, 2]) & ~np.isin(instance, exclude)
        d = np.linalg.norm(j[..., None, :] - xyz[keep], axis=-1).min(-1)
        return (d < 0.04).any(-1).mean(-1)

    got = contact_frames(joints, xyz, instance, objects)
    np.testing.assert_allclose(got, brute(joints, []))
    assert 0.05 < got.min() and got.max() < 0.95  # the check sees both kinds of frame
    np.testing.assert_allclose(contact_frames(joints, xyz, instance, objects, exclude=[2]),
                               brute(joints, [2]))
    mask = np.arange(30) < 10
    np.testing.assert_allclose(contact_frames(joints, xyz, instance, objects, mask=mask),
                               brute(joints[:, :10], []))
    assert contact_frames(joints[0], xyz, instance, objects, exclude=[1, 2]) == 0.0
    with pytest.raises(ValueError, match="one instance id per point"):
        contact_frames(joints, xyz, instance[:-1], objects)


def _foot_faults_reference(joints, mask, fps=30.0, h=0.05, v=0.5, sink=0.03):
    """Frame-pair loop of :func:`jaxmotion.eval.skating.foot_faults`."""
    from jaxmotion.eval.skating import FOOT_FLOOR_OFFSETS, FOOT_JOINTS

    off = np.asarray(FOOT_FLOOR_OFFSETS)
    bad, n = 0, 0
    for t in range(len(joints) - 1):
        if not (mask[t] and mask[t + 1]):
            continue
        n += 1
        slides = False
        for f, j in enumerate(FOOT_JOINTS):
            a, b = joints[t, j], joints[t + 1, j]
            if a[2] - off[f] < h and b[2] - off[f] < h and np.hypot(*(b[:2] - a[:2])) * fps > v:
                slides = True
        lowest = min(joints[t + 1, j, 2] - off[f] for f, j in enumerate(FOOT_JOINTS))
        bad += slides or lowest > h or lowest < -sink
    return bad / n


def test_foot_faults_matches_a_frame_loop_and_counts_slides_hovers_and_sinks():
    from jaxmotion.eval.skating import FOOT_FLOOR_OFFSETS, FOOT_JOINTS, foot_faults

    t = 40
    planted = np.zeros((t, 22, 3), np.float32)
    planted[:, :, 2] = 0.9
    planted[:, list(FOOT_JOINTS), 2] = np.asarray(FOOT_FLOOR_OFFSETS)[None]
    assert float(foot_faults(planted)) == 0.0
    hover = planted.copy()
    hover[10:20, list(FOOT_JOINTS), 2] += 0.2  # both feet in the air for 10 frames
    assert float(foot_faults(hover)) == pytest.approx(10 / (t - 1))
    sunk = planted.copy()
    sunk[30:, list(FOOT_JOINTS), 2] -= 0.1  # the feet 10 cm under the floor
    assert float(foot_faults(sunk)) == pytest.approx(10 / (t - 1))
    slide = planted.copy()
    slide[:, :, 0] += np.arange(t)[:, None] * 0.05  # 1.5 m/s with the feet on the floor
    assert float(foot_faults(slide)) == 1.0

    rng = np.random.default_rng(0)
    for _ in range(5):
        j = planted + rng.normal(0, 0.04, planted.shape).astype(np.float32)
        mask = rng.random(t) > 0.2
        got = float(jax.jit(foot_faults)(j, mask))
        assert got == pytest.approx(_foot_faults_reference(j, mask), abs=1e-6)
    assert np.isnan(float(foot_faults(planted, np.zeros(t, bool))))


def test_select_motion_with_feet_keeps_the_planted_feet_among_those_near_the_target():
    """``feet=True``: among candidates within ``GOAL_SLACK`` of the closest, the one whose
    feet slide, hover or sink least; one further away does not compete however well planted."""
    from jaxmotion.eval.skating import FOOT_FLOOR_OFFSETS, FOOT_JOINTS
    from jaxmotion.pipelines.affordance import GOAL_SLACK, select_motion

    t = 30
    stand = np.zeros((t, 22, 3), np.float32)
    stand[:, :, 2] = np.linspace(0.0, 1.6, 22)[None]
    stand[:, list(FOOT_JOINTS), 2] = np.asarray(FOOT_FLOOR_OFFSETS)[None]
    points = np.array([[1.0, 0.0, 0.5]], np.float32)
    target, mask = np.array([True]), np.ones(t, bool)

    def at(x, hover=0.0):
        m = stand.copy()
        m[:, :, 0] += x
        m[:, list(FOOT_JOINTS), 2] += hover
        return m

    closest_hovering = at(1.0, hover=0.15)  # touches the target, feet 15 cm in the air
    near_planted = at(1.0 - 0.5 * GOAL_SLACK)  # a little further, feet on the floor
    far_planted = at(1.0 - 5 * GOAL_SLACK)  # far: does not compete
    cands = jnp.asarray(np.stack([far_planted, closest_hovering, near_planted])[None])
    args = (points[None], target[None], mask[None])
    assert int(select_motion(cands, *args, return_index=True)[0]) == 1
    assert int(select_motion(cands, *args, feet=True, return_index=True)[0]) == 2
    assert int(select_motion(cands[:, :2], *args, feet=True, return_index=True)[0]) == 1


def test_off_floor_counts_a_pelvis_beyond_the_wall_and_select_motion_avoids_it():
    """A pelvis more than 0.5 m (xy) from every floor point and target point is off the floor
    (checked against a loop); a walk from beyond the room's wall loses to one on its floor."""
    from jaxmotion.pipelines.affordance import OFF_FLOOR, off_floor, select_motion

    g = np.arange(0.0, 3.0, 0.1)
    floor = np.array([[x, y, 0.0] for x in g for y in g], np.float32)  # the room: x, y in [0, 3)
    seat = np.array([[x, y, 0.45] for x in (2.0, 2.2) for y in (2.0, 2.2)], np.float32)
    post = np.array([[1.5, 1.3, 0.5], [1.5, 1.3, 1.0]], np.float32)  # a thin obstacle
    points = np.concatenate([floor, seat, post])  # a scan open to the west: no wall points
    target = np.r_[np.zeros(len(floor), bool), np.ones(len(seat), bool), np.zeros(2, bool)]
    t = 30
    base = np.zeros((t, 22, 3), np.float32)
    base[:, :, 2] = np.linspace(0.0, 1.6, 22)[None]

    def walk(start, end):
        m = base.copy()
        m[:, :, :2] += np.linspace(start, end, t)[:, None, :]
        return m

    inside = walk([1.0, 1.0], [2.0, 1.6])  # brushes the post for two frames
    through = walk([-1.2, 1.5], [2.0, 1.6])  # starts 1.2 m beyond the room's edge at x = 0
    cands = np.stack([through, inside])[None]
    got = np.asarray(off_floor(jnp.asarray(cands), points[None], target[None]))[0]
    for m in range(2):  # a loop over frames and points
        for f in range(t):
            d = np.hypot(*(points[:, :2] - cands[0, m, f, 0, :2]).T)
            ground = (points[:, 2] < 0.05) | target
            assert got[m, f] == (d[ground].min() > OFF_FLOOR)
    assert not got[1].any() and got[0].sum() == 7  # x < -0.5 m: frames 0-6
    on_seat = walk([2.1, 2.1], [2.1, 2.1])
    on_seat[:, 0, :2] = 2.1  # over the seat's points: the target is floor enough
    assert not np.asarray(off_floor(jnp.asarray(on_seat[None, None]), points[None],
                                    target[None])).any()
    avoid = (points[:, 2] > 0.1) & ~target
    pick = select_motion(jnp.asarray(cands), points[None], target[None], np.ones((1, t), bool),
                         avoid=avoid[None], return_index=True)
    assert int(pick[0]) == 1  # 2 frames at the post beat 7 beyond the floor
