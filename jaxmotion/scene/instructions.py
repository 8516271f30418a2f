"""Sr3D-style referring instructions for the four HUMANISE actions (host-side, numpy rng).

An instruction is "<verb phrase> <referring expression>", e.g. "sit on the chair that is
closest to the desk", "walk to the table between the sofa and the bed", "lie down on the
bed", "get up from the armchair next to the bookshelf". As in Sr3D, the referring
expression names the target's class plus at most one relation to anchors whose class
occurs once in the room, and it must single out exactly one object: every generated
instruction is checked with :meth:`SceneGraph.resolve`. :func:`parse_instruction` reads
a generated text back into (action, :class:`Reference`).

Targets: ``sit`` / ``stand_up`` take seats (chair, armchair, sofa, stool, toilet, bed edge),
``lie`` a bed or sofa, ``walk`` any object.
"""

from __future__ import annotations

import itertools
import re

import numpy as np

from jaxmotion.scene.furniture import BUILDERS, LIE_CATEGORIES, SEAT_CATEGORIES
from jaxmotion.scene.graph import Reference, SceneGraph, as_scene_graph

ACTIONS = ("walk", "sit", "stand_up", "lie")
ACTION_TARGETS = {"walk": None, "sit": SEAT_CATEGORIES, "stand_up": SEAT_CATEGORIES,
                  "lie": LIE_CATEGORIES}
NEAR = 1.0  # "next to" / "right by" only within this xy box distance (m)
VERBS = {
    "walk": ("walk to", "go to", "go over to", "walk over to", "head to", "head over to",
             "move to", "approach", "walk up to", "make your way to", "step over to",
             "walk towards"),
    "sit": ("sit on", "sit down on", "have a seat on", "take a seat on", "go sit on",
            "sit yourself down on", "sit down in", "sit in"),
    "stand_up": ("stand up from", "get up from", "rise from", "stand up off", "get up off",
                 "get off"),
    "lie": ("lie down on", "lie on", "lay down on", "stretch out on", "take a nap on",
            "go lie down on", "lie flat on"),
}
_SIT_IN = ("sit down in", "sit in")  # only for armchairs
WORDS = {"sofa": ("sofa", "couch"), "fridge": ("fridge", "refrigerator"),
         "bookshelf": ("bookshelf", "bookcase"), "nightstand": ("nightstand", "bedside table"),
         "tv": ("tv", "television"), "picture": ("picture", "painting"),
         "cabinet": ("cabinet", "cupboard"), "sink": ("sink", "washbasin")}
TEMPLATES = {
    None: ("the {t}",),
    "closest": ("the {t} closest to the {a}", "the {t} that is closest to the {a}",
                "the {t} nearest to the {a}", "the {t} nearest the {a}",
                "the {t} which is closest to the {a}"),
    "near": ("the {t} next to the {a}", "the {t} right by the {a}", "the {t} close to the {a}"),
    "farthest": ("the {t} farthest from the {a}", "the {t} that is farthest from the {a}",
                 "the {t} furthest from the {a}", "the {t} furthest away from the {a}"),
    "between": ("the {t} between the {a} and the {b}",
                "the {t} that is between the {a} and the {b}",
                "the {t} in between the {a} and the {b}",
                "the {t} located between the {a} and the {b}"),
    "on": ("the {t} on the {a}", "the {t} on top of the {a}", "the {t} that is on the {a}",
           "the {t} standing on the {a}", "the {t} sitting on the {a}"),
    "supporting": ("the {t} with the {a} on it", "the {t} that the {a} is on",
                   "the {t} supporting the {a}", "the {t} holding the {a}"),
    "above": ("the {t} above the {a}", "the {t} over the {a}", "the {t} hanging above the {a}",
              "the {t} that hangs over the {a}"),
    "below": ("the {t} below the {a}", "the {t} beneath the {a}", "the {t} underneath the {a}",
              "the {t} under the {a}"),
}
_PREFIXES = ("", "", "", "", "please ", "now ", "go ahead and ", "i want you to ")
# Parser keywords, tried in this order on the words after the target's mention.
_KEYWORDS = (("between", ("between",)),
             ("supporting", ("with the", "that the", "supporting", "holding")),
             ("farthest", ("farthest", "furthest")),
             ("closest", ("closest", "nearest", "next to", "right by", "close to")),
             ("above", ("above", "over", "hangs over")),
             ("below", ("below", "beneath", "underneath", "under")),
             ("on", ("on top of", "on", "standing on", "sitting on")))


