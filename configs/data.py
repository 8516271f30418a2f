"""Data config file: the dataset, scene crops and affordance maps (see jaxmotion.data.config).

Presets: ``default`` (the values of :class:`jaxmotion.data.config.DataConfig`), ``paper`` (the
papers' sizes, spelled out) and ``tiny`` (for tests). Load it with
``jaxmotion.config.load_config("data", ["preset=tiny", ...])``.
"""

from __future__ import annotations

from typing import Any

from jaxmotion.data.config import AffordanceConfig, CropConfig, DataConfig

__all__ = ["AffordanceConfig", "CropConfig", "DataConfig", "PRESETS", "get_config"]

PRESETS: dict[str, dict[str, Any]] = {
    "default": {},
    "paper": {"crop.num_points": 8192, "max_frames": 120, "batch_size": 32},
    "tiny": {"crop.num_points": 256, "max_frames": 16, "min_frames": 8, "batch_size": 4},
}


def get_config() -> DataConfig:
    """The default data config; presets and ``key=value`` overrides go on top of it."""
    return DataConfig()
