"""A library of real motion clips for the synthetic world (``jaxmotion synth --motions SRC``).

``SRC`` is a folder searched recursively for motion files that
:func:`jaxmotion.io.load_motion` reads: ``.npz`` (AMASS, SMPL+H / SMPL-X; subject
``shape.npz`` files are skipped), ``.bvh`` (read with the reader's defaults: y-up, unit and
joint map detected) and ``.npy`` (HumanML3D ``new_joints``, 20 fps). Each file becomes, at
30 fps with its lowest foot joint put at the floor's toe height (as ``jaxmotion data
convert`` does), zero or more **clips**: windows of 30-120 frames that perform one action.

Action label of a file, first that applies:

1. ``SRC/labels.json``: ``{"relative/path.npz": "sit", ...}`` (``null`` skips the file);
2. its name: a path component or a ``_``/``-``/``.``-separated token of the file name that
   is an action word (``walk``/``walking``, ``sit``/``sitting``, ``stand_up``/``standup``/
   ``getup``, ``lie``/``lying``), e.g. ``sit/chair_03.bvh`` or ``07_lie_bed.npz``;
3. else the geometry decides: every action whose window (below) the file holds.

Windows come from per-frame body states (:func:`frame_states`: standing, seated on
something at least 30 cm high with the weight behind the feet (not squatting), lying), so a
labelled file must also *show* its action (it is rejected, and counted, otherwise):

- ``walk``: upright throughout; the first 120 frames, or, when the pelvis ends them less
  than half its path length from where it started (there and back, as a walk that turns
  round), the frames up to where it is farthest from its start; the pelvis ends at least
  0.5 m from its start;
- ``sit``: standing, then seated for at least :data:`HOLD` frames: ends :data:`HOLD`
  frames after the body settles;
- ``stand_up``: seated, then standing: starts :data:`HOLD` frames before the body rises;
- ``lie``: not lying, then lying (at least :data:`HOLD` frames): ends :data:`HOLD` frames
  after the torso is down.

A window must also keep its feet on the floor (the lowest foot joint within 3 cm of toe
height, no joint below the floor).

SMPL-X parameters: AMASS keeps its own (the first 10 betas); joint-only sources (BVH,
HumanML3D) get parameters fitted to the clip's joints on the neutral body
(:func:`jaxmotion.body.fit_joints_to_body`, ``fit_iters`` iterations; 0 = its analytic start
only) while the clip keeps the source's joints; the mean fit error is reported.

The library is cached in ``cache_dir/<digest>.npz``; the digest (:func:`library_digest`)
hashes the content of every motion file, ``labels.json``, ``fit_iters`` and these rules.
"""

from __future__ import annotations

import hashlib
import itertools
import json
import re
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from jaxmotion._atomic import atomic_open
from jaxmotion.data.format import ACTIONS, DatasetError
from jaxmotion.geometry.skeleton import NUM_BETAS
from jaxmotion.io.load import load_motion
from jaxmotion.io.motion import MotionFormatError, smplx_joints_host
from jaxmotion.motion.kinematics import TOE_HEIGHT

__all__ = [
    "HOLD", "LABELS_FILE", "LIBRARY_FORMATS", "Clip", "MotionLibrary", "action_windows",
    "frame_states", "library_digest", "library_files", "load_library", "read_library",
]  # fmt: skip

LIBRARY_VERSION = 4  # bump when the rules below or the readers change: digest and cache follow
LIBRARY_FORMATS = {".npz": "amass", ".bvh": "bvh", ".npy": "humanml3d"}
LABELS_FILE = "labels.json"
FPS = 30.0
MIN_FRAMES, MAX_FRAMES = 30, 120
HOLD = 12  # frames kept after settling into (or before rising from) the pose
_SETTLE = 6  # a state must hold this many frames to count
_NAMES = {"walk": "walk", "walking": "walk", "sit": "sit", "sitting": "sit", "sitdown": "sit",
          "stand_up": "stand_up", "standup": "stand_up", "getup": "stand_up",
          "get_up": "stand_up", "lie": "lie", "lying": "lie", "liedown": "lie",
          "lie_down": "lie"}


