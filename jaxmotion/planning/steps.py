"""A story told in words: "stand up from chair 3, walk to the table between the sofa and the
tv and sit on the chair next to it, then lie down on the bed" read into the steps of a plan
(:class:`~jaxmotion.planning.story.Step`), each an action on an object id of the room.

:func:`split_steps` cuts the text at each verb the phrasing reader reads as an action
(:func:`jaxmotion.grounding.phrasing.read_phrasing`); :func:`plan_from_text` grounds each
clause on its own with the single-instruction grounding (:func:`jaxmotion.grounding.
ground_candidates`: ids as ``jaxmotion scene info`` prints them, "chair 3", "object 12";
classes; scene-graph relations; "the seat at the desk"), and, across clauses:

- a clause naming no object, or only "it" / "there" / "here", means the previous step's
  object ("walk to the bed and lie down on it");
- a sit or lie on an object that does not take it means the nearest object that does ("walk
  to table 4 and sit": the seat nearest table 4), unless the clause names that object by its
  id ("sit on object 4", a lamp: refused);
- of several objects that fit a clause ("the chair next to it"), the one nearest the previous
  step's object is meant (the first step: the first that fits, said in the notes).

A text with one action is not a story: ``generate`` makes it one clip, as before.
"""

from __future__ import annotations

import functools

from jaxmotion.constants import STRUCTURE
from jaxmotion.errors import GenerateError

__all__ = ["is_story", "plan_from_text", "split_steps"]

#: Words that refer to the previous step's object.
_BACK = ("it", "there", "here", "that", "this", "them")
#: Words a clause may end with that belong to the next one.
_JOINERS = ("and", "then", "after", "that", "finally", "next", "afterwards", "later", "to")


def _destinations(words) -> list[list[str]]:
    """A walk's clause cut before each further destination: "walk to the table and then to
    the fridge" -> "walk to the table", "walk to the fridge" ("then to", "and to", "and then
    to" after a first "to"; "next to", "close to" are relations and do not cut)."""
    cuts = [i for i in range(2, len(words)) if words[i] == "to" and words[i - 1] in (
        "then", "and") and "to" in words[:i - 1]]
    if not cuts:
        return [words]
    out, start = [], 0
    for i in cuts:
        part = words[start:i]
        while len(part) > 1 and part[-1] in _JOINERS:
            part.pop()
        out.append(part)
        start = i
    return [out[0]] + [["walk", *p] for p in out[1:]] + [["walk", *words[start:]]]


def split_steps(text) -> list[tuple[str, str]]:
    """``(action, clause)`` per step of ``text``, in order (never raises; ``[]`` when no
    action is read). A walk to several places is one step per place."""
    from jaxmotion.grounding.phrasing import read_phrasing, tokenize

    r = read_phrasing(text)
    raw = tokenize(text)
    out = []
    for k, (action, start) in enumerate(r.steps):
        end = r.steps[k + 1][1] if k + 1 < len(r.steps) else len(raw)
        words = [w for w in raw[start:end] if w != "|"]
        while len(words) > 1 and words[-1] in _JOINERS:
            words.pop()
        parts = _destinations(words) if action == "walk" else [words]
        out.extend((action, " ".join(p)) for p in parts)
    return out


def is_story(text) -> bool:
    """Whether ``text`` asks for more than one motion (and so is told as a story): several
    actions on several objects, or a walk to several places."""
    from jaxmotion.grounding.phrasing import read_phrasing

    try:
        r = read_phrasing(text)  # split_steps makes one step of each of r.steps
        if bool(r.several) and len(r.steps) > 1:
            return True
        return sum(a == "walk" for a, _ in split_steps(text)) > sum(
            a == "walk" for a, _ in r.steps)
    except Exception:  # noqa: BLE001 - never stop a generate over this question
        return False


