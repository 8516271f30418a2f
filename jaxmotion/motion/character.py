"""The kinematic character: per-frame controls -> joint rotations -> joints.

An action is written as :class:`Controls`: a few interpretable channels per
frame (hip-centre position, pelvis heading and tilt, spine bend, gaze, foot
targets, arm swing). :func:`solve_pose` turns them into SMPL-X local joint
rotations and the root translation:

- pelvis: ``upright(yaw) · Rx(pitch) · Rz(roll) · Ry(twist)`` (rest-frame axes:
  x = body left, y = up, z = forward; pitch > 0 leans forward);
- hips follow from the pelvis; the hip centre is lowered where a leg could not
  otherwise reach its ankle target (smoothly, then hard-clamped);
- legs: analytic two-bone IK (thigh and shin lengths of this body) to the ankle
  targets, knees bending over planted feet (else towards the pelvis' front);
- feet: the world orientation given by the stepping code, or a pose relative to
  the shin (``foot_rel``), blended geodesically; where a planted flat foot would
  dorsiflex the ankle beyond 22 deg the heel rises about the toe joint instead;
- spine: the bend spread evenly over spine1..3; neck and head share the
  rotation to the wanted head orientation (a world-stable gaze, or relative to
  the chest), so the head stays steady while the torso moves;
- arms: swing / abduction / elbow flexion in the chest frame.

Everything is exact forward kinematics of the body's own skeleton, so bone
lengths never change. The final joints come from the foundation's jax FK.
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields

import numpy as np
from scipy.ndimage import gaussian_filter1d, maximum_filter1d

from jaxmotion.motion import kinematics as K

__all__ = ["Controls", "Motion", "make_motion", "solve_pose"]

FPS = 30
REACH = 0.995  # fraction of the straight leg a stance leg may use (knees never lock)
MAX_DORSI = np.radians(22.0)  # ankle dorsiflexion beyond which a planted heel lifts


@dataclass
class Motion:
    """One synthesized motion (numpy, world z-up, metres, 30 fps).

    Attributes:
      joints: ``[T,22,3]`` float32. transl: ``[T,3]``. global_orient: ``[T,3]`` and
      body_pose: ``[T,21,3]`` SMPL-X axis-angle. betas: ``[10]``.
      fps, action (walk/sit/stand_up/lie), target_id, anchor_frame.
      contacts: ``[T,2]`` bool, left/right toe joint planted (for foot-skate checks).
    """

    joints: np.ndarray
    transl: np.ndarray
    global_orient: np.ndarray
    body_pose: np.ndarray
    betas: np.ndarray
    fps: int
    action: str
    target_id: int
    anchor_frame: int
    contacts: np.ndarray = field(default_factory=lambda: np.zeros((0, 2), bool))

    @property
    def num_frames(self) -> int:
        return len(self.joints)


@dataclass
class Controls:
    """Per-frame animation channels (``T`` frames). Angles in radians, lengths in metres.

    hip ``[T,3]``: hip-centre position. yaw/pitch/roll/twist ``[T]``: pelvis.
    spine_flex/spine_bend/spine_twist ``[T]``: total over the three spine joints.
    gaze_yaw/gaze_pitch ``[T]``: world head orientation (pitch > 0 looks down);
    head_world ``[T]``: 1 = world gaze, 0 = head relative to the chest, flexed by head_flex.
    ankle ``[T,2,3]``: ankle targets (left, right). foot_rot ``[T,2,3,3]``: world foot
    rotations; foot_rel ``[T,2]`` blends to a shin-relative foot flexed by foot_flex
    (plantar flexion > 0). contact ``[T,2]``: toe joint planted.
    arm_swing/arm_abduct/elbow ``[T,2]``: arm forward swing, outward abduction, elbow flexion.
    clamp ``[T]``: lower the hips where a leg cannot reach (stance phases).
    """

    hip: np.ndarray
    yaw: np.ndarray
    pitch: np.ndarray
    roll: np.ndarray
    twist: np.ndarray
    spine_flex: np.ndarray
    spine_bend: np.ndarray
    spine_twist: np.ndarray
    gaze_yaw: np.ndarray
    gaze_pitch: np.ndarray
    head_world: np.ndarray
    head_flex: np.ndarray
    ankle: np.ndarray
    foot_rot: np.ndarray
    foot_rel: np.ndarray
    foot_flex: np.ndarray
    contact: np.ndarray
    arm_swing: np.ndarray
    arm_abduct: np.ndarray
    elbow: np.ndarray
    clamp: np.ndarray

    @property
    def n(self) -> int:
        return len(self.yaw)

    @staticmethod
    def cat(parts: list[Controls]) -> Controls:
        """Concatenate segments in time."""
        return Controls(
            **{
                f.name: np.concatenate([getattr(p, f.name) for p in parts])
                for f in fields(Controls)
            }
        )

    def last(self) -> Controls:
        """The final frame as a one-frame segment (the state the next segment starts from)."""
        return Controls(**{f.name: getattr(self, f.name)[-1:].copy() for f in fields(Controls)})

    def hold(self, n: int) -> Controls:
        """``n`` frames of this segment's final frame."""
        return Controls(
            **{f.name: np.repeat(getattr(self, f.name)[-1:], n, 0) for f in fields(Controls)}
        )


