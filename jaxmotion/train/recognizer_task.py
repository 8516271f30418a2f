"""Training task ``recognizer``: the 4-class action recognizer (walk / sit / stand up / lie).

The network and its loss are in :mod:`jaxmotion.models.recognizer`; loading a trained one and
scoring motions with it in :mod:`jaxmotion.eval.recognizer`. Run it with
``python -m jaxmotion.train --config configs/recognizer.py data_dir=DIR workdir=runs/recognizer``.
"""

from __future__ import annotations

import itertools

import jax
import numpy as np
from flax import nnx

from jaxmotion.data.format import ACTIONS, DatasetError, load_manifest, load_sample
from jaxmotion.data.loader import Dataset
from jaxmotion.eval.evaluator import manifest_sha256
from jaxmotion.models.recognizer import RECOGNIZER_VERSION, ActionRecognizer, classification_loss
from jaxmotion.train.evaluator_task import fit_feature_stats

__all__ = ["MotionActionDataset", "RecognizerTask"]


class MotionActionDataset(Dataset):
    """A split's motions and action labels only (no scene, no crop, no affordance): batches
    ``{"joints" [B, T, 22, 3] (world frame, zero past the end), "mask" [B, T],
    "action" [B] int32}`` (index into :data:`~jaxmotion.data.format.ACTIONS`).

    ``time_crop`` > 0: each motion drops a random ``[0, time_crop]`` fraction of its frames at
    the start and another at the end (the recognizer then also sees motions that do not begin
    or end exactly where the dataset's do); the result starts at frame 0 of the batch. Batches
    are a function of ``(seed, step)`` as :class:`Dataset`'s; with ``time_crop`` 0 they are
    not random at all.
    """

    def __init__(self, data_dir, split: str, *, max_frames: int = 120,
                 max_samples: int | None = None, time_crop: float = 0.0):
        if not 0.0 <= time_crop < 0.5:
            raise ValueError(f"time_crop must be in [0, 0.5), got {time_crop}")
        super().__init__(data_dir, split, max_frames=max_frames, max_samples=max_samples)
        self.time_crop = float(time_crop)

    def host_batch(self, indices, rng: np.random.Generator | None) -> dict:
        n, t_max = len(indices), self.max_frames
        joints = np.zeros((n, t_max, 22, 3), np.float32)
        mask = np.zeros((n, t_max), bool)
        action = np.zeros(n, np.int32)
        for row, i in enumerate(indices):
            path = self.files[int(i)]
            s = load_sample(path)
            t = int(s["mask"].sum())
            if s["joints"].shape[0] > t_max:
                raise DatasetError(f"{path}: {s['joints'].shape[0]} frames > max_frames={t_max}")
            if t == 0 or not s["mask"][:t].all():
                raise DatasetError(f"{path}: the frame mask must be a non-empty prefix (valid "
                                   "frames first)")
            lo, hi = 0, t
            if self.time_crop > 0 and rng is not None and t > 2:
                cut = int(self.time_crop * t)
                lo, hi = int(rng.integers(0, cut + 1)), t - int(rng.integers(0, cut + 1))
            joints[row, : hi - lo], mask[row, : hi - lo] = s["joints"][lo:hi], True
            action[row] = ACTIONS.index(s["action"])
        return {"joints": joints, "mask": mask, "action": action}

    def add_affordance(self, out: dict) -> dict:
        return out  # no scene crop, so no affordance map

    def batch(self, indices, rng: np.random.Generator | None = None) -> dict:
        return self.host_batch(indices, rng)


class RecognizerTask:
    """Task ``recognizer``: :class:`ActionRecognizer` trained with cross-entropy.

    Motion features are z-scored with statistics of ``cfg.stats_batches`` training batches
    (stored in the weights file). The logged ``accuracy`` is the training batches' (dropout
    and time crops on); the loop's ``val_loss`` is the val split's cross-entropy.
    """

    def dataset(self, cfg, split: str, *, augment: bool = False) -> MotionActionDataset:
        return MotionActionDataset(cfg.data_dir, split, max_frames=cfg.max_frames,
                                   max_samples=cfg.max_samples if split == "train" else None,
                                   time_crop=cfg.time_crop if augment else 0.0)

    def build_model(self, cfg, rngs: nnx.Rngs) -> ActionRecognizer:
        manifest = load_manifest(cfg.data_dir)
        self.label_smoothing = float(cfg.label_smoothing)
        self.info = {"recognizer_version": RECOGNIZER_VERSION, "actions": list(ACTIONS),
                     "data_manifest_sha256": manifest_sha256(cfg.data_dir),
                     "data_kind": str(manifest.get("kind", "")), "fps": manifest.get("fps")}
        ds = self.dataset(cfg, "train")
        it = ds.iterate(min(cfg.batch_size, len(ds)), cfg.seed + 2, prefetch=0)
        model = ActionRecognizer(cfg.model, rngs=rngs)
        self.stats = fit_feature_stats(model, itertools.islice(it, cfg.stats_batches))
        return model

    def train_batches(self, cfg, start_step: int):
        ds = self.dataset(cfg, "train", augment=True)
        return ds.iterate(cfg.batch_size, cfg.seed, start_step=start_step)

    def val_batches(self, cfg) -> list[dict]:
        try:
            ds = self.dataset(cfg, "val")
        except DatasetError:
            return []
        bs = min(cfg.batch_size, len(ds))
        bs -= bs % len(jax.devices())
        if bs < 1:
            return []
        it = ds.iterate(bs, cfg.seed + 1, prefetch=0)
        return list(itertools.islice(it, cfg.eval_batches))

    def loss(self, model: ActionRecognizer, batch: dict, key: jax.Array, *, train: bool):
        del key  # dropout draws from the model's streams, re-keyed per step by the loop
        logits = model(batch["joints"], batch["mask"], deterministic=not train)
        return classification_loss(logits, batch["action"],
                                   label_smoothing=self.label_smoothing if train else 0.0)

    def export_tensors(self) -> dict:
        return dict(self.stats)

    def export_config(self) -> dict:
        return dict(self.info)
