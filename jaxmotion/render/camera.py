"""Pinhole cameras that frame a motion: fixed on the whole clip, or following it smoothly.

A camera looks from azimuth ``a`` and elevation ``e`` (degrees; the direction from the target
to the eye is ``(cos e cos a, cos e sin a, sin e)`` in the z-up world, matplotlib's
``view_init`` convention) at a target point, from a distance that fits the framed points into
the middle of the picture. Pixels: x right, y down; the vertical field of view is
:data:`FOV_DEG`; the principal point may sit off the picture's centre (a crop).

:func:`plan_cameras` chooses, for a clip (:class:`CameraPlan`):

- ``"fixed"``: one camera for every frame, framing all joints of all samples over the clip;
- ``"follow"``: the fixed camera's eye and direction, zoomed in so that any
  :data:`FOLLOW_WINDOW_S` of the motion fills the picture, its picture's centre gliding after
  the motion (smoothed with a Gaussian of :data:`FOLLOW_SIGMA_S`): an operator on a tripod.
  Each frame is an off-axis crop of the fixed camera's view, so the room is drawn once;
- ``"auto"``: fixed when the whole motion fits with a 1.7 m body at least
  :data:`MIN_BODY_FRACTION` of the picture's height, else follow.

The azimuth, unless given, is picked among 12 directions: the one that sees the body's front
(its mean facing over the clip) and has the fewest scene points between the eye and the
motion (walls, furniture), see :func:`choose_azimuth`.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

__all__ = [
    "CAMERA_MODES",
    "FOLLOW_SIGMA_S",
    "FOLLOW_WINDOW_S",
    "FOV_DEG",
    "MAX_ZOOM",
    "MIN_BODY_FRACTION",
    "Camera",
    "CameraPlan",
    "choose_azimuth",
    "plan_cameras",
]

CAMERA_MODES = ("auto", "fixed", "follow")
FOV_DEG = 38.0  # vertical field of view
ELEVATION_DEG = 24.0  # default height of the view above the horizontal
FILL = 0.82  # the framed points fill at most this fraction of the picture's width and height
MIN_BODY_FRACTION = 0.42  # "auto" follows when a fixed view would make a 1.7 m body smaller
FOLLOW_WINDOW_S = 2.0
FOLLOW_SIGMA_S = 0.6
MAX_ZOOM = 4.0
_BODY_HEIGHT = 1.7


@dataclasses.dataclass(frozen=True)
class Camera:
    """One pinhole camera: ``eye [3]``, rows of ``rot [3, 3]`` = right, down, forward (world),
    focal length ``focal`` and principal point ``(cx, cy)`` in pixels, picture size."""

    eye: np.ndarray
    rot: np.ndarray
    focal: float
    cx: float
    cy: float
    width: int
    height: int

    @staticmethod
    def look(target, azimuth: float, elevation: float, distance: float, width: int,
             height: int) -> Camera:
        """The camera ``distance`` metres from ``target`` in the direction (azimuth, elevation)."""
        back = _direction(azimuth, elevation)
        forward = -back
        right = np.cross(forward, [0.0, 0.0, 1.0])
        right /= np.linalg.norm(right)
        down = np.cross(forward, right)
        focal = 0.5 * height / math.tan(math.radians(FOV_DEG) / 2)
        eye = np.asarray(target, np.float64) + distance * back
        return Camera(eye, np.stack([right, down, forward]), focal, width / 2, height / 2,
                      width, height)

    def scaled(self, factor: float) -> Camera:
        """The same view on a picture ``factor`` times larger each way (sizes rounded)."""
        w, h = round(self.width * factor), round(self.height * factor)
        fx = w / self.width
        return dataclasses.replace(self, focal=self.focal * fx, cx=self.cx * fx,
                                   cy=self.cy * fx, width=w, height=h)

    def view(self, p: np.ndarray) -> np.ndarray:
        """World points ``[..., 3]`` in camera coordinates (x right, y down, z forward)."""
        return rotate(np.asarray(p, np.float64) - self.eye, self.rot)

    def project(self, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Pixel coordinates ``[..., 2]`` and depth ``[...]`` (metres along the view axis)."""
        c = self.view(p)
        z = c[..., 2]
        safe = np.where(np.abs(z) > 1e-9, z, 1e-9)
        xy = np.stack([self.cx + self.focal * c[..., 0] / safe,
                       self.cy + self.focal * c[..., 1] / safe], axis=-1)
        return xy, z


