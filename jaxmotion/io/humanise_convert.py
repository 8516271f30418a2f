"""Convert HUMANISE (Wang et al., NeurIPS 2022) to jaxmotion's sample schema, in its rooms.

``jaxmotion data convert --from humanise HUMANISE --scannet ScanNet --out DIR``

writes the layout of :mod:`jaxmotion.data.format` (as ``jaxmotion synth`` and
:mod:`jaxmotion.io.convert` do), so :class:`jaxmotion.data.Dataset` and the training tasks
read it unchanged::

    DIR/manifest.json              counts, settings, rules applied, errors
    DIR/scenes/<scene_id>.npz      each ScanNet room used, in HUMANISE's frame
    DIR/samples/<split>/<id>.npz   one sample per HUMANISE annotation
    DIR/stats.npz                  normalisation statistics of the training crops

Rules (recorded in the manifest):

- **Sources**: both HUMANISE layouts (:mod:`jaxmotion.io.humanise`): every annotation of every
  ``align_data_release/<action>/<scene>_<id>/anno.pkl``, or every ``motions/NNNNNN.pkl`` with
  its ``annotation.csv`` row. ``SRC`` is the folder holding ``align_data_release/`` (or that
  folder itself), or the one holding ``motions/`` and ``annotation.csv``.
- **Scene**: ``SCANNET/scans/<scene_id>/`` (or ``SCANNET/<scene_id>/``) read by
  :func:`jaxmotion.scene.load_scene` (objects from its aggregation, axis-aligned, ``points``
  surface samples, seed 0), then moved by the annotation's ``scene_translation``: the frame
  HUMANISE places its motions in (taken to be the axis-aligned scan translated; the reader
  gives the motions in it). One file per scene; a scene met again with another translation
  is an error for that annotation.
- **Action**: the HUMANISE action folder (``stand up`` -> ``stand_up``), or the table's
  ``action`` column; **text**: the utterance; **target_id**: the annotation's ``object_id``
  (it must be an object of the scene's table).
- **Frames**: 30 fps as HUMANISE; a motion longer than ``max_frames`` (120) keeps the
  ``max_frames`` frames at its anchor (the first ones for stand_up, else the last), one
  shorter than ``min_frames`` (30) is dropped. Heights are kept (the motion stands on the
  scan's floor).
- **SMPL-X**: HUMANISE's parameters (first 10 betas); joints by jaxmotion's skeleton.
- **Splits**: HUMANISE's, by ScanNet id: scenes numbered below 600 train, the others test
  (no val); ``split="train"`` (or val / test) puts everything in one split.

Resumable and atomic as :func:`jaxmotion.io.convert.convert`: a source counts as done when its
record ``DIR/.convert/done/<key>.json`` and all its samples exist; a source that cannot be read
(bad pickle, missing scan, missing aggregation, unknown object) is reported in the manifest's
``errors`` with the file and the fix, and retried next run.
"""

from __future__ import annotations

import dataclasses
import json
import re
import time
from pathlib import Path

import numpy as np

from jaxmotion._version import __version__
from jaxmotion.data.format import (
    ACTIONS,
    SPLITS,
    DatasetError,
    save_sample,
    write_json_atomic,
)
from jaxmotion.errors import SceneError
from jaxmotion.io.convert import FORMAT_VERSION, check_out_folder, finished_source, source_key
from jaxmotion.io.humanise import load_humanise, read_pickle
from jaxmotion.io.motion import Motion, MotionFormatError
from jaxmotion.scene.io import load_scene, save_scene

__all__ = ["HUMANISE_TRAIN_SCENES", "convert_humanise", "humanise_sources"]

HUMANISE_TRAIN_SCENES = 600  # ScanNet scenes numbered below this are HUMANISE's training set
_SCENE_ID = re.compile(r"scene\d{4}_\d{2}")


