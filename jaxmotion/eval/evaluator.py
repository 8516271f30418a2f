"""The trained text–motion evaluator: loading it, and the Guo et al. 2022 scores.

Train one on any dataset in the sample schema (network and loss:
:mod:`jaxmotion.models.evaluator`; training task: :mod:`jaxmotion.train.evaluator_task`)::

    python -m jaxmotion.train --config configs/evaluator.py data_dir=DIR workdir=runs/evaluator

then score generated motions against the ground truth::

    ev = load_evaluator("runs/evaluator")
    scores = text_motion_scores(ev, texts, gt_joints, gt_mask, gen_joints, gen_mask, rng=0)

Versioning: ``model.safetensors`` carries ``evaluator_version`` (:data:`EVALUATOR_VERSION`,
bumped whenever features, architecture or loss change; loading refuses other versions), the
sha256 of the training data's ``manifest.json`` (canonical JSON), the data's frame rate and the
text encoder's weights checksum. :meth:`Evaluator.describe` (also in every score dict) adds the
sha256 of the weights file itself: numbers are comparable only under the same description.

Text input is the frozen all-MiniLM-L6-v2 sentence embedding (384-d), not Guo et al.'s
GloVe word sequence; motion input is joints (the model makes them position- and
heading-invariant), not HumanML3D's 263-d features.
"""

from __future__ import annotations

import hashlib
import json
import warnings
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
from flax import nnx

from jaxmotion.constants import TEXT_ENCODER
from jaxmotion.data.format import load_manifest
from jaxmotion.eval._common import motion_batch, run_in_chunks, sample_sets, seed_of
from jaxmotion.eval.text_motion_metrics import (
    diversity,
    fid,
    multimodal_distance,
    multimodality,
    r_precision,
)
from jaxmotion.models.evaluator import EVALUATOR_VERSION, EvaluatorConfig, TextMotionEvaluator

__all__ = ["EVALUATOR_VERSION", "Evaluator", "load_evaluator", "manifest_sha256",
           "text_motion_scores"]


def manifest_sha256(data_dir) -> str:
    """sha256 of ``DIR/manifest.json`` as canonical JSON (sorted keys, compact separators)."""
    text = json.dumps(load_manifest(data_dir), sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode("utf-8")).hexdigest()


class Evaluator:
    """A trained, frozen evaluator (made by :func:`load_evaluator`).

    ``encode_motion(joints [B, T, 22, 3], mask [B, T]) -> [B, D]`` and
    ``encode_text(texts) -> [B, D]`` return float32 numpy features (jitted, in chunks of
    ``batch_size``; chunks are padded to powers of two (at least 8) and T to a multiple of 32,
    so few shapes compile; padding never changes a result). ``version`` is the file's
    ``evaluator_version``.
    """

    def __init__(self, model: TextMotionEvaluator, info: dict, *, batch_size: int = 256):
        model.eval()
        self.model, self.info, self.batch_size = model, dict(info), int(batch_size)
        graphdef, state = nnx.split(model)
        self._state = state

        @jax.jit
        def motion(state, joints, mask):
            return nnx.merge(graphdef, state).encode_motion(joints, mask, deterministic=True)

        @jax.jit
        def text(state, emb):
            return nnx.merge(graphdef, state).encode_text(emb, deterministic=True)

        self._motion, self._text = motion, text

    @property
    def version(self) -> str:
        return self.info["evaluator_version"]

    @property
    def dim(self) -> int:
        return self.model.cfg.output_dim

    def describe(self) -> dict:
        """What identifies this evaluator's numbers (version, weights and data hashes, ...)."""
        keys = ("evaluator_version", "weights_sha256", "data_manifest_sha256", "data_kind", "fps",
                "text_encoder", "text_encoder_sha256", "step")
        return {k: self.info.get(k) for k in keys}

    def encode_motion(self, joints, mask=None) -> np.ndarray:
        """``joints [B, T, 22, 3]`` (z-up, metres) and a prefix ``mask [B, T]`` -> ``[B, D]``."""
        joints, mask = motion_batch(joints, mask)
        return run_in_chunks(self._motion, self._state, (joints, mask), self.batch_size)

    def encode_text_embeddings(self, emb) -> np.ndarray:
        """MiniLM sentence embeddings ``[B, 384]`` -> ``[B, D]``."""
        emb = np.asarray(emb, np.float32)
        if emb.ndim != 2 or emb.shape[1] != self.model.cfg.text_dim or emb.shape[0] == 0:
            raise ValueError(f"text embeddings must be [B, {self.model.cfg.text_dim}] with "
                             f"B >= 1, got {emb.shape}")
        return run_in_chunks(self._text, self._state, (emb,), self.batch_size)

    def encode_text(self, texts: list[str]) -> np.ndarray:
        """Sentences -> ``[B, D]`` (through the frozen MiniLM the evaluator was trained with)."""
        from jaxmotion.text import load_text_encoder

        if isinstance(texts, str):
            raise TypeError("pass a list of strings, e.g. encode_text([text]), not a single str")
        enc = load_text_encoder(self.info.get("text_encoder", TEXT_ENCODER))
        want = self.info.get("text_encoder_sha256")
        if want and enc.checksum != want:
            raise ValueError(f"the installed {enc.name} weights (sha256 {enc.checksum[:12]}) "
                             f"differ from the ones this evaluator was trained with "
                             f"({want[:12]}); its text features would not be comparable")
        return self.encode_text_embeddings(enc(list(texts)))

    def __repr__(self):
        return f"Evaluator(version={self.version!r}, dim={self.dim})"


