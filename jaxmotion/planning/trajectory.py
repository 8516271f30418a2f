"""Root trajectories that follow a walking path: the object-centric models' trajectory
features (pelvis position and 6D orientation per frame, :mod:`jaxmotion.motion.representation`)
timed by a human speed profile.

The speed profile is the synthetic world's (:func:`jaxmotion.motion.pace.speed_profile`): from
rest, accelerating over ``accel`` seconds to the cruise ``speed``, slower on curves (sideways
acceleration at most 1.5 m/s², heading rate limited), stopping over ``decel`` seconds. The
pelvis stays at the body's standing height; the body faces along the path, turned smoothly
(the heading is the path's tangent, averaged over ~0.3 m), and holds ``start_heading`` /
``end_heading`` when given (facing a seat before sitting, say) by turning over the first /
last ``turn_time`` seconds.

A walking pelvis also turns within each step (:func:`walking_rhythm`, as the synthetic world's
walker): it rolls towards the stance foot and twists against the stride. The completion model
reads the gait's phase from that turning, so a root made by rule carries it too.
"""

from __future__ import annotations

import numpy as np

from jaxmotion.motion.pace import GaitParams, arc_length, speed_profile, wrap

__all__ = ["CRUISE_SPEED", "STEP_LENGTH", "path_trajectory", "trajectory_features",
           "walking_rhythm"]

#: Default cruise speed of the pelvis (m/s): the middle of the synthetic walks' 0.8–1.5 m/s.
CRUISE_SPEED = 1.1
#: Distance walked per step (m) that phases :func:`walking_rhythm`.
STEP_LENGTH = 0.65


def _gait(speed: float, accel: float, decel: float) -> GaitParams:
    return GaitParams(speed=speed, step_len=STEP_LENGTH, width=0.09, final_width=0.11, clearance=0.07,
                      heel_off=0.4, heel_strike=-0.17, accel=accel, decel=decel,
                      turn_rate=np.radians(175.0), toe_out=0.05, first_foot=0, turn_sign=1.0)


def walking_rhythm(xy, fps: float = 30.0, step_len: float = STEP_LENGTH):
    """How a walking pelvis turns within its steps along ``xy [T, 2]``: ``(roll [T],
    twist [T])`` in radians, about the body's forward and vertical axes, with the synthetic
    walker's amplitudes (:func:`jaxmotion.motion.segments.from_locomotion`): it rolls towards
    the stance foot once a stride (0.04 rad) and twists against the stride (0.08 rad). The
    phase is the distance walked over ``step_len``; both fade in with the speed (full from
    0.4 m/s) and are zero standing still."""
    from jaxmotion.motion.segments import PELVIS_ROLL, PELVIS_TWIST

    xy = np.asarray(xy, float)
    walked = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(xy, axis=0), axis=1))])
    speed = np.gradient(walked) * fps if len(xy) > 1 else np.zeros(len(xy))
    active = np.clip(speed / 0.4, 0.0, 1.0)
    phase = walked / step_len  # steps taken
    return (PELVIS_ROLL * np.sin(np.pi * phase) * active,
            -PELVIS_TWIST * np.cos(np.pi * phase) * active)


def trajectory_features(pelvis, heading, roll=None, twist=None) -> np.ndarray:
    """Trajectory features ``[T, 9]`` (pelvis xyz, 6D global orientation) of an upright body
    at ``pelvis [T, 3]`` facing ``heading [T]`` (radians from +x, counter-clockwise), rolled
    by ``roll [T]`` about its forward axis and twisted by ``twist [T]`` about its vertical
    axis (radians; None: 0), as the synthetic character's pelvis
    (:mod:`jaxmotion.motion.character`)."""
    from jaxmotion.geometry.rotations import matrix_to_rotation_6d
    from jaxmotion.motion.kinematics import ry, rz, upright

    rot = upright(np.asarray(heading, float))
    if roll is not None:
        rot = rot @ rz(np.asarray(roll, float))
    if twist is not None:
        rot = rot @ ry(np.asarray(twist, float))
    six = np.asarray(matrix_to_rotation_6d(np.asarray(rot, np.float32)), np.float32)
    return np.concatenate([np.asarray(pelvis, np.float32), six], axis=-1)


def path_trajectory(path, *, betas=None, fps: float = 30.0, speed: float = CRUISE_SPEED,
                    accel: float = 0.6, decel: float = 0.7, start_heading: float | None = None,
                    end_heading: float | None = None, turn_time: float = 0.6,
                    height: float | None = None) -> np.ndarray:
    """Trajectory features ``[T, 9]`` of a walk along ``path [M, 2]`` (xy, metres, from
    :func:`jaxmotion.planning.scene_path`), from rest to rest at ``fps``.

    Args:
      path: the ground path, first point the start.
      betas: ``[10]`` body shape for the standing pelvis height (None: the neutral body);
        ``height`` overrides it.
      speed, accel, decel: cruise speed (m/s), seconds to reach it and to stop.
      start_heading, end_heading: facing (radians) at the first / last frame; None: along
        the path.
      turn_time: seconds over which the body turns from / to them.
    Returns:
      ``[T, 9]`` float32, T ≥ 2.
    """
    path = np.asarray(path, float)
    if path.ndim != 2 or path.shape[1] != 2 or len(path) < 2:
        raise ValueError(f"path must be [M, 2] with M >= 2, got {path.shape}")
    if not (0.2 <= speed <= 2.5):
        raise ValueError(f"speed must be a walking speed in [0.2, 2.5] m/s, got {speed}")
    if height is None:
        from jaxmotion.diffusion.anchor_guidance import standing_height

        height = float(standing_height(betas))
    arc = arc_length(path)
    if arc[-1] < 1e-6:
        raise ValueError("the path has no length: start and goal coincide")
    t, s = speed_profile(path, _gait(speed, accel, decel))
    frames = np.arange(0.0, t[-1] + 1e-9, 1.0 / fps)
    sf = np.interp(frames, t, s)
    xy = np.stack([np.interp(sf, arc, path[:, 0]), np.interp(sf, arc, path[:, 1])], -1)
    # heading: the path's tangent averaged over ~0.3 m, read at each frame's arc length
    d = np.diff(path, axis=0)
    seg = np.unwrap(np.arctan2(d[:, 1], d[:, 0]))
    k = max(1, round(0.15 / max(float(np.diff(arc).mean()), 1e-6)))
    smooth = np.convolve(np.pad(seg, k, mode="edge"), np.ones(2 * k + 1) / (2 * k + 1), "valid")
    heading = np.interp(sf, 0.5 * (arc[:-1] + arc[1:]), smooth)
    n_turn = max(1, round(turn_time * fps))
    ramp = np.clip(np.arange(len(frames)) / n_turn, 0.0, 1.0)
    ramp = ramp * ramp * (3 - 2 * ramp)
    if start_heading is not None:
        delta = wrap(heading[0] - start_heading)
        heading = heading - (1.0 - ramp) * delta
    if end_heading is not None:
        delta = wrap(end_heading - heading[-1])
        heading = heading + (1.0 - ramp)[::-1] * delta
    pelvis = np.concatenate([xy, np.full((len(xy), 1), height)], -1)
    return trajectory_features(pelvis, heading, *walking_rhythm(xy, fps))
