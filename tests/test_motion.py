"""The procedural character and the four HUMANISE actions, against the acceptance criteria.

Rooms are made here (rectangular or L-shaped floors, furniture boxes with realistic
sizes, seats facing into the room). The fast test checks ~40 random motions; the
``slow`` one checks 240 and prints the statistics (``pytest -m slow -s``).
"""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from jaxmotion.geometry import JOINT_NAMES, rest_joints, smplx_joints
from jaxmotion.motion import (
    ACTIONS,
    MotionError,
    PlanningError,
    SeatUnreachable,
    UnsupportedTarget,
    synthesize,
)
from jaxmotion.motion import kinematics as K
from jaxmotion.motion.limits import LIMITS, joint_angles, limit_violations
from jaxmotion.motion.quality import report

# category: (size x, size y, height, surface height or None, has a front); sizes along x / y
# for a seat facing -y (beds: long along y, the foot end in front).
CATS = {
    "chair": ((0.42, 0.55), (0.42, 0.55), (0.8, 1.0), (0.42, 0.5), True),
    "armchair": ((0.7, 0.9), (0.7, 0.9), (0.75, 0.95), (0.38, 0.46), True),
    "sofa": ((1.6, 2.3), (0.8, 1.0), (0.75, 0.9), (0.38, 0.46), True),
    "bed": ((1.2, 1.8), (1.9, 2.2), (0.5, 1.0), (0.45, 0.6), True),
    "stool": ((0.3, 0.45), (0.3, 0.45), (0.45, 0.7), None, False),
    "toilet": ((0.4, 0.45), (0.6, 0.7), (0.75, 0.8), (0.4, 0.44), True),
    "table": ((0.8, 1.6), (0.7, 1.0), (0.7, 0.78), None, False),
    "cabinet": ((0.4, 1.0), (0.4, 0.6), (0.8, 2.0), None, False),
}
SEATS = ("chair", "armchair", "sofa", "bed", "stool", "toilet")


def random_room(rng):
    """A rectangular or L-shaped room with 4-8 non-overlapping pieces of furniture."""
    w, d = rng.uniform(4.5, 7.0), rng.uniform(4.5, 6.5)
    rects = [(0.0, 0.0, w, d)]
    if rng.random() < 0.4:
        rects = [(0.0, 0.0, w, 0.6 * d), (0.0, 0.0, 0.6 * w, d)]
    centre = np.array([0.4 * w, 0.4 * d])
    objs, boxes = [], []
    names = list(CATS)
    for k in range(int(rng.integers(4, 9))):
        cat = ("chair", "bed", "sofa")[k] if k < 3 else names[int(rng.integers(len(names)))]
        sx, sy, hz, sh, has_front = CATS[cat]
        size = np.array([rng.uniform(*sx), rng.uniform(*sy)])
        for _ in range(60):
            lo = np.array([rng.uniform(0, w - size.max()), rng.uniform(0, d - size.max())])
            # Seats face the room's centre (their front is the nearest axis direction).
            to_c = centre - (lo + 0.5 * size)
            ax = int(np.argmax(np.abs(to_c)))
            front = np.zeros(2)
            front[ax] = np.sign(to_c[ax])
            sz = size if ax == 1 else size[::-1]
            hi = lo + sz
            on_floor = any(
                lo[0] >= r[0] and lo[1] >= r[1] and hi[0] <= r[2] and hi[1] <= r[3] for r in rects
            )
            if not on_floor or any(
                np.all(lo < b[1] + 0.7) and np.all(hi > b[0] - 0.7) for b in boxes
            ):
                continue
            boxes.append((lo, hi))
            o = {
                "id": len(objs) + 1,
                "category": cat,
                "bbox_min": [*lo, 0.0],
                "bbox_max": [*hi, rng.uniform(*hz)],
            }
            if cat == "stool":
                o["surface_height"] = o["bbox_max"][2]
            elif sh is not None:
                o["surface_height"] = rng.uniform(*sh)
            if has_front:
                o["front"] = front.tolist()
            objs.append(o)
            break
    return rects, objs


def sample_motions(n, seed):
    """``n`` motions, round-robin over the actions, in random rooms (resampling failures)."""
    rng = np.random.default_rng(seed)
    out, failures = [], []
    k = 0
    while len(out) < n:
        action = ACTIONS[k % 4]
        k += 1
        rects, objs = random_room(rng)
        ok = [
            o
            for o in objs
            if action == "walk" or o["category"] in (("bed", "sofa") if action == "lie" else SEATS)
        ]
        target = ok[int(rng.integers(len(ok)))]
        try:
            m = synthesize(
                action, rects, objs, target["id"], np.random.default_rng(int(rng.integers(2**31)))
            )
        except MotionError as err:
            failures.append((action, type(err).__name__))
            continue
        out.append((m, objs, target))
    return out, failures