@dataclass(frozen=True, eq=False)
class Clip:
    """One window of one source file, at 30 fps, floor at z = 0 (source xy and heading).

    Attributes:
      action: one of ``ACTIONS``. source: path relative to the library folder.
      start, stop: the window's frames in the source (at 30 fps). label: how the action was
      known (``file``, ``name``, ``geometry``). fitted: SMPL-X parameters fitted to joints.
      joints ``[T,22,3]``, global_orient ``[T,3]``, body_pose ``[T,21,3]``, transl ``[T,3]``,
      betas ``[10]``: float32, metres / axis-angle radians.
    """

    action: str
    source: str
    start: int
    stop: int
    label: str
    fitted: bool
    joints: np.ndarray
    global_orient: np.ndarray
    body_pose: np.ndarray
    transl: np.ndarray
    betas: np.ndarray

    @property
    def anchor(self) -> int:
        """HUMANISE anchor frame: 0 for ``stand_up``, else the last."""
        return 0 if self.action == "stand_up" else len(self.joints) - 1


@dataclass(frozen=True)
class MotionLibrary:
    """Clips by action, the folder they came from, its digest and a report (JSON-like)."""

    path: str
    digest: str
    clips: tuple[Clip, ...]
    report: dict = field(default_factory=dict)

    def of(self, action: str) -> list[Clip]:
        return [c for c in self.clips if c.action == action]

    def counts(self) -> dict:
        n = Counter(c.action for c in self.clips)
        return {a: n.get(a, 0) for a in ACTIONS}


# ----------------------------------------------------------------------------- files
def library_files(src) -> list[Path]:
    """The motion files under ``src`` (sorted); DatasetError naming the fix when none."""
    src = Path(src)
    if not src.is_dir():
        raise DatasetError(
            f"--motions {src}: no such folder; give a folder of motion files (AMASS .npz, "
            ".bvh, HumanML3D .npy) that jaxmotion.io.load_motion reads")
    files = sorted(p for p in src.rglob("*") if p.is_file() and p.suffix.lower() in
                   LIBRARY_FORMATS and p.name != "shape.npz")
    if not files:
        raise DatasetError(
            f"--motions {src}: no motion files (.npz AMASS, .bvh, .npy HumanML3D) in this "
            "folder or below it; put your motions there (README, 'Your own data')")
    return files


def library_digest(src, fit_iters: int) -> str:
    """``sha1:<hex>`` of the motion files' paths and bytes, ``labels.json``, ``fit_iters`` and
    the library rules: two builds with different libraries never share a folder."""
    src = Path(src)
    h = hashlib.sha1(f"jaxmotion-library-{LIBRARY_VERSION}-fit{int(fit_iters)}".encode())
    for p in library_files(src) + ([src / LABELS_FILE] if (src / LABELS_FILE).is_file() else []):
        h.update(p.relative_to(src).as_posix().encode() + b"\0")
        with open(p, "rb") as f:
            for block in iter(lambda: f.read(1 << 20), b""):
                h.update(block)
        h.update(b"\0")
    return "sha1:" + h.hexdigest()


def _read_labels(src: Path) -> dict:
    path = src / LABELS_FILE
    if not path.is_file():
        return {}
    try:
        labels = json.loads(path.read_text())
    except (OSError, json.JSONDecodeError) as e:
        raise DatasetError(f"{path}: not readable JSON ({e}); write "
                           '{"relative/path.npz": "sit", ...}') from e
    bad = {k: v for k, v in labels.items() if v is not None and v not in ACTIONS}
    if not isinstance(labels, dict) or bad:
        raise DatasetError(f"{path}: labels must map file paths to one of {ACTIONS} or null; "
                           f"got {dict(list(bad.items())[:3])}")
    return labels