def rotate(p: np.ndarray, rot: np.ndarray) -> np.ndarray:
    """``p @ rot.T`` for points ``[..., 3]`` written out per component: NumPy's ``@`` calls
    BLAS, whose threads slow a busy machine down more than they help here."""
    x, y, z = p[..., 0:1], p[..., 1:2], p[..., 2:3]
    return x * rot[:, 0] + y * rot[:, 1] + z * rot[:, 2]


def _direction(azimuth: float, elevation: float) -> np.ndarray:
    a, e = math.radians(azimuth), math.radians(elevation)
    return np.array([math.cos(e) * math.cos(a), math.cos(e) * math.sin(a), math.sin(e)])


def fit_distance(points: np.ndarray, target: np.ndarray, azimuth: float, elevation: float,
                 width: int, height: int, fill: float = FILL) -> float:
    """The smallest distance from ``target`` at which every point of ``points [M, 3]`` projects
    into the middle ``fill`` of the picture (at least 1.5 m)."""
    cam = Camera.look(target, azimuth, elevation, 0.0, width, height)
    c = (np.asarray(points, np.float64).reshape(-1, 3) - target) @ cam.rot.T  # eye at target
    hw, hh = fill * width / 2 / cam.focal, fill * height / 2 / cam.focal
    need = np.maximum(np.abs(c[:, 0]) / hw, np.abs(c[:, 1]) / hh) - c[:, 2]
    return max(1.5, float(need.max()))


