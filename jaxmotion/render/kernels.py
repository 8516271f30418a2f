"""The per-frame loops of :mod:`jaxmotion.render.frames`, compiled with numba.

A frame of ``motion.mp4`` draws about 48k body triangles, most a few pixels wide, at twice
the picture's size; in NumPy that is a chain of array passes over candidate pixels (the
reference, :func:`jaxmotion.render.raster.raster_triangles` with
:func:`~jaxmotion.render.raster.resolve`), here one loop over the triangles that writes the
z-buffer as it goes. Each kernel repeats its NumPy reference's arithmetic in the same order
and precision (float64 for positions and depths, float32 edge functions with the same
3e-5 margin, the same ``(depth, id)`` tie-break), so the pixels it covers and the triangle
that wins each are the reference's:

- :func:`skin`: a body's vertices for a frame (linear blend skinning);
- :func:`project`: body vertices to pixel coordinates and depths (as ``Camera.project``);
- :func:`raster_triangles`: triangles into a depth + id buffer, depth-tested against the room;
- :func:`vertex_colours`: area-weighted vertex normals shaded by the body's lights;
- :func:`compose`: Gouraud colours of the body pixels (perspective-correct barycentrics)
  over the room's colours, each ``s × s`` block of samples averaged into one pixel;
- :func:`shadow_pixels`: the contact and drop shadows of a ``ShadowMap`` on the room's
  pixels inside a box (each pixel's world point from its depth);
- :func:`raster_surfels`: the room's disc splats into a depth + id buffer (once per clip);
- :func:`kth_distances`: each splat's distance to its 6th-nearest point (its radius; a grid
  search, ``scipy.spatial.cKDTree``'s answer);
- :func:`to_uint8`: a float picture in [0, 1] to bytes.

Every kernel releases the GIL (``nogil``), so the frames that
:func:`~jaxmotion.render.frames.drawn_frames` draws on two threads run on two cores, and is
cached on disk (``cache=True``: compiled once per installation, ~1 s each; later processes
load the machine code in milliseconds, see :func:`warm_up`).
"""

from __future__ import annotations

import math
import threading

import numba
import numpy as np

__all__ = ["BUCKET_SIDES", "EDGE_EPS", "compose", "kth_distances", "project", "raster_surfels",
           "raster_triangles", "shadow_pixels", "skin", "to_uint8", "vertex_colours", "warm_up"]

_JIT = {"cache": True, "nogil": True, "boundscheck": False}
#: A pixel centre on an edge shared by two triangles must not fall out of both to float32
#: rounding: centres within this much of an edge (in barycentric units) count as inside, so
#: such a pixel gets two fragments and the depth test keeps one (here and in the reference,
#: :mod:`jaxmotion.render.raster`).
EDGE_EPS = np.float32(3e-5)
_NEAR = 1e-3  # triangles with a vertex nearer than this (metres) are dropped
#: The sides (pixels) of the squares a triangle's candidate pixels are tested in: the smallest
#: one ≥ its bounding box's longer side, or the power of two above (here and in the reference).
BUCKET_SIDES = np.array([1, 2, 3, 4, 6, 8, 12, 16, 24, 32, 48, 64], np.int64)
_F0, _F1, _HALF = np.float32(0.0), np.float32(1.0), np.float32(0.5)
_F255 = np.float32(255.0)
_NEAR_FLOOR = np.float32(0.05)  # receivers this near z = 0 take the drop shadow
# the body's lighting weights (float32): ambient, hemisphere, key, rim, specular
_LIT = np.array([0.30, 0.20, 0.55, 0.10, 0.12], np.float32)


@numba.njit(**_JIT)
def skin(rest, affine, influence, weight, count, out):
    """Linear blend skinning of one body: ``out [V, 3]`` float32 from the rest vertices
    ``rest [V, 3]`` float32 and the joints' maps ``affine [J, 12]`` float32 (row-major
    ``[G | t]``), each vertex blending its ``count [V]`` strongest joints ``influence [V, C]``
    with weights ``weight [V, C]`` (a single joint's map taken as it is, several summed in
    order: the arithmetic of ``Bodies.from_smplx``'s NumPy blend)."""
    m = np.empty(12, np.float32)
    for v in range(rest.shape[0]):
        j = influence[v, 0]
        if count[v] <= 1:
            for q in range(12):
                m[q] = affine[j, q]
        else:
            w = weight[v, 0]
            for q in range(12):
                m[q] = affine[j, q] * w
            for c in range(1, count[v]):
                j, w = influence[v, c], weight[v, c]
                for q in range(12):
                    m[q] += w * affine[j, q]
        x, y, z = rest[v, 0], rest[v, 1], rest[v, 2]
        for r in range(3):
            out[v, r] = m[4 * r] * x + m[4 * r + 1] * y + m[4 * r + 2] * z + m[4 * r + 3]


