"""Training task ``cvae``: the HUMANISE conditional VAE baseline (:mod:`jaxmotion.models.cvae`).

Each batch is a dataset crop (:class:`jaxmotion.data.Dataset`): points and colours, the
target's points, the motion's joints and SMPL-X parameters, and the text's word-token states
(the frozen MiniLM's, through the on-disk token cache). The motion's features
(:func:`~jaxmotion.models.cvae.cvae_features`) are taken in the crop frame (pelvis =
``joints[:, 0]``, global orientation turned by the crop's rotation), not normalised: metres,
6D and radians, as the L1 terms weigh them. The loss is

``w_t L1(translation) + w_o L1(orientation 6D) + w_p L1(body pose) + w_j L1(joints)
+ w_kl KL + w_c MSE(target centre)``

with HUMANISE's weights 1, 1, 10, 0.1 and 0.1 for translation, orientation, pose, KL and the
centre; its marker term (L1 on 67 body-surface markers, x10) is the L1 on the 22 joints of the
forward kinematics here (``joint_weight`` 10). ``action`` trains an action-specific model on
that action's samples only (HUMANISE trains one per action); ``""`` the action-agnostic one.
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np
from flax import nnx

from jaxmotion.data.format import DatasetError
from jaxmotion.train.data_task import DataTask, split_dataset

__all__ = ["CVAENet", "CVAETask", "action_dataset"]

#: Loss terms and the config field that weighs each.
WEIGHTS = {"translation": "translation_weight", "orientation": "orientation_weight",
           "pose": "pose_weight", "joints": "joint_weight", "kl": "kl_weight",
           "centre": "centre_weight"}


class CVAENet(nnx.Module):
    """Holds the cVAE under ``net`` (the prefix of its weights in the exported file)."""

    def __init__(self, net):
        self.net = net


def action_dataset(cfg, split: str):
    """The ``split`` of ``cfg.data_dir`` (:func:`split_dataset`), only the samples of
    ``cfg.action`` when it is set; :class:`DatasetError` when none is left."""
    ds = split_dataset(cfg, split)
    if not cfg.action:
        return ds

    def action_of(path):  # the sample's action alone (an npz member is read on its own)
        with np.load(path, allow_pickle=False) as z:
            return str(z["action"])

    ds.files = [f for f in ds.files if action_of(f) == cfg.action]
    if not ds.files:
        raise DatasetError(f"{cfg.data_dir}: the {split} split has no {cfg.action!r} sample "
                           "for an action-specific cVAE (action=...); set action='' to train "
                           "the action-agnostic model")
    return ds


def crop_targets(batch):
    """``(features [B, T, 72], joints [B, T, 22, 3], centre [B, 3], centre_valid [B])`` of a
    batch in its crop frame: the motion's features, its joints and the target's box centre
    ``(min + max) / 2`` (valid where the crop holds a point of the target)."""
    from jaxmotion.geometry.rotations import axis_angle_to_matrix
    from jaxmotion.models.cvae import cvae_features

    rot = jnp.asarray(batch["rotation"], jnp.float32)[:, None]  # [B, 1, 3, 3]
    g = rot @ axis_angle_to_matrix(jnp.asarray(batch["global_orient"], jnp.float32))
    joints = jnp.asarray(batch["joints"], jnp.float32)
    feats = cvae_features(joints[:, :, 0], g, batch["body_pose"])
    m = jnp.asarray(batch["target_mask"], bool)[..., None]
    pts = jnp.asarray(batch["points"], jnp.float32)
    lo = jnp.min(jnp.where(m, pts, jnp.inf), axis=1)
    hi = jnp.max(jnp.where(m, pts, -jnp.inf), axis=1)
    valid = jnp.any(m[..., 0], axis=1)
    centre = jnp.where(valid[:, None], 0.5 * (lo + hi), 0.0)
    return feats, joints, centre, valid


class CVAETask(DataTask):
    """The ``cvae`` task (module docstring)."""

    def text_tokens(self, cfg) -> int:
        return int(cfg.model.text_tokens)

    def build_model(self, cfg, rngs):
        from jaxmotion.models.cvae import CVAE

        if cfg.model.num_points != cfg.crop.num_points:
            raise ValueError(f"model.num_points={cfg.model.num_points} must equal "
                             f"crop.num_points={cfg.crop.num_points}: the scene branch "
                             "flattens a fixed number of tokens")
        self.weights = {k: float(getattr(cfg, name)) for k, name in WEIGHTS.items()}
        return CVAENet(CVAE(cfg.model, rngs=rngs))

    def dataset(self, cfg, split: str):
        return action_dataset(cfg, split)

    def loss(self, model, batch, key, *, train):
        from jaxmotion.models.cvae import cvae_loss_terms, features_to_joints

        feats, joints, centre, valid = crop_targets(batch)
        mask = jnp.asarray(batch["mask"], bool)
        cond = {"xyz": batch["points"], "rgb": batch["colors"], "tokens": batch["text_tokens"],
                "token_mask": batch["text_mask"], "betas": batch["betas"]}
        out = model.net(key, feats, mask, cond, deterministic=not train)
        pred_joints = features_to_joints(out["features"], batch["betas"])
        terms = cvae_loss_terms(out["features"], feats, mask, out["mu"], out["logvar"],
                                out["centre"], centre, valid, pred_joints=pred_joints,
                                true_joints=joints)
        total = sum(self.weights[k] * v for k, v in terms.items())
        return total, terms
