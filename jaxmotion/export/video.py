"""Offscreen pictures of a motion in its scene: animated GIF or MP4, and a still PNG.

Given posed body meshes (``vertices`` and ``faces``), :func:`render_motion_video` hands the
clip to :mod:`jaxmotion.render`: shaded bodies in the lit room, a camera that frames or
follows the motion (``jaxmotion generate`` writes its ``motion.mp4`` that way). The rest of
this module draws the lighter picture of joints alone, described below.

Each video frame shows the scene points near the motion in their colours (or
the affordance heat layer), the body (subsampled vertices, when given without faces)
and the skeleton of every sample in its own colour (``PALETTE``,
matplotlib's "tab10"), drawn on top, with the text and the time. The camera is
fixed for the whole clip: it looks at the centre of the joints' bounding box
over all frames and samples, 30° above the horizontal (azimuth −60°), and
frames a cube 0.6 m wider than that box, with the perspective of matplotlib's
mplot3d (``view_init(30, -60)``, cubic box, a square view as wide as the longer
side of the picture: the same pixels). Only scene points within 1 m (in xy) of
that cube and below 0.5 m above the highest joint are drawn, so walls and the
ceiling do not hide the person.

Drawing (numpy and Pillow, no matplotlib): as the camera never moves, the scene
is projected once into a background picture (square dots of about 1.5 pixels,
the nearest point winning each pixel); each frame is a copy of it with the
bodies, the skeletons and the time drawn on top. Pictures are drawn at twice
the size and halved, which smooths the edges. A GIF uses one 255-colour palette
for all frames, without dithering, so the still scene is the same pixels in
every frame and each GIF frame stores only the rectangle that changed.

Speed: at most ``max_frames`` frames are drawn (the motion is subsampled by a
whole stride and the output frame rate lowered to match, so the clip keeps its
real duration; GIFs also stay at or below 50 frames per second, the fastest
browsers play). A 120-frame motion (one sample, 60 000 scene points) with the
defaults (480×360, 40 frames) takes about 0.35 s as GIF (0.2 MB) and 0.25 s as
MP4 (0.13 MB, x264 "veryfast"), at 640×480 with 60 frames about 0.5 s either way
(GIF 0.33 MB), on a CPU core shared with other work; the first call adds about
0.1 s of imports. (The earlier matplotlib drawing took 12 s and 5 s at 640×480.)
"""

from __future__ import annotations

import functools
import importlib.util
import io
import math
from pathlib import Path

import numpy as np

from jaxmotion._atomic import atomic_open
from jaxmotion.export._common import (
    INFERNO,
    PALETTE,
    affordance_channels,
    check_array,
    check_fps,
    heat_colours,
    random_subset,
    scene_points,
)
from jaxmotion.geometry.skeleton import NUM_JOINTS, PARENTS

__all__ = ["render_frame", "render_motion_video"]

_MARGIN = 1.0  # metres of scene drawn around the framed cube (xy)
_ELEV, _AZIM = 30.0, -60.0  # camera, degrees
SUPERSAMPLE = 2  # pictures are drawn at SUPERSAMPLE times their size, then reduced (antialiasing)
# Sizes in output pixels, those of the earlier matplotlib drawing at 100 dpi:
_DOT = 1.5  # scene dot side (a marker of s=1: 1 pt ≈ 1.4 px)
_BODY_DOT = 2.0  # body dot side (s=2)
_BONE = 3.0  # bone width (2.2 pt)
_CAPTION_PX, _CLOCK_PX = 12.5, 11.0  # font sizes (9 pt and 8 pt)
GIF_MAX_FPS = 50.0  # browsers slow down GIF frames shorter than 20 ms
_EMPTY = (math.inf, math.inf, -math.inf, -math.inf)  # an empty box (x0, y0, x1, y1)


