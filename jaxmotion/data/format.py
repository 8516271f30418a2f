"""The on-disk dataset format (the sample schema). External tools read these names.

Layout of a dataset directory ``DIR``::

    DIR/manifest.json                      counts, seed, version, splits
    DIR/scenes/<scene_id>.npz              xyz, rgb, normal, semantic, instance,
                                           objects (JSON string)
    DIR/samples/<split>/<sample_id>.npz    text, action, scene_id, target_id,
                                           joints [T,22,3], fps, mask [T],
                                           transl [T,3], global_orient [T,3],
                                           body_pose [T,21,3], betas [10]
    DIR/stats.npz                          normalisation statistics (see loader)
    DIR/provenance/<split>/<sample_id>.json  only ``jaxmotion synth --motions``: the
                                           sample's origin (a library clip or procedural)

Scenes use :func:`jaxmotion.scene.save_scene` / ``load_scene``. Samples are
written atomically (temp file + ``os.replace``) so an interrupted build never
leaves a half-written file.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from jaxmotion._atomic import atomic_open
from jaxmotion._npio import load_npz

__all__ = [
    "ACTIONS",
    "SAMPLE_KEYS",
    "SPLITS",
    "DatasetError",
    "anchor_frame",
    "load_manifest",
    "load_sample",
    "save_sample",
    "write_json_atomic",
]

ACTIONS = ("walk", "sit", "stand_up", "lie")
SPLITS = ("train", "val", "test")
SAMPLE_KEYS = (
    "text", "action", "scene_id", "target_id", "joints", "fps", "mask",
    "transl", "global_orient", "body_pose", "betas",
)  # fmt: skip


class DatasetError(ValueError):
    """A dataset file is missing or malformed; the message names the file."""


def anchor_frame(action: str, mask: np.ndarray) -> int:
    """HUMANISE anchor frame: the first frame for ``stand_up``, else the last valid frame."""
    if action == "stand_up":
        return 0
    valid = np.flatnonzero(np.asarray(mask, bool))
    return int(valid[-1]) if len(valid) else 0


def _validate(sample: dict, where: str) -> dict:
    missing = [k for k in SAMPLE_KEYS if k not in sample]
    if missing:
        raise DatasetError(f"{where}: missing keys {missing}; a sample needs {list(SAMPLE_KEYS)}")
    joints = np.asarray(sample["joints"], np.float32)
    if joints.ndim != 3 or joints.shape[1:] != (22, 3):
        raise DatasetError(f"{where}: joints must be [T, 22, 3], got {joints.shape}")
    t = joints.shape[0]
    shapes = {"mask": (t,), "transl": (t, 3), "global_orient": (t, 3), "body_pose": (t, 21, 3),
              "betas": (10,)}
    out = dict(sample)
    for key, shape in shapes.items():
        arr = np.asarray(sample[key])
        if arr.shape != shape:
            raise DatasetError(f"{where}: {key} must have shape {shape}, got {arr.shape}")
        out[key] = arr.astype(bool if key == "mask" else np.float32)
    out["joints"] = joints
    if not np.all(np.isfinite(joints[out["mask"]])):
        raise DatasetError(f"{where}: joints contain NaN or inf in valid frames")
    action = str(sample["action"])
    if action not in ACTIONS:
        raise DatasetError(f"{where}: action {action!r} is not one of {ACTIONS}")
    out.update(
        text=str(sample["text"]), action=action, scene_id=str(sample["scene_id"]),
        target_id=int(sample["target_id"]), fps=float(sample["fps"]),
    )  # fmt: skip
    return out


def save_sample(path, sample: dict) -> Path:
    """Validate and write one sample ``.npz`` atomically."""
    path = Path(path)
    s = _validate(sample, str(path))
    arrays = {k: s[k] for k in SAMPLE_KEYS}
    arrays = {k: (np.asarray(v) if not isinstance(v, str) else np.array(v)) for k, v in arrays.items()}
    with atomic_open(path, "wb") as f:
        np.savez(f, **arrays)
    return path


def load_sample(path) -> dict:
    """Read and validate one sample ``.npz`` into a dict of numpy arrays and Python scalars."""
    path = Path(path)
    if not path.is_file():
        raise DatasetError(f"{path}: no such sample file")
    try:
        with load_npz(path, allow_pickle=False) as data:
            raw = {k: data[k] for k in data.files}
    except (OSError, ValueError) as err:
        raise DatasetError(f"{path}: not a readable .npz sample ({err})") from err
    raw = {k: (v.item() if v.ndim == 0 else v) for k, v in raw.items()}
    return _validate(raw, str(path))


def write_json_atomic(path, obj) -> Path:
    """Write JSON via a temp file and ``os.replace``."""
    path = Path(path)
    with atomic_open(path, "w") as f:
        json.dump(obj, f, indent=2, sort_keys=True)
        f.write("\n")
    return path


def load_manifest(data_dir) -> dict:
    """Read ``DIR/manifest.json``; a clear error says how to make a dataset."""
    path = Path(data_dir) / "manifest.json"
    if not path.is_file():
        raise DatasetError(
            f"{path}: not found. {data_dir} is not a jaxmotion dataset; make one with "
            f"'jaxmotion synth --out {data_dir}'."
        )
    with open(path) as f:
        return json.load(f)