def check(m, objs, target):
    """All acceptance criteria for one motion; returns its report."""
    r = report(m, objs, target["id"])
    name = f"{m.action} on {target['category']}"
    assert r["joints"] == 22 and 30 <= r["frames"] <= 120, name
    assert r["floor_penetration"] <= 0.02, (name, r["floor_penetration"])
    assert r["planted_drift"] < 0.02, (name, r["planted_drift"])
    assert r["furniture_penetration"] <= 0.05, (name, r["furniture_penetration"])
    assert r["root_speed"] < 2.5, (name, r["root_speed"])
    assert r["bone_error"] < 1e-4, (name, r["bone_error"])
    assert not r["limit_violations"], (name, r["limit_violations"])
    if m.action in ("sit", "stand_up", "lie"):
        assert r["anchor_xy_dist"] <= 0.10, (name, r["anchor_xy_dist"])
        assert 0.0 <= r["anchor_height"] <= 0.30, (name, r["anchor_height"])
    if m.action in ("sit", "stand_up"):  # thighs near horizontal (high stools slope down)
        assert -45 <= r["anchor_thigh_elevation"] <= 20, (name, r["anchor_thigh_elevation"])
    if m.action == "lie":
        assert abs(r["anchor_torso_elevation"]) <= 20, (name, r["anchor_torso_elevation"])
    if m.action == "walk":  # HUMANISE: ends 0.1-0.2 m from the object, facing it within 30 deg
        assert 0.08 <= r["anchor_distance"] <= 0.22, (name, r["anchor_distance"])
        assert r["anchor_facing_error"] <= 30, (name, r["anchor_facing_error"])
    assert m.anchor_frame == (0 if m.action == "stand_up" else m.num_frames - 1)
    assert m.contacts.shape == (m.num_frames, 2)
    return r


def summarize(reports):
    keys = [
        "floor_penetration",
        "planted_drift",
        "foot_skate",
        "furniture_penetration",
        "root_speed",
        "anchor_height",
        "anchor_xy_dist",
        "anchor_thigh_elevation",
        "anchor_torso_elevation",
        "anchor_distance",
        "anchor_facing_error",
        "frames",
    ]
    lines = []
    for action in ACTIONS:
        rs = [r for a, r in reports if a == action]
        lines.append(f"{action}: {len(rs)} samples")
        for key in keys:
            v = [r[key] for r in rs if key in r]
            if v:
                lines.append(
                    f"  {key:24s} min {np.min(v):8.4f}  median {np.median(v):8.4f}"
                    f"  max {np.max(v):8.4f}"
                )
    return "\n".join(lines)


# ----------------------------------------------------------------------------- kinematics


def test_numpy_fk_matches_jax_fk():
    rng = np.random.default_rng(0)
    betas = np.clip(rng.normal(size=10), -2, 2)
    local = Rotation.random(5 * 22, random_state=1).as_matrix().reshape(5, 22, 3, 3)
    transl = rng.normal(size=(5, 3))
    rest = np.asarray(rest_joints(betas), np.float64)
    got = K.fk_numpy(local, transl, rest)
    aa = K.rotvec(local)
    want = np.asarray(smplx_joints(aa[:, 0], aa[:, 1:], transl, betas))
    np.testing.assert_allclose(got, want, atol=2e-5)
    np.testing.assert_allclose(K.jax_joints(aa[:, 0], aa[:, 1:], transl, betas), want, atol=1e-5)


def test_two_bone_ik_reaches_with_exact_lengths():
    rng = np.random.default_rng(1)
    body = K.make_body(np.zeros(10))
    u1 = K.normalize(body.rest[4] - body.rest[1])
    u2 = K.normalize(body.rest[7] - body.rest[4])
    m0 = K.normalize(np.cross(K.normalize(body.rest[7] - body.rest[1]), [0, 0, 1.0]))
    root = rng.normal(size=(50, 3))
    target = root + K.normalize(rng.normal(size=(50, 3))) * rng.uniform(0.1, 0.75, (50, 1))
    pole = rng.normal(size=(50, 3))
    g1, g2, mid, end = K.two_bone(root, target, pole, body.thigh[0], body.shin[0], u1, u2, m0)
    np.testing.assert_allclose(end, target, atol=1e-9)
    np.testing.assert_allclose(root + g1 @ (body.rest[4] - body.rest[1]), mid, atol=1e-9)
    np.testing.assert_allclose(mid + g2 @ (body.rest[7] - body.rest[4]), end, atol=1e-9)
    side = np.sum(
        (mid - root)
        * (
            pole
            - np.sum(pole * K.normalize(target - root), 1, keepdims=True)
            * K.normalize(target - root)
        ),
        1,
    )
    assert np.all(side > 0)  # the knee bends towards the pole
    far = root + np.array([0, 0, -2.0])  # out of reach: straight limb towards the target
    _, _, _, end = K.two_bone(root[:1], far[:1], pole[:1], body.thigh[0], body.shin[0], u1, u2, m0)
    np.testing.assert_allclose(np.linalg.norm(end - root[:1]), 0.9995 * body.leg[0], rtol=1e-9)


