"""A differentiable SMPL-X body in JAX and joints → body fitting.

- :mod:`jaxmotion.body.model`: the SMPL-X kinematic tree with linear blend
  skinning of the mannequin-x "wooden" mesh (:func:`load_mannequin`) or of a
  user's own SMPL-X model file (:func:`load_smplx`); :func:`body_forward` poses
  it from SMPL-X parameters into vertices, vertex normals and joints (z-up world).
- :mod:`jaxmotion.body.fit`: :func:`fit_joints_to_body`, SMPL-X parameters from
  joints with jaxopt's LBFGS, smoothness and joint-limit priors, vmapped over
  sequences.
- :mod:`jaxmotion.body.priors`: joint limits (degrees per joint axis) and
  smoothness terms.
"""

from jaxmotion.body.model import (
    BodyModel,
    BodyOutput,
    body_forward,
    forward_tree,
    joint_names,
    lbs,
    load_mannequin,
    load_smplx,
    local_rotations,
    shaped_rest,
    shaped_rest_host,
    vertex_normals,
)
from jaxmotion.body.priors import (
    JOINT_LIMITS_DEG,
    LIMIT_AXES,
    joint_limit_excess,
    limit_angles,
    rotation_from_limit_angles,
)

_FIT = ("BodyFit", "FitWeights", "fit_joints_to_body", "initial_pose")
__all__ = [
    "JOINT_LIMITS_DEG", "LIMIT_AXES", "BodyFit", "BodyModel", "BodyOutput", "FitWeights",
    "body_forward", "fit_joints_to_body", "forward_tree", "initial_pose", "joint_limit_excess",
    "joint_names", "lbs", "limit_angles", "load_mannequin", "load_smplx", "local_rotations",
    "rotation_from_limit_angles", "shaped_rest", "shaped_rest_host", "vertex_normals",
]


def __getattr__(name):  # the fit (and jaxopt, ~0.3 s to import) only when asked for
    if name in _FIT:
        from jaxmotion.body import fit

        return getattr(fit, name)
    raise AttributeError(f"module 'jaxmotion.body' has no attribute {name!r}")
