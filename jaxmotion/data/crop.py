"""Training crops: a square of the room around the motion, in a local frame.

Per sample (the afford-motion recipe, see REFERENCE_FACTS):

1. take the xy extent of the pelvis trajectory over valid frames, padded by
   ``margin`` metres;
2. sample the crop centre ``c`` uniformly such that the padded extent fits in
   the ``size × size`` square (centred on the extent when it cannot fit); with
   ``centre="room"`` instead take the centre of the room's xy bounding box,
   moved only as far as the padded extent needs to fit (the ADM's room view:
   no hint of where the motion is when the room fits in the square);
3. keep the scene points inside the square and draw ``num_points`` of them
   (without replacement when there are enough, else all of them plus random
   duplicates);
4. recentre: subtract ``(c_x, c_y, z_p)`` where ``z_p`` is the
   ``z_percentile``-th percentile of the drawn points' z (the floor, robustly);
5. rotate about z by a random angle in ``[−rotation_range, rotation_range]``.

The same rigid transform is applied to the motion, so
``x_crop = R (x_world − shift)``. Colours go to [−1, 1].

Host-side numpy; every random choice comes from the ``numpy.random.Generator``
passed in.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["Crop", "CropSpec", "crop_at", "crop_sample", "crop_spec_from_config", "features_to_joints",
           "generate_crop", "model_colors", "motion_features"]


@dataclass(frozen=True)
class CropSpec:
    """Crop parameters (mirrors ``configs/data.py``'s ``crop`` section)."""

    size: float = 4.0
    num_points: int = 8192
    z_percentile: float = 2.0
    rotate: bool = True
    rotation_range: float = float(np.pi)
    margin: float = 0.3
    centre: str = "motion"

    def __post_init__(self):
        if self.centre not in ("motion", "room"):
            raise ValueError(f"CropSpec.centre must be 'motion' or 'room', got {self.centre!r}")


def crop_spec_from_config(run_config: dict, *, rotate: bool = False, **overrides) -> CropSpec:
    """The :class:`CropSpec` a trained model's crops follow, from its stored run config (the
    ``config.json`` in its weights file, whose ``crop`` section is a
    :class:`~jaxmotion.data.config.CropConfig`); no rotation unless ``rotate`` (inference and
    evaluation crops are not augmented). ``overrides`` replace fields (e.g. ``num_points``)."""
    from jaxmotion.config import config_from_dict
    from jaxmotion.data.config import CropConfig

    cfg = config_from_dict(CropConfig, run_config["crop"])
    return CropSpec(**{**cfg.__dict__, "rotate": bool(rotate), **overrides})


@dataclass(frozen=True)
class Crop:
    """One training crop. Shapes: N = num_points, T = frames.

    Attributes:
      points: ``[N, 3]`` float32, crop frame, metres.
      colors: ``[N, 3]`` float32 in [−1, 1].
      target_mask: ``[N]`` bool, points of the target instance.
      joints: ``[T, 22, 3]`` float32, crop frame.
      mask: ``[T]`` bool, valid frames.
      rotation: ``[3, 3]``, shift: ``[3]`` with ``x_crop = rotation @ (x_world − shift)``.
      indices: ``[N]`` indices of the drawn points in the room (to gather any per-point field).
    """

    points: np.ndarray
    colors: np.ndarray
    target_mask: np.ndarray
    joints: np.ndarray
    mask: np.ndarray
    rotation: np.ndarray
    shift: np.ndarray
    indices: np.ndarray

    def to_world(self, x: np.ndarray) -> np.ndarray:
        """Map crop-frame coordinates ``[..., 3]`` back to the world."""
        return np.asarray(x) @ self.rotation + self.shift


def _rot_z(angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]], np.float32)


