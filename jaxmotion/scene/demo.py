"""The built-in demo room: a synthetic dining room, and how ``generate`` reads a scene argument.

``demo_scene()`` is ``sample_room(DEMO_SEED)`` scanned with :data:`DEMO_POINTS` points (read from
the shipped ``assets/demo_room.npz``, identical, tested); :func:`load_scene_arg` turns
``"demo"``, a path or a :class:`~jaxmotion.scene.Scene` into a scene.
"""

from __future__ import annotations

import dataclasses
import functools
from pathlib import Path

import numpy as np

from jaxmotion.errors import GenerateError

__all__ = ["DEMO_POINTS", "DEMO_SEED", "build_demo_scene", "demo_scene", "load_scene_arg",
           "room_for"]

DEMO_SEED = 22  # a dining room (L-shaped, 4.3 x 6.0 m) with one table and one chair by it
DEMO_POINTS = 60_000
_ASSETS = Path(__file__).resolve().parent.parent / "assets"


def demo_scene(num_points: int = DEMO_POINTS):
    """The built-in demo room (a synthetic dining room, z-up, metres): ``sample_room(22)``
    scanned with ``num_points`` points; the default size is read from the shipped
    ``assets/demo_room.npz`` (identical, tested; it saves the second it takes to build)."""
    if num_points == DEMO_POINTS and (_ASSETS / "demo_room.npz").is_file():
        from jaxmotion.scene import load_scene

        return load_scene(_ASSETS / "demo_room.npz")
    return build_demo_scene(int(num_points))


@functools.lru_cache(maxsize=2)
def build_demo_scene(num_points: int = DEMO_POINTS):
    """Build the demo room from its seed (what ``assets/demo_room.npz`` holds)."""
    from jaxmotion.scene.rooms import room_to_scene, sample_room

    room = sample_room(DEMO_SEED)
    scene = room_to_scene(room, num_points, np.random.default_rng(DEMO_SEED))
    return dataclasses.replace(scene, name="demo")


def load_scene_arg(scene, num_points: int | None = None, *, up: str = "auto",
                   unit: str = "auto", segment: bool = True):
    """``"demo"`` (:func:`demo_scene`), a path (any file :func:`jaxmotion.scene.load_scene`
    reads) or a :class:`~jaxmotion.scene.Scene`, made ready by
    :func:`jaxmotion.scene.prepare.prepare_room` (levelled; objects found when it has no
    labels, unless ``segment`` is False). What was done is said as
    :class:`~jaxmotion.errors.SceneNote` warnings; :class:`GenerateError` when the file cannot
    be read."""
    import warnings

    from jaxmotion.errors import SceneNote
    from jaxmotion.scene import SceneError
    from jaxmotion.scene.prepare import prepare_room

    if isinstance(scene, str) and scene == "demo":
        return demo_scene()
    try:
        room = prepare_room(scene, num_points=num_points, up=up, unit=unit, segment=segment)
    except SceneError as e:
        raise GenerateError(str(e)) from e
    for note in room.notes:
        warnings.warn(SceneNote(note), stacklevel=2)
    return room.scene


def room_for(scene, opts):
    """:func:`load_scene_arg` with ``generate``'s options: their points, up axis and unit;
    objects found in a room without labels except for ``pipeline="affordance"``, whose
    model chooses the place in such a room on its own."""
    return load_scene_arg(scene, opts.num_points, up=opts.up, unit=opts.unit,
                          segment=opts.pipeline != "affordance")


# --------------------------------------------------------------------------- result
