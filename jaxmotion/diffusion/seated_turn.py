"""Seated turn: a seated body's legs turned towards free floor.

A chair in a real room has neighbours: the next chair 15 cm in front of it, a table's legs,
a coffee table before a sofa. The trajectory model seats the body facing the way it came, and
the legs of the seated body then go into whatever stands there (on real ScanNet rooms, the
knees and feet of a body on a chair against the next chair for a third of the motion). A
person sits down turned a little towards the free side.

This module turns the seated part of a sit (or a stand-up) about the vertical through the
pelvis, after the path is sampled and cleared (:mod:`.clearance`): of the yaw angles
:data:`ANGLES`, the one whose leg area is freest. The leg area of a heading is
:data:`LEG_SAMPLES` places in front of the pelvis (:data:`LEG_REACH` metres ahead,
:data:`LEG_HALF_WIDTH` to either side), and its cost the number of obstacle points (any but the
target's, between :data:`LEG_BAND` above the floor) within :data:`LEG_RADIUS` of them, plus
:data:`TURN_COST` per radian turned, so that a body turns only when it frees its legs, and
never more than it must. The turn is taken in full over the anchor's hold and fades out over
the taper before it (:data:`~.anchor_guidance.HOLD`, :data:`~.anchor_guidance.TAPER`): the
body turns as it sits down. Positions are not touched. Pure functions of arrays for one
motion; ``vmap`` for batches.
"""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp

from jaxmotion.constants import ACTION_CLASSES
from jaxmotion.diffusion.anchor_guidance import anchor_frame, hold_weights

__all__ = ["ANGLES", "LEG_BAND", "LEG_HALF_WIDTH", "LEG_RADIUS", "LEG_REACH", "LEG_SAMPLES",
           "TURN_COST", "leg_cost", "seated_turn", "turn_yaw"]

_SIT, _STAND_UP = ACTION_CLASSES.index("sit"), ACTION_CLASSES.index("stand_up")

#: Yaw angles tried (radians): up to 50 degrees either way, in 10 degree steps.
ANGLES = tuple(math.radians(d) for d in range(-50, 51, 10))
#: Where a seated body's legs are, relative to its pelvis: this far ahead (m) ...
LEG_REACH = (0.2, 0.35, 0.5, 0.65)
#: ... this far to either side (m) ...
LEG_HALF_WIDTH = 0.15
#: ... between these heights (m) ...
LEG_BAND = (0.05, 0.7)
#: ... and an obstacle point within this distance (m, horizontal) of a place counts.
LEG_RADIUS = 0.08
#: The places: every reach, at the middle and both sides.
LEG_SAMPLES = len(LEG_REACH) * 3
#: Cost of turning, in obstacle points per radian: a turn must free more than a few points.
TURN_COST = 10.0


def _forward(six):
    """The body's forward axis (SMPL-X z) in the world's xy, unit length, from the 6D root
    orientation ``six [6]`` (the matrix's first two rows)."""
    f = jnp.stack([six[2], six[5]])
    return f / jnp.maximum(jnp.linalg.norm(f), 1e-6)


def leg_cost(pelvis_xy, forward, points, obstacle) -> jnp.ndarray:
    """The obstacle points (``points [N, 3]`` where ``obstacle [N]``) within
    :data:`LEG_RADIUS` of the leg places of a body seated at ``pelvis_xy [2]`` facing
    ``forward [2]`` (unit): a float count."""
    side = jnp.stack([-forward[1], forward[0]])
    reach = jnp.asarray(LEG_REACH)[:, None, None]
    lateral = jnp.asarray([-LEG_HALF_WIDTH, 0.0, LEG_HALF_WIDTH])[None, :, None]
    places = (pelvis_xy + reach * forward + lateral * side).reshape(-1, 2)
    d2 = jnp.sum((places[:, None, :] - points[None, :, :2]) ** 2, -1)
    near = jnp.any(d2 < LEG_RADIUS ** 2, axis=0) & obstacle
    return jnp.sum(near.astype(jnp.float32))


def turn_yaw(six, angle):
    """The 6D orientation ``six [..., 6]`` turned by ``angle`` (radians, broadcast) about the
    world's vertical: ``R' = R_z(angle) R`` on the matrix's first two rows."""
    r0, r1 = six[..., :3], six[..., 3:]
    c, s = jnp.cos(angle)[..., None], jnp.sin(angle)[..., None]
    return jnp.concatenate([c * r0 - s * r1, s * r0 + c * r1], axis=-1)


def seated_turn(traj, points, target_mask, mask, action, given=None):
    """The trajectory ``traj [T, 9]`` (pelvis xyz, 6D orientation; metres, crop frame) with the
    seated frames of a sit or stand up (``action``, an index of
    :data:`~jaxmotion.constants.ACTION_CLASSES`; other actions unchanged) turned towards free
    floor; ``points [N, 3]`` the crop, ``target_mask [N]`` the target's, ``mask [T]`` the valid
    frames, ``given [T]`` bool or None: frames held by inpainting, never turned. Returns ``(traj [T, 9], angle)``, the angle turned (radians)."""
    traj, points, mask = jnp.asarray(traj), jnp.asarray(points), jnp.asarray(mask, bool)
    frame = anchor_frame(mask, action)
    z = points[:, 2]
    obstacle = ~jnp.asarray(target_mask, bool) & (z > LEG_BAND[0]) & (z < LEG_BAND[1])
    pelvis, forward = traj[frame, :2], _forward(traj[frame, 3:9])
    angles = jnp.asarray(ANGLES)

    def cost(a):
        c, s = jnp.cos(a), jnp.sin(a)
        f = jnp.stack([c * forward[0] - s * forward[1], s * forward[0] + c * forward[1]])
        return leg_cost(pelvis, f, points, obstacle) + TURN_COST * jnp.abs(a)

    costs = jax.vmap(cost)(angles)
    seated = (jnp.asarray(action) == _SIT) | (jnp.asarray(action) == _STAND_UP)
    angle = jnp.where(seated, angles[jnp.argmin(costs)], 0.0)
    weight = hold_weights(mask, frame)
    if given is not None:
        weight = weight * (1.0 - jnp.asarray(given, jnp.float32))
    turned = turn_yaw(traj[:, 3:9], angle * weight)
    return traj.at[:, 3:9].set(turned), angle