def humanise_sources(src) -> tuple[str, list[Path]]:
    """(layout, source files) of a HUMANISE copy: ``"original"`` and its ``anno.pkl`` files, or
    ``"reformatted"`` and its ``motions/*.pkl``. MotionFormatError when it is neither."""
    src = Path(src)
    if not src.is_dir():
        raise MotionFormatError(f"{src}: no such folder; give your HUMANISE folder (the one "
                                "holding align_data_release/ and pure_motion/, or motions/ and "
                                "annotation.csv)")
    release = src if src.name == "align_data_release" else src / "align_data_release"
    if release.is_dir():
        files = sorted(p for p in release.glob("*/*/anno.pkl") if p.is_file())
        if not files:
            raise MotionFormatError(f"{release}: no <action>/<scene>_<id>/anno.pkl files")
        return "original", files
    if (src / "motions").is_dir():
        if not (src / "annotation.csv").is_file():
            raise MotionFormatError(f"{src}: motions/ without annotation.csv; the re-formatted "
                                    "release keeps the scene, action and text there: put it "
                                    "next to motions/")
        files = sorted(p for p in (src / "motions").glob("*.pkl") if p.is_file())
        if not files:
            raise MotionFormatError(f"{src / 'motions'}: no .pkl motion files")
        return "reformatted", files
    raise MotionFormatError(f"{src}: not a HUMANISE folder (no align_data_release/, no motions/); "
                            "give the folder holding align_data_release/ and pure_motion/, or "
                            "motions/ and annotation.csv")


def _scan_folder(scannet: Path, scene_id: str, where: str) -> Path:
    for folder in (scannet / "scans" / scene_id, scannet / scene_id):
        if folder.is_dir():
            return folder
    raise SceneError(f"{where}: its scene {scene_id} is not in --scannet {scannet} (looked for "
                     f"{scannet / 'scans' / scene_id} and {scannet / scene_id}); download that "
                     "scan (_vh_clean_2.ply, .aggregation.json, _vh_clean_2.0.010000.segs.json, "
                     ".txt) into it")


class _Rooms:
    """The scenes of a conversion: written once each (atomically), remembered per run."""

    def __init__(self, root: Path, scannet: Path, points: int):
        self.root, self.scannet, self.points = root, scannet, points
        self.known: dict[str, tuple[list[float], set[int]]] = {}
        self.failed: dict[str, str] = {}  # a scan that cannot be read fails once per run

    def objects(self, scene_id: str, translation: list[float], where: str) -> set[int]:
        """The object ids of ``scene_id``, its file written with ``translation`` if new."""
        record = self.root / ".convert" / "scenes" / f"{scene_id}.json"
        if scene_id not in self.known and record.is_file() and (
                self.root / "scenes" / f"{scene_id}.npz").is_file():
            saved = json.loads(record.read_text())
            self.known[scene_id] = (saved["scene_translation"], set(saved["object_ids"]))
        if scene_id in self.failed:
            raise SceneError(self.failed[scene_id])
        if scene_id not in self.known:
            try:
                self.known[scene_id] = self._write(scene_id, translation, where)
            except SceneError as e:
                self.failed[scene_id] = str(e)
                raise
        saved_t, ids = self.known[scene_id]
        if not np.allclose(saved_t, translation, atol=1e-6):
            raise MotionFormatError(f"{where}: scene_translation {translation} differs from "
                                    f"{saved_t}, which scenes/{scene_id}.npz was written with; "
                                    "HUMANISE uses one translation per scene: check the file")
        return ids

    def _write(self, scene_id: str, translation: list[float], where: str):
        record = self.root / ".convert" / "scenes" / f"{scene_id}.json"
        scan = _scan_folder(self.scannet, scene_id, where)
        try:
            scene = load_scene(scan, num_points=self.points, seed=0).translated(translation)
        except SceneError as e:
            raise SceneError(f"{where}: its scene {scene_id}: {e}") from None
        save_scene(dataclasses.replace(scene, name=scene_id),
                   self.root / "scenes" / f"{scene_id}.npz")
        ids = {o["id"] for o in scene.objects}
        write_json_atomic(record, {"scene_translation": translation, "scan": str(scan),
                                   "object_ids": sorted(ids)})
        return translation, ids


def _annotations(layout: str, path: Path, trust: bool) -> list[Motion]:
    if layout == "reformatted":
        return [load_humanise(path, trust_pickle=trust)]
    annos = read_pickle(path, trust_pickle=trust)
    count = len(annos) if isinstance(annos, list) else 1
    return [load_humanise(path, index=i, trust_pickle=trust) for i in range(count)]


