"""The geometric action judge: hand-built seated / lying / standing poses from the rest
skeleton, and the synthetic world's own ground-truth motions (fast: one per action;
``slow``: ten per action, with the acceptance rates printed)."""

import jax
import numpy as np
import pytest

from jaxmotion.eval.action_judge import (
    ACTIONS,
    SEAT_HEIGHT_BAND,
    action_id,
    action_report,
    judge_action,
    judge_actions,
)
from jaxmotion.geometry.skeleton import rest_joints_host
from jaxmotion.motion import kinematics as K

REST = rest_joints_host()
CHAIR_MIN, CHAIR_MAX = np.array([1.0, 1.0, 0.0]), np.array([1.45, 1.45, 0.95])  # backrest top
SEAT = 0.45  # chair seat surface
BED_MIN, BED_MAX = np.array([3.0, 0.0, 0.0]), np.array([5.1, 1.4, 1.1])  # headboard top
MATTRESS = 0.52


def pose(local_updates, root, pelvis_at=None, feet_on_floor=False):
    """FK of the rest skeleton: ``local_updates`` {joint: 3x3}, root rotation; then moved so
    the pelvis is at ``pelvis_at`` (and, with ``feet_on_floor``, the toes 2.5 cm up)."""
    local = np.tile(np.eye(3), (1, 22, 1, 1))
    local[0, 0] = root
    for j, r in local_updates.items():
        local[0, j] = r
    p = K.fk_numpy(local, np.zeros((1, 3)), REST)[0]
    p = p - p[0] + np.asarray(pelvis_at, float)
    if feet_on_floor:
        p[:, 2] += 0.025 - p[[10, 11], 2].min()
    return p.astype(np.float32)


def standing(xy, heading=0.0):
    return pose({}, K.upright(heading), [*xy, 0.0], feet_on_floor=True)


def seated(xy, height, heading=0.0):
    """Hips flexed 90 deg, knees 90 deg: thighs horizontal, shins vertical."""
    bend = {1: K.rx(-np.pi / 2), 2: K.rx(-np.pi / 2), 4: K.rx(np.pi / 2), 5: K.rx(np.pi / 2)}
    return pose(bend, K.upright(heading), [*xy, height])


def lying(xy, height, heading=0.0):
    """Supine, legs towards ``heading`` (the character's lying pitch, 2.3 deg off flat)."""
    return pose({}, K.upright(heading) @ K.rx(-np.pi / 2 + 0.04), [*xy, height])


def chair_points(seed=0):
    """Seat top at SEAT, a backrest along y = 1.45 (above the seat), legs down to the floor."""
    rng = np.random.default_rng(seed)
    seat = np.c_[rng.uniform(1.0, 1.45, (300, 2)), np.full(300, SEAT)]
    back = np.c_[rng.uniform(1.0, 1.45, 100), np.full(100, 1.42), rng.uniform(SEAT, 0.95, 100)]
    legs = np.c_[np.full(40, 1.02), np.full(40, 1.02), rng.uniform(0.0, SEAT, 40)]
    return np.concatenate([seat, back, legs]).astype(np.float32)


def motion(*poses):
    return np.stack(poses)


def test_rest_built_poses_measure_as_designed():
    s = action_report(motion(standing([2.0, 2.0])), None, "walk", CHAIR_MIN, CHAIR_MAX)
    assert 1.05 < float(s["pelvis_height_ratio"]) < 1.2  # straight legs + pelvis above hips
    assert float(s["torso_elevation"]) > 80 and float(s["thigh_elevation"]) < -80
    assert abs(float(s["feet_height"])) < 1e-3
    c = action_report(motion(seated([1.2, 1.2], SEAT + 0.17)), None, "sit", CHAIR_MIN, CHAIR_MAX,
                      surface_height=SEAT)  # fmt: skip
    assert abs(float(c["thigh_elevation"])) < 5 and float(c["pelvis_height_ratio"]) < 0.9
    np.testing.assert_allclose(float(c["pelvis_above_surface"]), 0.17, atol=1e-5)
    lie = action_report(motion(lying([4.0, 0.7], MATTRESS + 0.11)), None, "lie", BED_MIN, BED_MAX)
    assert abs(float(lie["torso_elevation"])) < 5