def test_limits_flag_broken_poses():
    pose = np.zeros((2, 21, 3))
    assert limit_violations(pose) == []
    pose[1, JOINT_NAMES.index("l_knee") - 1] = [-0.6, 0, 0]  # knee bent backwards 34 deg
    pose[1, JOINT_NAMES.index("neck") - 1] = [0, 2.5, 0]  # head turned 143 deg
    bad = {v[0] for v in limit_violations(pose)}
    assert bad == {"l_knee", "neck"}
    assert set(LIMITS) == set(JOINT_NAMES[1:])
    assert joint_angles(pose).shape == (2, 21, 3)


@pytest.mark.parametrize("side", ["l", "r"])
def test_elbow_flexion_beyond_90_degrees_is_read_as_flexion(side):
    """Flexion is the elbow's first Euler angle: 130° is not misread through gimbal flips."""
    j = JOINT_NAMES.index(f"{side}_elbow") - 1
    sign = -1.0 if side == "l" else 1.0  # the left forearm flexes about -y, the right about +y
    pose = np.zeros((3, 21, 3))
    pose[0, j] = [0, sign * np.radians(130), 0]  # deep flexion: fine
    pose[1, j] = [0, sign * np.radians(60), 0]
    pose[2, j] = [0, -sign * np.radians(40), 0]  # bent backwards 40 deg: broken
    ang = joint_angles(pose)[:, j]
    np.testing.assert_allclose(ang[:, 0], sign * np.array([130.0, 60.0, -40.0]), atol=1e-6)
    np.testing.assert_allclose(ang[:, 1:], 0.0, atol=1e-6)
    bad = limit_violations(pose)
    assert bad == [(f"{side}_elbow", 0, *bad[0][2:])] and abs(abs(bad[0][2]) - 40) < 1e-6


# ----------------------------------------------------------------------------- actions

ROOM = [(0.0, 0.0, 6.0, 5.0)]
OBJECTS = [
    {
        "id": 1,
        "category": "chair",
        "bbox_min": [1.0, 1.0, 0],
        "bbox_max": [1.5, 1.5, 0.9],
        "surface_height": 0.46,
        "front": [1, 0],
    },
    {"id": 2, "category": "table", "bbox_min": [3.0, 1.5, 0], "bbox_max": [4.2, 2.3, 0.75]},
    {
        "id": 3,
        "category": "bed",
        "bbox_min": [3.8, 3.0, 0],
        "bbox_max": [5.8, 4.6, 0.9],
        "surface_height": 0.55,
        "front": [-1, 0],
    },
    {
        "id": 4,
        "category": "sofa",
        "bbox_min": [0.1, 3.2, 0],
        "bbox_max": [2.1, 4.1, 0.85],
        "surface_height": 0.43,
        "front": [0, -1],
    },
    {"id": 5, "category": "lamp", "bbox_min": [5.5, 0.2, 2.0], "bbox_max": [5.9, 0.6, 2.4]},
]


@pytest.mark.parametrize("action,target", [("walk", 2), ("sit", 1), ("stand_up", 4), ("lie", 3)])
def test_motion_format_and_smplx_parameters(action, target):
    m = synthesize(action, ROOM, OBJECTS, target, np.random.default_rng(7))
    t = m.num_frames
    assert 30 <= t <= 120 and m.fps == 30 and m.action == action and m.target_id == target
    assert m.joints.shape == (t, 22, 3) and m.transl.shape == (t, 3)
    assert (
        m.global_orient.shape == (t, 3)
        and m.body_pose.shape == (t, 21, 3)
        and m.betas.shape == (10,)
    )
    assert np.all(np.abs(m.betas) <= 2)
    # The SMPL-X parameters reproduce the joints; joints[0] = rest pelvis + transl.
    again = np.asarray(smplx_joints(m.global_orient, m.body_pose, m.transl, m.betas))
    np.testing.assert_allclose(again, m.joints, atol=1e-5)
    np.testing.assert_allclose(
        m.joints[:, 0], np.asarray(rest_joints(m.betas))[0] + m.transl, atol=1e-5
    )
    check(m, OBJECTS, next(o for o in OBJECTS if o["id"] == target))


