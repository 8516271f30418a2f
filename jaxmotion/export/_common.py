"""Input checks and small helpers shared by the writers (host numpy)."""

from __future__ import annotations

import numpy as np

from jaxmotion.geometry.skeleton import NUM_JOINTS

# Rx(-90°): jaxmotion's z-up world -> the y-up world of BVH and glTF, (x, y, z) -> (x, z, -y).
Z_UP_TO_Y_UP = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])


def check_array(name: str, value, shape: tuple[int | None, ...], dtype=np.float64) -> np.ndarray:
    """``value`` as an array of ``shape`` (None = any size) with finite entries, else ValueError."""
    a = np.asarray(value, dtype)
    if a.ndim != len(shape) or any(s is not None and s != n for s, n in zip(shape, a.shape)):
        want = ", ".join("*" if s is None else str(s) for s in shape)
        raise ValueError(f"{name} must have shape [{want}], got {list(a.shape)}")
    if a.dtype.kind == "f" and not np.all(np.isfinite(a)):
        raise ValueError(f"{name} has non-finite values (NaN or inf)")
    return a


def check_fps(fps) -> float:
    fps = float(fps)
    if not np.isfinite(fps) or fps <= 0:
        raise ValueError(f"fps must be a positive number, got {fps}")
    return fps


def smplx_motion(global_orient, body_pose, transl) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """SMPL-X parameters with a leading sample axis: ``[K,T,3]``, ``[K,T,21,3]``, ``[K,T,3]``.

    Accepts one motion (``[T,3]``, ``[T,21,3]``, ``[T,3]``) or K of them.
    """
    go = np.asarray(global_orient, np.float64)
    if go.ndim == 2:
        global_orient, body_pose, transl = (np.asarray(x)[None] for x in (go, body_pose, transl))
    elif go.ndim != 3:
        raise ValueError(f"global_orient must be [T,3] or [K,T,3], got {list(go.shape)}")
    go = check_array("global_orient", global_orient, (None, None, 3))
    k, t = go.shape[:2]
    if t == 0:
        raise ValueError("the motion has no frame (T = 0)")
    bp = check_array("body_pose", body_pose, (k, t, NUM_JOINTS - 1, 3))
    tr = check_array("transl", transl, (k, t, 3))
    return go, bp, tr


def scene_points(scene_xyz, scene_rgb) -> tuple[np.ndarray, np.ndarray]:
    """Checked ``xyz [N,3]`` and ``rgb [N,3]`` in [0, 1] (mid grey when ``scene_rgb`` is None)."""
    xyz = check_array("scene_xyz", scene_xyz, (None, 3))
    if scene_rgb is None:
        return xyz, np.full_like(xyz, 0.6)
    rgb = check_array("scene_rgb", scene_rgb, (len(xyz), 3))
    if rgb.size and (rgb.min() < 0 or rgb.max() > 1):
        raise ValueError(
            f"scene_rgb must be in [0, 1], got values in [{rgb.min():.3g}, {rgb.max():.3g}] "
            "(divide 8-bit colours by 255)"
        )
    return xyz, rgb


def affordance_channels(affordance, num_points: int) -> np.ndarray:
    """Checked affordance ``[N]`` or ``[N,C]`` in [0, 1], returned as ``[N,C]``."""
    a = np.asarray(affordance, np.float64)
    a = check_array("affordance", a[:, None] if a.ndim == 1 else a, (num_points, None))
    if a.size and (a.min() < 0 or a.max() > 1):
        raise ValueError(
            f"affordance must be the map in [0, 1] (geometry.affordance_map), got values in "
            f"[{a.min():.3g}, {a.max():.3g}]"
        )
    return a


def heat_colours(rgb: np.ndarray, strength: np.ndarray, cmap_table: np.ndarray) -> np.ndarray:
    """Affordance heat layer: ``(1 − a) · 0.8 · grey(rgb) + a · cmap(a)`` per point.

    The grey keeps the room readable where the affordance vanishes. ``cmap_table``
    is ``[S,3]`` evenly spaced colours of the colormap over [0, 1].
    """
    grey = 0.8 * (rgb @ np.array([0.299, 0.587, 0.114]))[:, None]
    s = np.linspace(0.0, 1.0, len(cmap_table))
    heat = np.stack([np.interp(strength, s, cmap_table[:, c]) for c in range(3)], axis=-1)
    return (1 - strength)[:, None] * grey + strength[:, None] * heat


# Matplotlib's "inferno" at 9 even stops: the viewer's JavaScript interpolates the same table.
INFERNO = np.array(
    [
        [0.001, 0.000, 0.014],
        [0.129, 0.047, 0.291],
        [0.342, 0.062, 0.429],
        [0.541, 0.135, 0.415],
        [0.736, 0.216, 0.330],
        [0.894, 0.353, 0.194],
        [0.978, 0.558, 0.035],
        [0.975, 0.798, 0.206],
        [0.988, 0.998, 0.645],
    ]
)


def vertex_normals(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Unit area-weighted normals of ``[V, 3]`` vertices; zero for vertices in no face."""
    vertices = np.asarray(vertices)
    a, b, c = vertices[faces[:, 0]], vertices[faces[:, 1]], vertices[faces[:, 2]]
    e1, e2 = b - a, c - a
    fn = np.empty_like(e1)  # the cross product written out (np.cross is slower)
    fn[:, 0] = e1[:, 1] * e2[:, 2] - e1[:, 2] * e2[:, 1]
    fn[:, 1] = e1[:, 2] * e2[:, 0] - e1[:, 0] * e2[:, 2]
    fn[:, 2] = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]
    acc = np.zeros_like(vertices)
    for c in range(3):
        np.add.at(acc, faces[:, c], fn)
    norm = np.linalg.norm(acc, axis=1, keepdims=True)
    return acc / np.where(norm > 0, norm, 1.0)


def strongest_influences(weights: np.ndarray, count: int) -> tuple[np.ndarray, np.ndarray]:
    """The ``count`` largest skinning weights per vertex of ``weights [V, J]``, renormalised to
    sum 1, and their joints: ``(joints [V, count], weights [V, count])``, strongest first."""
    idx = np.argsort(-weights, axis=1, kind="stable")[:, :count]
    w = np.take_along_axis(weights, idx, axis=1)
    return idx, w / w.sum(axis=1, keepdims=True)


def random_subset(n: int, max_count: int, seed: int) -> np.ndarray:
    """Sorted indices of at most ``max_count`` of ``n`` items, seeded (all of them if n ≤ max)."""
    if n <= max_count:
        return np.arange(n)
    return np.sort(np.random.default_rng(seed).choice(n, max_count, replace=False))


# Per-sample colours (matplotlib's "tab10"): bodies, skeletons and legends of sample k use
# PALETTE[k % 10] in every writer.
PALETTE = np.array(
    [
        [0.122, 0.467, 0.706],
        [1.000, 0.498, 0.055],
        [0.173, 0.627, 0.173],
        [0.839, 0.153, 0.157],
        [0.580, 0.404, 0.741],
        [0.549, 0.337, 0.294],
        [0.890, 0.467, 0.761],
        [0.498, 0.498, 0.498],
        [0.737, 0.741, 0.133],
        [0.090, 0.745, 0.812],
    ]
)
