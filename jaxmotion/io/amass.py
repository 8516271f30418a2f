"""AMASS motions (SMPL+H and SMPL-X ``.npz`` files) as SMPL-X body parameters and joints.

Keys read (the user's own AMASS copy; z-up, metres, as jaxmotion):

- SMPL+H (``*_poses.npz``): ``poses`` [N, 156] = root 3, 21 body joints × 3, 2 × 15 hand
  joints × 3; ``trans`` [N, 3]; ``betas`` [16]; ``mocap_framerate``.
- SMPL-X (``*_stageii.npz``): ``poses`` [N, 165] = root, 21 body, jaw, 2 eyes, 2 × 15
  hands; or the split ``root_orient`` [N, 3] and ``pose_body`` [N, 63] (preferred when
  present); ``trans``; ``betas``; ``mocap_frame_rate``.

The root and the 21 body joints share the order of the 22 SMPL-X body joints, so they are
kept as ``global_orient`` / ``body_pose`` with ``transl = trans`` and the first 10 betas
(hands, jaw and eyes are dropped). **Joints** are the forward kinematics of these
parameters on **jaxmotion's SMPL-X skeleton** (mannequin-x's neutral SMPL-X rest joints
shaped by the 10 betas, :func:`jaxmotion.geometry.smplx_joints`), not the SMPL+H model's
own joint regressor or gendered SMPL-X models: they differ from those by a few centimetres
(bone lengths and rest pelvis), while jaxmotion's exporters and models reproduce them
exactly. Subject ``shape.npz`` files (betas only) are not motions.
"""

from __future__ import annotations

import zipfile
from pathlib import Path

import numpy as np

from jaxmotion.geometry.skeleton import NUM_BETAS, NUM_JOINTS
from jaxmotion.io.motion import Motion, MotionFormatError, smplx_joints_host

__all__ = ["load_amass"]

_BODY = 3 * (NUM_JOINTS - 1)  # 63 body pose values
_POSES_WIDTHS = {156: "SMPL+H", 165: "SMPL-X"}


def _array(data, key: str, where: str) -> np.ndarray:
    try:
        a = np.asarray(data[key])
    except ValueError as e:  # an object array needs pickle: not a number array
        raise MotionFormatError(f"{where}: key {key!r} is not a plain number array ({e})") from e
    if a.dtype.kind not in "fiu":
        raise MotionFormatError(f"{where}: key {key!r} must hold numbers, got {a.dtype}")
    return a.astype(np.float64)


def load_amass(path, *, fps: float | None = None) -> Motion:
    """Read an AMASS ``.npz`` motion (SMPL+H or SMPL-X); see the module docstring.

    Args:
      path: the ``.npz`` file.
      fps: resample to this rate (joints and ``transl`` linearly, rotations by slerp), or
        None for the capture rate (often 120 fps, some 60 / 100 / 250).
    Returns:
      joints ``[T, 22, 3]`` and the SMPL-X body parameters (``global_orient`` ``[T, 3]``,
      ``body_pose`` ``[T, 21, 3]``, ``transl`` ``[T, 3]``, ``betas`` ``[10]``); no texts.
      ``info`` has ``model`` (SMPL+H / SMPL-X) and ``gender`` when the file gives them.
    Raises MotionFormatError naming the file and the fix.
    """
    path = Path(path)
    where = str(path)
    if not path.is_file():
        raise MotionFormatError(f"{where}: no such file")
    try:
        data = np.load(path, allow_pickle=False)
    except (OSError, ValueError, EOFError, zipfile.BadZipFile) as e:
        raise MotionFormatError(f"{where}: not a readable .npz file ({e}); give an AMASS "
                                "motion (*_poses.npz or *_stageii.npz)") from e
    if not isinstance(data, np.lib.npyio.NpzFile):
        raise MotionFormatError(f"{where}: a single .npy array, not an AMASS .npz archive")
    with data:
        keys = set(data.files)
        if "trans" not in keys or not ({"poses"} <= keys or {"root_orient", "pose_body"} <= keys):
            what = ("a subject shape file (betas only), not a motion"
                    if keys and keys <= {"betas", "gender", "num_betas", "surface_model_type"}
                    else f"not an AMASS motion (keys {sorted(keys)})")
            raise MotionFormatError(f"{where}: {what}; an AMASS motion has 'trans' and 'poses' "
                                    "(or 'root_orient' and 'pose_body')")
        trans = _array(data, "trans", where)
        n = trans.shape[0] if trans.ndim == 2 else -1
        if trans.ndim != 2 or trans.shape[1] != 3 or n < 1:
            raise MotionFormatError(f"{where}: 'trans' must be [N >= 1, 3], got "
                                    f"{list(trans.shape)}")
        if {"root_orient", "pose_body"} <= keys:
            orient, body = _array(data, "root_orient", where), _array(data, "pose_body", where)
            model = "SMPL-X"
            if orient.shape != (n, 3) or body.shape != (n, _BODY):
                raise MotionFormatError(
                    f"{where}: 'root_orient' must be [{n}, 3] and 'pose_body' [{n}, {_BODY}], got "
                    f"{list(orient.shape)} and {list(body.shape)}")
        else:
            poses = _array(data, "poses", where)
            if poses.ndim != 2 or poses.shape[0] != n or poses.shape[1] not in _POSES_WIDTHS:
                raise MotionFormatError(
                    f"{where}: 'poses' must be [{n}, 156] (SMPL+H) or [{n}, 165] (SMPL-X), got "
                    f"{list(poses.shape)}")
            model = _POSES_WIDTHS[poses.shape[1]]
            orient, body = poses[:, :3], poses[:, 3:3 + _BODY]
        rate_key = next((k for k in ("mocap_framerate", "mocap_frame_rate") if k in keys), None)
        if rate_key is None:
            raise MotionFormatError(f"{where}: no frame rate ('mocap_framerate' or "
                                    "'mocap_frame_rate'); is this an AMASS motion file?")
        rate = float(_array(data, rate_key, where).reshape(-1)[0])
        betas = _array(data, "betas", where).reshape(-1) if "betas" in keys else np.zeros(0)
        gender = None
        try:  # informative only: an object array (needs pickle) is ignored
            g = np.asarray(data["gender"]).reshape(-1) if "gender" in keys else np.zeros(0)
        except ValueError:
            g = np.zeros(0)
        if g.size and g.dtype.kind in "SU":
            gender = g[0].decode() if isinstance(g[0], bytes) else str(g[0])
    betas = np.pad(betas[:NUM_BETAS], (0, max(0, NUM_BETAS - len(betas))))
    for name, a in (("trans", trans), ("poses", orient), ("poses", body), ("betas", betas)):
        if not np.isfinite(a).all():
            raise MotionFormatError(f"{where}: {name!r} has NaN or inf values")
    if not (np.isfinite(rate) and rate > 0):
        raise MotionFormatError(f"{where}: {rate_key} must be a positive number, got {rate}")
    body = body.reshape(n, NUM_JOINTS - 1, 3)
    info = {"format": "amass", "model": model}
    if gender:
        info["gender"] = gender
    motion = Motion(joints=smplx_joints_host(orient, body, trans, betas), fps=rate,
                    global_orient=orient, body_pose=body, transl=trans, betas=betas,
                    source=where, info=info)
    return motion if fps is None else motion.resampled(fps)
