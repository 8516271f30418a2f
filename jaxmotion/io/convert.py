"""Convert a motion dataset (HumanML3D, AMASS, BVH files) to jaxmotion's sample schema.

``jaxmotion data convert --from humanml3d|amass|bvh SRC --out DIR``

writes the layout of :mod:`jaxmotion.data.format` (the same as ``jaxmotion synth``), so
:class:`jaxmotion.data.Dataset` and the training tasks read it unchanged::

    DIR/manifest.json              counts, settings, rules applied, errors
    DIR/scenes/floor.npz           the one scene: a flat floor (these motions have no room)
    DIR/samples/<split>/<id>.npz   one sample per clip (and caption, with captions="all")
    DIR/stats.npz                  normalisation statistics of the training crops

Rules (recorded in the manifest):

- **Clips**: each motion is resampled to 30 fps and cut into ``ceil(T / 120)`` equal
  consecutive clips of at most ``max_frames`` = 120 frames (4 s); clips shorter than
  ``min_frames`` (30) are dropped. HumanML3D captions with a time span are cut out first,
  as HumanML3D's loader does (:func:`jaxmotion.io.caption_clips`).
- **Placement**: z is shifted so the lowest foot joint of the whole motion is 2.5 cm above
  the floor (as in the synthetic world; ``floor=False`` keeps the source heights); each
  clip is moved in xy so its pelvis path is centred on the origin (heading kept).
- **Scene**: ``floor``, a 20 m × 20 m grid of points at z = 0, 4 cm apart (NYU40 ``floor``,
  instance 0, one object ``floor``); ``target_id`` is −1 (no target object).
- **Action label**: ``"walk"`` for every sample unless ``action=`` names another of
  :data:`jaxmotion.data.ACTIONS` (the sources carry no such label).
- **Text**: HumanML3D: the first caption of the clip (``captions="all"``: one sample per
  caption); AMASS and BVH: empty text (the papers' text-free pre-training).
- **SMPL-X**: AMASS keeps its parameters (first 10 betas); joint-only sources (HumanML3D,
  BVH) get parameters fitted to the joints on the neutral body
  (:func:`jaxmotion.body.fit_joints_to_body`, ``fit_iters`` iterations; 0 = the analytic
  start only, exact when the bone lengths match SMPL-X's, a few cm off otherwise); the
  sample keeps the source's joints. The mean fit error is in the manifest.
- **Splits**: HumanML3D's ``train/val/test.txt`` lists; otherwise a hash of each source
  file's path (80 / 10 / 10, stable when files are added); ``split="train"`` (or val /
  test) puts everything in one split.

Resumable and atomic: every file is written through a temporary file and ``os.replace``;
a source counts as done when its record ``DIR/.convert/done/<key>.json`` and all the
samples it lists exist, so running the same command again continues where it stopped. A
source that cannot be read is reported in the manifest's ``errors`` and retried next run.
"""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import itertools
import json
import math
import re
import time
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from jaxmotion._version import __version__
from jaxmotion.constants import SCENE_FPS
from jaxmotion.data.format import (
    ACTIONS,
    SPLITS,
    DatasetError,
    load_manifest,
    save_sample,
    write_json_atomic,
)
from jaxmotion.geometry.skeleton import NUM_BETAS
from jaxmotion.io.humanml3d import caption_clips, load_humanml3d
from jaxmotion.io.load import load_motion
from jaxmotion.io.motion import Motion, MotionFormatError, smplx_joints_host
from jaxmotion.motion.kinematics import TOE_HEIGHT
from jaxmotion.scene.furniture import CATEGORY_IDS
from jaxmotion.scene.io import Scene, save_scene

__all__ = ["CONVERT_KINDS", "FLOOR_SCENE_ID", "ConvertSettings", "check_out_folder", "convert",
           "finished_source", "floor_scene", "source_key"]

