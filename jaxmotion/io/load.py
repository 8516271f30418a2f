"""One entry point for every motion format: :func:`load_motion`."""

from __future__ import annotations

import inspect
from pathlib import Path

from jaxmotion.io.amass import load_amass
from jaxmotion.io.bvh import load_bvh
from jaxmotion.io.gltf import load_gltf
from jaxmotion.io.humanise import load_humanise
from jaxmotion.io.humanml3d import load_humanml3d
from jaxmotion.io.motion import Motion, MotionFormatError

__all__ = ["READERS", "detect_format", "load_motion"]

READERS = {
    "bvh": load_bvh,
    "gltf": load_gltf,
    "humanml3d": load_humanml3d,
    "amass": load_amass,
    "humanise": load_humanise,
}
_BY_SUFFIX = {".bvh": "bvh", ".glb": "gltf", ".gltf": "gltf", ".npy": "humanml3d",
              ".npz": "amass", ".pkl": "humanise"}


def detect_format(path) -> str:
    """The format of a motion file from its name: ``.bvh`` → bvh, ``.glb`` / ``.gltf`` →
    gltf (a skinned animation), ``.npy`` → humanml3d
    (``new_joints/<id>.npy``), ``.npz`` → amass, ``.pkl`` → humanise. Raises
    MotionFormatError for a folder or another extension."""
    path = Path(path)
    if path.is_dir():
        raise MotionFormatError(
            f"{path}: a folder, not a motion file; give one file, or a HumanML3D folder with "
            "format='humanml3d' and motion_id=...; to convert a whole dataset use "
            "jaxmotion.io.convert (or 'jaxmotion data convert')")
    fmt = _BY_SUFFIX.get(path.suffix.lower())
    if fmt is None:
        raise MotionFormatError(
            f"{path}: unknown motion file type {path.suffix!r}; jaxmotion reads .bvh (BVH), "
            ".glb / .gltf (a skinned glTF animation), .npy "
            "(HumanML3D new_joints), .npz (AMASS) and .pkl (HUMANISE), or name the format "
            f"with format= one of {', '.join(READERS)}")
    return fmt


def load_motion(path, *, format: str | None = None, **options) -> Motion:
    """Read a motion file of any supported format as a :class:`~jaxmotion.io.Motion`.

    Args:
      path: the file (see :func:`detect_format`), or a HumanML3D folder with
        ``format="humanml3d", motion_id=...``.
      format: ``"bvh"``, ``"humanml3d"``, ``"amass"`` or ``"humanise"``; default: from the
        file name.
      options: the reader's keyword options, e.g. ``fps=30`` (all readers), ``up``,
        ``unit``, ``joint_map`` (BVH), ``motion_id`` (HumanML3D), ``index``,
        ``trust_pickle`` (HUMANISE). See :func:`~jaxmotion.io.load_bvh`,
        :func:`~jaxmotion.io.load_humanml3d`, :func:`~jaxmotion.io.load_amass`,
        :func:`~jaxmotion.io.load_humanise`.
    Returns:
      the motion: joints ``[T, 22, 3]`` metres z-up, fps, SMPL-X parameters where the source
      has them, captions, source.
    Raises:
      MotionFormatError (a ValueError) naming the file and the fix.
    """
    fmt = detect_format(path) if format is None else str(format).lower()
    reader = READERS.get(fmt)
    if reader is None:
        raise MotionFormatError(f"{path}: unknown format {format!r}; use one of "
                                f"{', '.join(READERS)}")
    params = inspect.signature(reader).parameters
    allowed = [n for n, p in params.items() if p.kind is p.KEYWORD_ONLY or n == "motion_id"]
    if unknown := sorted(set(options) - set(allowed)):
        raise MotionFormatError(f"{path}: option(s) {unknown} do not apply to {fmt} files; its "
                                f"options are {allowed}")
    return reader(path, **options)