def label_from_name(rel: str) -> str | None:
    """The action a relative path names (a folder, or a token of the file name), or None."""
    parts = rel.lower().split("/")
    words = parts[:-1] + re.split(r"[-_.\s]+", parts[-1].rsplit(".", 1)[0]) + [
        re.sub(r"[-.\s]+", "_", p.rsplit(".", 1)[0]) for p in parts]
    words += ["_".join(pair) for pair in itertools.pairwise(words)]
    found = {_NAMES[w] for w in words if w in _NAMES}
    return found.pop() if len(found) == 1 else None


# ----------------------------------------------------------------------------- geometry
# (joint a, joint b, fraction of the way a -> b, mass fraction): the segments' centres of
# mass, after de Leva (1996); the trunk runs pelvis -> neck, the head sits at its joint
_SEGMENTS = (
    (0, 12, 0.5, 0.497), (15, 15, 0.0, 0.081),  # trunk, head
    (16, 18, 0.44, 0.028), (17, 19, 0.44, 0.028),  # upper arms
    (18, 20, 0.5, 0.022), (19, 21, 0.5, 0.022),  # forearms and hands
    (1, 4, 0.43, 0.100), (2, 5, 0.43, 0.100),  # thighs
    (4, 7, 0.43, 0.0465), (5, 8, 0.43, 0.0465),  # shanks
    (7, 10, 0.5, 0.0145), (8, 11, 0.5, 0.0145),  # feet
)  # fmt: skip
SEAT_BEHIND = 0.10  # the centre of mass behind the feet's support: the weight is on a seat, m
_FOOT_DOWN = 0.15  # a foot whose lowest joint (ankle, toe) is this high or lower bears weight, m


def _behind_feet(j: np.ndarray) -> np.ndarray:
    """``[T]`` metres the body's centre of mass lies behind the support of its feet, along the
    direction it faces (from its hips): behind the rearmost ankle or toe joint of the feet on
    the floor; ``inf`` when no foot is on the floor."""
    com = sum(m * (j[:, a] + f * (j[:, b] - j[:, a])) for a, b, f, m in _SEGMENTS)
    com = com / sum(m for *_, m in _SEGMENTS)
    left = j[:, 1, :2] - j[:, 2, :2]
    fwd = np.stack([left[:, 1], -left[:, 0]], 1)  # left x up
    fwd /= np.maximum(np.linalg.norm(fwd, axis=1, keepdims=True), 1e-9)
    feet = j[:, [7, 8, 10, 11]]  # l/r ankle, l/r toe
    along = np.einsum("tki,ti->tk", feet[..., :2], fwd)
    down = np.tile(np.minimum(feet[:, :2, 2], feet[:, 2:, 2]) <= _FOOT_DOWN, (1, 2))
    rear = np.where(down, along, np.inf).min(1)
    return rear - np.einsum("ti,ti->t", com[:, :2], fwd)