CONVERT_KINDS = ("humanml3d", "amass", "bvh", "gltf")
FLOOR_SCENE_ID = "floor"
FORMAT_VERSION = 1
_READER_OPTIONS = {"bvh": ("up", "unit", "joint_map"), "gltf": ("up", "unit", "joint_map"),
                   "amass": (), "humanml3d": ()}
_FEET = (10, 11)


@dataclass(frozen=True)
class ConvertSettings:
    """What defines a conversion (a resumed run must use the same)."""

    kind: str
    action: str = "walk"
    fps: float = SCENE_FPS
    max_frames: int = 120
    min_frames: int = 30
    captions: str = "first"
    split: str = "auto"
    fit_iters: int = 200
    floor: bool = True
    floor_size: float = 20.0
    floor_spacing: float = 0.04
    reader_options: tuple[tuple[str, str], ...] = ()

    def __post_init__(self):
        if self.kind not in CONVERT_KINDS:
            raise ValueError(f"cannot convert {self.kind!r} data; choose one of "
                             f"{', '.join(CONVERT_KINDS)}")
        if self.action not in ACTIONS:
            raise ValueError(f"action {self.action!r} is not one of {ACTIONS}")
        if self.captions not in ("first", "all"):
            raise ValueError(f"captions must be 'first' or 'all', got {self.captions!r}")
        if self.split not in ("auto", *SPLITS):
            raise ValueError(f"split must be 'auto' or one of {SPLITS}, got {self.split!r}")
        if not 1 <= self.min_frames <= self.max_frames:
            raise ValueError(f"need 1 <= min_frames ({self.min_frames}) <= max_frames "
                             f"({self.max_frames})")
        if self.fit_iters < 0 or not self.fps > 0 or not self.floor_size > 2.0:
            raise ValueError("fit_iters must be >= 0, fps > 0 and floor_size > 2 m")
        if not 0 < self.floor_spacing <= 0.1:
            raise ValueError(f"floor_spacing must be in (0, 0.1] m, got {self.floor_spacing}")


# ----------------------------------------------------------------------------- the floor
def floor_scene(size: float = 20.0, spacing: float = 0.04) -> Scene:
    """A square floor ``size`` metres wide centred on the origin at z = 0: grid points
    ``spacing`` apart, grey, normals +z, semantic NYU40 floor, instance 0, object 0."""
    n = round(size / spacing) + 1
    g = np.linspace(-size / 2, size / 2, n)
    xx, yy = np.meshgrid(g, g, indexing="ij")
    xyz = np.stack([xx.ravel(), yy.ravel(), np.zeros(n * n)], 1)
    normal = np.zeros_like(xyz)
    normal[:, 2] = 1.0
    half = size / 2
    obj = {"id": 0, "category": "floor", "bbox_min": [-half, -half, 0.0],
           "bbox_max": [half, half, 0.0]}
    return Scene(xyz=xyz, normal=normal, semantic=np.full(n * n, CATEGORY_IDS["floor"]),
                 instance=np.zeros(n * n, np.int64), objects=(obj,), name=FLOOR_SCENE_ID)


# ----------------------------------------------------------------------------- sources
def source_key(rel: str) -> str:
    """A file-name-safe, unique id for a source path."""
    stem = re.sub(r"[^A-Za-z0-9_-]+", "_", rel.rsplit(".", 1)[0]).strip("_")[-60:]
    return f"{stem}-{hashlib.sha1(rel.encode()).hexdigest()[:6]}"


def _hash_split(rel: str) -> str:
    r = int(hashlib.sha1(rel.encode()).hexdigest()[:8], 16) % 100
    return "train" if r < 80 else "val" if r < 90 else "test"


