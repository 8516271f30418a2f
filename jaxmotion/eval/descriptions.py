"""A description set written apart from the instruction generator, and its evaluation.

``jaxmotion/eval/data/descriptions_unseen9001.jsonl`` holds instructions written by hand, in
the style of people saying what they want ("Plonk yourself on the stool next to the sofa",
"Go raid the fridge", "Sit at the desk, please"), for objects of the rooms of
``jaxmotion synth --seed 9001`` (``data/unseen9001``, rooms no training used). None uses a verb
phrase of the synthetic generator (:data:`jaxmotion.scene.instructions.VERBS`), so the set
measures how the instruction reader and the models do on phrasing they were not built from
(the affordance paper's Table 4 protocol: people's descriptions, unseen scenes).

One row per line::

    {"scene": "scene_00000", "target_id": 7, "action": "sit",
     "text": "Please park yourself on the chair near the door.", "category": "chair",
     "noun": "chair", "relation": "closest", "anchors": ["door"], "same_class": 2}

``category``: the target's class in the room's object table; ``noun``: the word of the text
naming it (with ``seat_at``: the object the seat is at, "sit at the desk"); ``relation`` /
``anchors``: the scene-graph relation the words mean, where they use one (an annotation for
reading the failures, checked against the room in the tests); ``same_class``: how many
objects of the target's class the room has.
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

__all__ = ["DESCRIPTIONS", "load_descriptions"]

#: the shipped description set (rooms of data/unseen9001)
DESCRIPTIONS = Path(__file__).with_name("data") / "descriptions_unseen9001.jsonl"
_KEYS = ("scene", "target_id", "action", "text")


def load_descriptions(path=None) -> tuple[list[dict], str]:
    """The rows of a description file (default: :data:`DESCRIPTIONS`) and the first 12 hex
    digits of its SHA-256 (the set's version in reports). Raises ValueError naming the line
    of a row without ``scene``, ``target_id``, ``action`` and ``text``."""
    path = Path(path) if path is not None else DESCRIPTIONS
    raw = path.read_bytes()
    rows = []
    for n, line in enumerate(raw.decode("utf-8").splitlines(), 1):
        if not line.strip():
            continue
        row = json.loads(line)
        missing = [k for k in _KEYS if k not in row]
        if missing:
            raise ValueError(f"{path}:{n}: missing {', '.join(missing)}")
        rows.append(row)
    return rows, hashlib.sha256(raw).hexdigest()[:12]
