"""Motion segments as :class:`~jaxmotion.motion.character.Controls`: stand, walk, sit, rise, lie.

Each segment starts exactly from the last frame of the previous one (a one-frame
``Controls`` state) and ends at rest, so concatenated segments are continuous.
Lengths in metres, angles in radians, durations in seconds, 30 fps.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from jaxmotion.motion import kinematics as K
from jaxmotion.motion.character import FPS, Controls
from jaxmotion.motion.gait import GaitParams, Locomotion, smoothstep, wrap

__all__ = [
    "PELVIS_ROLL",
    "PELVIS_TWIST",
    "Style",
    "foot_pose",
    "from_locomotion",
    "lie_down",
    "sample_style",
    "seated",
    "sit_down",
    "stand_up",
    "standing",
]

#: How the walker's pelvis turns within its steps (radians): rolled towards the stance foot at
#: a full sway (2.5 cm), twisted against the stride at a full fore-aft swing.
PELVIS_ROLL, PELVIS_TWIST = 0.04, 0.08


@dataclass(frozen=True)
class Style:
    """Per-motion posture style."""

    gaze_pitch: float  # standing gaze, down from horizontal
    arm_abduct: float  # arms out from the body
    elbow: float  # relaxed elbow flexion
    arm_amp: float  # arm swing per unit of foot fore-aft offset
    lean: float  # forward lean of the torso when walking at 1.5 m/s


def sample_style(rng: np.random.Generator) -> Style:
    """Random posture style."""
    return Style(
        gaze_pitch=rng.uniform(0.05, 0.25),
        arm_abduct=rng.uniform(0.05, 0.12),
        elbow=rng.uniform(0.12, 0.35),
        arm_amp=rng.uniform(0.25, 0.5),
        lean=rng.uniform(0.03, 0.12),
    )


def foot_pose(xy, lift, yaw, beta, body: K.Body, i: int):
    """Flat foot pose + pitch -> ankle target ``[n,3]`` and world foot rotation ``[n,3,3]``.

    ``beta > 0`` pivots about the toe joint (heel raised), ``beta < 0`` about the heel.
    """
    rflat = K.upright(yaw)
    ankle = np.concatenate([xy, (body.ankle_height[i] + lift)[:, None]], 1)
    toe = ankle + np.einsum("tij,j->ti", rflat, body.toe_off[i])
    heel_rest = np.array([0.0, 0.012 - body.ankle_height[i], -0.055])
    heel = ankle + np.einsum("tij,j->ti", rflat, heel_rest)
    left = np.stack([-np.sin(yaw), np.cos(yaw), np.zeros_like(yaw)], 1)
    rp = K.rot_axis(left, beta)
    pivot = np.where((beta > 0)[:, None], toe, heel)
    ankle = pivot + np.einsum("tij,tj->ti", rp, ankle - pivot)
    return ankle, rp @ rflat


def _n(x, n):
    return np.repeat(np.asarray(x, float)[None], n, 0)


def standing(body, style: Style, hip_xy, yaw, feet_xy, feet_yaw, n: int) -> Controls:
    """``n`` frames of a relaxed upright stance."""
    feet_xy, feet_yaw = np.asarray(feet_xy, float), np.asarray(feet_yaw, float)
    ankle, rot = zip(
        *(
            foot_pose(feet_xy[None, i], np.zeros(1), feet_yaw[i : i + 1], np.zeros(1), body, i)
            for i in (0, 1)
        )
    )
    hip = np.array([hip_xy[0], hip_xy[1], body.stand_height])
    z = np.zeros(n)
    return Controls(
        hip=_n(hip, n),
        yaw=z + yaw,
        pitch=z + 0.02,
        roll=z.copy(),
        twist=z.copy(),
        spine_flex=z + 0.02,
        spine_bend=z.copy(),
        spine_twist=z.copy(),
        gaze_yaw=z + yaw,
        gaze_pitch=z + style.gaze_pitch,
        head_world=z + 1,
        head_flex=z.copy(),
        ankle=_n(np.concatenate(ankle), n),
        foot_rot=_n(np.concatenate(rot), n),
        foot_rel=np.zeros((n, 2)),
        foot_flex=np.zeros((n, 2)),
        contact=np.ones((n, 2), bool),
        arm_swing=np.zeros((n, 2)),
        arm_abduct=np.zeros((n, 2)) + style.arm_abduct,
        elbow=np.zeros((n, 2)) + style.elbow,
        clamp=np.ones(n, bool),
    )


def from_locomotion(lo: Locomotion, body, g: GaitParams, style: Style, start: Controls) -> Controls:
    """Controls for a stepping segment; posture channels ease in from ``start``."""
    n = lo.n
    act = np.clip(lo.speed / 0.5, 0.0, 1.0)
    left = np.stack([-np.sin(lo.heading), np.cos(lo.heading)], 1)
    hip = np.concatenate(
        [lo.center + lo.sway[:, None] * left, (body.stand_height + lo.bob)[:, None]], 1
    )
    ankles, rots = [], []
    for i in (0, 1):
        a, r = foot_pose(lo.foot_xy[:, i], lo.lift[:, i], lo.yaw[:, i], lo.beta[:, i], body, i)
        ankles.append(a)
        rots.append(r)
    roll = PELVIS_ROLL * lo.sway / 0.025
    accel = np.gradient(lo.speed) * FPS
    lean = style.lean * lo.speed / 1.5 + 0.04 * np.clip(accel, -1.5, 1.5)
    ahead = np.concatenate([lo.heading[8:], np.repeat(lo.heading[-1:], min(8, n))])[:n]
    swing = style.arm_amp * np.clip(lo.fore_aft, -1.2, 1.2) * (0.15 + 0.85 * act)
    # The pelvis turns with the feet (their mean yaw, at most 6 deg towards the
    # heading); the spine and then the head carry the rest of a turn.
    feet = lo.yaw[:, 0] + 0.5 * wrap(lo.yaw[:, 1] - lo.yaw[:, 0])
    feet = lo.heading + wrap(feet - lo.heading)
    yaw = feet + np.clip(lo.heading - feet, -0.1, 0.1)
    c = Controls(
        hip=hip,
        yaw=yaw,
        pitch=0.02 + 0.3 * lean,
        roll=roll,
        twist=-PELVIS_TWIST * lo.fore_aft * act,
        spine_flex=0.02 + 0.7 * lean,
        spine_bend=-0.7 * roll,
        spine_twist=0.16 * lo.fore_aft * act + (lo.heading - yaw),
        gaze_yaw=lo.heading + 0.5 * wrap(ahead - lo.heading),
        gaze_pitch=style.gaze_pitch + 0.08 * act,
        head_world=np.ones(n),
        head_flex=np.zeros(n),
        ankle=np.stack(ankles, 1),
        foot_rot=np.stack(rots, 1),
        # In the air the foot relaxes towards the shin (no ankle roll on side steps).
        foot_rel=0.6 * smoothstep(lo.lift / 0.04),
        foot_flex=np.full((n, 2), 0.1),
        contact=lo.contact,
        arm_swing=np.stack([-swing, swing], 1),
        arm_abduct=np.zeros((n, 2)) + style.arm_abduct,
        elbow=style.elbow + 0.35 * np.maximum(np.stack([-swing, swing], 1), 0.0),
        clamp=np.ones(n, bool),
    )
    return _ease_from(
        start,
        c,
        (
            "pitch",
            "spine_flex",
            "gaze_pitch",
            "head_world",
            "head_flex",
            "elbow",
            "arm_abduct",
            "arm_swing",
        ),
    )


def _ease_from(start: Controls, c: Controls, names, time=0.4) -> Controls:
    """Blend the listed channels from ``start``'s values into ``c`` over ``time`` seconds."""
    w = smoothstep(np.arange(c.n) / (time * FPS))
    upd = {}
    for name in names:
        a, b = getattr(start, name)[0], getattr(c, name)
        ww = w.reshape((-1,) + (1,) * (b.ndim - 1))
        upd[name] = a + ww * (b - a)
    return replace(c, **upd)


