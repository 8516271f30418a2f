"""Box and cylinder parts of the synthetic rooms: moves, triangles, surface samples, meshes.

Host-side numpy only. A :class:`Part` is an axis-aligned box, or an upright (z-axis)
cylinder inscribed in its box, in metres, z-up. Furniture is built from parts in
object-local coordinates (:mod:`jaxmotion.scene.furniture`) and moved into the room by
quarter turns about z plus a translation, so every box stays exact and axis-aligned.
"""

from __future__ import annotations

import dataclasses
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    import trimesh

# Outward normals of the six box faces, in the order of ``Part.faces``.
FACE_DIRS = np.array([[-1, 0, 0], [1, 0, 0], [0, -1, 0], [0, 1, 0], [0, 0, -1], [0, 0, 1]], float)
CYLINDER_SECTIONS = 16
_EPS = 1e-6


# Palettes (rgb in [0, 1]) the furniture builders draw colours from.
WOOD = ((0.55, 0.38, 0.22), (0.72, 0.55, 0.36), (0.36, 0.24, 0.15), (0.82, 0.70, 0.52))
LAMINATE = ((0.92, 0.92, 0.90), (0.62, 0.62, 0.64), (0.22, 0.22, 0.24))
FABRIC = ((0.30, 0.36, 0.56), (0.56, 0.22, 0.22), (0.44, 0.50, 0.40), (0.70, 0.64, 0.54),
          (0.26, 0.26, 0.30), (0.62, 0.48, 0.30))
METAL = ((0.72, 0.73, 0.76), (0.16, 0.16, 0.17))
CERAMIC = ((0.95, 0.95, 0.95), (0.90, 0.90, 0.86))
BRIGHT = ((0.80, 0.20, 0.20), (0.20, 0.45, 0.75), (0.90, 0.75, 0.20), (0.25, 0.60, 0.35),
          (0.55, 0.30, 0.60), (0.90, 0.55, 0.25))


@dataclasses.dataclass(frozen=True)
class Part:
    """One solid piece of a room (m).

    Attributes:
      lo, hi: box corners (xmin, ymin, zmin), (xmax, ymax, zmax).
      rgb: colour in [0, 1].
      shape: ``"box"`` or ``"cylinder"`` (axis z, radius = half the smaller xy side).
      semantic, instance: labels of the points sampled on it (-1 = none).
      faces: which box faces are visible (-x, +x, -y, +y, -z, +z); a face resting on the
        floor (z = 0, pointing down) is never sampled whatever this says.
    """

    lo: tuple[float, float, float]
    hi: tuple[float, float, float]
    rgb: tuple[float, float, float]
    shape: str = "box"
    semantic: int = -1
    instance: int = -1
    faces: tuple[bool, ...] = (True,) * 6


def part(x0, x1, y0, y1, z0, z1, rgb, shape="box") -> Part:
    """A part spanning [x0, x1] x [y0, y1] x [z0, z1] (any corner order), colour rgb."""
    lo = (min(x0, x1), min(y0, y1), min(z0, z1))
    hi = (max(x0, x1), max(y0, y1), max(z0, z1))
    return Part(tuple(map(float, lo)), tuple(map(float, hi)),
                tuple(float(np.clip(c, 0.0, 1.0)) for c in rgb), shape)


def tone(rng, palette, jitter=0.06):
    """A palette colour with per-instance brightness and tint jitter."""
    base = np.asarray(palette[rng.integers(len(palette))], float)
    return np.clip(base * (1.0 + rng.normal(0.0, jitter)) + rng.normal(0.0, jitter / 3, 3), 0, 1)


def shade(rgb, f):
    """rgb scaled by f, clipped to [0, 1]."""
    return np.clip(np.asarray(rgb) * f, 0.0, 1.0)


def leg_set(w, d, h, t, rgb, inset=0.0, round_=False, z0=0.0):
    """Four legs of side t (m) at the corners of a w x d rectangle, from z0 to h."""
    xs, ys = (-w / 2 + inset, w / 2 - inset - t), (-d / 2 + inset, d / 2 - inset - t)
    shape = "cylinder" if round_ else "box"
    return [part(x, x + t, y, y + t, z0, h, rgb, shape) for x in xs for y in ys]


