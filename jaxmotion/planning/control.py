"""Trajectory control: a person walking along a ground path the user gives, ``xy [T, 2]``
at 30 fps in the scene frame (metres), as MotionLCM and OmniControl control the pelvis.

The path becomes a root trajectory (:func:`ground_trajectory`: the pelvis at the body's
standing height over each point, the body facing where it goes, turned smoothly, holding its
facing where it stands still) and the object-centric completion model writes the body along
it in overlapping windows (:meth:`jaxmotion.planning.story.Teller.along`), the pelvis held to
the path by inpainting. :func:`check_path` refuses a path no person walks (NaN, shorter than
two frames, faster than :data:`MAX_SPEED`, outside the room) before any model is loaded.
"""

from __future__ import annotations

import sys
import time

import numpy as np

from jaxmotion.errors import GenerateError

__all__ = ["MAX_SPEED", "check_path", "control_generation", "follow", "ground_trajectory",
           "load_path", "planned_generation"]

#: The fastest a given path may move (m/s, between two frames at 30 fps): a brisk walk's
#: ceiling; the synthetic walks move at 0.8–1.5 m/s.
MAX_SPEED = 2.5
#: Below this speed (m/s) the body keeps the facing it had (standing still, turning on the spot).
_STILL = 0.15
#: How far (m) the path may leave the room's points' box.
_MARGIN = 0.25


def load_path(path) -> np.ndarray:
    """A ground path ``[T, 2]`` from a ``.npy`` file, or a ``.csv`` / ``.txt`` file of two
    columns (x, y per line); :class:`GenerateError` naming the fix."""
    from pathlib import Path

    p = Path(path)
    if not p.is_file():
        raise GenerateError(f"--trajectory {path}: no such file; give a .npy (or .csv) array "
                            "[T, 2] of pelvis x, y per frame at 30 fps, metres, scene frame")
    try:
        xy = (np.load(p, allow_pickle=False) if p.suffix.lower() == ".npy"
              else np.loadtxt(p, delimiter="," if p.suffix.lower() == ".csv" else None,
                              ndmin=2))
    except (ValueError, OSError) as e:
        raise GenerateError(f"--trajectory {path}: cannot read it ({e}); give a .npy array or "
                            "a .csv of x, y lines") from e
    return np.asarray(xy)


def check_path(xy, scene=None, fps: float = 30.0) -> np.ndarray:
    """``xy`` as float64 ``[T, 2]`` after checking it is a path a person walks (see module
    docstring); :class:`GenerateError` naming the problem and the fix."""
    try:
        xy = np.asarray(xy, np.float64)
    except (TypeError, ValueError) as e:
        raise GenerateError(f"the trajectory is not an array of numbers: {e}") from e
    if xy.ndim != 2 or xy.shape[1] != 2:
        raise GenerateError(f"the trajectory must be [T, 2] (pelvis x, y per frame at {fps:g} "
                            f"fps, metres), got shape {xy.shape}")
    if len(xy) < 2:
        raise GenerateError("the trajectory needs at least 2 frames")
    if not np.all(np.isfinite(xy)):
        bad = int(np.flatnonzero(~np.all(np.isfinite(xy), axis=1))[0])
        raise GenerateError(f"the trajectory has a NaN or infinite value at frame {bad}")
    speed = np.linalg.norm(np.diff(xy, axis=0), axis=1) * fps
    if speed.max() > MAX_SPEED:
        i = int(np.argmax(speed))
        raise GenerateError(
            f"the trajectory moves {speed[i]:.2f} m/s between frames {i} and {i + 1}: a walk "
            f"stays under {MAX_SPEED} m/s; give one point per frame at {fps:g} fps (resample "
            "a sparse path), in metres")
    if scene is not None and len(scene.xyz):
        lo = scene.xyz[:, :2].min(0) - _MARGIN
        hi = scene.xyz[:, :2].max(0) + _MARGIN
        out = np.flatnonzero(np.any((xy < lo) | (xy > hi), axis=1))
        if len(out):
            raise GenerateError(
                f"the trajectory leaves the room at frame {int(out[0])} ({xy[out[0]].round(2)}"
                f" outside x {lo[0] + _MARGIN:.2f}..{hi[0] - _MARGIN:.2f}, y "
                f"{lo[1] + _MARGIN:.2f}..{hi[1] - _MARGIN:.2f}): give it in the scene's frame, "
                "metres")
    return xy


