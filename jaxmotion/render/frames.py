"""Pictures of K bodies moving in a room: frames, MP4 / GIF clips and still PNGs.

:class:`Clip` holds what one rendering needs (bodies, joints for the camera, the room layer,
options) and draws frame ``f`` as ``uint8 [H, W, 3]`` (:meth:`Clip.draw`):

1. the room (:class:`~jaxmotion.render.scene.SceneLayer`), drawn once per clip from the base
   camera (at ``room_supersample`` times the size and reduced, for stills); a following
   camera crops each frame out of a room picture drawn at its zoom;
2. the bodies' contact and drop shadows on it (:class:`~jaxmotion.render.scene.ShadowMap`);
3. the bodies, rasterised (:mod:`~jaxmotion.render.raster`) at :data:`SUPERSAMPLE` times the
   size inside their bounding box only, depth-tested against the room, shaded per vertex
   (a hemisphere ambient, a key light from over the camera's left shoulder, a soft rim and a
   little specular) and interpolated across each triangle (Gouraud; the triangles are a few
   pixels wide), then reduced to the picture (antialiased edges);
4. the caption (top left, on a translucent band), the time (bottom right) and, for several
   samples, a legend.

Several samples are drawn ``"overlay"`` (one room, every body in its colour,
:data:`~jaxmotion.export._common.PALETTE`) or ``"grid"`` (a tile per sample, same camera).
:func:`render_video` writes a clip (MP4 streamed to ffmpeg, or GIF), :func:`render_still` one
PNG (optionally with faint "ghost" bodies at earlier frames).
"""

from __future__ import annotations

import contextlib
import math
import os
import tempfile
import warnings
from pathlib import Path

import numpy as np

from jaxmotion._atomic import atomic_open
from jaxmotion.export._common import PALETTE
from jaxmotion.render import kernels
from jaxmotion.render.body import Bodies
from jaxmotion.render.camera import ELEVATION_DEG, Camera, frame_box, plan_cameras
from jaxmotion.render.scene import CutawayHoles, SceneLayer, ShadowMap, light_direction

__all__ = ["SAMPLE_LAYOUTS", "SUPERSAMPLE", "Clip", "body_colour", "drawn_frames", "render_still",
           "render_video"]

SUPERSAMPLE = 2  # bodies are drawn at this many times the picture's size, then reduced
SAMPLE_LAYOUTS = ("overlay", "grid")
_BG_ID = 0xFFFF_FFFD  # the room's pixels in the body pass's z-buffer
_SHADOW_STRIDE = 3  # every 3rd body vertex casts the shadows
_GHOST = 0.35  # opacity of the faint bodies of a still
MAX_ROOM_PIXELS = 4_000_000  # a follow camera's room picture is at most this large


def body_colour(sample: int) -> np.ndarray:
    """The body colour of sample ``sample``: its palette colour, lightened."""
    return 0.5 * PALETTE[sample % len(PALETTE)] + 0.5 * np.array([0.93, 0.93, 0.95])