def test_standing_near_is_a_walk_only():
    near = motion(standing([1.2, 0.75], heading=np.pi / 2))  # 0.25 m in front of the chair
    far = motion(standing([1.2, -0.6]))  # 1.6 m away
    assert bool(judge_action(near, None, "walk", CHAIR_MIN, CHAIR_MAX))
    assert not bool(judge_action(far, None, "walk", CHAIR_MIN, CHAIR_MAX))
    assert not bool(action_report(far, None, "walk", CHAIR_MIN, CHAIR_MAX)["near_box"])
    for other in ("sit", "stand_up", "lie"):
        assert not bool(judge_action(near, None, other, CHAIR_MIN, CHAIR_MAX, chair_points()))
    # Floating 20 cm above the floor: feet not on the floor.
    up = near.copy()
    up[..., 2] += 0.2
    r = action_report(up, None, "walk", CHAIR_MIN, CHAIR_MAX)
    assert not bool(r["feet_on_floor"]) and not bool(r["success"])


def test_seated_on_the_chair():
    on = motion(seated([1.22, 1.2], SEAT + 0.17, heading=-np.pi / 2))
    pts = chair_points()
    r = action_report(on, None, "sit", CHAIR_MIN, CHAIR_MAX, pts)
    np.testing.assert_allclose(float(r["surface_height"]), SEAT, atol=1e-6)  # not the backrest
    assert bool(r["success"]) and bool(r["seated"]) and bool(r["knees_bent"])
    assert bool(judge_action(on, None, "stand up", CHAIR_MIN, CHAIR_MAX, pts))
    assert not bool(judge_action(on, None, "lie", CHAIR_MIN, CHAIR_MAX, pts))
    assert not bool(judge_action(on, None, "walk", CHAIR_MIN, CHAIR_MAX, pts))
    # Hovering half a metre above the seat, or seated 0.3 m beside the chair: no.
    hover = motion(seated([1.22, 1.2], SEAT + 0.5, heading=-np.pi / 2))
    r = action_report(hover, None, "sit", CHAIR_MIN, CHAIR_MAX, pts)
    assert float(r["pelvis_above_surface"]) > SEAT_HEIGHT_BAND[1] and not bool(r["success"])
    beside = motion(seated([0.7, 1.2], SEAT + 0.17))
    r = action_report(beside, None, "sit", CHAIR_MIN, CHAIR_MAX, surface_height=SEAT)
    assert not bool(r["over_footprint"]) and not bool(r["success"])
    # No point of the target under the pelvis: the surface is unknown and the check fails.
    r = action_report(beside, None, "sit", CHAIR_MIN, CHAIR_MAX, pts)
    assert np.isnan(float(r["surface_height"])) and not bool(r["seat_height_ok"])


def test_surface_height_sources():
    on = motion(seated([1.22, 1.2], SEAT + 0.17))
    box_top = action_report(on, None, "sit", CHAIR_MIN, CHAIR_MAX)  # no points: the box top
    np.testing.assert_allclose(float(box_top["surface_height"]), CHAIR_MAX[2])
    assert not bool(box_top["success"])  # 0.95 m backrest taken as the seat
    given = action_report(on, None, "sit", CHAIR_MIN, CHAIR_MAX, chair_points(), surface_height=0.3)
    np.testing.assert_allclose(float(given["surface_height"]), 0.3)
    # Padded points (point_mask False) are ignored, even a "surface" right under the pelvis.
    pts = np.concatenate([chair_points(), [[1.22, 1.2, SEAT + 0.15]]]).astype(np.float32)
    keep = np.r_[np.ones(len(pts) - 1, bool), False]
    r = action_report(on, None, "sit", CHAIR_MIN, CHAIR_MAX, pts, point_mask=keep)
    np.testing.assert_allclose(float(r["surface_height"]), SEAT, atol=1e-6)