def _bump(u, peak):
    """Smooth 0 -> 1 -> 0 over u in [0, 1], maximal at ``peak``."""
    return np.where(u < peak, smoothstep(u / peak), 1 - smoothstep((u - peak) / (1 - peak)))


def _blend(start: Controls, n: int, targets: dict, progress: dict, bumps: dict) -> Controls:
    """A transition: every channel holds ``start`` unless given a target (reached with its
    progress curve ``[n]``) and/or an additive bump ``[n]``."""
    out = start.hold(n)
    for name in ("yaw", "gaze_yaw"):  # headings: take the short way round
        if name in targets:
            targets[name] = getattr(start, name)[0] + wrap(targets[name] - getattr(start, name)[0])
    for name, target in targets.items():
        a = getattr(start, name)[0]
        w = progress.get(name, progress["default"]).reshape((-1,) + (1,) * np.ndim(a))
        setattr(out, name, a + w * (np.asarray(target, float) - a))
    for name, b in bumps.items():
        v = getattr(out, name)
        setattr(out, name, v + b.reshape((-1,) + (1,) * (v.ndim - 1)))
    return out


@dataclass(frozen=True)
class SeatPose:
    """A seated posture: hip centre ``[3]``, pelvis pitch, spine flexion, arm pose."""

    hip: np.ndarray
    yaw: float
    pitch: float
    spine_flex: float
    arm_swing: float
    elbow: float


