"""Scenes as labelled point clouds (metres, z-up) and their file I/O.

Host-side numpy only; see :mod:`jaxmotion.scene.io`.
"""

from jaxmotion.scene.io import (
    DEFAULT_MESH_POINTS,
    SUPPORTED_EXTENSIONS,
    Scene,
    SceneError,
    load_scene,
    save_scene,
    scene_to_trimesh_points,
)

__all__ = [
    "DEFAULT_MESH_POINTS",
    "SUPPORTED_EXTENSIONS",
    "Scene",
    "SceneError",
    "load_scene",
    "save_scene",
    "scene_to_trimesh_points",
]
