"""The 22-joint SMPL-X body skeleton and its forward kinematics.

Rest joints are SMPL-X's own: the neutral rest skeleton and its linear response
to the first ten shape coefficients (betas) come from the SMPL-X calibration
shipped in the ``mannequin-x`` package (Apache-2.0), so no SMPL-X model file is
needed. A user's SMPL-X model can supply its own :class:`Skeleton` later.

Frames
------
The rest skeleton lives in SMPL-X's canonical frame: **y up, the body faces
+z, its left is +x**. The world of jaxmotion is z-up; as in AMASS, the global
orientation carries the body from one to the other. ``Rx(+90°)`` stands the body
up facing −y; :func:`upright_orientation` gives the global orientation for any
heading.

Forward kinematics follows SMPL-X exactly (so that exported parameters
reproduce our joints in any SMPL-X implementation): the global orientation
rotates the body about the rest **pelvis**, and the translation is added after,
so ``joints[0] = rest[0] + transl`` (the "pelvis offset" of HUMANISE).
"""

from __future__ import annotations

import functools
from importlib import resources
from typing import NamedTuple

import jax.numpy as jnp
import numpy as np

from jaxmotion._npio import load_npz
from jaxmotion.constants import NUM_JOINTS
from jaxmotion.geometry.rotations import axis_angle_to_matrix, rotate_about_z

__all__ = [
    "JOINT_NAMES",
    "MIRROR_PERMUTATION",
    "NUM_BETAS",
    "NUM_JOINTS",
    "PARENTS",
    "SMPLX_JOINT_NAMES",
    "SMPLX_PARENTS",
    "Skeleton",
    "bone_lengths",
    "forward_kinematics",
    "forward_kinematics_with_rotations",
    "kinematic_chain",
    "neutral_skeleton",
    "rest_joints",
    "rest_joints_host",
    "smplx_joints",
    "upright_orientation",
]

JOINT_NAMES: tuple[str, ...] = (
    "pelvis", "l_hip", "r_hip", "spine1", "l_knee", "r_knee", "spine2", "l_ankle",
    "r_ankle", "spine3", "l_foot", "r_foot", "neck", "l_collar", "r_collar", "head",
    "l_shoulder", "r_shoulder", "l_elbow", "r_elbow", "l_wrist", "r_wrist",
)  # fmt: skip
PARENTS: tuple[int, ...] = (
    -1, 0, 0, 0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 9, 9, 12, 13, 14, 16, 17, 18, 19,
)  # fmt: skip
NUM_BETAS = 10

# The full SMPL-X skeleton (55 joints) with the names of the SMPL-X model files and of the
# SMPL-X Blender add-on's armature: the 22 body joints (JOINT_NAMES spelled out), jaw, eyes,
# then per hand index, middle, pinky, ring, thumb (1 = base, 3 = tip), left hand first.
_FINGERS = tuple(f"{f}{k}" for f in ("index", "middle", "pinky", "ring", "thumb") for k in (1, 2, 3))
SMPLX_JOINT_NAMES: tuple[str, ...] = (
    tuple(n.replace("l_", "left_", 1) if n.startswith("l_") else
          n.replace("r_", "right_", 1) if n.startswith("r_") else n for n in JOINT_NAMES)
    + ("jaw", "left_eye_smplhf", "right_eye_smplhf")
    + tuple(f"left_{f}" for f in _FINGERS) + tuple(f"right_{f}" for f in _FINGERS)
)
SMPLX_PARENTS: tuple[int, ...] = (
    PARENTS + (15, 15, 15)
    + tuple(20 if k % 3 == 0 else 25 + k - 1 for k in range(15))
    + tuple(21 if k % 3 == 0 else 40 + k - 1 for k in range(15))
)

# Index of each joint's left/right counterpart (itself on the midline), used to
# mirror motions (x -> -x in the body frame, left and right swapped).
MIRROR_PERMUTATION: tuple[int, ...] = tuple(
    JOINT_NAMES.index(
        n.replace("l_", "#").replace("r_", "l_").replace("#", "r_") if n[:2] in ("l_", "r_") else n
    )
    for n in JOINT_NAMES
)

# The mannequin-x joint order (its first 22 joints) must be SMPL-X's body order.
_MANNEQUIN_NAMES = (
    "Pelvis", "L_Hip", "R_Hip", "Torso", "L_Knee", "R_Knee", "Spine", "L_Ankle", "R_Ankle",
    "Chest", "L_Toe", "R_Toe", "Neck", "L_Thorax", "R_Thorax", "Head", "L_Shoulder",
    "R_Shoulder", "L_Elbow", "R_Elbow", "L_Wrist", "R_Wrist",
)  # fmt: skip