class Clip:
    """One rendering of ``bodies`` in a room (see the module docstring).

    Args:
      bodies: the posed meshes (:class:`~jaxmotion.render.body.Bodies`).
      joints: ``[K, T, 22, 3]`` the same motions' joints (frame the camera).
      fps: frames per second of the motion (the clock).
      scene_xyz, scene_rgb, scene_normal: the room's points (see ``SceneLayer``).
      highlight: ``[N]`` bool, the target object's points, or None; instance: ``[N]`` object
        ids of the points (−1: none) or None (the cutaway removes whole objects).
      text: caption; size: ``(width, height)``; samples: ``"overlay"`` or ``"grid"``.
      camera: ``"auto"``, ``"fixed"`` or ``"follow"``; azimuth, elevation: degrees (azimuth
        None: chosen to see the body's front past the furniture).
      floor: draw the floor plane (z = 0).
      room_supersample: draw the room at this many times the picture's size (a fixed camera;
        2 for stills: smoother edges, four times the work); a follow camera draws it at its
        zoom (up to :data:`MAX_ROOM_PIXELS`) and crops each frame out of it.
    """

    def __init__(self, bodies: Bodies, joints, fps: float, scene_xyz, scene_rgb=None, *,
                 scene_normal=None, highlight=None, instance=None, text: str = "",
                 size: tuple[int, int] = (640, 480), samples: str = "overlay",
                 camera: str = "auto", azimuth: float | None = None,
                 elevation: float = ELEVATION_DEG, floor: bool = True,
                 room_supersample: float = 1.0):
        if samples not in SAMPLE_LAYOUTS:
            raise ValueError(f"samples must be 'overlay' or 'grid', got {samples!r}")
        self.bodies = bodies
        self.joints = np.asarray(joints, np.float64)
        if self.joints.shape[:2] != (bodies.num_samples, bodies.num_frames):
            raise ValueError(f"joints {list(self.joints.shape)} and the bodies ({bodies.num_samples} "
                             f"samples, {bodies.num_frames} frames) do not match")
        self.fps = float(fps)
        self.width, self.height = (int(s) for s in size)
        if min(self.width, self.height) < 16:
            raise ValueError(f"size must be at least 16×16 pixels, got {tuple(size)}")
        self.text = text
        k = bodies.num_samples
        self.grid = (1, 1)
        if samples == "grid" and k > 1:
            cols = max(1, round(math.sqrt(k * self.height / self.width * 16 / 9)))
            cols = min(k, max(cols, math.ceil(k / math.ceil(math.sqrt(k)))))
            self.grid = (cols, math.ceil(k / cols))
        self.layout = samples if k > 1 else "overlay"
        tw, th = self.width // self.grid[0], self.height // self.grid[1]
        self.tile = (tw, th)
        xyz = np.asarray(scene_xyz, np.float64).reshape(-1, 3)
        self.plan = plan_cameras(self.joints, self.fps, tw, th, mode=camera, azimuth=azimuth,
                                 elevation=elevation, scene_xyz=xyz)
        self.cameras, self.mode = self.plan.cameras, self.plan.mode
        self.light = light_direction(self.plan.base)
        rgb = np.full_like(xyz, 0.6) if scene_rgb is None else scene_rgb
        self.scene = SceneLayer(xyz, rgb, scene_normal, highlight, instance, light=self.light,
                                floor=floor)
        self.top = float(self.joints[..., 2].max())
        self.faces = bodies.faces
        self._room = None
        self._marks = None  # the caption's and the legend's drawing (see _static_marks)
        self._mark_cache: dict = {}
        self._room_supersample = max(1.0, float(room_supersample))

    # ---------------------------------------------------------------- background

    def room(self):
        """The room from the base camera (drawn once; see ``SceneLayer.background``)."""
        if self._room is None:
            base = self.plan.base
            centre, _ = frame_box(self.joints)
            back = -base.rot[2, :2] / max(float(np.linalg.norm(base.rot[2, :2])), 1e-9)
            reach = float(((self.joints[..., :2] - centre[:2]) @ back).max()) + 0.3
            poses = self.joints[:, ::max(1, self.joints.shape[1] // 40)]
            if self.mode == "fixed":
                s = self._room_supersample
                ss = round(s) if s == round(s) else 1
                self._room = self.scene.background(base, centre, reach, self.top, supersample=ss,
                                                   holes=CutawayHoles(base, poses))
            else:  # a follow camera crops frames out of a picture drawn at its zoom
                scale = min(self.plan.zoom, math.sqrt(MAX_ROOM_PIXELS / (base.width * base.height)))
                big = base.scaled(max(1.0, scale))  # the holes on the picture's own pixels
                self._room = self.scene.background(big, centre, reach, self.top,
                                                   holes=CutawayHoles(big, poses))
        return self._room

    def _background(self, f: int):
        room = self.room()
        return room if self.mode == "fixed" else room.crop(self.cameras[f])

    # ---------------------------------------------------------------- one frame

    def draw(self, f: int, ghosts=()) -> np.ndarray:
        """Frame ``f`` (an index into the motion's T frames): ``uint8 [H, W, 3]``; the bodies
        of the frames ``ghosts`` are drawn faintly behind (same camera, see-through)."""
        f = int(f)
        bg = self._background(f)
        cam = self.cameras[f]
        verts = self.bodies.frame(f)
        tw, th = self.tile
        out = np.full((self.height, self.width, 3), 255, np.uint8)
        groups = [list(range(self.bodies.num_samples))] if self.layout == "overlay" else \
            [[s] for s in range(self.bodies.num_samples)]
        for tile, members in enumerate(groups):
            rgb = bg.rgb.copy()
            self._shadows(rgb, bg, verts[members])
            for g in ghosts:
                layer = rgb.copy()
                self._bodies(layer, bg.depth, cam, self.bodies.frame(g), members)
                rgb += _GHOST * (layer - rgb)
            self._bodies(rgb, bg.depth, cam, verts, members)
            c, r = tile % self.grid[0], tile // self.grid[0]
            out[r * th:(r + 1) * th, c * tw:(c + 1) * tw] = _to_uint8(rgb)
        return self._annotate(out, f, [g[0] for g in groups] if self.layout == "grid" else None)

    def _shadows(self, rgb: np.ndarray, bg, verts: np.ndarray) -> None:
        shadow = ShadowMap(verts[:, ::_SHADOW_STRIDE].reshape(-1, 3), self.light)
        shadow.darken(rgb, bg, top=float(verts[..., 2].max()))

    def _bodies(self, rgb: np.ndarray, depth: np.ndarray, cam: Camera, verts: np.ndarray,
                members: list[int]) -> None:
        """Draw the bodies ``members`` of ``verts [K, V, 3]`` into ``rgb`` in place."""
        s = SUPERSAMPLE
        big = cam.scaled(s)
        h, w = depth.shape
        nv, nf = verts.shape[1], len(self.faces)
        pts = np.ascontiguousarray(verts[members], np.float32).reshape(-1, 3)
        x, y, z = np.empty(len(pts)), np.empty(len(pts)), np.empty(len(pts))
        kernels.project(pts, big.eye, big.rot, float(big.focal), float(big.cx), float(big.cy),
                        0.0, 0.0, x, y, z)
        front = z > 1e-3
        if not front.any():
            return
        x0 = max(0, math.floor(x[front].min() / s) - 1)
        y0 = max(0, math.floor(y[front].min() / s) - 1)
        x1 = min(w, math.ceil(x[front].max() / s) + 1)
        y1 = min(h, math.ceil(y[front].max() / s) + 1)
        if x1 <= x0 or y1 <= y0:
            return
        x -= x0 * s
        y -= y0 * s
        # the region's z-buffer starts as the room's depth, each pixel's s × s samples
        buf_depth = np.repeat(np.repeat(depth[y0:y1, x0:x1], s, 0), s, 1)
        ids = np.full(buf_depth.shape, _BG_ID, np.int64)
        for i in range(len(members)):
            kernels.raster_triangles(x, y, z, self.faces, i * nv, i * nf, buf_depth, ids)
        if not (ids < len(members) * nf).any():
            return
        colours = np.empty((len(pts), 3), np.float32)
        view = -cam.rot[2]
        half = self.light + view
        half /= np.linalg.norm(half)
        for i, k in enumerate(members):
            kernels.vertex_colours(pts[i * nv:(i + 1) * nv], self.faces, body_colour(k),
                                   self.light, view, half, colours[i * nv:(i + 1) * nv])
        region = rgb[y0:y1, x0:x1]
        kernels.compose(ids, x, y, z, self.faces, nf, nv, colours, region, s, region)

    def _annotate(self, img: np.ndarray, f: int, tile_samples) -> np.ndarray:
        """Draw the caption, the clock and (several samples) the legend on ``img`` (in place;
        returned). Each group of marks is drawn by Pillow on the crop of the picture it
        covers, which gives the pixels a drawing on the whole picture gives; the caption and
        the legend, the same on every frame, are drawn once and reused while the pixels
        under them are unchanged (a body passing under redraws them)."""
        caption, legend = self._static_marks(tile_samples is not None)
        for ops, cache in ((caption, self._mark_cache), (self._clock_marks(f), None),
                           (legend, self._mark_cache)):
            if ops:
                _draw_marks(img, ops, cache)
        return img

    def _static_marks(self, grid: bool):
        """The caption's and the legend's drawing operations (see :func:`_draw_marks`)."""
        if self._marks is None:
            from jaxmotion.export.video import caption_font, wrap_text

            scale = max(self.width, self.height) / 640
            caption = []
            if self.text:
                font = caption_font(13.0 * scale)
                text = "\n".join(wrap_text(self.text, font, 0.9 * self.width))
                pos = (0.02 * self.width, 0.02 * self.height)
                box = _scratch_draw().multiline_textbbox(pos, text, font=font)
                pad = 4 * scale
                caption = [("rect", (box[0] - pad, box[1] - pad, box[2] + pad, box[3] + pad),
                            (255, 255, 255, 190)), ("mtext", pos, text, (20, 20, 20), font)]
            legend = []
            k = self.bodies.num_samples
            if k > 1:
                font = caption_font(11.0 * scale)
                tw, th = self.tile
                for i in range(k):
                    colour = tuple(round(255 * c) for c in PALETTE[i % len(PALETTE)])
                    if not grid:  # overlay: a legend at the bottom left
                        pos = (0.02 * self.width, 0.98 * self.height - (k - 1 - i) * 14 * scale)
                    else:
                        pos = ((i % self.grid[0]) * tw + 6 * scale,
                               (i // self.grid[0] + 1) * th - 4 * scale)
                    legend.append(("text", pos, f"sample {i}", colour, font, "ld"))
            self._marks = (tuple(caption), tuple(legend))
        return self._marks

    def _clock_marks(self, f: int):
        """The clock's drawing operations at frame ``f``: the time on a translucent box."""
        from jaxmotion.export.video import caption_font

        font = caption_font(11.0 * max(self.width, self.height) / 640)
        clock = f"{f / self.fps:5.2f} s"
        pos = (0.98 * self.width, 0.98 * self.height)
        box = _scratch_draw().textbbox(pos, clock, font=font, anchor="rd")
        return [("rect", (box[0] - 3, box[1] - 3, box[2] + 3, box[3] + 3), (255, 255, 255, 190)),
                ("text", pos, clock, (20, 20, 20), font, "rd")]


def _scratch_draw():
    """An ImageDraw to measure text with (its picture is never drawn on)."""
    from PIL import Image, ImageDraw

    return ImageDraw.Draw(Image.new("RGB", (1, 1)), "RGBA")


def _draw_marks(img: np.ndarray, ops, cache: dict | None) -> None:
    """Draw ``ops`` (``("rect", box, fill)``, ``("text", pos, text, fill, font, anchor)``,
    ``("mtext", pos, text, fill, font)``, in picture coordinates) on ``img [H, W, 3]`` uint8
    in place, through a Pillow picture of the crop they cover only: its corner on even
    pixels (no coordinate changes its rounding when moved there), a margin around the
    marks' boxes. With ``cache`` (a dict; ``ops`` a tuple, the same every frame) a crop whose
    pixels are those of the last drawing takes its result back."""
    from PIL import Image, ImageDraw

    measure = _scratch_draw()
    boxes = []
    for op in ops:
        if op[0] == "rect":
            boxes.append(op[1])
        elif op[0] == "text":
            boxes.append(measure.textbbox(op[1], op[2], font=op[4], anchor=op[5]))
        else:
            boxes.append(measure.multiline_textbbox(op[1], op[2], font=op[4]))
    lo = np.floor(np.min([b[:2] for b in boxes], 0)).astype(int) - 4
    hi = np.ceil(np.max([b[2:] for b in boxes], 0)).astype(int) + 4
    h, w = img.shape[:2]
    x0, y0 = max(0, lo[0] - lo[0] % 2), max(0, lo[1] - lo[1] % 2)
    x1, y1 = min(w, hi[0]), min(h, hi[1])
    if x1 <= x0 or y1 <= y0:
        return
    crop = img[y0:y1, x0:x1]
    key = (ops, x0, y0) if cache is not None else None
    known = None if key is None else cache.get(key)
    if known is not None and np.array_equal(known[0], crop):
        crop[...] = known[1]
        return
    before = crop.copy()
    im = Image.fromarray(before)
    draw = ImageDraw.Draw(im, "RGBA")
    for op in ops:
        if op[0] == "rect":
            b = op[1]
            draw.rectangle([b[0] - x0, b[1] - y0, b[2] - x0, b[3] - y0], fill=op[2])
        elif op[0] == "text":
            draw.text((op[1][0] - x0, op[1][1] - y0), op[2], fill=op[3], font=op[4],
                      anchor=op[5])
        else:
            draw.multiline_text((op[1][0] - x0, op[1][1] - y0), op[2], fill=op[3], font=op[4])
    crop[...] = np.asarray(im)
    if key is not None:
        cache[key] = (before, crop.copy())


def _to_uint8(rgb: np.ndarray) -> np.ndarray:
    out = np.empty(rgb.shape, np.uint8)
    kernels.to_uint8(rgb, out)
    return out


# --------------------------------------------------------------------------- writers


def _frame_indices(t: int, fps: float, out_fps: float | None, max_frames: int | None):
    """Indices of the drawn frames (a whole stride) and the output frame rate."""
    stride = 1
    if out_fps is not None:
        stride = max(1, round(fps / out_fps))
    if max_frames is not None:
        stride = max(stride, math.ceil(t / max_frames))
    return np.arange(0, t, stride), fps / stride


def drawn_frames(clip: Clip, frames, workers: int | None = None):
    """``clip.draw(f)`` for each of ``frames``, in order, drawn by ``workers`` threads (None:
    up to 2, the machine's cores permitting; NumPy releases the GIL in the heavy steps, so two
    threads draw 1.6× as many frames per second on two cores, the same pixels). The first
    frame is drawn alone (it builds the room picture the others share); at most two frames per
    thread are held at once."""
    from collections import deque
    from concurrent.futures import ThreadPoolExecutor

    frames = [int(f) for f in frames]
    workers = min(2, os.cpu_count() or 1) if workers is None else max(1, int(workers))
    if not frames:
        return
    yield clip.draw(frames[0])
    if workers == 1:
        yield from (clip.draw(f) for f in frames[1:])
        return
    with ThreadPoolExecutor(workers) as pool:
        todo, running = iter(frames[1:]), deque()
        for f in todo:
            running.append(pool.submit(clip.draw, f))
            if len(running) >= 2 * workers:
                yield running.popleft().result()
        while running:
            yield running.popleft().result()


def render_video(path, clip: Clip, *, video_fps: float | None = None,
                 max_frames: int | None = None, meanwhile=None) -> Path:
    """Write ``clip`` to ``.mp4`` (H.264, streamed to ffmpeg) or ``.gif``, atomically.

    Frames are drawn at a whole stride of the motion's: ``video_fps`` (None: every frame),
    also at most ``max_frames`` frames; the clip keeps the motion's duration.
    ``meanwhile``: a function run on another thread while the frames are drawn (from after
    ffmpeg has started: no thread may be busy when it forks); its exception is raised here.
    ``generate`` writes its other files so while the room picture is drawn, on one core.
    """
    from jaxmotion.export.video import GIF_MAX_FPS, gif_bytes

    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in (".mp4", ".gif"):
        raise ValueError(f"render_video writes .mp4 or .gif, got {path.name!r}")
    if suffix == ".mp4" and (clip.width % 2 or clip.height % 2):
        raise ValueError(f"an .mp4 needs an even width and height, got {clip.width}×"
                         f"{clip.height}")
    if suffix == ".gif":
        video_fps = min(video_fps or clip.fps, GIF_MAX_FPS)
    frames, out_fps = _frame_indices(clip.bodies.num_frames, clip.fps, video_fps, max_frames)
    if suffix == ".gif":
        with _beside(meanwhile):
            images = list(drawn_frames(clip, frames))
        box = (0, 0, clip.width, clip.height)
        data = gif_bytes(images, [box] * len(images), images[0], out_fps,
                          [(255, 255, 255), (20, 20, 20)])
        with atomic_open(path, "wb") as fh:
            fh.write(data)
        return path
    import imageio_ffmpeg

    # ffmpeg starts by a fork, whose handlers stop NumPy's BLAS threads: nothing may be
    # running on another thread then (a background kernels.warm_up is waited for here)
    kernels.warm_up()
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp.mp4", dir=path.parent)
    os.close(fd)
    try:
        writer = imageio_ffmpeg.write_frames(
            tmp, (clip.width, clip.height), fps=out_fps, codec="libx264", macro_block_size=1,
            quality=None, output_params=["-preset", "veryfast", "-crf", "20",
                                         "-movflags", "+faststart"])
        with warnings.catch_warnings():  # fork + exec of ffmpeg: JAX's fork warning is moot
            warnings.filterwarnings("ignore", message="os.fork", category=RuntimeWarning)
            writer.send(None)
        try:
            with _beside(meanwhile):
                for image in drawn_frames(clip, frames):
                    writer.send(np.ascontiguousarray(image))
        finally:
            writer.close()
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return path


@contextlib.contextmanager
def _beside(fn):
    """Run ``fn`` on another thread for the duration of the block; wait for it at the end and
    raise its exception (after the block's own, which wins)."""
    if fn is None:
        yield
        return
    from concurrent.futures import ThreadPoolExecutor

    with ThreadPoolExecutor(1, thread_name_prefix="beside the video") as pool:
        done = pool.submit(fn)
        yield
    done.result()


def render_still(path_png, clip: Clip, *, frame: int | None = None, ghosts: int = 0) -> Path:
    """One PNG of ``clip`` at ``frame`` (None: the last), atomically. ``ghosts`` > 0 also
    draws the bodies of that many other frames, evenly spread over the clip, faintly (for a
    fixed camera: one picture that shows where the motion went)."""
    import io

    from PIL import Image

    path = Path(path_png)
    if path.suffix.lower() != ".png":
        raise ValueError(f"render_still writes .png, got {path.name!r}")
    t = clip.bodies.num_frames
    frame = t - 1 if frame is None else int(frame)
    if not -t <= frame < t:
        raise ValueError(f"frame must be in [-{t}, {t}), got {frame}")
    frame %= t
    others = []
    if ghosts > 0 and clip.mode == "fixed":
        spread = np.linspace(0, t - 1, ghosts + 1).round().astype(int)
        others = [int(g) for g in spread if g != frame][:ghosts]
    buf = io.BytesIO()
    Image.fromarray(clip.draw(frame, others)).save(buf, format="PNG")
    with atomic_open(path, "wb") as fh:
        fh.write(buf.getvalue())
    return path