def _fields(layout: str, path: Path, motion: Motion) -> tuple[str, str, int, list[float]]:
    """(scene id, action, target id, scene translation) of one annotation."""
    info, where = motion.info, motion.source
    scene_id = str(info.get("scene") or info.get("scene_id") or "").strip()
    if not scene_id and layout == "original" and (m := _SCENE_ID.search(path.parent.name)):
        scene_id = m.group(0)
    if not re.fullmatch(r"[A-Za-z0-9_.-]+", scene_id) or scene_id.startswith("."):
        raise MotionFormatError(f"{where}: no usable scene id (anno 'scene' / csv 'scene_id', "
                                f"got {scene_id!r}); it names the ScanNet scan, e.g. scene0000_00")
    raw = path.parents[1].name if layout == "original" else str(info.get("action", ""))
    action = re.sub(r"[\s-]+", "_", raw.strip().lower())
    if action not in ACTIONS:
        raise MotionFormatError(f"{where}: action {raw!r} is none of HUMANISE's "
                                f"{', '.join(ACTIONS)}; check the folder name / action column")
    try:
        target = int(info["object_id"])
        translation = [float(v) for v in info["scene_translation"]]
    except (KeyError, TypeError, ValueError) as e:
        raise MotionFormatError(f"{where}: needs an integer object_id and a scene_translation "
                                f"of 3 numbers ({type(e).__name__}: {e})") from None
    return scene_id, action, target, translation


def _convert_source(root, rooms, settings, layout, key, path) -> dict:
    record = {"source": str(path), "files": [], "dropped_short": 0, "trimmed": 0}
    fixed = settings["split"]
    for n, motion in enumerate(_annotations(layout, path, settings["trust_pickle"])):
        scene_id, action, target, translation = _fields(layout, path, motion)
        ids = rooms.objects(scene_id, translation, motion.source)
        if target not in ids:
            raise MotionFormatError(
                f"{motion.source}: object_id {target} is not an object of {scene_id} (its "
                f"objects: {sorted(ids)}); the aggregation in --scannet must be ScanNet's own")
        t, cap = motion.num_frames, settings["max_frames"]
        if t < settings["min_frames"]:
            record["dropped_short"] += 1
            continue
        if t > cap:
            motion = motion.frames(0, cap) if action == "stand_up" else motion.frames(t - cap, t)
            record["trimmed"] += 1
        if fixed == "auto" and not _SCENE_ID.fullmatch(scene_id):
            raise MotionFormatError(f"{motion.source}: scene id {scene_id!r} is not a ScanNet id "
                                    "(sceneNNNN_NN), so HUMANISE's split cannot place it; give "
                                    "--split train|val|test")
        split = fixed if fixed != "auto" else (
            "train" if int(scene_id[5:9]) < HUMANISE_TRAIN_SCENES else "test")
        name = f"{key}_{n:03d}.npz"
        save_sample(root / "samples" / split / name, {
            "text": motion.texts[0] if motion.texts else "", "action": action,
            "scene_id": scene_id, "target_id": target, "joints": motion.joints,
            "fps": motion.fps, "mask": np.ones(motion.num_frames, bool),
            "global_orient": motion.global_orient, "body_pose": motion.body_pose,
            "transl": motion.transl, "betas": motion.betas})
        record["files"].append(f"samples/{split}/{name}")
    return record