def plan_from_text(scene, text, similarity=None):
    """The plan a story text asks for in ``scene``: ``(steps, notes, warnings)``, ``steps`` a
    list of ``{"action", "object"}`` (for :func:`~jaxmotion.planning.story.read_plan`),
    ``notes`` what was chosen and why, in words, ``warnings`` the choices the text left open
    (worth saying to the user). :class:`GenerateError` naming the step that cannot be
    grounded and the fix.

    "Nearest" is the scene graph's box-to-box distance (:meth:`~jaxmotion.scene.graph.
    SceneGraph.distance`), as "the seat at the desk" in the single-instruction grounding."""
    from jaxmotion.grounding import ground_candidates, object_table, read_instruction
    from jaxmotion.grounding.phrasing import (
        action_classes,
        preferred_seats,
        tokenize,
    )
    from jaxmotion.grounding.phrasing import takes as action_takes
    from jaxmotion.scene.graph import SceneGraph

    objects = list(object_table(scene))
    graph = SceneGraph(objects)

    def nearest(objs, to):
        return min(objs, key=lambda o: graph.distance(o["id"], to["id"]))

    steps, notes, warns, prev = [], [], [], None
    clauses = split_steps(text)
    if not clauses:
        raise GenerateError(f"no action read in {text!r}: say what to do, e.g. 'stand up from "
                            "chair 3, walk to table 4 and sit'")
    for i, (action, clause) in enumerate(clauses, 1):
        ins = read_instruction(clause, similarity)
        words = set(tokenize(clause))
        classes = action_classes(action)
        takes = functools.partial(action_takes, action)
        found = None
        if ins.reading.target is None and not ins.named_ids and prev is not None and (
                words & set(_BACK) or not ins.reading.generic):
            obj = prev
            why = f"the previous step's {prev['category']} {prev['id']}"
        else:
            found = ground_candidates(scene, ins)
            if found.error:
                raise GenerateError(f"step {i} ('{clause}'): {found.error}")
            if not found.objects:
                have = ", ".join(sorted({o["category"] for o in objects})) or "none"
                r = ins.reading
                why = (f"this room has no {r.target_words or r.target} (its objects: {have})"
                       if r.target else f"it names no object of this room (its objects: {have})")
                example = next((f"'{o['category']} {o['id']}'" for o in objects
                                if o["category"] not in STRUCTURE), "'chair 3'")
                raise GenerateError(
                    f"step {i} ('{clause}'): {why}; name one of its objects by its id as "
                    f"`jaxmotion scene info` lists them ({example}), or give a plan file")
            fits = [o for o in found.objects if takes(o)] or found.objects
            obj = fits[0] if prev is None or len(fits) == 1 else nearest(fits, prev)
            why = {"named id": "named by its id"}.get(found.how, f"found by {found.how}")
            if len(fits) > 1 and prev is not None:
                why += f"; of {len(fits)} that fit, the one nearest the previous step's object"
            elif len(fits) > 1:
                why += f"; of {len(fits)} that fit, the first (name one by id to choose)"
                warns.append(f"step {i} ('{clause}'): {len(fits)} objects fit; "
                             f"{obj['category']} {obj['id']} was taken (name one by id to choose)")
        if not takes(obj) and found is not None and found.how == "named id":
            raise GenerateError(f"step {i} ('{clause}'): cannot {action.replace('_', ' ')} on "
                                f"{obj['category']} {obj['id']}; name an object that takes it "
                                f"({', '.join(classes)})")
        if not takes(obj):
            seats = preferred_seats(action, objects)
            if not seats:
                raise GenerateError(f"step {i} ('{clause}'): this room has nothing to {action} "
                                    f"on (its objects: {sorted({o['category'] for o in objects})})")
            near = nearest(seats, obj)
            why = f"the {near['category']} nearest the {obj['category']} {obj['id']}"
            obj = near
        steps.append({"action": action, "object": int(obj["id"])})
        notes.append(f"step {i}: {action.replace('_', ' ')} — {obj['category']} {obj['id']} "
                     f"({why})")
        prev = obj
    return steps, notes, warns
