"""Procedural stepping: heading, footsteps and foot trajectories along a planned path.

The pelvis path comes first (a planned path and its speed profile, see
:mod:`~jaxmotion.motion.pace`); footsteps are then placed where the pelvis will
be at each step's mid-stance, offset to the side of the stepping foot. This
keeps the feet under the body for any speed profile, including starting,
stopping and turning on the spot, and it ends with both feet at the final
stance. A foot is turned to the heading just after it lands, so that while
turning the two feet never differ by more than one step's rotation (at most
:data:`~jaxmotion.motion.pace.TURN_PER_STEP`) and the hips never over-twist.

Timing (step period ``T = step_len / speed`` when walking, shorter when turning
on the spot): consecutive lift-offs of the two feet are ``T`` apart; a swing
lasts ``0.8 T`` so each foot is on the ground ``1.2 T`` of every ``2 T`` stride
(double support ``0.2 T``). A swinging foot is lifted, carried (peak speed ~1.7x
its mean) and set down.

Each foot is described per frame by its *flat* pose (ankle xy, lift above the
floor, yaw) and a pitch ``beta``: ``beta > 0`` raises the heel about the toe
joint (heel-off, toe-off), ``beta < 0`` raises the toes about the heel point
(heel strike). The pivot never goes below the floor, so neither does the foot.
``contact`` marks frames where the toe joint is planted (flat foot or heel-off).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.ndimage import gaussian_filter1d

from jaxmotion.motion.pace import (
    GaitParams,
    arc_length,
    sample_gait,
    smoothstep,
    speed_profile,
    wrap,
)

__all__ = [
    "GaitParams",
    "Locomotion",
    "locomote",
    "sample_gait",
    "smoothstep",
    "speed_profile",
    "wrap",
]

SWING, LOAD_TIME = 0.8, 0.1  # swing fraction of T; heel-strike-to-flat duration (s)


@dataclass
class Locomotion:
    """A stepping segment sampled at ``fps``; arrays have ``n`` frames.

    Attributes:
      center: ``[n,2]`` pelvis path point (before sway). heading: ``[n]`` rad.
      speed: ``[n]`` pelvis speed, m/s. sway: ``[n]`` lateral pelvis shift (m, + left).
      bob: ``[n]`` vertical pelvis offset (m): highest at mid-stance, lowest in double support.
      foot_xy: ``[n,2,2]`` flat ankle xy; lift: ``[n,2]`` (m); yaw: ``[n,2]``; beta: ``[n,2]``.
      contact: ``[n,2]`` bool, toe joint planted. fore_aft: ``[n]`` (left − right foot
      position along the heading) / step length, drives arm swing and pelvis twist.
    """

    center: np.ndarray
    heading: np.ndarray
    speed: np.ndarray
    sway: np.ndarray
    bob: np.ndarray
    foot_xy: np.ndarray
    lift: np.ndarray
    yaw: np.ndarray
    beta: np.ndarray
    contact: np.ndarray
    fore_aft: np.ndarray

    @property
    def n(self) -> int:
        return len(self.heading)


def _heading_track(t, s, path, length, g, h0, h_end):
    """Rate-limited heading over time: path tangent, blended to ``h_end`` near the goal."""
    if len(path) > 1:
        d = np.gradient(path, axis=0)
        k = 5  # ~10 cm box smoothing of the tangent
        d = np.stack(
            [
                np.convolve(np.pad(d[:, i], k, mode="edge"), np.ones(2 * k + 1), "valid")
                for i in (0, 1)
            ],
            1,
        )
        tang = np.unwrap(np.arctan2(d[:, 1], d[:, 0]))
        ht = np.interp(s, arc_length(path), tang)
    else:
        ht = np.full_like(t, h0)
    if h_end is None:
        h_end = ht[-1]
    delta = wrap(h_end - ht[-1])
    if abs(delta) > np.radians(150):
        delta = g.turn_sign * (2 * np.pi - abs(delta)) if np.sign(delta) != g.turn_sign else delta
    zone = 0.7  # start turning to the final heading this far (m) before the end
    w_end = smoothstep((s - (length - zone)) / zone) if length > 1e-3 else np.ones_like(s)
    w_start = 1.0 - smoothstep(t / 0.6)
    target = ht + w_end * (ht[-1] + delta - ht) + w_start * wrap(h0 - ht[0])
    rate = g.max_turn_rate
    out = np.empty_like(target)
    out[0] = ht[0] + wrap(h0 - ht[0])
    dt = t[1] - t[0] if len(t) > 1 else 1.0
    step, prev, tgt = rate * dt, float(out[0]), target.tolist()
    for i in range(1, len(t)):  # plain floats: this loop runs ~3000 times per segment
        prev += max(-step, min(step, tgt[i] - prev))
        out[i] = prev
    return out, ht[-1] + delta


def locomote(
    path,
    g: GaitParams,
    feet_xy,
    feet_yaw,
    heading0,
    heading_end=None,
    delay=0.0,
    settle=0.3,
    fps=30,
    width_end=None,
    final_feet=None,
) -> Locomotion:
    """Walk along ``path`` (``[M,2]``, arc-length resampled) and stop, stepping as needed.

    Args:
      g: gait style. feet_xy: ``[2,2]`` initial flat ankle xy (left, right); feet_yaw: ``[2]``.
      heading0: initial facing (rad); heading_end: final facing (default: path end tangent).
      delay: standing time before the pelvis starts moving (s).
      settle: standing time after the last foot lands (s).
      width_end: lateral ankle offset of the final stance (default ``g.final_width``).
      final_feet: optional ``(xy [2,2], yaw [2])`` of the final stance, overriding it.
    Returns:
      :class:`Locomotion` at ``fps``; the last frame is standing still.
    """
    path = np.atleast_2d(np.asarray(path, float))
    length = float(arc_length(path)[-1])
    width_end = g.final_width if width_end is None else width_end
    T = g.period
    if length > 1e-3:
        tp, sp = speed_profile(path, g)
        tw = float(tp[-1])
        # Facing away from the path: turn on the spot first, then set off.
        d0 = path[min(5, len(path) - 1)] - path[0]
        turn0 = abs(wrap(np.arctan2(d0[1], d0[0]) - heading0))
        t_go = delay + max(0.0, turn0 - 0.5) / g.max_turn_rate
    else:
        tw, t_go = 0.0, delay
    # Fine time base for the pelvis (long enough for any turn and the last steps).
    dt = 1.0 / (fps * 10)
    horizon = t_go + tw + 2 * np.pi / g.max_turn_rate + 4 * T + settle + 1.0
    tf = np.arange(0.0, horizon, dt)
    s = np.interp(tf - t_go, tp, sp) if tw > 0 else np.zeros_like(tf)
    center_f = (
        np.stack([np.interp(s, arc_length(path), path[:, i]) for i in (0, 1)], 1)
        if length > 0
        else np.repeat(path[:1], len(tf), 0)
    )
    head_f, h_end = _heading_track(tf, s, path, length, g, heading0, heading_end)
    settled = np.abs(head_f - h_end) < np.radians(1.0)
    t_still = max(t_go + tw, tf[np.argmax(settled & (tf >= t_go + tw))] if settled[-1] else tf[-1])

    def at(tq, arr):
        return (
            np.interp(tq, tf, arr)
            if arr.ndim == 1
            else np.stack([np.interp(tq, tf, arr[:, i]) for i in range(arr.shape[1])], 1)
        )

    # Footsteps.
    holds_xy, holds_yaw = (
        [np.asarray(feet_xy, float).copy()[i] for i in (0, 1)],
        list(np.asarray(feet_yaw, float)),
    )
    speed_f = np.gradient(s, dt)
    steps, foot, t_lift, skipped = [], g.first_foot, delay + 0.05, 0
    for _ in range(60):
        # Quicker steps when turning on the spot than when walking.
        v = float(at(np.array([min(t_lift + 0.5 * T, tf[-1])]), speed_f)[0])
        Tk = g.turn_period + (T - g.turn_period) * float(np.clip(v / (0.6 * g.speed), 0.0, 1.0))
        t_land = t_lift + SWING * Tk
        t_mid = t_land + 0.6 * Tk
        final = t_mid >= t_still
        c = at(np.array([t_mid]), center_f)[0]
        h = float(at(np.array([min(t_mid, tf[-1])]), head_f)[0])
        # The foot turns to the heading soon after landing, not at mid-stance: in a
        # turn the two feet then differ by at most one step's rotation.
        h_foot = float(at(np.array([min(t_land + 0.2 * Tk, tf[-1])]), head_f)[0])
        side = 1.0 if foot == 0 else -1.0
        lat = side * (width_end if final else g.width)
        target = c + lat * np.array([-np.sin(h), np.cos(h)])
        yaw = (h if final else h_foot) + side * g.toe_out
        if final and final_feet is not None:
            target, yaw = np.asarray(final_feet[0][foot], float), float(final_feet[1][foot])
        dist = np.linalg.norm(target - holds_xy[foot])
        dyaw = abs(wrap(yaw - holds_yaw[foot]))
        if t_lift > t_still - Tk and dist < 0.025 and dyaw < np.radians(5):
            skipped += 1
            if skipped >= 2:
                break
        else:
            skipped = 0
            steps.append(
                {
                    "foot": foot,
                    "t_lift": t_lift,
                    "t_land": t_land,
                    "xy0": holds_xy[foot].copy(),
                    "yaw0": holds_yaw[foot],
                    "xy1": target,
                    "yaw1": holds_yaw[foot] + wrap(yaw - holds_yaw[foot]),
                    "dist": dist,
                    "T": Tk,
                }
            )
            holds_xy[foot], holds_yaw[foot] = target, steps[-1]["yaw1"]
        foot, t_lift = 1 - foot, t_lift + Tk
    t_end = max([st["t_land"] + LOAD_TIME for st in steps] + [t_still]) + settle
    n = int(np.ceil(t_end * fps)) + 1
    t = np.arange(n) / fps
    return _assemble(t, tf, center_f, head_f, s, steps, feet_xy, feet_yaw, g)


def _assemble(t, tf, center_f, head_f, s, steps, feet_xy, feet_yaw, g) -> Locomotion:
    n = len(t)
    center = np.stack([np.interp(t, tf, center_f[:, i]) for i in (0, 1)], 1)
    heading = np.interp(t, tf, head_f)
    speed = np.gradient(np.interp(t, tf, s), t) if n > 1 else np.zeros(n)
    xy = np.repeat(np.asarray(feet_xy, float)[None], n, 0)
    yaw = np.repeat(np.asarray(feet_yaw, float)[None], n, 0)
    lift, beta = np.zeros((n, 2)), np.zeros((n, 2))
    contact = np.ones((n, 2), bool)
    sway, bob = np.zeros(n), np.zeros(n)
    for st in steps:
        f, tl, td, T = st["foot"], st["t_lift"], st["t_land"], st["T"]
        r = np.clip((st["dist"] - 0.05) / 0.35, 0.0, 1.0)
        # Stance before this step: hold, then heel-off about the toe.
        pre = 0.35 * T * r
        m = (t >= tl - pre) & (t < tl)
        if pre > 0:
            beta[m, f] = np.maximum(
                beta[m, f], g.heel_off * r * smoothstep((t[m] - (tl - pre)) / pre)
            )
        # Swing.
        m = (t >= tl) & (t < td)
        u = (t[m] - tl) / (td - tl)
        uh = np.clip((u - 0.06) / 0.86, 0.0, 1.0)  # lift, carry, set down
        mj = 0.5 * smoothstep(uh) + 0.25 * (1 - np.cos(np.pi * uh))  # peak speed ~1.7x the mean
        xy[m, f] = st["xy0"] + mj[:, None] * (st["xy1"] - st["xy0"])
        yaw[m, f] = st["yaw0"] + mj * (st["yaw1"] - st["yaw0"])
        lift[m, f] = g.clearance * np.clip(st["dist"] / 0.3, 0.5, 1.0) * np.sin(np.pi * u) ** 1.5
        beta[m, f] = np.where(
            u < 0.5,
            g.heel_off * r * (1 - smoothstep(u / 0.5)),
            g.heel_strike * r * smoothstep((u - 0.5) / 0.5),
        )
        contact[m, f] = False
        # After landing: hold the new foothold; heel strike rolls flat.
        m = t >= td
        xy[m, f], yaw[m, f] = st["xy1"], st["yaw1"]
        m = (t >= td) & (t < td + LOAD_TIME)
        beta[m, f] = g.heel_strike * r * (1 - smoothstep((t[m] - td) / LOAD_TIME))
        contact[m, f] = r == 0
        # Pelvis sways over, and rises above, the stance foot at mid-stance.
        x = (t - (td + 0.6 * T)) / T
        bump = np.where(np.abs(x) < 1, 0.5 * (1 + np.cos(np.pi * x)), 0.0)
        side = 1.0 if f == 0 else -1.0
        wk = np.clip(st["dist"] / g.step_len, 0.2, 1.0)
        sway += side * bump * wk
        bob += np.where(np.abs(x) < 0.5, np.cos(np.pi * x) ** 2, 0.0) * wk
    activity = np.clip(speed / 0.4, 0, 1)
    walking = np.zeros(n)
    if steps:  # smooth envelope of the stepping period: the pelvis dips while stepping
        T = g.period
        t0, t1 = steps[0]["t_lift"] - 0.3 * T, steps[-1]["t_land"] + 0.2 * T
        walking = smoothstep((t - t0) / (0.5 * T)) * (1 - smoothstep((t - t1) / (0.5 * T)))
    bob = 0.022 * (bob - walking) - 0.012 * activity * g.speed / 1.5
    fwd = np.stack([np.cos(heading), np.sin(heading)], 1)
    fore_aft = np.sum((xy[:, 0] - xy[:, 1]) * fwd, 1) / g.step_len
    # Arms and pelvis follow the stride as a whole, not the quick swing of a foot.
    fore_aft = (
        gaussian_filter1d(
            fore_aft, 0.3 * g.period * (len(t) - 1) / max(t[-1], 1e-9), mode="nearest"
        )
        if n > 1
        else fore_aft
    )
    return Locomotion(
        center, heading, speed, 0.025 * sway, bob, xy, lift, yaw, beta, contact, fore_aft
    )
