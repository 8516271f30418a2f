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

_HOMES = {"ACTIONS": "actions", "MAX_FRAMES": "actions", "MIN_FRAMES": "actions",
          "sample_betas": "actions", "synthesize": "actions", "Motion": "character",
          "MotionError": "planner", "PlanningError": "planner", "build_grid": "planner",
          "plan_path": "planner", "SeatUnreachable": "seating", "UnsupportedTarget": "seating"}

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


def __getattr__(name):  # imported when used: the models need only motion.representation
    if name in _HOMES:
        import importlib

        return getattr(importlib.import_module(f"jaxmotion.motion.{_HOMES[name]}"), name)
    raise AttributeError(f"module 'jaxmotion.motion' has no attribute {name!r}")
