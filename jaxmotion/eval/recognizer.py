"""The trained action recognizer: loading it, and action accuracy as the object-centric paper
measures it (Cen et al. 2024): the action recognised in each motion against the action its
instruction asks for.

Train one on any dataset in the sample schema (network and loss:
:mod:`jaxmotion.models.recognizer`; training task: :mod:`jaxmotion.train.recognizer_task`)::

    python -m jaxmotion.train --config configs/recognizer.py data_dir=DIR workdir=runs/recognizer

then score motions::

    rec = load_recognizer("runs/recognizer")
    acc = action_accuracy(rec, joints, mask, ["sit", "walk", ...])

The accuracy of the same recognizer on the dataset's own test motions is the ceiling row of
the table: a generated motion cannot be recognised better than real ones.

The paper's Table 1 also gives FID, diversity and multimodality on the recognizer's features
(not on a text–motion evaluator's): :meth:`Recognizer.features` (host, chunked) or the pure
:func:`recognizer_features` give the penultimate-layer vector ``[B, hidden]`` of each motion,
and :func:`recognizer_scores` the three numbers of generated motions against real ones, with
the arithmetic of :mod:`jaxmotion.eval.text_motion_metrics`::

    scores = recognizer_scores(rec, gt_joints, gt_mask, gen_joints, gen_mask, rng=0)

Versioning: ``model.safetensors`` carries ``recognizer_version`` (:data:`RECOGNIZER_VERSION`,
bumped whenever features, architecture, loss or labels change; loading refuses other
versions), the sha256 of the training data's ``manifest.json`` and the data's frame rate;
:meth:`Recognizer.describe` adds the sha256 of the weights file itself: accuracies are
comparable only under the same description. Motions must be at the training data's frame
rate (30 fps for scene data): the features include per-frame velocities.
"""

from __future__ import annotations

import hashlib
from collections.abc import Sequence
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
from flax import nnx

from jaxmotion.eval._common import motion_batch, run_in_chunks, sample_sets, seed_of
from jaxmotion.eval.text_motion_metrics import diversity, fid, multimodality
from jaxmotion.models.recognizer import (
    ACTIONS,
    RECOGNIZER_VERSION,
    ActionRecognizer,
    RecognizerConfig,
)

__all__ = ["ACTIONS", "RECOGNIZER_VERSION", "Recognizer", "action_accuracy", "action_ids",
           "load_recognizer", "recognizer_features", "recognizer_scores"]

RETRAIN = ("python -m jaxmotion.train --config configs/recognizer.py data_dir=DATA "
           "workdir=runs/recognizer")


def action_ids(actions) -> np.ndarray:
    """Action names (``"walk"``, ``"sit"``, ``"stand_up"``, ``"lie"``) or ids -> ``[N]`` int32
    indices into :data:`ACTIONS`."""
    if isinstance(actions, str):
        raise TypeError("pass a sequence of actions, e.g. ['sit'], not a single str")
    items = list(actions) if not isinstance(actions, np.ndarray) else actions.tolist()
    out = []
    for a in items:
        if isinstance(a, str):
            if a not in ACTIONS:
                raise ValueError(f"unknown action {a!r}; valid: {', '.join(ACTIONS)}")
            out.append(ACTIONS.index(a))
        elif isinstance(a, (int, np.integer)) and not isinstance(a, bool):
            if not 0 <= int(a) < len(ACTIONS):
                raise ValueError(f"action id {a} out of range 0..{len(ACTIONS) - 1}")
            out.append(int(a))
        else:
            raise TypeError(f"an action is a name in {ACTIONS} or its index, got {a!r}")
    return np.asarray(out, np.int32)


def recognizer_features(model: ActionRecognizer, joints: jax.Array,
                        mask: jax.Array) -> jax.Array:
    """The recognizer's penultimate-layer (pre-logit) features of each motion, in eval mode.

    Pure and jit-able (``nnx.jit(recognizer_features)``, or through ``nnx.split`` /
    ``nnx.merge`` as :class:`Recognizer` does). ``joints [B, T, 22, 3]`` (z-up, metres, the
    training data's frame rate) and a prefix ``mask [B, T]`` -> ``[B, hidden]`` float32; the
    values of padded frames, the padded length, a shift and a turn about z change nothing.
    """
    return model.features(joints, mask, deterministic=True)


