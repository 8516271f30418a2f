"""Constants every stage shares, each defined once (light: imports nothing heavy).

- :data:`SCENE_FPS`: frame rate of scene-interaction motions (HUMANISE, the synthetic world,
  every motion ``generate`` makes): 30 frames per second.
- :data:`NUM_JOINTS`: the 22 SMPL-X body joints (order: :data:`jaxmotion.geometry.skeleton.JOINT_NAMES`).
- :data:`AFFORDANCE_JOINTS`, :data:`AFFORDANCE_SIGMA`: the affordance map's six joints (pelvis,
  feet, neck, wrists) and its Gaussian width σ = 0.8 m (paper eq. 1–2).
- :data:`TEXT_ENCODER`: the sentence encoder every model here reads (all-MiniLM-L6-v2).
- :data:`FOOT_JOINTS`: the foot joints of foot skating and foot contact (left / right ankle,
  left / right foot).
- :data:`PASSABLE`: object categories a body may pass through or touch (openings, things on
  walls, floor covers): never obstacles for paths or for choosing among candidate motions.
"""

from __future__ import annotations

__all__ = ["ACTION_CLASSES", "AFFORDANCE_JOINTS", "AFFORDANCE_SIGMA", "FOOT_JOINTS", "NUM_JOINTS",
           "PASSABLE", "SCENE_FPS", "STRUCTURE", "STRUCTURE_IDS", "TEXT_ENCODER", "UNKNOWN_ACTION"]

SCENE_FPS: float = 30.0
NUM_JOINTS: int = 22
AFFORDANCE_JOINTS: tuple[int, ...] = (0, 10, 11, 12, 20, 21)
AFFORDANCE_SIGMA: float = 0.8
TEXT_ENCODER: str = "minilm"
FOOT_JOINTS: tuple[int, ...] = (7, 8, 10, 11)
PASSABLE: tuple[str, ...] = ("door", "window", "picture", "curtain", "rug")
#: The object-centric models' action classes (their action embedding's rows); the last is
#: "unknown" (the instruction named none of the four).
ACTION_CLASSES: tuple[str, ...] = ("walk", "sit", "stand_up", "lie", "unknown")
UNKNOWN_ACTION: int = len(ACTION_CLASSES) - 1
#: A room's own surfaces: labelled in scans, never objects (targets, furniture) themselves.
STRUCTURE: tuple[str, ...] = ("wall", "floor", "ceiling")
#: Their semantic ids (NYU40's; jaxmotion's synthetic rooms use the same for wall and floor).
STRUCTURE_IDS: dict[str, int] = {"wall": 1, "floor": 2, "ceiling": 22}
