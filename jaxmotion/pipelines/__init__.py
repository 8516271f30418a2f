"""Synthesis pipelines: from a scene region, a text and (optionally) a known target to motions.

Every pipeline is an object loaded from checkpoint files (``from_files``) whose ``sample``
draws motions for a batch of crops (points and colours in the crop frame), a text condition
and, where known, the target object's points; it returns ``{"joints" [B,T,22,3], ...}`` in the
crop frame. Inference only: nothing here imports :mod:`jaxmotion.train`.

- :class:`AffordancePipeline` (:mod:`.affordance`): ADM → AMDM (Wang et al., CVPR 2024), and the
  one-stage baseline (an AMDM reading the scene's colours).
- :mod:`.checkpoints`: the shipped checkpoints, a user's folder or workdirs, and loading them.
"""

__all__ = ["AffordancePipeline", "adm_map_one", "adm_maps_one", "take_text"]


def __getattr__(name):  # imported on first use: the object-centric pipeline needs none of it
    if name in __all__:
        from jaxmotion.pipelines import affordance

        return getattr(affordance, name)
    raise AttributeError(f"module 'jaxmotion.pipelines' has no attribute {name!r}")
