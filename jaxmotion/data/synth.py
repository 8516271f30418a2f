"""Build the synthetic HUMANISE-like dataset: rooms, instructions and motions.

``jaxmotion synth --out DIR --scenes N --per-scene K --seed S --workers W [--motions SRC]``

For scene ``i`` a room is drawn from ``SeedSequence([seed, i])``, sampled to a
ScanNet-like point cloud and saved as ``scenes/<scene_id>.npz``; then ``K``
(instruction, motion) pairs are drawn, each from ``default_rng([seed, i, k,
attempt])`` and retried with the next attempt when the kinematic character
cannot perform it (no path, seat unreachable). The split is **by scene**: a
seeded permutation of the scene indices gives 80 % train, 10 % val, 10 % test.

``--split-scenes S`` (``SynthSettings.split_scenes``) grows the training set
without touching val and test: the permutation runs over the first ``S`` scenes
only and every scene from ``S`` on is a training scene. Scene ``i`` is the same
room with the same samples whatever ``scenes`` is, so ``--scenes 5000
--split-scenes 2000`` holds the 2000-scene build (same val / test files) plus
3000 training rooms; run on the folder of that build, it adds them in place.

Everything is deterministic for a seed (whatever the number of workers), every
file is written atomically, and a scene counts as done when its scene file and
all its sample files exist, so an interrupted build resumes where it stopped by
running the same command again. ``manifest.json`` (counts, seed, settings,
version) is written at the end; ``stats.npz`` (normalisation statistics of the
training crops) after it.

``--motions SRC`` (``build_dataset(..., motions=SRC)``) takes real motions for the
samples where they fit, the way HUMANISE placed AMASS clips in scanned rooms: ``SRC`` is
read into a clip library (:mod:`jaxmotion.data.motion_library`, cached in
``DIR/.motions/``) and, for each drawn instruction, :func:`~jaxmotion.data.clip_placement.
place_clip` tries clips of its action, in an order drawn from
``default_rng([seed, i, k, attempt, CLIP_STREAM])``, until one fits the room; when none
does, the procedural character makes the sample exactly as a build without ``--motions``
would (same generator). Each sample's origin is recorded in
``DIR/provenance/<split>/<sample_id>.json`` (written before the sample; the clip's source
file, frames, rotation and shift), the manifest counts samples from clips and procedural
fallbacks, and ``settings.motions`` holds the library's content digest, so builds with
different libraries are never mixed in one folder. Without ``--motions`` nothing of this
exists and the output is unchanged.

``--phrasing rich`` (``SynthSettings.phrasing``) draws the instructions from the rich
phrasing space (``sample_task(..., phrasing="rich")``,
:func:`jaxmotion.scene.instructions.sample_rich_instruction`): the same rooms, and the same
kind of targets, with far more verb phrases, relation phrasings and object words. Without it
the texts are the default grammar's, byte for byte the ones the shipped checkpoints were
trained on; the manifest records ``phrasing`` only when it is not ``"default"``.
"""

from __future__ import annotations

import dataclasses
import functools
import json
import multiprocessing as mp
import time
from collections import Counter
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from jaxmotion._version import __version__
from jaxmotion.data.format import DatasetError, load_manifest, save_sample, write_json_atomic

__all__ = [
    "SynthSettings", "build_dataset", "render_dataset_previews", "scene_id", "split_of_scenes",
    "write_stats",
]

FORMAT_VERSION = 1
_MAX_ATTEMPTS = 30
CLIP_STREAM = 0x4D07  # the clip-choice generator's extra seed word (see the module docstring)


@dataclass(frozen=True)
class SynthSettings:
    """What defines a synthetic dataset (two builds with equal settings are identical)."""

    scenes: int
    per_scene: int
    seed: int = 0
    points_per_scene: int = 50_000
    train_fraction: float = 0.8
    val_fraction: float = 0.1
    split_scenes: int | None = None
    motions: str | None = None  # the motion library's digest (--motions), None: procedural
    phrasing: str = "default"  # instruction phrasing (--phrasing): "default" or "rich"

    def __post_init__(self):
        from jaxmotion.scene.instructions import PHRASINGS

        if self.phrasing not in PHRASINGS:
            raise ValueError(f"phrasing={self.phrasing!r}: choose from {PHRASINGS}")
        if self.split_scenes is not None and not 3 <= self.split_scenes <= self.scenes:
            raise ValueError(
                f"split_scenes={self.split_scenes} must be between 3 and scenes={self.scenes}: "
                "the first split_scenes rooms are split into train / val / test, the rest train")

    def split_labels(self) -> list[str]:
        """The split of every scene index (see the module docstring)."""
        n = self.scenes if self.split_scenes is None else self.split_scenes
        labels = split_of_scenes(n, self.seed, self.train_fraction, self.val_fraction)
        return labels + ["train"] * (self.scenes - n)