def _leg_rest(body: K.Body, i: int):
    r = body.rest
    hip, knee, ankle = r[K.HIP[i]], r[K.KNEE[i]], r[K.ANKLE[i]]
    d0 = K.normalize(ankle - hip)
    return (
        K.normalize(knee - hip),
        K.normalize(ankle - knee),
        K.normalize(np.cross(d0, [0.0, 0.0, 1.0])),
    )


def _arm_rest(body: K.Body, i: int):
    r = body.rest
    u1 = K.normalize(r[K.ELBOW[i]] - r[K.SHOULDER[i]])
    u2 = K.normalize(r[K.WRIST[i]] - r[K.ELBOW[i]])
    # SMPL-X's T-pose droops at the elbow (~20 deg); straighten the extended arm
    # to a natural carrying angle of 5 deg so hanging hands stay by the thighs.
    axis = np.cross(u2, u1)
    kink = np.arctan2(np.linalg.norm(axis), u1 @ u2)
    fix = K.rot_axis(K.normalize(axis), max(kink - np.radians(5.0), 0.0))
    return u1, K.normalize(np.cross(u1, [0.0, 0.0, 1.0])), fix


def _clamp_heights(hip_z, zmax, enabled):
    """Lower ``hip_z`` smoothly so that it never exceeds ``zmax`` where ``enabled``."""
    deficit = np.where(enabled, np.maximum(hip_z - zmax, 0.0), 0.0)
    if deficit.any():
        deficit = np.maximum(gaussian_filter1d(maximum_filter1d(deficit, 7), 1.5), deficit)
    z = hip_z - deficit
    return np.where(enabled, np.minimum(z, zmax), z)


