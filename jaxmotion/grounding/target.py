"""From an instruction to the object it means: the instruction read once, then the target.

:func:`read_instruction` reads a text once into an :class:`Instruction` (the action, the
referring expression — target class, relation, anchor classes — whether the body meets the
object at the first frame, and object ids named as "chair 3" / "object 12"); it never raises.
Free phrasing is read with word lists (:mod:`jaxmotion.grounding.phrasing`), and where they
run out, with the sentence encoder's similarity when one is given
(:mod:`jaxmotion.grounding.similarity`).

:func:`ground_candidates` gives the room's objects the text may mean — the named class (or,
when the room has none, a related class or the objects the action can take), "the seat at
the desk", narrowed by the scene graph when the text's relation singles some out — with
notes and warnings that say how (:func:`candidate_objects`: just the objects and how).
:class:`Target` is the object the motion is for, once known. Region choice among several
candidates by the ADM's map is :mod:`jaxmotion.grounding.region`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from jaxmotion.grounding import lexicon as lx
from jaxmotion.grounding.objects import mentioned_objects, object_table
from jaxmotion.grounding.phrasing import (
    Reading,
    action_classes,
    canonical_category,
    preferred_seats,
    read_phrasing,
    takes,
    tokenize,
)

__all__ = ["Candidates", "Instruction", "Target", "candidate_objects", "ground_candidates",
           "read_instruction"]

_UNITS = ("m", "cm", "mm", "meter", "meters", "metre", "metres", "feet", "foot", "ft", "step",
          "steps", "second", "seconds", "s", "sec", "secs", "time", "times", "x", "minute",
          "minutes", "min", "mins")
_ID_WORDS = ("object", "id", "number", "instance", "item", "thing")
_VERB = {"walk": "walk to", "sit": "sit on", "stand_up": "stand up from", "lie": "lie on"}


@dataclass(frozen=True)
class Instruction:
    """One instruction, read once (:func:`read_instruction`).

    Attributes:
      text: the whitespace-normalised text.
      action: ``walk`` / ``sit`` / ``stand_up`` / ``lie``, or None when it cannot be told.
      reference: the referring expression (:class:`jaxmotion.scene.graph.Reference`: target
        class, relation, anchor classes), or None when the text names no known class; with
        ``reading.seat_at`` it names the object the seat is at ("the desk").
      anchor_first: whether the body meets the object at the first frame (getting up
        from it) rather than the last.
      named_ids: ``(word, id)`` pairs for objects named by id ("chair 3", "object 12").
      reading: what the word lists read (:class:`~jaxmotion.grounding.phrasing.Reading`).
      action_how: how the action was read: ``words``, ``object`` (a verb such as "rest"
        whose action depends on the object), ``destination`` (an unknown verb going "to" an
        object), ``preposition`` (off / out of a seat: getting up; onto it: sitting),
        ``similarity`` (the sentence encoder's nearest action prototype) or ``""``.
      notes: what was guessed or ignored while reading, for the user.
      similarity: the :class:`~jaxmotion.grounding.similarity.TextSimilarity` it was read
        with (also used to match unknown object words with the room's classes), or None.
      memo: results of grounding steps run on it that must run once (the language model's
        answer, :func:`jaxmotion.grounding.llm.llm_candidates`), by step name.
    """

    text: str
    action: str | None
    reference: object | None
    anchor_first: bool
    named_ids: tuple[tuple[str, int], ...] = ()
    reading: Reading = field(default_factory=Reading)
    action_how: str = ""
    notes: tuple[str, ...] = ()
    similarity: object = field(default=None, compare=False, repr=False)
    memo: dict = field(default_factory=dict, compare=False, repr=False)


def read_instruction(text, similarity=None) -> Instruction:
    """Read ``text`` once into an :class:`Instruction`; never raises (what it cannot read is
    None, and said in ``notes``).

    ``similarity``: a :class:`~jaxmotion.grounding.similarity.TextSimilarity`, or a folder
    for one's cache (the sentence encoder), used only where the word lists find no action
    (and later, by :func:`ground_candidates`, no class of the room); None: word lists only.
    """
    from jaxmotion.scene.graph import Reference
    from jaxmotion.scene.instructions import anchor_is_first

    try:
        text = " ".join(str(text).split())
    except Exception:  # noqa: BLE001 - a str subclass whose __str__ fails
        text = ""
    reading = read_phrasing(text)
    notes = list(reading.notes)
    action, how = reading.action, reading.action_how
    if similarity is not None and not isinstance(similarity, _similarity_type()):
        similarity = _similarity_type()(similarity)
    if action is None and similarity is not None and reading.query:
        from jaxmotion.grounding.similarity import guess_action

        try:
            guess, score = guess_action(similarity, reading.query)
        except Exception as e:  # noqa: BLE001 - the encoder missing or broken: say so
            notes.append(f"the sentence encoder could not be used to read the action ({e})")
        else:
            if guess is not None:
                action, how = guess, "similarity"
                notes.append(f"read '{reading.query}' as {action} by meaning (cosine "
                             f"{score:.2f} to the action's examples)")
    reference = None
    if reading.target is not None:
        try:
            reference = Reference(reading.target, reading.relation, reading.anchors)
        except ValueError:
            reference = Reference(reading.target)
    named = _named_ids(tokenize(text))
    return Instruction(text=text, action=action, reference=reference,
                       anchor_first=action == "stand_up" or bool(anchor_is_first(text)),
                       named_ids=named, reading=reading, action_how=how, notes=tuple(notes),
                       similarity=similarity)


def _named_ids(words) -> tuple[tuple[str, int], ...]:
    """``(word, id)`` for "chair 3", "object #12", "stool number 2" (not "2 meters")."""
    out = []
    for k, w in enumerate(words):
        if not w.isdigit() or k == 0 or len(w) > 9:
            continue
        if k + 1 < len(words) and words[k + 1] in _UNITS:
            continue
        j = k - 1
        if words[j] == "|" and j > 0 and words[j - 1] in ("no", "nr", "num"):  # "chair no. 5"
            j -= 1
        if words[j] in ("no", "number", "num", "nr", "id") and j > 0:
            j -= 1
        if words[j].isalpha():
            out.append((words[j], int(w)))
    return tuple(out)


def _similarity_type():
    from jaxmotion.grounding.similarity import TextSimilarity

    return TextSimilarity


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


@dataclass(frozen=True)
class Candidates:
    """The objects an instruction may mean in a room (:func:`ground_candidates`).

    Attributes:
      objects: object-table entries; how: ``llm`` (the language model's choice),
        ``named id`` ("chair 3"), ``scene graph`` (a
        relation narrowed them), ``class`` (the named class), ``seat at`` (the seats
        nearest the named object), ``related`` (a related class: the room has none of the
        named one), ``action`` (the objects the action can take), ``similarity`` (the class
        nearest the text's words by meaning) or ``""`` (none).
      notes: how they were found, in words; warnings: what the user should know (a class
        missing from the room, a relation that fits nothing, an object that does not take
        the action); error: why nothing can be done (the action needs an object the room
        does not have), or ``""``.
    """

    objects: list
    how: str
    notes: tuple[str, ...] = ()
    warnings: tuple[str, ...] = ()
    error: str = ""


def candidate_objects(room, text, grounding: str = "auto") -> tuple[list[dict], str]:
    """The objects the region may be centred on, and how they were found
    (:func:`ground_candidates`; ``grounding="auto"`` lets the text's relation narrow them by
    the scene graph, ``"adm"`` leaves the choice among the class to the ADM). ``text``: the
    instruction, or the :class:`Instruction` already read from it (not read again).
    ``([], "")`` when the text names no object of the room."""
    found = ground_candidates(room, text, grounding)
    return found.objects, found.how


def _name(o) -> str:
    return f"{o['category']} {o['id']}"


def _names(objs) -> str:
    return ", ".join(_name(o) for o in objs)


def _plural(action) -> str:
    classes = action_classes(action)
    return "beds or sofas" if action == "lie" else (
        "seats (" + ", ".join(classes) + ")" if classes else "objects")


def ground_candidates(room, text, grounding: str = "auto") -> Candidates:
    """The room's objects ``text`` (a string or an :class:`Instruction`) may mean, how they
    were found and what the user should know (:class:`Candidates`); never raises for a
    text. A scene without an object table (an unlabelled scan) has no candidates and no
    error: the place comes from the affordance model's map."""
    ins = text if isinstance(text, Instruction) else read_instruction(text)
    objects = list(object_table(room))
    if not objects:  # an unlabelled scan or mesh: nothing to ground in, the ADM's map chooses
        return Candidates([], "", (("the scene has no object labels: the affordance model's "
                                    "map over the room chooses where"),))
    r, action = ins.reading, ins.action
    notes: list[str] = []
    warns: list[str] = []
    by_class: dict[str, list[dict]] = {}
    for o in objects:
        by_class.setdefault(canonical_category(o["category"]), []).append(o)
    for word, oid in ins.named_ids:
        o = next((o for o in objects if int(o["id"]) == oid), None)
        if o is not None and (word in _ID_WORDS or canonical_category(word) == canonical_category(
                o["category"])):
            return Candidates([o], "named id", (f"{_name(o)} is named by its id",))
    target, how = r.target, "class"
    found: list[dict] = []
    if target is None and not r.generic:
        literal = mentioned_objects(room, ins.text)  # a class of the room outside the lexicon
        if literal:
            target = canonical_category(literal[0]["category"])
        elif r.object_phrase and ins.similarity is not None and by_class:
            target, how = _by_meaning(ins, r.object_phrase, by_class, notes)
    if target is not None:
        found = list(by_class.get(target, ()))
        if not found:
            found, how = _instead(target, action, r, by_class, warns, objects)
    if not found:  # "sit down", "take a seat", or nothing the room has of the named class
        classes = action_classes(action)
        if classes is None:
            return Candidates([], "", tuple(notes), tuple(warns))
        found = _takers(action, classes, by_class, objects)
        how = "action"
        if not found:
            return Candidates([], "", tuple(notes), tuple(warns), error=(
                f"this room has no {_plural(action)} to {_VERB[action]} (its objects: "
                f"{_classes(objects)}); name one of its objects, pass --object ID "
                "(object_id=), or ask to walk to one"))
        if target is None:
            notes.append(f"the text names no object: the room's {_plural(action)} are the "
                         f"candidates ({_names(found)})")
    if r.relation is not None and grounding == "auto":
        found, how = _narrow(found, how, r, by_class, objects, notes, warns)
    if r.seat_at and target is not None and how not in ("action",):
        found, how = _seat_at(found, how, action, r, by_class, objects, notes, warns, grounding)
    classes = action_classes(action)
    if classes is not None and found and not r.seat_at:
        odd = sorted({o["category"] for o in found if not takes(action, o)})
        if odd:
            warns.append(f"jaxmotion's models {_VERB[action]} {_plural(action)}; "
                         f"{' and '.join(odd)} is not one: the motion is for it as asked, "
                         "and may not look right")
    return Candidates(found, how, tuple(notes), tuple(warns))


def _classes(objects) -> str:
    return ", ".join(sorted({o["category"] for o in objects})) or "none"


def _by_meaning(ins, phrase, by_class, notes):
    from jaxmotion.grounding.similarity import guess_category

    try:
        guess, score = guess_category(ins.similarity, phrase, sorted(by_class))
    except Exception as e:  # noqa: BLE001 - the encoder missing or broken: say so
        notes.append(f"the sentence encoder could not be used to read '{phrase}' ({e})")
        return None, "class"
    if guess is None:
        notes.append(f"'{phrase}' is like none of this room's classes (best cosine "
                     f"{score:.2f})")
        return None, "class"
    notes.append(f"read '{phrase}' as {guess} by meaning (cosine {score:.2f})")
    return guess, "similarity"


def _takers(action, classes, by_class, objects) -> list[dict]:
    """The objects ``action`` (sit, stand up, lie) takes: those of its classes, else those
    whose surface affords it (``affords``: an unnamed seat or bed found by segmentation,
    :mod:`jaxmotion.scene.segment`)."""
    found = [o for c in classes for o in by_class.get(c, ())]
    return found or [o for o in objects if takes(action, o)]


def _instead(target, action, r, by_class, warns, objects):
    """Objects to use when the room has none of the named class: a related class, else
    (sitting, lying, getting up) the objects the action takes."""
    for c in lx.RELATED.get(target, ()):
        if by_class.get(c) and (action_classes(action) is None or r.seat_at
                                or c in action_classes(action)):
            warns.append(f"there is no {target} in this room; using the {c} instead "
                         f"({_names(by_class[c])})")
            return list(by_class[c]), "related"
    classes = action_classes(action)
    if classes is not None and not r.seat_at:
        found = _takers(action, classes, by_class, objects)
        if found:
            warns.append(f"there is no {target} in this room (its objects: "
                         f"{_classes(objects)}); {_VERB[action]} one of those it has instead: "
                         f"{_names(found)}")
            return found, "action"
    if classes is None:  # with an action that needs one, the caller says there is none
        warns.append(f"there is no {target} in this room (its objects: {_classes(objects)}); "
                     "the target is chosen as for a text that names no object")
    return [], ""


def _narrow(found, how, r, by_class, objects, notes, warns):
    """``found`` narrowed by the text's relation (the scene graph), with a side of the
    anchor for "in front of" / "behind"; unchanged (with a warning) when it fits none."""
    from jaxmotion.scene.graph import Reference, SceneGraph

    missing = [a for a in r.anchors if not by_class.get(a)]
    if missing:
        warns.append(f"there is no {' or '.join(missing)} in this room: "
                     f"'{r.relation_words}' was ignored")
        return found, how
    if len(found) < 2:
        return found, how
    graph = SceneGraph(objects)
    anchor_cats = [sorted({o["category"] for o in by_class[a]}) for a in r.anchors]
    picked: set[int] = set()
    for cat in sorted({o["category"] for o in found}):
        for anchors in _product(anchor_cats):
            picked |= set(graph.resolve(Reference(cat, r.relation, anchors)))
    if r.side is not None and r.relation == "closest":
        picked = _on_side(found, by_class[r.anchors[0]], r.side, graph) or picked
    narrowed = [o for o in found if o["id"] in picked]
    if not narrowed:
        warns.append(f"no {found[0]['category']} here is {r.relation_words} the "
                     f"{' and the '.join(r.anchors)}; all {len(found)} are candidates")
        return found, how
    if len(narrowed) < len(found):
        notes.append(f"'{r.relation_words} the {' and the '.join(r.anchors)}' narrowed "
                     f"{len(found)} objects to {_names(narrowed)}")
    return narrowed, "scene graph"


def _product(lists):
    out = [()]
    for options in lists:
        out = [(*p, o) for p in out for o in options]
    return out


def _on_side(found, anchors, side, graph) -> set[int]:
    """Ids of ``found`` nearest an anchor among those on its front (or back) side, for
    anchors that have a front; empty when none has one or none is there."""
    picked: set[int] = set()
    sign = 1.0 if side == "front" else -1.0
    for a in anchors:
        if "front" not in a:
            continue
        centre = 0.5 * (np.asarray(a["bbox_min"][:2]) + np.asarray(a["bbox_max"][:2]))
        front = np.asarray(a["front"][:2], float)
        there = [o for o in found if o["id"] != a["id"] and sign * float(np.dot(
            0.5 * (np.asarray(o["bbox_min"][:2]) + np.asarray(o["bbox_max"][:2])) - centre,
            front)) > 0]
        if there:
            d = [graph.distance(o["id"], a["id"]) for o in there]
            picked |= {o["id"] for o, v in zip(there, d) if v <= min(d) + graph.tie_tol}
    return picked


def _seat_at(anchors, how, action, r, by_class, objects, notes, warns, grounding):
    """"sit at the desk": the objects of the action's classes nearest each of ``anchors``
    (the named objects; a side of them for "across from" / "in front of")."""
    from jaxmotion.scene.graph import SceneGraph

    classes = action_classes(action) or ()
    ids = {o["id"] for o in anchors}
    seats = preferred_seats(action, [o for c in classes for o in by_class.get(c, ())
                                     if o["id"] not in ids])
    words = f"{r.preposition or 'at'} the {r.target_words}"
    if not seats:
        warns.append(f"'{words}' asks for one of the room's {_plural(action)} near it, and "
                     f"it has none: the motion is for {_names(anchors)} itself")
        return anchors, how
    if grounding != "auto":
        notes.append(f"'{words}': the ADM chooses among the room's {_plural(action)}")
        return seats, "action"
    graph = SceneGraph(objects)
    picked: set[int] = set()
    if r.side is not None:
        picked = _on_side(seats, anchors, r.side, graph)
    if not picked:
        for a in anchors:
            d = [graph.distance(s["id"], a["id"]) for s in seats]
            picked |= {s["id"] for s, v in zip(seats, d) if v <= min(d) + graph.tie_tol}
    chosen = [s for s in seats if s["id"] in picked]
    notes.append(f"'{words}': the {'seat' if action != 'lie' else 'bed or sofa'} nearest "
                 f"{_names(anchors)} ({_names(chosen)})")
    return chosen, "seat at"
