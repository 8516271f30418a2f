"""jaxmotion: language-guided human motion generation in 3D scenes, in JAX/Flax.

Importing the package is cheap: no JAX computation is compiled or run at import
time, and subpackages load on first attribute access
(``jaxmotion.geometry``, ``jaxmotion.scene``, ...).

Conventions kept by every module: metres and seconds, z-up world with the floor
at z = 0, the 22 SMPL-X body joints in the standard order
(:data:`jaxmotion.geometry.JOINT_NAMES`), float32 arrays.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING

from jaxmotion._version import __version__

_SUBMODULES = (
    "batch", "body", "config", "constants", "data", "diffusion", "errors", "eval", "export", "generation",
    "geometry", "grounding", "models", "motion", "options", "pipelines", "result", "scene",
    "text", "train", "viz",
)

__all__ = ["__version__", "generate", "generate_batch", *_SUBMODULES]


def generate(scene, text: str | None = None, **kwargs):
    """Generate motions of a person doing ``text`` in ``scene`` ("demo", a path or a Scene).

    See :func:`jaxmotion.generation.generate` for the options
    (:class:`jaxmotion.options.GenerateOptions`); returns a
    :class:`jaxmotion.result.Generation` (``.joints``, ``.smplx``, ``.save(dir)``).
    """
    from jaxmotion.generation import DEFAULT_TEXT
    from jaxmotion.generation import generate as run

    return run(scene, DEFAULT_TEXT if text is None else text, **kwargs)


def generate_batch(cases, out, **kwargs):
    """Generate every request of ``cases`` (a ``.jsonl`` file or a list of dicts with
    ``text`` or ``plan`` and optionally ``scene``, ``object_id``, ``seed``, ``samples``,
    ``name``) into one folder per request under ``out``, the object-centric samples of many
    requests sampled together over every local device. See :func:`jaxmotion.batch.
    generate_batch` for the options; returns this process's rows of ``out/summary.jsonl``."""
    from jaxmotion.batch import generate_batch as run

    return run(cases, out, **kwargs)


if TYPE_CHECKING:  # pragma: no cover
    from jaxmotion import config, data, geometry, motion, scene, text, viz  # noqa: F401


def __getattr__(name: str):
    if name in _SUBMODULES:
        module = importlib.import_module(f"jaxmotion.{name}")
        globals()[name] = module
        return module
    raise AttributeError(f"module 'jaxmotion' has no attribute {name!r}")


def __dir__():
    return sorted(__all__)