def frame_states(joints: np.ndarray) -> dict:
    """Per-frame body states of ``joints [T,22,3]`` (z-up, floor at 0), bool ``[T]`` arrays:

    - ``lying``: the pelvis -> neck vector within 35 deg of level, both thighs within 45 deg
      of level and both ankles at least 35 cm (horizontally) from the pelvis: the legs lie
      along the support too (a body kneeling or squatting while bent forward, its torso as
      level, has a thigh hanging under it or its feet under the pelvis);
    - ``seated``: torso up (> 45 deg), thighs on average > 45 deg from hanging straight down,
      the pelvis at least 30 cm high (on furniture, not the floor) and 10 % below its highest,
      in a run of such frames whose weight rests on a seat for at least 6 frames in a row
      (``_SETTLE``): the centre of mass (segment-mass-weighted joints) at least :data:`SEAT_BEHIND`
      behind the feet's support along the facing direction (behind the rearmost ankle or toe
      joint of the feet on the floor, the heel being a few cm behind the ankle), or no foot on
      the floor (legs hanging from a bar stool). A squat, deep or half, on flat feet or toes,
      upright or leaning, balances its centre of mass over its feet and is not seated; the
      frames of a sit's run where the body leans forward to rise (or has not yet settled) stay
      seated with the run;
    - ``standing``: torso up (> 60 deg), both thighs within 40 deg of straight down;
    - ``upright``: neither lying nor seated, the pelvis within 15 % of its highest (walking).
    """
    j = np.asarray(joints, np.float64)
    torso = j[:, 12] - j[:, 0]
    torso_el = np.degrees(np.arcsin(np.clip(torso[:, 2] / np.linalg.norm(torso, axis=1), -1, 1)))
    thigh = j[:, [4, 5]] - j[:, [1, 2]]
    # angle of each thigh from straight down, degrees
    down = np.degrees(np.arccos(np.clip(-thigh[..., 2] / np.linalg.norm(thigh, axis=-1), -1, 1)))
    height = j[:, 0, 2]
    ankle_reach = np.linalg.norm(j[:, [7, 8], :2] - j[:, None, 0, :2], axis=-1)
    lying = (torso_el < 35.0) & (down.min(1) > 45.0) & (ankle_reach.min(1) > 0.35)
    standing = ~lying & (torso_el > 60.0) & (down.max(1) < 40.0)
    sitting = (~lying & (torso_el > 45.0) & (down.mean(1) > 45.0) & (height > 0.3)
               & (height < 0.9 * height.max()))
    on_seat = _behind_feet(j) >= SEAT_BEHIND
    seated = np.zeros_like(sitting)
    for a, b in _runs(sitting, 1):
        seated[a:b] = bool(_runs(on_seat[a:b], _SETTLE))
    upright = ~lying & ~seated & (height > 0.85 * height.max())
    return {"standing": standing, "seated": seated, "lying": lying, "upright": upright}


def _runs(x: np.ndarray, n: int) -> list[tuple[int, int]]:
    """(start, stop) of the runs of True in ``x`` at least ``n`` long."""
    d = np.diff(np.concatenate([[0], x.astype(int), [0]]))
    return [(a, b) for a, b in zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1),
                                   strict=True) if b - a >= n]


def action_windows(joints: np.ndarray) -> dict:
    """``{action: (start, stop)}``: the first window of each action the motion holds (see the
    module docstring); 30-120 frames at 30 fps."""
    s = frame_states(joints)
    t, out = len(joints), {}
    pelvis = np.asarray(joints, np.float64)[:, 0, :2]
    if s["upright"].all() and t >= MIN_FRAMES:
        stop = min(t, MAX_FRAMES)
        away = np.linalg.norm(pelvis[:stop] - pelvis[0], axis=1)
        if away[-1] < 0.5 * np.linalg.norm(np.diff(pelvis[:stop], axis=0), axis=1).sum():
            stop = int(np.argmax(away)) + 1  # there and back: up to the farthest point
        if stop >= MIN_FRAMES and away[stop - 1] >= 0.5:
            out["walk"] = (0, stop)
    for action, before, after in (("sit", "standing", "seated"), ("lie", None, "lying")):
        for a, b in _runs(s[after], HOLD):
            stop = a + HOLD
            start = max(0, stop - MAX_FRAMES)
            pre = s[before][start:a] if before else ~s["lying"][start:a]
            if stop - start >= MIN_FRAMES and pre.any():
                out[action] = (start, stop)
                break
    for a, b in _runs(s["seated"], _SETTLE):
        start = max(a, b - HOLD)
        stop = min(t, start + MAX_FRAMES)
        if stop - start >= MIN_FRAMES and _runs(s["standing"][b:stop], _SETTLE):
            out["stand_up"] = (start, stop)
            break
    return out


