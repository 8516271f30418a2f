"""What ``generate`` understood from the text, said plainly: the action, the target and how it
was chosen, and warnings where the text could not be followed as written.

:func:`explain` runs after grounding and returns an :class:`Understanding` (kept in the
result, :attr:`jaxmotion.result.Generation.understanding`, and printed in the command line's
JSON summary); it warns (:class:`UserWarning`, which the command line prints as
``warning: ...`` on stderr) when

- the action is not one of the four the models know (and says which they are),
- the named object's class is not in the room (and what was done instead),
- several objects fit the text (which one was chosen — the one a body reaches most freely,
  or the ADM's map's — and that ``--object ID`` or a relation — with an example that
  singles out another — chooses another),
- the object does not take the action ("lie on the chair"), or the text asks for more than
  one motion;

and with ``echo`` prints its notes to stderr.
"""

from __future__ import annotations

import sys
import warnings
from dataclasses import dataclass

from jaxmotion.grounding.objects import object_table
from jaxmotion.grounding.phrasing import canonical_category
from jaxmotion.grounding.region import sampled_action
from jaxmotion.grounding.target import Instruction, ground_candidates, read_instruction

__all__ = ["Understanding", "explain", "relation_hint"]

_ACTIONS = "walk to an object, sit on it, stand up from it or lie on it"
_DOING = {"walk": "walking to", "sit": "sitting on", "stand_up": "getting up from",
          "lie": "lying on"}


@dataclass(frozen=True)
class Understanding:
    """What was understood from a text (:func:`explain`).

    Attributes:
      action: ``walk`` / ``sit`` / ``stand_up`` / ``lie``, or None; action_from: what it was
        read from, in words ("the words 'take a seat'").
      target_id: the object the motion is for, or None; target: it as "chair 4"; how: how
        it was chosen (:attr:`jaxmotion.result.Generation.grounding`).
      notes: how the text was read and the target chosen, in sentences; warnings: what could
        not be done as written, and what was done instead.
      llm: with ``--grounding llm``, the language model's prompts and answers
        (:meth:`jaxmotion.grounding.llm.LLMGrounding.as_json`; saved as
        ``grounding_llm.json``), else None.
    """

    action: str | None = None
    action_from: str = ""
    target_id: int | None = None
    target: str | None = None
    how: str = ""
    notes: tuple[str, ...] = ()
    warnings: tuple[str, ...] = ()
    llm: dict | None = None

    def as_json(self) -> dict:
        """The fields as JSON-ready values (for the summary line)."""
        return {"action": self.action, "action_from": self.action_from,
                "target": self.target, "notes": list(self.notes),
                "warnings": list(self.warnings)}


def _name(o) -> str:
    return f"{o['category']} {o['id']}"


