"""AMASS-style SMPL-X ``.npz``: the fitted SMPL-X parameters of one motion, for SMPL-X tools.

The layout of AMASS's SMPL-X files (``*_stageii.npz``), the animation files the SMPL-X
Blender add-on imports (it reads AMASS or SMPL-X ``.npz``). Every array is float64 and
every string a plain numpy string (no pickle needed to read the file).

Keys
----
- ``trans`` ``[T, 3]``: SMPL-X's translation parameter (``transl``), metres — **not** the
  pelvis position. SMPL-X turns the body by ``root_orient`` about the rest pelvis of its
  shape, ``J_pelvis(betas)`` (in the model's own rest frame), then adds ``trans``, so the
  pelvis is at ``J_pelvis(betas) + trans`` in the world; ``J_pelvis`` is added as it is,
  unrotated (about ``(0.003, −0.351, 0.012)`` m for the neutral body at betas = 0, so the
  pelvis sits 0.35 m off ``trans`` along world −y). This is also how AMASS stores it.
- ``poses`` ``[T, 165]``: axis-angle, radians: root 3, 21 body joints × 3, jaw 3, 2 eyes × 3,
  left hand 15 × 3, right hand 15 × 3 (SMPL-X's joint order,
  ``jaxmotion.geometry.SMPLX_JOINT_NAMES``). A generated motion has no jaw, eye or finger
  motion: those are zero rotations (jaw closed, eyes forward, fingers flat in a model
  without a hand mean).
- the same split as AMASS's SMPL-X files: ``root_orient`` ``[T, 3]``, ``pose_body``
  ``[T, 63]``, ``pose_jaw`` ``[T, 3]``, ``pose_eye`` ``[T, 6]``, ``pose_hand`` ``[T, 90]``.
- ``betas`` ``[B]`` the body shape (the 10 fitted ones); ``gender`` (``"neutral"``: the
  shape and joints are the neutral SMPL-X body's); ``mocap_frame_rate`` (frames per second);
  ``surface_model_type`` (``"smplx"``).

Frame: jaxmotion's world, z-up, metres, the same as AMASS's: the motion lands where it was
generated, in the room's coordinates (those of ``motion.npz``'s joints and of the scene).
:func:`jaxmotion.io.load_motion` reads the file back (its AMASS reader).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from jaxmotion._atomic import atomic_open
from jaxmotion.export._common import check_array, check_fps, smplx_motion
from jaxmotion.geometry.skeleton import NUM_BETAS

__all__ = ["AMASS_KEYS", "write_amass_npz"]

#: The keys :func:`write_amass_npz` writes, each as in AMASS's SMPL-X files.
AMASS_KEYS = ("trans", "poses", "root_orient", "pose_body", "pose_jaw", "pose_eye", "pose_hand",
              "betas", "gender", "mocap_frame_rate", "surface_model_type")
_GENDERS = ("neutral", "female", "male")
_HAND_JOINTS = 15


def write_amass_npz(path, global_orient, body_pose, transl, betas, fps: float, *,
                    gender: str = "neutral") -> Path:
    """Write one motion's SMPL-X parameters as an AMASS-style SMPL-X ``.npz``, atomically.

    Args:
      path: the ``.npz`` file to write.
      global_orient: ``[T, 3]`` axis-angle, radians; body_pose: ``[T, 21, 3]``;
      transl: ``[T, 3]`` SMPL-X's translation parameter, metres, z-up world (see the module
        docstring: not the pelvis position).
      betas: ``[B]`` shape coefficients, or None (the neutral shape: 10 zeros).
      fps: frames per second of the motion.
      gender: which SMPL-X model the parameters belong to (``"neutral"`` for jaxmotion's
        fits, which use the neutral body).
    Returns:
      the path written. ValueError naming the argument for a bad shape or value.
    """
    go, bp, tr = smplx_motion(global_orient, body_pose, transl)
    if go.shape[0] != 1:
        raise ValueError(f"an AMASS file holds one motion, got {go.shape[0]}; write each "
                         "sample to its own file")
    go, bp, tr = go[0], bp[0], tr[0]
    t = go.shape[0]
    fps = check_fps(fps)
    betas = (np.zeros(NUM_BETAS) if betas is None
             else check_array("betas", np.asarray(betas, np.float64).reshape(-1), (None,)))
    if gender not in _GENDERS:
        raise ValueError(f"gender must be one of {', '.join(_GENDERS)}, got {gender!r}")
    pose_jaw, pose_eye = np.zeros((t, 3)), np.zeros((t, 6))
    pose_hand = np.zeros((t, 2 * _HAND_JOINTS * 3))
    # SMPL-X's joint order: root, body, jaw, eyes, hands (165 = 3 × 55 joints)
    poses = np.concatenate([go, bp.reshape(t, -1), pose_jaw, pose_eye, pose_hand], axis=1)
    arrays = {
        "trans": tr, "poses": poses, "root_orient": go, "pose_body": bp.reshape(t, -1),
        "pose_jaw": pose_jaw, "pose_eye": pose_eye, "pose_hand": pose_hand, "betas": betas,
        "gender": np.array(gender), "mocap_frame_rate": np.float64(fps),
        "surface_model_type": np.array("smplx"),
    }
    with atomic_open(path, "wb") as f:
        np.savez(f, **{k: arrays[k] for k in AMASS_KEYS})
    return Path(path)
