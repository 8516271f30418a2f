"""Walking style and pacing: sampled gait parameters, pelvis speed along a path.

Lengths in metres, times in seconds, angles in radians.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = [
    "A_LAT",
    "TURN_PER_STEP",
    "GaitParams",
    "arc_length",
    "sample_gait",
    "smoothstep",
    "speed_profile",
    "wrap",
]

TURN_PER_STEP = np.radians(45.0)  # the most the heading turns during one turning step


def smoothstep(x):
    """C2 ramp 0 -> 1 on [0, 1] (quintic), clipped outside."""
    x = np.clip(x, 0.0, 1.0)
    return x * x * x * (10 - 15 * x + 6 * x * x)


def wrap(a):
    """Angles wrapped to [-pi, pi)."""
    return (np.asarray(a) + np.pi) % (2 * np.pi) - np.pi


@dataclass(frozen=True)
class GaitParams:
    """Sampled walking style. Lengths in metres, times in seconds, angles in radians."""

    speed: float  # cruise speed of the pelvis, m/s
    step_len: float  # distance per step at cruise speed
    width: float  # lateral ankle offset from the path while walking
    final_width: float  # lateral ankle offset of the final stance
    clearance: float  # swing lift of a full step
    heel_off: float  # toe-off pitch
    heel_strike: float  # heel-strike pitch (negative)
    accel: float  # time to reach cruise speed
    decel: float  # time to stop
    turn_rate: float  # max heading rate, rad/s
    toe_out: float  # extra outward yaw of each foot
    first_foot: int  # 0 = left foot steps first, 1 = right
    turn_sign: float  # direction of a ~180 deg turn (+1 ccw, -1 cw)

    @property
    def period(self) -> float:
        """Step period ``T`` (s)."""
        return self.step_len / self.speed

    @property
    def turn_period(self) -> float:
        """Step period when turning on the spot (s): quicker than walking steps."""
        return min(self.period, 0.45)

    @property
    def max_turn_rate(self) -> float:
        """Heading rate limit (rad/s): ``turn_rate``, and :data:`TURN_PER_STEP` a turning step."""
        return min(self.turn_rate, TURN_PER_STEP / self.turn_period)


def sample_gait(rng: np.random.Generator, leg: float) -> GaitParams:
    """Random walking style for a body whose hip-to-ankle reach is ``leg`` metres."""
    speed = rng.uniform(0.8, 1.5)
    rel = (speed - 0.8) / 0.7
    step = leg * np.clip(0.62 + 0.28 * rel + rng.normal(0, 0.04), 0.55, 0.95)
    return GaitParams(
        speed=speed,
        step_len=step,
        width=rng.uniform(0.075, 0.1),
        final_width=rng.uniform(0.09, 0.13),
        clearance=rng.uniform(0.05, 0.085),
        heel_off=np.radians(rng.uniform(18, 30)),
        heel_strike=-np.radians(rng.uniform(6, 14)),
        accel=rng.uniform(0.45, 0.8),
        decel=rng.uniform(0.5, 0.8),
        turn_rate=np.radians(rng.uniform(150, 200)),
        toe_out=np.radians(rng.uniform(0, 6)),
        first_foot=int(rng.integers(2)),
        turn_sign=float(rng.choice([-1.0, 1.0])),
    )


A_LAT = 1.5  # largest sideways acceleration on a curve, m/s^2


def speed_profile(path: np.ndarray, g: GaitParams, ds: float = 0.01):
    """Pelvis arc length over time along ``path`` ``[M,2]``: ``(t [K], s [K])``, from rest to rest.

    Cruise speed ``g.speed``, slower on curves (sideways acceleration at most
    :data:`A_LAT`, heading rate at most ``g.max_turn_rate``), accelerating over
    ``g.accel`` and stopping over ``g.decel`` seconds (then smoothed, ~0.1 s).
    """
    arc = arc_length(path)
    length = arc[-1]
    sg = np.linspace(0.0, length, max(2, int(np.ceil(length / ds)) + 1))
    d = np.diff(path, axis=0)
    head = np.unwrap(np.arctan2(d[:, 1], d[:, 0])) if len(d) else np.zeros(1)
    k = 7  # ~15 cm smoothing before differentiating
    head = np.convolve(np.pad(head, k, mode="edge"), np.ones(2 * k + 1) / (2 * k + 1), "valid")
    kappa = (
        np.abs(np.gradient(head, np.maximum(np.diff(arc).mean(), 1e-6)))
        if len(head) > 1
        else np.zeros(1)
    )
    kappa = np.interp(sg, 0.5 * (arc[:-1] + arc[1:]) if len(arc) > 1 else [0.0], kappa)
    rate = g.max_turn_rate
    vmax = np.minimum(
        g.speed,
        np.minimum(np.sqrt(A_LAT / np.maximum(kappa, 1e-6)), rate / np.maximum(kappa, 1e-6)),
    )
    v = vmax.tolist()
    v[0] = 0.0
    step = np.diff(sg)
    acc, dec, ds_ = g.speed / g.accel, g.speed / g.decel, float(step[0]) if len(step) else 0.0
    for i in range(1, len(v)):  # accelerate (uniform steps: plain floats are fast)
        v[i] = min(v[i], (v[i - 1] ** 2 + 2 * acc * ds_) ** 0.5)
    v[-1] = 0.0
    for i in range(len(v) - 2, -1, -1):  # brake
        v[i] = min(v[i], (v[i + 1] ** 2 + 2 * dec * ds_) ** 0.5)
    v = np.asarray(v)
    tg = np.concatenate([[0.0], np.cumsum(2 * step / np.maximum(v[:-1] + v[1:], 1e-3))])
    # Resample in time and smooth the velocity (finite jerk).
    dt = 0.01
    t = np.arange(0.0, tg[-1] + 0.3, dt)
    vel = np.gradient(np.interp(t, tg, sg), dt)
    ker = np.exp(-0.5 * (np.arange(-25, 26) * dt / 0.08) ** 2)
    vel = np.convolve(np.pad(vel, 25), ker / ker.sum(), "same")[25:-25]
    s = np.cumsum(vel) * dt
    return t, np.clip(s * length / max(s[-1], 1e-9), 0.0, length)


def arc_length(path: np.ndarray) -> np.ndarray:
    """Cumulative arc length ``[M]`` of a polyline ``[M,2]`` (starts at 0)."""
    return np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(path, axis=0), axis=1))])