class Recognizer:
    """A trained, frozen action recognizer (made by :func:`load_recognizer`).

    ``logits(joints [B, T, 22, 3], mask [B, T]) -> [B, 4]`` float32 and
    ``predict(joints, mask) -> [B]`` int32 indices into :data:`ACTIONS` (jitted, in chunks of
    ``batch_size``; chunks are padded to powers of two (at least 8) and T to a multiple of
    32, so few shapes compile; padding never changes a result). ``version`` is the file's
    ``recognizer_version``.
    """

    def __init__(self, model: ActionRecognizer, info: dict, *, batch_size: int = 256):
        model.eval()
        self.model, self.info, self.batch_size = model, dict(info), int(batch_size)
        graphdef, state = nnx.split(model)
        self._state = state

        @jax.jit
        def logits(state, joints, mask):
            return nnx.merge(graphdef, state)(joints, mask, deterministic=True)

        @jax.jit
        def features(state, joints, mask):
            return recognizer_features(nnx.merge(graphdef, state), joints, mask)

        self._logits, self._features = logits, features

    @property
    def version(self) -> str:
        return self.info["recognizer_version"]

    @property
    def actions(self) -> tuple[str, ...]:
        return ACTIONS

    def describe(self) -> dict:
        """What identifies this recognizer's numbers (version, weights and data hashes, ...)."""
        keys = ("recognizer_version", "weights_sha256", "data_manifest_sha256", "data_kind",
                "fps", "step")
        return {k: self.info.get(k) for k in keys}

    def logits(self, joints, mask=None) -> np.ndarray:
        """``joints [B, T, 22, 3]`` (z-up, metres) and a prefix ``mask [B, T]`` (None: every
        frame valid) -> ``[B, 4]`` logits in the order of :data:`ACTIONS`."""
        joints, mask = motion_batch(joints, mask)
        return run_in_chunks(self._logits, self._state, (joints, mask), self.batch_size)

    def features(self, joints, mask=None) -> np.ndarray:
        """``joints [B, T, 22, 3]`` and a prefix ``mask [B, T]`` (None: every frame valid) ->
        ``[B, hidden]`` float32 penultimate-layer features (:func:`recognizer_features`)."""
        joints, mask = motion_batch(joints, mask)
        return run_in_chunks(self._features, self._state, (joints, mask), self.batch_size)

    @property
    def dim(self) -> int:
        """Width of :meth:`features`."""
        return self.model.cfg.hidden

    def predict(self, joints, mask=None) -> np.ndarray:
        """The recognised action of each motion: ``[B]`` int32 indices into :data:`ACTIONS`."""
        return np.argmax(self.logits(joints, mask), axis=-1).astype(np.int32)

    def predict_names(self, joints, mask=None) -> list[str]:
        """The recognised action of each motion by name."""
        return [ACTIONS[i] for i in self.predict(joints, mask)]

    def __repr__(self):
        return f"Recognizer(version={self.version!r})"


def load_recognizer(path, *, batch_size: int = 256) -> Recognizer:
    """The recognizer in a training workdir or a ``model.safetensors`` written by its training.

    Refuses files of another :data:`RECOGNIZER_VERSION` (retrain with :data:`RETRAIN`)."""
    from jaxmotion.config import config_from_dict
    from jaxmotion.models.weights import apply_weights, load_weights

    path = Path(path)
    file = path / "model.safetensors" if path.is_dir() else path
    if not file.is_file():
        raise FileNotFoundError(f"{file}: no trained recognizer here; train one with {RETRAIN}")
    tensors, cfg = load_weights(file)
    version = cfg.get("recognizer_version")
    if version is None:
        raise ValueError(f"{file}: not an action recognizer (task {cfg.get('task')!r}); train "
                         f"one with {RETRAIN}")
    if version != RECOGNIZER_VERSION:
        raise ValueError(f"{file}: recognizer version {version!r}, but this jaxmotion computes "
                         f"{RECOGNIZER_VERSION!r}; retrain it with {RETRAIN} (or use the "
                         "jaxmotion version that wrote it)")
    if tuple(cfg.get("actions", ACTIONS)) != ACTIONS:
        raise ValueError(f"{file}: labels {cfg.get('actions')} differ from {ACTIONS}; retrain "
                         f"it with {RETRAIN}")
    model = ActionRecognizer(config_from_dict(RecognizerConfig, cfg["model"]), rngs=nnx.Rngs(0))
    apply_weights(model, tensors, source=str(file))
    for name in ("feature_mean", "feature_std"):
        getattr(model, name)[...] = jnp.asarray(tensors[f"stats/{name}"])
    info = {**cfg, "weights_sha256": hashlib.sha256(file.read_bytes()).hexdigest()}
    return Recognizer(model, info, batch_size=batch_size)