def crop_sample(
    rng: np.random.Generator,
    xyz: np.ndarray,
    rgb: np.ndarray,
    instance: np.ndarray,
    joints: np.ndarray,
    mask: np.ndarray,
    target_id: int,
    spec: CropSpec = CropSpec(),
    centre=None,
) -> Crop:
    """Crop one sample. See the module docstring for the recipe.

    Args:
      rng: source of every random choice.
      xyz ``[P,3]``, rgb ``[P,3]`` in [0,1], instance ``[P]``: the whole room.
      joints ``[T,22,3]``, mask ``[T]``: the motion in the world frame.
      target_id: instance id of the target object (its points form ``target_mask``).
      centre: an xy crop centre chosen elsewhere (e.g. where ``jaxmotion generate`` would
        put it), replacing steps 1–2; the motion is then not guaranteed to fit in the square.
    """
    mask = np.asarray(mask, bool)
    if not mask.any():
        raise ValueError("crop_sample: the motion has no valid frame (mask is all False)")
    if centre is not None:
        try:
            pick, pts, shift, rot = crop_at(rng, xyz, centre, spec)
        except ValueError as e:
            raise ValueError(f"crop_sample: {e}") from None
        return _crop(rgb, instance, joints, mask, target_id, pick, pts, shift, rot)
    pelvis = joints[mask, 0, :2]
    lo = pelvis.min(0) - spec.margin
    hi = pelvis.max(0) + spec.margin
    half = 0.5 * spec.size
    c_lo, c_hi = hi - half, lo + half  # centres for which [lo, hi] fits in the square
    fits = c_lo <= c_hi
    if spec.centre == "room":
        room_c = 0.5 * (xyz[:, :2].min(0) + xyz[:, :2].max(0))
        centre = np.where(fits, np.clip(room_c, np.minimum(c_lo, c_hi), np.maximum(c_lo, c_hi)),
                          0.5 * (lo + hi))
    else:
        centre = np.where(fits, rng.uniform(np.minimum(c_lo, c_hi), np.maximum(c_lo, c_hi)),
                          0.5 * (lo + hi))

    try:
        pick, pts, shift, rot = crop_at(rng, xyz, centre, spec)
    except ValueError:
        raise ValueError(
            f"crop_sample: no scene point within the {spec.size} m square around the motion "
            f"(centre {centre.round(2).tolist()}); is the motion in the scene's frame?"
        ) from None
    return _crop(rgb, instance, joints, mask, target_id, pick, pts, shift, rot)


def _crop(rgb, instance, joints, mask, target_id, pick, pts, shift, rot) -> Crop:
    return Crop(
        points=pts,
        colors=model_colors(rgb[pick]),
        target_mask=np.asarray(instance[pick] == target_id),
        joints=((joints - shift) @ rot.T).astype(np.float32),
        mask=mask,
        rotation=rot,
        shift=shift,
        indices=pick,
    )


def model_colors(rgb) -> np.ndarray:
    """Colours in [0, 1] as the models read them: float32 in [−1, 1]."""
    return (2.0 * np.asarray(rgb) - 1.0).astype(np.float32)


def crop_at(
    rng: np.random.Generator, xyz: np.ndarray, centre, spec: CropSpec = CropSpec()
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Steps 3–5 of the recipe for a given xy ``centre``: ``(indices [N], points [N,3] in the
    crop frame, shift [3], rotation [3,3])`` with ``x_crop = rotation @ (x_world − shift)``.

    Raises ``ValueError`` when no point of ``xyz`` lies in the square.
    """
    centre = np.asarray(centre, np.float64)[:2]
    half = 0.5 * spec.size
    idx = np.flatnonzero(np.all(np.abs(xyz[:, :2] - centre) <= half, axis=1))
    if len(idx) == 0:
        raise ValueError(f"no scene point within the {spec.size} m square centred at "
                         f"{centre.round(2).tolist()}")
    n = spec.num_points
    if len(idx) >= n:
        pick = rng.choice(idx, n, replace=False)
    else:
        pick = np.concatenate([idx, rng.choice(idx, n - len(idx), replace=True)])
    pts = xyz[pick].astype(np.float32)
    z0 = np.percentile(pts[:, 2], spec.z_percentile)
    shift = np.array([centre[0], centre[1], z0], np.float32)
    angle = rng.uniform(-spec.rotation_range, spec.rotation_range) if spec.rotate else 0.0
    rot = _rot_z(angle)
    return pick, ((pts - shift) @ rot.T).astype(np.float32), shift, rot



def generate_crop(xyz: np.ndarray, centre, spec: CropSpec, seed: int):
    """The crop ``generate`` samples in around ``centre``, whichever pipeline samples:
    :func:`crop_at` on the run's ``seed`` (its stream 1). :class:`~jaxmotion.errors.
    GenerateError` when no point of the scene lies in the square."""
    from jaxmotion.errors import GenerateError

    try:
        return crop_at(np.random.default_rng([seed, 1]), xyz, centre, spec)
    except ValueError as e:
        raise GenerateError(f"the scene has no points near the chosen region: {e}") from e

def motion_features(joints: np.ndarray) -> np.ndarray:
    """The models' motion representation: absolute joint positions, ``[..., T, 22, 3] -> [..., T, 66]``."""
    joints = np.asarray(joints)
    return joints.reshape(*joints.shape[:-2], 66)


def features_to_joints(features: np.ndarray) -> np.ndarray:
    """Inverse of :func:`motion_features`: ``[..., T, 66] -> [..., T, 22, 3]``."""
    features = np.asarray(features)
    return features.reshape(*features.shape[:-1], 22, 3)
