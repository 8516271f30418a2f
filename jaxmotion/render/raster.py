"""A z-buffer software rasterizer in NumPy: triangles and disc splats into fragments.

The renderer draws with :mod:`jaxmotion.render.kernels`, the same arithmetic as compiled
loops; this module is their reference in array passes (the tests check that the kernels cover
the same pixels with the same winners and depths).

Everything works on *fragments*: one candidate pixel of one primitive, as a flat pixel index
and a 64-bit key ``depth_bits << 32 | primitive_id``. A positive float32's bit pattern read as
an unsigned integer grows with the float, so the smallest key of a pixel is its nearest
fragment, and one ``np.minimum.at`` resolves the depth test and names the winner at once
(:func:`resolve`); shading then runs once per visible pixel (deferred), not per fragment.

Coverage follows the usual rule: a pixel ``(i, j)`` (column, row; y down) is covered when its
centre ``(i + 0.5, j + 0.5)`` lies inside the projected triangle (edges included, with a
margin of 3e-5 in barycentric units for float32 rounding), so a closed mesh leaves no holes
however small its triangles. Depth is interpolated perspective-correctly:
``1/z`` is linear in screen space. Triangles are grouped by the longer side of their
pixel bounding box (1, 2, 3, 4, 6, 8, 12, ...) and each group is tested as one ``[m, n, n]``
array of float32 edge functions, so a body of
48k triangles, most of them a few pixels wide, costs a few array passes rather than a Python
loop; the few large triangles are cut into groups that bound the memory used.

Screen coordinates are pixels, x right, y down, ``z`` the depth along the view axis (metres,
> 0 in front of the camera).
"""

from __future__ import annotations

import numpy as np

from jaxmotion.render.kernels import BUCKET_SIDES, EDGE_EPS

__all__ = [
    "EMPTY_KEY",
    "Fragments",
    "depth_of_keys",
    "id_of_keys",
    "keys",
    "raster_surfels",
    "raster_triangles",
    "resolve",
    "triangle_barycentrics",
]

EMPTY_KEY = np.uint64(0xFFFF_FFFF_FFFF_FFFF)  # no fragment: farther than anything
_ID_MASK = np.uint64(0xFFFF_FFFF)
_MAX_CANDIDATES = 1 << 21  # candidate pixels tested in one array pass (memory bound)


class Fragments:
    """Flat pixel indices ``pix [M]`` (``row * width + column``) and keys ``key [M]`` uint64."""

    __slots__ = ("key", "pix")

    def __init__(self, pix: np.ndarray, key: np.ndarray):
        self.pix, self.key = pix, key

    @staticmethod
    def concat(parts) -> Fragments:
        parts = [p for p in parts if len(p.pix)]
        if not parts:
            return Fragments(np.zeros(0, np.int64), np.zeros(0, np.uint64))
        return Fragments(np.concatenate([p.pix for p in parts]),
                         np.concatenate([p.key for p in parts]))


def keys(depth: np.ndarray, ids: np.ndarray) -> np.ndarray:
    """Pack positive depths (float, metres) and primitive ids (< 2³²) into sortable uint64 keys."""
    bits = np.asarray(depth, np.float32).view(np.uint32).astype(np.uint64)
    return (bits << np.uint64(32)) | np.asarray(ids, np.uint64)


def depth_of_keys(k: np.ndarray) -> np.ndarray:
    """The float32 depths of keys (inf for :data:`EMPTY_KEY`)."""
    d = (k >> np.uint64(32)).astype(np.uint32).view(np.float32)
    return np.where(k == EMPTY_KEY, np.float32(np.inf), d)


def id_of_keys(k: np.ndarray) -> np.ndarray:
    """The primitive ids of keys, int64 (−1 for :data:`EMPTY_KEY`)."""
    return np.where(k == EMPTY_KEY, -1, (k & _ID_MASK).astype(np.int64))


def resolve(buffer: np.ndarray, frags: Fragments) -> np.ndarray:
    """Depth-test ``frags`` into ``buffer`` (flat uint64 keys, updated in place and returned)."""
    if len(frags.pix):
        np.minimum.at(buffer, frags.pix, frags.key)
    return buffer


