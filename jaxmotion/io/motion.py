"""The :class:`Motion` every reader returns, its error, and host-side helpers (numpy only).

A :class:`Motion` is one clip in jaxmotion's conventions: the 22 SMPL-X body joints
(order :data:`jaxmotion.geometry.JOINT_NAMES`) in metres, **z-up**, at ``fps`` frames per
second, optionally with the SMPL-X parameters that produce them, captions and where it came
from. Readers convert a file's units, axes and skeleton to this; nothing downstream needs to
know the source format.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from types import MappingProxyType

import numpy as np
from scipy.spatial.transform import Rotation

from jaxmotion.geometry.skeleton import NUM_BETAS, NUM_JOINTS, PARENTS, rest_joints_host

__all__ = [
    "Y_UP_TO_Z_UP",
    "Motion",
    "MotionFormatError",
    "smplx_joints_host",
    "y_up_to_z_up",
]

# (x, y, z)_y-up -> (x, -z, y)_z-up: +90 degrees about x (a file's forward +z becomes -y).
Y_UP_TO_Z_UP = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])


class MotionFormatError(ValueError):
    """A motion file is missing, malformed or not in the format asked for; the message names
    the file and the fix."""


def y_up_to_z_up(x: np.ndarray) -> np.ndarray:
    """Points ``[..., 3]`` of a y-up file in jaxmotion's z-up world: ``(x, y, z) -> (x, -z, y)``."""
    x = np.asarray(x)
    return np.stack([x[..., 0], -x[..., 2], x[..., 1]], axis=-1)


def smplx_joints_host(global_orient, body_pose, transl, betas=None) -> np.ndarray:
    """:func:`jaxmotion.geometry.smplx_joints` in NumPy (float64), for readers.

    The same kinematics (the global orientation turns the body about the rest pelvis,
    ``transl`` is added after) without dispatching XLA programs, which cost a compilation
    per new clip length in a fresh process.

    Args:
      global_orient: ``[T, 3]`` axis-angle (radians); body_pose: ``[T, 21, 3]``;
      transl: ``[T, 3]`` metres; betas: ``[B]`` (B ≤ 10) or None for the neutral body.
    Returns:
      ``[T, 22, 3]`` joints, metres, in the parameters' world frame.
    """
    go = np.asarray(global_orient, np.float64).reshape(-1, 3)
    t = len(go)
    bp = np.asarray(body_pose, np.float64).reshape(t, NUM_JOINTS - 1, 3)
    tr = np.asarray(transl, np.float64).reshape(t, 3)
    rest = rest_joints_host(None if betas is None else np.asarray(betas, np.float64)[:NUM_BETAS])
    aa = np.concatenate([go[:, None], bp], axis=1).reshape(-1, 3)
    local = Rotation.from_rotvec(aa).as_matrix().reshape(t, NUM_JOINTS, 3, 3)
    glob = [local[:, 0]]
    pos = [np.broadcast_to(rest[0] + tr, (t, 3))]
    for j in range(1, NUM_JOINTS):
        p = PARENTS[j]
        pos.append(pos[p] + glob[p] @ (rest[j] - rest[p]))
        glob.append(glob[p] @ local[:, j])
    return np.stack(pos, axis=1)


def _frozen(name: str, value, shape: tuple) -> np.ndarray:
    a = np.asarray(value)
    if a.dtype.kind not in "fiu" or a.shape != shape:
        want = "[" + ", ".join(str(s) for s in shape) + "]"
        raise ValueError(f"Motion.{name} must be a real array of shape {want}, got "
                         f"{a.dtype} {list(a.shape)}")
    a = a.astype(np.float32)  # a private copy
    if not np.isfinite(a).all():
        raise ValueError(f"Motion.{name} has NaN or inf values")
    a.setflags(write=False)
    return a


