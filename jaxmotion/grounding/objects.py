"""The room's objects: its object table, the objects a text names, and their class mates.

The table is the scene's own (``Scene.objects``: given by the file, or derived from per-point
``instance`` / ``semantic`` labels once, when the scene is built). Each object is a dict with
``id``, ``category``, ``bbox_min`` / ``bbox_max`` (xyz, metres) and, where it has one, ``front``.
"""

from __future__ import annotations

import re

from jaxmotion.errors import GenerateError

__all__ = ["find_object", "mentioned_objects", "object_table", "same_class_others"]


def find_object(room, object_id) -> dict:
    """The object ``object_id`` of the room's table; :class:`GenerateError` naming the valid
    ids when there is none."""
    objects = object_table(room)
    if not objects:
        raise GenerateError(f"object {object_id} given but the scene has no objects (no "
                            "per-point instance labels, as a ScanNet-style .ply or a jaxmotion "
                            ".npz has); leave out --object to find the target from the text")
    for o in objects:
        if o["id"] == int(object_id):
            return o
    valid = ", ".join(f"{o['id']} ({o['category']})" for o in objects)
    raise GenerateError(f"unknown object id {object_id}; this scene's objects: {valid}")


_ALIASES = {"refrigerator": "fridge", "television": "tv", "night stand": "nightstand",
            "couch": "sofa", "bookcase": "bookshelf", "settee": "sofa", "bathroom sink": "sink"}


def object_table(room) -> tuple[dict, ...]:
    """The room's object table: ``room.objects``, the one table of the scene (given by the
    file, or derived from its per-point labels when the scene was built:
    :func:`jaxmotion.scene.objects.table_from_labels`)."""
    return tuple(room.objects)


def mentioned_objects(room, text: str) -> list[dict]:
    """Objects of the first category the text names (whole words, plural ``s`` allowed,
    a few synonyms such as "couch" → sofa; the earliest mention wins, so in "the chair next
    to the table" it is the chair); ``[]`` when it names none."""
    low = " " + re.sub(r"[^a-z ]+", " ", text.lower()) + " "
    for alias, name in _ALIASES.items():
        low = re.sub(rf" {alias}(s)? ", f" {name}\\1 ", low)
    objects = object_table(room)
    best, where = None, len(low)
    for cat in sorted({o["category"] for o in objects}, key=len, reverse=True):
        name = cat.replace("_", " ").lower()
        m = re.search(rf" {re.escape(name)}(s|es)? ", low)
        if m and m.start() < where:
            best, where = name, m.start()
    if best is None:
        return []
    return [o for o in objects if o["category"].replace("_", " ").lower() == best]


def same_class_others(objects, object_id) -> list[int]:
    """Ids of the objects of ``object_id``'s category other than it: once the target is
    known, the points the ADM's map must leave out (``exclude`` of
    :meth:`jaxmotion.pipelines.AffordancePipeline.sample_affordance`); ``[]`` when
    ``object_id`` is None or not in ``objects``."""
    cat = next((o["category"] for o in objects if o["id"] == object_id), None)
    if object_id is None or cat is None:
        return []
    return [int(o["id"]) for o in objects if o["category"] == cat and o["id"] != object_id]
