"""Frames and units found from a room's geometry: metres, z-up, the floor at z = 0 (host numpy).

A room file says little about its frame: glTF is y-up by its specification but many files are
authored z-up, PLY / OBJ / STL have no convention, phone scans come tilted by a degree or two,
CAD exports are in millimetres or feet, and the floor sits wherever the scanner stood.
:func:`level_scene` finds the frame from the geometry, in this order:

1. **unit** (:func:`detect_unit`): a room is at most :data:`MAX_ROOM` m across and a storey
   at most :data:`MAX_STOREY` m tall (its box's smallest side); a room whose smallest side
   is 6–20 "m" is in feet, a larger one in centimetres or millimetres (the first that makes
   both fit); a scene that fits none is refused with the fix (``--unit``) before any work;
2. **up axis** (:func:`find_floor`): for each axis and direction, the largest plane facing
   along it near that end of the room (RANSAC over a seeded subsample); the floor is the
   large horizontal plane at the bottom, so the axis whose plane holds the most points wins,
   counted twice for the shortest side of the room's box (rooms are lower than they are
   wide) and 1.2 times for the file's own convention (``prior``), and of its two ends
   the floor is the one the rest of the room stands on (more points in the half metre
   above it than below the other end);
3. **level and shift**: the floor plane's normal is turned to +z (a tilt under
   :data:`TILT_TOLERANCE` is left alone) and the floor moved to z = 0 (a shift under
   :data:`FLOOR_TOLERANCE` likewise), so a file already in jaxmotion's frame is unchanged.

Each change is said in the notes (``generate`` and ``scene info`` print them, and they reach
the JSON summary).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from jaxmotion.errors import SceneError

__all__ = ["AXIS_TO_Z", "FLOOR_TOLERANCE", "MAX_ROOM", "MAX_STOREY", "TILT_TOLERANCE", "UNITS",
           "Floor",
           "detect_unit", "estimate_normals", "find_floor", "level_scene", "rotation_between"]

MAX_ROOM = 60.0  # m: the largest room side read as metres
MAX_STOREY = 6.0  # m: a smallest side above this (and under 20) is feet, not metres
TILT_TOLERANCE = np.deg2rad(1.0)  # a floor tilted less than this is left as it is
FLOOR_TOLERANCE = 0.02  # m: a floor this close to z = 0 is not moved
#: unit name -> metres per unit (``--unit``; :func:`detect_unit` tries feet, then cm, then mm)
UNITS = {"m": 1.0, "cm": 0.01, "mm": 0.001, "ft": 0.3048, "in": 0.0254}
_PLANE_TOL = 0.03  # m: inlier distance of a floor plane
_AXIS_COS = np.cos(np.deg2rad(25.0))  # a candidate floor is within 25 degrees of an axis
_SAMPLE = 20_000  # points the planes are found on (seeded subsample)
_TRIALS = 300


def detect_unit(xyz: np.ndarray, unit: str = "auto") -> tuple[float, str | None]:
    """(metres per file unit, a note or None) for the scene ``xyz [N, 3]``.

    ``unit``: ``"auto"`` (from the size, module docstring) or one of :data:`UNITS`. Raises
    :class:`SceneError` when no unit makes it a room."""
    if unit != "auto":
        if unit not in UNITS:
            raise SceneError(f"unknown unit {unit!r}; give one of {', '.join(UNITS)} or 'auto'")
        scale = UNITS[unit]
        return scale, None if scale == 1.0 else f"read in {unit} (as told): scaled by {scale:g}"
    ext = np.percentile(xyz, 99.5, axis=0) - np.percentile(xyz, 0.5, axis=0)
    big, small = float(ext.max()), float(ext.min())
    if big <= MAX_ROOM and small <= MAX_STOREY:
        return 1.0, None
    if big <= MAX_ROOM and small <= 20.0:
        return UNITS["ft"], (f"the room is {big:.1f} x {small:.1f} units: read as feet "
                             "(scaled by 0.3048); pass --unit m if it really is metres")
    if big <= MAX_ROOM:  # a tall hall in metres
        return 1.0, None
    fits = [n for n in ("cm", "mm") if big * UNITS[n] <= MAX_ROOM]
    name = next((n for n in fits if small * UNITS[n] <= MAX_STOREY), fits[0] if fits else None)
    if name is None:
        raise SceneError(f"the scene is {big:.3g} units across: no unit (m, cm, mm) makes it "
                         f"a room of at most {MAX_ROOM:.0f} m; crop it to one room or give "
                         "--unit")
    return UNITS[name], (f"the room is {big:.0f} x {small:.0f} units: read as {name} (scaled "
                         f"by {UNITS[name]:g}); pass --unit to say otherwise")


def estimate_normals(xyz: np.ndarray, k: int = 12) -> np.ndarray:
    """Unit normals ``[N, 3]`` of a point cloud: the smallest principal axis of each point's
    ``k`` nearest neighbours, turned to face up (+z) on horizontal surfaces and towards the
    room's vertical axis on the others (walls face into the room)."""
    from scipy.spatial import cKDTree

    xyz = np.asarray(xyz, np.float64)
    if len(xyz) < 3:
        return np.zeros_like(xyz)
    k = min(k, len(xyz))
    _, idx = cKDTree(xyz).query(xyz, k=k)
    nb = xyz[idx] - xyz[idx].mean(axis=1, keepdims=True)
    cov = np.einsum("nki,nkj->nij", nb, nb)
    _, vec = np.linalg.eigh(cov)
    n = vec[:, :, 0]
    centre = np.median(xyz[:, :2], axis=0)
    inward = np.concatenate([centre - xyz[:, :2], np.zeros((len(xyz), 1))], 1)
    flip = np.where(np.abs(n[:, 2]) > 0.7, n[:, 2] < 0, np.einsum("nc,nc->n", n, inward) < 0)
    n = np.where(flip[:, None], -n, n)
    return (n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12)).astype(np.float32)


