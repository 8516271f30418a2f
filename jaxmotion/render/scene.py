"""The room layer: scene points as lit disc splats, a floor plane, eye-dome lighting, shadows.

:class:`SceneLayer` prepares a room once per clip (host NumPy):

- **splat sizes**: each point's disc radius is its distance to its 6th-nearest neighbour
  (clipped to [4 mm, 10 cm]), so a surface sampled at any density reads as closed; found for
  the points a camera draws only (:meth:`SceneLayer.radii`);
- **normals**: the scene's own where it has them, else the smallest principal axis of the 12
  nearest neighbours (sign unknown: the points are lit two-sided; upright surfaces near the
  sides of the points' box, a scan's walls, are turned to face the room);
- **colours**: ``rgb · (ambient + key · |n · l|)`` with the light fixed for the clip, the
  target object's points tinted with :data:`HIGHLIGHT`.

For a camera, :meth:`SceneLayer.background` draws the picture without the bodies: the points
near the motion (a *cutaway*: points above the motion + 0.5 m and points between the eye and
the motion above 12 cm are left out, so neither ceiling nor near walls and furniture hide the
body), an infinite floor plane at z = 0 behind them (the scene's own floor points win), and
eye-dome lighting (EDL, a darkening where the depth steps away from the eye: the outlines
that make chairs readable against the floor in a point cloud). Its depth gives the shadows
the world point of every pixel that can receive one.

:class:`ShadowMap` darkens those pixels under the bodies of a frame: a grid of 2 cm cells
records how much body lies above each cell and its lowest point; a receiver at height ``z``
under body whose lowest point is ``g`` above it darkens by ``cover · exp(−g / 0.25 m)`` (a
contact shadow: strong under a seated pelvis or on the floor at the feet, faint under a body
standing tall), plus a wide soft drop shadow on the floor.
"""

from __future__ import annotations

import functools

import numpy as np

from jaxmotion.render import kernels
from jaxmotion.render.camera import Camera

__all__ = ["FLOOR_RGB", "HIGHLIGHT", "BackgroundPicture", "CutawayHoles", "SceneLayer",
           "ShadowMap", "gaussian_filter", "light_direction", "minimum_filter"]

HIGHLIGHT = np.array([1.0, 0.62, 0.05])  # the target object's tint (amber)
FLOOR_RGB = np.array([0.86, 0.855, 0.84])
SKY = np.array([1.0, 1.0, 1.0])  # the picture where nothing is drawn
_FLOOR_ID = 0xFFFF_FFFE  # primitive id of the floor plane in the scene's z-buffer
_CUT_ABOVE = 0.5  # metres above the motion's top joint
_CUT_NEAR_Z = 0.12  # points lower than this are never cut away (the floor)
_EDL_STRENGTH = 350.0
_EDL_MAX = 0.6  # the darkest outline keeps 40 % of the colour
_FLOOR_FADE = (4.0, 7.0)  # metres from the target: the floor fades to white between these
_CUT_SHARE = 0.05  # an object with more of its points in front of the body is left out whole
_SPLAT_MIN, _SPLAT_MAX = 0.004, 0.10  # metres: the splat radii's bounds
_BODY_RADIUS = 0.22  # metres around joints and bone midpoints: the body for the cutaway


def light_direction(cam: Camera) -> np.ndarray:
    """The key light's unit direction (toward the light): high, over the camera's left
    shoulder, so shadows fall behind and to the right of a body."""
    right, _, forward = cam.rot
    d = -0.45 * right - 0.55 * forward + np.array([0.0, 0.0, 1.3])
    return d / np.linalg.norm(d)


