"""Scenes as labelled point clouds (metres, z-up), their file I/O, and the synthetic world.

Host-side numpy only. :mod:`~jaxmotion.scene.io` loads and saves scenes;
:mod:`~jaxmotion.scene.rooms` and :mod:`~jaxmotion.scene.furniture` build synthetic
rooms; :mod:`~jaxmotion.scene.graph` holds Sr3D spatial relations and
:mod:`~jaxmotion.scene.instructions` writes referring instructions from them.
"""

from jaxmotion.scene.furniture import CATEGORY_IDS, LIE_CATEGORIES, NYU40_ID, SEAT_CATEGORIES
from jaxmotion.scene.graph import Reference, Relation, SceneGraph
from jaxmotion.scene.instructions import (
    ACTIONS,
    NoUniqueReference,
    parse_instruction,
    resolve,
    sample_instruction,
    sample_task,
    simple_text,
)
from jaxmotion.scene.io import (
    DEFAULT_MESH_POINTS,
    SUPPORTED_EXTENSIONS,
    Scene,
    SceneError,
    load_scene,
    load_scene_and_notes,
    save_scene,
    scene_to_trimesh_points,
)
from jaxmotion.scene.rooms import (
    ROOM_KINDS,
    Room,
    approach_points,
    free_space_grid,
    is_navigable,
    room_to_mesh,
    room_to_scene,
    sample_room,
)

__all__ = [name for name in dir() if not name.startswith("_")]