def test_lying_on_the_bed():
    on = motion(lying([4.0, 0.7], MATTRESS + 0.11))
    r = action_report(on, None, "lie", BED_MIN, BED_MAX, surface_height=MATTRESS)
    assert bool(r["success"]) and bool(r["torso_horizontal"]) and bool(r["over_footprint"])
    for other in ("sit", "stand_up", "walk"):
        assert not bool(judge_action(on, None, other, BED_MIN, BED_MAX, surface_height=MATTRESS))
    floor = motion(lying([4.0, -0.6], 0.11))  # on the floor beside the bed
    r = action_report(floor, None, "lie", BED_MIN, BED_MAX, surface_height=MATTRESS)
    assert not bool(r["over_footprint"]) and not bool(r["lie_height_ok"]) and not bool(r["success"])
    sunk = motion(lying([4.0, 0.7], 0.2))  # 32 cm below the mattress top
    assert not bool(judge_action(sunk, None, "lie", BED_MIN, BED_MAX, surface_height=MATTRESS))


def test_anchor_frame_and_padding():
    stand = standing([1.2, 0.2], heading=np.pi / 2)
    sit = seated([1.22, 1.2], SEAT + 0.17, heading=-np.pi / 2)
    sit_motion = motion(stand, stand, sit, sit)
    rise_motion = sit_motion[::-1]
    kw = {"surface_height": SEAT}
    assert bool(judge_action(sit_motion, None, "sit", CHAIR_MIN, CHAIR_MAX, **kw))
    assert not bool(judge_action(sit_motion, None, "stand_up", CHAIR_MIN, CHAIR_MAX, **kw))
    assert bool(judge_action(rise_motion, None, "stand_up", CHAIR_MIN, CHAIR_MAX, **kw))
    assert not bool(judge_action(rise_motion, None, "sit", CHAIR_MIN, CHAIR_MAX, **kw))
    # Garbage after the last valid frame is not the anchor.
    padded = np.concatenate([sit_motion, np.full((3, 22, 3), np.nan, np.float32)])
    mask = np.r_[np.ones(4, bool), np.zeros(3, bool)]
    r = action_report(padded, mask, "sit", CHAIR_MIN, CHAIR_MAX, **kw)
    assert int(r["anchor"]) == 3 and bool(r["success"])
    none = action_report(sit_motion, np.zeros(4, bool), "sit", CHAIR_MIN, CHAIR_MAX, **kw)
    assert not bool(none["success"])


def test_action_names():
    assert [action_id(a) for a in ("walk", "sit", "stand up", "Stand_Up", "lie", 3)] == [
        0, 1, 2, 2, 3, 3]  # fmt: skip
    with pytest.raises(ValueError):
        action_id("dance")
    with pytest.raises(ValueError):
        action_report(np.zeros((4, 21, 3)), None, "sit", CHAIR_MIN, CHAIR_MAX)


def test_batch_and_jit_agree_with_single():
    pts = chair_points()
    cases = [
        ("sit", motion(seated([1.22, 1.2], SEAT + 0.17), seated([1.22, 1.2], SEAT + 0.17))),
        ("walk", motion(standing([1.2, 0.75]), standing([1.2, 0.75]))),
        ("lie", motion(lying([1.2, 1.2], SEAT + 0.1), lying([1.2, 1.2], SEAT + 0.1))),
        ("stand up", motion(seated([1.22, 1.2], SEAT + 0.17), standing([1.2, 0.2]))),
        ("sit", motion(standing([1.2, 0.75]), standing([1.2, 0.75]))),
    ]
    joints = np.stack([m for _, m in cases])
    mask = np.ones(joints.shape[:2], bool)
    mask[2, 1] = False
    lo, hi = np.tile(CHAIR_MIN, (5, 1)), np.tile(CHAIR_MAX, (5, 1))
    batch = judge_actions(joints, mask, [a for a, _ in cases], lo, hi, np.stack([pts] * 5))
    assert batch["success"].shape == (5,)
    by_id = judge_actions(joints, mask, np.array([1, 0, 3, 2, 1]), lo, hi, np.stack([pts] * 5))
    np.testing.assert_array_equal(by_id["success"], batch["success"])
    jitted = jax.jit(lambda j, m: action_report(j, m, "sit", CHAIR_MIN, CHAIR_MAX, pts))
    for i, (a, m) in enumerate(cases):
        one = action_report(m, mask[i], a, CHAIR_MIN, CHAIR_MAX, pts)
        for k, v in one.items():
            np.testing.assert_allclose(np.asarray(batch[k][i]), np.asarray(v), rtol=1e-5,
                                       atol=1e-6, err_msg=k)  # fmt: skip
        if a == "sit":
            again = jitted(m, mask[i])
            assert all(np.allclose(again[k], one[k], equal_nan=True) for k in one)
    assert np.asarray(batch["success"]).tolist() == [True, True, True, True, False]