def frame_box(joints: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Target (centre of the joints' box) and the box's corners, padded by a body's reach."""
    flat = joints.reshape(-1, 3)
    lo, hi = flat.min(0) - [0.25, 0.25, 0.0], flat.max(0) + [0.25, 0.25, 0.2]
    lo[2] = min(lo[2], 0.0)  # keep the feet and the floor under them in view
    corners = np.array([[(lo, hi)[k >> a & 1][a] for a in range(3)] for k in range(8)])
    return 0.5 * (lo + hi), corners


def choose_azimuth(joints: np.ndarray, scene_xyz: np.ndarray | None = None,
                   elevation: float = ELEVATION_DEG) -> float:
    """An azimuth (degrees) that sees the body's front and the fewest scene points in the way.

    ``joints [K, T, 22, 3]``. Each of 12 directions scores the cosine between the view and the
    body's mean facing over the clip (from the hips: left hip − right hip, turned by −90°) minus
    the fraction of the scene points that lie between the eye and the motion within its
    silhouette. The default view of a scene without points is the front-left (30° off the
    facing), a three-quarter view.
    """
    j = joints.reshape(-1, *joints.shape[-3:])
    across = (j[:, :, 1] - j[:, :, 2])[..., :2].reshape(-1, 2)  # left hip − right hip
    across /= np.maximum(np.linalg.norm(across, axis=1, keepdims=True), 1e-9)
    facing = np.array([across[:, 1].mean(), -across[:, 0].mean()])  # 90° to the right: front
    facing /= max(np.linalg.norm(facing), 1e-9)
    centre, corners = frame_box(joints)
    radius = 0.5 * float(np.linalg.norm(corners.max(0)[:2] - corners.min(0)[:2])) + 0.3
    near = None
    if scene_xyz is not None and len(scene_xyz):
        step = max(1, len(scene_xyz) // 20_000)
        pts = np.asarray(scene_xyz[::step], np.float64)
        near = pts[(pts[:, 2] > 0.15) & (pts[:, 2] < corners[:, 2].max() + 0.3)]
    best, best_score = 0.0, -np.inf
    for az in np.arange(0.0, 360.0, 30.0):
        d = _direction(az, elevation)
        score = float(d[:2] @ facing) / max(np.linalg.norm(d[:2]), 1e-9)
        score -= 0.3 * abs(score - math.cos(math.radians(30)))  # prefer three-quarter views
        if near is not None and len(near):
            rel = near - centre
            along = rel @ d  # toward the eye
            perp = np.linalg.norm(rel - along[:, None] * d, axis=1)
            blocking = (along > radius) & (along < radius + 3.0) & (perp < radius)
            score -= 4.0 * blocking.mean() * 10  # a few per cent of the room in the way is bad
        if score > best_score + 1e-9:
            best, best_score = float(az), score
    return best


def _gaussian_smooth(x: np.ndarray, sigma: float) -> np.ndarray:
    """Smooth ``x [T, D]`` along time with a Gaussian of ``sigma`` frames (edges held)."""
    if sigma <= 0 or len(x) < 2:
        return x.copy()
    r = math.ceil(3 * sigma)
    k = np.exp(-0.5 * (np.arange(-r, r + 1) / sigma) ** 2)
    k /= k.sum()
    padded = np.concatenate([np.repeat(x[:1], r, 0), x, np.repeat(x[-1:], r, 0)])
    return np.stack([np.convolve(padded[:, d], k, mode="valid") for d in range(x.shape[1])], 1)


@dataclasses.dataclass(frozen=True)
class CameraPlan:
    """The cameras of a clip: ``base`` sees the whole motion; ``cameras[t]`` is frame t's,
    the same eye and direction with the focal length ``zoom`` times longer and the principal
    point moved (an off-axis crop of ``base``'s picture); ``mode`` is ``"fixed"`` (every
    camera is ``base``) or ``"follow"``."""

    base: Camera
    cameras: list
    mode: str
    zoom: float


def plan_cameras(joints: np.ndarray, fps: float, width: int, height: int, *,
                 mode: str = "auto", azimuth: float | None = None,
                 elevation: float = ELEVATION_DEG, scene_xyz=None) -> CameraPlan:
    """The cameras of a clip of ``joints [K, T, 22, 3]`` (see the module docstring).

    The follow camera keeps the fixed camera's eye and direction (a camera operator on a
    tripod): it zooms in by the largest factor (≤ :data:`MAX_ZOOM`) at which any
    :data:`FOLLOW_WINDOW_S` of the motion fits the picture, and pans after the motion's
    smoothed centre, so the room is drawn once and every frame is a crop of it.
    """
    if mode not in CAMERA_MODES:
        raise ValueError(f"camera must be one of {', '.join(CAMERA_MODES)}, got {mode!r}")
    j = np.asarray(joints, np.float64)
    t = j.shape[1]
    if azimuth is None:
        azimuth = choose_azimuth(j, scene_xyz, elevation)
    centre, corners = frame_box(j)
    whole = fit_distance(corners, centre, azimuth, elevation, width, height)
    base = Camera.look(centre, azimuth, elevation, whole, width, height)
    body_fraction = _BODY_HEIGHT * base.focal / whole / height
    if mode == "fixed" or (mode == "auto" and (body_fraction >= MIN_BODY_FRACTION or t < 2)):
        return CameraPlan(base, [base] * t, "fixed", 1.0)
    # follow: per frame, the box of the motion within ±half a window, on base's picture
    half = max(1, round(FOLLOW_WINDOW_S * fps / 2))
    boxes = np.empty((t, 4))
    for f in range(t):
        _, box = frame_box(j[:, max(0, f - half): f + half + 1])
        xy, _ = base.project(box)
        boxes[f] = [*xy.min(0), *xy.max(0)]
    extent = np.maximum(boxes[:, 2:] - boxes[:, :2], 1.0)
    zoom = float(np.clip(np.min(FILL * np.array([width, height]) / extent), 1.0, MAX_ZOOM))
    if mode == "auto" and zoom < 1.15:
        return CameraPlan(base, [base] * t, "fixed", 1.0)
    mid = _gaussian_smooth(0.5 * (boxes[:, :2] + boxes[:, 2:]), FOLLOW_SIGMA_S * fps)
    size = np.array([width, height], np.float64)
    mid = np.clip(mid, size / (2 * zoom), size - size / (2 * zoom))  # the crop stays inside
    cams = [dataclasses.replace(base, focal=base.focal * zoom,
                                cx=width / 2 - zoom * (m[0] - base.cx),
                                cy=height / 2 - zoom * (m[1] - base.cy)) for m in mid]
    return CameraPlan(base, cams, "follow", zoom)