def _feet_on_floor(joints: np.ndarray) -> bool:
    return (abs(float(joints[:, [10, 11], 2].min()) - TOE_HEIGHT) <= 0.03
            and float(joints[..., 2].min()) > -0.02)


# ----------------------------------------------------------------------------- loading
def _fit(joints: np.ndarray, fit_iters: int) -> tuple[np.ndarray, ...]:
    """Neutral-body SMPL-X parameters of ``joints [T ≤ 120,22,3]`` (padded to 120 frames so
    one compiled program serves every clip) and the mean joint error."""
    t = len(joints)
    padded = np.concatenate([joints, np.repeat(joints[-1:], MAX_FRAMES - t, 0)]).astype(np.float32)
    from jaxmotion.body.fit import fit_joints_to_body, initial_pose

    if fit_iters == 0:
        from jaxmotion.geometry import matrix_to_axis_angle, rest_joints

        local, transl = initial_pose(padded, rest_joints())
        aa = np.asarray(matrix_to_axis_angle(local), np.float64)
        go, bp, tr = aa[:, 0], aa[:, 1:], np.asarray(transl, np.float64)
    else:
        f = fit_joints_to_body(padded, np.arange(MAX_FRAMES) < t, iters=fit_iters, fps=FPS)
        go, bp, tr = (np.asarray(x, np.float64) for x in (f.global_orient, f.body_pose, f.transl))
    go, bp, tr = go[:t], bp[:t], tr[:t]
    err = float(np.linalg.norm(smplx_joints_host(go, bp, tr) - joints, axis=-1).mean())
    return go, bp, tr, err


def _clips_of(path: Path, rel: str, label, label_by: str, fit_iters: int, report: dict):
    motion = load_motion(path, format=LIBRARY_FORMATS[path.suffix.lower()]).resampled(FPS)
    dz = TOE_HEIGHT - float(motion.joints[:, [10, 11], 2].min())
    joints = np.asarray(motion.joints, np.float64) + [0.0, 0.0, dz]
    windows = action_windows(joints)
    if label is not None:
        if label not in windows:
            report["rejected"][f"labelled {label} but no {label} window"] += 1
            return []
        windows = {label: windows[label]}
    elif not windows:
        report["rejected"]["no action recognised"] += 1
    clips = []
    for action, (a, b) in windows.items():
        j = joints[a:b]
        if not _feet_on_floor(j):
            report["rejected"]["feet off the floor"] += 1
            continue
        if motion.has_smplx:
            go, bp = np.asarray(motion.global_orient[a:b]), np.asarray(motion.body_pose[a:b])
            tr = np.asarray(motion.transl[a:b], np.float64) + [0.0, 0.0, dz]
            betas = np.zeros(NUM_BETAS) if motion.betas is None else np.asarray(motion.betas)
        else:
            go, bp, tr, err = _fit(j, fit_iters)
            betas = np.zeros(NUM_BETAS)
            report["fit_errors"].append(err)
        clips.append(Clip(action, rel, int(a), int(b), label_by, not motion.has_smplx,
                          *(np.asarray(x, np.float32) for x in (j, go, bp, tr, betas))))
    return clips