def ground_trajectory(xy, *, height: float, fps: float = 30.0,
                      smooth_time: float = 0.3) -> np.ndarray:
    """Trajectory features ``[T, 9]`` of an upright body walking along ``xy [T, 2]``: the
    pelvis at ``height`` over each point, facing the direction of travel (averaged over
    ``smooth_time`` seconds), keeping its last facing while it moves slower than 0.15 m/s
    (the first moving frame's facing before it first moves; +x if it never does), and
    turning within its steps as a walking pelvis does
    (:func:`jaxmotion.planning.trajectory.walking_rhythm`: a few degrees of roll and twist)."""
    from jaxmotion.planning.trajectory import trajectory_features, walking_rhythm

    xy = np.asarray(xy, np.float64)
    vel = np.gradient(xy, axis=0) * fps
    moving = np.linalg.norm(vel, axis=1) > _STILL
    angle = np.arctan2(vel[:, 1], vel[:, 0])
    if moving.any():
        idx = np.where(moving, np.arange(len(xy)), -1)
        idx = np.maximum.accumulate(idx)  # last moving frame so far
        idx = np.where(idx < 0, int(np.flatnonzero(moving)[0]), idx)
        heading = np.unwrap(angle[idx])
    else:
        heading = np.zeros(len(xy))
    k = max(1, round(smooth_time * fps / 2))
    heading = np.convolve(np.pad(heading, k, mode="edge"), np.ones(2 * k + 1) / (2 * k + 1),
                          "valid")
    pelvis = np.concatenate([xy, np.full((len(xy), 1), float(height))], -1)
    return trajectory_features(pelvis, heading, *walking_rhythm(xy, fps))


def follow(scene, xy, text: str = "walk along the path", *, seed: int = 0, files=None,
           steps: int = 20, guidance: float = 1.0, object_id: int | None = None,
           progress: bool = False):
    """A motion whose pelvis follows ``xy [T, 2]`` (30 fps, scene frame) in ``scene``, as a
    :class:`~jaxmotion.planning.story.Story` (one walk segment, ``paths = [xy]``).

    Args:
      text: the instruction the completion model reads (the body's manner).
      seed: every random choice (the same seed gives the same motion).
      files: ``(trajectory, completion)`` weights, or a folder holding both (default: shipped).
      steps, guidance: DDIM steps and text guidance of the completion model.
      object_id: the object the walk heads for (its target sensor); None: the object nearest
        the path's end.
    """
    from jaxmotion.constants import SCENE_FPS
    from jaxmotion.diffusion.samplers import SamplerSpec
    from jaxmotion.pipelines.checkpoints import resolve_object_checkpoints
    from jaxmotion.planning.story import Story, Teller, head_for, story_arrays
    from jaxmotion.scene.demo import load_scene_arg

    scene = load_scene_arg(scene)
    xy = check_path(xy, scene, SCENE_FPS)
    ids = {int(o["id"]) for o in scene.objects}
    if object_id is not None and int(object_id) not in ids:
        raise GenerateError(f"object {object_id} is not in the scene; its ids are "
                            f"{sorted(ids)} (jaxmotion scene info)")
    oid = head_for(scene, xy[-1]) if object_id is None else int(object_id)
    teller = Teller(scene, resolve_object_checkpoints(files), seed,
                     SamplerSpec("ddim", steps, guidance=guidance))
    if progress:
        print(f"  following a {len(xy) / SCENE_FPS:.1f} s path", file=sys.stderr, flush=True)
    full = ground_trajectory(xy, height=teller.stand, fps=SCENE_FPS)
    motion = teller.along(full, 0, oid, teller.embed(text))
    joints, _ = story_arrays(motion)
    return Story(motion, joints, SCENE_FPS, [{"action": "walk", "object": oid, "first": 0,
                                               "last": len(motion) - 1}],
                 [xy.astype(np.float32)])