def _settings_dict(settings: SynthSettings) -> dict:
    """What manifests record: the fields, ``split_scenes`` and ``motions`` only when set and
    ``phrasing`` only when not ``"default"`` (so manifests written before they existed
    compare equal)."""
    d = asdict(settings)
    for key in ("split_scenes", "motions"):
        if d[key] is None:
            del d[key]
    if d["phrasing"] == "default":
        del d["phrasing"]
    return d


def _grows(old: dict, new: SynthSettings) -> bool:
    """Whether ``new`` only adds training rooms to a build with settings ``old``: same seed,
    points and fractions, and its ``split_scenes`` equal to the old split's scene count."""
    old_split = old.get("split_scenes") or old.get("scenes")
    same = {k: v for k, v in old.items() if k not in ("scenes", "split_scenes")} == {
        k: v for k, v in _settings_dict(new).items() if k not in ("scenes", "split_scenes")}
    return same and new.split_scenes == old_split and new.scenes >= old.get("scenes", 0)


def scene_id(i: int) -> str:
    return f"scene_{i:05d}"


def split_of_scenes(n: int, seed: int, train_fraction=0.8, val_fraction=0.1) -> list[str]:
    """Split label per scene index: a seeded permutation cut into train / val / test.

    With 3 or more scenes every split gets at least one.
    """
    order = np.random.default_rng([seed, 0x5B117]).permutation(n)
    n_val = int(round(val_fraction * n))
    n_test = n - int(round(train_fraction * n)) - n_val
    if n >= 3:
        n_val, n_test = max(n_val, 1), max(n_test, 1)
    n_train = n - n_val - n_test
    labels = [""] * n
    for rank, i in enumerate(order):
        labels[i] = "train" if rank < n_train else "val" if rank < n_train + n_val else "test"
    return labels


def _sample_paths(root: Path, split: str, sid: str, k: int) -> list[Path]:
    return [root / "samples" / split / f"{sid}_{j:02d}.npz" for j in range(k)]


def _provenance_path(root: Path, sample: Path) -> Path:
    return root / "provenance" / sample.parent.name / f"{sample.stem}.json"


@functools.lru_cache(maxsize=2)
def _library(root: str, digest: str):
    from jaxmotion.data.motion_library import read_library

    return read_library(Path(root) / ".motions" / f"{digest.split(':')[-1]}.npz")


def _from_library(root: Path, s: SynthSettings, room, info, rng, path: Path) -> dict | None:
    """Sample arrays of a placed library clip (its provenance written), or None."""
    from jaxmotion.data.clip_placement import place_clip

    lib = _library(str(root), s.motions)
    p = place_clip(lib.clips, info["action"], room.floor_rects, room.objects,
                   info["target_id"], rng)
    if p is None:
        write_json_atomic(_provenance_path(root, path), {"source": "procedural"})
        return None
    c = p.clip
    write_json_atomic(_provenance_path(root, path), {
        "source": "library", "clip": c.source, "frames": [c.start, c.stop], "label": c.label,
        "smplx_fitted": c.fitted, "angle": round(p.angle, 9),
        "shift": [round(float(v), 9) for v in p.shift]})
    return {"joints": p.joints, "transl": p.transl, "global_orient": p.global_orient,
            "body_pose": p.body_pose, "betas": p.betas, "fps": 30.0}


def _scene_done(root: Path, split: str, sid: str, k: int) -> bool:
    return (root / "scenes" / f"{sid}.npz").is_file() and all(
        p.is_file() for p in _sample_paths(root, split, sid, k)
    )


