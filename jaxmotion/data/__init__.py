"""Datasets in the sample schema: on-disk format, training crops, batched loading.

See :mod:`jaxmotion.data.format` for the layout that external tools read.
"""

from jaxmotion.data.crop import Crop, CropSpec, crop_sample, features_to_joints, motion_features
from jaxmotion.data.format import (
    ACTIONS,
    SAMPLE_KEYS,
    SPLITS,
    DatasetError,
    anchor_frame,
    load_manifest,
    load_sample,
    save_sample,
    write_json_atomic,
)
from jaxmotion.data.loader import Dataset, Stats, compute_stats, load_stats, save_stats

__all__ = [name for name in dir() if not name.startswith("_")]