@dataclasses.dataclass(frozen=True)
class Floor:
    """The floor plane found in a scene: unit ``normal [3]`` pointing up into the room,
    ``offset`` (the plane is ``x · normal = offset``), ``inliers`` (its share of the sampled
    points) and ``axis`` / ``sign`` (the file axis it lies along)."""

    normal: np.ndarray
    offset: float
    inliers: float
    axis: int
    sign: int


def _plane(pts: np.ndarray, axis_dir: np.ndarray, rng) -> tuple[np.ndarray, float, np.ndarray]:
    """The plane with the most points of ``pts`` within :data:`_PLANE_TOL`, its normal within
    25 degrees of ``axis_dir`` and facing it: ``(normal, offset, inlier mask)``, refined by a
    least-squares fit of its inliers."""
    if len(pts) < 3:
        return (axis_dir, float((pts @ axis_dir).min()) if len(pts) else 0.0,
                np.zeros(len(pts), bool))
    tri = pts[rng.integers(0, len(pts), (_TRIALS, 3))]
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    norm = np.linalg.norm(n, axis=1)
    n = n / np.maximum(norm, 1e-12)[:, None]
    n *= np.where(n @ axis_dir < 0, -1.0, 1.0)[:, None]
    ok = (norm > 1e-9) & (n @ axis_dir >= _AXIS_COS)
    if not ok.any():  # degenerate samples: the axis itself through the lowest points
        n, ok = axis_dir[None], np.ones(1, bool)
        tri = np.repeat(pts[np.argmin(pts @ axis_dir)][None, None], 3, 1)
    n, d = n[ok], np.einsum("mc,mc->m", n[ok], tri[ok, 0])
    counts = (np.abs(pts @ n.T - d) <= _PLANE_TOL).sum(0)
    best = int(np.argmax(counts))
    normal, offset = n[best], float(d[best])
    for _ in range(2):  # least squares on the inliers
        inl = np.abs(pts @ normal - offset) <= _PLANE_TOL
        if inl.sum() < 3:
            break
        q = pts[inl]
        c = q.mean(0)
        w = np.linalg.eigh((q - c).T @ (q - c))[1][:, 0]
        w = w if w @ axis_dir >= 0 else -w
        normal, offset = w, float(c @ w)
    return normal, offset, np.abs(pts @ normal - offset) <= _PLANE_TOL


def _sample(xyz: np.ndarray, seed: int):
    """``(rng, points)``: the seeded generator and the subsample the planes are found on."""
    rng = np.random.default_rng(seed)
    return rng, xyz[rng.choice(len(xyz), min(len(xyz), _SAMPLE), replace=False)]