def action_accuracy(recognizer: Recognizer, joints, mask, actions: Sequence) -> float:
    """Fraction of motions whose recognised action is the one asked for.

    Args:
      joints: ``[N, T, 22, 3]`` motions (z-up, metres, the training data's frame rate);
        ``mask``: ``[N, T]`` prefix masks (None: every frame valid).
      actions: N action names (``"walk"``, ``"sit"``, ``"stand_up"``, ``"lie"``) or ids.
    """
    want = action_ids(actions)
    n = np.shape(joints)[0]
    if len(want) != n:
        raise ValueError(f"need one action per motion: {len(want)} actions for {n} motions")
    return float(np.mean(recognizer.predict(joints, mask) == want))


def recognizer_scores(recognizer: Recognizer, gt_joints, gt_mask, gen_joints, gen_mask, rng=0,
                      *, diversity_pairs: int = 300, mm_pairs: int = 10) -> dict:
    """FID, diversity and multimodality on the recognizer's features (the object-centric
    paper's Table 1 columns), with the arithmetic and pair conventions of
    :func:`jaxmotion.eval.evaluator.text_motion_scores`.

    Args:
      gt_joints: ``[N, T, 22, 3]``, ``gt_mask [N, T]``: the dataset's motions of the N cases.
      gen_joints: ``[N, T', 22, 3]`` or ``[N, K, T', 22, 3]`` (K samples per case) with
        ``gen_mask`` ``[N, T']`` or ``[N, K, T']``.
      rng: int seed or numpy Generator (the diversity and multimodality pairs; the real set and
        every sample set use the same pairs).
      diversity_pairs, mm_pairs: 300 and 10 as in Guo et al. (the paper: 200 and 20), each
        reduced to N and K when fewer motions are given (recorded in ``protocol``).

    Returns ``{"real": {"diversity"}, "generated": {...}, "protocol": {...}, "recognizer":
    describe()}``. ``generated`` has ``fid`` (sample set k against the real motions, N ≥ 2)
    and ``diversity``, each the mean over the K sample sets, and with K > 1 ``multimodality``
    (pairs among each case's K samples, averaged over cases). The real set's FID against
    itself is 0 by construction and its multimodality undefined (one motion per case).
    """
    n = np.shape(gt_joints)[0]
    gen_joints, gen_mask = sample_sets(gen_joints, gen_mask, n, "real motions")
    k, t = gen_joints.shape[1], gen_joints.shape[2]
    real_f = recognizer.features(gt_joints, gt_mask)
    gen_f = recognizer.features(gen_joints.reshape(n * k, t, 22, 3),
                                gen_mask.reshape(n * k, t)).reshape(n, k, -1)
    seed = seed_of(rng)
    protocol = {"num_cases": n, "sample_sets": k,
                "diversity_pairs": min(diversity_pairs, n)}

    def div(f):
        return diversity(f, protocol["diversity_pairs"], np.random.default_rng([seed, 1]))

    sets = [{"diversity": div(gen_f[:, i]), **({"fid": fid(real_f, gen_f[:, i])}
                                               if n >= 2 else {})} for i in range(k)]
    generated = {key: float(np.mean([s[key] for s in sets])) for key in sets[0]}
    if k > 1:
        protocol["mm_pairs"] = min(mm_pairs, k)
        generated["multimodality"] = multimodality(gen_f, protocol["mm_pairs"],
                                                   np.random.default_rng([seed, 2]))
    return {"real": {"diversity": div(real_f)}, "generated": generated, "protocol": protocol,
            "recognizer": recognizer.describe()}
