"""The result of :func:`jaxmotion.generate`: arrays in the scene's frame, and how they were made.

:meth:`Generation.save` writes the output folder (:func:`jaxmotion.export.write_generation`).
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

import numpy as np

__all__ = ["OUTPUT_FILES", "Generation"]

#: The files :meth:`Generation.save` writes (``motion.gif`` instead of the MP4 with
#: ``video="gif"``).
OUTPUT_FILES = ("motion.npz", "motion.bvh", "motion_smplx.npz", "motion.glb", "motion.mp4",
                "viewer.html")


@dataclasses.dataclass
class Generation:
    """The result of :func:`generate` (numpy arrays; K samples, T frames, N crop points).

    Attributes:
      text: the instruction (whitespace-normalised); scene: the whole room.
      joints: ``[K, T, 22, 3]`` SMPL-X body joints in the scene's frame, metres.
      fps: frames per second; mask: ``[T]`` valid frames.
      smplx: ``global_orient [K,T,3]``, ``body_pose [K,T,21,3]``, ``transl [K,T,3]``,
        ``betas [K,10]`` (axis-angle, SMPL-X conventions), or empty without fitting.
      fit_error: ``[K]`` mean joint distance (m) between the fitted body and ``joints``.
      crop_xyz ``[N,3]`` (scene frame), crop_rgb ``[N,3]`` in [0, 1]: the points the models saw.
      affordance: ``[K, N, 6]`` the ADM's maps (pelvis, feet, neck, wrists) in [0, 1] on the
        crop's points (carried from the room view for a room-view ADM).
      view_xyz ``[M,3]`` (scene frame), view_affordance ``[K, M, 6]``: a room-view ADM's input
        points and its maps on them (None for a crop-view ADM).
      rotation ``[3,3]``, shift ``[3]``: the crop frame, ``x_scene = x_crop @ rotation + shift``.
      object_id: as passed; target_id: the object the region was centred on (``object_id``, or
        the one chosen from the text; None when the region came from tiling the room).
      grounding: how the region was chosen: ``object_id``, ``scene graph`` (the text's
        relation singled the object out), ``class`` (the only object of the named class),
        ``seat at`` (the seat at the named desk / table), ``named id`` ("chair 3"),
        ``related`` / ``action`` / ``similarity`` (a stand-in for a class the room lacks,
        the only object the action takes, the class nearest the words by meaning), ``reach``
        (among several, the one with the most free floor to approach it on), ``wander`` (no
        object named: a walk to an object drawn with the seed), ``adm`` (the ADM's map chose
        among candidates) or ``adm peak`` (no candidates; the ADM's strongest tile).
      understanding: what was understood from the text, said plainly: the action, the
        target and how it was chosen, warnings
        (:class:`~jaxmotion.grounding.report.Understanding`), or None.
      excluded: ids of the objects the ADM's map was kept off (the other objects of the
        target's class, once the target was known).
      seed, steps: as passed; adm_steps: the ADM stage's DDIM steps used; guidance: the
        ``(ADM, AMDM)`` guidance scales used;
      consistency: the affordance-consistency strength used (0 = off).
      adm_candidates: ADM maps drawn per sample (the one lighting the target most kept); 1
        when the target was not known before sampling.
      motion_candidates: motions drawn per sample from its map (the one reaching the target
        kept); 1 when the target was not known.
      pipeline: the pipeline that sampled the motions, ``affordance``, ``object-centric`` or
        ``cvae`` (with ``auto``, the object-centric one when the target object was known).
      timings: seconds per stage.
      segments: a story's steps (``generate(plan=...)``): ``{"action", "object", "first",
        "last"}`` per step (frame indices, inclusive); empty for one instruction.
      paths: a story's planned walking paths ``[M, 2]`` (scene frame), in order.
    """

    text: str
    scene: Any
    joints: np.ndarray
    fps: float
    mask: np.ndarray
    smplx: dict
    fit_error: np.ndarray
    crop_xyz: np.ndarray
    crop_rgb: np.ndarray
    affordance: np.ndarray
    rotation: np.ndarray
    shift: np.ndarray
    object_id: int | None
    target_id: int | None
    seed: int
    steps: int
    timings: dict
    guidance: tuple[float, float] = (1.0, 1.0)
    consistency: float = 0.0
    view_xyz: np.ndarray | None = None
    view_affordance: np.ndarray | None = None
    grounding: str = ""
    excluded: tuple[int, ...] = ()
    adm_candidates: int = 1
    adm_steps: int = 0
    motion_candidates: int = 1
    understanding: Any = None
    pipeline: str = "affordance"
    segments: tuple = ()
    paths: tuple = ()

    @property
    def num_samples(self) -> int:
        return self.joints.shape[0]

    def __repr__(self):
        k, t = self.joints.shape[:2]
        return (f"Generation({self.text!r}, samples={k}, frames={t}, fps={self.fps:g}, "
                f"scene={self.scene.name!r})")

    def save(self, out, *, video: str | None = "mp4", bvh_sample: int = 0,
             extra: dict | None = None, skeleton: str = "smplx") -> dict[str, Path]:
        """Write the outputs into folder ``out``; returns ``{name: path}``. See
        :func:`jaxmotion.export.write_generation`: ``motion.npz`` (every field),
        ``motion.bvh`` and ``motion_smplx.npz`` (AMASS-style SMPL-X; sample ``bvh_sample``),
        ``motion.glb``, ``motion.mp4`` /
        ``motion.gif`` (``video="mp4"|"gif"``, None to skip: the rendered bodies in the room)
        and ``viewer.html``; ``extra``: more files ``{name: text or bytes}`` written with them
        (batch generation's ``summary.json``); ``skeleton``: ``motion.bvh``'s bone names and
        hierarchy (``smplx``, ``mixamo``, ``ue5``). An error or an interrupt leaves no
        half-written file and no new empty folder."""
        from jaxmotion.export.folder import write_generation

        return write_generation(self, out, video=video, bvh_sample=bvh_sample, extra=extra,
                                skeleton=skeleton)
