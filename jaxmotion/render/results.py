"""Rendering what ``generate`` made: a :class:`~jaxmotion.result.Generation`, a saved
``motion.npz`` or a dataset sample, in its room.

- :func:`clip_for_motion`: a :class:`~jaxmotion.render.Clip` from SMPL-X parameters, joints and
  a :class:`~jaxmotion.scene.Scene` (the mannequin skinned per frame, the target's points
  highlighted, the room's normals and object ids used);
- :func:`render_generation`: ``motion.mp4`` of a result (``jaxmotion generate`` calls it);
- :func:`load_motion`: the arrays of a saved ``motion.npz`` (``generate``'s output, K samples)
  or of a dataset sample (one motion, ``jaxmotion synth`` / ``data convert``);
- :func:`scene_for_motion`: the room a saved motion was made in: ``"demo"``, a scene file, or
  for a dataset sample its ``scenes/<scene_id>.npz`` found beside the samples.

The motions are in the scene's frame (``motion.npz``'s ``scene_rotation`` / ``scene_shift`` only
say where the models' crop was), so the room is drawn as loaded.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np

from jaxmotion.render.body import Bodies
from jaxmotion.render.frames import Clip, render_still, render_video

__all__ = ["SavedMotion", "clip_for_motion", "load_motion", "render_generation", "render_saved",
           "scene_for_motion"]

MAX_SCENE_POINTS = 100_000  # the room is drawn from at most this many points
GENERATE_VIDEO_FPS = 15.0  # generate's motion.mp4: every other frame of a 30 fps motion


@dataclasses.dataclass
class SavedMotion:
    """A motion read back: ``smplx`` (``global_orient [K,T,3]``, ``body_pose [K,T,21,3]``,
    ``transl [K,T,3]``, ``betas [K,B]``), ``joints [K,T,22,3]``, ``fps``, ``text``, the
    scene's name, the target object's id (None: none), the valid frames ``mask [T]``."""

    smplx: dict
    joints: np.ndarray
    fps: float
    text: str
    scene_name: str
    target_id: int | None
    mask: np.ndarray
    kind: str  # "generate" or "sample"


def clip_for_motion(scene, smplx: dict, joints, fps: float, *, text: str = "",
                    target_id: int | None = None, mask=None, max_points: int = MAX_SCENE_POINTS,
                    seed: int = 0, **options) -> Clip:
    """A :class:`Clip` of K motions (SMPL-X parameters and joints, ``[K, T, ...]``) in
    ``scene``; ``mask [T]`` keeps the valid frames; ``options`` go to :class:`Clip` (``size``,
    ``samples``, ``camera``, ``azimuth``, ``elevation``)."""
    from jaxmotion.export._common import random_subset

    joints = np.asarray(joints, np.float64)
    frames = slice(None) if mask is None else np.flatnonzero(np.asarray(mask, bool))
    if mask is not None and not len(frames):
        raise ValueError("the motion has no valid frame (its mask is all False)")
    bodies = Bodies.from_smplx(np.asarray(smplx["global_orient"])[:, frames],
                               np.asarray(smplx["body_pose"])[:, frames],
                               np.asarray(smplx["transl"])[:, frames], smplx.get("betas"))
    sel = random_subset(scene.num_points, max_points, seed)
    highlight = None
    if target_id is not None and target_id >= 0:
        highlight = scene.instance[sel] == int(target_id)
    return Clip(bodies, joints[:, frames], fps, scene.xyz[sel], scene.rgb[sel],
                scene_normal=scene.normal[sel], highlight=highlight,
                instance=scene.instance[sel], text=text, **options)


def render_generation(res, path, *, size=(640, 480), video_fps: float | None = GENERATE_VIDEO_FPS,
                      samples: str = "overlay", camera: str = "auto", meanwhile=None) -> Path:
    """Write ``res``'s video (``.mp4`` or ``.gif``): the fitted mannequins in the room, the
    target highlighted, the text as caption, at ``video_fps`` frames per second;
    ``meanwhile`` runs on another thread while the frames are drawn (:func:`render_video`)."""
    clip = clip_for_motion(res.scene, res.smplx, res.joints, res.fps, text=res.text,
                           target_id=res.target_id, mask=res.mask, seed=res.seed, size=size,
                           samples=samples, camera=camera)
    return render_video(path, clip, video_fps=video_fps, meanwhile=meanwhile)


def load_motion(path) -> SavedMotion:
    """Read ``generate``'s ``motion.npz`` or a dataset sample ``.npz``; ``ValueError`` naming
    what is missing for anything else."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no such file; give a motion.npz written by "
                                "'jaxmotion generate' or a dataset sample .npz")
    try:
        with np.load(path, allow_pickle=False) as d:
            data = {k: d[k] for k in d.files}
    except (OSError, ValueError) as err:
        raise ValueError(f"{path}: not a readable .npz file ({err})") from None
    need = ("global_orient", "body_pose", "transl", "joints")
    missing = [k for k in need if k not in data]
    if missing:
        raise ValueError(f"{path}: no {', '.join(missing)}: not a motion.npz of 'jaxmotion "
                         "generate' nor a dataset sample with SMPL-X parameters")
    sample = "scene_id" in data and data["joints"].ndim == 3  # a dataset sample: one motion
    add = (lambda a: np.asarray(a)[None]) if sample else np.asarray
    smplx = {k: add(data[k]).astype(np.float64) for k in ("global_orient", "transl")}
    joints = add(data["joints"]).astype(np.float64)
    k, t = joints.shape[:2]
    smplx["body_pose"] = add(data["body_pose"]).astype(np.float64).reshape(k, t, 21, 3)
    if "betas" in data:
        smplx["betas"] = add(data["betas"]).astype(np.float64).reshape(k, -1)
    for name, value in smplx.items():
        if name != "betas" and value.shape[:2] != (k, t):
            raise ValueError(f"{path}: {name} has shape {list(value.shape)}, the joints "
                             f"[{k}, {t}, 22, 3]")
    target = int(data.get("target_id", -1))
    scene_name = str(data.get("scene_id" if sample else "scene_name", ""))
    mask = np.asarray(data.get("mask", np.ones(t, bool)), bool).reshape(-1)
    return SavedMotion(smplx, joints, float(data.get("fps", 30.0)), str(data.get("text", "")),
                       scene_name, None if target < 0 else target, mask,
                       "sample" if sample else "generate")