class NoUniqueReference(ValueError):
    """No referring expression singles out the requested target in its room."""


def _rng(rng) -> np.random.Generator:
    if isinstance(rng, np.random.Generator):
        return rng
    if rng is None or isinstance(rng, bool):
        raise TypeError("pass a numpy.random.Generator or an int seed (no hidden randomness)")
    return np.random.default_rng(rng)


def _word(category, rng):
    words = WORDS.get(category, (category,))
    return words[0] if len(words) == 1 or rng.random() < 0.65 else words[rng.integers(len(words))]


def targets_for(graph_or_room, action: str) -> list[int]:
    """Ids of the objects ``action`` can target in a room."""
    g = as_scene_graph(graph_or_room)
    if action not in ACTIONS:
        raise ValueError(f"unknown action {action!r}; choose from {ACTIONS}")
    allowed = ACTION_TARGETS[action]
    return [i for i in g.ids if allowed is None or g.category(i) in allowed]


def referring_options(graph_or_room, target_id: int) -> dict:
    """{relation (None = plain "the <class>"): [Reference, ...]} that resolve to exactly
    ``target_id``, anchors drawn from the classes that occur once in the room."""
    g = as_scene_graph(graph_or_room)
    cat, want = g.category(target_id), frozenset([target_id])
    alone = g.count(cat) == 1
    unique = [c for c in g.categories if g.count(c) == 1 and c != cat]
    opts = {None: [Reference(cat)]} if alone else {}
    for a in unique:
        for rel in ("closest", "farthest", "above", "below", "on", "supporting"):
            near = g.distance(target_id, g.instances(a)[0]) <= NEAR
            if alone and (rel == "farthest" or (rel == "closest" and not near)):
                continue  # true but odd for a lone object
            ref = Reference(cat, rel, (a,))
            if g.resolve(ref) == want:
                opts.setdefault(rel, []).append(ref)
    for a, b in itertools.combinations(unique, 2):
        ref = Reference(cat, "between", (a, b))
        if g.resolve(ref) == want:
            opts.setdefault("between", []).append(ref)
    return opts


def sample_instruction(room, action: str, target_id: int, rng, *, graph=None,
                       plain_prob: float = 0.6) -> tuple[str, dict]:
    """A random instruction for ``action`` on object ``target_id``: (text, info).

    ``info``: action, target_id, target_class, relation (None for "the <class>"),
    anchor_classes, anchor_ids, template (verb and expression template ids, for variety
    counts). A lone object of its class is named plainly with probability ``plain_prob``,
    else (and always for a class with several instances) through a relation type drawn
    uniformly among those that single it out. ``rng``: numpy Generator or int seed.
    Raises ValueError for a target the action cannot take, NoUniqueReference when no
    expression singles the target out.
    """
    g, rng = (graph if graph is not None else as_scene_graph(room)), _rng(rng)
    cat = g.category(target_id)
    if target_id not in targets_for(g, action):
        raise ValueError(f"{action!r} cannot target {g.name(target_id)}")
    opts = referring_options(g, target_id)
    if not opts:
        raise NoUniqueReference(f"nothing singles out {g.name(target_id)} in its room")
    rels = [r for r in opts if r is not None]
    if None in opts and (not rels or rng.random() < plain_prob):
        rel = None
    else:
        rel = rels[rng.integers(len(rels))]
    ref = opts[rel][rng.integers(len(opts[rel]))]
    anchor_ids = [g.instances(c)[0] for c in ref.anchors]
    pool = rel
    if rel == "closest" and g.distance(target_id, anchor_ids[0]) <= NEAR and rng.random() < 0.5:
        pool = "near"
    ti = int(rng.integers(len(TEMPLATES[pool])))
    words = [_word(c, rng) for c in (cat, *ref.anchors)]
    expr = TEMPLATES[pool][ti].format(t=words[0], a=(words[1:2] or [""])[0],
                                      b=(words[2:3] or [""])[0])
    verbs = [v for v in VERBS[action] if cat == "armchair" or v not in _SIT_IN]
    verb = verbs[rng.integers(len(verbs))]
    if cat == "bed" and action in ("sit", "stand_up") and rng.random() < 0.5:
        expr = ("the edge of " if rng.random() < 0.6 else "the side of ") + expr
    prefix = _PREFIXES[rng.integers(len(_PREFIXES))]
    if prefix == "go ahead and " and verb.startswith("go "):
        prefix = ""  # not "go ahead and go to"
    text = prefix + f"{verb} {expr}"
    if rng.random() < 0.5 or text.startswith("i "):  # "I want you to", never "i want"
        text = text[0].upper() + text[1:]
    text += "." if rng.random() < 0.5 else ""
    info = dict(action=action, target_id=int(target_id), target_class=cat, relation=rel,
                anchor_classes=tuple(ref.anchors), anchor_ids=tuple(anchor_ids),
                template=f"{action}:{VERBS[action].index(verb)}|{pool}:{ti}")
    return text, info