def load_library(src, *, cache_dir=None, fit_iters: int = 200, digest: str | None = None,
                 progress: bool = False) -> MotionLibrary:
    """Read (or take from ``cache_dir``) the clips of the motion folder ``src``.

    Args:
      src: the folder (see the module docstring). cache_dir: where ``<digest>.npz`` is kept.
      fit_iters: SMPL-X fitting iterations for joint-only sources (0: analytic start).
      digest: :func:`library_digest` when already computed.
    Raises:
      DatasetError naming the folder and the fix: no folder, no motion files, no readable
      motion, no clip of any action.
    """
    src = Path(src)
    digest = digest or library_digest(src, fit_iters)
    cache = None if cache_dir is None else Path(cache_dir) / f"{digest.split(':')[-1]}.npz"
    if cache is not None and cache.is_file():
        lib = read_library(cache)
        return MotionLibrary(str(src), digest, lib.clips, {**lib.report, "path": str(src)})
    from tqdm.auto import tqdm

    labels = _read_labels(src)
    report = {"files": 0, "unreadable": [], "rejected": Counter(), "fit_errors": [],
              "labels": Counter()}
    clips = []
    files = library_files(src)
    for path in tqdm(files, desc="motion library", unit="file", disable=not progress):
        rel = path.relative_to(src).as_posix()
        report["files"] += 1
        label, label_by = (labels[rel], "file") if rel in labels else (label_from_name(rel),
                                                                      "name")
        if rel in labels and label is None:
            report["rejected"]["skipped by labels.json"] += 1
            continue
        try:
            new = _clips_of(path, rel, label, label_by if label else "geometry", fit_iters,
                            report)
        except (MotionFormatError, ValueError) as e:
            report["unreadable"].append(f"{rel}: {e}")
            continue
        report["labels"].update(c.label for c in new)
        clips += new
    if len(report["unreadable"]) == len(files):
        raise DatasetError(
            f"--motions {src}: none of its {len(files)} motion files could be read (first: "
            f"{report['unreadable'][0]}); give AMASS .npz, .bvh or HumanML3D .npy motions")
    fits = report.pop("fit_errors")
    report = {"path": str(src), "files": report["files"],
              "unreadable": len(report["unreadable"]),
              "unreadable_first": report["unreadable"][:10],
              "clips": {a: sum(c.action == a for c in clips) for a in ACTIONS},
              "labels": dict(sorted(report["labels"].items())),
              "rejected": dict(sorted(report["rejected"].items())),
              "fitted_clips": len(fits),
              "smplx_fit_error_m": round(float(np.mean(fits)), 5) if fits else None}
    if not clips:
        raise DatasetError(
            f"--motions {src}: {report['files']} motion files but no clip of walk, sit, "
            f"stand_up or lie ({report['rejected']}); label files with {LABELS_FILE} or by "
            "name (sit/..., *_lie_*), and check that each shows its action on a floor at z = 0 "
            "(z-up, metres; BVH files are read y-up)")
    lib = MotionLibrary(str(src), digest, tuple(clips), report)
    if cache is not None:
        _save_library(lib, cache)
    return lib


_ARRAYS = ("joints", "global_orient", "body_pose", "transl")


def _save_library(lib: MotionLibrary, path: Path) -> None:
    meta = {"digest": lib.digest, "report": lib.report,
            "clips": [[c.action, c.source, c.start, c.stop, c.label, c.fitted]
                      for c in lib.clips]}
    arrays = {k: np.concatenate([getattr(c, k) for c in lib.clips]) for k in _ARRAYS}
    arrays["betas"] = np.stack([c.betas for c in lib.clips])
    path.parent.mkdir(parents=True, exist_ok=True)
    with atomic_open(path, "wb") as f:
        np.savez(f, meta=np.array(json.dumps(meta)), **arrays)


def read_library(path) -> MotionLibrary:
    """A library cached by :func:`load_library` (``cache_dir/<digest>.npz``)."""
    with np.load(path, allow_pickle=False) as data:
        meta = json.loads(str(data["meta"]))
        arrays = {k: data[k] for k in (*_ARRAYS, "betas")}
    clips, at = [], 0
    for i, (action, source, start, stop, label, fitted) in enumerate(meta["clips"]):
        n = stop - start
        clips.append(Clip(action, source, start, stop, label, fitted,
                          *(arrays[k][at:at + n] for k in _ARRAYS), arrays["betas"][i]))
        at += n
    return MotionLibrary(meta["report"].get("path", ""), meta["digest"], tuple(clips),
                         meta["report"])
