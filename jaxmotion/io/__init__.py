"""Real motion data in: BVH, HumanML3D, AMASS and HUMANISE files as one :class:`Motion`.

``load_motion(path)`` detects the format from the file name (or takes ``format=``) and
returns the 22 SMPL-X body joints in jaxmotion's conventions (metres, z-up, order
:data:`jaxmotion.geometry.JOINT_NAMES`), the frame rate, the SMPL-X body parameters where
the source has them, and captions. Every reader is host-side NumPy; each module docstring
states its format's keys, frames, units and the conversions made. Bad input raises
:class:`MotionFormatError` (a ``ValueError``) naming the file and the fix.

Licensed datasets are read from the user's own copy and never shipped with jaxmotion.
"""

from jaxmotion.io.amass import load_amass
from jaxmotion.io.bvh import JOINT_MAPS, bvh_world_positions, load_bvh, resolve_joint_map
from jaxmotion.io.gltf import load_gltf
from jaxmotion.io.humanise import load_humanise
from jaxmotion.io.humanml3d import (
    HUMANML3D_FPS,
    caption_clips,
    load_humanml3d,
    load_split,
    read_captions,
)
from jaxmotion.io.load import READERS, detect_format, load_motion
from jaxmotion.io.motion import Y_UP_TO_Z_UP, Motion, MotionFormatError, smplx_joints_host

__all__ = [
    "HUMANML3D_FPS",
    "JOINT_MAPS",
    "READERS",
    "Y_UP_TO_Z_UP",
    "Motion",
    "MotionFormatError",
    "bvh_world_positions",
    "caption_clips",
    "detect_format",
    "load_amass",
    "load_bvh",
    "load_gltf",
    "load_humanise",
    "load_humanml3d",
    "load_motion",
    "load_split",
    "read_captions",
    "resolve_joint_map",
    "smplx_joints_host",
]
