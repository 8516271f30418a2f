"""Point Transformer semantic segmentation: the frozen per-point feature backbone of ADM.

Pretrained on the synthetic rooms' semantic labels, then frozen: ADM receives its ``out_dim``
(32) features per point, computed outside ADM (``model.eval(); feats, _ = model(xyz, rgb)``).
The classification head is the official one (Linear-Norm-ReLU-Linear on the finest decoder
features). Labels are the synthetic world's semantic ids (0..num_classes-1, -1 = unlabelled).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import optax
from flax import nnx

from jaxmotion.models.configs import PointTransformerConfig
from jaxmotion.models.point_transformer import Norm, PointTransformerUNet

__all__ = ["PointTransformerSeg", "segmentation_loss"]


class PointTransformerSeg(nnx.Module):
    """``(xyz [B, N, 3], rgb [B, N, in_channels]) -> (features [B, N, out_dim], logits [B, N, K])``.

    ``in_channels`` (3 for rgb; 0 for xyz only) and ``num_classes`` come from the config. The
    features are the U-Net's finest output (``planes[0]`` wide), linearly projected when
    ``out_dim != planes[0]``.
    """

    def __init__(self, cfg: PointTransformerConfig, *, rngs: nnx.Rngs):
        self.cfg = cfg
        self.unet = PointTransformerUNet(cfg, cfg.in_channels, rngs=rngs)
        c = cfg.planes[0]
        self.proj = None if cfg.out_dim == c else nnx.Linear(c, cfg.out_dim, rngs=rngs)
        self.cls1 = nnx.Linear(c, c, rngs=rngs)
        self.cls_norm = Norm(cfg.norm, c, rngs=rngs)
        self.cls2 = nnx.Linear(c, cfg.num_classes, rngs=rngs)

    def geometry(self, xyz):
        """Precomputable geometry (:func:`jaxmotion.models.point_transformer.build_geometry`)."""
        return self.unet.geometry(xyz)

    def __call__(self, xyz, rgb=None, *, geometry=None, deterministic=None):
        x = self.unet(xyz, rgb, geometry=geometry, deterministic=deterministic)
        feats = x if self.proj is None else self.proj(x)
        h = jax.nn.relu(self.cls_norm(self.cls1(x), deterministic=deterministic))
        return feats, self.cls2(h)


def segmentation_loss(logits: jax.Array, labels: jax.Array, ignore_index: int = -1):
    """Mean cross-entropy over labelled points and their accuracy.

    ``logits [..., N, K]``, ``labels [..., N]`` int (``ignore_index`` or out of range = skip).
    Returns ``(loss, accuracy)`` scalars (0 when nothing is labelled).
    """
    k = logits.shape[-1]
    valid = (labels != ignore_index) & (labels >= 0) & (labels < k)
    safe = jnp.where(valid, labels, 0)
    ce = optax.softmax_cross_entropy_with_integer_labels(logits.astype(jnp.float32), safe)
    n = jnp.maximum(jnp.sum(valid), 1)
    loss = jnp.sum(jnp.where(valid, ce, 0.0)) / n
    acc = jnp.sum(valid & (jnp.argmax(logits, -1) == safe)) / n
    return loss, acc