def explain(room, instruction, chosen, how: str, options=None, *, echo: bool = False,
            warn: bool = True) -> Understanding:
    """What was understood of ``instruction`` (an :class:`~jaxmotion.grounding.Instruction`
    or a text) in ``room``, once the target ``chosen`` (an id or None) was found ``how``.

    ``options``: anything with ``object_id`` and ``grounding`` (a
    :class:`~jaxmotion.options.GenerateOptions`); None: neither. ``warn``: issue each warning
    as a :class:`UserWarning`; ``echo``: print the notes to stderr. Never raises for a text.
    """
    ins = instruction if isinstance(instruction, Instruction) else read_instruction(instruction)
    object_id = getattr(options, "object_id", None)
    grounding = getattr(options, "grounding", "auto")
    objects = list(object_table(room))
    by_id = {int(o["id"]): o for o in objects}
    r = ins.reading
    notes: list[str] = []
    warns: list[str] = []
    action_from = ""
    if ins.action is None:
        walk_to = ("an object drawn with the seed" if how == "wander" else
                   "the object the ADM's map lights most")
        done = (f"with no object named either, it is done as a walk to {walk_to}"
                if sampled_action(None, how, chosen) == "walk" else
                "the text goes to them as written, so expect one of those")
        warns.append(f"could not tell which action {ins.text!r} asks for: jaxmotion's models "
                     f"{_ACTIONS}; {done} (say e.g. 'walk to the door' or 'sit on the chair')")
    else:
        action_from = {"words": f"the words '{r.action_words}'",
                       "object": f"'{r.action_words}' with a {r.target or 'seat'}",
                       "preposition": f"'{r.action_words} {r.preposition} the "
                                      f"{r.target_words}': the way it goes",
                       "destination": f"'{r.action_words} {r.preposition} the "
                                      f"{r.target_words}': going to a place",
                       "similarity": "the meaning of the words (sentence encoder)"}.get(
                           ins.action_how, "")
        notes.append(f"action: {ins.action}" + (f" (from {action_from})" if action_from else ""))
    notes.extend(ins.notes)
    if r.several and ins.action is not None:
        warns.append(f"the text asks for more than one motion; jaxmotion makes one: "
                     f"{_DOING[ins.action]} the {r.target_words or 'object'}")
    target = None
    if chosen is not None:
        target = _name(by_id[int(chosen)]) if int(chosen) in by_id else f"object {chosen}"
    if object_id is not None:
        notes.append(f"target: {target}, given by --object (object_id)")
        o = by_id.get(int(object_id))
        if o is not None and r.target and not r.seat_at and (
                canonical_category(o["category"]) != r.target):
            warns.append(f"the text names a {r.target_words} but object {object_id} is a "
                         f"{o['category']}; the motion is for {target}")
    elif how == "llm" and "llm" in ins.memo:
        notes.append(f"target: {target}, chosen by the language model (its prompts and answers "
                     "are saved as grounding_llm.json)")
        notes.extend(ins.memo["llm"].notes)
    else:
        found = ground_candidates(room, ins, grounding)
        notes.extend(found.notes)
        warns.extend(found.warnings)
        if chosen is None:
            notes.append("target: none; " + ("the text names no object of this room" if objects
                                             else "the scene has no object labels")
                         + ", so the region is where the ADM's map is strongest")
        elif how in ("adm", "reach") and len(found.objects) > 1:
            names = ", ".join(_name(o) for o in found.objects)
            by = ("the ADM's map" if how == "adm" else
                  "the most free floor to approach it on")
            notes.append(f"target: {target}, chosen by {by} among {names}")
            hint = relation_hint(objects, found.objects, int(chosen))
            chose = ("the ADM's map chose " + target if how == "adm" else
                     f"chose {target}, the one with the most free floor around it")
            warns.append(f"{len(found.objects)} objects fit the text ({names}); {chose}. "
                         "To choose another, pass --object ID (object_id=ID)"
                         + (f" or name a relation: {hint}" if hint else ""))
        else:
            notes.append(f"target: {target} ({_how(how, found, r)})")
            if ins.action is None and sampled_action(None, how, chosen) == "walk":
                notes.append(f"action: a walk to {target} (none understood, no object named)")
    if warn:
        for w in warns:
            warnings.warn(w, UserWarning, stacklevel=3)
    if echo:
        for n in notes:
            print(f"  {n}", file=sys.stderr, flush=True)
    return Understanding(action=ins.action, action_from=action_from,
                         target_id=None if chosen is None else int(chosen), target=target,
                         how=how, notes=tuple(notes), warnings=tuple(warns),
                         llm=ins.memo["llm"].as_json() if "llm" in ins.memo else None)


def _how(how: str, found, r) -> str:
    cls = found.objects[0]["category"] if found.objects else "object"
    return {
        "class": f"the only {cls} in the room",
        "scene graph": f"the {cls} {r.relation_words} the {' and the '.join(r.anchors)}",
        "seat at": f"the seat {r.preposition or 'at'} the {r.target_words}",
        "named id": "named by its id",
        "related": f"the room has no {r.target}; its only {cls}",
        "action": "the only object here the action takes",
        "similarity": "the class nearest the text's words by meaning",
        "object_id": "given by --object (object_id)",
        "adm peak": "the text names no object of this room: the object the ADM's map lights most "
                    "where it is strongest",
        "wander": "the text names no object of this room: drawn with the seed among the objects "
                  "with free floor around them",
    }.get(how, how)


def relation_hint(objects, candidates, chosen: int) -> str:
    """An example phrase that singles out a candidate other than ``chosen`` with the scene
    graph ("'the stool next to the cabinet' is stool 7"), or ``""`` when none does."""
    from jaxmotion.scene.instructions import referring_options

    forms = {"closest": "the {t} next to the {a}", "farthest": "the {t} farthest from the {a}",
             "between": "the {t} between the {a} and the {b}", "on": "the {t} on the {a}",
             "supporting": "the {t} with the {a} on it", "above": "the {t} above the {a}",
             "below": "the {t} below the {a}"}
    for o in candidates:
        if int(o["id"]) == int(chosen):
            continue
        try:
            options = referring_options(objects, int(o["id"]))
        except Exception:  # noqa: BLE001 - a hint is optional; an odd object table skips it
            options = {}
        for rel, form in forms.items():
            for ref in options.get(rel, ()):
                anchors = [*ref.anchors, "", ""]
                phrase = form.format(t=ref.target, a=anchors[0], b=anchors[1])
                return f"'{phrase}' is {_name(o)}"
    return ""