def rot90(k: int) -> np.ndarray:
    """[3, 3] rotation by k quarter turns counter-clockwise about z (exact integers)."""
    c, s = [(1, 0), (0, 1), (-1, 0), (0, -1)][k % 4]
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]], float)


def moved(p: Part, k: int, t) -> Part:
    """``p`` rotated by k quarter turns about the origin, then shifted by t [3] (m)."""
    r = rot90(k)
    corners = np.stack([np.asarray(p.lo), np.asarray(p.hi)]) @ r.T + np.asarray(t, float)
    dirs = FACE_DIRS @ r.T  # where each local face now points
    faces = [False] * 6
    for visible, d in zip(p.faces, dirs):
        faces[int(np.argmax(FACE_DIRS @ d))] = visible
    return dataclasses.replace(p, lo=tuple(corners.min(0).tolist()),
                               hi=tuple(corners.max(0).tolist()), faces=tuple(faces))


def bounds(parts) -> tuple[np.ndarray, np.ndarray]:
    """Axis-aligned box (lo [3], hi [3]) around parts, metres."""
    return (np.min([p.lo for p in parts], axis=0), np.max([p.hi for p in parts], axis=0))


def _box_triangles(p: Part):
    lo, hi = np.asarray(p.lo), np.asarray(p.hi)
    tris = []
    for f, d in enumerate(FACE_DIRS):
        axis, side = int(np.argmax(np.abs(d))), d.max() > 0
        if not p.faces[f] or (axis == 2 and not side and lo[2] <= _EPS < hi[2]):
            continue
        u, v = [a for a in range(3) if a != axis]
        quad = np.empty((4, 3))
        quad[:, axis] = hi[axis] if side else lo[axis]
        quad[:, u] = [lo[u], hi[u], hi[u], lo[u]]
        quad[:, v] = [lo[v], lo[v], hi[v], hi[v]]
        tris += [quad[[0, 1, 2]], quad[[0, 2, 3]]]
    return np.array(tris).reshape(-1, 3, 3)


def _cylinder_triangles(p: Part):
    lo, hi = np.asarray(p.lo), np.asarray(p.hi)
    c, r = 0.5 * (lo[:2] + hi[:2]), 0.5 * min(hi[0] - lo[0], hi[1] - lo[1])
    a = np.linspace(0.0, 2 * np.pi, CYLINDER_SECTIONS + 1)
    ring = c + r * np.stack([np.cos(a), np.sin(a)], 1)  # [S+1, 2]
    bot = np.concatenate([ring, np.full((len(ring), 1), lo[2])], 1)
    top = np.concatenate([ring, np.full((len(ring), 1), hi[2])], 1)
    tris = []
    for i in range(CYLINDER_SECTIONS):
        tris += [[bot[i], bot[i + 1], top[i + 1]], [bot[i], top[i + 1], top[i]]]
        tris.append([np.array([*c, hi[2]]), top[i], top[i + 1]])
        if lo[2] > _EPS:  # bottom cap unless it rests on the floor
            tris.append([np.array([*c, lo[2]]), bot[i + 1], bot[i]])
    return np.array(tris, float)


def part_triangles(p: Part) -> tuple[np.ndarray, np.ndarray]:
    """Visible triangles of a part: (tri [F, 3, 3], outward unit normal [F, 3])."""
    tri = _cylinder_triangles(p) if p.shape == "cylinder" else _box_triangles(p)
    if len(tri) == 0:
        return np.zeros((0, 3, 3)), np.zeros((0, 3))
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    centre = 0.5 * (np.asarray(p.lo) + np.asarray(p.hi))
    flip = np.einsum("fc,fc->f", n, tri.mean(1) - centre) < 0  # convex: outward = away
    tri[flip] = tri[flip][:, [0, 2, 1]]
    n[flip] = -n[flip]
    return tri, n