def load_evaluator(path, *, batch_size: int = 256) -> Evaluator:
    """The evaluator in a training workdir or a ``model.safetensors`` written by its training."""
    from jaxmotion.config import config_from_dict
    from jaxmotion.models.weights import apply_weights, load_weights

    path = Path(path)
    file = path / "model.safetensors" if path.is_dir() else path
    tensors, cfg = load_weights(file)
    version = cfg.get("evaluator_version")
    if version is None:
        raise ValueError(f"{file}: not an evaluator (task {cfg.get('task')!r}); train one with "
                         "python -m jaxmotion.train --config configs/evaluator.py")
    if version != EVALUATOR_VERSION:
        raise ValueError(f"{file}: evaluator version {version!r}, but this jaxmotion computes "
                         f"{EVALUATOR_VERSION!r} features; retrain it or use the jaxmotion "
                         "version that wrote it")
    model = TextMotionEvaluator(config_from_dict(EvaluatorConfig, cfg["model"]),
                                rngs=nnx.Rngs(0))
    apply_weights(model, tensors, source=str(file))
    for name in ("feature_mean", "feature_std"):
        getattr(model, name)[...] = jnp.asarray(tensors[f"stats/{name}"])
    info = {**cfg, "weights_sha256": hashlib.sha256(file.read_bytes()).hexdigest()}
    return Evaluator(model, info, batch_size=batch_size)


def _reduced(name: str, wanted: int, available: int) -> int:
    if available < wanted:
        warnings.warn(f"{name}={wanted} needs more samples than the {available} given; using "
                      f"{available} (recorded in the result's 'protocol')", stacklevel=3)
    return min(wanted, available)


def text_motion_scores(evaluator: Evaluator, texts: list[str], gt_joints, gt_mask, gen_joints,
                       gen_mask, rng=0, *, pool: int = 32, diversity_pairs: int = 300,
                       mm_pairs: int = 10) -> dict:
    """FID, R-precision top 1/2/3, MultiModal distance, Diversity, MultiModality (Guo et al.).

    Args:
      texts: N sentences; ``gt_joints [N, T, 22, 3]``, ``gt_mask [N, T]``: their motions.
      gen_joints: ``[N, T', 22, 3]`` or ``[N, K, T', 22, 3]`` (K samples per text) with
        ``gen_mask`` ``[N, T']`` or ``[N, K, T']``.
      rng: int seed or numpy Generator (R-precision pools, Diversity and MultiModality pairs;
        the real and every generated replication use the same pools and pairs).
      pool, diversity_pairs, mm_pairs: the protocol's 32, 300 and 10, each reduced (with a
        warning) when fewer samples are given.

    Returns ``{"real": {...}, "generated": {...}, "protocol": {...}, "evaluator": {...}}``.
    ``real`` (the "Real" row of the papers' tables) has ``r_precision_top1/2/3``,
    ``multimodal_dist`` and ``diversity`` (its FID against itself is 0 by construction).
    ``generated`` has these and ``fid`` (against the real features), each the mean over the K
    replications with ``<key>_ci95`` (1.96 std / sqrt K) when K > 1, and ``multimodality``
    over the K samples per text when K > 1.
    """
    n = len(texts)
    gen_joints, gen_mask = sample_sets(gen_joints, gen_mask, n, "texts")
    if np.shape(gt_joints)[:1] != (n,):
        raise ValueError(f"gt_joints must have one motion per text ({n}), got "
                         f"{np.shape(gt_joints)}")
    k, t = gen_joints.shape[1], gen_joints.shape[2]
    text_f = evaluator.encode_text(texts)
    real_f = evaluator.encode_motion(gt_joints, gt_mask)
    gen_f = evaluator.encode_motion(gen_joints.reshape(n * k, t, 22, 3),
                                    gen_mask.reshape(n * k, t)).reshape(n, k, -1)
    protocol = {"num_texts": n, "replications": k, "pool": _reduced("pool", pool, n),
                "diversity_pairs": _reduced("diversity_pairs", diversity_pairs, n)}
    seed = seed_of(rng)

    def row(motion_f):
        top = r_precision(text_f, motion_f, 3, protocol["pool"],
                          rng=np.random.default_rng([seed, 0]))
        return {"r_precision_top1": float(top[0]), "r_precision_top2": float(top[1]),
                "r_precision_top3": float(top[2]),
                "multimodal_dist": multimodal_distance(text_f, motion_f),
                "diversity": diversity(motion_f, protocol["diversity_pairs"],
                                       np.random.default_rng([seed, 1]))}

    reps = [{"fid": fid(real_f, gen_f[:, r]), **row(gen_f[:, r])} for r in range(k)]
    generated = {key: float(np.mean([x[key] for x in reps])) for key in reps[0]}
    if k > 1:
        generated.update({f"{key}_ci95": float(1.96 * np.std([x[key] for x in reps]) / np.sqrt(k))
                          for key in reps[0]})
        protocol["mm_pairs"] = _reduced("mm_pairs", mm_pairs, k)
        generated["multimodality"] = multimodality(gen_f, protocol["mm_pairs"],
                                                   np.random.default_rng([seed, 2]))
    return {"real": row(real_f), "generated": generated, "protocol": protocol,
            "evaluator": evaluator.describe()}
