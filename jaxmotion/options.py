"""The options of ``generate``: one frozen dataclass, validated once, shared by every caller.

:class:`GenerateOptions` holds how to sample (steps, guidance, candidates, grounding, ...) with
the shipped defaults, and checks every value when it is built, so the command line, the Python
API, the eval runner and the probes share the defaults and the validation (the ``check_*``
functions are the per-value checks the eval runner's ``--model`` syntax reuses). A bad value is a
:class:`~jaxmotion.errors.GenerateError` whose message names the fix, raised before anything is
loaded.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np

from jaxmotion.errors import GenerateError

__all__ = [
    "DEFAULT_ADM_CANDIDATES", "DEFAULT_ADM_STEPS", "DEFAULT_CONSISTENCY", "DEFAULT_GUIDANCE",
    "DEFAULT_MOTION_CANDIDATES", "DEFAULT_STEPS", "DEFAULT_TEXT", "GROUNDINGS", "MAX_ADM_CANDIDATES",
    "MAX_MOTION_CANDIDATES", "MAX_SAMPLES", "PIPELINES", "GenerateOptions", "check_candidates",
    "check_consistency", "check_guidance", "check_positive_int",
]

DEFAULT_TEXT = "sit on the chair next to the table"
#: Classifier-free guidance scales (ADM, AMDM) of the shipped checkpoints, chosen on the
#: synthetic validation split (docs/results.md in the git history, "Guidance"): w = 5 on the
#: ADM sharpens its maps; guiding the AMDM made motions end farther away.
DEFAULT_GUIDANCE: tuple[float, float] = (5.0, 1.0)
#: Strength of affordance-consistency guidance on the AMDM (0 = off; see
#: :mod:`jaxmotion.diffusion.affordance_guidance`), chosen on the validation split
#: (docs/results.md in the git history, "Consistency guidance").
DEFAULT_CONSISTENCY: float = 0.5
#: ADM maps drawn per sample once the target object is known; the one lighting it most is kept
#: (docs/results.md in the git history, "The generate protocol").
DEFAULT_ADM_CANDIDATES: int = 16
#: DDIM steps of the affordance stage: how often the ADM's maps light the target depends on how
#: many are drawn, not on their steps (3 to 20), so the time buys candidates.
DEFAULT_ADM_STEPS: int = 5
#: DDIM steps of the motion stage (AMDM).
DEFAULT_STEPS: int = 20
#: Motions drawn per sample from its map once the target object is known; the one whose body
#: comes closest to the target at the anchor frame is kept (docs/results.md in the git
#: history, "Best of M motions").
DEFAULT_MOTION_CANDIDATES: int = 4
MAX_SAMPLES = 256
MAX_ADM_CANDIDATES = 32
MAX_MOTION_CANDIDATES = 16
#: How the target is found without ``object_id``: ``auto`` (words, the scene graph, then the
#: ADM), ``adm`` (the ADM among the named class), ``llm`` (a language model, two prompts).
GROUNDINGS = ("auto", "adm", "llm")
#: The generation pipelines (``pipeline`` option); the first is the default: ``auto`` runs the
#: object-centric pipeline when the text's target object is found (no teleports, the action
#: done on the target; docs/benchmarks.md) and the affordance pipeline otherwise. ``cvae`` is the
#: HUMANISE baseline, run only when asked for (its weights are the user's: none ship).
PIPELINES = ("auto", "affordance", "object-centric", "cvae")


def check_positive_int(name: str, value, lo: int = 1, hi: int | None = None) -> int:
    """``value`` as an int in [lo, hi]; :class:`GenerateError` otherwise (bools refused)."""
    if not isinstance(value, (int, np.integer)) or isinstance(value, bool) or value < lo or (
            hi is not None and value > hi):
        span = f"≥ {lo}" if hi is None else f"in [{lo}, {hi}]"
        raise GenerateError(f"{name} must be an integer {span}, got {value!r}")
    return int(value)


def check_candidates(name: str, value) -> int:
    """``adm_candidates`` (1..32) or ``motion_candidates`` (1..16)."""
    hi = MAX_ADM_CANDIDATES if name == "adm_candidates" else MAX_MOTION_CANDIDATES
    return check_positive_int(name, value, 1, hi)


def check_guidance(guidance) -> tuple[float, float]:
    """``None`` / one scale / an ``(ADM, AMDM)`` pair → two positive floats."""
    if guidance is None:
        return DEFAULT_GUIDANCE
    pair = (guidance, guidance) if np.ndim(guidance) == 0 else tuple(guidance)
    try:
        pair = tuple(float(g) for g in pair)
    except (TypeError, ValueError):
        pair = ()
    if len(pair) != 2 or not all(np.isfinite(g) and g > 0 for g in pair):
        raise GenerateError(f"guidance must be a positive number or an (ADM, AMDM) pair of them "
                            f"(1 = no guidance), got {guidance!r}")
    return pair


def check_consistency(value) -> float:
    """``None`` → :data:`DEFAULT_CONSISTENCY`; else a float in [0, 1]."""
    if value is None:
        return DEFAULT_CONSISTENCY
    try:
        v = float(value)
    except (TypeError, ValueError):
        v = float("nan")
    if isinstance(value, bool) or not 0.0 <= v <= 1.0:
        raise GenerateError(f"consistency must be a number in [0, 1] (0 = off), got {value!r}")
    return v


@dataclasses.dataclass(frozen=True)
class GenerateOptions:
    """How :func:`jaxmotion.generate` samples; every field is checked when built.

    Attributes:
      object_id: target the object with this instance id instead of finding it from the text.
      samples: K motions, batched by vmap (1..256); seed: the PRNG seed (same seed, same
        output).
      steps: DDIM steps of the motion stage (AMDM); adm_steps: of the affordance stage (ADM).
      guidance: classifier-free guidance ``(ADM, AMDM)``; one number sets both (1 = none).
      consistency: strength in [0, 1] of affordance-consistency guidance (0 = off).
      grounding: ``auto`` (a relation in the text narrows the named objects by the scene's
        geometry; among several left, the one a body reaches most freely; with none named, a
        walk to an object drawn with the seed: :mod:`jaxmotion.grounding.reach`), ``adm``
        (the ADM's map chooses among the named class, or where it is strongest when none is
        named) or ``llm`` (a language model at ``JAXMOTION_LLM_URL`` chooses the target in two
        prompts, :mod:`jaxmotion.grounding.llm`; prompts and answers saved as
        ``grounding_llm.json``).
      adm_candidates: once the target is known, the ADM draws this many maps per sample and
        the one lighting the target most is kept (1..32).
      motion_candidates: once the target is known, the AMDM draws this many motions per sample
        and the one reaching the target at the anchor frame is kept (1..16).
      checkpoints: None (shipped), a folder with ``adm.safetensors`` / ``amdm.safetensors``,
        or an ``(adm, amdm)`` pair of workdirs / files.
      pipeline: ``auto`` (the default: object-centric when the target object is known, else
        affordance), ``affordance`` (ADM → AMDM), ``object-centric`` (sensors → trajectory
        → completion, Cen et al. 2024; needs a target object, grounded as for the affordance
        pipeline, whose ADM still chooses among same-class candidates) or ``cvae`` (the
        HUMANISE cVAE baseline on the crop around the grounded target; ``cvae_checkpoints``).
      object_checkpoints: the object-centric models: None (shipped), a folder with
        ``trajectory.safetensors`` / ``completion.safetensors``, or a ``(trajectory,
        completion)`` pair of workdirs / files.
      cvae_checkpoints: the HUMANISE cVAE baseline's weights (``pipeline="cvae"``): a
        ``configs/cvae.py`` training workdir or ``.safetensors``, or a tuple of them
        (action-specific and / or action-agnostic models); none ship, so the cvae pipeline
        needs them.
      num_points: surface samples taken from a mesh (None: the loader's default).
      up: the room file's up axis: ``auto`` (found from its floor), ``z`` or ``y``; unit: its
        length unit, ``auto`` (from its size) or ``m`` / ``cm`` / ``mm`` / ``ft`` / ``in``
        (:mod:`jaxmotion.scene.level`).
      fit: fit SMPL-X bodies (needed to write BVH / GLB); fit_iters: LBFGS iterations.
      aot: keep the traced programs on disk (:mod:`jaxmotion.compiled`).
    """

    object_id: int | None = None
    samples: int = 1
    seed: int = 0
    steps: int = DEFAULT_STEPS
    adm_steps: int = DEFAULT_ADM_STEPS
    guidance: tuple[float, float] = DEFAULT_GUIDANCE
    consistency: float = DEFAULT_CONSISTENCY
    grounding: str = "auto"
    adm_candidates: int = DEFAULT_ADM_CANDIDATES
    motion_candidates: int = DEFAULT_MOTION_CANDIDATES
    checkpoints: str | Path | tuple | None = None
    pipeline: str = "auto"
    object_checkpoints: str | Path | tuple | None = None
    cvae_checkpoints: str | Path | tuple | None = None
    num_points: int | None = None
    up: str = "auto"
    unit: str = "auto"
    fit: bool = True
    fit_iters: int = 100
    aot: bool = True

    def __post_init__(self):
        put = lambda k, v: object.__setattr__(self, k, v)
        if self.object_id is not None:
            put("object_id", check_positive_int("object_id", self.object_id, 0))
        put("samples", check_positive_int("samples", self.samples))
        if self.samples > MAX_SAMPLES:
            raise GenerateError(f"samples={self.samples} is more than {MAX_SAMPLES}; generate "
                                "in several calls")
        put("seed", check_positive_int("seed", self.seed, 0))
        put("steps", check_positive_int("steps", self.steps))
        put("adm_steps", check_positive_int(
            "adm_steps", DEFAULT_ADM_STEPS if self.adm_steps is None else self.adm_steps))
        put("guidance", check_guidance(self.guidance))
        put("consistency", check_consistency(self.consistency))
        if self.grounding not in GROUNDINGS:
            raise GenerateError(f"grounding must be one of {', '.join(GROUNDINGS)}, got "
                                f"{self.grounding!r}")
        for name, default in (("adm_candidates", DEFAULT_ADM_CANDIDATES),
                              ("motion_candidates", DEFAULT_MOTION_CANDIDATES)):
            value = getattr(self, name)
            put(name, check_candidates(name, default if value is None else value))
        if self.num_points is not None:
            put("num_points", check_positive_int("num_points", self.num_points, 1))
        put("fit_iters", check_positive_int("fit_iters", self.fit_iters))
        if self.up not in ("auto", "z", "y"):
            raise GenerateError(f"up must be auto, z or y, got {self.up!r}")
        if self.unit not in ("auto", "m", "cm", "mm", "ft", "in"):
            raise GenerateError(f"unit must be auto, m, cm, mm, ft or in, got {self.unit!r}")
        if isinstance(self.checkpoints, list):
            put("checkpoints", tuple(self.checkpoints))
        if isinstance(self.object_checkpoints, list):
            put("object_checkpoints", tuple(self.object_checkpoints))
        if isinstance(self.cvae_checkpoints, list):
            put("cvae_checkpoints", tuple(self.cvae_checkpoints))
        if self.pipeline not in PIPELINES:
            raise GenerateError(f"pipeline must be one of {', '.join(PIPELINES)}, got "
                                f"{self.pipeline!r}")

    @classmethod
    def build(cls, **kwargs) -> GenerateOptions:
        """Options from keyword arguments where None means "the default" (as the command
        line and :func:`jaxmotion.generate` pass them); unknown names are refused."""
        names = {f.name for f in dataclasses.fields(cls)}
        unknown = sorted(set(kwargs) - names)
        if unknown:
            raise GenerateError(f"unknown option(s) {', '.join(unknown)}; valid: "
                                + ", ".join(sorted(names)))
        keep_none = {"object_id", "checkpoints", "num_points", "object_checkpoints",
                     "cvae_checkpoints"}
        return cls(**{k: v for k, v in kwargs.items() if v is not None or k in keep_none})

    @classmethod
    def merged(cls, options: GenerateOptions | None, **overrides) -> GenerateOptions:
        """``options`` (None: built from ``overrides`` by :meth:`build`) with the ``overrides``
        that are not None replacing its fields, as :func:`jaxmotion.generate` takes them."""
        if options is None:
            return cls.build(**overrides)
        return dataclasses.replace(options, **{k: v for k, v in overrides.items()
                                               if v is not None})