def _sources(settings: ConvertSettings, src: Path) -> list[tuple[str, str, Path]]:
    """(key, split, path) of every source motion."""
    if not src.exists():
        raise MotionFormatError(f"{src}: no such file or folder")
    kind = settings.kind
    if kind == "humanml3d":
        folder = src / "new_joints"
        if not folder.is_dir():
            raise MotionFormatError(f"{src}: not a HumanML3D folder (no new_joints/); give the "
                                    "folder holding new_joints/, texts/ and train.txt")
        lists = {sp: src / f"{sp}.txt" for sp in SPLITS if (src / f"{sp}.txt").is_file()}
        if lists:
            from jaxmotion.io.humanml3d import load_split

            out = [(i, sp, folder / f"{i}.npy") for sp in lists for i in load_split(src, sp)]
        else:
            out = [(p.stem, _hash_split(p.stem), p) for p in sorted(folder.glob("*.npy"))]
    else:
        suffixes = {"amass": (".npz",), "gltf": (".glb", ".gltf")}.get(kind, (".bvh",))
        if src.is_file():
            files, base = [src], src.parent
        else:
            files = sorted(p for p in src.rglob("*") if p.suffix.lower() in suffixes
                           and p.is_file() and p.name != "shape.npz")
            base = src
        out = []
        for p in files:
            rel = p.relative_to(base).as_posix()
            out.append((source_key(rel), _hash_split(rel), p))
    if not out:
        raise MotionFormatError(f"{src}: no {kind} motions found")
    if settings.split != "auto":
        out = [(k, settings.split, p) for k, _, p in out]
    return out


# ----------------------------------------------------------------------------- fitting
@functools.lru_cache(maxsize=4)
def _analytic_fit():
    import jax

    from jaxmotion.body.fit import initial_pose
    from jaxmotion.geometry import matrix_to_axis_angle, rest_joints

    def fit(joints):
        local, transl = initial_pose(joints, rest_joints())
        return matrix_to_axis_angle(local), transl

    return jax.jit(fit)


def _fit_smplx(joints: np.ndarray, settings: ConvertSettings) -> dict:
    """SMPL-X parameters of the neutral body fitted to ``joints [T, 22, 3]`` (T ≤ max_frames);
    padded to ``max_frames`` so that one compiled program serves every clip."""
    t, pad = len(joints), settings.max_frames - len(joints)
    padded = np.concatenate([joints, np.repeat(joints[-1:], pad, 0)]).astype(np.float32)
    if settings.fit_iters == 0:
        aa, transl = (np.asarray(x, np.float64) for x in _analytic_fit()(padded))
        go, bp = aa[:, 0], aa[:, 1:]
    else:
        from jaxmotion.body.fit import fit_joints_to_body

        mask = np.arange(settings.max_frames) < t
        f = fit_joints_to_body(padded, mask, iters=settings.fit_iters, fps=settings.fps)
        go, bp, transl = (np.asarray(x, np.float64) for x in (f.global_orient, f.body_pose,
                                                              f.transl))
    go, bp, transl = go[:t], bp[:t], transl[:t]
    err = np.linalg.norm(smplx_joints_host(go, bp, transl) - joints, axis=-1).mean()
    return {"global_orient": go, "body_pose": bp, "transl": transl,
            "betas": np.zeros(NUM_BETAS), "fit_error": float(err)}


# ----------------------------------------------------------------------------- one source
def _load(settings: ConvertSettings, path: Path) -> list[Motion]:
    """The source's motions at ``settings.fps``, floor-shifted, one per caption span."""
    opts = dict(settings.reader_options)  # load_bvh reads a unit given as text
    motion = (load_humanml3d(path) if settings.kind == "humanml3d"
              else load_motion(path, format=settings.kind, **opts))
    clips = caption_clips(motion) if settings.kind == "humanml3d" else [motion]
    clips = [c.resampled(settings.fps) for c in clips]
    if not settings.floor:
        return clips
    # the lowest foot joint of the whole motion, as the clips sample it, goes to TOE_HEIGHT
    dz = TOE_HEIGHT - float(motion.resampled(settings.fps).joints[:, list(_FEET), 2].min())
    shift = np.array([0.0, 0.0, dz])
    return [c.replace(joints=c.joints + shift,
                      **({"transl": c.transl + shift} if c.has_smplx else {})) for c in clips]