def seated(spot, body: K.Body, style: Style, rng: np.random.Generator) -> tuple[Controls, SeatPose]:
    """The seated state on a :class:`~jaxmotion.motion.seating.SeatSpot` (one frame),
    hands resting on the thighs, and its :class:`SeatPose`."""
    tilt = spot.pitch + spot.spine_flex  # forward inclination of the chest
    swing = rng.uniform(0.15, 0.4)
    drop = (body.rest[16, 1] - body.hip_center[1]) * np.cos(tilt) - 0.09  # shoulder -> thigh top
    ua, fa = body.upper_arm.mean(), body.forearm.mean()
    c = np.clip((drop - ua * np.cos(swing + tilt)) / fa, -1.0, 1.0)
    elbow = float(np.clip(np.arccos(c) - swing - tilt, 0.15, 1.4))
    pose = SeatPose(spot.hip, spot.yaw, spot.pitch, spot.spine_flex, swing, elbow)
    st = standing(body, style, spot.hip[:2], spot.yaw, spot.feet_xy, spot.feet_yaw, 1)
    st.hip[:] = spot.hip
    st.pitch[:], st.spine_flex[:], st.gaze_pitch[:] = spot.pitch, spot.spine_flex, 0.12
    st.arm_swing[:], st.elbow[:], st.arm_abduct[:] = swing, elbow, 0.0
    return st, pose


def sit_down(start: Controls, seat: SeatPose, duration: float, lean: float) -> Controls:
    """Lower the hips from standing onto the seat, leaning forward on the way (feet planted)."""
    n = max(2, round(duration * FPS))
    u = np.arange(1, n + 1) / n
    uh = smoothstep(u / 0.85)  # the hips move back a little ahead of going down
    uv = smoothstep((u - 0.05) / 0.9)
    b = _bump(u, 0.45)
    out = _blend(
        start,
        n,
        targets={
            "hip": seat.hip,
            "pitch": seat.pitch,
            "spine_flex": seat.spine_flex,
            "gaze_pitch": 0.12,
            "arm_swing": [seat.arm_swing] * 2,
            "elbow": [seat.elbow] * 2,
            "arm_abduct": [0.0, 0.0],
            "yaw": seat.yaw,
            "gaze_yaw": seat.yaw,
        },
        progress={"default": uh, "pitch": uv, "spine_flex": uv, "hip": uh},
        bumps={
            "pitch": lean * b,
            "spine_flex": 0.3 * lean * b,
            "gaze_pitch": 0.15 * b,
            "arm_swing": 0.35 * b,
        },
    )
    out.hip[:, 2] = start.hip[0, 2] + uv * (seat.hip[2] - start.hip[0, 2])
    return out


def stand_up(
    start: Controls, hip_stand: np.ndarray, duration: float, lean: float, style: Style
) -> Controls:
    """Rise from the seat: lean forward, bring the hips over the feet, straighten up."""
    n = max(2, round(duration * FPS))
    u = np.arange(1, n + 1) / n
    # Lean forward on the seat first; the hips leave it near the lean's peak.
    uh = 0.08 * smoothstep(u / 0.35) + 0.92 * smoothstep((u - 0.22) / 0.6)
    uv = smoothstep((u - 0.3) / 0.65)
    b = _bump(u, 0.36)
    out = _blend(
        start,
        n,
        targets={
            "hip": hip_stand,
            "pitch": 0.02,
            "spine_flex": 0.02,
            "gaze_pitch": style.gaze_pitch,
            "arm_swing": [0.0, 0.0],
            "elbow": [style.elbow] * 2,
            "arm_abduct": [style.arm_abduct] * 2,
        },
        progress={"default": uv, "hip": uh, "arm_swing": u},
        bumps={
            "pitch": lean * b,
            "spine_flex": 0.3 * lean * b,
            "gaze_pitch": 0.1 * b,
            "arm_swing": 0.3 * b,
        },
    )
    out.hip[:, 2] = start.hip[0, 2] + uv * (hip_stand[2] - start.hip[0, 2])
    return out


def _leg_angles(body, i, hip_w, ankle_w, rp):
    """Sagittal hip and knee flexion (rad) that put the ankle where it is, pelvis frame."""
    v = rp.T @ (ankle_w - hip_w)
    l1, l2 = body.thigh[i], body.shin[i]
    dist = np.clip(np.hypot(v[1], v[2]), abs(l1 - l2) + 1e-3, l1 + l2 - 1e-3)
    psi = np.arctan2(v[2], -v[1])
    knee = np.pi - np.arccos(np.clip((l1**2 + l2**2 - dist**2) / (2 * l1 * l2), -1, 1))
    return psi + np.arccos(np.clip((l1**2 + dist**2 - l2**2) / (2 * l1 * dist), -1, 1)), knee