class BackgroundPicture:
    """The room drawn from one camera ``cam``: ``rgb [H, W, 3]`` float32 in [0, 1] and
    ``depth [H, W]`` float32 (inf where nothing is drawn)."""

    __slots__ = ("cam", "depth", "rgb")

    def __init__(self, cam: Camera, rgb, depth):
        self.cam, self.rgb, self.depth = cam, rgb, depth

    def crop(self, cam: Camera) -> BackgroundPicture:
        """The picture seen by ``cam``: this camera's eye and direction, another focal length
        and principal point (an off-axis crop, resampled: colours bilinearly, depth from the
        nearest pixel)."""
        from PIL import Image

        src = self.cam
        k = src.focal / cam.focal
        # frame pixel centre i + 0.5 ↦ source coordinate cx_s + k (i + 0.5 − cx)
        x0, y0 = src.cx - k * cam.cx, src.cy - k * cam.cy
        x1, y1 = src.cx + k * (cam.width - cam.cx), src.cy + k * (cam.height - cam.cy)
        # a crop reaching a hair past the picture (rounding) is nudged back inside
        dx = max(0.0, -x0) - max(0.0, x1 - src.width)
        dy = max(0.0, -y0) - max(0.0, y1 - src.height)
        box = (max(0.0, x0 + dx), max(0.0, y0 + dy), min(float(src.width), x1 + dx),
               min(float(src.height), y1 + dy))
        img = Image.fromarray(np.clip(self.rgb * 255 + 0.5, 0, 255).astype(np.uint8))
        rgb = np.asarray(img.resize((cam.width, cam.height), Image.BILINEAR, box=box),
                         np.float32) / 255.0
        ix = np.floor(src.cx + k * (np.arange(cam.width) + 0.5 - cam.cx)).astype(np.int64)
        iy = np.floor(src.cy + k * (np.arange(cam.height) + 0.5 - cam.cy)).astype(np.int64)
        ix, iy = np.clip(ix, 0, src.width - 1), np.clip(iy, 0, src.height - 1)
        return BackgroundPicture(cam, rgb, self.depth[np.ix_(iy, ix)])


