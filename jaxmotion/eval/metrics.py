"""Every evaluation metric in one namespace, and APD.

The metrics of HUMANISE, "Move as You Say, Interact as You Can" and Guo et al.
2022, as pure functions (formulas, shapes and units in each docstring):

- body–scene (:mod:`.body_metrics`): :func:`signed_distance_to_body` (positive
  inside), :func:`non_collision`, :func:`contact`, :func:`goal_distance` at the
  :func:`anchor_index` frame;
- joints-only fast variants (:mod:`.joint_spheres`): :func:`joint_sphere_sdf`,
  :func:`joints_physical_metrics`;
- motion: :func:`apd` (here), :func:`foot_skating` (:mod:`.skating`);
- plausibility (:mod:`.plausibility`): :func:`plausibility` (top pelvis / joint speeds,
  teleports, jerk, floor penetration, skating, bone-length spread per motion) and
  :func:`summarize_plausibility`; the geometric action judge (:mod:`.action_judge`):
  :func:`judge_action` (seated / lying / standing near the target at the anchor frame);
- grounding (:mod:`.grounding`): :func:`affordance_grounding`,
  :func:`grounding_accuracy`;
- text–motion, host-side numpy (:mod:`.text_motion_metrics`): :func:`fid`,
  :func:`r_precision`, :func:`multimodal_distance`, :func:`diversity`,
  :func:`multimodality`.

The jax functions work on one motion / case (``vmap`` for batches) and are
``jit``-compatible; string arguments such as ``action`` are static. Units are
metres; frame masks are ``[T]`` bools, True = valid. Empty inputs: a zero-size
axis raises ``ValueError``; a mask selecting nothing raises ``ValueError`` when
called eagerly and gives NaN under ``jit`` / ``vmap``.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from jaxmotion.eval._common import as_mask, masked_mean, require_any, require_nonempty, safe_norm
from jaxmotion.eval.action_judge import action_id, action_report, judge_action, judge_actions
from jaxmotion.eval.body_metrics import (
    CONTACT_THRESHOLD,
    anchor_goal_distance,
    anchor_index,
    contact,
    goal_distance,
    is_stand_up,
    non_collision,
    signed_distance_to_body,
    signed_distance_to_body_frames,
)
from jaxmotion.eval.grounding import (
    SUCCESS_THRESHOLDS,
    affordance_grounding,
    affordance_grounding_from_map,
    grounding_accuracy,
)
from jaxmotion.eval.joint_spheres import (
    JOINT_RADII,
    joint_sphere_sdf,
    joint_sphere_sdf_frames,
    joints_goal_distance,
    joints_physical_metrics,
)
from jaxmotion.eval.plausibility import (
    PLAUSIBILITY_KEYS,
    TELEPORT_JOINT_SPEED,
    TELEPORT_PELVIS_SPEED,
    plausibility,
    summarize_plausibility,
)
from jaxmotion.eval.skating import FOOT_FLOOR_OFFSETS, FOOT_JOINTS, foot_skating
from jaxmotion.eval.text_motion_metrics import (
    diversity,
    euclidean_distance_matrix,
    fid,
    frechet_distance,
    multimodal_distance,
    multimodality,
    r_precision,
)

__all__ = [
    "PLAUSIBILITY_KEYS", "TELEPORT_JOINT_SPEED", "TELEPORT_PELVIS_SPEED", "action_id",
    "action_report", "judge_action", "judge_actions", "plausibility", "summarize_plausibility",
    "CONTACT_THRESHOLD",
    "FOOT_FLOOR_OFFSETS",
    "FOOT_JOINTS",
    "JOINT_RADII",
    "SUCCESS_THRESHOLDS",
    "affordance_grounding",
    "affordance_grounding_from_map",
    "anchor_goal_distance",
    "anchor_index",
    "apd",
    "contact",
    "diversity",
    "euclidean_distance_matrix",
    "fid",
    "foot_skating",
    "frechet_distance",
    "goal_distance",
    "grounding_accuracy",
    "is_stand_up",
    "joint_sphere_sdf",
    "joint_sphere_sdf_frames",
    "joints_goal_distance",
    "joints_physical_metrics",
    "multimodal_distance",
    "multimodality",
    "non_collision",
    "r_precision",
    "signed_distance_to_body",
    "signed_distance_to_body_frames",
]


def apd(samples, mask=None):
    """Average pairwise distance between K samples of one case: ``[K, T, ...] -> ()``.

    ``APD = mean_t  1/(K(K−1)) Σ_{i≠j} || x_{i,t} − x_{j,t} ||₂`` — the mean over
    ordered pairs, which equals the mean over unordered pairs ``i < j`` (each
    distance is counted twice). Trailing axes are flattened into one vector per
    frame (e.g. ``[K, T, 22, 3]`` → 66-d, afford-motion; ``[K, T, 67, 3]`` markers,
    HUMANISE). K = 1 gives 0. ``mask``: ``[T]`` valid frames.

    Memory: a loop over samples keeps one ``[K, T, D]`` block alive.
    """
    samples = jnp.asarray(samples, jnp.float32)
    if samples.ndim < 3:
        raise ValueError(f"samples must be [K, T, ...], got shape {samples.shape}")
    require_nonempty(samples, "samples", "need at least one sample")
    k, t = samples.shape[:2]
    if t == 0:
        raise ValueError("samples have no frames")
    mask = as_mask(mask, t, "mask")
    require_any(mask, "mask selects no frame: APD is undefined")
    if k == 1:
        return jnp.zeros((), jnp.float32)
    return _apd(samples.reshape(k, t, -1), mask)


@jax.jit
def _apd(x, mask):
    k = x.shape[0]
    # Row i: Σ_j |x_i − x_j| per frame; the diagonal term is exactly 0.
    rows = jax.lax.map(lambda xi: jnp.sum(safe_norm(x - xi[None]), axis=0), x)  # [K, T]
    per_frame = jnp.sum(rows, axis=0) / (k * (k - 1))
    return masked_mean(per_frame, mask)
