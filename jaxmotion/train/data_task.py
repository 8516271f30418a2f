"""Shared data plumbing of the training tasks: a split as a :class:`~jaxmotion.data.Dataset`
with the config's crops, the normalisation statistics, and :class:`DataTask` (seeded train
iterator, fixed validation batches, text embeddings through the on-disk caches)."""

from __future__ import annotations

import itertools
from pathlib import Path

import jax
import numpy as np

from jaxmotion.config import config_to_dict
from jaxmotion.constants import TEXT_ENCODER
from jaxmotion.data.crop import CropSpec
from jaxmotion.data.format import DatasetError
from jaxmotion.data.loader import Dataset, Stats, compute_stats, load_stats, save_stats

__all__ = ["DataTask", "crop_spec", "dataset_stats", "split_dataset"]


def crop_spec(cfg) -> CropSpec:
    return CropSpec(**config_to_dict(cfg.crop))


def split_dataset(cfg, split: str) -> Dataset:
    """The ``split`` of ``cfg.data_dir`` with the config's crops, frames and sample limit."""
    return Dataset(cfg.data_dir, split, crop_spec(cfg), max_frames=cfg.max_frames,
                   sigma=cfg.affordance.sigma,
                   max_samples=cfg.max_samples if split == "train" else None)


def dataset_stats(cfg) -> Stats:
    """The dataset's ``stats.npz`` (computed and saved when missing and writable)."""
    path = Path(cfg.data_dir) / "stats.npz"
    if path.is_file():
        return load_stats(path)
    st = compute_stats(split_dataset(cfg, "train"), num_batches=8, batch_size=8, seed=cfg.seed)
    try:
        save_stats(st, path)
    except OSError:
        pass  # read-only dataset: recomputed next time
    return st


class DataTask:
    """Shared data plumbing: seeded train iterator, fixed validation batches, text embeddings."""

    needs_text = True

    def text_tokens(self, cfg) -> int:
        """Token states per text the batches need (0 = the pooled embedding only)."""
        return 0

    @staticmethod
    def cache_dir(cfg, name: str, fallback: str) -> Path:
        """``<data_dir>/.cache/<name>``, or ``<workdir>/<fallback>`` when the dataset is
        read-only (:func:`jaxmotion.text.dataset_cache_dir`)."""
        from jaxmotion.text.cache import dataset_cache_dir

        return dataset_cache_dir(cfg.data_dir, cfg.workdir, name, fallback)

    def _text(self, cfg):
        if not hasattr(self, "_encoder"):
            from jaxmotion.text import EmbeddingCache, load_text_encoder

            self._encoder = load_text_encoder(TEXT_ENCODER)
            self._cache = EmbeddingCache(self.cache_dir(cfg, "text", "text_cache"))
        return self._encoder, self._cache

    def _token_cache(self, cfg):
        if not hasattr(self, "_tokens"):
            from jaxmotion.text import TokenCache

            self._tokens = TokenCache(self.cache_dir(cfg, "text-tokens", "text_token_cache"))
        return self._tokens

    def prepare(self, cfg, raw: dict) -> dict:
        out = {k: v for k, v in raw.items() if isinstance(v, np.ndarray)}
        if self.needs_text:
            encoder, cache = self._text(cfg)
            out["text_emb"] = np.asarray(cache.encode(encoder, raw["text"]), np.float32)
            n = self.text_tokens(cfg)
            if n:
                out["text_tokens"], out["text_mask"] = self._token_cache(cfg).encode(
                    encoder, raw["text"], n)
        return out

    def dataset(self, cfg, split: str) -> Dataset:
        """The ``split`` this task reads (:func:`split_dataset`; a task may narrow it)."""
        return split_dataset(cfg, split)

    def train_batches(self, cfg, start_step: int):
        ds = self.dataset(cfg, "train")
        return (self.prepare(cfg, b) for b in ds.iterate(
            cfg.batch_size, cfg.seed, start_step=start_step,
            workers=int(getattr(cfg, "loader_workers", 0))))

    def val_batches(self, cfg) -> list[dict]:
        try:
            ds = self.dataset(cfg, "val")
        except DatasetError:
            return []
        bs = min(cfg.batch_size, len(ds))
        bs -= bs % len(jax.devices())
        if bs == 0:
            return []
        it = ds.iterate(bs, cfg.seed + 1, prefetch=0)
        return [self.prepare(cfg, b) for b in itertools.islice(it, cfg.eval_batches)]