class SceneLayer:
    """A room prepared for drawing (see the module docstring).

    Args:
      xyz: ``[N, 3]`` points, z-up, metres; rgb: ``[N, 3]`` in [0, 1].
      normal: ``[N, 3]`` unit normals, zero rows unknown (None: all unknown).
      highlight: ``[N]`` bool, the target object's points (tinted), or None.
      instance: ``[N]`` object ids (−1: none), or None: an object that would hide the body
        is left out whole.
      light: the key light's direction (see :func:`light_direction`).
      floor: draw the floor plane at z = 0.
    """

    def __init__(self, xyz, rgb, normal=None, highlight=None, instance=None, *, light,
                 floor: bool = True):
        self.xyz = np.asarray(xyz, np.float64)
        self.instance = None if instance is None else np.asarray(instance, np.int64)
        n = len(self.xyz)
        rgb = np.asarray(rgb, np.float64)
        self.floor = floor
        # splat radii: 2 cm for a handful of points, else found when first drawn (radii)
        self._radius = np.full(n, 0.02 if n < 8 else np.nan)
        normal = np.zeros((n, 3)) if normal is None else np.asarray(normal, np.float64)
        self.oriented = np.abs(normal).sum(1) > 0  # the scene's own normals: facing known
        unknown = np.abs(normal).sum(1) == 0
        if n >= 8 and unknown.any():  # a scan without normals
            from scipy.spatial import cKDTree

            d, nb = cKDTree(self.xyz).query(self.xyz, k=13)
            self._radius = np.clip(d[:, 6], _SPLAT_MIN, _SPLAT_MAX)
            normal = normal.copy()
            normal[unknown] = _pca_normals(self.xyz, nb[unknown])
            walls = _wall_points(self.xyz, normal) & unknown
            centre = (self.xyz.min(0) + self.xyz.max(0)) / 2
            inward = ((centre - self.xyz[walls])[:, :2] * normal[walls, :2]).sum(1)
            normal[walls] *= np.where(inward < 0, -1.0, 1.0)[:, None]
            self.oriented |= walls
        self.normal = normal
        lit = np.abs(normal @ light)
        shade = np.where(np.abs(normal).sum(1) > 0, 0.62 + 0.45 * lit, 0.9)
        self.highlight = np.zeros(n, bool) if highlight is None else np.asarray(highlight, bool)
        if self.highlight.any():
            h = self.highlight
            rgb = rgb.copy()
            rgb[h] = 0.3 * rgb[h] + 0.7 * HIGHLIGHT
        self.colour = np.clip(rgb * shade[:, None], 0.0, 1.0).astype(np.float32)

    def radii(self, sel: np.ndarray) -> np.ndarray:
        """The splat radii ``[len(sel)]`` of the points ``sel``: each one's distance to its
        6th-nearest neighbour, clipped to [4 mm, 10 cm]; found for the points drawn only,
        once (a camera sees about half of a room's points)."""
        r = self._radius[sel]
        todo = np.isnan(r)
        if todo.any():
            d = kernels.kth_distances(self.xyz, sel[todo], 6, _SPLAT_MAX)
            r[todo] = np.clip(d, _SPLAT_MIN, _SPLAT_MAX)
            self._radius[sel[todo]] = r[todo]
        return r

    def visible(self, cam: Camera, target: np.ndarray, reach: float, top: float,
                holes: CutawayHoles | None = None) -> np.ndarray:
        """Indices of the points drawn for ``cam`` looking at ``target``: the points facing the
        camera (those whose own normal faces away are the far side of a surface: the outside
        of the near walls), below ``top`` + 0.5 m; of the points of no object (walls, an
        unlabelled scan) not those nearer to the eye than ``reach`` (horizontally from the
        target, toward the eye) unless on the floor; and not those in front of the body
        (``holes``; objects with more than 5 % of their points there, whole) unless on the floor or
        highlighted."""
        p = self.xyz
        back = -cam.rot[2]
        back_h = back[:2] / max(np.linalg.norm(back[:2]), 1e-9)
        toward_eye = (p[:, :2] - target[:2]) @ back_h
        low = p[:, 2] < _CUT_NEAR_Z
        unlabelled = np.ones(len(p), bool) if self.instance is None else self.instance < 0
        keep = p[:, 2] < top + _CUT_ABOVE
        keep &= low | (toward_eye < reach) | ~unlabelled
        facing = ((cam.eye - p) * self.normal).sum(1) > 0
        keep &= facing | ~self.oriented
        sel = np.flatnonzero(keep)
        if holes is not None:
            cut = holes.in_front(cam, p[sel]) & ~low[sel] & ~self.highlight[sel]
            if self.instance is not None:  # an object mostly in front goes whole
                inst = self.instance[sel]
                objects = inst >= 0
                if objects.any():
                    _ids, where = np.unique(inst[objects], return_inverse=True)
                    share = np.bincount(where, cut[objects]) / np.bincount(where)
                    whole = np.zeros(len(sel), bool)
                    whole[objects] = share[where] > _CUT_SHARE
                    cut |= whole & ~self.highlight[sel]
            sel = sel[~cut]
        return sel

    def background(self, cam: Camera, target: np.ndarray, reach: float, top: float,
                   supersample: int = 1, holes: CutawayHoles | None = None
                   ) -> BackgroundPicture:
        """The room from ``cam`` (see the module docstring), drawn at ``supersample`` times the
        camera's size and reduced to it (colours averaged, the nearest depth kept)."""
        big = cam.scaled(supersample) if supersample > 1 else cam
        w, h = big.width, big.height
        sel = self.visible(cam, target, reach, top, holes)
        depth = np.full(w * h, np.inf, np.float32)
        ids = np.full(w * h, -1, np.int64)
        if self.floor:
            floor_depth = _floor_depth(big)
            ok = np.flatnonzero(np.isfinite(floor_depth))
            # the plane lies 1 cm deeper than it is, so the scene's own floor points win
            depth[ok] = floor_depth[ok] + np.float32(0.01)
            ids[ok] = _FLOOR_ID
        kernels.raster_surfels(big.view(self.xyz[sel]), self.normal[sel] @ big.rot.T,
                               self.radii(sel), float(big.focal), float(big.cx),
                               float(big.cy), depth.reshape(h, w), ids.reshape(h, w))
        point = np.flatnonzero((ids >= 0) & (ids < len(sel)))
        rgb = np.empty((w * h, 3), np.float32)
        rgb[:] = SKY
        rgb[point] = self.colour[sel[ids[point]]]
        if self.floor:
            on = np.flatnonzero(ids == _FLOOR_ID)
            depth[on] -= np.float32(0.01)
            rgb[on] = _floor_colour(_floor_points(big, on, depth[on]), target)
        rgb = rgb.reshape(h, w, 3)
        depth = depth.reshape(h, w)
        rgb *= _eye_dome(depth)[..., None]
        if supersample > 1:
            s = supersample
            rgb = rgb.reshape(cam.height, s, cam.width, s, 3).mean((1, 3))
            depth = depth.reshape(cam.height, s, cam.width, s).min((1, 3))
        return BackgroundPicture(cam, np.ascontiguousarray(rgb, np.float32),
                                 np.ascontiguousarray(depth, np.float32))