class Skeleton(NamedTuple):
    """Rest skeleton with a linear shape space.

    Attributes:
      rest: ``[22, 3]`` rest joint positions for betas = 0, metres, SMPL-X frame.
      shape_dirs: ``[22, 3, B]`` change of each rest joint per unit of each beta.
    """

    rest: np.ndarray
    shape_dirs: np.ndarray


@functools.lru_cache(maxsize=1)
def neutral_skeleton() -> Skeleton:
    """The neutral SMPL-X body skeleton from mannequin-x's SMPL-X calibration.

    Read once from the package's assets (host numpy, float32).
    """
    try:
        pkg = resources.files("mannequin")
    except ModuleNotFoundError as err:  # pragma: no cover - dependency missing
        raise ImportError(
            "jaxmotion needs the 'mannequin-x' package for the SMPL-X rest skeleton: "
            "pip install 'mannequin-x>=0.3,<0.4'"
        ) from err
    with (pkg / "assets" / "smplx_calibration.npz").open("rb") as f, load_npz(f) as data:
        rest = np.asarray(data["joint_rest"][:NUM_JOINTS], np.float32)
        dirs = np.asarray(data["joint_dirs"][:NUM_JOINTS, :, :NUM_BETAS], np.float32)
    with (pkg / "assets" / "wooden.npz").open("rb") as f, load_npz(f) as data:
        names = tuple(str(n) for n in data["joint_names"][:NUM_JOINTS])
        parents = tuple(int(p) for p in data["parents"][:NUM_JOINTS])
    if names != _MANNEQUIN_NAMES or parents != PARENTS:
        raise RuntimeError(
            "The installed mannequin-x assets do not use the SMPL-X body joint order this "
            f"version of jaxmotion expects (got {names}); install 'mannequin-x>=0.3,<0.4'."
        )
    return Skeleton(rest=rest, shape_dirs=dirs)


def rest_joints(betas: jnp.ndarray | None = None, skeleton: Skeleton | None = None) -> jnp.ndarray:
    """Shape-dependent rest joints: ``rest + shape_dirs @ betas``.

    Args:
      betas: ``[..., B]`` shape coefficients (B <= the skeleton's), or None for the
        neutral body.
      skeleton: defaults to :func:`neutral_skeleton`.
    Returns:
      ``[..., 22, 3]`` rest joints in the SMPL-X frame (y up), metres.
    """
    sk = neutral_skeleton() if skeleton is None else skeleton
    rest = jnp.asarray(sk.rest)
    if betas is None:
        return rest
    betas = jnp.asarray(betas, rest.dtype)
    nb = betas.shape[-1]
    if nb > sk.shape_dirs.shape[-1]:
        raise ValueError(
            f"betas has {nb} coefficients but the skeleton has {sk.shape_dirs.shape[-1]} "
            "shape directions; pass at most that many."
        )
    return rest + jnp.einsum("jcb,...b->...jc", jnp.asarray(sk.shape_dirs[..., :nb]), betas)


def rest_joints_host(betas=None, skeleton: Skeleton | None = None) -> np.ndarray:
    """:func:`rest_joints` of one shape in NumPy (float64), for exporters: ``[22, 3]``, no XLA
    program dispatched (each eager JAX operation is a compilation in a fresh process)."""
    sk = neutral_skeleton() if skeleton is None else skeleton
    rest = np.asarray(sk.rest, np.float64)
    if betas is None:
        return rest
    betas = np.asarray(betas, np.float64).reshape(-1)
    if len(betas) > sk.shape_dirs.shape[-1]:
        raise ValueError(
            f"betas has {len(betas)} coefficients but the skeleton has "
            f"{sk.shape_dirs.shape[-1]} shape directions; pass at most that many."
        )
    return rest + np.asarray(sk.shape_dirs, np.float64)[..., : len(betas)] @ betas


def kinematic_chain(joints) -> tuple[int, ...]:
    """``joints`` and every joint they hang from, in skeleton order (a parent before its
    children, the pelvis first): what :func:`forward_kinematics_with_rotations` needs to place
    ``joints`` alone (the feet: pelvis, hips, knees, ankles, feet)."""
    needed = {0}
    for j in joints:
        j = int(j)
        if not 0 <= j < NUM_JOINTS:
            raise ValueError(f"joint index {j} is not one of the {NUM_JOINTS} joints")
        while j not in needed:
            needed.add(j)
            j = PARENTS[j]
    return tuple(sorted(needed))


