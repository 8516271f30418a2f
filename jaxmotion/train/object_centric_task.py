"""Training tasks ``trajectory`` and ``completion``: the object-centric pipeline's denoisers.

Each batch is a dataset crop (:class:`jaxmotion.data.Dataset`: points, normals, the target's
points, the motion's SMPL-X parameters). The features (:mod:`jaxmotion.motion.representation`)
are taken in the crop frame (pelvis ``= joints[:, 0]``, global orientation turned by the
crop's rotation) and z-scored by statistics measured on ``stats_batches`` training batches
(saved with the weights). The sensors are computed inside the jitted step
(:func:`~jaxmotion.pipelines.object_centric.crop_sensors`), the trajectory sensor on the
ground-truth trajectory (what the stage-1 trajectory stands for at sampling time) and on the
first ``sensor_points`` crop points. Loss: masked x0 loss (``loss=l1`` as the paper, or
``mse``) with the body rotations weighted ``pose_weight`` (10 in the paper); the text and the
two scene sensors are dropped independently with ``diffusion.cond_drop_prob`` for
classifier-free guidance. ``pretrain=True`` drops both for every example: motions without a
scene or a text, as the paper pre-trains on AMASS.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
from flax import nnx

from jaxmotion.train.data_task import DataTask, split_dataset

__all__ = ["ObjectCentricNet", "ObjectCentricTask"]


class ObjectCentricNet(nnx.Module):
    """Holds the denoiser under ``net`` (the prefix of its weights in the exported file)."""

    def __init__(self, net):
        self.net = net


def crop_features(batch):
    """Motion features ``[B, T, 135]`` of a batch in its crop frame (zeros past the end)."""
    from jaxmotion.geometry.rotations import axis_angle_to_matrix
    from jaxmotion.motion.representation import motion_features

    rot = jnp.asarray(batch["rotation"], jnp.float32)[:, None]  # [B, 1, 3, 3]
    g = rot @ axis_angle_to_matrix(jnp.asarray(batch["global_orient"], jnp.float32))
    feats = motion_features(jnp.asarray(batch["joints"])[:, :, 0], g, batch["body_pose"])
    return feats * jnp.asarray(batch["mask"], jnp.float32)[..., None]


_crop_features_jit = jax.jit(crop_features)


class ObjectCentricTask(DataTask):
    """``trajectory`` (kind from ``cfg.model.kind``) or ``completion``."""

    def build_model(self, cfg, rngs):
        from jaxmotion.diffusion import make_schedule
        from jaxmotion.models import ObjectCentricDenoiser

        if cfg.model.kind != cfg.task:
            raise ValueError(f"task={cfg.task!r} trains the {cfg.task} model, but "
                             f"model.kind={cfg.model.kind!r}; make them equal")
        self.schedule = make_schedule(cfg.diffusion.schedule, cfg.diffusion.steps)
        self.dim = cfg.model.motion_dim
        net = ObjectCentricDenoiser(cfg.model, rngs=rngs)
        if cfg.init_from:
            self.mean, self.std = self._init_from(net, cfg)
        else:
            self.mean, self.std = self._feature_stats(cfg)
        w = np.ones(self.dim, np.float32)
        w[9:] = float(cfg.pose_weight)
        self.weights = jnp.asarray(w)
        self.loss_type = str(cfg.loss)
        self.pretrain = bool(cfg.pretrain)
        self.sensor_points = int(cfg.sensor_points)
        self.action_unknown = float(cfg.action_unknown_prob)
        self.geometric = {name: float(getattr(cfg, f"{name}_weight", 0.0))
                          for name in ("joint", "foot_contact", "joint_velocity")}
        self.geometric_weighting = str(getattr(cfg, "geometric_weighting", "signal"))
        return ObjectCentricNet(net)

    def _init_from(self, net, cfg):
        """Load ``cfg.init_from``'s weights into ``net``; its statistics ``(mean, std)``."""
        from jaxmotion.config import config_to_dict
        from jaxmotion.models.weights import apply_weights, load_weights, weights_path

        path = weights_path(cfg.init_from)
        tensors, saved = load_weights(path)
        if saved.get("task") != cfg.task:
            raise ValueError(f"init_from={cfg.init_from}: {path} is a {saved.get('task')!r} "
                             f"checkpoint, not a {cfg.task} one")
        mine = config_to_dict(cfg.model)
        theirs = {"action_token": False, "traj_velocity": False, **saved["model"]}
        # switched on over theirs: the new inputs start with zero weights (the same function)
        grow = {k for k in ("action_token", "traj_velocity", "traj_sensor")
                if mine[k] and not theirs[k]}
        diff = [f"{k} ({theirs.get(k)!r} vs {mine[k]!r})" for k in sorted(mine)
                if theirs.get(k) != mine[k] and k != "temporal_basis" and k not in grow]
        if diff:
            raise ValueError(f"init_from={cfg.init_from}: its model config differs in "
                             f"{', '.join(diff)}; pass the same model.* settings")
        if "action_token" in grow:
            emb = net.action_embed.embedding
            tensors = {**tensors, "params/net/action_embed/embedding": np.zeros(emb.shape,
                                                                               np.float32)}
        name = "params/net/traj_mlp/fc1/kernel"
        if "traj_sensor" in grow:  # zero rows for the sensor inputs, after the 9 trajectory ones
            k = np.asarray(tensors[name])
            flat = 7 * int(cfg.model.sensor_res) ** 3
            tensors = {**tensors, name: np.concatenate(
                [k[:9], np.zeros((flat, k.shape[1]), k.dtype), k[9:]], axis=0)}
        if "traj_velocity" in grow:  # zero rows for the velocity inputs, appended last
            from jaxmotion.motion.representation import VELOCITY_DIM

            k = np.asarray(tensors[name])
            tensors = {**tensors, name: np.concatenate(
                [k, np.zeros((VELOCITY_DIM, k.shape[1]), k.dtype)], axis=0)}
        apply_weights(net, tensors, prefix="net/", source=str(path))
        return (jnp.asarray(tensors["stats/feature_mean"]),
                jnp.asarray(tensors["stats/feature_std"]))

    def _feature_stats(self, cfg):
        """Mean and std ``[dim]`` of the features over the valid frames of ``stats_batches``
        training batches (deterministic in the seed); the std is floored at ``std_floor``."""
        ds = split_dataset(cfg, "train")
        bs = min(cfg.batch_size, len(ds))
        total = np.zeros(self.dim, np.float64)
        sq = np.zeros(self.dim, np.float64)
        count = 0
        for b in range(int(cfg.stats_batches)):
            host = ds.step_batch(b, bs, cfg.seed + 7, max(1, len(ds) // bs))
            f = np.asarray(_crop_features_jit({k: host[k] for k in (
                "rotation", "global_orient", "joints", "body_pose", "mask")}), np.float64)
            f = f[host["mask"]][:, : self.dim]
            total += f.sum(0)
            sq += (f * f).sum(0)
            count += len(f)
        mean = total / max(count, 1)
        std = np.sqrt(np.maximum(sq / max(count, 1) - mean * mean, 0.0))
        return (jnp.asarray(mean, jnp.float32),
                jnp.asarray(np.maximum(std, float(cfg.std_floor)), jnp.float32))

    def export_tensors(self) -> dict:
        return {"stats/feature_mean": self.mean, "stats/feature_std": self.std}

    def export_config(self) -> dict:
        return {"sensor_points": self.sensor_points}

    def loss(self, model, batch, key, *, train):
        from jaxmotion.diffusion import diffusion_loss
        from jaxmotion.pipelines.object_centric import crop_sensors, trajectory_sensors

        net = model.net
        cfg = net.cfg
        k_drop, k_loss, k_act = jax.random.split(key, 3)
        mask = jnp.asarray(batch["mask"], bool)
        b = mask.shape[0]
        feats = crop_features(batch)
        x0 = (feats[..., : self.dim] - self.mean) / self.std * mask[..., None]
        points, normals = batch["points"], batch["normals"]
        env, tgt = jax.vmap(lambda p, n, m: crop_sensors(p, n, m, cfg.sensor_res))(
            points, normals, batch["target_mask"])
        env, tgt = jax.lax.stop_gradient(env), jax.lax.stop_gradient(tgt)
        if self.pretrain:
            drop_t = drop_s = jnp.ones((b,), bool)
        else:
            p = self.cond_drop if train else 0.0
            kt, ks = jax.random.split(k_drop)
            drop_t = jax.random.uniform(kt, (b,)) < p
            drop_s = jax.random.uniform(ks, (b,)) < p
        cond = {"text": batch["text_emb"], "betas": batch["betas"], "env_sensor": env,
                "target_sensor": tgt, "mask": mask, "drop_text": drop_t, "drop_scene": drop_s}
        if cfg.action_token:  # the dataset's label, sometimes withheld (as unread text is)
            from jaxmotion.constants import UNKNOWN_ACTION

            hide = jax.random.uniform(k_act, (b,)) < (self.action_unknown if train else 0.0)
            cond["action"] = jnp.where(hide, UNKNOWN_ACTION, jnp.asarray(batch["action"],
                                                                        jnp.int32))
        if cfg.kind == "completion":
            cond["trajectory"] = x0[..., :9]
            if cfg.traj_velocity:
                from jaxmotion.constants import SCENE_FPS
                from jaxmotion.motion.representation import trajectory_velocity

                cond["traj_velocity"] = trajectory_velocity(feats[..., :9], mask, SCENE_FPS)
            if cfg.traj_sensor:
                sp = self.sensor_points or points.shape[1]
                cond["traj_sensor"] = jax.lax.stop_gradient(jax.vmap(
                    lambda p, n, tr: trajectory_sensors(p, n, tr, cfg.sensor_res))(
                    points[:, :sp], normals[:, :sp], feats[..., :9]))

        def denoise(x, t, c):
            return net(x, t, c, deterministic=not train)

        loss, aux = diffusion_loss(k_loss, denoise, self.schedule, x0, cond, mask,
                                   cond_drop_prob=0.0, loss_type=self.loss_type,
                                   feature_weights=self.weights, return_aux=True)
        if not any(self.geometric.values()):
            return loss, {}
        return self.geometric_terms(loss, aux, x0, mask, batch["betas"])

    def geometric_terms(self, loss, aux, x0, mask, betas):
        """The x0 loss plus the weighted geometric terms on the forward kinematics of the
        predicted and the true clean motion (both through the same skeleton of ``betas``).
        The prediction's body rides on the true trajectory: the sampler replaces the
        trajectory features by the given trajectory (inpainting), so only the body's joint
        rotations of ``x0_hat`` reach a motion."""
        from jaxmotion.constants import SCENE_FPS
        from jaxmotion.diffusion.geometric_losses import (
            foot_contact_loss,
            joint_position_loss,
            velocity_loss,
        )
        from jaxmotion.motion.representation import TRAJECTORY_DIM, motion_to_joints

        def joints(x):  # frames past the end hold the mean (zeros are no rotation)
            return motion_to_joints(jnp.where(mask[..., None], x * self.std + self.mean,
                                              self.mean), betas)

        x0_hat = jnp.concatenate([x0[..., :TRAJECTORY_DIM], aux["x0_hat"][..., TRAJECTORY_DIM:]],
                                 axis=-1)
        pred, true = joints(x0_hat), jax.lax.stop_gradient(joints(x0))
        w = (self.schedule.alphas_cumprod[aux["t"]] if self.geometric_weighting == "signal"
             else None)
        terms = {"x0": loss}
        if self.geometric["joint"]:
            terms["joint"] = joint_position_loss(pred, true, mask, w)
        if self.geometric["foot_contact"]:
            terms["foot_contact"] = foot_contact_loss(pred, true, mask, SCENE_FPS, w)
        if self.geometric["joint_velocity"]:
            terms["joint_velocity"] = velocity_loss(pred, true, mask, SCENE_FPS, w)
        total = loss + sum(self.geometric[k] * v for k, v in terms.items() if k != "x0")
        return total, terms