def control_generation(scene, text: str, trajectory, opts, progress: bool = False):
    """``jaxmotion.generate(scene, text, trajectory=xy)``: :func:`follow` as a
    :class:`~jaxmotion.result.Generation` (:func:`~jaxmotion.planning.story.story_result`);
    ``trajectory`` is ``[T, 2]`` or a file :func:`load_path` reads. ``opts`` gives ``seed``,
    ``steps``, the motion stage's ``guidance``, ``object_id`` and ``object_checkpoints``."""
    from jaxmotion.planning.story import story_result
    from jaxmotion.scene.demo import room_for
    from jaxmotion.text.condition import check_text

    t0 = time.perf_counter()
    text = check_text(text)
    room = room_for(scene, opts)
    if isinstance(trajectory, (str, bytes)) or hasattr(trajectory, "__fspath__"):
        trajectory = load_path(trajectory)
    story = follow(room, trajectory, text, seed=opts.seed, files=opts.object_checkpoints,
                   steps=opts.steps, guidance=opts.guidance[1], object_id=opts.object_id,
                   progress=progress)
    oid = story.segments[0]["object"]
    return story_result(story, room, text, opts, {"trajectory": time.perf_counter() - t0},
                        pipeline="trajectory", grounding="trajectory",
                        target_id=None if oid < 0 else oid, object_id=opts.object_id)


def planned_generation(scene, text: str, opts, progress: bool = False, *, plan=None,
                       trajectory=None, meanwhile=None):
    """``generate`` with a ``plan`` (:func:`~jaxmotion.planning.story.story_generation`), a
    ``trajectory`` (:func:`control_generation`), or a ``text`` that tells a story of several
    steps (:func:`~jaxmotion.planning.steps.plan_from_text`); None when it is none of those
    (one instruction: ``generate`` makes one clip). ``meanwhile`` (no arguments) is called
    once the request is known to be one of those and its options fit, before any work."""
    import warnings

    from jaxmotion.planning.steps import is_story

    if plan is not None and trajectory is not None:
        raise GenerateError("give a plan (a story) or a trajectory (a path to follow), not both")
    if plan is None and trajectory is None and not is_story(text):
        return None
    if opts.pipeline == "cvae":
        raise GenerateError("the cvae pipeline samples one instruction in one place; a story or "
                            "a path to follow needs the other pipelines: leave out pipeline=cvae")
    if opts.samples > 1:
        warnings.warn(f"a story or a followed path is one motion: samples={opts.samples} is "
                      "not used (run again with other seeds for others)", UserWarning,
                      stacklevel=3)
    if meanwhile is not None:
        meanwhile()
    if trajectory is not None:
        return control_generation(scene, text, trajectory, opts, progress)
    from jaxmotion.planning.story import story_generation

    if plan is not None:
        return story_generation(scene, plan, opts, progress)
    from jaxmotion._jax_setup import enable_compilation_cache
    from jaxmotion.planning.steps import plan_from_text
    from jaxmotion.scene.demo import room_for
    from jaxmotion.text.condition import check_text

    text = check_text(text)
    if opts.object_id is not None:
        raise GenerateError("the text tells several steps, each naming its own object: leave "
                            "out --object (object_id), or name the objects in the text by id")
    room = room_for(scene, opts)
    steps, notes, warns = plan_from_text(room, text,
                                         enable_compilation_cache() / "text-embeddings")
    if progress:
        for note in notes:
            print(f"  {note}", file=sys.stderr, flush=True)
    for warn in warns:
        warnings.warn(warn, UserWarning, stacklevel=3)
    return story_generation(room, steps, opts, progress, text=text)
