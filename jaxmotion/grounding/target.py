"""From an instruction to the object it means: the instruction read once, then the target.

:func:`read_instruction` reads a text once into an :class:`Instruction` (the action, the
referring expression — target class, relation, anchor classes — whether the body meets the
object at the first frame, and object ids named as "chair 3" / "object 12"); it never raises.
:func:`candidate_objects` gives the room's objects the text may mean, narrowed by the scene
graph when the text's relation singles them out; :class:`Target` is the object the motion is
for, once known, with its points in the scene. Region choice among several candidates by the
ADM's map is :mod:`jaxmotion.grounding.region`.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np

from jaxmotion.grounding.objects import mentioned_objects, object_table

__all__ = ["Instruction", "Target", "candidate_objects", "read_instruction"]

_NAMED_ID = re.compile(r"\b([a-z][a-z_ ]*?)\s+(?:#|no\.?\s*|number\s+)?(\d+)\b")


@dataclass(frozen=True)
class Instruction:
    """One instruction, read once (:func:`read_instruction`).

    Attributes:
      text: the whitespace-normalised text.
      action: ``walk`` / ``sit`` / ``stand_up`` / ``lie``, or None when no verb of the
        grammar is found.
      reference: the referring expression (:class:`jaxmotion.scene.graph.Reference`: target
        class, relation, anchor classes), or None when the text is outside the grammar.
      anchor_first: whether the body meets the object at the first frame (getting up from
        it) rather than the last (:func:`jaxmotion.scene.instructions.anchor_is_first`).
      named_ids: ``(word, id)`` pairs for objects named by id ("chair 3", "object 12").
    """

    text: str
    action: str | None
    reference: object | None
    anchor_first: bool
    named_ids: tuple[tuple[str, int], ...] = ()


def read_instruction(text: str) -> Instruction:
    """Read ``text`` once into an :class:`Instruction`; never raises on a string (what it
    cannot read is None)."""
    from jaxmotion.scene.instructions import anchor_is_first, parse_instruction

    text = " ".join(str(text).split())
    try:
        action, reference = parse_instruction(text)
    except ValueError:  # not in the grammar the parser knows
        action, reference = None, None
    low = text.lower()
    named = tuple((m.group(1).strip().split()[-1], int(m.group(2)))
                  for m in _NAMED_ID.finditer(low))
    return Instruction(text=text, action=action, reference=reference,
                       anchor_first=bool(anchor_is_first(text)), named_ids=named)


@dataclass(frozen=True)
class Target:
    """The object a motion is for, once known.

    Attributes:
      object_id: its instance id; category: its class; bbox_min, bbox_max: its axis-aligned
        box ``[3]`` (metres, scene frame); indices: ``[M]`` indices of its points in the
        scene; how: how it was found (``object_id``, ``scene graph``, ``class``, ``adm``).
    """

    object_id: int
    category: str
    bbox_min: np.ndarray
    bbox_max: np.ndarray
    indices: np.ndarray
    how: str

    @classmethod
    def of(cls, room, obj: dict, how: str) -> Target:
        """The :class:`Target` of object table entry ``obj`` in ``room``."""
        return cls(object_id=int(obj["id"]), category=str(obj["category"]),
                   bbox_min=np.asarray(obj["bbox_min"], np.float64),
                   bbox_max=np.asarray(obj["bbox_max"], np.float64),
                   indices=np.flatnonzero(room.instance == int(obj["id"])), how=how)


def candidate_objects(room, text: str | Instruction,
                      grounding: str = "auto") -> tuple[list[dict], str]:
    """The objects the region may be centred on, and how they were found: the objects of the
    category the text names (:func:`mentioned_objects`; ``"class"``), narrowed with
    ``grounding="auto"`` by the relation of the text's referring expression when it parses
    and picks some of them (:func:`jaxmotion.scene.instructions.resolve`; ``"scene graph"``).
    ``text``: the instruction, or the :class:`Instruction` already read from it (not read
    again). ``([], "")`` when the text names no object of the room."""
    instruction = text if isinstance(text, Instruction) else None
    candidates = mentioned_objects(room, text if instruction is None else instruction.text)
    if grounding != "auto" or len(candidates) < 2:
        return candidates, "class" if candidates else ""
    from jaxmotion.scene.instructions import resolve

    ref = (instruction or read_instruction(text)).reference
    if ref is None or ref.relation is None:  # not in the parser's grammar, or no relation
        return candidates, "class"
    picked = resolve(object_table(room), ref)
    narrowed = [o for o in candidates if o["id"] in picked]
    if not narrowed:  # the parser read another target class than mentioned_objects did
        return candidates, "class"
    return narrowed, "scene graph"
