"""The HUMANISE cVAE baseline (Wang et al., NeurIPS 2022) as a pipeline: scene + words -> motions.

Given a crop of the room (points and colours in the crop frame), the instruction's word-token
states and a body shape, :meth:`CVAEPipeline.sample` draws K latents ``z ~ N(0, I)`` (an
explicit PRNG key) and decodes each into a motion: pelvis, global orientation and body pose per
frame (:mod:`jaxmotion.models.cvae`), then the 22 joints by forward kinematics (exact bones).
The target object is not an input of the cVAE (it regresses the target's centre from the scene
and the words while training); ``generate`` centres the crop square on the grounded target, as
it does for the other pipelines, so the cVAE sees the part of the room the text is about.

Weights come from ``configs/cvae.py`` runs only: jaxmotion ships none. Several files may be
given: action-specific models (``action=sit`` ...) and an action-agnostic one; the one trained
for the instruction's action is used, else the action-agnostic one (:func:`choose_cvae`).
Inference only: nothing here imports :mod:`jaxmotion.train`.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from pathlib import Path

import jax
import jax.numpy as jnp
from flax import nnx

from jaxmotion.errors import GenerateError
from jaxmotion.models.cvae import CVAE, CVAEConfig, features_to_joints

__all__ = ["CVAEPipeline", "choose_cvae", "load_cvae_pipeline", "sample_in_room"]


@dataclass
class CVAEPipeline:
    """A trained cVAE (inference mode) and what it was trained for: ``action`` (``""`` =
    action-agnostic), ``frames`` (the motions' length) and the run's config."""

    net: CVAE
    action: str
    frames: int
    run_config: dict

    @classmethod
    def from_file(cls, path) -> CVAEPipeline:
        """From the exported ``model.safetensors`` of a ``configs/cvae.py`` run (or its
        workdir); :class:`ValueError` when it is not one."""
        from jaxmotion.config import config_from_dict
        from jaxmotion.models.weights import (
            abstract_module,
            apply_weights,
            load_weights,
            weights_path,
        )

        src = weights_path(path)
        tensors, saved = load_weights(src)
        if saved.get("task") != "cvae":
            raise ValueError(f"{src} is a {saved.get('task')!r} checkpoint, not a cvae one")
        cfg = config_from_dict(CVAEConfig, saved["model"])
        net = abstract_module(lambda: CVAE(cfg, rngs=nnx.Rngs(0)))
        apply_weights(net, tensors, prefix="net/", source=str(src))
        net.eval()
        return cls(net, str(saved.get("action", "")), int(saved["max_frames"]), saved)

    def sample(self, key, points, colors, tokens, token_mask, betas, mask,
               num_samples: int = 1) -> dict:
        """K motions per crop (jit it).

        Args:
          key: PRNG key (the latents); points ``[B, N, 3]`` (crop frame, metres) and colors
          ``[B, N, 3]`` (rgb in [-1, 1]); tokens ``[B, L, text_dim]`` and token_mask ``[B, L]``:
          the text's word-token states (:func:`jaxmotion.text.condition.embed_one`); betas
          ``[B, 10]``; mask ``[B, T]`` bool, the frames to generate; num_samples: K (static).
        Returns:
          ``{"features" [B, K, T, 72], "joints" [B, K, T, 22, 3]}`` in the crop frame.
        """
        cond = {"xyz": points, "rgb": colors, "tokens": tokens, "token_mask": token_mask,
                "betas": betas}
        feats = self.net.sample(key, cond, mask, num_samples)
        joints = features_to_joints(feats, jnp.asarray(betas, jnp.float32)[:, None])
        return {"features": feats, "joints": joints}


@functools.lru_cache(maxsize=4)
def load_cvae_pipeline(path: str) -> CVAEPipeline:
    """The :class:`CVAEPipeline` of a weights file, kept for the process;
    :class:`GenerateError` when it does not load."""
    try:
        return CVAEPipeline.from_file(path)
    except (KeyError, ValueError) as e:
        raise GenerateError(f"cVAE checkpoint {path} does not load: {e}") from e


def choose_cvae(files, action) -> Path:
    """The file among ``files`` (of :func:`~jaxmotion.pipelines.checkpoints.
    resolve_cvae_checkpoints`) for an instruction asking for ``action`` (None: unknown): the
    model trained for that action, else the action-agnostic one, else (an unknown action, one
    file) that file; :class:`GenerateError` otherwise."""
    from jaxmotion.pipelines.checkpoints import weights_config

    trained = {weights_config(f).get("action", ""): Path(f) for f in files}
    if action in trained:
        return trained[action]
    if "" in trained:
        return trained[""]
    if action is None and len(trained) == 1:
        return next(iter(trained.values()))
    told = "the instruction's action could not be read" if action is None else (
        f"the instruction asks to {action}")
    raise GenerateError(f"{told}, and the cVAE checkpoints given are action-specific "
                        f"({', '.join(sorted(trained))}); add one trained with "
                        f"action={action or '<the action>'} or an action-agnostic one "
                        "(configs/cvae.py action='')")


def sample_in_room(room, centre, text: str, action, opts, files, root, aot_dir, versions):
    """``generate``'s synthesis stage with the cVAE: K motions in the scene's frame.

    Args:
      room: the :class:`~jaxmotion.scene.Scene`; centre: the crop square's xy centre (on the
        grounded target, as for the other pipelines); text: the instruction; action: its action
        (``Instruction.action``, picks the checkpoint, :func:`choose_cvae`).
      opts: :class:`~jaxmotion.options.GenerateOptions` (samples, seed); files: the cVAE
        weights files; root: the run's PRNG key data (its second split samples, as the other
        pipelines'); aot_dir, versions: the compiled-program cache.
    Returns:
      ``(joints [K, T, 22, 3], (crop point indices, rotation, shift))``.
    """
    import numpy as np

    from jaxmotion._jax_setup import enable_compilation_cache
    from jaxmotion.compiled import cached_call, digest
    from jaxmotion.data.crop import crop_spec_from_config, generate_crop, model_colors
    from jaxmotion.pipelines.checkpoints import weights_config
    from jaxmotion.text.condition import embed_one

    file = choose_cvae(files, action)
    run_cfg = weights_config(file)
    spec, frames = crop_spec_from_config(run_cfg), int(run_cfg["max_frames"])
    if spec.num_points != int(run_cfg["model"]["num_points"]):
        raise GenerateError(f"{file}: crop.num_points and model.num_points differ")
    pick, pts, shift, rot = generate_crop(room.xyz, centre, spec, opts.seed)
    words = embed_one(text, enable_compilation_cache() / "text-embeddings",
                      int(run_cfg["model"]["text_tokens"]))
    k = opts.samples
    args = (np.asarray(root), pts[None].astype(np.float32),
            model_colors(room.rgb[pick])[None].astype(np.float32),
            np.asarray(words["tokens"], np.float32), np.asarray(words["mask"], bool),
            np.zeros((1, 10), np.float32), np.ones((1, frames), bool))

    def build():
        pipe = load_cvae_pipeline(str(file))
        main = lambda kd: jax.random.split(jax.random.wrap_key_data(kd))[1]
        return lambda kd, p, c, t, tm, b, m: pipe.sample(main(kd), p, c, t, tm, b, m,
                                                         k)["joints"][0]

    res = cached_call(aot_dir, "sample-cvae", digest(versions, k, Path(file)), build, args)
    joints = (np.asarray(jax.device_get(res)) @ rot + shift).astype(np.float32)
    return joints, (pick, rot, shift)