def forward_kinematics_with_rotations(
    local_rot: jnp.ndarray, transl: jnp.ndarray, rest: jnp.ndarray | None = None,
    chain=None,
) -> tuple[jnp.ndarray, jnp.ndarray]:
    """Forward kinematics returning joints and global rotations.

    Args:
      local_rot: ``[..., 22, 3, 3]`` rotation of each joint relative to its parent
        (joint 0: the global orientation); with ``chain``, ``[..., len(chain), 3, 3]``, the
        rotations of those joints in that order.
      transl: ``[..., 3]`` root translation (SMPL-X ``transl``), metres.
      rest: ``[..., 22, 3]`` rest joints (default: neutral), broadcast with the batch.
      chain: None (every joint), or a :func:`kinematic_chain`: only those joints are placed
        (the same numbers as for the whole body, for a fraction of the work: the feet's
        chain is 9 of the 22 joints).
    Returns:
      joints ``[..., 22, 3]`` and global rotations ``[..., 22, 3, 3]`` (with ``chain``:
      ``[..., len(chain), ...]``, in its order).
    """
    chain = tuple(range(NUM_JOINTS)) if chain is None else tuple(int(j) for j in chain)
    if chain != kinematic_chain(chain):
        raise ValueError(f"chain {chain} is not a kinematic chain (the pelvis first, each "
                         "joint after its parent): build it with kinematic_chain(joints)")
    if local_rot.shape[-3:] != (len(chain), 3, 3):
        raise ValueError(f"local_rot must be [..., {len(chain)}, 3, 3] for {len(chain)} "
                         f"joints, got {local_rot.shape}")
    rest = rest_joints() if rest is None else jnp.asarray(rest)
    slot = {j: i for i, j in enumerate(chain)}
    rots = [local_rot[..., 0, :, :]]
    pos = [rest[..., 0, :] + transl]
    # Unrolled over the (static) tree: small matmuls fuse well under jit.
    for i, j in enumerate(chain[1:], start=1):
        p = slot[PARENTS[j]]
        offset = rest[..., j, :] - rest[..., PARENTS[j], :]
        pos.append(pos[p] + jnp.einsum("...ij,...j->...i", rots[p], offset))
        rots.append(rots[p] @ local_rot[..., i, :, :])
    return jnp.stack(pos, axis=-2), jnp.stack(rots, axis=-3)


def forward_kinematics(
    local_rot: jnp.ndarray, transl: jnp.ndarray, rest: jnp.ndarray | None = None
) -> jnp.ndarray:
    """Joint positions ``[..., 22, 3]`` from local rotations ``[..., 22, 3, 3]`` and ``transl``.

    See :func:`forward_kinematics_with_rotations`.
    """
    return forward_kinematics_with_rotations(local_rot, transl, rest)[0]


def smplx_joints(
    global_orient: jnp.ndarray,
    body_pose: jnp.ndarray,
    transl: jnp.ndarray,
    betas: jnp.ndarray | None = None,
) -> jnp.ndarray:
    """Joints from SMPL-X axis-angle parameters.

    Args:
      global_orient: ``[..., 3]``; body_pose: ``[..., 21, 3]``; transl: ``[..., 3]``;
      betas: ``[..., B]`` or None.
    Returns:
      ``[..., 22, 3]`` joints in the world frame, metres.
    """
    aa = jnp.concatenate([global_orient[..., None, :], body_pose], axis=-2)
    return forward_kinematics(axis_angle_to_matrix(aa), transl, rest_joints(betas))


def upright_orientation(heading: jnp.ndarray) -> jnp.ndarray:
    """Global orientation ``[..., 3, 3]`` standing the body up (z-up) facing ``heading``.

    ``heading`` is the facing angle in the xy plane, radians counter-clockwise
    from +x. The body's forward (+z in SMPL-X) maps to ``(cos h, sin h, 0)``.
    """
    heading = jnp.asarray(heading, jnp.float32)
    stand = jnp.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]], jnp.float32)  # Rx(90°)
    return rotate_about_z(heading + jnp.pi / 2) @ stand


def bone_lengths(joints: jnp.ndarray) -> jnp.ndarray:
    """Length of the bone from each joint's parent to the joint: ``[..., 22, 3] -> [..., 21]``."""
    parents = jnp.asarray(PARENTS[1:])
    return jnp.linalg.norm(joints[..., 1:, :] - joints[..., parents, :], axis=-1)
