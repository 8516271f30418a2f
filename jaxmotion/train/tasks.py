"""What each training config trains: the backbone, ADM and AMDM of the affordance pipeline.

A task builds its model, turns dataset batches (:class:`jaxmotion.data.Dataset`)
into model inputs, and computes the loss inside the jitted step:

- ``segmentation``: the Point Transformer backbone on the rooms' semantic labels
  (cross-entropy); its ``model.safetensors`` is ADM's frozen feature extractor.
- ``adm``: the affordance diffusion model; x0-prediction loss on the z-scored
  ground-truth affordance map, conditioned on the text embedding and the frozen
  backbone's per-point features (text dropped with ``cond_drop_prob``).
- ``amdm``: the affordance-to-motion diffusion model (and the one-stage baseline
  with ``model.scene_input=rgb``); masked x0 loss on the z-scored motion features,
  conditioned on text and the affordance map, each dropped independently. With
  ``predicted_fraction > 0`` and a trained ADM (``adm_workdir``), that fraction of
  each batch uses an ADM-sampled map (DDIM, ``adm_sampler_steps``) instead of the
  ground truth, as the paper mixes them 50/50.
- ``cvae``: the HUMANISE conditional VAE baseline (:class:`jaxmotion.train.cvae_task.CVAETask`;
  L1 reconstruction, KL and target-centre terms).
- ``evaluator``: the text–motion evaluator of the Guo et al. 2022 metrics
  (:class:`jaxmotion.eval.evaluator.EvaluatorTask`; contrastive hinge loss).

Text embeddings come from the frozen MiniLM encoder with an on-disk cache, and
normalisation statistics from the dataset's ``stats.npz``.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
from flax import nnx

from jaxmotion.config import config_to_dict
from jaxmotion.models.frozen import ADMNet, load_adm, load_backbone
from jaxmotion.models.weights import flatten_state
from jaxmotion.train.cvae_task import CVAETask
from jaxmotion.train.data_task import DataTask, dataset_stats
from jaxmotion.train.evaluator_task import EvaluatorTask
from jaxmotion.train.object_centric_task import ObjectCentricTask
from jaxmotion.train.objects_task import ObjectsTask
from jaxmotion.train.recognizer_task import RecognizerTask

__all__ = ["TASKS", "ADMTask", "AMDMTask", "SegmentationTask", "get_task"]


# --------------------------------------------------------------------------- segmentation
class SegmentationTask(DataTask):
    needs_text = False

    def build_model(self, cfg, rngs):
        from jaxmotion.models import PointTransformerSeg

        return PointTransformerSeg(cfg.model, rngs=rngs)

    def loss(self, model, batch, key, *, train):
        from jaxmotion.models import segmentation_loss

        _, logits = model(batch["points"], batch["colors"], deterministic=not train)
        loss, acc = segmentation_loss(logits, batch["semantic"])
        return loss, {"accuracy": acc}


# --------------------------------------------------------------------------- ADM
def _text_condition(batch):
    """A batch's text condition: the pooled embedding, or the word-level mapping (see
    :func:`jaxmotion.models.adm_text_cond`) when the batch carries token states."""
    if "text_tokens" in batch:
        return {"pooled": batch["text_emb"], "tokens": batch["text_tokens"],
                "mask": batch["text_mask"]}
    return batch["text_emb"]


class ADMTask(DataTask):
    trainable = nnx.All(nnx.Param, nnx.PathContains("adm"))

    def text_tokens(self, cfg) -> int:
        return int(cfg.model.text_tokens)

    def build_model(self, cfg, rngs):
        from jaxmotion.diffusion import make_schedule
        from jaxmotion.models import make_adm

        if not cfg.backbone_workdir:
            raise ValueError(
                "ADM needs the pretrained backbone: set backbone_workdir=DIR to the workdir of "
                "'python -m jaxmotion.train --config configs/segmentation.py'")
        backbone = load_backbone(cfg.backbone_workdir)
        self.backbone_config = config_to_dict(backbone.cfg)
        self.backbone_tensors = {f"params/backbone/{k}": v for k, v in
                                 flatten_state(nnx.state(backbone, nnx.Param)).items()}
        if backbone.cfg.out_dim != cfg.model.feature_dim:
            raise ValueError(f"the backbone gives {backbone.cfg.out_dim}-d features but "
                             f"model.feature_dim={cfg.model.feature_dim}; make them equal")
        self.schedule = make_schedule(cfg.diffusion.schedule, cfg.diffusion.steps)
        st = dataset_stats(cfg)
        self.mean = jnp.asarray(st["affordance_mean"])
        self.std = jnp.asarray(st["affordance_std"])
        adm = make_adm(cfg.model, rngs=rngs)
        if getattr(cfg, "init_from", ""):
            _init_adm(adm, cfg)
        self.sigma = float(cfg.affordance.sigma)
        self.target_drop = float(getattr(cfg, "target_drop", 0.0))
        return ADMNet(backbone, adm)

    # -- selection by grounding (the training loop's probe) ---------------------------------
    probe_score = "instance_success@0.3"  # what model_best.safetensors maximises

    def probe_every(self, cfg) -> int:
        return int(getattr(cfg, "grounding_every", 0))

    def probe_batches(self, cfg) -> list[dict]:
        """The first ``grounding_cases`` val crops (as the paper protocol crops them), in
        batches of ``batch_size``; the last is padded with ``valid`` False rows."""
        from jaxmotion.data.cases import load_cases
        from jaxmotion.diffusion import SamplerSpec

        self.probe_spec = SamplerSpec("ddim", int(cfg.grounding_steps),
                                      guidance=float(cfg.grounding_guidance))
        try:
            cases, _ = load_cases(cfg.data_dir, "val", config_to_dict(cfg),
                                  num_cases=int(cfg.grounding_cases), seed=0)
        except FileNotFoundError as err:
            raise ValueError(f"grounding_every={cfg.grounding_every} scores the ADM on the val "
                             f"split, and {cfg.data_dir} has none ({err}); set "
                             "grounding_every=0 or use a dataset with a val split") from err
        n_dev = len(jax.devices())
        bs = max(n_dev, cfg.batch_size - cfg.batch_size % n_dev)
        batches = []
        for lo in range(0, len(cases), bs):
            part = cases[lo:lo + bs]
            rows = part + [part[0]] * (bs - len(part))
            raw = {k: np.stack([c[k] for c in rows]) for k in
                   ("points", "colors", "target_mask", "target_class_mask")}
            raw["valid"] = np.arange(bs) < len(part)
            raw["text"] = [c["text"] for c in rows]
            batches.append(self.prepare(cfg, raw))
        return batches

    def probe(self, model, batch, key) -> dict:
        """Per crop: whether the EMA ADM's map reaches the target instance
        (``instance_success@0.3``), its class (``class_success@0.3``), and the class's mean
        distance (``min_dist``, metres), as :mod:`jaxmotion.eval.grounding` defines them."""
        from jaxmotion.eval.grounding import affordance_grounding
        from jaxmotion.geometry.affordance import affordance_to_distance
        from jaxmotion.pipelines.affordance import adm_map_one

        keys = jax.random.split(key, batch["points"].shape[0])
        # an ADM with the target input is probed as generate runs it: told the target
        target = batch["target_mask"] if model.adm.cfg.target_input else None
        maps = jax.vmap(lambda k, p, c, t, m: adm_map_one(
            model, self.schedule, (self.mean, self.std), k, p, c, t, self.probe_spec,
            target=m))(keys, batch["points"], batch["colors"], _text_condition(batch), target)
        d = affordance_to_distance(maps, self.sigma)
        inst = jax.vmap(affordance_grounding)(d, batch["target_mask"])
        cls = jax.vmap(affordance_grounding)(d, batch["target_class_mask"])
        return {"instance_success@0.3": inst["success@0.3"],
                "class_success@0.3": cls["success@0.3"], "min_dist": cls["min_dist"]}

    def export_tensors(self) -> dict:
        # The frozen backbone travels inside ADM's weights file: one self-contained file.
        return {"stats/affordance_mean": self.mean, "stats/affordance_std": self.std,
                **self.backbone_tensors}

    def export_config(self) -> dict:
        return {"backbone_model": self.backbone_config}

    def loss(self, model, batch, key, *, train):
        from jaxmotion.diffusion import diffusion_loss
        from jaxmotion.models import adm_text_cond

        x0 = (batch["affordance"] - self.mean) / self.std
        target = None
        if model.adm.cfg.target_input:  # the known target, dropped per example (target_drop)
            key, k_drop = jax.random.split(key)
            p = self.target_drop if train else 0.0
            keep = jax.random.uniform(k_drop, (x0.shape[0], 1)) >= p
            target = jnp.asarray(batch["target_mask"], jnp.float32) * keep
        fixed = model.condition(batch["points"], batch["colors"], target)

        def denoise(x, t, cond):
            return model.adm(x, t, {**adm_text_cond(cond["text"]), **fixed},
                             deterministic=not train)

        # The pooled vector and the token states are one "text" entry: dropped together.
        loss = diffusion_loss(key, denoise, self.schedule, x0, {"text": _text_condition(batch)},
                              cond_drop_prob=self.cond_drop if train else 0.0)
        return loss, {}


def _read_init(cfg, task: str):
    """``(path, tensors, saved config)`` of ``cfg.init_from``, refused unless it is a ``task``
    checkpoint."""
    from jaxmotion.models.weights import load_weights, weights_path

    path = weights_path(cfg.init_from)
    tensors, saved = load_weights(path)
    if saved.get("task") != task:
        raise ValueError(f"init_from={cfg.init_from}: {path} is a {saved.get('task')!r} "
                         f"checkpoint, not an {task.upper()} one")
    return path, tensors, saved


def _init_adm(adm, cfg) -> None:
    """Start ``adm`` from the weights of another ADM run (``cfg.init_from``)."""
    from jaxmotion.models.weights import apply_weights

    path, tensors, saved = _read_init(cfg, "adm")
    mine = config_to_dict(cfg.model)
    theirs = {"target_input": False, **saved["model"]}
    grow = mine["target_input"] and not theirs["target_input"]
    diff = [f"{k} ({theirs.get(k)!r} vs {mine[k]!r})" for k in sorted(mine)
            if theirs.get(k) != mine[k] and not (grow and k == "target_input")]
    if diff:
        raise ValueError(f"init_from={cfg.init_from}: its model config differs in "
                         f"{', '.join(diff)}; pass the same model.* settings")
    if grow:  # the target channel's input weights start at 0: the same function as theirs
        name = next(k for k in tensors if k.endswith("adm/point_in/kernel"))
        kernel = np.asarray(tensors[name])
        at = cfg.model.affordance_dim + cfg.model.feature_dim  # [x, features, target, xyz]
        tensors = {**tensors, name: np.insert(kernel, at, 0.0, axis=0)}
    apply_weights(adm, tensors, prefix="adm/", source=str(path))


# --------------------------------------------------------------------------- AMDM
class AMDMNet(nnx.Module):
    """The trainable AMDM (parameters under ``amdm``) and, optionally, a frozen ADM + backbone."""

    def __init__(self, amdm, adm_net=None):
        self.amdm = amdm
        self.adm_net = adm_net


class AMDMTask(DataTask):
    trainable = nnx.All(nnx.Param, nnx.PathContains("amdm"))

    def text_tokens(self, cfg) -> int:
        # the frozen ADM that samples maps for training may read token states
        return int(getattr(self, "adm_text_tokens", 0))

    def build_model(self, cfg, rngs):
        from jaxmotion.diffusion import make_schedule
        from jaxmotion.models import AMDM

        self.schedule = make_schedule(cfg.diffusion.schedule, cfg.diffusion.steps)
        st = dataset_stats(cfg)
        self.m_mean, self.m_std = jnp.asarray(st["motion_mean"]), jnp.asarray(st["motion_std"])
        self.a_mean = jnp.asarray(st["affordance_mean"])
        self.a_std = jnp.asarray(st["affordance_std"])
        self.velocity_weight = float(getattr(cfg, "velocity_weight", 0.0))
        self.acceleration_weight = float(getattr(cfg, "acceleration_weight", 0.0))
        self.geometric_weighting = str(getattr(cfg, "geometric_weighting", "uniform"))
        if (self.velocity_weight or self.acceleration_weight) and cfg.model.motion_dim != 66:
            raise ValueError("velocity_weight / acceleration_weight need the 66-d joint-position "
                             f"features (model.motion_dim=66), got {cfg.model.motion_dim}")
        self.predicted_fraction = float(cfg.predicted_fraction)
        self.adm_steps = int(cfg.adm_sampler_steps)
        adm_net = None
        if self.predicted_fraction > 0 and cfg.model.scene_input == "affordance":
            from jaxmotion.models.weights import read_config

            if cfg.adm_workdir and read_config(cfg.adm_workdir).get("crop", {}).get(
                    "centre") == "room":
                raise ValueError(
                    f"adm_workdir={cfg.adm_workdir} is a room-view ADM (crop.centre=room); the "
                    "AMDM's predicted maps are sampled on its own crops, so they need a "
                    "crop-view ADM: point adm_workdir to one, or set predicted_fraction=0")
            if not cfg.adm_workdir:
                raise ValueError("predicted_fraction > 0 needs a trained ADM: set "
                                 "adm_workdir=DIR (or predicted_fraction=0 to train on "
                                 "ground-truth affordance only)")
            adm_net, self.adm_schedule, _ = load_adm(cfg.adm_workdir)
            self.adm_text_tokens = int(adm_net.adm.cfg.text_tokens)
        amdm = AMDM(cfg.model, rngs=rngs)
        if getattr(cfg, "init_from", ""):
            self._init_amdm(amdm, cfg)
        return AMDMNet(amdm, adm_net)

    def _init_amdm(self, amdm, cfg) -> None:
        """Start ``amdm`` from another AMDM's weights (``cfg.init_from``), with its
        normalisation statistics (the same function, whatever this dataset's statistics)."""
        from jaxmotion.models.weights import apply_weights

        path, tensors, saved = _read_init(cfg, "amdm")
        mine = config_to_dict(cfg.model)
        # temporal_basis has no parameters: a fine-tune may switch it on
        diff = [f"{k} ({saved['model'].get(k)!r} vs {mine[k]!r})" for k in sorted(mine)
                if saved["model"].get(k, mine[k]) != mine[k] and k != "temporal_basis"]
        if diff:
            raise ValueError(f"init_from={cfg.init_from}: its model config differs in "
                             f"{', '.join(diff)}; pass the same model.* settings")
        apply_weights(amdm, tensors, prefix="amdm/", source=str(path))
        for name in ("motion_mean", "motion_std", "affordance_mean", "affordance_std"):
            short = {"motion_mean": "m_mean", "motion_std": "m_std",
                     "affordance_mean": "a_mean", "affordance_std": "a_std"}[name]
            setattr(self, short, jnp.asarray(tensors[f"stats/{name}"]))

    def export_tensors(self) -> dict:
        return {"stats/motion_mean": self.m_mean, "stats/motion_std": self.m_std,
                "stats/affordance_mean": self.a_mean, "stats/affordance_std": self.a_std}

    def _predicted_affordance(self, model, batch, key):
        """ADM-sampled (normalised) maps for the batch, DDIM with few steps, no gradients."""
        from jaxmotion.diffusion import ddim_sample
        from jaxmotion.models import adm_text_cond

        net = model.adm_net
        # an ADM that reads a known target is told the batch's target, as generate tells it
        target = batch["target_mask"] if net.adm.cfg.target_input else None
        fixed = {**net.condition(batch["points"], batch["colors"], target),
                 **adm_text_cond(_text_condition(batch))}

        def denoise(x, t, cond):
            return net.adm(x, t, fixed, deterministic=True)

        shape = batch["affordance"].shape
        return jax.lax.stop_gradient(ddim_sample(key, denoise, self.adm_schedule, shape,
                                                 num_steps=self.adm_steps))

    def loss(self, model, batch, key, *, train):
        from jaxmotion.diffusion import diffusion_loss

        k_mix, k_adm, k_drop, k_loss = jax.random.split(key, 4)
        b = batch["motion"].shape[0]
        x0 = (batch["motion"] - self.m_mean) / self.m_std
        mask = batch["mask"]
        if model.amdm.cfg.scene_input == "affordance":
            aff = (batch["affordance"] - self.a_mean) / self.a_std
            if model.adm_net is not None and train:
                use_pred = jax.random.uniform(k_mix, (b,)) < self.predicted_fraction
                pred = self._predicted_affordance(model, batch, k_adm)
                aff = jnp.where(use_pred[:, None, None], pred, aff)
            scene = {"xyz": batch["points"], "affordance": aff}
        else:
            scene = {"xyz": batch["points"], "rgb": batch["colors"]}
        p = self.cond_drop if train else 0.0
        kt, ka = jax.random.split(k_drop)
        drops = {"drop_text": jax.random.uniform(kt, (b,)) < p,
                 "drop_affordance": jax.random.uniform(ka, (b,)) < p}
        cond = {"text": batch["text_emb"], "mask": mask, **scene, **drops}

        def denoise(x, t, c):
            return model.amdm(x, t, c, deterministic=not train)

        loss, aux = diffusion_loss(k_loss, denoise, self.schedule, x0, cond, mask,
                                   cond_drop_prob=0.0, return_aux=True)
        if not (self.velocity_weight or self.acceleration_weight):
            return loss, {}
        from jaxmotion.constants import SCENE_FPS
        from jaxmotion.diffusion.geometric_losses import acceleration_loss, velocity_loss

        def metres(x):  # z-scored absolute joint positions -> metres (the mean cancels)
            return (x * self.m_std).reshape(x.shape[0], x.shape[1], -1, 3)

        pred, true = metres(aux["x0_hat"]), metres(x0)
        w = (self.schedule.alphas_cumprod[aux["t"]] if self.geometric_weighting == "signal"
             else None)
        terms = {"x0": loss}
        if self.velocity_weight:
            terms["velocity"] = velocity_loss(pred, true, mask, SCENE_FPS, w)
            loss = loss + self.velocity_weight * terms["velocity"]
        if self.acceleration_weight:
            terms["acceleration"] = acceleration_loss(pred, true, mask, SCENE_FPS, w)
            loss = loss + self.acceleration_weight * terms["acceleration"]
        return loss, terms


TASKS = {"segmentation": SegmentationTask, "adm": ADMTask, "amdm": AMDMTask,
         "evaluator": EvaluatorTask, "recognizer": RecognizerTask,
         "trajectory": ObjectCentricTask, "completion": ObjectCentricTask, "cvae": CVAETask,
         "objects": ObjectsTask}


def get_task(cfg):
    """The task object for ``cfg.task`` (with its condition-dropout rate)."""
    if cfg.task not in TASKS:
        raise ValueError(f"unknown task {cfg.task!r}; valid: {', '.join(TASKS)}")
    task = TASKS[cfg.task]()
    task.cond_drop = float(getattr(getattr(cfg, "diffusion", None), "cond_drop_prob", 0.0))
    return task
