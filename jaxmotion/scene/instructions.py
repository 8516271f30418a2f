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

``phrasing="rich"`` (:func:`sample_rich_instruction`, word lists in
:mod:`jaxmotion.scene.rich_phrasing`) composes the same references from a far larger space:
polite and filler frames, adverbs, purpose clauses, two-clause forms on the one target,
more relation words and object synonyms, and "have a seat at the desk" for the seat at it
(:func:`phrasing_space` counts it). Its texts are read by the free-phrasing reader
(:mod:`jaxmotion.grounding`), not by :func:`parse_instruction`. The default phrasing is
unchanged: the same texts for a seed as before the option existed.
"""

from __future__ import annotations

import itertools
import re

import numpy as np

from jaxmotion.scene import rich_phrasing as rp
from jaxmotion.scene.furniture import BUILDERS, LIE_CATEGORIES, SEAT_CATEGORIES
from jaxmotion.scene.graph import Reference, SceneGraph, as_scene_graph

ACTIONS = ("walk", "sit", "stand_up", "lie")
ACTION_TARGETS = {"walk": None, "sit": SEAT_CATEGORIES, "stand_up": SEAT_CATEGORIES,
                  "lie": LIE_CATEGORIES}
NEAR = 1.0  # "next to" / "right by" only within this xy box distance (m)
SEAT_AT_NEAR = 0.5  # "sit at the desk" only for a seat within this xy box distance (m)
PHRASINGS = ("default", "rich")  # sample_task(phrasing=...)
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


def _draw_reference(g, target_id: int, opts: dict, rng, plain_prob: float):
    """One of ``opts`` (:func:`referring_options`), as both grammars draw it: the plain name
    with probability ``plain_prob`` when it is an option (always when it is the only one),
    else a relation type uniformly, then one of its references. Returns ``(relation,
    reference, anchor_ids, template pool)``; the pool is ``"near"`` for half of the
    "closest" references whose anchor is within :data:`NEAR`."""
    rels = [r for r in opts if r is not None]
    if None in opts and (not rels or rng.random() < plain_prob):
        rel = None
    else:
        rel = rels[rng.integers(len(rels))]
    ref = opts[rel][rng.integers(len(opts[rel]))]
    anchor_ids = tuple(g.instances(c)[0] for c in ref.anchors)
    pool = rel
    if rel == "closest" and g.distance(target_id, anchor_ids[0]) <= NEAR and rng.random() < 0.5:
        pool = "near"
    return rel, ref, anchor_ids, pool


def sample_instruction(room, action: str, target_id: int, rng, *, graph=None,
                       plain_prob: float = 0.6, phrasing: str = "default") -> tuple[str, dict]:
    """A random instruction for ``action`` on object ``target_id``: (text, info).

    ``info``: action, target_id, target_class, relation (None for "the <class>"),
    anchor_classes, anchor_ids, template (verb and expression template ids, for variety
    counts). A lone object of its class is named plainly with probability ``plain_prob``,
    else (and always for a class with several instances) through a relation type drawn
    uniformly among those that single it out. ``rng``: numpy Generator or int seed.
    ``phrasing``: ``"default"`` (the grammar the shipped checkpoints were trained on) or
    ``"rich"`` (:func:`sample_rich_instruction`). Raises ValueError for a target the action
    cannot take, NoUniqueReference when no expression singles the target out.
    """
    g, rng = (graph if graph is not None else as_scene_graph(room)), _rng(rng)
    cat = g.category(target_id)
    if target_id not in targets_for(g, action):
        raise ValueError(f"{action!r} cannot target {g.name(target_id)}")
    if phrasing != "default":
        if phrasing not in PHRASINGS:
            raise ValueError(f"unknown phrasing {phrasing!r}; choose from {PHRASINGS}")
        return sample_rich_instruction(g, action, target_id, rng, plain_prob=plain_prob)
    opts = referring_options(g, target_id)
    if not opts:
        raise NoUniqueReference(f"nothing singles out {g.name(target_id)} in its room")
    rel, ref, anchor_ids, pool = _draw_reference(g, target_id, opts, rng, plain_prob)
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


# --------------------------------------------------------------------------- rich phrasing
def _cores(action: str) -> tuple[str, ...]:
    """The rich space's verb cores of ``action``: the default's, then the added ones."""
    return tuple(dict.fromkeys((*VERBS[action], *rp.EXTRA_VERBS[action])))


def _verb_phrase(frame: str, adverb: str, core: str, suffix: str) -> str | None:
    """A frame filled with "<adverb><core> {x}<suffix>" ({x}: the referring expression), or
    None for a combination the rich space leaves out: "go ahead and go to", two adverbs
    ("slowly walk to ... quickly"), a condition suffix in a frame that ends after it or
    starts with one ("when you're ready, ... right away", "... if you can for me")."""
    if frame.startswith("go ahead and") and core.startswith("go "):
        return None
    if adverb and suffix in rp.SUFFIX_ADVERBS:
        return None
    if suffix in rp.SUFFIX_CONDITIONS and (frame.rstrip("?")[-3:] != "{v}" or frame.startswith(
            ("if ", "when "))):
        return None
    return frame.replace("{v}", f"{adverb}{core} {{x}}{suffix}")


def rich_templates() -> dict:
    """{pool: expression templates} of the rich space ({t} target, {a} / {b} anchors;
    pools as :data:`TEMPLATES`, ``near`` being ``closest`` within :data:`NEAR`)."""
    out: dict = {None: ("the {t}",)}
    for pool, words in rp.RELATION_WORDS.items():
        tail = " the {a} and the {b}" if pool == "between" else " the {a}"
        forms = []
        for w in words:
            word, participle = (w, False) if isinstance(w, str) else w
            for conn in rp.RELATION_CONNECTORS[:4] if participle else rp.RELATION_CONNECTORS:
                forms.append(f"the {{t}} {conn}{word}{tail}")
        forms += rp.SUPERLATIVE_TEMPLATES.get(pool, ())
        out[pool] = tuple(dict.fromkeys(forms))
    out["supporting"] = tuple(f"the {{t}} {s}" for s in rp.SUPPORTING_TEMPLATES)
    return out


def _rich_word(category, rng):
    words = rp.RICH_WORDS.get(category) or WORDS.get(category) or (category,)
    return words[0] if len(words) == 1 or rng.random() < 0.5 else words[rng.integers(len(words))]


def seat_at_anchors(graph_or_room, action: str, target_id: int) -> list[int]:
    """Ids of the objects ``target_id`` is "the seat at" for ``action`` (sit / stand_up):
    a desk, table or coffee table alone of its class in the room, whose nearest seat
    (beds left out when the room has another seat; ties within the graph's ``tie_tol``) is
    the target alone, within :data:`SEAT_AT_NEAR`; the target is not a bed. This is how the
    free-phrasing reader takes "sit at the desk"."""
    g = as_scene_graph(graph_or_room)
    if action not in ("sit", "stand_up") or g.category(target_id) == "bed":
        return []
    out = []
    for cat in rp.SEAT_AT_ANCHORS:
        if g.count(cat) != 1:
            continue
        a = g.instances(cat)[0]
        seats = [i for i in g.ids if g.category(i) in SEAT_CATEGORIES and i != a]
        if any(g.category(i) != "bed" for i in seats):
            seats = [i for i in seats if g.category(i) != "bed"]
        d = {i: g.distance(i, a) for i in seats}
        best = min(d.values(), default=np.inf)
        tied = [i for i, v in d.items() if v <= best + g.tie_tol]
        if tied == [target_id] and best <= SEAT_AT_NEAR:
            out.append(a)
    return out


def sample_rich_instruction(room, action: str, target_id: int, rng, *, graph=None,
                            plain_prob: float = 0.6, seat_at_prob: float = 0.5,
                            multi_prob: float = 0.12) -> tuple[str, dict]:
    """A random instruction in the rich phrasing space (:mod:`jaxmotion.scene.rich_phrasing`)
    for ``action`` on ``target_id``: (text, info) as :func:`sample_instruction`.

    The referring expression is drawn as the default's (same relations, the same
    ``plain_prob``, "next to"-like words only within :data:`NEAR`) from
    :func:`rich_templates` with the rich object words; with probability ``seat_at_prob``,
    when the target is the seat at a desk or table (:func:`seat_at_anchors`), sitting and
    getting up name that instead ("have a seat at the desk", relation ``"at"``). With
    probability ``multi_prob`` the sentence is a two-clause form on the one target
    (:data:`~jaxmotion.scene.rich_phrasing.MULTI_CLAUSE`), else a frame around an adverb,
    the verb core, the expression and a suffix. ``info["template"]`` names the parts.
    """
    g, rng = (graph if graph is not None else as_scene_graph(room)), _rng(rng)
    cat = g.category(target_id)
    if target_id not in targets_for(g, action):
        raise ValueError(f"{action!r} cannot target {g.name(target_id)}")
    opts = referring_options(g, target_id)
    at = seat_at_anchors(g, action, target_id)
    if not opts and not at:
        raise NoUniqueReference(f"nothing singles out {g.name(target_id)} in its room")
    if at and (not opts or rng.random() < seat_at_prob):
        a = at[rng.integers(len(at))]
        core = rp.SEAT_AT_VERBS[action][rng.integers(len(rp.SEAT_AT_VERBS[action]))]
        expr = f"the {_rich_word(g.category(a), rng)}"
        rel, anchors, anchor_ids, pool, ti, form = "at", (g.category(a),), (a,), "at", 0, "frame"
    else:
        rel, ref, anchor_ids, pool = _draw_reference(g, target_id, opts, rng, plain_prob)
        anchors = tuple(ref.anchors)
        templates = rich_templates()[pool]
        ti = int(rng.integers(len(templates)))
        words = [_rich_word(c, rng) for c in (cat, *anchors)]
        expr = templates[ti].format(t=words[0], a=(words[1:2] or [""])[0],
                                    b=(words[2:3] or [""])[0])
        if cat == "bed" and action in ("sit", "stand_up") and rng.random() < 0.5:
            expr = ("the edge of " if rng.random() < 0.6 else "the side of ") + expr
        cores = [c for c in _cores(action) if cat == "armchair" or c not in rp.IN_ONLY]
        core = cores[rng.integers(len(cores))]
        form = "multi" if rng.random() < multi_prob else "frame"
    if form == "multi":
        forms = rp.MULTI_CLAUSE[action]
        fi = int(rng.integers(len(forms)))
        text = forms[fi].replace("{e}", expr).replace("{E}", expr).replace("{c}", core)
        text = re.sub(r"([.?] )([a-z])", lambda m: m.group(1) + m.group(2).upper(), text)
        parts = f"multi:{fi}"
    else:
        fi = int(rng.integers(len(rp.FRAMES)))
        if _verb_phrase(rp.FRAMES[fi], "", core, "") is None:  # "go ahead and go to"
            fi = 0
        adverb = rp.PREFIX_ADVERBS[rng.integers(len(rp.PREFIX_ADVERBS))]
        suffixes = [x for x in rp.SUFFIXES[action]
                    if _verb_phrase(rp.FRAMES[fi], adverb, core, x) is not None]
        suffix = suffixes[rng.integers(len(suffixes))]
        text = _verb_phrase(rp.FRAMES[fi], adverb, core, suffix).replace("{x}", expr)
        parts = f"frame:{fi}|{adverb.strip()}|{suffix.strip()}"
    if text.startswith(("i ", "i'")) or rng.random() < 0.5:
        text = text[0].upper() + text[1:]
    if not text.endswith("?") and rng.random() < 0.5:
        text += "."
    info = {"action": action, "target_id": int(target_id), "target_class": cat,
            "relation": rel, "anchor_classes": anchors,
            "anchor_ids": tuple(int(i) for i in anchor_ids),
            "template": f"rich:{action}:{core}|{pool}:{ti}|{parts}"}
    return text, info


def phrasing_space(kind: str = "rich") -> dict:
    """How many distinct phrasings a phrasing (``"default"`` / ``"rich"``) composes.

    ``verb_phrases``: distinct verb phrases over the four actions (the sentence without its
    referring expression: frame or prefix, adverb, verb core, suffix, or a two-clause
    form), with ``verb_phrases_by_action``; ``verb_cores``: distinct verb cores;
    ``relation_phrasings``: distinct expression templates that use a relation;
    ``object_words``: distinct words for the object classes.
    """
    if kind not in PHRASINGS:
        raise ValueError(f"unknown phrasing {kind!r}; choose from {PHRASINGS}")
    by_action: dict[str, set] = {}
    if kind == "default":
        for a in ACTIONS:
            by_action[a] = {f"{p}{v} {{x}}" for p in _PREFIXES for v in VERBS[a]}
        cores = {v for a in ACTIONS for v in VERBS[a]}
        relations = {t for k, ts in TEMPLATES.items() if k is not None for t in ts}
        words = {w for c in BUILDERS for w in WORDS.get(c, (c,))}
    else:
        for a in ACTIONS:
            phrases = set()
            seat_at = rp.SEAT_AT_VERBS.get(a, ())
            for core in (*_cores(a), *seat_at):
                for frame in rp.FRAMES:
                    for adverb in rp.PREFIX_ADVERBS:
                        for suffix in rp.SUFFIXES[a]:
                            p = _verb_phrase(frame, adverb, core, suffix)
                            if p is not None:
                                phrases.add(p)
            for core in _cores(a):
                phrases.update(m.replace("{c}", core) for m in rp.MULTI_CLAUSE[a])
            by_action[a] = phrases
        cores = {c for a in ACTIONS for c in (*_cores(a), *rp.SEAT_AT_VERBS.get(a, ()))}
        relations = {t for k, ts in rich_templates().items() if k is not None for t in ts}
        words = {w for c in BUILDERS for w in (rp.RICH_WORDS.get(c) or WORDS.get(c) or (c,))}
    return {"verb_phrases": len(set().union(*by_action.values())),
            "verb_phrases_by_action": {a: len(p) for a, p in by_action.items()},
            "verb_cores": len(cores), "relation_phrasings": len(relations),
            "object_words": len(words)}


def sample_task(room, rng, *, action: str | None = None, graph=None,
                max_tries: int = 50, phrasing: str = "default") -> tuple[str, dict]:
    """Pick an action (uniform over those with a target here, or ``action``), a target and
    an instruction that singles it out: (text, info) as :func:`sample_instruction`, in the
    given ``phrasing`` (``"default"``: the same texts for a seed as before the option
    existed; ``"rich"``: :func:`sample_rich_instruction`)."""
    if phrasing not in PHRASINGS:
        raise ValueError(f"unknown phrasing {phrasing!r}; choose from {PHRASINGS}")
    g, rng = (graph if graph is not None else as_scene_graph(room)), _rng(rng)
    actions = [action] if action is not None else [a for a in ACTIONS if targets_for(g, a)]
    if not actions or not targets_for(g, actions[0]):
        raise ValueError(f"no object in the room for {actions}")
    for _ in range(max_tries):
        act = actions[rng.integers(len(actions))]
        cands = targets_for(g, act)
        try:
            return sample_instruction(room, act, cands[rng.integers(len(cands))], rng, graph=g,
                                      phrasing=phrasing)
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


__all__ = ["ACTIONS", "ACTION_TARGETS", "PHRASINGS", "NoUniqueReference", "Reference",
           "SceneGraph", "anchor_is_first", "parse_instruction", "phrasing_space",
           "referring_options", "resolve", "rich_templates", "sample_instruction",
           "sample_rich_instruction", "sample_task", "seat_at_anchors", "simple_text",
           "targets_for"]
