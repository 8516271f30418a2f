"""HumanML3D clips: joint positions and their captions.

Layout of a HumanML3D folder ``ROOT`` (the user's own copy, made by its scripts)::

    ROOT/new_joints/<id>.npy     float32 [T, 22, 3], y-up, metres, 20 fps, floor at y = 0
    ROOT/texts/<id>.txt          one caption per line: caption#word/POS tokens#start#end
    ROOT/train.txt, val.txt, test.txt   one id per line
    ROOT/new_joint_vecs/<id>.npy [T, 263] features (not read here)

Ids starting with ``M`` are the mirrored clips, just other ids. The joints are the SMPL
body joints in SMPL-X order, turned z-up by ``(x, y, z) → (x, −z, y)`` (the first frame,
facing +z in the file, faces −y). A caption line whose ``start`` and ``end`` are both 0 (or
NaN) describes the whole clip; otherwise it describes the part from ``start`` to ``end``
seconds, which HumanML3D's own loader cuts out as frames ``[⌊20·start⌋, ⌊20·end⌋)``
(:func:`caption_clips` does the same).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from jaxmotion.io.motion import Motion, MotionFormatError, y_up_to_z_up

__all__ = ["HUMANML3D_FPS", "caption_clips", "load_humanml3d", "load_split", "read_captions"]

HUMANML3D_FPS = 20.0


def read_captions(path) -> list[tuple[str, float, float]]:
    """``(caption, start, end)`` per line of a ``texts/<id>.txt`` file (seconds; 0, 0 = the
    whole clip). Blank lines are skipped; a missing file has no captions."""
    path = Path(path)
    if not path.is_file():
        return []
    try:
        lines = path.read_text(encoding="utf-8").splitlines()
    except (OSError, UnicodeDecodeError) as e:
        raise MotionFormatError(f"{path}: unreadable caption file ({e})") from e
    out = []
    for k, line in enumerate(lines, 1):
        if not line.strip():
            continue
        parts = line.rsplit("#", 3)
        try:
            if len(parts) != 4:
                raise ValueError
            start, end = (0.0 if math.isnan(v) else v for v in map(float, parts[2:]))
        except ValueError:
            raise MotionFormatError(
                f"{path}:{k}: expected 'caption#tokens#start#end' (start/end in seconds, "
                f"0#0 for the whole clip), got {line[:80]!r}") from None
        if start < 0 or end < 0 or (end and end < start):
            raise MotionFormatError(f"{path}:{k}: bad time span {start}..{end} s; start <= end, "
                                    "both >= 0 (0#0: the whole clip)")
        out.append((parts[0].strip(), start, end))
    return out


def _npy(path: Path) -> np.ndarray:
    try:
        a = np.load(path, allow_pickle=False)
    except (OSError, ValueError, EOFError) as e:
        raise MotionFormatError(f"{path}: not a readable .npy array ({e}); re-create it with "
                                "HumanML3D's scripts") from e
    if a.ndim == 2 and a.shape[1] == 263:
        raise MotionFormatError(f"{path}: this is a [T, 263] feature file (new_joint_vecs); "
                                "read new_joints/<id>.npy instead")
    if a.ndim != 3 or a.shape[1:] != (22, 3) or a.shape[0] < 1 or a.dtype.kind not in "fiu":
        raise MotionFormatError(f"{path}: HumanML3D joints must be a [T, 22, 3] float array, got "
                                f"{a.dtype} {list(a.shape)}; give a new_joints/<id>.npy file")
    if not np.isfinite(a).all():
        raise MotionFormatError(f"{path}: the joints have NaN or inf values")
    return a


def load_humanml3d(path, motion_id: str | None = None, *, fps: float | None = None) -> Motion:
    """Read one HumanML3D clip with its captions.

    Args:
      path: ``ROOT/new_joints/<id>.npy``, or ``ROOT`` together with ``motion_id``.
      motion_id: the clip id (e.g. ``"000021"``, ``"M000021"``) when ``path`` is the root.
      fps: resample to this rate (default: HumanML3D's 20 fps).
    Returns:
      joints ``[T, 22, 3]`` metres z-up; no SMPL-X parameters; ``texts`` with their
      ``text_spans`` (whole-clip captions span ``(0, duration)``); ``info`` has ``id``.
    """
    path = Path(path)
    if motion_id is not None:
        root, file = path, path / "new_joints" / f"{motion_id}.npy"
    else:
        root, file = path.parent.parent, path
    if not file.is_file():
        hint = ("give ROOT/new_joints/<id>.npy, or the HumanML3D folder and motion_id"
                if motion_id is None else f"is {root} the HumanML3D folder (with new_joints/)?")
        raise MotionFormatError(f"{file}: no such file; {hint}")
    joints = y_up_to_z_up(_npy(file))
    duration = (len(joints) - 1) / HUMANML3D_FPS
    captions = read_captions(root / "texts" / f"{file.stem}.txt")
    spans = tuple((0.0, duration) if s == e == 0 else (s, min(e, duration))
                  for _, s, e in captions)
    motion = Motion(joints=joints, fps=HUMANML3D_FPS, texts=tuple(c for c, _, _ in captions),
                    text_spans=spans, source=str(file),
                    info={"format": "humanml3d", "id": file.stem})
    return motion if fps is None else motion.resampled(fps)


def caption_clips(motion: Motion) -> list[Motion]:
    """Split a clip by caption span, as HumanML3D's loader does: the whole clip with its
    whole-clip captions (when it has any), then one clip per distinct partial span
    (frames ``[⌊fps·start⌋, ⌊fps·end⌋)``) with its captions. Each clip's ``text_spans``
    cover it whole; ``info["span"]`` is the span in the source (seconds). A clip without
    captions comes back whole, as the only element."""
    if not motion.texts:
        return [motion.replace(info={**motion.info, "span": [0.0, motion.duration]})]
    tol = 0.5 / motion.fps
    groups: dict[tuple[float, float] | None, list[str]] = {}
    for text, span in zip(motion.texts, motion.text_spans, strict=True):
        whole = span[0] <= tol and span[1] >= motion.duration - tol
        groups.setdefault(None if whole else span, []).append(text)
    out = []
    for span in sorted(groups, key=lambda s: (s is not None, s or (0.0, 0.0))):
        if span is None:
            clip = motion
        else:
            i0, i1 = int(span[0] * motion.fps), int(span[1] * motion.fps)
            if i1 - i0 < 1 or i0 >= motion.num_frames:
                continue
            clip = motion.frames(i0, i1)
        out.append(clip.replace(texts=tuple(groups[span]), text_spans=None,
                                info={**motion.info, "span": list(span or (0.0, motion.duration))}))
    return out


def load_split(root, split: str) -> list[str]:
    """The clip ids of a split, read from ``ROOT/<split>.txt`` (``train``, ``val``, ``test``,
    or any other list the folder has, e.g. ``train_val``, ``all``)."""
    root = Path(root)
    file = root / f"{split}.txt"
    if not file.is_file():
        have = sorted(p.stem for p in root.glob("*.txt")) if root.is_dir() else []
        raise MotionFormatError(f"{file}: no such split list; {root} has "
                                f"{have or 'no .txt lists'} (HumanML3D ships train, val, test)")
    try:
        return [s.strip() for s in file.read_text(encoding="utf-8").splitlines() if s.strip()]
    except (OSError, UnicodeDecodeError) as e:
        raise MotionFormatError(f"{file}: unreadable split list ({e})") from e