def _end_plane(pts: np.ndarray, axis: int, sign: int, rng) -> tuple[np.ndarray, float, float]:
    """``(normal, offset, share of pts)`` of the largest plane facing ``sign`` along ``axis``
    in the slab at that end of ``pts`` (deep enough for a tilted floor)."""
    u = sign * pts[:, axis]
    span = float(np.percentile(u, 99) - np.percentile(u, 1))
    band = u <= np.percentile(u, 1) + max(0.3, 0.1 * span)
    normal, offset, inl = _plane(pts[band], np.eye(3)[axis] * sign, rng)
    return normal, offset, inl.sum() / len(pts)


def find_floor(xyz: np.ndarray, prior: int = 2, seed: int = 0) -> Floor | None:
    """The floor plane of ``xyz [N, 3]`` (metres) along any file axis (module docstring, step
    2); ``prior`` is the file convention's up axis (0, 1, 2). None for fewer than 50 points."""
    xyz = np.asarray(xyz, np.float64)
    if len(xyz) < 50:
        return None
    rng, pts = _sample(xyz, seed)
    found = {(axis, sign): _end_plane(pts, axis, sign, rng)
             for axis in range(3) for sign in (1, -1)}
    # a room is lower than it is wide: the shortest side of its box is the up axis unless
    # another axis has a far larger floor; the file's convention breaks near ties
    ext = np.percentile(pts, 99, axis=0) - np.percentile(pts, 1, axis=0)
    lowest = int(np.argmin(ext))
    best_axis = max(range(3), key=lambda a: max(found[a, 1][2], found[a, -1][2])
                    * (2.0 if a == lowest else 1.0) * (1.2 if a == prior else 1.0))
    planes = []
    for sign in (1, -1):
        normal, offset, share = found[best_axis, sign]
        height = pts @ normal - offset  # above this plane, along its normal
        # what stands on a floor (legs, bases, seats) fills the half metre above it; below
        # a ceiling there are only the walls, which both ends share
        planes.append((int(((height > 0.05) & (height < 0.6)).sum()), share, sign))
    # the floor: the end the rest of the room stands on, weighed by how much of a plane it
    # is (a real scan's ceiling is often partly scanned, and lamps or a dropped ceiling fill
    # the half metre below it as furniture fills the half metre above the floor); the file's
    # own up breaks near ties; a plane with far fewer points than the other end's is no
    # floor (an end with nothing)
    a, b = planes

    def weight(p):
        return p[0] * np.sqrt(max(p[1], 1e-9)) * (1.3 if best_axis == prior and p[2] == 1
                                                   else 1.0)

    floor_end = a if (weight(a) >= weight(b) and a[1] >= 0.3 * b[1]) or b[1] < 0.3 * a[1] \
        else b
    normal, offset, share = found[best_axis, floor_end[2]]
    return Floor(np.asarray(normal, np.float64), float(offset), float(share), best_axis,
                 floor_end[2])


