"""Geometry core: rotations, the SMPL-X body skeleton, affordance fields, distances.

Pure jax.numpy, float32, jit- and vmap-friendly. Importing this package compiles
nothing; functions compile on first call.
"""

from jaxmotion.geometry.affordance import (
    AFFORDANCE_JOINTS,
    AFFORDANCE_SIGMA,
    affordance_distance,
    affordance_map,
    affordance_to_distance,
    distance_to_affordance,
)
from jaxmotion.geometry.distance import (
    box_signed_distance,
    carry_field,
    nearest_points,
    occupancy_from_sdf,
    points_in_boxes,
    signed_distance,
    voxel_grid_centers,
)
from jaxmotion.geometry.rotations import (
    axis_angle_to_matrix,
    axis_angle_to_quaternion,
    matrix_to_axis_angle,
    matrix_to_quaternion,
    matrix_to_rotation_6d,
    quaternion_multiply,
    quaternion_to_axis_angle,
    quaternion_to_matrix,
    rotate_about_z,
    rotation_6d_to_matrix,
    skew,
)
from jaxmotion.geometry.sensors import (
    SENSOR_CHANNELS,
    environment_sensor,
    sensor_grid,
    target_sensor,
    trajectory_sensor,
    voxel_sensor,
)
from jaxmotion.geometry.skeleton import (
    JOINT_NAMES,
    MIRROR_PERMUTATION,
    NUM_BETAS,
    NUM_JOINTS,
    PARENTS,
    SMPLX_JOINT_NAMES,
    SMPLX_PARENTS,
    Skeleton,
    bone_lengths,
    forward_kinematics,
    forward_kinematics_with_rotations,
    kinematic_chain,
    neutral_skeleton,
    rest_joints,
    rest_joints_host,
    smplx_joints,
    upright_orientation,
)

__all__ = [name for name in dir() if not name.startswith("_")]