def _bucket_sides(extent: np.ndarray) -> np.ndarray:
    """The smallest of :data:`~jaxmotion.render.kernels.BUCKET_SIDES` ≥ each bounding-box
    side, or the power of two above."""
    e = np.maximum(extent, 1)
    out = BUCKET_SIDES[np.minimum(np.searchsorted(BUCKET_SIDES, e), len(BUCKET_SIDES) - 1)]
    big = e > BUCKET_SIDES[-1]
    out[big] = 1 << np.ceil(np.log2(e[big])).astype(np.int64)
    return out


def raster_triangles(
    xy: np.ndarray,
    z: np.ndarray,
    faces: np.ndarray,
    width: int,
    height: int,
    *,
    id_offset: int = 0,
    cull_back: bool = True,
    near: float = 1e-3,
) -> Fragments:
    """Fragments of the triangles ``faces [F, 3]`` over vertices at ``xy [V, 2]``, depth ``z [V]``.

    Args:
      xy: pixel coordinates (x right, y down, pixel ``(i, j)`` centred at ``(i+.5, j+.5)``).
      z: depth along the view axis; triangles with a vertex nearer than ``near`` are dropped.
      faces: vertex indices; counter-clockwise seen from the front in a y-up picture (the
        usual outward winding), which is clockwise in these y-down coordinates.
      width, height: the picture; fragments outside it are dropped.
      id_offset: primitive ids are ``id_offset + face index``.
      cull_back: drop triangles seen from behind (closed meshes).
    Returns:
      the covered pixels with keys ``depth, id``.
    """
    faces = np.asarray(faces, np.int64)
    x, y, z = (np.asarray(a, np.float64) for a in (xy[:, 0], xy[:, 1], z))
    f0, f1, f2 = faces[:, 0], faces[:, 1], faces[:, 2]
    xa, xb, xc = x[f0], x[f1], x[f2]
    ya, yb, yc = y[f0], y[f1], y[f2]
    area2 = (xb - xa) * (yc - ya) - (xc - xa) * (yb - ya)
    ok = (area2 < 0) if cull_back else (area2 != 0)
    ok &= (z[f0] > near) & (z[f1] > near) & (z[f2] > near)
    idx = np.flatnonzero(ok)
    xa, xb, xc, ya, yb, yc, area2 = (a[idx] for a in (xa, xb, xc, ya, yb, yc, area2))
    # pixel bounding boxes (pixel i is covered when its centre i + 0.5 is), clipped
    x0 = np.maximum(np.ceil(np.minimum(np.minimum(xa, xb), xc) - 0.5), 0.0)
    x1 = np.minimum(np.floor(np.maximum(np.maximum(xa, xb), xc) - 0.5), width - 1.0)
    y0 = np.maximum(np.ceil(np.minimum(np.minimum(ya, yb), yc) - 0.5), 0.0)
    y1 = np.minimum(np.floor(np.maximum(np.maximum(ya, yb), yc) - 0.5), height - 1.0)
    some = np.flatnonzero((x1 >= x0) & (y1 >= y0))
    if not len(some):
        return Fragments.concat([])
    idx = idx[some]
    xa, xb, xc, ya, yb, yc, area2, x0, x1, y0, y1 = (
        a[some] for a in (xa, xb, xc, ya, yb, yc, area2, x0, x1, y0, y1))
    # Edge functions as planes over the screen, scaled to be the barycentric weights and taken
    # relative to the first candidate's centre (x0 + .5, y0 + .5), so that float32 keeps them
    # exact enough: b_i(x0 + .5 + dx, y0 + .5 + dy) = a_i dx + b_i dy + c_i (edge i opposite
    # corner i). 1/z is linear on screen too: one more plane.
    inv = 1.0 / area2
    ox, oy = x0 + 0.5, y0 + 0.5
    za, zb, zc = 1.0 / z[f0[idx]], 1.0 / z[f1[idx]], 1.0 / z[f2[idx]]
    planes = []
    for (xj, yj), (xk, yk) in (((xb, yb), (xc, yc)), ((xc, yc), (xa, ya)), ((xa, ya), (xb, yb))):
        a, b = (yj - yk) * inv, (xk - xj) * inv
        planes.append((a, b, (xj * yk - xk * yj) * inv + a * ox + b * oy))
    depth_plane = tuple(planes[0][i] * za + planes[1][i] * zb + planes[2][i] * zc
                        for i in range(3))
    f32 = [tuple(c.astype(np.float32) for c in p) for p in planes]
    ids = idx + id_offset
    side = _bucket_sides(np.maximum(x1 - x0, y1 - y0).astype(np.int64) + 1)
    order = np.argsort(side, kind="stable")
    starts = np.flatnonzero(np.diff(side[order], prepend=-1))
    parts = []
    x0i, y0i = x0.astype(np.int64), y0.astype(np.int64)
    for lo_, hi_ in zip(starts, [*starts[1:], len(order)]):
        members = order[lo_:hi_]
        n = int(side[members[0]])
        step = max(1, _MAX_CANDIDATES // (n * n))
        for lo in range(0, len(members), step):
            m = members[lo : lo + step]
            parts.append(_triangle_bucket(n, m, f32, depth_plane, x0i, y0i, ids, width, height))
    return Fragments.concat(parts)


def _triangle_bucket(n, m, planes, depth_plane, x0, y0, ids, width, height) -> Fragments:
    """Fragments of the triangles ``m`` whose bounding boxes fit ``n × n`` pixels."""
    off = np.arange(n, dtype=np.float32)
    inside = None
    for a, b, c in planes:  # E = (b dy + c) [m, n, 1] + (a dx) [m, 1, n]
        e = (b[m, None] * off + c[m, None])[:, :, None] + (a[m, None] * off)[:, None, :]
        inside = e if inside is None else np.minimum(inside, e, out=inside)
    k, r, c = np.nonzero(inside >= -EDGE_EPS)
    col, row = x0[m][k] + c, y0[m][k] + r
    keep = (col < width) & (row < height)
    k, r, c, col, row = k[keep], r[keep], c[keep], col[keep], row[keep]
    mk = m[k]
    inv_depth = depth_plane[0][mk] * c + depth_plane[1][mk] * r + depth_plane[2][mk]
    good = inv_depth > 0
    depth = 1.0 / np.where(good, inv_depth, 1.0)
    return Fragments((row * width + col)[good], keys(depth[good], ids[mk[good]]))


def triangle_barycentrics(xy: np.ndarray, z: np.ndarray, faces: np.ndarray, face: np.ndarray,
                          px: np.ndarray, py: np.ndarray) -> np.ndarray:
    """Perspective-correct barycentric weights ``[M, 3]`` of pixel centres in their triangles.

    ``face [M]`` indexes ``faces``; ``px, py [M]`` are pixel columns and rows. The weights
    interpolate vertex attributes as they are on the 3-D triangle (not on its picture).
    """
    tri = faces[face]
    tx, ty = xy[tri, 0], xy[tri, 1]
    cx, cy = px + 0.5, py + 0.5
    area2 = (tx[:, 1] - tx[:, 0]) * (ty[:, 2] - ty[:, 0]) - (tx[:, 2] - tx[:, 0]) * (ty[:, 1] - ty[:, 0])
    area2 = np.where(area2 == 0, 1.0, area2)
    j, k = [1, 2, 0], [2, 0, 1]
    b = ((ty[:, j] - ty[:, k]) * cx[:, None] + (tx[:, k] - tx[:, j]) * cy[:, None]
         + tx[:, j] * ty[:, k] - tx[:, k] * ty[:, j]) / area2[:, None]
    b = np.clip(b, 0.0, None) / z[tri]  # clip: a centre on an edge may round a hair outside
    total = b.sum(1, keepdims=True)
    return b / np.where(total > 0, total, 1.0)


def raster_surfels(
    centre: np.ndarray,
    normal: np.ndarray,
    radius: np.ndarray,
    focal: float,
    cx: float,
    cy: float,
    width: int,
    height: int,
    *,
    id_offset: int = 0,
    near: float = 1e-2,
    max_pixels: int = 32,
) -> Fragments:
    """Fragments of round surface elements: discs of ``radius [N]`` metres around
    ``centre [N, 3]`` with normals ``normal [N, 3]`` (unit, any sign; a zero row: a disc facing
    the camera), both in camera coordinates (x right, y down, z forward), under a pinhole of
    ``focal`` pixels and principal point ``(cx, cy)``.

    Each disc is drawn as its projection linearised at the centre: the ellipse
    ``δᵀ Σ⁻¹ δ ≤ 1`` with ``Σ = R² J Jᵀ + ¼ I`` (``J`` the Jacobian from the disc's plane to the
    picture; the ¼ px² keeps a disc seen edge-on a line half a pixel wide rather than nothing),
    and depths on its plane, ``z₀ + g · δ`` (so overlapping discs of one slanted surface do not
    step in depth). The footprint is searched within at most ``max_pixels`` of the centre.
    """
    c = np.asarray(centre, np.float64)
    n = np.asarray(normal, np.float64)
    n = np.where((np.abs(n).sum(1) > 0)[:, None], n, [0.0, 0.0, 1.0])
    z = c[:, 2]
    zs = np.maximum(z, near)
    x, y = cx + focal * c[:, 0] / zs, cy + focal * c[:, 1] / zs
    # a tangent basis (t1, t2) of each disc's plane
    helper = np.where((np.abs(n[:, 0]) < 0.9)[:, None], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0])
    t1 = np.cross(n, helper)
    t1 /= np.linalg.norm(t1, axis=1, keepdims=True)
    t2 = np.cross(n, t1)
    # J = d(pixel)/d(a, b): rows x, y; columns the two tangents
    fz = focal / zs
    px_x, px_y = c[:, 0] / zs, c[:, 1] / zs
    j = np.empty((len(c), 2, 2))
    for col, t in enumerate((t1, t2)):
        j[:, 0, col] = fz * (t[:, 0] - px_x * t[:, 2])
        j[:, 1, col] = fz * (t[:, 1] - px_y * t[:, 2])
    r2 = np.asarray(radius, np.float64) ** 2
    sxx = r2 * (j[:, 0, 0] ** 2 + j[:, 0, 1] ** 2) + 0.25
    syy = r2 * (j[:, 1, 0] ** 2 + j[:, 1, 1] ** 2) + 0.25
    sxy = r2 * (j[:, 0, 0] * j[:, 1, 0] + j[:, 0, 1] * j[:, 1, 1])
    det = sxx * syy - sxy * sxy
    qa, qb, qc = syy / det, -sxy / det, sxx / det  # Σ⁻¹
    # depth gradient on screen: dz/dδ = [t1_z, t2_z] J⁺ (J⁺ regularised like Σ)
    jjt = np.stack([np.stack([sxx, sxy], -1), np.stack([sxy, syy], -1)], -2) / np.maximum(r2, 1e-12)[:, None, None]
    tz = np.stack([t1[:, 2], t2[:, 2]], -1)  # [N, 2]
    g = np.einsum("nk,nik->ni", tz, j)  # tz Jᵀ  -> [N, 2]
    g = np.linalg.solve(jjt, g[..., None])[..., 0]
    hx = np.minimum(np.ceil(np.sqrt(sxx)), max_pixels).astype(np.int64)
    hy = np.minimum(np.ceil(np.sqrt(syy)), max_pixels).astype(np.int64)
    ok = (z > near) & (x + hx > 0) & (x - hx < width) & (y + hy > 0) & (y - hy < height)
    idx = np.flatnonzero(ok)
    if not len(idx):
        return Fragments.concat([])
    half = np.maximum(hx, hy)[idx]
    parts = []
    f32 = np.float32
    for h in np.unique(half):
        members = idx[half == h]
        s = 2 * int(h) + 1
        step = max(1, _MAX_CANDIDATES // (s * s))
        for lo in range(0, len(members), step):
            m = members[lo : lo + step]
            col = np.floor(x[m]).astype(np.int64)[:, None] + np.arange(-h, h + 1)  # [m, s]
            row = np.floor(y[m]).astype(np.int64)[:, None] + np.arange(-h, h + 1)
            dx = (col + 0.5 - x[m][:, None]).astype(f32)
            dy = (row + 0.5 - y[m][:, None]).astype(f32)
            a, b, cc = (q[m].astype(f32)[:, None, None] for q in (qa, qb, qc))
            quad = a * (dx * dx)[:, None, :] + (2 * b) * (dy[:, :, None] * dx[:, None, :]) \
                + cc * (dy * dy)[:, :, None]
            inside = quad <= 1.0
            inside &= ((col >= 0) & (col < width))[:, None, :]
            inside &= ((row >= 0) & (row < height))[:, :, None]
            k, r_, c_ = np.nonzero(inside)
            depth = z[m][k] + g[m, 0][k] * dx[k, c_] + g[m, 1][k] * dy[k, r_]
            good = depth > near
            k, r_, c_, depth = k[good], r_[good], c_[good], depth[good]
            parts.append(Fragments(row[k, r_] * width + col[k, c_], keys(depth, m[k] + id_offset)))
    return Fragments.concat(parts)