@numba.njit(**_JIT)
def project(verts, eye, rot, focal, cx, cy, shift_x, shift_y, x, y, z):
    """Pixel coordinates minus ``(shift_x, shift_y)`` into ``x, y [N]`` and depths into
    ``z [N]`` (float64) of world points ``verts [N, 3]`` seen by a camera (``eye [3]``,
    ``rot [3, 3]`` rows right, down, forward, ``focal``, ``(cx, cy)``)."""
    for i in range(verts.shape[0]):
        p0, p1, p2 = verts[i, 0] - eye[0], verts[i, 1] - eye[1], verts[i, 2] - eye[2]
        c0 = p0 * rot[0, 0] + p1 * rot[0, 1] + p2 * rot[0, 2]
        c1 = p0 * rot[1, 0] + p1 * rot[1, 1] + p2 * rot[1, 2]
        c2 = p0 * rot[2, 0] + p1 * rot[2, 1] + p2 * rot[2, 2]
        safe = c2 if abs(c2) > 1e-9 else 1e-9
        x[i] = (cx + focal * c0 / safe) - shift_x
        y[i] = (cy + focal * c1 / safe) - shift_y
        z[i] = c2


@numba.njit(**_JIT)
def _bucket_side(extent):
    """raster._bucket_sides for one extent: the side of the square the reference tests."""
    e = max(extent, 1)
    for s in BUCKET_SIDES:
        if s >= e:
            return s
    return 1 << math.ceil(math.log2(e))


@numba.njit(**_JIT)
def raster_triangles(x, y, z, faces, vert_offset, id_offset, depth, ids):
    """Depth-test the front-facing triangles ``faces [F, 3]`` (indices into ``x, y, z`` from
    ``vert_offset``; counter-clockwise seen from the front in a y-up picture) into the
    buffers ``depth [H, W]`` float32 and ``ids [H, W]`` int64 in place: a pixel takes a
    triangle's fragment (id ``id_offset + f``) when its depth is smaller, or equal with a
    smaller id. Coverage, depth and ties are those of ``raster.raster_triangles`` (the pixel
    centre inside, edges within 3e-5 barycentric units included; 1/z interpolated across the
    picture) followed by ``raster.resolve``."""
    h, w = depth.shape
    for f in range(faces.shape[0]):
        i0, i1, i2 = faces[f, 0] + vert_offset, faces[f, 1] + vert_offset, faces[f, 2] + vert_offset
        xa, xb, xc = x[i0], x[i1], x[i2]
        ya, yb, yc = y[i0], y[i1], y[i2]
        area2 = (xb - xa) * (yc - ya) - (xc - xa) * (yb - ya)
        if not (area2 < 0) or not (z[i0] > _NEAR and z[i1] > _NEAR and z[i2] > _NEAR):
            continue
        x0 = max(math.ceil(min(min(xa, xb), xc) - 0.5), 0.0)
        x1 = min(math.floor(max(max(xa, xb), xc) - 0.5), w - 1.0)
        y0 = max(math.ceil(min(min(ya, yb), yc) - 0.5), 0.0)
        y1 = min(math.floor(max(max(ya, yb), yc) - 0.5), h - 1.0)
        if x1 < x0 or y1 < y0:
            continue
        inv = 1.0 / area2
        ox, oy = x0 + 0.5, y0 + 0.5
        # edge i opposite corner i: b_i(ox + dx, oy + dy) = a_i dx + b_i dy + c_i
        a0, b0 = (yb - yc) * inv, (xc - xb) * inv
        c0 = (xb * yc - xc * yb) * inv + a0 * ox + b0 * oy
        a1, b1 = (yc - ya) * inv, (xa - xc) * inv
        c1 = (xc * ya - xa * yc) * inv + a1 * ox + b1 * oy
        a2, b2 = (ya - yb) * inv, (xb - xa) * inv
        c2 = (xa * yb - xb * ya) * inv + a2 * ox + b2 * oy
        za, zb, zc = 1.0 / z[i0], 1.0 / z[i1], 1.0 / z[i2]
        da = a0 * za + a1 * zb + a2 * zc
        db = b0 * za + b1 * zb + b2 * zc
        dc = c0 * za + c1 * zb + c2 * zc
        fa0, fb0, fc0 = np.float32(a0), np.float32(b0), np.float32(c0)
        fa1, fb1, fc1 = np.float32(a1), np.float32(b1), np.float32(c1)
        fa2, fb2, fc2 = np.float32(a2), np.float32(b2), np.float32(c2)
        col0, row0 = int(x0), int(y0)
        # the reference tests a square of the bucket's side: one pixel past the box can
        # hold a centre within the edge margin
        n = _bucket_side(max(int(x1 - x0), int(y1 - y0)) + 1)
        cols = min(n, int(x1 - x0) + 2, w - col0)
        rows = min(n, int(y1 - y0) + 2, h - row0)
        tid = id_offset + f
        for dy in range(rows):
            fy = np.float32(dy)
            e0y, e1y, e2y = fb0 * fy + fc0, fb1 * fy + fc1, fb2 * fy + fc2
            for dx in range(cols):
                fx = np.float32(dx)
                if not (e0y + fa0 * fx >= -EDGE_EPS and e1y + fa1 * fx >= -EDGE_EPS
                        and e2y + fa2 * fx >= -EDGE_EPS):
                    continue
                inv_depth = da * dx + db * dy + dc
                if not inv_depth > 0:
                    continue
                d = np.float32(1.0 / inv_depth)
                r, c = row0 + dy, col0 + dx
                cur = depth[r, c]
                if d < cur or (d == cur and tid < ids[r, c]):
                    depth[r, c] = d
                    ids[r, c] = tid