def convert_humanise(src, out, *, scannet=None, points: int = 50_000, max_frames: int = 120,
                     min_frames: int = 30, split: str = "auto", trust_pickle: bool = False,
                     progress: bool = True, stats: bool = True) -> dict:
    """Convert a HUMANISE copy into a sample-schema dataset in ``out`` (or resume one).

    Args:
      src: the HUMANISE folder (see :func:`humanise_sources`); out: the dataset folder.
      scannet: the ScanNet folder holding ``scans/<scene_id>/`` (required: the motions are
        placed in these rooms).
      points: surface points per scene; max_frames, min_frames: see the module docstring.
      split: ``"auto"`` (HUMANISE's split by ScanNet id) or one of train / val / test.
      trust_pickle: unpickle anything (runs the files' code; see :mod:`jaxmotion.io.humanise`).
      progress: show a progress bar; stats: write ``stats.npz`` at the end.
    Returns:
      the manifest (also written to ``out/manifest.json``).
    Raises:
      ValueError (MotionFormatError, DatasetError, SceneError) for unusable options, ``src``,
      ``scannet`` or ``out``; a bad source is reported in the manifest instead.
    """
    from tqdm.auto import tqdm

    if scannet is None:
        raise DatasetError("HUMANISE motions are placed in ScanNet rooms: give --scannet DIR "
                           "(scannet=), your ScanNet folder holding scans/<scene_id>/ with each "
                           "scan's _vh_clean_2.ply, .aggregation.json, "
                           "_vh_clean_2.0.010000.segs.json and .txt")
    scannet = Path(scannet)
    if not scannet.is_dir():
        raise DatasetError(f"--scannet {scannet}: no such folder; give the ScanNet folder "
                           "holding scans/<scene_id>/")
    if split not in ("auto", *SPLITS):
        raise ValueError(f"split must be 'auto' or one of {SPLITS}, got {split!r}")
    if not (1 <= min_frames <= max_frames and points > 0):
        raise ValueError(f"need 1 <= min_frames ({min_frames}) <= max_frames ({max_frames}) "
                         f"and points > 0 ({points})")
    root, src = Path(out), Path(src)
    layout, files = humanise_sources(src)
    settings = {"kind": "humanise", "points": int(points), "max_frames": int(max_frames),
                "min_frames": int(min_frames), "split": split, "trust_pickle": bool(trust_pickle),
                "scannet": str(scannet.resolve())}
    check_out_folder(root, settings)
    write_json_atomic(root / ".convert" / "settings.json", settings)
    (root / "scenes").mkdir(parents=True, exist_ok=True)
    rooms = _Rooms(root, scannet, int(points))
    base = files[0].parents[2] if layout == "original" else files[0].parent
    t0 = time.perf_counter()
    records, errors, converted = [], [], 0
    for path in tqdm(files, desc="convert humanise", unit="file", disable=not progress):
        key = source_key(path.relative_to(base).as_posix())
        record = finished_source(root, key)
        if record is None:
            try:
                record = _convert_source(root, rooms, settings, layout, key, path)
            except (MotionFormatError, SceneError) as e:
                errors.append({"source": str(path), "error": str(e)})
                continue
            write_json_atomic(root / ".convert" / "done" / f"{key}.json", record)
            converted += 1
        records.append(record)
    counts = {sp: len(list((root / "samples" / sp).glob("*.npz"))) for sp in SPLITS}
    scenes = sorted(p.stem for p in (root / "scenes").glob("*.npz"))
    manifest = {
        "format_version": FORMAT_VERSION,
        "jaxmotion_version": __version__,
        "kind": "converted from humanise (the user's own copy of licensed data: do not share)",
        "source": str(src),
        "convert_settings": settings,
        "scenes": {"total": len(scenes), "ids": scenes},
        "samples": counts,
        "sources": {"total": len(files), "done": len(records), "layout": layout,
                    "converted_this_run": converted, "failed": len(errors)},
        "errors": errors[:50],
        "dropped_clips": {"shorter_than_min_frames": sum(r["dropped_short"] for r in records)},
        "trimmed_to_max_frames": sum(r["trimmed"] for r in records),
        "rules": {
            "action": "the HUMANISE action folder / action column",
            "text": "the HUMANISE utterance",
            "target": "the annotation's object_id (a ScanNet objectId of the scene)",
            "smplx": "HUMANISE's parameters (first 10 betas)",
            "scene": "the axis-aligned ScanNet scan moved by HUMANISE's scene_translation",
            "split": ("HUMANISE's: ScanNet scenes below 600 train, the others test"
                      if split == "auto" else f"everything in {split}"),
        },
        "build_seconds_this_run": round(time.perf_counter() - t0, 1),
        "fps": 30.0,
    }
    write_json_atomic(root / "manifest.json", manifest)
    if stats and counts["train"]:
        from jaxmotion.data.synth import write_stats

        write_stats(root)
    return manifest