def render_motion_video(
    path,
    scene_xyz,
    scene_rgb,
    joints,
    fps: float,
    *,
    vertices=None,
    faces=None,
    affordance=None,
    text: str = "",
    size: tuple[int, int] = (480, 360),
    max_points: int = 60_000,
    max_frames: int | None = 40,
    max_body_points: int = 2_000,
    seed: int = 0,
    scene_normal=None,
    highlight=None,
    instance=None,
    samples: str = "overlay",
    camera: str = "auto",
    azimuth: float | None = None,
    video_fps: float | None = None,
) -> Path:
    """Render the motion in its scene to ``.gif`` or ``.mp4`` (chosen by the suffix), atomically.

    With ``vertices`` and ``faces`` the bodies are drawn as shaded meshes in the lit room
    (:mod:`jaxmotion.render`: a camera that frames or follows the motion, shadows, the
    target highlighted); with joints alone, as skeletons over the room's points (this
    module's drawing).

    Args:
      path: output file, ``.gif`` or ``.mp4`` (MP4 needs ``imageio-ffmpeg``).
      scene_xyz: ``[N, 3]`` scene points, z-up, metres; scene_rgb: ``[N, 3]`` in [0, 1] or None.
      joints: ``[T, 22, 3]`` or ``[K, T, 22, 3]`` (K samples), same frame as the scene.
      fps: frames per second of ``joints``.
      vertices: ``[(K,) T, V, 3]`` posed body vertices (e.g. ``body_forward(...).vertices``);
        faces: ``[F, 3]`` their triangles. Without faces, at most ``max_body_points``
        vertices per body are drawn as dots.
      affordance: ``[N]`` or ``[N, C]`` affordance map in [0, 1]: the scene is drawn as a
        heat layer of its maximum over the channels.
      text: caption drawn at the top.
      size: ``(width, height)`` pixels (even numbers for MP4).
      max_points, max_frames: speed limits, see the module docstring (``max_frames`` None:
        no limit).
      seed: for the random point subsets.
      scene_normal, highlight, instance, samples, camera, azimuth, video_fps: for shaded
        bodies only: the room's normals ``[N, 3]``, the target's points ``[N]`` bool, the
        points' object ids ``[N]``, ``"overlay"`` or ``"grid"``, ``"auto"`` / ``"fixed"`` /
        ``"follow"``, the view's azimuth in degrees (None: chosen), the clip's frame rate
        (None: the motion's); see :class:`jaxmotion.render.Clip`.
    Returns:
      the path written.
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in (".gif", ".mp4"):
        raise ValueError(f"render_motion_video writes .gif or .mp4, got {path.name!r}")
    if suffix == ".mp4" and importlib.util.find_spec("imageio_ffmpeg") is None:
        raise ValueError("writing .mp4 needs imageio-ffmpeg: pip install 'imageio-ffmpeg>=0.5'")
    width, height = _check_size(size, even=suffix == ".mp4")
    if (max_frames is not None and max_frames < 1) or max_points < 0 or max_body_points < 1:
        raise ValueError("max_frames and max_body_points must be ≥ 1, max_points ≥ 0")
    fps = check_fps(fps)
    j, xyz, rgb = _motion_and_scene(scene_xyz, scene_rgb, joints, affordance)
    k, t = j.shape[:2]
    if vertices is not None and faces is not None:
        from jaxmotion.render import Bodies, Clip, render_video

        bodies = Bodies.from_vertices(vertices, faces)
        sel = random_subset(len(xyz), max_points, seed)
        pick = lambda a: None if a is None else np.asarray(a)[sel]
        clip = Clip(bodies, j, fps, xyz[sel], rgb[sel], scene_normal=pick(scene_normal),
                    highlight=pick(highlight), instance=pick(instance), text=text,
                    size=(width, height), samples=samples, camera=camera, azimuth=azimuth)
        return render_video(path, clip, video_fps=video_fps, max_frames=max_frames)
    if max_frames is None:
        max_frames = t
    body = keep = None
    if vertices is not None:  # without faces: dots
        body = np.asarray(vertices, np.float64)
        body = check_array("vertices", body[None] if body.ndim == 3 else body, (k, t, None, 3))
        keep = random_subset(body.shape[2], max_body_points, seed)

    stride = math.ceil(t / max_frames)
    if suffix == ".gif":
        stride = max(stride, math.ceil(fps / GIF_MAX_FPS - 1e-9))
    frames = np.arange(0, t, stride)
    out_fps = fps / stride

    from PIL import Image, ImageDraw

    cam = Camera(j, width, height)
    background = cam.background(xyz, rgb, max_points, seed, text)
    clock_font = caption_font(_CLOCK_PX * SUPERSAMPLE)
    images, boxes = [], []  # frames, and the box (x0, y0, x1, y1) where each differs from
    for f in frames:  # the still scene (output pixels)
        canvas = background.copy()
        box = [_EMPTY]
        if body is not None:
            pts, colours = [], []
            for s in range(k):
                pts.append(body[s, f, keep])
                base = 0.55 + 0.45 * PALETTE[s % len(PALETTE)]
                colours.append(np.broadcast_to(base, (len(keep), 3)))
            box.append(cam.dots(canvas, np.concatenate(pts), np.concatenate(colours), _BODY_DOT))
        im = Image.fromarray(canvas)
        draw = ImageDraw.Draw(im)
        for s in range(k):
            box.append(cam.skeleton(draw, j[s, f], _rgb8(PALETTE[s % len(PALETTE)]), _BONE))
        clock = ((0.98 * im.width, 0.98 * im.height), f"{f / fps:5.2f} s")
        draw.text(*clock, fill=(0, 0, 0), font=clock_font, anchor="rd")
        box.append(draw.textbbox(*clock, font=clock_font, anchor="rd"))
        images.append(np.asarray(im.reduce(SUPERSAMPLE)))
        box = np.array(box, np.float64)
        boxes.append(
            (
                max(0, math.floor(box[:, 0].min() / SUPERSAMPLE) - 1),
                max(0, math.floor(box[:, 1].min() / SUPERSAMPLE) - 1),
                min(width, math.ceil(box[:, 2].max() / SUPERSAMPLE) + 1),
                min(height, math.ceil(box[:, 3].max() / SUPERSAMPLE) + 1),
            )
        )

    if suffix == ".gif":
        exact = [(255, 255, 255), (0, 0, 0)]
        exact += [_rgb8(PALETTE[s % len(PALETTE)]) for s in range(min(k, len(PALETTE)))]
        still = np.asarray(Image.fromarray(background).reduce(SUPERSAMPLE))
        data = gif_bytes(images, boxes, still, out_fps, exact)
    else:
        import imageio.v3 as iio

        data = iio.imwrite(
            "<bytes>",
            np.stack(images),
            extension=".mp4",
            plugin="FFMPEG",
            fps=out_fps,
            codec="libx264",
            output_params=["-preset", "veryfast"],  # twice as fast as "medium", no bigger here
            macro_block_size=1,
        )
    with atomic_open(path, "wb") as fh:
        fh.write(data)
    return path


def render_frame(
    path_png,
    scene_xyz,
    scene_rgb,
    joints,
    *,
    frame: int | None = None,
    size: tuple[int, int] = (960, 540),
    affordance=None,
    text: str = "",
    ghosts: int = 6,
    max_points: int = 200_000,
    seed: int = 0,
) -> Path:
    """One still PNG of the motion in its scene (e.g. for a README), atomically.

    Same view, scene and colours as :func:`render_motion_video`, zoomed out or panned
    where needed so that every joint of every frame is inside the picture (a wide
    picture crops the view's square more). The skeleton of every sample is drawn
    bold at ``frame`` and faintly at ``ghosts`` other frames spread evenly over the
    clip, so one picture shows where the motion goes.

    Args:
      path_png: output file, ``.png``.
      scene_xyz, scene_rgb, joints, affordance, text, seed: as for ``render_motion_video``.
      frame: the bold frame, an index into T (negative counts from the end); None: the last.
      size: ``(width, height)`` pixels.
      ghosts: number of faint frames (0: none).
      max_points: at most this many scene points are drawn.
    Returns:
      the path written.
    """
    path = Path(path_png)
    if path.suffix.lower() != ".png":
        raise ValueError(f"render_frame writes .png, got {path.name!r}")
    width, height = _check_size(size)
    if max_points < 0 or ghosts < 0:
        raise ValueError("max_points and ghosts must be ≥ 0")
    j, xyz, rgb = _motion_and_scene(scene_xyz, scene_rgb, joints, affordance)
    k, t = j.shape[:2]
    if frame is None:
        frame = t - 1
    if not isinstance(frame, (int, np.integer)) or not -t <= frame < t:
        raise ValueError(f"frame must be an integer in [-{t}, {t}), got {frame!r}")
    frame = int(frame) % t
    faint = [f for f in np.linspace(0, t - 1, ghosts + 1).round().astype(int) if f != frame]
    faint = faint[:ghosts]

    from PIL import Image, ImageDraw

    cam = Camera(j, width, height)
    cam.fit(j)
    dot = _DOT * max(1.0, max(width, height) / 640)  # a big picture is seen smaller
    im = Image.fromarray(cam.background(xyz, rgb, max_points, seed, text, dot)).convert("RGBA")
    layer = Image.new("RGBA", im.size, (0, 0, 0, 0))
    draw = ImageDraw.Draw(layer)
    for f in faint:
        for s in range(k):
            cam.skeleton(draw, j[s, f], (*_rgb8(PALETTE[s % len(PALETTE)]), 255), 0.7 * _BONE)
    layer.putalpha(layer.getchannel("A").point(lambda a: a * 0.35))
    im.alpha_composite(layer)
    draw = ImageDraw.Draw(im)
    for s in range(k):
        cam.skeleton(draw, j[s, frame], (*_rgb8(PALETTE[s % len(PALETTE)]), 255), 1.3 * _BONE)
    buf = io.BytesIO()
    im.convert("RGB").reduce(SUPERSAMPLE).save(buf, format="PNG")
    with atomic_open(path, "wb") as fh:
        fh.write(buf.getvalue())
    return path


# --------------------------------------------------------------------------- helpers


def _check_size(size, even: bool = False) -> tuple[int, int]:
    width, height = (int(s) for s in size)
    if width < 16 or height < 16 or (even and (width % 2 or height % 2)):
        raise ValueError(
            f"size must be at least 16×16 pixels{' (even for .mp4)' if even else ''}, got {size}"
        )
    return width, height


def _motion_and_scene(scene_xyz, scene_rgb, joints, affordance):
    """Checked ``joints [K,T,22,3]``, scene ``xyz [N,3]`` and its colours ``[N,3]`` in [0, 1]."""
    xyz, rgb = scene_points(scene_xyz, scene_rgb)
    j = np.asarray(joints, np.float64)
    j = check_array("joints", j[None] if j.ndim == 3 else j, (None, None, NUM_JOINTS, 3))
    if j.shape[1] == 0:
        raise ValueError("joints has no frame (T = 0)")
    if affordance is not None:
        rgb = heat_colours(rgb, affordance_channels(affordance, len(xyz)).max(axis=1), INFERNO)
    return j, xyz, rgb


def _rgb8(colour) -> tuple[int, int, int]:
    r, g, b = (round(255 * float(c)) for c in colour)
    return r, g, b


@functools.lru_cache(maxsize=8)
def caption_font(px: float):
    from PIL import ImageFont

    try:
        return ImageFont.load_default(size=px)  # Aileron, or a bitmap font without FreeType
    except TypeError:  # Pillow < 10.1: the small bitmap font only
        return ImageFont.load_default()


class Camera:
    """The fixed camera of a clip, drawing at ``SUPERSAMPLE`` times ``width × height``.

    Reproduces matplotlib's mplot3d projection of a cubic 3-D axes (limits the
    framed cube, no automatic margin, ``view_init(30, -60)``, perspective,
    focal length 1, eye 10 box units away, 2-D view limits [-0.095, 0.09]) on a
    square as wide as the longer side, centred on the picture.
    """

    def __init__(self, joints: np.ndarray, width: int, height: int):
        flat = joints.reshape(-1, 3)
        self.lo, self.hi = flat.min(0), flat.max(0)
        self.centre = 0.5 * (self.lo + self.hi)
        self.half = max(0.5 * float(np.max(self.hi - self.lo)) + 0.3, 1.0)
        self.width, self.height = width * SUPERSAMPLE, height * SUPERSAMPLE
        box = 1.8294640721620434 * 25 / 24 / math.sqrt(3)  # mplot3d's side of a cubic box
        span = 2 * self.half  # the cube's side, metres
        e, a = math.radians(_ELEV), math.radians(_AZIM)
        w = np.array([math.cos(e) * math.cos(a), math.cos(e) * math.sin(a), math.sin(e)])
        u = np.cross([0.0, 0.0, 1.0], w)
        u /= np.linalg.norm(u)
        v = np.cross(w, u)
        eye = box / 2 + 10.0 * w  # in box units
        # box units: q = (p - origin) * box / span; view coordinates: [u, v, w] · (q - eye)
        rot = np.stack([u, v, w]) * (box / span)
        origin = self.centre - span / 2
        self._rot = rot
        self._shift = -np.stack([u, v, w]) @ eye - rot @ origin
        side = max(width, height) * SUPERSAMPLE
        self._scale = side / 0.185  # 2-D view limits [-0.095, 0.09]
        self._x0 = (self.width - side) / 2 + 0.095 * self._scale
        self._y0 = self.height - (self.height - side) / 2 - 0.095 * self._scale

    def fit(self, joints: np.ndarray, fill: float = 0.9) -> None:
        """Zoom out (never in) and pan, as little as needed, so every joint lies in the middle
        ``fill`` of the picture's width and height."""
        xy = self.project(joints.reshape(-1, 3))[0]
        lo, hi = xy.min(0), xy.max(0)
        size = np.array([self.width, self.height], np.float64)
        zoom = min(1.0, *(fill * size / np.maximum(hi - lo, 1e-9)))
        mid = size / 2
        lo, hi = mid + zoom * (lo - mid), mid + zoom * (hi - mid)
        margin = (1 - fill) / 2 * size
        pan = np.maximum(0, margin - lo) - np.maximum(0, hi - (size - margin))
        self._scale *= zoom
        self._x0 = mid[0] + zoom * (self._x0 - mid[0]) + pan[0]
        self._y0 = mid[1] + zoom * (self._y0 - mid[1]) + pan[1]

    def project(self, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Pixel coordinates ``[..., 2]`` (x right, y down, pixel centres at +0.5) and depth."""
        c = p @ self._rot.T + self._shift
        depth = -c[..., 2]
        x = self._x0 + self._scale * c[..., 0] / depth
        y = self._y0 - self._scale * c[..., 1] / depth
        return np.stack([x, y], axis=-1), depth

    def background(
        self, xyz, rgb, max_points: int, seed: int, text: str, dot: float = _DOT
    ) -> np.ndarray:
        """The still scene ``[H, W, 3]`` uint8 on white (dots ``dot`` pixels wide), captioned."""
        near = np.all(np.abs(xyz[:, :2] - self.centre[:2]) < self.half + _MARGIN, axis=1) & (
            xyz[:, 2] < self.hi[2] + 0.5
        )
        sel = np.flatnonzero(near)[random_subset(int(near.sum()), max_points, seed)]
        img = np.full((self.height, self.width, 3), 255, np.uint8)
        self.dots(img, xyz[sel], rgb[sel], dot)
        if text:
            from PIL import Image, ImageDraw

            im = Image.fromarray(img)
            font = caption_font(_CAPTION_PX * SUPERSAMPLE)
            lines = wrap_text(text, font, 0.96 * self.width)
            ImageDraw.Draw(im).multiline_text(
                (0.02 * self.width, 0.02 * self.height), "\n".join(lines), fill=(0, 0, 0), font=font
            )
            img = np.array(im)
        return img

    def dots(self, img: np.ndarray, pts: np.ndarray, rgb: np.ndarray, side: float):
        """Paint square dots of ``side`` output pixels into ``img``, the nearest point on top.

        Returns the box ``(x0, y0, x1, y1)`` (pixels) that holds them.
        """
        if not len(pts):
            return _EMPTY
        xy, depth = self.project(pts)
        n = max(1, round(side * SUPERSAMPLE))
        ok = depth > 0
        order = np.flatnonzero(ok)[np.argsort(depth[ok], kind="stable")]  # nearest first
        corner = np.floor(xy[order] - n / 2 + 0.5).astype(np.int64)
        off = np.arange(n)
        cx = (corner[:, 0, None, None] + off[None, None, :]).repeat(n, 1)
        cy = (corner[:, 1, None, None] + off[None, :, None]).repeat(n, 2)
        inside = (cx >= 0) & (cx < self.width) & (cy >= 0) & (cy < self.height)
        pixel = (cy * self.width + cx)[inside]
        point = np.broadcast_to(np.arange(len(order))[:, None, None], inside.shape)[inside]
        pixel, first = np.unique(pixel, return_index=True)  # candidates run nearest first
        colours = np.clip(np.round(np.asarray(rgb)[order] * 255), 0, 255).astype(np.uint8)
        img.reshape(-1, 3)[pixel] = colours[point[first]]
        if not len(pixel):
            return _EMPTY
        return (*corner[point[first]].min(0), *(corner[point[first]].max(0) + n))

    def skeleton(self, draw, joints: np.ndarray, fill, width: float):
        """Draw one pose ``[22, 3]``: bones ``width`` output pixels wide, round joints.

        Returns the box ``(x0, y0, x1, y1)`` (pixels) that holds it.
        """
        xy, _ = self.project(joints)
        xy = xy - 0.5  # Pillow's pixel centres are at whole coordinates
        w = max(1, round(width * SUPERSAMPLE))
        for c in range(1, NUM_JOINTS):
            draw.line([tuple(xy[PARENTS[c]]), tuple(xy[c])], fill=fill, width=w)
        r = w / 2
        for x, y in xy:
            draw.ellipse([x - r + 0.5, y - r + 0.5, x + r - 0.5, y + r - 0.5], fill=fill)
        return (*(xy.min(0) - w), *(xy.max(0) + w + 1))


def wrap_text(text: str, font, width: float) -> list[str]:
    """``text`` broken at spaces into lines at most ``width`` pixels long (long words kept)."""
    lines = []
    for para in text.splitlines() or [""]:
        line = ""
        for word in para.split(" "):
            trial = f"{line} {word}" if line else word
            if line and font.getlength(trial) > width:
                lines.append(line)
                line = word
            else:
                line = trial
        lines.append(line)
    return lines


def gif_bytes(images: list[np.ndarray], boxes, still: np.ndarray, fps: float, exact) -> bytes:
    """Animated GIF of RGB frames: one shared palette, frame times summing to the clip's.

    The palette has the colours ``exact`` (white, black, the skeletons') and a median cut
    of every third pixel of the first, middle and last frames; each pixel gets its nearest
    palette colour, computed once for ``still`` (the frames without the moving parts) and
    per frame only where it differs from it, inside its box ``(x0, y0, x1, y1)`` of ``boxes``.
    """
    from PIL import Image

    picks = sorted({0, len(images) // 2, len(images) - 1})
    sample = np.concatenate([images[i][::3, ::3] for i in picks])
    # 255 colours in all: Pillow marks unchanged pixels with the free index (transparent).
    cut = Image.fromarray(sample).quantize(255 - len(exact), dither=Image.Dither.NONE)
    colours = np.asarray(cut.getpalette("RGB"), np.uint8).reshape(-1, 3)[: 255 - len(exact)]
    palette = np.concatenate([np.asarray(exact, np.uint8).reshape(-1, 3), colours])
    keys, inverse = np.unique(_colour_keys(still), return_inverse=True)
    still_index = _nearest(np.stack([keys >> 16, keys >> 8 & 255, keys & 255], -1), palette)
    still_index = still_index[inverse.reshape(-1)].reshape(still.shape[:2])
    frames = []
    for im, (x0, y0, x1, y1) in zip(images, boxes):
        index = still_index.copy()
        if x1 > x0 and y1 > y0:
            part = im[y0:y1, x0:x1]
            moved = np.any(part != still[y0:y1, x0:x1], axis=-1)
            index[y0:y1, x0:x1][moved] = _nearest(part[moved], palette)
        frame = Image.fromarray(index)
        frame.putpalette(palette.tobytes())
        frames.append(frame)
    # GIF times are whole hundredths of a second: round the running time, not each frame.
    ends = np.round(np.arange(1, len(frames) + 1) * 100.0 / fps).astype(int)
    durations = (10 * np.diff(ends, prepend=0)).tolist()
    buf = io.BytesIO()
    frames[0].save(
        buf,
        format="GIF",
        save_all=True,
        append_images=frames[1:],
        duration=durations,
        loop=0,
        optimize=True,
    )
    return buf.getvalue()


def _colour_keys(rgb: np.ndarray) -> np.ndarray:
    c = rgb.reshape(-1, 3).astype(np.int32)
    return c[:, 0] << 16 | c[:, 1] << 8 | c[:, 2]


def _nearest(rgb: np.ndarray, palette: np.ndarray) -> np.ndarray:
    """Index (uint8) of the nearest ``palette [P, 3]`` colour of each ``rgb [M, 3]`` colour.

    ``|c - p|² - |c|² = |p|² - 2 c·p``, exact in float32 for 8-bit colours (sums < 2²⁴).
    """
    c = np.asarray(rgb, np.float32).reshape(-1, 3)
    p = np.asarray(palette, np.float32)
    pp = (p * p).sum(1)
    out = np.empty(len(c), np.uint8)
    for i in range(0, len(c), 4096):  # no matmul: BLAS threads cost more than they save here
        b = c[i : i + 4096]
        d = pp - 2 * (b[:, :1] * p[:, 0] + b[:, 1:2] * p[:, 1] + b[:, 2:] * p[:, 2])
        out[i : i + 4096] = np.argmin(d, axis=1)
    return out