@numba.njit(**_JIT)
def vertex_colours(verts, faces, base, light, view, half, out):
    """Colours ``out [V, 3]`` float32 of the vertices ``verts [V, 3]`` float32 of a mesh:
    unit area-weighted normals (the face normals summed face by face, as
    ``export._common.vertex_normals``) lit by the weights ``_LIT`` (a hemisphere ambient, a
    key light ``light``, a rim toward ``view``, a specular at ``half``) on ``base [3]``."""
    nv = verts.shape[0]
    acc = np.zeros((nv, 3), np.float32)
    for f in range(faces.shape[0]):
        a, b, c = faces[f, 0], faces[f, 1], faces[f, 2]
        e10, e11, e12 = verts[b, 0] - verts[a, 0], verts[b, 1] - verts[a, 1], verts[b, 2] - verts[a, 2]
        e20, e21, e22 = verts[c, 0] - verts[a, 0], verts[c, 1] - verts[a, 1], verts[c, 2] - verts[a, 2]
        n0 = e11 * e22 - e12 * e21
        n1 = e12 * e20 - e10 * e22
        n2 = e10 * e21 - e11 * e20
        for v in (a, b, c):
            acc[v, 0] += n0
            acc[v, 1] += n1
            acc[v, 2] += n2
    lx, ly, lz = np.float32(light[0]), np.float32(light[1]), np.float32(light[2])
    vx, vy, vz = np.float32(view[0]), np.float32(view[1]), np.float32(view[2])
    hx, hy, hz = np.float32(half[0]), np.float32(half[1]), np.float32(half[2])
    for v in range(nv):
        n0, n1, n2 = acc[v, 0], acc[v, 1], acc[v, 2]
        norm = np.float32(math.sqrt(n0 * n0 + n1 * n1 + n2 * n2))
        if norm > 0:
            n0, n1, n2 = n0 / norm, n1 / norm, n2 / norm
        key = max(n0 * lx + n1 * ly + n2 * lz, _F0)
        rim = (_F1 - min(max(n0 * vx + n1 * vy + n2 * vz, _F0), _F1)) ** 3
        spec = max(n0 * hx + n1 * hy + n2 * hz, _F0) ** 40
        hemi = _HALF + _HALF * n2
        lit = np.float64(_LIT[0] + _LIT[1] * hemi + _LIT[2] * key)
        extra = np.float64(_LIT[3] * rim + _LIT[4] * spec)
        for k in range(3):
            out[v, k] = np.float32(min(max(base[k] * lit + extra, 0.0), 1.0))