def _pieces(motion: Motion, settings: ConvertSettings) -> list[Motion]:
    t = motion.num_frames
    n = math.ceil(t / settings.max_frames)
    cuts = np.round(np.linspace(0, t, n + 1)).astype(int)
    return [motion.frames(a, b) for a, b in itertools.pairwise(cuts)
            if b - a >= settings.min_frames]


def _convert_source(root: Path, settings: ConvertSettings, key: str, split: str,
                    path: Path) -> dict:
    """Write the samples of one source; returns its record (also saved as its marker)."""
    record = {"source": str(path), "split": split, "files": [], "fit_errors": [],
              "dropped_short": 0, "dropped_far": 0}
    reach = settings.floor_size / 2 - 1.0  # pelvis xy must stay this far inside the floor
    n = 0
    for clip in _load(settings, path):
        pieces = _pieces(clip, settings)
        record["dropped_short"] += int(clip.num_frames >= 1 and not pieces)
        for piece in pieces:
            pelvis = piece.joints[:, 0, :2]
            centre = 0.5 * (pelvis.min(0) + pelvis.max(0))
            if np.abs(pelvis - centre).max() > reach:
                record["dropped_far"] += 1
                continue
            shift = np.array([-centre[0], -centre[1], 0.0])
            joints = np.asarray(piece.joints, np.float64) + shift
            if piece.has_smplx:
                params = {"global_orient": piece.global_orient, "body_pose": piece.body_pose,
                          "transl": piece.transl + shift,
                          "betas": np.zeros(NUM_BETAS) if piece.betas is None else piece.betas}
            else:
                params = _fit_smplx(joints, settings)
                record["fit_errors"].append(params.pop("fit_error"))
            texts = list(piece.texts) or [""]
            if settings.captions == "first":
                texts = texts[:1]
            for text in texts:
                name = f"{key}_{n:03d}.npz"
                n += 1
                save_sample(root / "samples" / split / name, {
                    "text": text, "action": settings.action, "scene_id": FLOOR_SCENE_ID,
                    "target_id": -1, "joints": joints, "fps": settings.fps,
                    "mask": np.ones(piece.num_frames, bool), **params})
                record["files"].append(f"samples/{split}/{name}")
    return record


def finished_source(root: Path, key: str) -> dict | None:
    """The record of source ``key`` when it was converted and all its files exist, else None."""
    marker = root / ".convert" / "done" / f"{key}.json"
    if not marker.is_file():
        return None
    try:
        record = json.loads(marker.read_text())
    except (OSError, json.JSONDecodeError):
        return None
    return record if all((root / f).is_file() for f in record.get("files", [])) else None


def check_out_folder(root: Path, settings: dict) -> None:
    """DatasetError when ``root`` holds another dataset or a conversion with other settings."""
    saved = root / ".convert" / "settings.json"
    if (root / "manifest.json").is_file():
        old = load_manifest(root).get("convert_settings")
        if old is None:
            raise DatasetError(f"{root} already holds a dataset that was not converted (e.g. "
                               "'jaxmotion synth'); choose another --out")
        if old != settings:
            raise DatasetError(f"{root} holds a conversion with other settings ({old}); use the "
                               "same settings to resume, or another --out")
    elif saved.is_file() and json.loads(saved.read_text()) != settings:
        raise DatasetError(f"{root} holds an unfinished conversion with other settings; use the "
                           "same settings to resume, or another --out")


