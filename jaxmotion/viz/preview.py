"""Still previews of a motion in a room: a top view and a perspective view as PNG.

Meant for a person to judge a sample at a glance: scene points in their colours
(height-shaded in the top view), the skeleton drawn at evenly spaced frames
from light (start) to dark (end), the pelvis path, and the target object's
points highlighted. Uses matplotlib's Agg backend (no display needed).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from jaxmotion._atomic import atomic_open
from jaxmotion.geometry.skeleton import PARENTS

__all__ = ["render_preview"]

_MAX_POINTS = 60_000


def _figure():
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    return plt


def _subsample(xyz, rgb, mask, rng):
    if len(xyz) <= _MAX_POINTS:
        return xyz, rgb, mask
    keep = rng.choice(len(xyz), _MAX_POINTS, replace=False)
    return xyz[keep], rgb[keep], mask[keep]


def _frames(t: int, count: int) -> np.ndarray:
    return np.unique(np.linspace(0, t - 1, min(count, t)).round().astype(int))


def _save(fig, path: Path, dpi: int):
    with atomic_open(path, "wb") as f:
        fig.savefig(f, format="png", dpi=dpi, bbox_inches="tight")


def render_preview(
    xyz: np.ndarray,
    rgb: np.ndarray,
    joints: np.ndarray,
    out_prefix,
    *,
    mask: np.ndarray | None = None,
    target_mask: np.ndarray | None = None,
    title: str = "",
    skeletons: int = 8,
    seed: int = 0,
    dpi: int = 110,
) -> list[Path]:
    """Write ``<out_prefix>_top.png`` and ``<out_prefix>_persp.png``; return their paths.

    Args:
      xyz ``[N,3]``, rgb ``[N,3]`` in [0,1]: the scene (z-up, metres).
      joints ``[T,22,3]``: the motion in the same frame; mask ``[T]`` valid frames.
      target_mask ``[N]``: points to highlight (the target object), optional.
      skeletons: how many frames to draw.
    """
    plt = _figure()
    joints = np.asarray(joints, np.float32)
    if mask is not None:
        joints = joints[np.asarray(mask, bool)]
    if len(joints) == 0:
        raise ValueError("render_preview: the motion has no valid frame")
    rng = np.random.default_rng(seed)
    tmask = np.zeros(len(xyz), bool) if target_mask is None else np.asarray(target_mask, bool)
    xyz, rgb, tmask = _subsample(np.asarray(xyz), np.clip(np.asarray(rgb), 0, 1), tmask, rng)
    frames = _frames(len(joints), skeletons)
    shades = plt.get_cmap("plasma")(np.linspace(0.15, 0.85, len(frames)))
    out_prefix = Path(out_prefix)
    paths = []

    # --- top view: points sorted by height so that tops of furniture stay visible
    fig, ax = plt.subplots(figsize=(7, 7))
    order = np.argsort(xyz[:, 2])
    ax.scatter(xyz[order, 0], xyz[order, 1], c=rgb[order], s=1.5, linewidths=0)
    if tmask.any():
        ax.scatter(xyz[tmask, 0], xyz[tmask, 1], s=2.0, c="#ff3b30", alpha=0.35, linewidths=0)
    ax.plot(joints[:, 0, 0], joints[:, 0, 1], "-", color="black", lw=1.0, alpha=0.7)
    for f, col in zip(frames, shades):
        for j, p in enumerate(PARENTS[1:], start=1):
            ax.plot(joints[f, [p, j], 0], joints[f, [p, j], 1], "-", color=col, lw=1.6)
    ax.set_aspect("equal")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_title((title + "\n" if title else "") + "top view (skeleton colour: start purple → end yellow)", fontsize=9)
    path = out_prefix.with_name(out_prefix.name + "_top.png")
    _save(fig, path, dpi)
    plt.close(fig)
    paths.append(path)

    # --- perspective view around the motion
    fig = plt.figure(figsize=(8, 6))
    ax = fig.add_subplot(projection="3d")
    lo, hi = joints[..., :2].min((0, 1)), joints[..., :2].max((0, 1))
    centre = 0.5 * (lo + hi)
    half = max(1.2, 0.5 * float(np.max(hi - lo)) + 0.6)
    top = 2.2
    near = np.all(np.abs(xyz[:, :2] - centre) < half, axis=1) & (xyz[:, 2] < top)
    ax.scatter(xyz[near, 0], xyz[near, 1], xyz[near, 2], c=rgb[near], s=0.6, linewidths=0,
               depthshade=False)
    for n, (f, col) in enumerate(zip(frames, shades)):
        ends = n in (0, len(frames) - 1)  # first and last pose bold, the rest faint
        for j, p in enumerate(PARENTS[1:], start=1):
            seg = joints[f, [p, j]]
            ax.plot(seg[:, 0], seg[:, 1], seg[:, 2], "-", color=col, lw=2.6 if ends else 1.0,
                    alpha=1.0 if ends else 0.45)
    ax.plot(joints[:, 0, 0], joints[:, 0, 1], joints[:, 0, 2], "-", color="black", lw=0.8)
    ax.set_xlim(centre[0] - half, centre[0] + half)
    ax.set_ylim(centre[1] - half, centre[1] + half)
    ax.set_zlim(0, top)
    ax.set_box_aspect((2 * half, 2 * half, top))
    ax.view_init(elev=25, azim=-60)
    ax.set_title(title, fontsize=9)
    path = out_prefix.with_name(out_prefix.name + "_persp.png")
    _save(fig, path, dpi)
    plt.close(fig)
    paths.append(path)
    return paths