def _build_scene(job) -> dict:
    """Worker: one room and its K samples. Returns per-scene counts."""
    from jaxmotion.motion import MotionError, synthesize
    from jaxmotion.scene import save_scene
    from jaxmotion.scene.instructions import NoUniqueReference, sample_task
    from jaxmotion.scene.rooms import room_to_scene, sample_room

    root, split, i, s = job
    root, s = Path(root), SynthSettings(**s)
    sid = scene_id(i)
    if _scene_done(root, split, sid, s.per_scene):
        return {"scene": sid, "skipped": True, "actions": {}, "failures": 0}
    room = sample_room(np.random.default_rng(np.random.SeedSequence([s.seed, i])))
    scene_path = root / "scenes" / f"{sid}.npz"
    if not scene_path.is_file():
        scene = room_to_scene(room, s.points_per_scene, np.random.default_rng([s.seed, i, 1 << 20]))
        save_scene(dataclasses.replace(scene, name=sid), scene_path)
    actions, failures, from_clips = Counter(), 0, 0
    for k, path in enumerate(_sample_paths(root, split, sid, s.per_scene)):
        if path.is_file():
            continue
        for attempt in range(_MAX_ATTEMPTS):
            rng = np.random.default_rng([s.seed, i, k, attempt])
            try:
                text, info = sample_task(room, rng, phrasing=s.phrasing)
                clip = None if s.motions is None else _from_library(
                    root, s, room, info, np.random.default_rng([s.seed, i, k, attempt,
                                                                CLIP_STREAM]), path)
                if clip is None:
                    m = synthesize(info["action"], room.floor_rects, room.objects,
                                   info["target_id"], rng)
            except (MotionError, NoUniqueReference):
                failures += 1
                continue
            break
        else:
            raise RuntimeError(f"{sid}: no motion could be made for sample {k} in {_MAX_ATTEMPTS} tries")
        if clip is None:
            clip = {"joints": m.joints, "transl": m.transl, "global_orient": m.global_orient,
                    "body_pose": m.body_pose, "betas": m.betas, "fps": float(m.fps)}
        else:
            from_clips += 1
        t = clip["joints"].shape[0]
        save_sample(path, dict(
            text=text, action=info["action"], scene_id=sid, target_id=info["target_id"],
            mask=np.ones(t, bool), **clip,
        ))  # fmt: skip
        actions[info["action"]] += 1
    return {"scene": sid, "skipped": False, "actions": dict(actions), "failures": failures,
            "from_clips": from_clips}


def _check_existing(root: Path, settings: SynthSettings):
    if not (root / "manifest.json").is_file():
        partial = root / ".synth_settings.json"
        if partial.is_file():
            old = json.loads(partial.read_text())
            if old != _settings_dict(settings):
                raise DatasetError(
                    f"{root} holds an unfinished build with other settings ({old}); "
                    "use the same settings to resume, or another --out"
                )
        return
    old = load_manifest(root).get("settings")
    if old != _settings_dict(settings) and not _grows(old or {}, settings):
        raise DatasetError(
            f"{root} already holds a dataset built with {old}; choose another --out or the same "
            "settings (or, to add training rooms, more --scenes with --split-scenes equal to its "
            "scene count)"
        )


def _count_sources(root: Path) -> dict:
    """Samples on disk by origin (their provenance records): library clips, procedural."""
    n = Counter()
    for f in (root / "provenance").glob("*/*.json"):
        if (root / "samples" / f.parent.name / f"{f.stem}.npz").is_file():
            n[json.loads(f.read_text())["source"]] += 1
    return {"library_clips": n["library"], "procedural_fallback": n["procedural"]}


