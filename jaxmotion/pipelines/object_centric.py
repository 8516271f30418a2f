"""The object-centric pipeline (Cen et al., CVPR 2024): sensors → trajectory → completion.

Given a crop of the room (points with normals, in the crop frame), the target object's points
in it, a sentence embedding and a body shape:

1. the **environment sensor** (a 4 m cube around the target's centre) and the **target
   sensor** (a cube over the target's box, read from the target's own points) describe the
   scene (:func:`crop_sensors`);
2. the **trajectory model** samples the root trajectory (pelvis position and 6D orientation per
   frame, :mod:`jaxmotion.motion.representation`); for sit, stand up and lie, anchor guidance
   (:mod:`jaxmotion.diffusion.anchor_guidance`) steers its pelvis over the target's support
   surface at the anchor frame, and for every action its standing and walking frames to the
   body's walking height; then those frames are moved out of the furniture and walls
   (:mod:`jaxmotion.diffusion.clearance`: the pelvis a body's half width from them);
3. the **completion model** samples the whole motion (trajectory + 21 body rotations) given
   that trajectory, one token per frame built from it and from the **trajectory sensor**
   (a 2 m cube per frame at the root, turned with it, :func:`trajectory_sensors`); foot
   guidance (:mod:`jaxmotion.diffusion.foot_guidance`) holds the feet near the floor still
   and the lowest foot on it;
4. joints by forward kinematics of the body's shape: bone lengths are exact in every frame.

Both models are :class:`~jaxmotion.models.ObjectCentricDenoiser` trained by
``configs/trajectory.py`` and ``configs/completion.py``; each weights file carries the
normalisation statistics of its features (``stats/feature_mean``, ``stats/feature_std``).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import jax
import jax.numpy as jnp

from jaxmotion.constants import ACTION_CLASSES, FOOT_JOINTS, SCENE_FPS, UNKNOWN_ACTION
from jaxmotion.diffusion import body_clearance as body_module
from jaxmotion.diffusion import foot_guidance as foot_module
from jaxmotion.diffusion.anchor_guidance import (
    make_anchor_refiner,
    make_join_refiner,
    standing_height,
)
from jaxmotion.diffusion.clearance import STANDING_SLACK, clear_path, free_frames
from jaxmotion.diffusion.seated_turn import seated_turn
from jaxmotion.diffusion.samplers import SamplerSpec
from jaxmotion.geometry.rotations import matrix_to_rotation_6d
from jaxmotion.geometry.sensors import environment_sensor, target_sensor, trajectory_sensor
from jaxmotion.motion.representation import (
    TRAJECTORY_DIM,
    motion_to_joints,
    motion_to_smplx,
    trajectory_frames,
    trajectory_velocity,
)

__all__ = [
    "ENVIRONMENT_HALF_SIZE",
    "TRAJECTORY_HALF_SIZE",
    "ObjectCentricPipeline",
    "action_index",
    "crop_sensors",
    "furniture_mask",
    "keeps_out_of_target",
    "load_object_pipeline",
    "sample_in_room",
    "trajectory_sensors",
]

ENVIRONMENT_HALF_SIZE = 2.0  # metres: the environment sensor is a 4 m cube
TRAJECTORY_HALF_SIZE = 1.0  # metres: the trajectory sensor is a 2 m cube per frame
TRAJ_SENSOR_PLACEMENTS = ("trajectory", "estimate")  # where the trajectory sensor sits
DEFAULT_SPEC = SamplerSpec("ddim", 20)
_FAR = 1.0e4  # where points that are not the target's go when the target sensor reads
# Best of M: a candidate whose pelvis moves faster than this (m/s) is kept only when every one
# does. The dataset's motions peak at 1.6 m/s (horizontal; 99th percentile 1.48).
BRISK_PELVIS_SPEED = 2.0


def crop_sensors(points, normals, target_mask, res: int):
    """``(environment [r, r, r, 7], target [r, r, r, 7])`` sensors of one crop.

    Args:
      points, normals: ``[N, 3]`` the crop's points and normals (crop frame).
      target_mask: ``[N]`` bool, the target's points (at least one).
      res: voxels per side (static).
    The environment sensor is centred on the mean of the target's points (as the authors'
    code centres it) and reads every point; the target sensor covers the target's box and
    reads the target's points only (the others are moved out of its reach).
    """
    m = jnp.asarray(target_mask, bool)
    w = m.astype(jnp.float32)[:, None]
    centre = jnp.sum(points * w, 0) / jnp.maximum(jnp.sum(w), 1.0)
    lo = jnp.min(jnp.where(m[:, None], points, jnp.inf), 0)
    hi = jnp.max(jnp.where(m[:, None], points, -jnp.inf), 0)
    lo, hi = jnp.where(jnp.isfinite(lo), lo, centre), jnp.where(jnp.isfinite(hi), hi, centre)
    hi = jnp.maximum(hi, lo + 1e-3)  # a one-point target still gets a (tiny) cube
    env = environment_sensor(points, normals, centre, ENVIRONMENT_HALF_SIZE, res)
    tgt = target_sensor(jnp.where(m[:, None], points, _FAR), normals, lo, hi, res)
    return env, tgt


def trajectory_sensors(points, normals, trajectory, res: int):
    """The trajectory sensor ``[T, r, r, r, 7]`` along ``trajectory [T, 9]`` (metres, crop
    frame): a 2 m cube per frame at the pelvis, turned with the root orientation. A frame
    whose 6D orientation is degenerate (the zeros of a padded frame, or two parallel columns)
    gets an unturned cube instead of a NaN one."""
    trajectory = jnp.asarray(trajectory, jnp.float32)
    d6 = trajectory[..., 3:TRAJECTORY_DIM]
    degenerate = jnp.linalg.norm(jnp.cross(d6[..., :3], d6[..., 3:]), axis=-1) < 1e-6
    identity = jnp.array([1.0, 0.0, 0.0, 0.0, 1.0, 0.0], jnp.float32)
    d6 = jnp.where(degenerate[..., None], identity, d6)
    pelvis, rot = trajectory_frames(jnp.concatenate([trajectory[..., :3], d6], -1))
    return trajectory_sensor(points, normals, pelvis, rot, TRAJECTORY_HALF_SIZE, res)


def _tensor(tensors, name, src):
    if name not in tensors:
        raise ValueError(f"{src}: no tensor {name!r}; is it an exported object-centric "
                         "checkpoint (model.safetensors of configs/trajectory.py or "
                         "configs/completion.py)?")
    return jnp.asarray(tensors[name])


def _load_denoiser(path, kind: str):
    from flax import nnx

    from jaxmotion.config import config_from_dict
    from jaxmotion.diffusion import make_schedule
    from jaxmotion.models import ObjectCentricConfig, ObjectCentricDenoiser
    from jaxmotion.models.weights import abstract_module, apply_weights, load_weights

    src = Path(path)
    tensors, saved = load_weights(src)
    if saved.get("task") != kind:
        raise ValueError(f"{src} is a {saved.get('task')!r} checkpoint, not a {kind} one")
    cfg = config_from_dict(ObjectCentricConfig, saved["model"])
    net = abstract_module(lambda: ObjectCentricDenoiser(cfg, rngs=nnx.Rngs(0)))
    apply_weights(net, tensors, prefix="net/", source=str(src))
    net.eval()
    sched = make_schedule(saved["diffusion"]["schedule"], int(saved["diffusion"]["steps"]))
    stats = (_tensor(tensors, "stats/feature_mean", src), _tensor(tensors, "stats/feature_std", src))
    return net, sched, stats, int(saved.get("sensor_points", 0))


@dataclass
class ObjectCentricPipeline:
    """The trajectory and completion denoisers with their schedules and statistics."""

    trajectory: Any  # flax.nnx.Module
    completion: Any
    traj_schedule: object
    comp_schedule: object
    traj_stats: tuple
    comp_stats: tuple
    sensor_points: int = 0

    @classmethod
    def from_files(cls, trajectory_file, completion_file) -> ObjectCentricPipeline:
        """From the exported ``model.safetensors`` of a trajectory and a completion run."""
        t_net, t_sched, t_stats, _ = _load_denoiser(trajectory_file, "trajectory")
        c_net, c_sched, c_stats, sp = _load_denoiser(completion_file, "completion")
        if t_net.cfg.sensor_res != c_net.cfg.sensor_res:
            raise ValueError(f"{trajectory_file} and {completion_file} read sensors of "
                             f"{t_net.cfg.sensor_res}³ and {c_net.cfg.sensor_res}³ voxels: use "
                             "checkpoints trained with the same model.sensor_res")
        return cls(t_net, c_net, t_sched, c_sched, t_stats, c_stats, sp)

    def sample_one(self, key, points, normals, target_mask, text, betas, mask, *,
                   trajectory_spec: SamplerSpec = DEFAULT_SPEC,
                   completion_spec: SamplerSpec = DEFAULT_SPEC,
                   keep_trajectory: bool = True, action=None,
                   anchor_guidance: float = 1.0, standing_guidance: float = 1.0,
                   foot_guidance: float = 1.0, body_clearance: float = 1.0, field=None,
                   prefix=None, prefix_frames=None,
                   traj_sensor_on: str = "trajectory", clearance: bool = True) -> dict:
        """One motion in one crop (jit / vmap it).

        Args:
          key: PRNG key.
          points, normals: ``[N, 3]`` crop points and normals (crop frame, metres).
          target_mask: ``[N]`` bool, the target object's points.
          text: ``[text_dim]`` sentence embedding; betas: ``[10]`` body shape.
          mask: ``[T]`` bool, the frames to generate (a prefix; T is static).
          trajectory_spec, completion_spec: how each stage samples (DDIM steps, guidance).
          keep_trajectory: the completion model's trajectory features are held to the stage-1
            trajectory at every step (inpainting, so the pelvis follows the sampled path
            exactly); False: it writes its own, conditioned on the stage-1 one (the authors').
          action: the action the instruction asks for, an index into
            :data:`~jaxmotion.models.object_centric.ACTION_CLASSES` (None: unknown); read by
            models with ``action_token``, ignored by others.
          anchor_guidance: the strength in [0, 1] of anchor guidance on the trajectory stage
            (:mod:`jaxmotion.diffusion.anchor_guidance`: for sit, stand up and lie the pelvis
            is moved over the target's support surface at the anchor frame; 0 = off).
          standing_guidance: the strength in [0, 1] of standing-height guidance on the
            trajectory stage (:func:`jaxmotion.diffusion.anchor_guidance.standing_offset`: the
            standing and walking frames at this body's walking height; 0 = off).
          foot_guidance: the strength in [0, 1] of foot guidance on the completion stage
            (:mod:`jaxmotion.diffusion.foot_guidance`: feet near the floor held still, the
            lowest foot on the floor; 0 = off).
          body_clearance: the strength in [0, 1] of body clearance on the completion stage
            (:mod:`jaxmotion.diffusion.body_clearance`: the joints kept off the furniture
            other than the target; 0 = off); it needs ``field``.
          field: the obstacles' distance field in the crop frame
            (:func:`jaxmotion.diffusion.body_clearance.room_field` of the room's points other
            than the target's); None: no body clearance.
          prefix, prefix_frames: ``[T, 135]`` motion features (crop frame) and ``[T]`` bool:
            the frames of ``prefix`` that are given (inpainted in both stages: the previous
            step's last frames when motions are joined); None: none.
          clearance: the trajectory's standing and walking frames are moved out of the
            furniture (:mod:`jaxmotion.diffusion.clearance`; False: the model's own path).
          traj_sensor_on: where a completion model with ``traj_sensor`` places the
            trajectory sensor: ``"trajectory"``, on the stage-1 trajectory once (the default:
            the same scores for half the sampling time; docs/results.md in the git
            history, "The trajectory sensor: trainable, and where it sits"), or
            ``"estimate"``, on the trajectory of the current noisy sample at every denoising
            step (the authors' code). Models without the sensor ignore it.
        Returns:
          ``{"trajectory" [T, 9], "motion" [T, 135], "joints" [T, 22, 3]}`` in metres, crop
          frame; frames outside ``mask`` are not meaningful.
        """
        k_traj, k_comp = jax.random.split(key)
        base, null = self._conditions(points, normals, target_mask, text, betas, mask, action)
        traj = self._trajectory(k_traj, base, null, points, normals, target_mask, betas, mask,
                                trajectory_spec, anchor_guidance, standing_guidance, prefix,
                                prefix_frames, clearance)
        return self._complete(k_comp, base, null, points, normals, traj, betas, completion_spec,
                              keep_trajectory, prefix, prefix_frames, foot_guidance,
                              traj_sensor_on, field, body_clearance)

    def _trajectory(self, key, base, null, points, normals, target_mask, betas, mask, spec,
                    anchor_guidance, standing_guidance, prefix, prefix_frames,
                    clearance: bool = True):
        """Stage 1: the root trajectory ``[T, 9]`` (metres, crop frame); with ``clearance``
        its standing and walking frames moved out of the furniture
        (:func:`jaxmotion.diffusion.clearance.clear_path`) and a seated body's legs turned
        towards free floor (:func:`jaxmotion.diffusion.seated_turn.seated_turn`)."""
        t_mean, t_std = self.traj_stats
        nt = mask.shape[0]

        def traj_denoise(x, t, c):
            return self.trajectory(x, t, c, deterministic=True)

        refine = None
        if anchor_guidance or standing_guidance:
            refine = make_anchor_refiner(points, normals, target_mask, mask,
                                         base["action"][0], t_mean, t_std, anchor_guidance,
                                         betas=betas, given=prefix_frames,
                                         standing=standing_guidance)
        shape = (1, nt, TRAJECTORY_DIM)
        known = values = None
        if prefix is not None:
            known = jnp.broadcast_to(jnp.asarray(prefix_frames, bool)[None, :, None], shape)
            values = ((prefix[:, :TRAJECTORY_DIM] - t_mean) / t_std)[None]
            join = make_join_refiner(values[0], prefix_frames, t_mean, t_std)
            refine = join if refine is None else (lambda x, t, a=refine: a(join(x, t), t))
        x = spec.run(key, traj_denoise, self.traj_schedule, shape, base, {**base, **null},
                     refine, known_mask=known, known_values=values)
        traj = x[0] * t_std + t_mean
        if clearance:
            traj = _cleared(traj, points, target_mask, mask, base["action"][0], betas,
                            prefix_frames)
        return traj

    def complete_one(self, key, points, normals, target_mask, text, betas, trajectory, mask, *,
                     spec: SamplerSpec = DEFAULT_SPEC, action=None, prefix=None,
                     prefix_frames=None, foot_guidance: float = 0.0,
                     body_clearance: float = 1.0, field=None) -> dict:
        """The completion stage alone along a given root ``trajectory [T, 9]`` (crop frame):
        trajectory control, the pelvis follows it exactly. Arguments as :meth:`sample_one`;
        returns the same dict. Foot guidance is off by default here: along the rule-made
        roots of given and planned paths (one pelvis height, no bob) it puts feet that
        hovered on the floor, where they slide (feet sliding along the test split's walks'
        paths in 63 % of frame pairs with it, 42 % without). Body clearance is on where a
        ``field`` is given."""
        base, null = self._conditions(points, normals, target_mask, text, betas, mask, action)
        return self._complete(key, base, null, points, normals, jnp.asarray(trajectory,
                                                                            jnp.float32),
                              betas, spec, True, prefix, prefix_frames, foot_guidance,
                              "trajectory", field, body_clearance)

    def _conditions(self, points, normals, target_mask, text, betas, mask, action):
        """The condition dict of a batch of one, and its text-dropped override."""
        env, tgt = crop_sensors(points, normals, target_mask, self.trajectory.cfg.sensor_res)
        base = {"text": text[None], "betas": betas[None], "env_sensor": env[None],
                "target_sensor": tgt[None], "mask": mask[None],
                "drop_text": jnp.zeros((1,), bool), "drop_scene": jnp.zeros((1,), bool),
                "action": jnp.full((1,), UNKNOWN_ACTION if action is None else action,
                                   jnp.int32)}
        return base, {"drop_text": jnp.ones((1,), bool)}  # guidance on the text

    def _complete(self, key, base, null, points, normals, traj, betas, spec, keep_trajectory,
                  prefix, prefix_frames, foot_guidance=0.0,
                  traj_sensor_on: str = "trajectory", field=None,
                  body_clearance: float = 0.0) -> dict:
        """Stage 2: the whole motion along ``traj [T, 9]`` (metres, crop frame); body clearance
        needs the obstacles' distance ``field``."""
        if traj_sensor_on not in TRAJ_SENSOR_PLACEMENTS:
            raise ValueError(f"traj_sensor_on must be one of {TRAJ_SENSOR_PLACEMENTS}, got "
                             f"{traj_sensor_on!r}")
        c_mean, c_std = self.comp_stats
        cond = {**base, "trajectory": ((traj - c_mean[:TRAJECTORY_DIM])
                                       / c_std[:TRAJECTORY_DIM])[None]}
        if self.completion.cfg.traj_velocity:
            cond["traj_velocity"] = trajectory_velocity(traj, base["mask"][0], SCENE_FPS)[None]
        sensed = self.completion.cfg.traj_sensor
        sp = self.sensor_points or points.shape[0]
        res = self.trajectory.cfg.sensor_res
        if sensed:
            cond["traj_sensor"] = trajectory_sensors(points[:sp], normals[:sp], traj, res)[None]
        on_estimate = sensed and traj_sensor_on == "estimate"

        def comp_denoise(x, t, c):
            if on_estimate:  # the sensor follows the noisy sample's own trajectory
                est = x[..., :TRAJECTORY_DIM] * c_std[:TRAJECTORY_DIM] + c_mean[:TRAJECTORY_DIM]
                c = {**c, "traj_sensor": jax.vmap(
                    lambda e: trajectory_sensors(points[:sp], normals[:sp], e, res))(est)}
            return self.completion(x, t, c, deterministic=True)

        shape = (1, traj.shape[0], c_mean.shape[0])
        known = values = None
        if keep_trajectory:  # the stage-1 trajectory held at every step (inpainting)
            known = jnp.zeros(shape, bool).at[..., :TRAJECTORY_DIM].set(True)
            values = jnp.zeros(shape, jnp.float32).at[..., :TRAJECTORY_DIM].set(
                cond["trajectory"])
        if prefix is not None:  # the given frames: every feature
            given = jnp.broadcast_to(jnp.asarray(prefix_frames, bool)[None, :, None], shape)
            known = given if known is None else known | given
            norm = ((prefix - c_mean) / c_std)[None]
            values = norm if values is None else jnp.where(given, norm, values)
        refine = None
        valid, act = base["mask"][0], base["action"][0]
        loss = None
        if body_clearance and field is not None:
            def loss(f):  # the whole body placed once for both terms
                joints = motion_to_joints(f, betas)
                clear = body_clearance * body_module.joints_clearance(joints, field, valid)
                if not foot_guidance:
                    return clear
                feet = joints[:, jnp.asarray(FOOT_JOINTS)]
                return clear + foot_guidance * foot_module.foot_terms(feet, valid, act)
        elif foot_guidance:
            def loss(f):
                return foot_guidance * foot_module.foot_loss(f, betas, valid, act)
        if loss is not None:
            late = round(foot_module.ACTIVE_FRACTION * self.comp_schedule.num_steps)
            body = foot_module.make_refiner(loss, c_mean, c_std, active_below=late)
            # the body is fitted around the root that will be kept: the known values first
            refine = body if known is None else (lambda x, t: body(jnp.where(known, values, x),
                                                                   t))
        y = spec.run(key, comp_denoise, self.comp_schedule, shape, cond, {**cond, **null},
                     refine, known_mask=known, known_values=values)
        motion = y[0] * c_std + c_mean
        return {"trajectory": traj, "motion": motion, "joints": motion_to_joints(motion, betas)}

    def sample(self, key, points, normals, target, text_emb, betas, mask, *,
               trajectory: SamplerSpec = DEFAULT_SPEC, completion: SamplerSpec = DEFAULT_SPEC,
               motion_candidates: int = 1, anchor_first=None,
               keep_trajectory: bool = True, action=None,
               anchor_guidance: float = 1.0, standing_guidance: float = 1.0,
               foot_guidance: float = 1.0, body_clearance: float = 1.0, fields=None,
               avoid=None, traj_sensor_on: str = "trajectory",
               clearance: bool = True) -> dict:
        """Motions for a batch of crops, the best of ``motion_candidates`` each: the two stages
        :meth:`sample_trajectories` then :meth:`complete_trajectories` (one program, or two
        that load side by side as ``generate``'s do; the same motions).

        Args:
          key: PRNG key.
          points, normals: ``[B, N, 3]`` crop points and normals.
          target: ``[B, N]`` bool, the target object's points.
          text_emb: ``[B, text_dim]``; betas: ``[B, 10]``; mask: ``[B, T]``.
          trajectory, completion: the two stages' samplers.
          anchor_first: ``[B]`` bool or None (as
            :func:`~jaxmotion.pipelines.affordance.select_motion`, which picks among the
            candidates: never a teleporting one while another is smooth; of those near enough
            the target at the anchor frame, the one whose feet slide, hover or sink in the
            fewest frames).
          keep_trajectory, anchor_guidance, standing_guidance: as :meth:`sample_one`.
          foot_guidance, body_clearance, traj_sensor_on, clearance: as :meth:`sample_one`.
          action: ``[B]`` int indices into ``ACTION_CLASSES`` (None: unknown).
          fields: ``[B, *FIELD_SHAPE]`` each crop's obstacle distance field
            (:func:`jaxmotion.diffusion.body_clearance.room_field`; None: no body clearance).
          avoid: ``[B, N]`` bool or None, the points a body must keep out of (furniture):
            among the plausible candidates, those touching them in the fewest frames compete.
        Returns:
          ``{"joints": [B, T, 22, 3], "motion": [B, T, 135]}`` (the kept candidates' joints
          and motion features) in the crop frame.
        """
        trajs = self.sample_trajectories(key, points, normals, target, text_emb, betas, mask,
                                         trajectory=trajectory,
                                         motion_candidates=motion_candidates, action=action,
                                         anchor_guidance=anchor_guidance,
                                         standing_guidance=standing_guidance,
                                         clearance=clearance)
        return self.complete_trajectories(key, points, normals, target, text_emb, betas, mask,
                                          trajs, completion=completion,
                                          anchor_first=anchor_first,
                                          keep_trajectory=keep_trajectory, action=action,
                                          foot_guidance=foot_guidance,
                                          body_clearance=body_clearance, fields=fields,
                                          avoid=avoid,
                                          traj_sensor_on=traj_sensor_on)

    def sample_trajectories(self, key, points, normals, target, text_emb, betas, mask, *,
                            trajectory: SamplerSpec = DEFAULT_SPEC, motion_candidates: int = 1,
                            action=None, anchor_guidance: float = 1.0,
                            standing_guidance: float = 1.0, keys=None,
                            clearance: bool = True):
        """Stage 1 of :meth:`sample`: the root trajectories ``[B, M, T, 9]`` (metres, crop
        frame) of each crop's ``M = motion_candidates`` candidates; arguments as there.
        ``keys``: each candidate's own key ``[B, M]`` instead of ``key``'s splits."""
        keys, action = self._candidate_keys(key, points.shape[0], motion_candidates, action,
                                            keys)

        def one(k, p, n, t, e, bt, mk, a):
            base, null = self._conditions(p, n, t, e, bt, mk, a)
            return self._trajectory(jax.random.split(k)[0], base, null, p, n, t, bt, mk,
                                    trajectory, anchor_guidance, standing_guidance, None, None,
                                    clearance)

        per_candidate = jax.vmap(one, in_axes=(0, None, None, None, None, None, None, None))
        return jax.vmap(per_candidate)(keys, points, normals, target, text_emb, betas, mask,
                                       action)

    def complete_trajectories(self, key, points, normals, target, text_emb, betas, mask,
                              trajectories, *, completion: SamplerSpec = DEFAULT_SPEC,
                              anchor_first=None, keep_trajectory: bool = True, action=None,
                              foot_guidance: float = 1.0, body_clearance: float = 1.0,
                              fields=None, avoid=None, traj_sensor_on: str = "trajectory",
                              keys=None) -> dict:
        """Stage 2 of :meth:`sample`: the motions along ``trajectories [B, M, T, 9]`` (from
        :meth:`sample_trajectories` with the same ``key`` or ``keys``), the best of the M
        kept; arguments and result as :meth:`sample`."""
        from jaxmotion.pipelines.affordance import select_motion

        b, m = trajectories.shape[:2]
        keys, action = self._candidate_keys(key, b, m, action, keys)

        def one(k, tr, p, n, t, e, bt, mk, a, fd):
            base, null = self._conditions(p, n, t, e, bt, mk, a)
            out = self._complete(jax.random.split(k)[1], base, null, p, n, tr, bt, completion,
                                 keep_trajectory, None, None, foot_guidance, traj_sensor_on,
                                 fd, body_clearance)
            return out["joints"], out["motion"]

        per_candidate = jax.vmap(one, in_axes=(0, 0) + (None,) * 8)
        joints, motion = jax.vmap(per_candidate)(keys, jnp.asarray(trajectories, jnp.float32),
                                                 points, normals, target, text_emb, betas, mask,
                                                 action, fields)
        if m == 1:
            return {"joints": joints[:, 0], "motion": motion[:, 0]}
        best = select_motion(joints, points, target, mask, anchor_first,
                             brisk_pelvis_speed=BRISK_PELVIS_SPEED, avoid=avoid, feet=True,
                             return_index=True)
        return {"joints": joints[jnp.arange(b), best], "motion": motion[jnp.arange(b), best]}

    @staticmethod
    def _candidate_keys(key, b: int, m: int, action, keys=None):
        """Each candidate's key ``[B, M]`` (split again into its two stages' keys, as
        :meth:`sample_one` does; ``keys`` when given) and the actions ``[B]``."""
        if keys is None:
            keys = jax.random.split(key, b * int(m)).reshape(b, int(m))
        if action is None:
            action = jnp.full((b,), UNKNOWN_ACTION, jnp.int32)
        return keys, jnp.asarray(action, jnp.int32)


@jax.jit
def _cleared(traj, points, target_mask, mask, action, betas, given):
    """The sampled trajectory ``traj [T, 9]`` moved out of the furniture and its seated
    legs turned to free floor (:mod:`jaxmotion.diffusion.clearance`,
    :mod:`jaxmotion.diffusion.seated_turn`). Jitted on its own, so that eager callers
    (``sample_one`` outside ``jit``) compile its loops once per shape, not at every call."""
    weight = free_frames(mask, action, given)
    standing = traj[:, 2] > standing_height(betas) - STANDING_SLACK
    traj = traj.at[:, :2].set(clear_path(traj[:, :2], points, target_mask, action, weight,
                                         standing))
    return seated_turn(traj, points, target_mask, mask, action, given)[0]


def furniture_mask(points, target_mask, *, target_too: bool = False):
    """The crop points ``[N]`` a body keeps out of, for choosing among candidate motions: every
    point above 0.1 m — the furniture, and the walls with their doors and windows (a walk to a
    door stops in front of it, not through the wall) — the target's (``target_mask [N]``)
    aside unless ``target_too`` (:func:`keeps_out_of_target`); ``points [N, 3]``."""
    import numpy as np

    return (np.asarray(points)[:, 2] > 0.1) & (~np.asarray(target_mask, bool) | bool(target_too))


def obstacle_field(room, chosen, action, shift, rot):
    """The distance field of the room's obstacles in a crop's frame, for body clearance
    (:func:`jaxmotion.diffusion.body_clearance.room_field`): every point of ``room`` (a
    :class:`~jaxmotion.scene.Scene`) but those of the target ``chosen``, unless the body keeps
    out of its target too (:func:`keeps_out_of_target` of ``action``)."""
    import numpy as np

    obstacle = np.ones(room.num_points, bool)
    if not keeps_out_of_target(action):
        obstacle &= np.asarray(room.instance) != chosen
    return body_module.room_field(room.xyz, obstacle, shift, rot)


def keeps_out_of_target(action) -> bool:
    """Whether a body doing ``action`` keeps out of its target too: a walk stops in front of
    it, and an action the instruction does not name (None) is not let into it either; a sit,
    a stand-up and a lie touch it."""
    return action in ("walk", None)


@functools.lru_cache(maxsize=4)
def load_object_pipeline(trajectory: str, completion: str) -> ObjectCentricPipeline:
    """The :class:`ObjectCentricPipeline` of two weights files, kept for the process;
    :class:`~jaxmotion.errors.GenerateError` when they do not load together."""
    from jaxmotion.errors import GenerateError

    try:
        return ObjectCentricPipeline.from_files(trajectory, completion)
    except (KeyError, ValueError) as e:
        raise GenerateError(f"checkpoints {trajectory} and {completion} do not load together: "
                            f"{e}") from e


def action_index(action) -> int:
    """The index of an action name (``Instruction.action``) in :data:`ACTION_CLASSES`; None or
    an unknown name gives the unknown class."""
    return ACTION_CLASSES.index(action) if action in ACTION_CLASSES[:-1] else UNKNOWN_ACTION


def sample_in_room(room, centre, chosen: int, anchor_first: bool, text_emb, opts, files, root,
                   aot_dir, versions, action=None):
    """``generate``'s synthesis stage with the object-centric pipeline: the K motions in the
    scene's frame for the crop square at ``centre`` around the target ``chosen``.

    Args:
      room: the :class:`~jaxmotion.scene.Scene`; centre: the crop square's xy centre.
      chosen: the target's instance id; anchor_first: the text gets up from it.
      text_emb: the sentence embedding ``[1, 384]`` (or a token-state dict; its pooled part).
      opts: :class:`~jaxmotion.options.GenerateOptions` (samples, seed, steps, guidance[1],
        motion_candidates); files: ``(trajectory, completion)`` weights files.
      root: the run's PRNG key data ``uint32[2]`` (its second split samples, as the
        affordance pipeline's);
      aot_dir, versions: the compiled-program cache (:func:`jaxmotion.compiled.cached_call`).
      action: the action the instruction asks for (``Instruction.action``; None: unknown).
    Returns:
      ``(joints [K, T, 22, 3], (crop point indices, rotation, shift), smplx)``: ``smplx`` the
      SMPL-X parameters the motions were sampled as (``global_orient``, ``body_pose``,
      ``transl``, ``betas``, scene frame; the joints are their forward kinematics, so no fit
      is needed).
    """
    from jaxmotion.compiled import cached_call

    args, crop = sampler_inputs(room, centre, chosen, anchor_first, text_emb, opts, files, root,
                                action)
    _, _, fingerprint, builds = _sampler_program(opts, files, versions)
    # two programs, the stages, so that their executables load side by side (prefetch_sampler)
    trajs = cached_call(aot_dir, PROGRAMS[0], fingerprint, builds[0], _stage_arguments(args))
    res = jax.device_get(cached_call(aot_dir, PROGRAMS[1], fingerprint, builds[1],
                                     _stage_arguments(args, trajs)))
    joints, smplx = scene_outputs(res, args[5], *crop[1:])
    return joints, crop, smplx


def sampler_inputs(room, centre, chosen: int, anchor_first: bool, text_emb, opts, files, root,
                   action=None):
    """The sampling programs' arguments for one request (:func:`sample_in_room`'s, K rows:
    :func:`_sampler_arguments`) and its crop ``(point indices, rotation, shift)``;
    ``x_scene = x_crop @ rotation + shift``."""
    import numpy as np

    from jaxmotion.data.crop import generate_crop
    from jaxmotion.errors import GenerateError
    from jaxmotion.text.condition import pooled_text

    spec, frames = _crop_and_frames(tuple(files))
    pick, pts, shift, rot = generate_crop(room.xyz, centre, spec, opts.seed)
    on_target = room.instance[pick] == chosen
    if not on_target.any():
        raise GenerateError(f"object {chosen} has no point in the {spec.size} m square the "
                            "object-centric models see; is it an object of the room?")
    normals = (np.asarray(room.normal[pick], np.float32) @ rot.T).astype(np.float32)
    avoid = furniture_mask(pts, on_target, target_too=keeps_out_of_target(action))
    field = obstacle_field(room, chosen, action, shift, rot)
    args = _sampler_arguments(opts.samples, frames, root, pts, normals, on_target,
                              np.asarray(pooled_text(text_emb), np.float32)[0], anchor_first,
                              action, avoid, rot, shift, field)
    return args, (pick, rot, shift)


def scene_outputs(res, betas, rot, shift):
    """``(joints [K, T, 22, 3], smplx)`` in the scene frame from a completion program's result
    (joints in the crop frame, SMPL-X parameters already in the scene's)."""
    import numpy as np

    joints = (np.asarray(res["joints"]) @ rot + shift).astype(np.float32)
    smplx = {n: np.asarray(res[n], np.float32) for n in ("global_orient", "body_pose", "transl")}
    smplx["betas"] = np.asarray(betas, np.float32)
    return joints, smplx


def prefetch_sampler(opts, files, root, aot_dir, versions) -> bool:
    """Start loading :func:`sample_in_room`'s two compiled programs (its stages) in the
    background, each on its own thread (:func:`jaxmotion.compiled.prefetch`), before the
    target is found: the programs' shapes depend on the options and the models only. An
    executable loads on one core (measured: two load side by side in the time of one), so
    the stages' two load in about the time of the larger. Returns whether both started (the
    programs are on disk)."""
    import numpy as np

    from jaxmotion.compiled import prefetch, specs_of

    if aot_dir is None:
        return False
    spec, frames, fingerprint, _ = _sampler_program(opts, files, versions)
    xyz = np.zeros((spec.num_points, 3), np.float32)
    flags = np.zeros(spec.num_points, bool)
    text = np.zeros(int(_denoiser_config(files[1])["text_dim"]), np.float32)
    args = _sampler_arguments(opts.samples, frames, root, xyz, xyz, flags, text, False, None,
                              flags, np.eye(3, dtype=np.float32), np.zeros(3, np.float32),
                              body_module.empty_field())
    trajs = np.zeros((opts.samples, opts.motion_candidates, frames, TRAJECTORY_DIM), np.float32)
    started = [prefetch(aot_dir, name, fingerprint, specs_of(stage_args)) for name, stage_args
               in zip(PROGRAMS, (_stage_arguments(args), _stage_arguments(args, trajs)))]
    return all(started)


def _denoiser_config(path) -> dict:
    from jaxmotion.models.weights import read_config

    return read_config(path)["model"]


#: The names of :func:`sample_in_room`'s two compiled programs in the cache: the trajectory
#: stage (every candidate's root) and the completion stage (the bodies, the best candidate,
#: its SMPL-X parameters in the scene frame).
PROGRAMS = ("sample-object-centric-trajectory", "sample-object-centric-completion")


@functools.lru_cache(maxsize=8)
def _crop_and_frames(files) -> tuple:
    """The crop spec and the motions' frames of the completion weights ``files[1]``."""
    from jaxmotion.data.crop import crop_spec_from_config
    from jaxmotion.models.weights import read_config

    run_cfg = read_config(files[1])
    return crop_spec_from_config(run_cfg), int(run_cfg["max_frames"])


def _in_scene(res, betas, rot, shift) -> dict:
    """A completion's result with its SMPL-X parameters in the scene frame
    (``x_scene = x_crop @ rot + shift``); the joints stay in the crop frame."""
    motion = res["motion"]
    turned = rot.T @ trajectory_frames(motion)[1]
    scene = jnp.concatenate([motion[..., :3] @ rot + shift, matrix_to_rotation_6d(turned),
                             motion[..., TRAJECTORY_DIM:]], axis=-1)
    return {"joints": res["joints"], **motion_to_smplx(scene, betas)}


def _sampler_program(opts, files, versions):
    """``(crop spec, frames, fingerprint, (build_trajectory, build_completion))`` of
    :func:`sample_in_room`'s two compiled programs for ``opts`` and the weights ``files``
    (their arguments: :func:`_stage_arguments`)."""
    from jaxmotion.compiled import digest

    spec, frames = _crop_and_frames(tuple(files))
    stage = SamplerSpec("ddim", opts.steps, guidance=opts.guidance[1])
    n_mot = opts.motion_candidates

    main = lambda kd: jax.random.split(jax.random.wrap_key_data(kd))[1]

    def build_trajectory():
        pipe = load_object_pipeline(str(files[0]), str(files[1]))

        def run(kd, p, n, t, e, b, m, a):
            return pipe.sample_trajectories(main(kd), p, n, t, e, b, m, trajectory=stage,
                                            motion_candidates=n_mot, action=a)

        return run

    def build_completion():
        pipe = load_object_pipeline(str(files[0]), str(files[1]))

        def run(kd, p, n, t, e, b, m, f, a, av, rot, shift, field, trajs):
            fields = jnp.broadcast_to(field, (p.shape[0], *field.shape))  # one crop, K rows
            res = pipe.complete_trajectories(main(kd), p, n, t, e, b, m, trajs,
                                             completion=stage, anchor_first=f, action=a,
                                             fields=fields, avoid=av)
            return _in_scene(res, b, rot, shift)

        return run

    fingerprint = digest(versions, stage, n_mot, Path(files[0]), Path(files[1]))
    return spec, frames, fingerprint, (build_trajectory, build_completion)


def candidate_keys(root, samples: int, motion_candidates: int):
    """The key data ``uint32 [K, M, 2]`` of every candidate of a request whose seed's key data
    is ``root``: those :func:`sample_in_room`'s programs draw (its second split, then one key
    per sample and candidate), so that a batch (:func:`batch_sampler`) draws the same motions
    as ``generate`` with that seed."""
    import numpy as np

    main = jax.random.split(jax.random.wrap_key_data(jnp.asarray(root, jnp.uint32)))[1]
    keys = jax.random.split(main, samples * motion_candidates)
    return np.asarray(jax.random.key_data(keys)).reshape(samples, motion_candidates, -1)


def batch_sampler(opts, files, mesh=None):
    """Both stages as one jitted program over rows of many requests (batch generation,
    :mod:`jaxmotion.batch`): ``run(keys [B, M, 2], points, normals, target, text, betas, mask,
    anchor_first, action, avoid, rotation [B, 3, 3], shift [B, 3], field [B, *FIELD_SHAPE])``
    → ``{"joints", ...}`` as
    the completion program's, each row in its own crop and scene frame. ``keys`` come from
    :func:`candidate_keys` (the rows of one request, its seed's). ``mesh``: a 1-D
    :class:`jax.sharding.Mesh` whose axis ``batch`` splits the rows; each device runs the
    program on its own rows only (``shard_map``). ``B`` must be a multiple of the mesh's
    size. A row's result does not depend on the other rows; several devices agree with one
    to float32 rounding (1e-6 m)."""
    stage = SamplerSpec("ddim", opts.steps, guidance=opts.guidance[1])
    n_mot = opts.motion_candidates
    pipe = load_object_pipeline(str(files[0]), str(files[1]))

    def run(keys, p, n, t, e, b, m, f, a, av, rot, shift, fields):
        keys = jax.random.wrap_key_data(keys)
        trajs = pipe.sample_trajectories(None, p, n, t, e, b, m, trajectory=stage,
                                         motion_candidates=n_mot, action=a, keys=keys)
        res = pipe.complete_trajectories(None, p, n, t, e, b, m, trajs, completion=stage,
                                         anchor_first=f, action=a, fields=fields, avoid=av,
                                         keys=keys)
        return jax.vmap(_in_scene)(res, b, rot, shift)

    if mesh is None:
        return jax.jit(run)
    from jax.sharding import PartitionSpec

    rows = PartitionSpec(mesh.axis_names[0])
    return jax.jit(jax.shard_map(run, mesh=mesh, in_specs=(rows,) * 13, out_specs=rows,
                                 check_vma=False))


def _stage_arguments(args, trajectories=None):
    """The trajectory program's arguments of :func:`_sampler_arguments`' ``args``; with
    ``trajectories [K, M, T, 9]`` (what it returned), the completion program's."""
    if trajectories is None:
        return (*args[:7], args[8])
    return (*args, trajectories)


def _sampler_arguments(k: int, frames: int, root, pts, normals, on_target, text, anchor_first,
                       action, avoid, rot, shift, field):
    """The arguments of :func:`_sampler_program`'s program for K samples of one crop (``field``
    its obstacles' distance field, :func:`obstacle_field`, once for the K)."""
    import numpy as np

    tile = lambda x: np.ascontiguousarray(np.broadcast_to(x, (k, *np.shape(x))))
    return (np.asarray(root), tile(pts), tile(normals), tile(on_target), tile(text),
            np.zeros((k, 10), np.float32), np.ones((k, frames), bool), np.full(k, anchor_first),
            np.full(k, action_index(action), np.int32), tile(avoid),
            np.asarray(rot, np.float32), np.asarray(shift, np.float32),
            np.asarray(field, np.float32))