def _wall_points(xyz: np.ndarray, normal: np.ndarray, reach: float = 0.25) -> np.ndarray:
    """``[N]`` bool: upright surfaces within ``reach`` of a side of the points' box in xy (a
    scan's walls; their normals are then turned to face the room, so that from outside the
    near walls are seen from behind and left out)."""
    lo, hi = xyz[:, :2].min(0), xyz[:, :2].max(0)
    side = np.minimum(xyz[:, :2] - lo, hi - xyz[:, :2]).min(1)
    return (np.abs(normal[:, 2]) < 0.35) & (side < reach)


def _pca_normals(xyz: np.ndarray, neighbours: np.ndarray) -> np.ndarray:
    """Unit normals from the neighbours' covariance (smallest eigenvector), sign arbitrary."""
    q = xyz[neighbours]
    q = q - q.mean(1, keepdims=True)
    cov = np.einsum("nki,nkj->nij", q, q)
    _, vec = np.linalg.eigh(cov)
    return vec[:, :, 0]


def _floor_depth(cam: Camera) -> np.ndarray:
    """Depth ``[H*W]`` float32 of the plane z = 0 along each pixel's ray; inf where the ray
    misses it (at or above the horizon) or meets it over 40 m away."""
    # ray (u, v, 1) in camera coordinates has world z component u r0z + v r1z + r2z, and
    # meets z = 0 at depth t = −eye_z / that
    u = ((np.arange(cam.width) + 0.5 - cam.cx) / cam.focal).astype(np.float32)
    v = ((np.arange(cam.height) + 0.5 - cam.cy) / cam.focal).astype(np.float32)
    r = cam.rot.astype(np.float32)
    dz = v[:, None] * r[1, 2] + u[None, :] * r[0, 2] + r[2, 2]
    with np.errstate(divide="ignore"):
        t = np.float32(-cam.eye[2]) / dz
    t[(dz > -1e-6) | (t > 40.0)] = np.inf
    return t.reshape(-1)


