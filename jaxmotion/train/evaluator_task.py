"""Training task ``evaluator``: the text–motion evaluator of the Guo et al. 2022 metrics.

The network and its contrastive loss are in :mod:`jaxmotion.models.evaluator`; loading a
trained one and scoring motions with it in :mod:`jaxmotion.eval.evaluator`. Run it with
``python -m jaxmotion.train --config configs/evaluator.py data_dir=DIR workdir=runs/evaluator``.
"""

from __future__ import annotations

import itertools

import jax
import jax.numpy as jnp
import numpy as np
from flax import nnx

from jaxmotion.constants import TEXT_ENCODER
from jaxmotion.data.format import DatasetError, load_manifest, load_sample
from jaxmotion.data.loader import Dataset
from jaxmotion.eval.evaluator import manifest_sha256
from jaxmotion.models.evaluator import (
    EVALUATOR_VERSION,
    TextMotionEvaluator,
    canonical_motion_features,
    contrastive_loss,
)

__all__ = ["EvaluatorTask", "MotionTextDataset", "fit_feature_stats"]


def fit_feature_stats(model, batches) -> dict:
    """Set ``model.feature_mean`` / ``feature_std`` (the z-score of its input) to the statistics
    of :func:`~jaxmotion.models.evaluator.canonical_motion_features` over the valid frames of
    ``batches`` (dicts with ``joints [B,T,22,3]``, ``mask [B,T]``; std floored at 1e-3); returns
    them as the tensors to export (``stats/feature_mean``, ``stats/feature_std``)."""
    feats = jax.jit(canonical_motion_features)
    rows = [np.asarray(feats(b["joints"], b["mask"]))[b["mask"]] for b in batches]
    x = np.concatenate(rows).astype(np.float64)
    model.feature_mean[...] = jnp.asarray(x.mean(0), jnp.float32)
    model.feature_std[...] = jnp.asarray(np.maximum(x.std(0), 1e-3), jnp.float32)
    return {"stats/feature_mean": np.asarray(model.feature_mean[...]),
            "stats/feature_std": np.asarray(model.feature_std[...])}


class MotionTextDataset(Dataset):
    """A split's motions and texts only (no scene crop, no affordance): batches
    ``{"joints" [B, T, 22, 3] (world frame, zero past the end), "mask" [B, T], "text"}``.

    The evaluator's features ignore where the motion is and which way it faces, so no crop
    or rotation is needed; iteration order and determinism are :class:`Dataset`'s.
    """

    def batch(self, indices, rng: np.random.Generator | None) -> dict:
        del rng  # nothing random: no crop, no augmentation
        n, t_max = len(indices), self.max_frames
        joints = np.zeros((n, t_max, 22, 3), np.float32)
        mask = np.zeros((n, t_max), bool)
        texts = []
        for row, i in enumerate(indices):
            s = load_sample(self.files[int(i)])
            t = s["joints"].shape[0]
            if t > t_max:
                raise DatasetError(f"{self.files[int(i)]}: {t} frames > max_frames={t_max}")
            if not s["mask"].any() or not s["mask"][: s["mask"].sum()].all():
                raise DatasetError(f"{self.files[int(i)]}: the frame mask must be a non-empty "
                                   "prefix (valid frames first)")
            joints[row, :t], mask[row, :t] = s["joints"], s["mask"]
            texts.append(s["text"])
        return {"joints": joints, "mask": mask, "text": texts}


class EvaluatorTask:
    """Task ``evaluator``: :class:`TextMotionEvaluator` trained with :func:`contrastive_loss`.

    Motion features are z-scored with statistics of ``cfg.stats_batches`` training batches
    (stored in the weights file); text embeddings come from the frozen MiniLM with the
    on-disk cache that the other tasks use.
    """

    def _dataset(self, cfg, split: str) -> MotionTextDataset:
        return MotionTextDataset(cfg.data_dir, split, max_frames=cfg.max_frames,
                                 max_samples=cfg.max_samples if split == "train" else None)

    def prepare(self, cfg, raw: dict) -> dict:
        if not hasattr(self, "_cache"):
            from jaxmotion.text import EmbeddingCache, dataset_cache_dir, load_text_encoder

            self._encoder = load_text_encoder(TEXT_ENCODER)
            self._cache = EmbeddingCache(dataset_cache_dir(cfg.data_dir, cfg.workdir, "text",
                                                           "text_cache"))
        emb = np.asarray(self._cache.encode(self._encoder, raw["text"]), np.float32)
        return {"joints": raw["joints"], "mask": raw["mask"], "text_emb": emb}

    def build_model(self, cfg, rngs: nnx.Rngs) -> TextMotionEvaluator:
        manifest = load_manifest(cfg.data_dir)
        self.margin = float(cfg.margin)
        self.info = {"evaluator_version": EVALUATOR_VERSION,
                     "data_manifest_sha256": manifest_sha256(cfg.data_dir),
                     "data_kind": str(manifest.get("kind", "")), "fps": manifest.get("fps")}
        it = self._dataset(cfg, "train").iterate(cfg.batch_size, cfg.seed + 2, prefetch=0)
        model = TextMotionEvaluator(cfg.model, rngs=rngs)
        self.stats = fit_feature_stats(model, itertools.islice(it, cfg.stats_batches))
        return model

    def train_batches(self, cfg, start_step: int):
        ds = self._dataset(cfg, "train")
        return (self.prepare(cfg, b) for b in ds.iterate(cfg.batch_size, cfg.seed,
                                                          start_step=start_step))

    def val_batches(self, cfg) -> list[dict]:
        try:
            ds = self._dataset(cfg, "val")
        except DatasetError:
            return []
        bs = min(cfg.batch_size, len(ds))
        bs -= bs % len(jax.devices())
        if bs < 2:  # a contrastive batch needs a mismatched pair
            return []
        it = ds.iterate(bs, cfg.seed + 1, prefetch=0)
        return [self.prepare(cfg, b) for b in itertools.islice(it, cfg.eval_batches)]

    def loss(self, model: TextMotionEvaluator, batch: dict, key: jax.Array, *, train: bool):
        del key  # dropout draws from the model's streams, re-keyed per step by the loop
        det = not train
        motion_f = model.encode_motion(batch["joints"], batch["mask"], deterministic=det)
        text_f = model.encode_text(batch["text_emb"], deterministic=det)
        e = batch["text_emb"]
        same_text = jnp.sum(jnp.square(e[:, None] - e[None]), axis=-1) < 1e-10
        return contrastive_loss(text_f, motion_f, same_text, self.margin)

    def export_tensors(self) -> dict:
        return dict(self.stats)

    def export_config(self) -> dict:
        from jaxmotion.text import load_text_encoder

        enc = load_text_encoder(TEXT_ENCODER)
        return {**self.info, "text_encoder": TEXT_ENCODER, "text_encoder_sha256": enc.checksum}