def _all_triangles(parts):
    tris, normals, owner = [], [], []
    for i, p in enumerate(parts):
        t, n = part_triangles(p)
        tris.append(t), normals.append(n), owner.append(np.full(len(t), i))
    return np.concatenate(tris), np.concatenate(normals), np.concatenate(owner)


def _inside_parts(points, owner, parts, index, eps=1e-4):
    """[M] bool: point m lies in (or on) a part of ``index`` other than its own part."""
    lo = np.array([parts[i].lo for i in index]) - eps
    hi = np.array([parts[i].hi for i in index]) + eps
    cyl = np.array([parts[i].shape == "cylinder" for i in index])
    hidden = np.zeros(len(points), bool)
    for s in range(0, len(points), 8192):  # chunks keep the [m, P] masks small
        q = points[s:s + 8192, None, :]
        inside = np.all((q >= lo) & (q <= hi), axis=-1)  # [m, P]
        if cyl.any():
            centre, rad = 0.5 * (lo + hi)[:, :2], 0.5 * np.minimum(*(hi - lo)[:, :2].T)
            radial = np.linalg.norm(q[..., :2] - centre, axis=-1) <= rad
            inside &= ~cyl | radial
        inside &= owner[s:s + 8192, None] != np.asarray(index)[None]
        hidden[s:s + 8192] = inside.any(axis=1)
    return hidden


def sample_parts(parts, num_points: int, rng: np.random.Generator, *, colour_noise=0.02):
    """Area-weighted points on the visible surfaces of parts (ScanNet-like labels).

    A point is dropped and redrawn when it lies in or on another *labelled* part
    (``instance >= 0``): floor under furniture, leg tops under seats, wall behind a door.
    Returns dict of numpy arrays: xyz [N, 3] (m), rgb [N, 3] in [0, 1] (part colour plus
    Gaussian noise ``colour_noise``), normal [N, 3] (outward), semantic [N], instance [N].
    """
    tri, normal, owner = _all_triangles(parts)
    area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    occluders = [i for i, p in enumerate(parts) if p.instance >= 0]
    rgb = np.array([p.rgb for p in parts])
    labels = np.array([(p.semantic, p.instance) for p in parts], np.int32)
    got, have = [], 0
    for _ in range(50):
        m = int(1.3 * (num_points - have)) + 64
        f = rng.choice(len(tri), size=m, p=area / area.sum())
        u, v = rng.random(m), rng.random(m)
        swap = u + v > 1.0  # fold the unit square onto the triangle
        u, v = np.where(swap, 1 - u, u), np.where(swap, 1 - v, v)
        t0 = tri[f, 0]
        xyz = t0 + u[:, None] * (tri[f, 1] - t0) + v[:, None] * (tri[f, 2] - t0)
        noise = rng.normal(0.0, colour_noise, (m, 3))
        keep = ~_inside_parts(xyz, owner[f], parts, occluders) if occluders else np.ones(m, bool)
        got.append((xyz[keep], f[keep], noise[keep]))
        have += int(keep.sum())
        if have >= num_points:
            break
    else:
        raise RuntimeError("could not sample enough visible surface points")
    xyz, f, noise = (np.concatenate(a)[:num_points] for a in zip(*got))
    return dict(xyz=xyz, rgb=np.clip(rgb[owner[f]] + noise, 0.0, 1.0), normal=normal[f],
                semantic=labels[owner[f], 0], instance=labels[owner[f], 1])


def parts_mesh(parts) -> trimesh.Trimesh:
    """All visible triangles of parts as one mesh, RGBA uint8 vertex colours (unshared
    vertices, so every triangle keeps its part's flat colour)."""
    import trimesh  # imported on use (scene loading does not need it)

    tri, _, owner = _all_triangles(parts)
    rgb = np.round(np.array([p.rgb for p in parts])[owner] * 255).astype(np.uint8)
    alpha = np.full((3 * len(tri), 1), 255, np.uint8)
    colours = np.concatenate([np.repeat(rgb, 3, axis=0), alpha], 1)
    faces = np.arange(3 * len(tri)).reshape(-1, 3)
    return trimesh.Trimesh(tri.reshape(-1, 3), faces, vertex_colors=colours, process=False)