def build_dataset(out, settings: SynthSettings, *, workers: int = 1, progress: bool = True,
                  stats: bool = True, motions=None, motions_fit_iters: int = 200) -> dict:
    """Build (or resume) a dataset in ``out``; returns the manifest dict.

    ``motions``: a folder of real motions to use where they fit (see the module docstring
    and :mod:`jaxmotion.data.motion_library`); ``motions_fit_iters``: SMPL-X fitting
    iterations for its joint-only files. Sets ``settings.motions`` to the library digest.
    """
    from tqdm.auto import tqdm

    if settings.scenes < 1 or settings.per_scene < 1:
        raise ValueError("--scenes and --per-scene must be at least 1")
    root = Path(out)
    library = None
    if motions is not None:  # check the folder before any work (and any folder is made)
        from jaxmotion.data.motion_library import library_digest, load_library

        digest = library_digest(motions, motions_fit_iters)
        if settings.motions not in (None, digest):
            raise DatasetError(f"settings.motions {settings.motions} is not the digest of "
                               f"--motions {motions} ({digest})")
        settings = dataclasses.replace(settings, motions=digest)
        _check_existing(root, settings)
        library = load_library(motions, cache_dir=root / ".motions", digest=digest,
                               fit_iters=motions_fit_iters, progress=progress)
    elif settings.motions is not None:
        raise ValueError("settings.motions is set: give the motion folder as motions=")
    (root / "scenes").mkdir(parents=True, exist_ok=True)
    _check_existing(root, settings)
    write_json_atomic(root / ".synth_settings.json", _settings_dict(settings))
    splits = settings.split_labels()
    jobs = [(str(root), splits[i], i, asdict(settings)) for i in range(settings.scenes)]
    t0 = time.perf_counter()
    results = []
    bar = tqdm(total=len(jobs), desc="synth scenes", unit="scene", disable=not progress)
    try:
        if workers <= 1:
            for job in jobs:
                results.append(_build_scene(job))
                bar.update()
        else:
            # spawn: safe with JAX and threads in the parent
            with mp.get_context("spawn").Pool(workers) as pool:
                for r in pool.imap_unordered(_build_scene, jobs, chunksize=1):
                    results.append(r)
                    bar.update()
    finally:
        bar.close()
    elapsed = time.perf_counter() - t0
    counts = {sp: len(list((root / "samples" / sp).glob("*.npz"))) for sp in ("train", "val", "test")}
    actions = Counter()
    for r in results:
        actions.update(r["actions"])
    manifest = {
        "format_version": FORMAT_VERSION,
        "jaxmotion_version": __version__,
        "kind": "synthetic (jaxmotion built-in world; not HUMANISE)" if library is None else
                "synthetic rooms (jaxmotion built-in world; not HUMANISE) with real motion clips "
                "where they fit (the user's own motions: mind their licence)",
        "settings": _settings_dict(settings),
        "seed": settings.seed,
        "scenes": {sp: splits.count(sp) for sp in ("train", "val", "test")},
        "samples": counts,
        "actions_built_this_run": dict(actions),
        "retries_this_run": int(sum(r["failures"] for r in results)),
        **({} if library is None else {
            "motion_library": {**library.report, "digest": library.digest},
            "samples_by_origin": _count_sources(root),
            "samples_from_clips_this_run": int(sum(r.get("from_clips", 0) for r in results)),
        }),
        "build_seconds_this_run": round(elapsed, 1),
        "fps": 30,
    }
    write_json_atomic(root / "manifest.json", manifest)
    (root / ".synth_settings.json").unlink(missing_ok=True)
    if stats:
        write_stats(root)
    return manifest


def write_stats(root, *, num_batches: int = 16, batch_size: int = 32, seed: int = 0):
    """Compute and save ``stats.npz`` from random training crops (default crop settings)."""
    from jaxmotion.data.crop import CropSpec
    from jaxmotion.data.loader import Dataset, compute_stats, save_stats

    ds = Dataset(root, "train", CropSpec())
    st = compute_stats(ds, num_batches=num_batches, batch_size=min(batch_size, len(ds)), seed=seed)
    return save_stats(st, Path(root) / "stats.npz")


def render_dataset_previews(root, *, count: int = 4, split: str = "train") -> list[Path]:
    """Render top and perspective PNGs of the first ``count`` samples of a split.

    Files: ``DIR/preview/<sample_id>_top.png`` and ``..._persp.png``.
    """
    from jaxmotion.data.format import load_sample
    from jaxmotion.scene import load_scene
    from jaxmotion.viz import render_preview

    root = Path(root)
    files = sorted((root / "samples" / split).glob("*.npz"))[:count]
    if not files:
        raise DatasetError(f"{root / 'samples' / split}: no samples to preview")
    paths = []
    for f in files:
        s = load_sample(f)
        scene = load_scene(root / "scenes" / f"{s['scene_id']}.npz")
        paths += render_preview(
            scene.xyz, scene.rgb, s["joints"], root / "preview" / f.stem, mask=s["mask"],
            target_mask=scene.instance == s["target_id"], title=f"{s['text']}  [{s['action']}]",
        )
    return paths
