"""Networks of the affordance pipeline (Flax NNX, float32, every size from :mod:`.configs`).

- :class:`PointTransformerSeg`: Point Transformer U-Net + segmentation head; pretrained on the
  synthetic rooms' semantics, then frozen as ADM's per-point feature backbone.
- :class:`ADM` (Perceiver), :class:`ADMMLP`, :class:`ADMPointTransformer`: affordance diffusion,
  ``model(x [B,N,6], t [B], cond) -> x0``; :func:`make_adm` picks by ``ADMConfig.arch``.
- :class:`AMDM`: affordance-to-motion diffusion, @Enc / @Dec (``AMDMConfig.arch``) and the
  one-stage baseline (``scene_input="rgb"``), ``model(x [B,T,66], t [B], cond) -> x0``.
- :class:`ObjectCentricDenoiser`: the object-centric pipeline's trajectory and completion
  denoisers (``ObjectCentricConfig.kind``), ``model(x [B,T,9|135], t [B], cond) -> x0``.
- :class:`PointTransformerEncoder`, :class:`PointTransformerUNet` and the geometry kernels
  (:func:`knn`, :func:`farthest_point_sampling`, :func:`build_geometry`).

Modules are built with ``Model(cfg, rngs=nnx.Rngs(seed))`` and start in training mode (dropout
on, BatchNorm on batch statistics; dropout draws from the ``dropout`` stream, else ``default``).
Use ``model.eval()`` or ``deterministic=True`` for inference. Models are functions of
``denoise_fn(x, t, cond)`` form, ``cond`` a dict of arrays (a pytree): samplers can close over
the module. Presets: ``ADMConfig.tiny() / cpu() / paper()`` etc.; the CPU default recommends
2048-point crops (see :mod:`.configs`).
"""

#: where each public name lives: imported on first use, so that ``jaxmotion.models.weights``
#: or one model does not import every network (and Flax, ~0.45 s) with it
_HOMES = {
    "ADM": "adm",
    "ADMMLP": "adm",
    "ADMPointTransformer": "adm",
    "adm_text_cond": "adm",
    "make_adm": "adm",
    "pooled_text": "adm",
    "AMDM": "amdm",
    "PRESET_NAMES": "configs",
    "ADMConfig": "configs",
    "AMDMConfig": "configs",
    "ObjectCentricConfig": "configs",
    "PointTransformerConfig": "configs",
    "preset_overrides": "configs",
    "ObjectCentricDenoiser": "object_centric",
    "param_count": "layers",
    "sinusoidal_embedding": "layers",
    "PointTransformerEncoder": "point_transformer",
    "PointTransformerUNet": "point_transformer",
    "build_geometry": "point_transformer",
    "farthest_point_sampling": "point_transformer",
    "knn": "point_transformer",
    "PointTransformerSeg": "segmentation",
    "segmentation_loss": "segmentation",
}

__all__ = [
    "ADM",
    "ADMMLP",
    "AMDM",
    "PRESET_NAMES",
    "ADMConfig",
    "ADMPointTransformer",
    "AMDMConfig",
    "ObjectCentricConfig",
    "ObjectCentricDenoiser",
    "PointTransformerConfig",
    "PointTransformerEncoder",
    "PointTransformerSeg",
    "PointTransformerUNet",
    "adm_text_cond",
    "build_geometry",
    "farthest_point_sampling",
    "knn",
    "make_adm",
    "param_count",
    "pooled_text",
    "preset_overrides",
    "segmentation_loss",
    "sinusoidal_embedding",
]


def __getattr__(name):
    if name in _HOMES:
        import importlib

        return getattr(importlib.import_module(f"jaxmotion.models.{_HOMES[name]}"), name)
    raise AttributeError(f"module 'jaxmotion.models' has no attribute {name!r}")
