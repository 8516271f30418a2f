"""Checkpoint files: the shipped defaults, a user's folder or workdirs, and loading them.

A checkpoint folder (the shipped ``jaxmotion/assets`` too) holds ``adm.safetensors`` and
``amdm.safetensors``, and optionally ``adm_text.safetensors`` (:data:`TEXT_ADM`): the ADM used
when no target object is known, beside an ``adm.safetensors`` that reads one
(``model.target_input``; told no target, such an ADM draws worse maps than one trained on the
text alone: docs/results.md in the git history, "The ADM told the target").
"""

from __future__ import annotations

import functools
from pathlib import Path

from jaxmotion.errors import GenerateError

__all__ = ["OBJECT_CENTRIC_FILES", "TEXT_ADM", "resolve_object_checkpoints", "adm_text_tokens", "adm_view", "default_checkpoints", "load_pipeline",
           "pick_pipeline", "pipeline_files", "resolve_checkpoints", "resolve_cvae_checkpoints", "text_adm_for", "weights_config"]

_ASSETS = Path(__file__).resolve().parent.parent / "assets"


def default_checkpoints() -> tuple[Path, Path]:
    """Paths of the shipped ADM and AMDM weights."""
    return _ASSETS / "adm.safetensors", _ASSETS / "amdm.safetensors"


#: The ADM used when no target object is known, beside a folder's ``adm.safetensors``
#: (optional: without it ``adm.safetensors`` serves both).
TEXT_ADM = "adm_text.safetensors"


def text_adm_for(adm_file: Path) -> Path:
    """The ADM for when no target is known: :data:`TEXT_ADM` beside a folder's
    ``adm.safetensors``, else the ADM itself."""
    other = Path(adm_file).with_name(TEXT_ADM)
    return other if Path(adm_file).name == "adm.safetensors" and other.is_file() else Path(adm_file)


def adm_view(adm_config: dict) -> str:
    """An ADM's ``crop.centre`` (``motion``, the crop view, when its file predates it)."""
    return adm_config.get("crop", {}).get("centre", "motion")


def adm_text_tokens(adm_config: dict) -> int:
    """How many token states an ADM reads (``model.text_tokens``; 0 = the pooled text)."""
    return int(adm_config.get("model", {}).get("text_tokens", 0))


def resolve_checkpoints(checkpoints) -> tuple[Path, Path]:
    """``(ADM file, AMDM file)`` for ``checkpoints``: None (the shipped ones), a folder with
    ``adm.safetensors`` and ``amdm.safetensors``, or an ``(adm, amdm)`` pair of training
    workdirs or files; :class:`GenerateError` when one is missing."""
    if checkpoints is None:
        adm, amdm = default_checkpoints()
        if not (adm.is_file() and amdm.is_file()):
            raise GenerateError(
                f"the default checkpoints are missing from {_ASSETS}; reinstall jaxmotion or pass "
                "checkpoints=DIR (a folder with adm.safetensors and amdm.safetensors)")
        return adm, amdm
    if isinstance(checkpoints, (tuple, list)):
        if len(checkpoints) != 2:
            raise GenerateError("checkpoints as a pair must be (ADM, AMDM) workdirs or files")
        from jaxmotion.models.weights import weights_path

        paths = [weights_path(p) for p in checkpoints]
    else:
        folder = Path(checkpoints)
        paths = [folder / "adm.safetensors", folder / "amdm.safetensors"]
    for p in paths:
        if not p.is_file():
            raise GenerateError(f"{p}: no such checkpoint file; a checkpoint folder holds "
                                "adm.safetensors and amdm.safetensors")
    return paths[0], paths[1]


@functools.lru_cache(maxsize=4)
def load_pipeline(adm: str, amdm: str):
    """The :class:`~jaxmotion.pipelines.affordance.AffordancePipeline` of two weights files
    (kept for the process: a second call with the same files returns the same object)."""
    from jaxmotion.pipelines.affordance import AffordancePipeline

    try:
        return AffordancePipeline.from_files(adm, amdm)
    except (KeyError, ValueError) as e:
        raise GenerateError(f"checkpoints {adm} and {amdm} do not load together: {e}") from e


def weights_config(path) -> dict:
    """The config stored in a weights file (:func:`jaxmotion.models.weights.read_config`)."""
    from jaxmotion.models.weights import read_config

    try:
        return read_config(path)
    except (OSError, ValueError) as e:
        raise GenerateError(f"{path}: not a jaxmotion weights file ({e})") from e


