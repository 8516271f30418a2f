"""Evaluation: the metrics of HUMANISE, "Move as You Say, Interact as You Can" and
Guo et al. 2022 (text–motion), as pure functions.

:mod:`jaxmotion.eval.metrics` is the single import for every metric (body signed
distance, non-collision, contact, goal distance, APD, joints-only variants,
foot skating, affordance and target grounding, FID / R-precision / MultiModal
distance / Diversity / MultiModality). Importing compiles nothing.
"""

from jaxmotion.eval.metrics import *
from jaxmotion.eval.metrics import __all__ as _metric_names

__all__ = list(_metric_names)