def scene_for_motion(motion: SavedMotion, motion_path, scene=None, num_points=None):
    """The room of a saved motion: ``scene`` (``"demo"`` or a file / ScanNet folder, levelled
    and labelled as ``generate`` prepared it) when given; else the demo room for a motion made
    in it, or a dataset sample's ``scenes/<scene_id>.npz`` in a folder above the sample.
    ``ValueError`` saying to pass ``--scene`` otherwise."""
    from jaxmotion.scene import load_scene
    from jaxmotion.scene.demo import demo_scene

    if scene is not None:
        if str(scene) == "demo":
            return demo_scene()
        if not Path(scene).exists():
            raise FileNotFoundError(f"--scene {scene}: no such file or folder")
        import warnings

        from jaxmotion.scene.demo import load_scene_arg

        with warnings.catch_warnings():  # the room as generate prepared it (notes said then)
            warnings.simplefilter("ignore", UserWarning)
            return load_scene_arg(str(scene), num_points)
    if motion.kind == "generate" and motion.scene_name == "demo":
        return demo_scene()
    if motion.kind == "sample" and motion.scene_name:
        for parent in Path(motion_path).resolve().parents:
            candidate = parent / "scenes" / f"{motion.scene_name}.npz"
            if candidate.is_file():
                return load_scene(candidate)
    raise ValueError(f"which room? the motion was made in {motion.scene_name!r}; give it with "
                     "--scene (a mesh, point cloud, .npz scene, ScanNet scan folder or 'demo')")


def render_saved(motion_path, out, *, scene=None, num_points=None, size=(640, 480),
                 samples: str = "overlay", camera: str = "auto", azimuth=None, elevation=None,
                 video_fps=None, frame=None) -> Path:
    """Render a saved motion (see :func:`load_motion`) to ``out``: ``.mp4`` / ``.gif`` (every
    frame, or at ``video_fps``) or ``.png`` (``frame``; None: the last)."""
    out = Path(out)
    if out.suffix.lower() not in (".mp4", ".gif", ".png"):
        raise ValueError(f"--out {out}: give a .mp4, .gif or .png file name")
    motion = load_motion(motion_path)
    room = scene_for_motion(motion, motion_path, scene, num_points)
    extra = {} if elevation is None else {"elevation": float(elevation)}
    clip = clip_for_motion(room, motion.smplx, motion.joints, motion.fps, text=motion.text,
                           target_id=motion.target_id, mask=motion.mask, size=size,
                           samples=samples, camera=camera, azimuth=azimuth, **extra)
    if out.suffix.lower() == ".png":
        return render_still(out, clip, frame=frame)
    return render_video(out, clip, video_fps=video_fps)