def test_same_seed_same_motion_and_variety():
    a = synthesize("sit", ROOM, OBJECTS, 1, np.random.default_rng(3))
    b = synthesize("sit", ROOM, OBJECTS, 1, np.random.default_rng(3))
    c = synthesize("sit", ROOM, OBJECTS, 1, np.random.default_rng(4))
    for name in ("joints", "transl", "global_orient", "body_pose", "betas"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name))
    assert not np.array_equal(a.betas, c.betas)
    assert a.num_frames != c.num_frames or not np.allclose(a.joints, c.joints)


def test_requests_that_cannot_be_met_raise_specific_errors():
    rng = np.random.default_rng(0)
    with pytest.raises(UnsupportedTarget):
        synthesize("lie", ROOM, OBJECTS, 1, rng)  # a chair is too short to lie on
    with pytest.raises(UnsupportedTarget):
        synthesize("sit", ROOM, OBJECTS, 2, rng)  # a table has no seat surface
    with pytest.raises(UnsupportedTarget):
        synthesize("walk", ROOM, OBJECTS, 99, rng)  # no such object
    with pytest.raises(ValueError):
        synthesize("dance", ROOM, OBJECTS, 1, rng)
    facing_wall = [
        {
            "id": 1,
            "category": "chair",
            "bbox_min": [0.3, 1, 0],
            "bbox_max": [0.8, 1.5, 0.9],
            "surface_height": 0.45,
            "front": [-1, 0],
        }
    ]
    with pytest.raises(SeatUnreachable):
        synthesize("sit", ROOM, facing_wall, 1, rng)
    boxed_in = [
        {"id": 1, "category": "cabinet", "bbox_min": [2.8, 2.3, 0], "bbox_max": [3.2, 2.7, 1.8]},
        {"id": 2, "category": "table", "bbox_min": [2.2, 1.7, 0], "bbox_max": [3.8, 2.1, 0.8]},
        {"id": 3, "category": "table", "bbox_min": [2.2, 2.9, 0], "bbox_max": [3.8, 3.3, 0.8]},
        {"id": 4, "category": "table", "bbox_min": [2.2, 2.1, 0], "bbox_max": [2.6, 2.9, 0.8]},
        {"id": 5, "category": "table", "bbox_min": [3.4, 2.1, 0], "bbox_max": [3.8, 2.9, 0.8]},
    ]
    with pytest.raises(PlanningError):
        synthesize("walk", ROOM, boxed_in, 1, rng)


def test_quality_checks_catch_defects():
    """The measurements are not vacuous: break a good motion and they notice."""
    from dataclasses import replace

    from jaxmotion.motion import quality

    m = synthesize("sit", ROOM, OBJECTS, 1, np.random.default_rng(5))
    assert quality.planted_drift(m) < 0.02 and quality.floor_penetration(m) <= 0.02
    j = m.joints.copy()
    run = np.flatnonzero(m.contacts[:, 0])[-10:]  # a planted stretch of the left foot
    j[run, 10, 0] += np.linspace(0, 0.05, len(run))  # ... sliding 5 cm
    j[run[-1], 7, 2] = -0.03  # ... and an ankle through the floor
    j[5, 20] = [3.6, 1.9, 0.4]  # a wrist 35 cm deep inside the table
    bad = replace(m, joints=j)
    assert quality.planted_drift(bad) > 0.04
    assert quality.floor_penetration(bad) > 0.09
    assert quality.furniture_penetration(bad, OBJECTS, 1) > 0.34
    assert quality.bone_error(bad) > 0.1


def test_quality_on_random_rooms():
    motions, failures = sample_motions(40, seed=11)
    reports = [(m.action, check(m, objs, target)) for m, objs, target in motions]
    assert len(failures) <= 0.3 * len(motions), failures  # resampling stays cheap
    assert len({round(float(m.betas[0]), 6) for m, _, _ in motions}) == len(
        motions
    )  # body shapes vary
    assert summarize(reports)


@pytest.mark.slow
def test_quality_on_many_random_rooms():
    motions, failures = sample_motions(240, seed=2024)
    reports = [(m.action, check(m, objs, target)) for m, objs, target in motions]
    print("\n" + summarize(reports))
    print("failures (resampled):", {a: sum(1 for f in failures if f[0] == a) for a in ACTIONS})
    assert len(failures) <= 0.3 * len(motions)
