"""The object-centric pipeline's denoisers (Cen et al., CVPR 2024): trajectory and completion.

``model(x, t, cond, *, deterministic=None) -> x0 [B, T, motion_dim]``: the x0 prediction of the
normalised features of :mod:`jaxmotion.motion.representation` (9 per frame for the trajectory
model, 135 for the completion model), with

- ``x [B, T, motion_dim]``: the noisy features; ``t [B]``: the diffusion step;
- ``cond["mask"] [B, T]`` bool, True = valid frame (default all valid);
- ``cond["text"] [B, text_dim]``: the sentence embedding; ``cond["betas"] [B, betas_dim]``;
- ``cond["env_sensor"]``, ``cond["target_sensor"]`` ``[B, r, r, r, 7]``: the environment and
  target sensors (:mod:`jaxmotion.geometry.sensors`);
- completion only: ``cond["trajectory"] [B, T, 9]`` (the stage-1 trajectory, normalised as the
  first 9 features), with ``traj_sensor``, ``cond["traj_sensor"] [B, T, r, r, r, 7]``, and
  with ``traj_velocity``, ``cond["traj_velocity"] [B, T, 4]`` (the trajectory's motion in
  the body's heading frame, :func:`~jaxmotion.motion.representation.trajectory_velocity`,
  computed from the trajectory in metres);
- with ``action_token``: ``cond["action"] [B]`` int, the action the instruction asks for
  (:data:`ACTION_CLASSES`: index into walk, sit, stand_up, lie; 4 = unknown; default unknown),
  whose learned embedding is added to the text token;
- optional ``cond["drop_text"]``, ``cond["drop_scene"] [B]`` (bool / 0-1): condition dropout
  for classifier-free guidance, done inside: the text embedding, or both scene sensors' tokens,
  of those rows are zeroed (the authors have none; the issue asks for it).

The backbone is a transformer decoder as in the authors' code: the target sequence is the
condition tokens [shape, text, environment sensor, target sensor] followed by the frame tokens;
its memory is the one timestep token. A sensor becomes a token by a two-layer SiLU MLP over its
flattened voxels. The completion model adds one token per frame (an MLP of the stage-1
trajectory and its trajectory sensor) before the motion tokens; a frame's trajectory token and
motion token share the frame's sinusoidal position and differ by a learned type vector.
Condition tokens are never masked; padded frames are.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
from flax import nnx

from jaxmotion.constants import ACTION_CLASSES, UNKNOWN_ACTION
from jaxmotion.models.configs import ObjectCentricConfig
from jaxmotion.models.layers import (
    TimestepEmbedder,
    TransformerDecoderLayer,
    keep_rows,
    low_frequency_projection,
    sinusoidal_embedding,
)
from jaxmotion.motion.representation import VELOCITY_DIM

__all__ = ["ACTION_CLASSES", "SENSOR_CHANNELS", "UNKNOWN_ACTION", "ObjectCentricDenoiser"]

SENSOR_CHANNELS = 7
#: The actions an ``action_token`` model tells apart (the dataset's ``ACTIONS``), then unknown.
N_COND = 4  # shape, text, environment sensor, target sensor


class _SensorMLP(nnx.Module):
    """Flattened sensor ``[..., r, r, r, 7]`` (+ extra features) -> token ``[..., d]``."""

    def __init__(self, in_dim: int, hidden: int, out_dim: int, *, rngs: nnx.Rngs):
        self.fc1 = nnx.Linear(in_dim, hidden, rngs=rngs)
        self.fc2 = nnx.Linear(hidden, out_dim, rngs=rngs)

    def __call__(self, x):
        return self.fc2(jax.nn.silu(self.fc1(x)))


def _flat_sensor(s, res):
    s = jnp.asarray(s, jnp.float32)
    want = (res, res, res, SENSOR_CHANNELS)
    if s.shape[-4:] != want:
        raise ValueError(f"a sensor must be [..., {res}, {res}, {res}, {SENSOR_CHANNELS}] "
                         f"(the config's sensor_res={res}), got {s.shape}")
    return s.reshape(*s.shape[:-4], -1)


class ObjectCentricDenoiser(nnx.Module):
    """The trajectory (``cfg.kind="trajectory"``) or completion denoiser (module docstring)."""

    def __init__(self, cfg: ObjectCentricConfig, *, rngs: nnx.Rngs):
        self.cfg = cfg
        d = cfg.d_model
        flat = cfg.sensor_res ** 3 * SENSOR_CHANNELS
        self.time_embed = TimestepEmbedder(cfg.time_dim, d, rngs=rngs)
        self.betas_proj = nnx.Linear(cfg.betas_dim, d, rngs=rngs)
        self.text_proj = nnx.Linear(cfg.text_dim, d, rngs=rngs)
        if cfg.action_token:  # starts at 0: switching it on keeps a trained model's function
            self.action_embed = nnx.Embed(len(ACTION_CLASSES), d,
                                          embedding_init=nnx.initializers.zeros, rngs=rngs)
        self.env_mlp = _SensorMLP(flat, cfg.sensor_hidden, d, rngs=rngs)
        self.target_mlp = _SensorMLP(flat, cfg.sensor_hidden, d, rngs=rngs)
        if cfg.kind == "completion":
            self.traj_mlp = _SensorMLP(9 + (flat if cfg.traj_sensor else 0)
                                       + (VELOCITY_DIM if cfg.traj_velocity else 0),
                                       cfg.sensor_hidden, d, rngs=rngs)
            self.type_embed = nnx.Param(0.02 * jax.random.normal(rngs.params(), (2, d)))
        self.motion_in = nnx.Linear(cfg.motion_dim, d, rngs=rngs)
        self.motion_out = nnx.Linear(d, cfg.motion_dim, rngs=rngs)
        self.pos_drop = nnx.Dropout(cfg.dropout, rngs=rngs)
        self.layers = nnx.List([
            TransformerDecoderLayer(d, cfg.num_heads, cfg.ff_dim, dropout=cfg.dropout,
                                    act="gelu", norm_first=cfg.norm_first, rngs=rngs)
            for _ in range(cfg.num_layers)])

    def __call__(self, x, t, cond, *, deterministic: bool | None = None):
        det, cfg = deterministic, self.cfg
        x = jnp.asarray(x, jnp.float32)
        if x.ndim != 3 or x.shape[-1] != cfg.motion_dim:
            raise ValueError(f"x must be [B, T, {cfg.motion_dim}], got {x.shape}")
        b, nt = x.shape[:2]
        for name, shape in (("text", (b, cfg.text_dim)), ("betas", (b, cfg.betas_dim))):
            if name not in cond or tuple(jnp.shape(cond[name])) != shape:
                raise ValueError(f"cond[{name!r}] must be {list(shape)}, got "
                                 f"{jnp.shape(cond[name]) if name in cond else 'nothing'}")
        mask = cond.get("mask")
        mask = jnp.ones((b, nt), bool) if mask is None else jnp.asarray(mask, bool)
        res = cfg.sensor_res
        keep_scene, keep_text = keep_rows(cond, "drop_scene", b), keep_rows(cond, "drop_text", b)
        text_tok = self.text_proj(jnp.asarray(cond["text"], jnp.float32) * keep_text)
        if cfg.action_token:
            action = cond.get("action")
            action = (jnp.full((b,), UNKNOWN_ACTION, jnp.int32) if action is None
                      else jnp.broadcast_to(jnp.asarray(action, jnp.int32), (b,)))
            action = jnp.where(keep_text[:, 0] > 0, action, UNKNOWN_ACTION)
            text_tok = text_tok + self.action_embed(action)
        tokens = [
            self.betas_proj(jnp.asarray(cond["betas"], jnp.float32)),
            text_tok,
            self.env_mlp(_flat_sensor(cond["env_sensor"], res) * keep_scene),
            self.target_mlp(_flat_sensor(cond["target_sensor"], res) * keep_scene),
        ]
        pos = sinusoidal_embedding(jnp.arange(N_COND + nt), cfg.d_model)
        seq = [jnp.stack(tokens, axis=1) + pos[None, :N_COND]]
        seq_mask = [jnp.ones((b, N_COND), bool)]
        frame_pos = pos[None, N_COND:]
        if cfg.kind == "completion":
            traj = jnp.asarray(cond["trajectory"], jnp.float32)
            if traj.shape != (b, nt, 9):
                raise ValueError(f"cond['trajectory'] must be [{b}, {nt}, 9], got {traj.shape}")
            feats = traj
            if cfg.traj_sensor:
                ts = _flat_sensor(cond["traj_sensor"], res)
                if ts.shape[:2] != (b, nt):
                    raise ValueError(f"cond['traj_sensor'] must be [{b}, {nt}, {res}, {res}, "
                                     f"{res}, 7], got {jnp.shape(cond['traj_sensor'])}")
                feats = jnp.concatenate([traj, ts * keep_scene[:, :, None]], axis=-1)
            if cfg.traj_velocity:
                vel = cond.get("traj_velocity")
                if vel is None or jnp.shape(vel) != (b, nt, VELOCITY_DIM):
                    raise ValueError(f"cond['traj_velocity'] must be [{b}, {nt}, {VELOCITY_DIM}]"
                                     f" (traj_velocity=True), got "
                                     f"{None if vel is None else jnp.shape(vel)}")
                feats = jnp.concatenate([feats, jnp.asarray(vel, jnp.float32)], axis=-1)
            seq.append(self.traj_mlp(feats) + frame_pos + self.type_embed[0])
            seq_mask.append(mask)
            motion = self.motion_in(x) + frame_pos + self.type_embed[1]
        else:
            motion = self.motion_in(x) + frame_pos
        seq.append(motion)
        seq_mask.append(mask)
        h = self.pos_drop(jnp.concatenate(seq, axis=1), deterministic=det)
        h_mask = jnp.concatenate(seq_mask, axis=1)
        memory = self.time_embed(jnp.broadcast_to(jnp.asarray(t), (b,)))[:, None]
        for layer in self.layers:
            h = layer(h, memory, h_mask, None, deterministic=det)
        out = self.motion_out(h[:, -nt:])
        if cfg.temporal_basis:
            out = low_frequency_projection(out, mask, cfg.temporal_basis)
        return out
