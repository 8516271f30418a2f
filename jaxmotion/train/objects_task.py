"""Training task ``objects``: the object classifier of object discovery.

Its data are the synthetic rooms' objects as segmentation finds them in degraded scans
(:mod:`jaxmotion.data.object_features`), built into ``<workdir>/features.npz`` on the first
run (resumable; the same ``rooms`` and ``room_seed`` give the same file); the last
``val_rooms`` rooms are the validation split. Features are z-scored with the training split's
statistics, stored in the weights file beside the categories, so that
:func:`jaxmotion.models.object_classifier.load_object_classifier` reads everything from one
``model.safetensors``.
"""

from __future__ import annotations

from pathlib import Path

import jax
import numpy as np

__all__ = ["ObjectsTask"]


class ObjectsTask:
    """Task ``objects`` (``configs/objects.py``): cross-entropy on the instances' categories."""

    needs_text = False

    def _data(self, cfg) -> dict:
        if not hasattr(self, "_arrays"):
            from jaxmotion.data.object_features import build_object_features

            Path(cfg.workdir).mkdir(parents=True, exist_ok=True)
            d = build_object_features(Path(cfg.workdir) / "features.npz", rooms=cfg.rooms,
                                      seed=cfg.room_seed, points=cfg.room_points,
                                      workers=cfg.loader_workers or 1, progress=cfg.progress)
            val = d["room"] >= cfg.rooms - cfg.val_rooms
            self._arrays = {"train": (d["features"][~val], d["labels"][~val]),
                            "val": (d["features"][val], d["labels"][val]),
                            "categories": tuple(str(c) for c in d["categories"])}
            x = self._arrays["train"][0]
            if not len(x):
                raise ValueError("no training objects: raise rooms or lower val_rooms")
            self.mean = x.mean(0).astype(np.float32)
            self.std = np.maximum(x.std(0), 1e-3).astype(np.float32)
        return self._arrays

    def build_model(self, cfg, rngs):
        from jaxmotion.models.object_classifier import make_object_classifier

        data = self._data(cfg)
        self.categories = data["categories"]
        if cfg.model.num_classes != len(self.categories):
            raise ValueError(f"model.num_classes={cfg.model.num_classes} but the data has "
                             f"{len(self.categories)} categories")
        self.label_smoothing = float(cfg.label_smoothing)
        return make_object_classifier(cfg.model, rngs=rngs)

    def _batch(self, x, y, idx) -> dict:
        return {"x": ((x[idx] - self.mean) / self.std).astype(np.float32),
                "y": y[idx].astype(np.int32)}

    def train_batches(self, cfg, start_step: int):
        x, y = self._data(cfg)["train"]
        # classes balanced by their square-root frequency: rare furniture is still seen
        freq = np.bincount(y, minlength=len(self.categories)).astype(np.float64)
        w = 1.0 / np.sqrt(np.maximum(freq[y], 1.0))
        w /= w.sum()
        step = start_step
        while True:
            rng = np.random.default_rng([cfg.seed, step])
            yield self._batch(x, y, rng.choice(len(y), cfg.batch_size, p=w))
            step += 1

    def val_batches(self, cfg) -> list[dict]:
        x, y = self._data(cfg)["val"]
        bs = cfg.batch_size - cfg.batch_size % len(jax.devices())
        return [self._batch(x, y, np.arange(i, i + bs)) for i in range(0, len(y) - bs + 1, bs)
                ][:cfg.eval_batches]

    def loss(self, model, batch: dict, key, *, train: bool):
        from jaxmotion.models.recognizer import classification_loss

        del key
        logits = model(batch["x"], deterministic=not train)
        return classification_loss(logits, batch["y"],
                                   label_smoothing=self.label_smoothing if train else 0.0)

    def export_tensors(self) -> dict:
        return {"feature_mean": self.mean, "feature_std": self.std}

    def export_config(self) -> dict:
        from jaxmotion.models.object_classifier import OBJECTS_VERSION

        return {"objects_version": OBJECTS_VERSION, "categories": list(self.categories)}
