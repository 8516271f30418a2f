"""Offscreen videos of a motion in its scene: animated GIF or MP4, drawn with matplotlib (Agg).

Each video frame shows the scene points near the motion in their colours (or
the affordance heat layer), the body (subsampled vertices, shaded when faces
are given) and the skeleton of every sample in its own colour (``PALETTE``,
matplotlib's "tab10"), drawn on top, with the text and the time. The camera is
fixed for the whole clip: it looks at the centre of the joints' bounding box
over all frames and samples, 30° above the horizontal (azimuth −60°), and
frames a cube 0.6 m wider than that box. Only scene points within 1 m (in xy)
of that cube and below 0.5 m above the highest joint are drawn, so walls and the
ceiling do not hide the person.

Speed: at most ``max_frames`` frames are drawn (the motion is subsampled by a
whole stride and the output frame rate lowered to match, so the clip keeps its
real duration), each with at most ``max_points`` scene points: 60 frames at
640×480 take about 9 s on one CPU core (GIF about 7 MB, MP4 about 0.3 MB).
"""

from __future__ import annotations

import importlib.util
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
    vertex_normals,
)
from jaxmotion.geometry.skeleton import NUM_JOINTS, PARENTS

__all__ = ["render_motion_video"]

_MARGIN = 1.0  # metres of scene drawn around the framed cube (xy)
_LIGHT = np.array([0.3, -0.5, 0.8]) / np.linalg.norm([0.3, -0.5, 0.8])


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
    size: tuple[int, int] = (640, 480),
    max_points: int = 20_000,
    max_frames: int = 60,
    max_body_points: int = 2_000,
    seed: int = 0,
) -> Path:
    """Render the motion in its scene to ``.gif`` or ``.mp4`` (chosen by the suffix), atomically.

    Args:
      path: output file, ``.gif`` or ``.mp4`` (MP4 needs ``imageio-ffmpeg``).
      scene_xyz: ``[N, 3]`` scene points, z-up, metres; scene_rgb: ``[N, 3]`` in [0, 1] or None.
      joints: ``[T, 22, 3]`` or ``[K, T, 22, 3]`` (K samples), same frame as the scene.
      fps: frames per second of ``joints``.
      vertices: ``[(K,) T, V, 3]`` posed body vertices (e.g. ``body_forward(...).vertices``),
        drawn as at most ``max_body_points`` points per body; faces: ``[F, 3]`` their
        triangles, used to shade those points.
      affordance: ``[N]`` or ``[N, C]`` affordance map in [0, 1]: the scene is drawn as a
        heat layer of its maximum over the channels.
      text: caption drawn at the top.
      size: ``(width, height)`` pixels (even numbers for MP4).
      max_points, max_frames: speed limits, see the module docstring.
      seed: for the random point subsets.
    Returns:
      the path written.
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in (".gif", ".mp4"):
        raise ValueError(f"render_motion_video writes .gif or .mp4, got {path.name!r}")
    if suffix == ".mp4" and importlib.util.find_spec("imageio_ffmpeg") is None:
        raise ValueError("writing .mp4 needs imageio-ffmpeg: pip install 'imageio-ffmpeg>=0.5'")
    width, height = (int(s) for s in size)
    if width < 16 or height < 16 or (suffix == ".mp4" and (width % 2 or height % 2)):
        raise ValueError(f"size must be at least 16×16 pixels (even for .mp4), got {size}")
    if max_frames < 1 or max_points < 0 or max_body_points < 1:
        raise ValueError("max_frames and max_body_points must be ≥ 1, max_points ≥ 0")
    fps = check_fps(fps)
    xyz, rgb = scene_points(scene_xyz, scene_rgb)
    j = np.asarray(joints, np.float64)
    j = check_array("joints", j[None] if j.ndim == 3 else j, (None, None, NUM_JOINTS, 3))
    k, t = j.shape[:2]
    if t == 0:
        raise ValueError("joints has no frame (T = 0)")
    if affordance is not None:
        rgb = heat_colours(rgb, affordance_channels(affordance, len(xyz)).max(axis=1), INFERNO)
    body = body_faces = keep = None
    if vertices is not None:
        body = np.asarray(vertices, np.float64)
        body = check_array("vertices", body[None] if body.ndim == 3 else body, (k, t, None, 3))
        drawn = np.arange(body.shape[2])
        if faces is not None:
            body_faces = check_array("faces", faces, (None, 3), np.int64)
            if body_faces.size and (body_faces.min() < 0 or body_faces.max() >= body.shape[2]):
                raise ValueError(f"faces index vertices outside [0, {body.shape[2]})")
            drawn = np.unique(body_faces)
        keep = drawn[random_subset(len(drawn), max_body_points, seed)]

    stride = math.ceil(t / max_frames)
    frames = np.arange(0, t, stride)
    lo, hi = j.reshape(-1, 3).min(0), j.reshape(-1, 3).max(0)
    centre = 0.5 * (lo + hi)
    half = max(0.5 * float(np.max(hi - lo)) + 0.3, 1.0)
    near = np.all(np.abs(xyz[:, :2] - centre[:2]) < half + _MARGIN, axis=1) & (
        xyz[:, 2] < hi[2] + 0.5
    )
    sel = np.flatnonzero(near)[random_subset(int(near.sum()), max_points, seed)]

    # A bare Agg figure: no pyplot state, whatever backend the caller's process uses.
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    from mpl_toolkits.mplot3d.art3d import Line3DCollection

    fig = Figure(figsize=(width / 100, height / 100), dpi=100)
    canvas = FigureCanvasAgg(fig)
    # A square axes as wide as the longer side: mplot3d draws (and clips) in a square.
    side = max(width, height)
    rect = ((1 - side / width) / 2, (1 - side / height) / 2, side / width, side / height)
    ax = fig.add_axes(rect, projection="3d")
    ax.set_axis_off()
    ax.computed_zorder = False  # draw order = zorder: the skeleton stays on top
    ax.scatter(*xyz[sel].T, c=rgb[sel], s=1.0, linewidths=0, depthshade=False, zorder=1)
    ax.set_xlim(centre[0] - half, centre[0] + half)
    ax.set_ylim(centre[1] - half, centre[1] + half)
    ax.set_zlim(centre[2] - half, centre[2] + half)
    ax.set_box_aspect((1, 1, 1))
    ax.view_init(elev=30, azim=-60)

    def skeleton(s: int, f: int) -> list[np.ndarray]:
        return [j[s, f, [PARENTS[c], c]] for c in range(1, NUM_JOINTS)]

    bones = [
        Line3DCollection(
            skeleton(s, 0), colors=[PALETTE[s % len(PALETTE)]], linewidths=2.2, zorder=3
        )
        for s in range(k)
    ]
    for b in bones:
        ax.add_collection3d(b, autolim=False)
    fig.text(0.02, 0.98, text, va="top", fontsize=9, wrap=True)
    clock = fig.text(0.98, 0.02, "", ha="right", va="bottom", fontsize=8)
    body_art, images = [], []
    for f in frames:
        for s, b in enumerate(bones):
            b.set_segments(skeleton(s, f))
        for a in body_art:
            a.remove()
        body_art = []
        if body is not None:
            for s in range(k):
                pts = body[s, f, keep]
                base = 0.55 + 0.45 * PALETTE[s % len(PALETTE)]
                if body_faces is not None:
                    n = vertex_normals(body[s, f], body_faces)[keep]
                    colour = base * (0.35 + 0.65 * np.abs(n @ _LIGHT))[:, None]
                else:
                    colour = np.broadcast_to(base, pts.shape)
                body_art.append(
                    ax.scatter(*pts.T, c=colour, s=2.0, linewidths=0, depthshade=False, zorder=2)
                )
        clock.set_text(f"{f / fps:5.2f} s")
        canvas.draw()
        images.append(np.asarray(canvas.buffer_rgba())[..., :3].copy())

    import imageio.v3 as iio

    out_fps = fps / stride
    if suffix == ".gif":
        data = iio.imwrite(
            "<bytes>", np.stack(images), extension=".gif", duration=1000.0 / out_fps, loop=0
        )
    else:
        data = iio.imwrite(
            "<bytes>",
            np.stack(images),
            extension=".mp4",
            plugin="FFMPEG",
            fps=out_fps,
            codec="libx264",
            macro_block_size=1,
        )
    with atomic_open(path, "wb") as fh:
        fh.write(data)
    return path