def rotation_between(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The smallest rotation ``[3, 3]`` taking unit vector ``a`` to unit vector ``b``."""
    a, b = np.asarray(a, np.float64), np.asarray(b, np.float64)
    v, c = np.cross(a, b), float(a @ b)
    if c < -1 + 1e-9:  # opposite: half a turn about any axis orthogonal to a
        axis = np.cross(a, [1.0, 0.0, 0.0] if abs(a[0]) < 0.9 else [0.0, 1.0, 0.0])
        axis /= np.linalg.norm(axis)
        return 2.0 * np.outer(axis, axis) - np.eye(3)
    vx = np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])
    return np.eye(3) + vx + vx @ vx / (1.0 + c)


#: A proper rotation taking each signed file axis ``(axis, sign)`` to +z (y-up: x -> x, y -> z).
AXIS_TO_Z = {
    (2, 1): np.eye(3),
    (1, 1): np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]]),
    (0, 1): np.array([[0.0, 0.0, -1.0], [0.0, 1.0, 0.0], [1.0, 0.0, 0.0]]),
    (2, -1): np.diag([1.0, -1.0, -1.0]),
    (1, -1): np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]]),
    (0, -1): np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]]),
}
_AXIS_NAMES = {(0, 1): "+x", (0, -1): "-x", (1, 1): "+y", (1, -1): "-y", (2, 1): "+z",
               (2, -1): "-z"}


def level_scene(scene, *, up: str = "auto", prior: str = "z", unit: str = "auto",
                seed: int = 0):
    """``scene`` in metres, z-up, its floor at z = 0, and notes on what was changed.

    Args:
      scene: a :class:`~jaxmotion.scene.Scene` as read from its file.
      up: ``"auto"`` (found, module docstring), ``"z"`` or ``"y"`` (the file's up axis, as
        told; the floor is still levelled and moved to z = 0).
      prior: the file format's convention (``"y"`` for glTF), preferred on near ties.
      unit: ``"auto"`` or a unit of :data:`UNITS`.
    Returns ``(scene, notes)``; raises :class:`SceneError` for a scene no unit makes a room.
    """
    if up not in ("auto", "y", "z"):
        raise ValueError(f"up must be 'auto', 'y' or 'z', got {up!r}")
    notes: list[str] = []
    if scene.num_points < 50:
        return scene, ()
    scale, note = detect_unit(scene.xyz, unit)
    if note:
        notes.append(note)
    xyz = np.asarray(scene.xyz, np.float64) * scale
    told = {"z": 2, "y": 1}.get(up)
    axis = told if told is not None else {"z": 2, "y": 1}[prior]
    floor = _along(xyz, told, seed) if told is not None else find_floor(xyz, axis, seed)
    if floor is None or floor.inliers < 0.02:
        coarse, fine = AXIS_TO_Z[axis, 1], np.eye(3)
        z0 = float(np.percentile((xyz @ coarse.T)[:, 2], 1))
        notes.append("no floor plane found (fewer than 2 % of the points lie on one): the "
                     f"{'given' if told is not None else 'file format convention'} up axis is "
                     "kept")
    else:
        coarse = AXIS_TO_Z[floor.axis, floor.sign]
        normal = coarse @ floor.normal
        tilt = float(np.arccos(np.clip(normal[2], -1.0, 1.0)))
        fine = rotation_between(normal, [0.0, 0.0, 1.0]) if tilt > TILT_TOLERANCE else np.eye(3)
        z0 = float(floor.offset) if tilt > TILT_TOLERANCE else float(np.median(
            (xyz @ coarse.T)[np.abs(xyz @ floor.normal - floor.offset) <= _PLANE_TOL, 2]))
        default = (2, 1) if prior == "z" else (1, 1)
        if (floor.axis, floor.sign) != default and told is None:
            named = _AXIS_NAMES[floor.axis, floor.sign]
            turned = ("kept as it is" if (floor.axis, floor.sign) == (2, 1) else "turned to z-up")
            notes.append(f"up axis found from the floor: the file is {named}-up, not "
                         f"{'y' if prior == 'y' else 'z'}-up as its format's convention has it: "
                         f"{turned} ({floor.inliers:.0%} of the points on the floor)")
        if tilt > TILT_TOLERANCE:
            notes.append(f"the floor was tilted by {np.rad2deg(tilt):.1f} degrees: levelled")
    rot = fine @ coarse
    shift = np.array([0.0, 0.0, -z0]) if abs(z0) > FLOOR_TOLERANCE else np.zeros(3)
    if abs(z0) > FLOOR_TOLERANCE:
        notes.append(f"the floor was at z = {z0:.2f} m: moved to z = 0")
    if scale != 1.0:
        scene = _scaled(scene, scale)
    if not np.allclose(rot, np.eye(3)) or shift.any():
        scene = scene.transformed(rot, shift)
    return scene, tuple(notes)


def _along(xyz: np.ndarray, axis: int, seed: int) -> Floor | None:
    """The floor along a told axis (+axis up): the largest plane at its low end."""
    rng, pts = _sample(xyz, seed)
    normal, offset, share = _end_plane(pts, axis, 1, rng)
    return Floor(normal, offset, share, axis, 1)


def _scaled(scene, scale: float):
    """``scene`` with points and boxes multiplied by ``scale`` (normals unchanged)."""
    objects = []
    for o in scene.objects:
        new = dict(o, bbox_min=[v * scale for v in o["bbox_min"]],
                   bbox_max=[v * scale for v in o["bbox_max"]])
        if "surface_height" in o:
            new["surface_height"] = o["surface_height"] * scale
        objects.append(new)
    return dataclasses.replace(scene, xyz=np.asarray(scene.xyz, np.float64) * scale,
                               objects=tuple(objects))