@numba.njit(**_JIT)
def compose(ids, x, y, z, faces, num_faces, num_verts, colours, room, s, out):
    """The pixels ``out [h, w, 3]`` float32 of a region: each the mean of its ``s × s``
    samples of ``ids [s·h, s·w]``, a sample of a body triangle (id < K·``num_faces``: sample
    ``id // num_faces``, whose vertices start at ``k · num_verts`` in ``x, y, z`` and
    ``colours``) taking the vertex colours interpolated at its centre (perspective-correct
    barycentrics, as ``raster.triangle_barycentrics``), any other sample the room's colour
    ``room [h, w, 3]`` of its pixel (``room`` and ``out`` may be the same array)."""
    h, w = out.shape[0], out.shape[1]
    limit = num_faces * (colours.shape[0] // num_verts)
    scale = np.float32(1.0 / (s * s))
    for r in range(h):
        for c in range(w):
            r0, g0, b0 = room[r, c, 0], room[r, c, 1], room[r, c, 2]
            acc0 = acc1 = acc2 = _F0
            for sy in range(s):
                for sx in range(s):
                    py, px = r * s + sy, c * s + sx
                    i = ids[py, px]
                    if i < limit:
                        k = i // num_faces
                        f = i - k * num_faces
                        off = k * num_verts
                        t0, t1, t2 = faces[f, 0] + off, faces[f, 1] + off, faces[f, 2] + off
                        x0, x1, x2 = x[t0], x[t1], x[t2]
                        y0, y1, y2 = y[t0], y[t1], y[t2]
                        cx, cy = px + 0.5, py + 0.5
                        area2 = (x1 - x0) * (y2 - y0) - (x2 - x0) * (y1 - y0)
                        if area2 == 0:
                            area2 = 1.0
                        w0 = ((y1 - y2) * cx + (x2 - x1) * cy + x1 * y2 - x2 * y1) / area2
                        w1 = ((y2 - y0) * cx + (x0 - x2) * cy + x2 * y0 - x0 * y2) / area2
                        w2 = ((y0 - y1) * cx + (x1 - x0) * cy + x0 * y1 - x1 * y0) / area2
                        w0 = max(w0, 0.0) / z[t0]
                        w1 = max(w1, 0.0) / z[t1]
                        w2 = max(w2, 0.0) / z[t2]
                        total = w0 + w1 + w2
                        if not total > 0:
                            total = 1.0
                        q0, q1, q2 = (np.float32(w0 / total), np.float32(w1 / total),
                                      np.float32(w2 / total))
                        v0 = q0 * colours[t0, 0] + q1 * colours[t1, 0] + q2 * colours[t2, 0]
                        v1 = q0 * colours[t0, 1] + q1 * colours[t1, 1] + q2 * colours[t2, 1]
                        v2 = q0 * colours[t0, 2] + q1 * colours[t1, 2] + q2 * colours[t2, 2]
                    else:
                        v0, v1, v2 = r0, g0, b0
                    if sy == 0 and sx == 0:
                        acc0, acc1, acc2 = v0, v1, v2
                    else:
                        acc0 += v0
                        acc1 += v1
                        acc2 += v2
            out[r, c, 0] = acc0 * scale
            out[r, c, 1] = acc1 * scale
            out[r, c, 2] = acc2 * scale


@numba.njit(**_JIT)
def shadow_pixels(rgb, depth, eye, rot, focal, cx, cy, box, lo, hi, top, origin, cell,
                  low, cover, drop):
    """Darken the pixels of ``rgb [H, W, 3]`` float32 in place where the room shows a world
    point (from ``depth [H, W]`` float32 and the camera: ``eye [3]``, ``rot [3, 3]`` float32,
    ``focal``, ``(cx, cy)``) within the pixel box ``box = (x0, y0, x1, y1)``, inside
    ``lo ≤ (x, y) < hi`` and ``z ≤ top``, and on a ``ShadowMap``'s grid (``origin``,
    ``cell``, maps ``low``, ``cover``, ``drop`` sampled bilinearly between cell centres): by
    ``(1 − 0.55 · contact) · (1 − 0.28 · drop)``, the drop only on receivers within
    ``_NEAR_FLOOR`` of the floor (``ShadowMap.darken``)."""
    gx, gy = low.shape
    o0, o1 = np.float32(origin[0]), np.float32(origin[1])
    fcell = np.float32(cell)
    quarter = np.float32(0.25)
    for r in range(box[1], box[3]):
        v = np.float32((r + 0.5 - cy) / focal)
        for c in range(box[0], box[2]):
            d = depth[r, c]
            if not np.isfinite(d):
                continue
            u = np.float32((c + 0.5 - cx) / focal)
            px = eye[0] + d * (u * rot[0, 0] + v * rot[1, 0] + rot[2, 0])
            py = eye[1] + d * (u * rot[0, 1] + v * rot[1, 1] + rot[2, 1])
            pz = eye[2] + d * (u * rot[0, 2] + v * rot[1, 2] + rot[2, 2])
            if not (px >= lo[0] and px < hi[0] and py >= lo[1] and py < hi[1] and pz <= top):
                continue
            g0 = (px - o0) / fcell - _HALF
            g1 = (py - o1) / fcell - _HALF
            if not (g0 >= 0 and g0 < gx - 1 and g1 >= 0 and g1 < gy - 1):
                continue
            i, j = int(g0), int(g1)
            fx, fy = np.float64(g0) - i, np.float64(g1) - j
            w00, w10 = (1 - fx) * (1 - fy), fx * (1 - fy)
            w01, w11 = (1 - fx) * fy, fx * fy
            s_low = w00 * low[i, j] + w10 * low[i + 1, j] + w01 * low[i, j + 1] \
                + w11 * low[i + 1, j + 1]
            s_cover = w00 * cover[i, j] + w10 * cover[i + 1, j] + w01 * cover[i, j + 1] \
                + w11 * cover[i + 1, j + 1]
            s_drop = w00 * drop[i, j] + w10 * drop[i + 1, j] + w01 * drop[i, j + 1] \
                + w11 * drop[i + 1, j + 1]
            gap = s_low - pz
            contact = s_cover * math.exp(-max(gap, 0.0) / quarter) if gap > -0.05 else 0.0
            shade = s_drop if abs(pz) < _NEAR_FLOOR else 0.0
            factor = np.float32((1.0 - 0.55 * contact) * (1.0 - 0.28 * shade))
            rgb[r, c, 0] *= factor
            rgb[r, c, 1] *= factor
            rgb[r, c, 2] *= factor


@numba.njit(**_JIT)
def raster_surfels(centre, normal, radius, focal, cx, cy, depth, ids, near=1e-2,
                   max_pixels=32):
    """Depth-test round surface elements into ``depth [H, W]`` float32 and ``ids [H, W]``
    int64 in place (id: the element's index; a smaller depth wins, an equal one the smaller
    id): discs of ``radius [N]`` around ``centre [N, 3]`` with normals ``normal [N, 3]`` (a
    zero row: facing the camera), in camera coordinates, under a pinhole of ``focal`` pixels
    and principal point ``(cx, cy)``. Each disc is the ellipse and the depth plane of
    ``raster.raster_surfels`` (its projection linearised at the centre, widened by a quarter
    pixel², searched within ``max_pixels`` of the centre); the 2 × 2 solve for the depth
    gradient is written out (LU with partial pivoting), so depths may differ from NumPy's
    LAPACK solve in the last bits."""
    h_img, w_img = depth.shape
    for i in range(centre.shape[0]):
        n0, n1, n2 = normal[i, 0], normal[i, 1], normal[i, 2]
        if not abs(n0) + abs(n1) + abs(n2) > 0:
            n0, n1, n2 = 0.0, 0.0, 1.0
        c0, c1, z = centre[i, 0], centre[i, 1], centre[i, 2]
        if not z > near:
            continue
        zs = max(z, near)
        x = cx + focal * c0 / zs
        y = cy + focal * c1 / zs
        # a tangent basis (t1, t2) of the disc's plane: t1 = n × helper, t2 = n × t1
        if abs(n0) < 0.9:
            e0, e1, e2 = 1.0, 0.0, 0.0
        else:
            e0, e1, e2 = 0.0, 1.0, 0.0
        a0, a1, a2 = n1 * e2 - n2 * e1, n2 * e0 - n0 * e2, n0 * e1 - n1 * e0
        norm = math.sqrt(a0 * a0 + a1 * a1 + a2 * a2)
        a0, a1, a2 = a0 / norm, a1 / norm, a2 / norm
        b0, b1, b2 = n1 * a2 - n2 * a1, n2 * a0 - n0 * a2, n0 * a1 - n1 * a0
        fz = focal / zs
        px_x, px_y = c0 / zs, c1 / zs
        j00, j01 = fz * (a0 - px_x * a2), fz * (b0 - px_x * b2)
        j10, j11 = fz * (a1 - px_y * a2), fz * (b1 - px_y * b2)
        r2 = radius[i] * radius[i]
        sxx = r2 * (j00 * j00 + j01 * j01) + 0.25
        syy = r2 * (j10 * j10 + j11 * j11) + 0.25
        sxy = r2 * (j00 * j10 + j01 * j11)
        det = sxx * syy - sxy * sxy
        qa, qb, qc = syy / det, -sxy / det, sxx / det
        # depth gradient on the picture: solve (J Jᵀ + ¼ I) / r² · g = J tz
        rr = max(r2, 1e-12)
        m00, m01, m10, m11 = sxx / rr, sxy / rr, sxy / rr, syy / rr
        g0, g1 = a2 * j00 + b2 * j01, a2 * j10 + b2 * j11
        if abs(m10) > abs(m00):
            m00, m01, m10, m11 = m10, m11, m00, m01
            g0, g1 = g1, g0
        low = m10 * (1.0 / m00)
        u11 = m11 - low * m01
        g1 = (g1 - low * g0) / u11
        g0 = (g0 - m01 * g1) / m00
        hx = min(math.ceil(math.sqrt(sxx)), max_pixels)
        hy = min(math.ceil(math.sqrt(syy)), max_pixels)
        if not (x + hx > 0 and x - hx < w_img and y + hy > 0 and y - hy < h_img):
            continue
        half = int(max(hx, hy))
        fa, fb2, fc = np.float32(qa), np.float32(2 * np.float32(qb)), np.float32(qc)
        col0, row0 = math.floor(x), math.floor(y)
        for rdy in range(-half, half + 1):
            row = row0 + rdy
            if row < 0 or row >= h_img:
                continue
            dy = np.float32(row + 0.5 - y)
            for rdx in range(-half, half + 1):
                col = col0 + rdx
                if col < 0 or col >= w_img:
                    continue
                dx = np.float32(col + 0.5 - x)
                if not fa * (dx * dx) + fb2 * (dy * dx) + fc * (dy * dy) <= _F1:
                    continue
                d64 = z + g0 * dx + g1 * dy
                if not d64 > near:
                    continue
                d = np.float32(d64)
                cur = depth[row, col]
                if d < cur or (d == cur and i < ids[row, col]):
                    depth[row, col] = d
                    ids[row, col] = i


def kth_distances(points, queries, rank, cap):
    """``[Q]`` float64: the distance from each of ``queries [Q]`` (indices into ``points
    [N, 3]`` float64) to its ``rank``-th nearest point, the point itself counting as the 0th
    (``cKDTree(points).query(points[queries], k=rank + 1)[0][:, rank]``); a distance of
    ``cap`` or more may come back as ``cap`` (the search stops there). Points are binned in a
    grid of cubes, searched shell by shell around each query's cube until no point outside
    can be nearer than the ``rank``-th found."""
    points = np.ascontiguousarray(points, np.float64)
    queries = np.ascontiguousarray(queries, np.int64)
    out = np.empty(len(queries), np.float64)
    if len(queries) == 0:
        return out
    lo = points.min(0)
    side = float(cap) / 2
    span = points.max(0) - lo
    while True:  # a coarser grid for a big space than one cell per point or so
        dims = (span // side).astype(np.int64) + 1
        if int(np.prod(dims)) <= max(8 * len(points), 1 << 16):
            break
        side *= 1.5
    cell = ((points - lo) // side).astype(np.int64)
    key = (cell[:, 0] * dims[1] + cell[:, 1]) * dims[2] + cell[:, 2]
    order = np.argsort(key, kind="stable")
    start = np.zeros(int(np.prod(dims)) + 1, np.int64)
    np.cumsum(np.bincount(key, minlength=len(start) - 1), out=start[1:])
    _kth_distances(points, order, start, lo, side, dims, queries, int(rank), float(cap), out)
    return out


@numba.njit(**_JIT)
def _kth_distances(points, order, start, lo, side, dims, queries, rank, cap, out):
    """:func:`kth_distances`' search (``order``: point indices sorted by cube; ``start``: each
    cube's first place in it)."""
    best = np.empty(rank + 1, np.float64)
    for q in range(queries.shape[0]):
        p = queries[q]
        px, py, pz = points[p, 0], points[p, 1], points[p, 2]
        ci = int((px - lo[0]) // side)
        cj = int((py - lo[1]) // side)
        ck = int((pz - lo[2]) // side)
        best[:] = np.inf
        r = 0
        while True:
            for i in range(max(ci - r, 0), min(ci + r, dims[0] - 1) + 1):
                for j in range(max(cj - r, 0), min(cj + r, dims[1] - 1) + 1):
                    for k in range(max(ck - r, 0), min(ck + r, dims[2] - 1) + 1):
                        if max(abs(i - ci), abs(j - cj), abs(k - ck)) != r:
                            continue  # searched in an earlier shell
                        c = (i * dims[1] + j) * dims[2] + k
                        for m in range(start[c], start[c + 1]):
                            o = order[m]
                            dx = points[o, 0] - px
                            dy = points[o, 1] - py
                            dz = points[o, 2] - pz
                            d2 = dx * dx + dy * dy + dz * dz
                            if d2 < best[rank]:
                                n = rank
                                while n > 0 and best[n - 1] > d2:
                                    best[n] = best[n - 1]
                                    n -= 1
                                best[n] = d2
            reach = r * side  # no point outside the shells searched is nearer than this
            if best[rank] <= reach * reach:
                out[q] = math.sqrt(best[rank])
                break
            if reach >= cap:
                out[q] = min(math.sqrt(best[rank]), cap)
                break
            r += 1


@numba.njit(**_JIT)
def to_uint8(rgb, out):
    """``out [H, W, 3]`` uint8 = ``rgb [H, W, 3]`` float32 · 255, rounded, clipped."""
    h, w = rgb.shape[0], rgb.shape[1]
    for r in range(h):
        for c in range(w):
            for k in range(3):
                v = rgb[r, c, k] * _F255 + _HALF
                out[r, c, k] = np.uint8(min(max(v, _F0), _F255))


_warm = threading.Lock()
_warmed = False


def warm_up() -> None:
    """Load (or, the first time on a machine, compile) every kernel for the argument types
    the renderer passes, once per process; :func:`jaxmotion.render.prepare_in_background`
    calls it from a thread so that it is done before the first frame needs it."""
    global _warmed
    with _warm:
        if _warmed:
            return
        f32 = np.float32
        verts = np.array([[0, 0, 2], [1, 0, 2], [0, 1, 2]], f32)
        faces = np.array([[0, 2, 1]], np.int64)
        eye, rot = np.zeros(3), np.eye(3)
        x, y, z = np.empty(3), np.empty(3), np.empty(3)
        one = np.zeros((1, 1), np.int64)
        skin(verts, np.zeros((2, 4, 12), f32)[0, 1:], one.repeat(3, 0), np.ones((3, 1), f32),
             np.ones(3, np.int64), np.empty((2, 3, 3), f32)[1])
        project(verts, eye, rot, 4.0, 2.0, 2.0, 0.0, 0.0, x, y, z)
        depth = np.full((4, 4), np.inf, f32)
        ids = np.full((4, 4), -1, np.int64)
        raster_surfels(verts.astype(np.float64), np.zeros((3, 3)), np.full(3, 0.1), 4.0, 2.0,
                       2.0, depth, ids)
        raster_triangles(x, y, z, faces, 0, 0, depth, ids)
        colours = np.empty((3, 3), f32)
        light = np.array([0.0, 0.0, 1.0])
        vertex_colours(verts, faces, light, light, light, light, colours)
        rgb = np.zeros((4, 4, 3), f32)
        region = rgb[1:3, 1:3]  # a view into the picture, as the frames pass it
        compose(ids, x, y, z, faces, 1, 3, colours, region, 2, region)
        grid = np.zeros((3, 3), f32)
        shadow_pixels(rgb, depth, eye.astype(f32), rot.astype(f32), 4.0, 1.0, 1.0,
                      np.array([0, 0, 2, 2], np.int64), np.zeros(2), np.ones(2), f32(1.0),
                      np.zeros(2), 0.02, grid, grid, grid)
        to_uint8(rgb, np.empty((4, 4, 3), np.uint8))
        kth_distances(np.eye(3), np.arange(3), 2, 0.1)
        _warmed = True