def sample_task(room, rng, *, action: str | None = None, graph=None,
                max_tries: int = 50) -> tuple[str, dict]:
    """Pick an action (uniform over those with a target here, or ``action``), a target and
    an instruction that singles it out: (text, info) as :func:`sample_instruction`."""
    g, rng = (graph if graph is not None else as_scene_graph(room)), _rng(rng)
    actions = [action] if action is not None else [a for a in ACTIONS if targets_for(g, a)]
    if not actions or not targets_for(g, actions[0]):
        raise ValueError(f"no object in the room for {actions}")
    for _ in range(max_tries):
        act = actions[rng.integers(len(actions))]
        cands = targets_for(g, act)
        try:
            return sample_instruction(room, act, cands[rng.integers(len(cands))], rng, graph=g)
        except NoUniqueReference:
            continue
    raise NoUniqueReference(f"no uniquely referable target for {actions} in {max_tries} tries")


def simple_text(action: str, category: str) -> str:
    """HUMANISE's rewritten training text "<action> the <object class>"."""
    verb = {"walk": "walk to", "sit": "sit on", "stand_up": "stand up from", "lie": "lie on"}
    return f"{verb[action]} the {category}"


def _norm(text):
    return " " + " ".join(re.sub(r"[^a-z]+", " ", text.lower()).split()) + " "


def anchor_is_first(text: str) -> bool:
    """Whether the frame where the body meets the object is the motion's first (getting up
    from it) rather than its last (walking to, sitting or lying down on it): the anchor frame
    of the goal distance (REFERENCE_FACTS). True when the text has a stand-up verb of the
    synthetic grammar (:data:`VERBS`) or says "stand up" / "get up"."""
    s = _norm(text)
    return any(f" {v} " in s for v in (*VERBS["stand_up"], "stand up", "get up"))


def parse_instruction(text: str) -> tuple[str, Reference]:
    """(action, Reference) of an instruction made by :func:`sample_instruction`.

    Keyword matching over the fixed vocabulary above (verbs, class names and synonyms,
    relation words); raises ValueError when no action or class is found.
    """
    s = _norm(text)
    action = next((a for a in ("stand_up", "lie", "sit", "walk")
                   if any(f" {v} " in s for v in VERBS[a])), None)
    names = sorted(((w, c) for c in BUILDERS for w in WORDS.get(c, (c,))),
                   key=lambda wc: -len(wc[0]))
    found, masked = [], s
    for w, c in names:
        for m in re.finditer(f" {w} ", masked):
            found.append((m.start(), m.end(), c))
            masked = masked[:m.start()] + " " * (m.end() - m.start() - 1) + masked[m.end() - 1:]
    found.sort()
    if action is None or not found:
        raise ValueError(f"cannot parse an action and a target class from {text!r}")
    target, anchors = found[0][2], tuple(c for _, _, c in found[1:])
    rest = s[found[0][1] - 1:]
    relation = None
    if anchors:
        relation = next((r for r, keys in _KEYWORDS if any(f" {k} " in rest for k in keys)),
                        None)
    if relation is None:  # no relation word the grammar knows ("beside"): the class alone
        return action, Reference(target)
    if len(anchors) != (2 if relation == "between" else 1):  # more or fewer than it takes
        return action, Reference(target)
    return action, Reference(target, relation, anchors)


def resolve(room_or_graph, reference) -> frozenset[int]:
    """Ids that a reference (a :class:`Reference`, a dict with ``target`` / ``relation`` /
    ``anchors``, or an instruction text) picks in a room, scene, object list or graph."""
    if isinstance(reference, str):
        reference = parse_instruction(reference)[1]
    elif isinstance(reference, dict):
        reference = Reference(reference["target"], reference.get("relation"),
                              tuple(reference.get("anchors", ())))
    return as_scene_graph(room_or_graph).resolve(reference)


__all__ = ["ACTIONS", "ACTION_TARGETS", "NoUniqueReference", "Reference", "SceneGraph",
           "anchor_is_first", "parse_instruction", "referring_options", "resolve", "sample_instruction",
           "sample_task", "simple_text", "targets_for"]