def solve_pose(c: Controls, body: K.Body):
    """Controls -> (local rotations ``[T,22,3,3]``, transl ``[T,3]``, hip centre ``[T,3]``)."""
    n, r = c.n, body.rest
    g = np.zeros((n, 22, 3, 3))
    rp = K.upright(c.yaw) @ K.rx(c.pitch) @ K.rz(c.roll) @ K.ry(c.twist)
    g[:, 0] = rp
    hip_off = np.stack(
        [np.einsum("tij,j->ti", rp, r[K.HIP[i]] - body.hip_center) for i in (0, 1)], 1
    )
    # Reach clamp: the highest hip centre from which both ankles are reachable.
    hc = c.hip.copy()
    zmax = np.full(n, np.inf)
    for i in (0, 1):
        dxy = np.linalg.norm(c.ankle[:, i, :2] - (hc[:, :2] + hip_off[:, i, :2]), axis=1)
        lim = (REACH * body.leg[i]) ** 2 - dxy**2
        zi = c.ankle[:, i, 2] + np.sqrt(np.maximum(lim, 0.0)) - hip_off[:, i, 2]
        zmax = np.minimum(zmax, np.where(lim > 0, zi, -np.inf))
    hc[:, 2] = _clamp_heights(hc[:, 2], np.maximum(zmax, hc[:, 2] - 0.25), c.clamp)
    pelvis = hc + np.einsum("tij,j->ti", rp, r[0] - body.hip_center)
    transl = pelvis - r[0]
    # Spine: the bend spread evenly over three joints.
    spine_local = K.rx(c.spine_flex / 3) @ K.rz(c.spine_bend / 3) @ K.ry(c.spine_twist / 3)
    g[:, 3] = rp @ spine_local
    g[:, 6] = g[:, 3] @ spine_local
    g[:, 9] = g[:, 6] @ spine_local
    chest = g[:, 9]
    # Neck and head share the turn to the wanted head orientation.
    head_rel = chest @ K.rx(c.head_flex)
    head_w = K.upright(c.gaze_yaw) @ K.rx(c.gaze_pitch)
    head = K.slerp(head_rel, head_w, c.head_world)
    half = K.from_rotvec(0.5 * K.rotvec(np.swapaxes(chest, -1, -2) @ head))
    g[:, 12] = chest @ half
    g[:, 15] = head
    g[:, 13] = g[:, 14] = chest  # collars stay in their rest pose
    # Arms in the chest frame: aim the upper arm, then flex the elbow about its rest hinge.
    for i in (0, 1):
        side = 1.0 if i == 0 else -1.0
        rot = K.rx(-c.arm_swing[:, i]) @ K.rz(side * c.arm_abduct[:, i])
        d = np.einsum("tij,j->ti", rot, [0.0, -1.0, 0.0])
        fwd = np.einsum("tij,j->ti", rot, [0.0, 0.0, 1.0])
        m = K.normalize(np.cross(d, fwd))
        u1, m0, fix = _arm_rest(body, i)
        g[:, K.SHOULDER[i]] = chest @ K.frame(d, m) @ K.frame(u1, m0).T
        g[:, K.ELBOW[i]] = (
            g[:, K.SHOULDER[i]] @ K.rot_axis(K.normalize(m0 - (m0 @ u1) * u1), c.elbow[:, i]) @ fix
        )
        g[:, K.WRIST[i]] = g[:, K.ELBOW[i]]
    # Legs: two-bone IK to the ankle targets.
    # Knees bend over planted feet (the hip, not the ankle, takes the twist); with
    # the feet off the ground towards the pelvis' front and up (never along the leg).
    pelvis_fwd = np.einsum("tij,j->ti", rp, [0.0, 0.6, 1.0])
    for i in (0, 1):
        ankle, frot = c.ankle[:, i].copy(), c.foot_rot[:, i].copy()
        hip_pos = hc + hip_off[:, i]
        u1, u2, m0 = _leg_rest(body, i)
        for it in range(4):
            pole = pelvis_fwd + 1.5 * (1.0 - c.foot_rel[:, i, None]) * np.einsum(
                "tij,j->ti", frot, [0.0, 0.0, 1.0]
            )
            g1, g2, _, _ = K.two_bone(hip_pos, ankle, pole, body.thigh[i], body.shin[i], u1, u2, m0)
            if it == 3:
                break
            # A flat foot under a shin leaning far forward would over-flex the ankle:
            # roll the foot about its toe joint instead (the heel rises, the toe stays).
            f = np.einsum("tji,tj->ti", g2, np.einsum("tij,j->ti", frot, [0.0, 0.0, 1.0]))
            extra = np.where(
                c.foot_rel[:, i] < 0.5,
                np.maximum(np.arctan2(f[:, 1], f[:, 2]) - MAX_DORSI, 0.0),
                0.0,
            )
            if not extra.any():
                break
            toe = ankle + np.einsum("tij,j->ti", frot, body.toe_off[i])
            roll = K.rot_axis(
                np.einsum("tij,j->ti", frot, [1.0, 0.0, 0.0]), extra + 0.01 * (extra > 0)
            )
            ankle = toe + np.einsum("tij,tj->ti", roll, ankle - toe)
            frot = roll @ frot
        g[:, K.HIP[i]], g[:, K.KNEE[i]] = g1, g2
        rel = g2 @ K.rx(c.foot_flex[:, i])
        g[:, K.ANKLE[i]] = K.slerp(frot, rel, c.foot_rel[:, i])
        g[:, K.FOOT[i]] = g[:, K.ANKLE[i]]
    return K.local_from_global(g), transl, hc


def make_motion(c: Controls, body: K.Body, action: str, target_id, anchor_frame: int) -> Motion:
    """Solve the pose and export SMPL-X parameters and joints (via the jax FK)."""
    local, transl, _ = solve_pose(c, body)
    aa = K.rotvec(local)
    joints = K.jax_joints(aa[:, 0], aa[:, 1:], transl, body.betas)
    return Motion(
        joints=joints,
        transl=transl.astype(np.float32),
        global_orient=aa[:, 0].astype(np.float32),
        body_pose=aa[:, 1:].astype(np.float32),
        betas=body.betas.astype(np.float32),
        fps=FPS,
        action=action,
        target_id=target_id,
        anchor_frame=int(anchor_frame),
        contacts=c.contact.copy(),
    )
