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

from jaxmotion.models.adm import (ADM, ADMMLP, ADMPointTransformer, adm_text_cond, make_adm,
                                 pooled_text)
from jaxmotion.models.amdm import AMDM
from jaxmotion.models.configs import (PRESET_NAMES, ADMConfig, AMDMConfig, ObjectCentricConfig,
                                      PointTransformerConfig, preset_overrides)
from jaxmotion.models.object_centric import ObjectCentricDenoiser
from jaxmotion.models.layers import param_count, sinusoidal_embedding
from jaxmotion.models.point_transformer import (PointTransformerEncoder, PointTransformerUNet,
                                                build_geometry, farthest_point_sampling, knn)
from jaxmotion.models.segmentation import PointTransformerSeg, segmentation_loss

__all__ = [
    "ADM", "ADMMLP", "ADMPointTransformer", "make_adm", "adm_text_cond", "pooled_text", "AMDM",
    "PointTransformerSeg", "segmentation_loss", "PointTransformerEncoder", "PointTransformerUNet", "build_geometry",
    "farthest_point_sampling", "knn", "PointTransformerConfig", "ADMConfig", "AMDMConfig",
    "PRESET_NAMES", "preset_overrides", "ObjectCentricConfig", "ObjectCentricDenoiser", "param_count", "sinusoidal_embedding",
]