@dataclasses.dataclass(frozen=True, eq=False)
class Motion:
    """One motion clip in jaxmotion's conventions (arrays are read-only float32 copies).

    Attributes:
      joints: ``[T, 22, 3]`` SMPL-X body joints (order ``JOINT_NAMES``), metres, z-up.
      fps: frames per second (> 0).
      global_orient: ``[T, 3]`` SMPL-X axis-angle (radians) in the z-up world, or None.
      body_pose: ``[T, 21, 3]`` axis-angle, or None (given with ``global_orient``).
      transl: ``[T, 3]`` SMPL-X translation, metres, or None (given with ``global_orient``).
      betas: ``[10]`` SMPL-X shape, or None (neutral body / unknown).
      texts: captions (may be empty).
      text_spans: ``(start, end)`` seconds of each caption (same length as ``texts``);
        default: the whole clip, ``(0, (T - 1) / fps)``.
      source: where the motion came from (a path), free-form.
      info: extra facts of the source (JSON-like: scene id, action, object id, ...).
    """

    joints: np.ndarray
    fps: float
    global_orient: np.ndarray | None = None
    body_pose: np.ndarray | None = None
    transl: np.ndarray | None = None
    betas: np.ndarray | None = None
    texts: tuple[str, ...] = ()
    text_spans: tuple[tuple[float, float], ...] | None = None
    source: str = ""
    info: Mapping = dataclasses.field(default_factory=dict)

    def __post_init__(self):
        j = np.asarray(self.joints)
        if j.ndim != 3 or j.shape[1:] != (NUM_JOINTS, 3) or j.shape[0] < 1:
            raise ValueError(f"Motion.joints must be [T >= 1, 22, 3], got {list(j.shape)}")
        t = j.shape[0]
        fps = float(self.fps)
        if not (np.isfinite(fps) and fps > 0):
            raise ValueError(f"Motion.fps must be a positive number, got {self.fps!r}")
        params = (self.global_orient, self.body_pose, self.transl)
        if any(p is None for p in params) and not all(p is None for p in params):
            raise ValueError("Motion: give global_orient, body_pose and transl together, or none")
        sets = {"joints": _frozen("joints", j, (t, NUM_JOINTS, 3)), "fps": fps}
        if self.global_orient is not None:
            sets.update(global_orient=_frozen("global_orient", self.global_orient, (t, 3)),
                        body_pose=_frozen("body_pose", self.body_pose, (t, NUM_JOINTS - 1, 3)),
                        transl=_frozen("transl", self.transl, (t, 3)))
        if self.betas is not None:
            sets["betas"] = _frozen("betas", self.betas, (NUM_BETAS,))
        texts = (self.texts,) if isinstance(self.texts, str) else tuple(self.texts)
        if not all(isinstance(s, str) for s in texts):
            raise ValueError("Motion.texts must be strings")
        spans = ((0.0, (t - 1) / fps),) * len(texts) if self.text_spans is None else tuple(
            (float(a), float(b)) for a, b in self.text_spans)
        if len(spans) != len(texts):
            raise ValueError(f"Motion.text_spans has {len(spans)} entries for {len(texts)} texts")
        sets.update(texts=texts, text_spans=spans, source=str(self.source),
                    info=MappingProxyType(dict(self.info)))
        for key, value in sets.items():
            object.__setattr__(self, key, value)

    def __repr__(self):
        return (f"Motion({self.num_frames} frames at {self.fps:g} fps, "
                f"smplx={self.has_smplx}, texts={len(self.texts)}, source={self.source!r})")

    @property
    def num_frames(self) -> int:
        """T, the number of frames."""
        return int(self.joints.shape[0])

    @property
    def duration(self) -> float:
        """Seconds from the first to the last frame, ``(T - 1) / fps``."""
        return (self.num_frames - 1) / self.fps

    @property
    def has_smplx(self) -> bool:
        """Whether SMPL-X parameters (global_orient, body_pose, transl) are present."""
        return self.global_orient is not None

    def replace(self, **changes) -> Motion:
        """A copy with fields replaced (validated again)."""
        return dataclasses.replace(self, **changes)

    def frames(self, start: int, stop: int) -> Motion:
        """Frames ``start:stop`` as a new motion; captions are kept only when their span
        covers the whole slice, with spans shifted to the slice's start."""
        t = self.num_frames
        start, stop, _ = slice(start, stop).indices(t)
        if stop <= start:
            raise ValueError(f"frames({start}, {stop}) of a {t}-frame motion is empty")
        cut = {k: getattr(self, k)[start:stop] for k in ("joints", "global_orient", "body_pose",
                                                        "transl") if getattr(self, k) is not None}
        t0, t1, eps = start / self.fps, (stop - 1) / self.fps, 0.5 / self.fps
        keep = [(s, (a, b)) for s, (a, b) in zip(self.texts, self.text_spans, strict=True)
                if a <= t0 + eps and b >= t1 - eps]
        return dataclasses.replace(
            self, **cut, texts=tuple(s for s, _ in keep),
            text_spans=tuple((max(a - t0, 0.0), min(b, t1) - t0) for _, (a, b) in keep))

    def resampled(self, fps: float) -> Motion:
        """The motion at another frame rate, over the same time span.

        Frame ``k`` is at ``k / fps`` seconds for ``k = 0 .. floor(duration · fps)``. Joints
        and ``transl`` are interpolated linearly, rotations (``global_orient``,
        ``body_pose``) spherically (slerp of each joint's quaternion).
        """
        fps = float(fps)
        if not (np.isfinite(fps) and fps > 0):
            raise ValueError(f"fps must be a positive number, got {fps!r}")
        if fps == self.fps:
            return self
        n = int(np.floor(self.duration * fps + 1e-6)) + 1
        src = np.minimum(np.arange(n) * (self.fps / fps), self.num_frames - 1)
        i0 = np.minimum(np.floor(src).astype(int), max(self.num_frames - 2, 0))
        i1 = np.minimum(i0 + 1, self.num_frames - 1)
        w = (src - i0)[:, None, None]

        def lerp(x):
            x = np.asarray(x, np.float64)
            w_ = w.reshape((n,) + (1,) * (x.ndim - 1))
            return x[i0] * (1.0 - w_) + x[i1] * w_

        new = {"joints": lerp(self.joints), "fps": fps}
        if self.has_smplx:
            aa = np.concatenate([self.global_orient[:, None], self.body_pose], axis=1)
            rot = _slerp(aa[i0], aa[i1], w[..., 0])
            new.update(global_orient=rot[:, 0], body_pose=rot[:, 1:], transl=lerp(self.transl))
        return dataclasses.replace(self, **new)


def _slerp(aa0: np.ndarray, aa1: np.ndarray, w: np.ndarray) -> np.ndarray:
    """Spherical interpolation of axis-angle rotations ``[..., 3]`` with weights ``[...]``."""
    shape = aa0.shape
    q0 = Rotation.from_rotvec(aa0.reshape(-1, 3)).as_quat()
    q1 = Rotation.from_rotvec(aa1.reshape(-1, 3)).as_quat()
    w = np.broadcast_to(w, shape[:-1]).reshape(-1, 1)
    dot = np.sum(q0 * q1, axis=1, keepdims=True)
    q1 = np.where(dot < 0, -q1, q1)  # the shorter way round
    dot = np.clip(np.abs(dot), -1.0, 1.0)
    theta = np.arccos(dot)
    small = theta < 1e-6
    s = np.sin(np.where(small, 1.0, theta))
    a = np.where(small, 1.0 - w, np.sin((1.0 - w) * theta) / s)
    b = np.where(small, w, np.sin(w * theta) / s)
    q = a * q0 + b * q1
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    return Rotation.from_quat(q).as_rotvec().reshape(shape)