# ----------------------------------------------------------------------------- ground truth
def ground_truth(action, seed, num_points=20_000):
    """One sample of the synthetic dataset's generator (as ``data/synth.py`` makes them):
    (joints [T,22,3], target object dict, target points [M,3], room)."""
    from jaxmotion.motion import MotionError, synthesize
    from jaxmotion.scene.instructions import NoUniqueReference, sample_task
    from jaxmotion.scene.rooms import room_to_scene, sample_room

    for attempt in range(50):
        rng = np.random.default_rng([seed, attempt])
        room = sample_room(rng)
        try:
            _, info = sample_task(room, rng, action=action)
            m = synthesize(action, room.floor_rects, room.objects, info["target_id"], rng)
        except (ValueError, MotionError, NoUniqueReference):
            continue
        scene = room_to_scene(room, num_points, np.random.default_rng([seed, attempt, 1]))
        obj = room.object(info["target_id"])
        return m.joints, obj, scene.xyz[scene.instance == info["target_id"]], room
    raise RuntimeError(f"no {action} sample for seed {seed}")


def verdicts(joints, obj, pts):
    """{judged action: bool} for one ground-truth motion."""
    return {a: bool(judge_action(joints, None, a, obj["bbox_min"], obj["bbox_max"], pts))
            for a in ACTIONS}  # fmt: skip


# Mismatches that must be rejected (a stand-up ends standing near the seat, so it may
# pass as a walk; every other pair is a different body state at the anchor frame).
MISMATCHES = {"walk": ("sit", "stand_up", "lie"), "sit": ("walk", "stand_up", "lie"),
              "stand_up": ("sit", "lie"), "lie": ("walk", "sit", "stand_up")}  # fmt: skip


def test_ground_truth_samples_are_judged_right():
    for action in ACTIONS:
        joints, obj, pts, _ = ground_truth(action, seed=11)
        v = verdicts(joints, obj, pts)
        assert v[action], (action, obj["category"], v)
        assert not any(v[o] for o in MISMATCHES[action]), (action, obj["category"], v)


@pytest.mark.slow
def test_ground_truth_rates():
    n = 10
    hits = {a: [] for a in ACTIONS}
    wrong = {a: [] for a in ACTIONS}
    other_target = []
    for action in ACTIONS:
        for seed in range(100, 100 + n):
            joints, obj, pts, room = ground_truth(action, seed)
            v = verdicts(joints, obj, pts)
            hits[action].append(v[action])
            wrong[action] += [v[o] for o in MISMATCHES[action]]
            if action != "walk":  # the same motion judged on another seat / bed of the room
                for o in room.objects:
                    if o["id"] != obj["id"] and o.get("surface_height") is not None:
                        other_target.append(bool(judge_action(
                            joints, None, action, o["bbox_min"], o["bbox_max"],
                            surface_height=o["surface_height"])))  # fmt: skip
    rates = {a: float(np.mean(h)) for a, h in hits.items()}
    false = {a: float(np.mean(w)) for a, w in wrong.items()}
    print(
        "\nground truth accepted:",
        rates,
        "\nmismatches accepted:",
        false,
        "\nother targets accepted:",
        float(np.mean(other_target)),
        len(other_target),
    )
    assert min(rates.values()) >= 0.9
    assert max(false.values()) <= 0.05
    assert np.mean(other_target) <= 0.05