def lie_down(
    start: Controls, body, hip_lie, yaw_lie, surface, duration, head_flex, rng, room: float = np.inf
) -> Controls:
    """From sitting on an edge to lying supine, legs swung up onto the surface.

    The legs follow hip / knee flexion schedules in the pelvis frame (lift: hip
    flexion ~95 deg, knees half straight; then both extend as the torso goes
    down), so the feet clear the edge and the hip never over-flexes; at the
    start they blend from the planted feet, at the end onto the surface.

    Args:
      start: seated state (facing away from the surface).
      hip_lie: ``[3]`` final hip centre. yaw_lie: final heading (the legs point that way).
      surface: world z of the surface. head_flex: head flexion on the pillow (rad).
      room: free length (m) in front of the final hip centre along ``yaw_lie``; the
        knees bend up when the legs would not fit.
    """
    n = max(2, round(duration * FPS))
    u = np.arange(1, n + 1) / n
    s0 = start
    yaw0 = s0.yaw[0]
    yaw = yaw0 + wrap(yaw_lie - yaw0) * smoothstep((u - 0.15) / 0.65)
    ur = smoothstep((u - 0.12) / 0.88)
    uf = smoothstep(u / 0.25)
    hip = s0.hip[0] + smoothstep((u - 0.1) / 0.85)[:, None] * (np.asarray(hip_lie) - s0.hip[0])
    out = _blend(
        s0,
        n,
        targets={
            "pitch": -np.pi / 2 + 0.04,
            "spine_flex": 0.02,
            "head_world": 0.0,
            "head_flex": head_flex,
            "arm_swing": [0.05, 0.05],
            "elbow": [0.25, 0.25],
            "arm_abduct": [0.3, 0.3],
            "foot_rel": [1.0, 1.0],
            "foot_flex": [0.45, 0.45],
            "spine_twist": 0.0,
            "twist": 0.0,
            "roll": 0.0,
        },
        progress={"default": ur, "head_world": smoothstep((u - 0.2) / 0.6), "foot_rel": uf},
        bumps={},
    )
    out.yaw, out.gaze_yaw, out.hip = yaw, yaw, hip
    out.contact[:] = False
    out.clamp[:] = False
    rp = K.upright(yaw) @ K.rx(out.pitch) @ K.rz(out.roll) @ K.ry(out.twist)
    rp0 = K.upright(yaw0) @ K.rx(s0.pitch[0]) @ K.rz(s0.roll[0]) @ K.ry(s0.twist[0])
    lift_hip, lift_knee = rng.uniform(1.5, 1.7), rng.uniform(0.7, 1.0)
    for i, side in ((0, 1.0), (1, -1.0)):
        off = body.rest[K.HIP[i]] - body.hip_center
        hip_i = hip + np.einsum("tij,j->ti", rp, off)
        phi0, kap0 = _leg_angles(body, i, s0.hip[0] + rp0 @ off, s0.ankle[0, i], rp0)
        down = smoothstep((u - 0.45) / 0.55)
        phi = phi0 + smoothstep(u / 0.35) * (lift_hip - phi0) + down * (0.08 - lift_hip)
        kap = (
            kap0
            + smoothstep((u - 0.05) / 0.35) * (lift_knee - kap0)
            + smoothstep((u - 0.5) / 0.5) * (0.1 - lift_knee)
        )
        l1, l2 = body.thigh[i], body.shin[i]
        rel = np.stack(
            [
                np.full(n, side * 0.02),
                -l1 * np.cos(phi) - l2 * np.cos(phi - kap),
                l1 * np.sin(phi) + l2 * np.sin(phi - kap),
            ],
            1,
        )
        target = hip_i + np.einsum("tij,tj->ti", rp, rel)
        # Blend in from the planted foot (lifting it before moving it), out onto the surface.
        w = np.stack([smoothstep((u - 0.1) / 0.3)] * 2 + [uf], 1)
        target = s0.ankle[0, i] + w * (target - s0.ankle[0, i])
        fwd = np.array([np.cos(yaw_lie), np.sin(yaw_lie)])
        reach = min(0.993 * body.leg[i], max(room, 0.55 * body.leg[i]))
        end = np.array([*(hip_i[-1, :2] + reach * fwd), surface + body.ankle_height[i] - 0.02])
        w = smoothstep((u - 0.75) / 0.25)[:, None]
        out.ankle[:, i] = target + w * (end - target)
    return out