def _floor_points(cam: Camera, pix: np.ndarray, depth: np.ndarray) -> np.ndarray:
    """World points ``[M, 3]`` float32 at depth ``depth [M]`` through flat pixels ``pix``."""
    u = (pix % cam.width + 0.5 - cam.cx) / cam.focal
    v = (pix // cam.width + 0.5 - cam.cy) / cam.focal
    ray = u[:, None] * cam.rot[0] + v[:, None] * cam.rot[1] + cam.rot[2]
    return (cam.eye + depth[:, None] * ray).astype(np.float32)


def _floor_colour(hit: np.ndarray, target: np.ndarray) -> np.ndarray:
    """The floor plane's colour at world points ``hit [M, 3]``: light grey in 0.5 m tiles of
    slightly different shade, fading to white away from ``target``."""
    tile = (np.floor(hit[:, 0] / 0.5) + np.floor(hit[:, 1] / 0.5)) % 2
    c = FLOOR_RGB[None, :] * (1.0 - 0.035 * tile)[:, None]
    r = np.linalg.norm(hit[:, :2] - target[:2], axis=1)
    fade = np.clip((r - _FLOOR_FADE[0]) / (_FLOOR_FADE[1] - _FLOOR_FADE[0]), 0.0, 1.0)
    return (c * (1 - fade)[:, None] + SKY * fade[:, None]).astype(np.float32)


def _eye_dome(depth: np.ndarray) -> np.ndarray:
    """Eye-dome lighting factor ``[H, W]`` in (0, 1]: dark where neighbours 2 pixels away are
    nearer in log-depth (outlines of objects against what lies behind them)."""
    finite = np.isfinite(depth)
    logd = np.log(np.where(finite, np.maximum(depth, 1e-3), 1e3)).astype(np.float32)
    pad = np.pad(logd, 2, mode="edge")
    h, w = depth.shape
    resp = np.zeros_like(logd)
    for dy, dx in ((-2, 0), (2, 0), (0, -2), (0, 2)):
        nb = pad[2 + dy: 2 + dy + h, 2 + dx: 2 + dx + w]
        resp += np.maximum(0.0, logd - nb)
    # ignore the gentle slope of a plane seen at a grazing angle; outline real steps
    resp = np.maximum(resp - 0.02, 0.0)
    dark = 1.0 - np.exp(-_EDL_STRENGTH * resp * resp / (1 + 20 * resp))
    return np.where(finite, 1.0 - _EDL_MAX * dark, 1.0).astype(np.float32)


class CutawayHoles:
    """Where the bodies will be on the picture, and how near: scene points in front of them
    are left out (a table between the camera and the person does not hide the person).

    ``joints [M, 22, 3]`` (the poses of the frames a camera shows) are widened into spheres of
    :data:`_BODY_RADIUS` around the joints and the bones' midpoints; a coarse grid of
    ``cell``-pixel squares keeps the nearest sphere surface's depth. A point is *in front*
    when its square holds body at least 5 cm deeper than the point.
    """

    def __init__(self, cam: Camera, joints: np.ndarray, cell: int = 8):
        from jaxmotion.geometry.skeleton import PARENTS

        j = np.asarray(joints, np.float64).reshape(-1, 22, 3)
        mids = 0.5 * (j[:, 1:] + j[:, list(PARENTS[1:])])
        pts = np.concatenate([j, mids], 1).reshape(-1, 3)
        xy, z = cam.project(pts)
        ok = z > 0.05
        xy, z = xy[ok], z[ok]
        self.cell = cell
        gw, gh = -(-cam.width // cell), -(-cam.height // cell)
        self.shape = (gh, gw)
        grid = np.full(gh * gw, np.inf)
        r = _BODY_RADIUS * cam.focal / z / cell + 0.5  # sphere radius, cells
        h = int(np.ceil(r.max())) if len(r) else 0
        off = np.arange(-h, h + 1)
        ci = np.floor(xy[:, 0] / cell).astype(np.int64)[:, None] + off
        ri = np.floor(xy[:, 1] / cell).astype(np.int64)[:, None] + off
        inside = (off[None, :, None] ** 2 + off[None, None, :] ** 2) <= (r * r)[:, None, None]
        inside &= ((ri >= 0) & (ri < gh))[:, :, None] & ((ci >= 0) & (ci < gw))[:, None, :]
        k, a, b = np.nonzero(inside)
        np.minimum.at(grid, ri[k, a] * gw + ci[k, b], z[k] - _BODY_RADIUS)
        self.grid = grid

    def in_front(self, cam: Camera, p: np.ndarray) -> np.ndarray:
        """``[M]`` bool: points ``p [M, 3]`` that would hide the body."""
        xy, z = cam.project(p)
        gh, gw = self.shape
        ci = np.floor(xy[:, 0] / self.cell).astype(np.int64)
        ri = np.floor(xy[:, 1] / self.cell).astype(np.int64)
        on = (ci >= 0) & (ci < gw) & (ri >= 0) & (ri < gh) & (z > 0)
        out = np.zeros(len(p), bool)
        body = self.grid[ri[on] * gw + ci[on]]
        out[on] = np.isfinite(body) & (z[on] < body - 0.05)
        return out


class ShadowMap:
    """Contact and drop shadows of the bodies of one frame (see the module docstring).

    Args:
      vertices: ``[M, 3]`` body vertices (all samples; a subset is enough).
      light: the key light's direction.
      cell: grid cell side, metres.
    """

    def __init__(self, vertices: np.ndarray, light: np.ndarray, cell: float = 0.02):
        v = np.asarray(vertices, np.float32)
        self.cell = cell
        # the drop shadow: vertices slid along the light onto the floor
        drop = v[:, :2] - v[:, 2:3] * (light[:2] / max(light[2], 0.2)).astype(np.float32)
        lo = np.minimum(v[:, :2].min(0), drop.min(0)) - 0.3
        hi = np.maximum(v[:, :2].max(0), drop.max(0)) + 0.3
        self.origin = lo.astype(np.float64)
        gx, gy = (int(n) for n in np.ceil((hi - lo) / cell) + 1)
        self.shape = (gx, gy)

        def cells(xy):
            ij = ((xy - lo) / cell).astype(np.int64)
            return np.clip(ij[:, 0], 0, gx - 1) * gy + np.clip(ij[:, 1], 0, gy - 1)

        c = cells(v[:, :2])
        low = np.full(gx * gy, np.inf, np.float32)
        np.minimum.at(low, c, v[:, 2])
        occupied = np.isfinite(low).reshape(gx, gy)
        low = minimum_filter(low.reshape(gx, gy), 5)
        self.low = np.where(np.isfinite(low), low, np.float32(1e3))
        self.cover = np.minimum(gaussian_filter(occupied.astype(np.float32), 0.045 / cell)
                                * 1.6, 1.0)
        dc = np.zeros(gx * gy, np.float32)
        dc[cells(drop)] = 1.0
        self.drop = np.minimum(gaussian_filter(dc.reshape(gx, gy), 0.07 / cell) * 1.4, 1.0)
        # the box (world xy) outside which nothing darkens
        some = np.argwhere((self.cover > 0.01) | (self.drop > 0.01))
        if len(some):
            self.box = (self.origin + some.min(0) * cell, self.origin + (some.max(0) + 1) * cell)
        else:
            self.box = (self.origin, self.origin)

    def darken(self, rgb: np.ndarray, bg: BackgroundPicture, top: float) -> None:
        """Darken ``rgb [H, W, 3]`` (float32, in place: ``bg``'s picture) where ``bg`` shows a
        world point (from its depth) at most ``top`` high, inside :attr:`box` and the grid: by
        ``(1 − 0.55 · contact) · (1 − 0.28 · drop)``, the maps interpolated bilinearly between
        cell centres, the drop shadow on receivers within 5 cm of the floor. Only the pixels
        the box projects to are visited (:func:`~jaxmotion.render.kernels.shadow_pixels`)."""
        cam = bg.cam
        lo, hi = self.box
        corners = np.array([[(lo[0], hi[0])[k & 1], (lo[1], hi[1])[k >> 1 & 1],
                             (-0.1, top)[k >> 2]] for k in range(8)])
        xy, z = cam.project(corners)
        if np.all(z > 1e-3):
            x0, y0 = np.maximum(np.floor(xy.min(0)).astype(int), 0)
            x1, y1 = np.minimum(np.ceil(xy.max(0)).astype(int) + 1, [cam.width, cam.height])
        else:
            x0 = y0 = 0
            x1, y1 = cam.width, cam.height
        if x1 <= x0 or y1 <= y0:
            return
        kernels.shadow_pixels(rgb, bg.depth, cam.eye.astype(np.float32),
                              cam.rot.astype(np.float32), float(cam.focal), float(cam.cx),
                              float(cam.cy), np.array([x0, y0, x1, y1], np.int64),
                              np.asarray(lo, np.float64), np.asarray(hi, np.float64),
                              np.float32(top), self.origin, float(self.cell), self.low,
                              self.cover, self.drop)


def minimum_filter(a: np.ndarray, size: int) -> np.ndarray:
    """The minimum over the ``size × size`` window centred on each cell of ``a [H, W]``, the
    edges extended (``scipy.ndimage.minimum_filter(a, size, mode="nearest")``, odd ``size``)."""
    h, w = a.shape
    padded = np.pad(a, size // 2, mode="edge")
    rows = padded[:h].copy()
    for i in range(1, size):
        np.minimum(rows, padded[i:i + h], out=rows)
    out = rows[:, :w].copy()
    for i in range(1, size):
        np.minimum(out, rows[:, i:i + w], out=out)
    return out


def gaussian_filter(a: np.ndarray, sigma: float) -> np.ndarray:
    """``a [H, W]`` float32 blurred by a Gaussian of ``sigma`` cells, zero outside
    (``scipy.ndimage.gaussian_filter(a, sigma, mode="constant")``: the kernel truncated at
    4 σ and normalised, one axis after the other, each pass in float64 kept in float32)."""
    h, w = a.shape
    rows = (_blur_matrix(h, float(sigma)) @ a.astype(np.float64)).astype(np.float32)
    return (rows.astype(np.float64) @ _blur_matrix(w, float(sigma)).T).astype(np.float32)


@functools.lru_cache(maxsize=64)
def _blur_matrix(n: int, sigma: float) -> np.ndarray:
    """``[n, n]``: row i holds the truncated Gaussian's weights around cell i."""
    radius = int(4.0 * sigma + 0.5)
    x = np.arange(-radius, radius + 1)
    weights = np.exp(-0.5 / (sigma * sigma) * x * x)
    weights /= weights.sum()
    offset = np.arange(n)[None, :] - np.arange(n)[:, None]
    near = np.abs(offset) <= radius
    out = np.zeros((n, n))
    out[near] = weights[offset[near] + radius]
    return out