def convert(kind: str, src, out, *, progress: bool = True, stats: bool = True,
            **options) -> dict:
    """Convert the motions of ``src`` into a sample-schema dataset in ``out`` (or resume).

    Args:
      kind: ``"humanml3d"`` (``src`` = the folder with ``new_joints/``), ``"amass"`` or
        ``"bvh"`` (``src`` = one file or a folder searched recursively).
      src: the source file or folder; out: the dataset folder (created).
      progress: show a progress bar; stats: write ``stats.npz`` at the end.
      options: :class:`ConvertSettings` fields (``action``, ``fps``, ``max_frames``,
        ``min_frames``, ``captions``, ``split``, ``fit_iters``, ``floor``, ``floor_size``,
        ``floor_spacing``) and, for BVH, the reader's ``up``, ``unit``, ``joint_map``.
    Returns:
      the manifest (also written to ``out/manifest.json``).
    Raises:
      ValueError (MotionFormatError, DatasetError) for unusable options, sources or ``out``.
    """
    from tqdm.auto import tqdm

    reader = {k: options.pop(k) for k in _READER_OPTIONS.get(kind, ()) if k in options}
    fields = {f.name for f in dataclasses.fields(ConvertSettings)} - {"kind", "reader_options"}
    if unknown := sorted(set(options) - fields):
        raise ValueError(f"unknown convert option(s) {unknown} for {kind}; options: "
                         f"{sorted(fields | set(_READER_OPTIONS.get(kind, ())))}")
    if isinstance(reader.get("joint_map"), dict):
        raise TypeError("joint_map: give a built-in name or a JSON file path when converting "
                         "(the settings are saved for resuming)")
    unit = reader.get("unit", "auto")
    try:
        ok = unit == "auto" or float(unit) > 0
    except (TypeError, ValueError):
        ok = False
    if not ok:
        raise ValueError(f"unit must be 'auto' or metres per file unit (> 0), got {unit!r}")
    settings = ConvertSettings(kind=kind, reader_options=tuple(sorted(
        (k, str(v)) for k, v in reader.items() if v is not None)), **options)
    root, src = Path(out), Path(src)
    sources = _sources(settings, src)
    settings_dict = json.loads(json.dumps(asdict(settings)))
    check_out_folder(root, settings_dict)
    write_json_atomic(root / ".convert" / "settings.json", settings_dict)
    scene_path = root / "scenes" / f"{FLOOR_SCENE_ID}.npz"
    if not scene_path.is_file():
        scene_path.parent.mkdir(parents=True, exist_ok=True)
        save_scene(floor_scene(settings.floor_size, settings.floor_spacing), scene_path)

    t0 = time.perf_counter()
    records, errors, converted = [], [], 0
    for key, split, path in tqdm(sources, desc=f"convert {kind}", unit="file",
                                 disable=not progress):
        record = finished_source(root, key)
        if record is None:
            try:
                record = _convert_source(root, settings, key, split, path)
            except MotionFormatError as e:
                errors.append({"source": str(path), "error": str(e)})
                continue
            write_json_atomic(root / ".convert" / "done" / f"{key}.json", record)
            converted += 1
        records.append(record)
    fit_errors = [e for r in records for e in r["fit_errors"]]
    counts = {sp: len(list((root / "samples" / sp).glob("*.npz"))) for sp in SPLITS}
    manifest = {
        "format_version": FORMAT_VERSION,
        "jaxmotion_version": __version__,
        "kind": f"converted from {kind} (the user's own copy of licensed data: do not share)",
        "source": str(src),
        "convert_settings": settings_dict,
        "scenes": {FLOOR_SCENE_ID: 1},
        "samples": counts,
        "sources": {"total": len(sources), "done": len(records),
                    "converted_this_run": converted, "failed": len(errors)},
        "errors": errors[:50],
        "dropped_clips": {"shorter_than_min_frames": sum(r["dropped_short"] for r in records),
                          "beyond_the_floor": sum(r["dropped_far"] for r in records)},
        "rules": {
            "action": f"every sample is labelled {settings.action!r} (sources carry no label)",
            "text": ("HumanML3D captions" if kind == "humanml3d" else "empty (text-free data)"),
            "smplx": ("source parameters" if kind == "amass" else "fitted to the joints on "
                      f"the neutral body ({settings.fit_iters} iterations)"),
            "scene": "floor only; target_id -1 (no target)",
        },
        "smplx_fit_error_m": round(float(np.mean(fit_errors)), 5) if fit_errors else None,
        "build_seconds_this_run": round(time.perf_counter() - t0, 1),
        "fps": settings.fps,
    }
    write_json_atomic(root / "manifest.json", manifest)
    if stats and counts["train"]:
        from jaxmotion.data.synth import write_stats

        write_stats(root)
    return manifest

