"""Procedural human motions in rooms: the four HUMANISE actions on the SMPL-X body skeleton.

A kinematic character driven by joint rotations and root translation through the
foundation's forward kinematics (so bone lengths are exact): planned walking
paths (:mod:`~jaxmotion.motion.planner`), gait style and pacing
(:mod:`~jaxmotion.motion.pace`), stepping with planted feet
(:mod:`~jaxmotion.motion.gait`), two-bone leg IK and posture control
(:mod:`~jaxmotion.motion.character`), sitting, rising and lying
(:mod:`~jaxmotion.motion.segments`, :mod:`~jaxmotion.motion.seating`), joint
limits (:mod:`~jaxmotion.motion.limits`) and quality metrics
(:mod:`~jaxmotion.motion.quality`). Entry point: :func:`synthesize`.
"""

from jaxmotion.motion.actions import (
    ACTIONS,
    MAX_FRAMES,
    MIN_FRAMES,
    sample_betas,
    synthesize,
)
from jaxmotion.motion.character import Motion
from jaxmotion.motion.planner import MotionError, PlanningError, build_grid, plan_path
from jaxmotion.motion.seating import SeatUnreachable, UnsupportedTarget

__all__ = [
    "ACTIONS",
    "MAX_FRAMES",
    "MIN_FRAMES",
    "Motion",
    "MotionError",
    "PlanningError",
    "SeatUnreachable",
    "UnsupportedTarget",
    "build_grid",
    "plan_path",
    "sample_betas",
    "synthesize",
]
