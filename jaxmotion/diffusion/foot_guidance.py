"""Foot guidance: the completion stage plants the feet it puts on the floor.

The completion model writes the body along a root trajectory that the first stage drew
without the legs. Under the generate protocol its feet came out at the wrong height for
that root (the lowest foot a whole motion 5–13 cm above or under the floor, within a motion
a 2–3 cm spread) and slid while they touched the floor, in seated phases most of all.
This module corrects the predicted clean motion ``x̂0`` at the late reverse steps of
that stage (noise levels under :data:`ACTIVE_FRACTION` of the schedule's), as
reconstruction guidance (MDM's foot-contact loss, GMD / OmniControl's spatial guidance,
:mod:`.anchor_guidance` on the trajectory stage): a few gradient steps on the
body's joint rotations lower

- **sliding**: the horizontal speed (m/s, in units of 0.5 m/s, the skating threshold) of
  each foot joint between two frames in which it is near the floor, weighted by how near
  (a smooth step at 5 cm above its flat-foot height, taken as a constant: the term holds a
  planted foot still, it does not lift a foot to stop it counting);
- **floor**: the height of the lowest foot joint above (or under) its flat-foot height,
  in units of 5 cm, in every frame of every action but lie (a lying body's feet rest on
  the bed);
- **sink**: how far each foot joint is more than :data:`SINK_TOLERANCE` under its
  flat-foot height, in units of 5 cm, squared and summed over the frames (divided by
  :data:`SINK_FRAMES`, not by the motion's length), in every action: a body perched on a
  seat too high for its legs had its toes 7–12 cm in the floor for 20 frames, and the
  floor term, a mean over the motion's frames, moved them 2 cm. Feet above the floor give
  it exactly nothing (``docs/results.md`` (git history), "Feet out of the floor: the sink term");
- **fast**: how far each foot joint moves faster than :data:`FAST_SPEED` between two frames,
  in units of :data:`FAST_SCALE`, squared and summed as the sink term: on real beds, the legs
  swung up onto the mattress at 9.0 m/s, the teleport threshold; a walking foot (3–5 m/s) is
  left alone;

the sampler's later steps then continue from the corrected ``x̂0``, so the body the
model finishes is its own, fitted to the planted feet. The root trajectory is not moved
(it stays the first stage's, held by inpainting): the legs bend or stretch to reach the
floor and hold a foot where it stands while the pelvis moves over it.

Pure functions of arrays for one motion; ``vmap`` for batches.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from jaxmotion.constants import ACTION_CLASSES, FOOT_JOINTS, SCENE_FPS
from jaxmotion.eval.skating import FOOT_FLOOR_OFFSETS
from jaxmotion.motion.representation import TRAJECTORY_DIM, motion_to_joints

__all__ = ["ACTIVE_FRACTION", "CONTACT_HEIGHT", "FAST_SCALE", "FAST_SPEED", "FLOOR_SCALE",
           "ITERATIONS", "SINK_FRAMES", "SINK_TOLERANCE", "SLIDE_SCALE", "STEP", "foot_loss",
           "foot_terms", "make_foot_refiner", "make_refiner"]

#: A foot joint this far (m) above its flat-foot height is half "near the floor".
CONTACT_HEIGHT = 0.05
#: Width (m) of the smooth step around :data:`CONTACT_HEIGHT`.
CONTACT_SOFTNESS = 0.01
#: Units of the two terms: a foot sliding at 0.5 m/s, the lowest foot 5 cm off the floor.
SLIDE_SCALE = 0.5
FLOOR_SCALE = 0.05
#: A foot joint more than this (m) under its flat-foot height is in the floor: the sink term.
SINK_TOLERANCE = 0.01
#: The sink term is summed over the frames and divided by this many, not by the motion's
#: length: a few frames in the floor (a perched start on a bar stool) are not diluted by the
#: many where the feet are fine, whose gradient is exactly 0.
SINK_FRAMES = 2.0
#: A foot joint faster than this (m/s) is slowed, in units of FAST_SCALE, summed over the
#: frame pairs (as the sink term): a swing of the legs onto a bed reached the teleport
#: threshold (9 m/s); a walking foot swings at 3-5 m/s and is left alone.
FAST_SPEED, FAST_SCALE = 6.5, 1.0
#: Gradient steps per reverse step, and the size of each (normalised feature units).
ITERATIONS = 3
STEP = 1.0
#: The gradient is smoothed over time by a Gaussian of this many frames before each step
#: (a positive semi-definite kernel: still a descent direction), so that the correction is
#: as smooth as the motion; a raw per-frame step leaves a frame-to-frame zigzag (jerk).
SMOOTHING = 2.0
#: The samplers apply it at the reverse steps whose noise level is under this fraction of the
#: schedule's steps (the late steps, where the body's pose is being settled: 6 of DDIM-20's
#: 20, for the cost of 6 rather than 20; see ``docs/results.md`` (git history), "Foot guidance
#: on the late steps only").
ACTIVE_FRACTION = 0.3

_LIE = ACTION_CLASSES.index("lie")


def foot_loss(features, betas, mask, action, floor_weight: float = 1.0):
    """Sliding + floor + sink + fast terms (module docstring) of motion ``features [T, 135]`` (metres,
    crop frame), body ``betas [10]``, valid frames ``mask [T]``, ``action`` index.

    Returns a float32 scalar (mean over valid frame pairs / frames)."""
    # the feet's kinematic chain alone: the same positions, a third of the work
    return foot_terms(motion_to_joints(features, betas, FOOT_JOINTS), mask, action,
                      floor_weight)


def foot_terms(feet, mask, action, floor_weight: float = 1.0):
    """:func:`foot_loss` of the foot joints ``feet [T, 4, 3]`` (``FOOT_JOINTS``, placed
    already: a caller that places the whole body shares its forward kinematics)."""
    offsets = jnp.asarray(FOOT_FLOOR_OFFSETS, jnp.float32)
    height = feet[..., 2] - offsets  # [T, F]
    near = jax.lax.stop_gradient(jax.nn.sigmoid((CONTACT_HEIGHT - height) / CONTACT_SOFTNESS))
    mask = jnp.asarray(mask, bool)
    pair = (mask[1:] & mask[:-1]).astype(jnp.float32)  # [T-1]
    step = (feet[1:, :, :2] - feet[:-1, :, :2]) * (SCENE_FPS / SLIDE_SCALE)
    slide = jnp.sum(near[1:] * near[:-1] * jnp.sum(step ** 2, axis=-1), axis=1)  # [T-1]
    slide = jnp.sum(slide * pair) / jnp.maximum(jnp.sum(pair), 1.0)
    lowest = -CONTACT_SOFTNESS * jax.nn.logsumexp(-height / CONTACT_SOFTNESS, axis=1)
    valid = mask.astype(jnp.float32) * (jnp.asarray(action) != _LIE)
    floor = jnp.sum(valid * (lowest / FLOOR_SCALE) ** 2) / jnp.maximum(jnp.sum(mask), 1.0)
    under = jax.nn.relu(-height - SINK_TOLERANCE) / FLOOR_SCALE  # [T, F]
    sink = jnp.sum(mask.astype(jnp.float32)[:, None] * under ** 2) / SINK_FRAMES
    speed = jnp.linalg.norm(feet[1:] - feet[:-1] + 1e-9, axis=-1) * SCENE_FPS  # [T-1, F]
    fast = jax.nn.relu(speed - FAST_SPEED) / FAST_SCALE
    fast = jnp.sum(pair[:, None] * fast ** 2) / SINK_FRAMES
    return slide + floor_weight * floor + sink + fast


def make_foot_refiner(betas, mask, action, mean, std, strength: float = 1.0, *,
                      iterations: int = ITERATIONS, step: float = STEP,
                      active_below: int | None = None):
    """A ``refine_fn(x0_hat [1, T, D], t [1]) -> x0_hat`` for the completion sampler.

    ``mean``, ``std``: the completion model's feature statistics (``x0_hat`` is
    normalised); ``strength`` in [0, 1] scales the step (0 = off); ``iterations``
    gradient steps of size ``step`` at each reverse step whose noise level ``t`` is below
    ``active_below`` (None: at every step; the earlier steps return ``x0_hat`` unchanged
    and cost nothing, ``t`` must not be batched under ``vmap``, as a sampler's is not).
    Only the body's rotations move (features after :data:`TRAJECTORY_DIM`)."""
    betas = None if betas is None else jnp.asarray(betas, jnp.float32)
    return make_refiner(lambda f: strength * foot_loss(f, betas, mask, action), mean, std,
                        iterations=iterations, step=step, active_below=active_below)


def make_refiner(loss, mean, std, *, iterations: int = ITERATIONS, step: float = STEP,
                 active_below: int | None = None):
    """The reconstruction guidance of :func:`make_foot_refiner` for any ``loss(features
    [T, 135]) -> scalar`` of the motion in metres (foot guidance's terms, those of
    :mod:`.body_clearance`, or their sum): ``iterations`` steps of size ``step`` down its
    gradient, smoothed over time, on the body's rotations of ``x0_hat`` (normalised by
    ``mean``, ``std``), at the reverse steps whose noise level is below ``active_below``."""
    scale = jnp.float32(step)
    body = (jnp.arange(mean.shape[-1]) >= TRAJECTORY_DIM).astype(jnp.float32)
    grad = jax.grad(lambda x: loss(x * std + mean))
    radius = int(3 * SMOOTHING + 0.5)
    kernel = jnp.exp(-0.5 * (jnp.arange(-radius, radius + 1) / SMOOTHING) ** 2)
    kernel = kernel / jnp.sum(kernel)

    def smooth(g):  # [T, D] along T, zero-padded
        return jax.vmap(lambda c: jnp.convolve(c, kernel, mode="same"), in_axes=1,
                        out_axes=1)(g)

    def guided(x0):
        def one(_, x):
            return x - scale * body * smooth(grad(x))

        return jax.lax.fori_loop(0, int(iterations), one, x0[0])[None]

    if active_below is None:
        return lambda x0, t: guided(x0)
    return lambda x0, t: jax.lax.cond(jnp.reshape(t, (-1,))[0] < active_below, guided,
                                      lambda x: x, x0)
