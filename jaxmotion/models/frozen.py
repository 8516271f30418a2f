"""Trained networks loaded frozen for inference: the segmentation backbone and the ADM.

- :func:`load_backbone`: the Point Transformer segmentation network, from its training
  workdir or from the tensors embedded in an ADM weights file.
- :class:`ADMNet`: the frozen backbone plus an ADM; :meth:`ADMNet.condition` builds the
  ADM's per-point condition (backbone features, xyz and, for an ADM that reads one, the
  known target's mask) for every caller: sampling, training loss and the AMDM's training on
  ADM-predicted maps.
- :func:`load_adm`: an :class:`ADMNet`, its diffusion schedule and its affordance
  statistics from one ``.safetensors`` file.

Training tasks (:mod:`jaxmotion.train.tasks`) build on these; nothing here imports training.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
from flax import nnx

from jaxmotion.config import config_from_dict

__all__ = ["ADMNet", "load_adm", "load_backbone"]


def load_backbone(workdir=None, *, tensors=None, model_config=None, prefix="", source=""):
    """The frozen segmentation backbone, from a segmentation run (its workdir or
    ``.safetensors``), from an ADM's weights (workdir or file: the backbone it embeds, e.g.
    ``jaxmotion/assets/adm.safetensors``, so new ADMs can train on the shipped backbone), or
    from tensors and a model config."""
    from jaxmotion.models.configs import PointTransformerConfig
    from jaxmotion.models.segmentation import PointTransformerSeg
    from jaxmotion.models.weights import abstract_module, apply_weights, load_weights, weights_path

    if workdir is not None:
        path = weights_path(workdir)
        if not path.exists():
            raise FileNotFoundError(
                f"no backbone weights at {path}: train one with 'python -m jaxmotion.train "
                f"--config configs/segmentation.py' or name an ADM's weights file, whose "
                f"backbone is embedded (e.g. jaxmotion/assets/adm.safetensors)")
        source = str(path)
        tensors, saved = load_weights(path)
        if saved.get("task") == "adm":
            model_config, prefix = saved["backbone_model"], "backbone/"
        elif saved.get("task", "segmentation") == "segmentation":
            model_config = saved["model"]
        else:
            raise ValueError(f"{source} is a {saved.get('task')!r} checkpoint; the backbone "
                             f"comes from a segmentation run or an ADM's weights")
    pt_cfg = config_from_dict(PointTransformerConfig, model_config)
    net = abstract_module(lambda: PointTransformerSeg(pt_cfg, rngs=nnx.Rngs(0)))
    apply_weights(net, tensors, prefix=prefix, source=source)
    net.eval()
    return net


class ADMNet(nnx.Module):
    """The frozen backbone + the ADM (parameters under ``adm``)."""

    def __init__(self, backbone, adm):
        self.backbone = backbone
        self.adm = adm

    def features(self, xyz, rgb):
        """Per-point backbone features ``[B, N, F]`` of ``xyz``, ``rgb`` ``[B, N, 3]`` (no
        gradient: the backbone is frozen)."""
        feats, _ = self.backbone(xyz, rgb, deterministic=True)
        return jax.lax.stop_gradient(feats)

    def condition(self, xyz, rgb, target=None) -> dict:
        """The ADM's per-point condition for a batch of crops ``xyz``, ``rgb`` ``[B, N, 3]``:
        ``{"features" [B,N,F], "xyz" [B,N,3]}`` and, for an ADM that reads a known target
        (``model.target_input``), ``"target" [B,N]`` float: ``target`` (the target's points,
        bool or float ``[B,N]``), or all zeros when None (no target known). The text
        condition (:func:`jaxmotion.models.adm_text_cond`) is added by the caller, since
        classifier-free guidance drops it and nothing else.

        Raises ``ValueError`` when ``target`` is given to an ADM without the target input."""
        fixed = {"features": self.features(xyz, rgb), "xyz": xyz}
        if self.adm.cfg.target_input:
            known = (jnp.zeros(xyz.shape[:2], jnp.float32) if target is None
                     else jnp.asarray(target, jnp.float32))
            fixed["target"] = known
        elif target is not None:
            raise ValueError("this ADM has no target input (model.target_input=false): leave "
                             "target out, or use an ADM trained with model.target_input=true")
        return fixed


def load_adm(path):
    """Frozen ADM (with its backbone), its schedule and its affordance statistics
    ``(mean [6], std [6])`` from an ADM training workdir or its ``.safetensors`` weights
    file (one read of the file)."""
    from jaxmotion.diffusion import make_schedule
    from jaxmotion.models.adm import make_adm
    from jaxmotion.models.configs import ADMConfig
    from jaxmotion.models.weights import abstract_module, apply_weights, load_weights, weights_path

    if not path:
        raise ValueError("no ADM given: pass an ADM training workdir or its .safetensors file")
    path = weights_path(path)
    src = str(path)
    tensors, saved = load_weights(path)
    if saved.get("task") != "adm":
        raise ValueError(f"{src} is a {saved.get('task')!r} checkpoint, not an ADM one")
    backbone = load_backbone(tensors=tensors, model_config=saved["backbone_model"],
                             prefix="backbone/", source=src)
    adm = abstract_module(lambda: make_adm(config_from_dict(ADMConfig, saved["model"]),
                                           rngs=nnx.Rngs(0)))
    net = ADMNet(backbone, adm)
    apply_weights(net.adm, tensors, prefix="adm/", source=src)
    net.eval()
    sched = make_schedule(saved["diffusion"]["schedule"], saved["diffusion"]["steps"])
    missing = [k for k in ("stats/affordance_mean", "stats/affordance_std") if k not in tensors]
    if missing:
        raise ValueError(f"{src} has no {missing}: retrain ADM with this jaxmotion version")
    stats = (jnp.asarray(tensors["stats/affordance_mean"]),
             jnp.asarray(tensors["stats/affordance_std"]))
    return net, sched, stats