#: The object-centric pipeline's files in a checkpoint folder (and in the shipped assets).
OBJECT_CENTRIC_FILES = ("trajectory.safetensors", "completion.safetensors")


def resolve_object_checkpoints(checkpoints) -> tuple[Path, Path]:
    """``(trajectory file, completion file)`` of the object-centric pipeline: None (the shipped
    ones), a folder holding :data:`OBJECT_CENTRIC_FILES`, or a pair of training workdirs or
    files; :class:`GenerateError` when one is missing."""
    if isinstance(checkpoints, (tuple, list)):
        if len(checkpoints) != 2:
            raise GenerateError("object checkpoints as a pair must be (trajectory, completion) "
                                "workdirs or files")
        from jaxmotion.models.weights import weights_path

        paths = [weights_path(p) for p in checkpoints]
    else:
        folder = _ASSETS if checkpoints is None else Path(checkpoints)
        paths = [folder / name for name in OBJECT_CENTRIC_FILES]
    for p in paths:
        if not p.is_file():
            how = ("train them with python -m jaxmotion.train --config configs/trajectory.py "
                   "and configs/completion.py, and pass their workdirs")
            raise GenerateError(f"{p}: no such checkpoint file; the object-centric pipeline "
                                f"needs {' and '.join(OBJECT_CENTRIC_FILES)} ({how})")
    for p, task in zip(paths, ("trajectory", "completion"), strict=True):
        got = weights_config(p).get("task")
        if got != task:
            raise GenerateError(f"{p} is a {got!r} checkpoint, not a {task} one")
    return paths[0], paths[1]


def resolve_cvae_checkpoints(checkpoints) -> tuple[Path, ...]:
    """The cVAE baseline's weights files: a training workdir or ``.safetensors`` of a
    ``configs/cvae.py`` run, or several (action-specific ones and / or an action-agnostic
    one, at most one per action). No cVAE ships with jaxmotion: None is refused.
    :class:`GenerateError` when one is missing, is not a cVAE, or they disagree on the
    motions' length or the crop's size."""
    from jaxmotion.models.weights import weights_path

    how = ("train one with python -m jaxmotion.train --config configs/cvae.py workdir=DIR and "
           "pass it (--cvae DIR; cvae_checkpoints=DIR)")
    if checkpoints is None or (isinstance(checkpoints, (tuple, list)) and not checkpoints):
        raise GenerateError(f"the cvae pipeline needs trained weights, and none ship with "
                            f"jaxmotion: {how}")
    given = checkpoints if isinstance(checkpoints, (tuple, list)) else (checkpoints,)
    paths = tuple(weights_path(p) for p in given)
    seen: dict[str, Path] = {}
    shapes = set()
    for p in paths:
        if not p.is_file():
            raise GenerateError(f"{p}: no such checkpoint file; {how}")
        cfg = weights_config(p)
        if cfg.get("task") != "cvae":
            raise GenerateError(f"{p} is a {cfg.get('task')!r} checkpoint, not a cvae one")
        action = cfg.get("action", "")
        if action in seen:
            raise GenerateError(f"{seen[action]} and {p} are both cVAEs for "
                                f"{action or 'any action (action-agnostic)'}; give one")
        seen[action] = p
        shapes.add((cfg["max_frames"], cfg["crop"]["size"]))
    if len(shapes) > 1:
        raise GenerateError(f"the cVAE checkpoints {', '.join(map(str, paths))} differ in "
                            "max_frames or crop.size; give ones trained alike")
    return paths


def pipeline_files(opts) -> tuple[Path, ...] | None:
    """The weights files of ``opts.pipeline`` (:class:`~jaxmotion.options.GenerateOptions`)
    besides the ADM and AMDM: the object-centric models (``auto``, ``object-centric``), the
    cVAE's (``cvae``), or None (``affordance``)."""
    if opts.pipeline == "affordance":
        return None
    if opts.pipeline == "cvae":
        return resolve_cvae_checkpoints(opts.cvae_checkpoints)
    return resolve_object_checkpoints(opts.object_checkpoints)


def pick_pipeline(requested: str, files, target) -> str:
    """The pipeline that samples, once grounding has run: ``cvae`` when asked for; the
    object-centric one when its ``files`` are there and the target object is known
    (``target`` not None); else the affordance one. :class:`GenerateError` when
    ``object-centric`` is asked for and no target is known."""
    if requested == "object-centric" and target is None:
        raise GenerateError("the object-centric pipeline needs a target object, and the "
                            "text names none of this room's: name one, or pass object_id")
    if requested == "cvae":
        return "cvae"
    return "object-centric" if files and target is not None else "affordance"
