"""Free phrasing read with word lists: the action, the target, its relation to anchors.

:func:`read_phrasing` reads any string (it never raises) the way people write instructions:
synonyms and paraphrases ("plop down onto the couch", "have a nap on the bed", "make your
way to the door"), politeness and adverbs ("could you please slowly…"), third-person
descriptions ("a person walks over and sits down"), several requests ("walk to the bed, then
lie down": the most specific action, on its object), relation words beyond the synthetic
templates ("beside", "by", "across from", "in front of") mapped to the scene graph's
relations, and "sit at the desk" (the seat nearest the desk). The words are in
:mod:`jaxmotion.grounding.lexicon`.

Steps, on the text's words (accents and case folded, verbs lemmatised): phrases that name an
object inside the verb ("go to bed"), then object names (longest first; "desk chair" is a
chair), then verb phrases (a negated one, "don't sit", and a participle describing an object,
"the lamp sitting on the table", do not count), then relation phrases between the target and
the anchors named after it. What it guesses or ignores it says in ``notes``.
"""

from __future__ import annotations

from dataclasses import dataclass

from jaxmotion.grounding import lexicon as lx
from jaxmotion.grounding.words import MAX_WORDS, canonical_category, indexes, lemma, spans, tokenize
from jaxmotion.scene.furniture import LIE_CATEGORIES, SEAT_CATEGORIES

__all__ = ["ACTION_OBJECT_CLASSES", "MAX_WORDS", "Reading", "action_classes", "takes",
           "canonical_category", "preferred_seats", "read_phrasing", "tokenize"]

_PRIORITY = {"stand_up": 3, "lie": 2, "sit": 1, "walk": 0}
#: the classes each action can take (None: any object)
ACTION_OBJECT_CLASSES = {"walk": None, "sit": tuple(SEAT_CATEGORIES),
                         "stand_up": tuple(SEAT_CATEGORIES), "lie": tuple(LIE_CATEGORIES)}
#: prepositions that put the body beside the object named after them ("sit by the bed":
#: on a seat near it, not on it)
_BESIDE = ("at", "by", "near", "beside", "next to", "close to", "in front of", "behind",
           "across from", "opposite", "facing", "around", "right next to", "right by",
           "near to", "alongside")
_TOWARDS = ("to", "towards", "toward", "over to", "up to")
_RELATION_WORDS = "next to, nearest, farthest from, between, on, with ... on it, above, below"


def action_classes(action: str | None) -> tuple[str, ...] | None:
    """The object classes ``action`` takes (sitting and getting up: seats, the bed last;
    lying: beds and sofas); None for walking or no action (any object)."""
    return ACTION_OBJECT_CLASSES.get(action) if action else None


def takes(action: str | None, obj: dict) -> bool:
    """Whether ``action`` can take the object-table row ``obj``: any object for a walk; for
    sit, stand up and lie an object of a class that takes it, or one whose surface affords
    it (``affords``, found by segmentation: an unnamed seat or bed)."""
    classes = action_classes(action)
    verb = "sit" if action == "stand_up" else action
    return (classes is None or canonical_category(obj["category"]) in classes
            or verb in obj.get("affords", ()))


def preferred_seats(action: str | None, objects) -> list:
    """Of ``objects`` (object-table rows) that ``action`` can take (:func:`takes`), the ones a
    plain "sit" / "stand up" means: the seats that are not beds, when there are any (a bed
    takes a sit, but a room's chairs and sofas come first); for other actions all that take
    it."""
    fits = [o for o in objects if takes(action, o)]
    if action in ("sit", "stand_up"):
        beds = [o for o in fits if canonical_category(o["category"]) == "bed"]
        if len(beds) < len(fits):
            fits = [o for o in fits if canonical_category(o["category"]) != "bed"]
    return fits


@dataclass(frozen=True)
class Reading:
    """What :func:`read_phrasing` read from a text (classes are canonical names, as in
    :data:`jaxmotion.grounding.lexicon.CATEGORY_WORDS`).

    Attributes:
      words: the text's words as read (folded, verbs lemmatised; "|" ends a sentence).
      action: ``walk`` / ``sit`` / ``stand_up`` / ``lie`` or None; action_words: the words
        it was read from; action_how: ``words`` (a verb phrase), ``object`` (a verb such as
        "rest" whose action depends on the object), ``destination`` (an unknown verb going
        "to" an object: "mosey over to the door" is walking there) or ``""``.
      target: the target's class, or None; target_words: the words naming it; generic: the
        words name any object the action can take ("a seat", "somewhere to lie down").
      preposition: the preposition before the target's name ("on", "at", ...), or "".
      relation, anchors, side: the scene-graph relation to the anchor classes named after
        the target, and ``front`` / ``back`` when the words ask for a side of the anchor
        ("in front of", "behind"); relation_words: the words read as the relation.
      seat_at: the target is the object of the action's classes nearest the named one
        ("sit at the desk": the seat at the desk, which is the anchor).
      object_phrase: words in the object's place that name no known class ("the credenza"),
        for the sentence-encoder fallback; query: the text with object names replaced by
        "it" and politeness dropped (the fallback's query for the action).
      several: the text asks for more than one motion (only the chosen one is done).
      steps: ``(action, first word)`` of each verb read as an action, in the text's order
        (``words`` indices; stories split the text there, :mod:`jaxmotion.planning.steps`).
      notes: what was guessed or ignored, in words for the user.
    """

    words: tuple[str, ...] = ()
    action: str | None = None
    action_words: str = ""
    action_how: str = ""
    target: str | None = None
    target_words: str = ""
    generic: bool = False
    preposition: str = ""
    relation: str | None = None
    anchors: tuple[str, ...] = ()
    relation_words: str = ""
    side: str | None = None
    seat_at: bool = False
    object_phrase: str = ""
    query: str = ""
    several: bool = False
    steps: tuple[tuple[str, int], ...] = ()
    notes: tuple[str, ...] = ()


@dataclass
class _Verb:
    start: int
    end: int
    kind: str  # strong / weak / idiom / generic
    value: object
    target: tuple | None = None  # (start, end, class, generic)
    action: str | None = None


def read_phrasing(text) -> Reading:
    """Read ``text`` (any string; never raises) into a :class:`Reading`."""
    raw = tokenize(text)
    lem = [lemma(w) for w in raw]
    n = len(raw)
    if not any(w != "|" for w in raw):
        return Reading(notes=(("the text has no words to read (only punctuation, symbols or "
                              "letters outside the Latin alphabet)"),))
    ix = indexes()
    free = [w != "|" for w in raw]
    notes: list[str] = []
    idioms = [i for i in spans(lem, ix["idioms"], free)
              if not (i[2][0] == "generic" and _used_as_verb(raw, lem, i[0], i[1]))]
    for s, e, _ in idioms:
        free[s:e] = [False] * (e - s)
    # "sink into the armchair", "seat yourself", "bed down": a name used as a verb
    objects = [o for o in spans(raw, ix["objects"], free) if not _used_as_verb(raw, lem, o[0], o[1])]
    # "desk chair", "sofa table": of two names in a row the second is the object
    objects = [o for k, o in enumerate(objects)
               if not (k + 1 < len(objects) and objects[k + 1][0] == o[1])]
    mentions = [(s, e, c, False) for s, e, c in objects]
    for s, e, (kind, value) in idioms:
        if kind == "generic":
            mentions.append((s, e, value, True))
        elif value[1] is not None:
            mentions.append((s, e, value[1], False))
    mentions.sort()
    for s, e, *_ in mentions:
        free[s:e] = [False] * (e - s)
    for s, e, _ in spans(lem, ix["filler"], list(free)):
        if not any(lem[s:e] == list(p) for p, _ in ix["verbs"].get(lem[s], ())):
            free[s:e] = [False] * (e - s)  # "please", "slowly": never a verb or relation
    breaks = [s for s, _, _ in spans(lem, ix["breaks"], free)] + [n]
    verbs = [_Verb(s, e, kind, value) for s, e, (kind, value) in
             spans(lem, ix["verbs"], free)]
    verbs += [_Verb(s, e, kind, value) for s, e, (kind, value) in idioms]
    verbs.sort(key=lambda v: v.start)
    mention_ends = {e for _, e, *_ in mentions}
    kept = []
    for v in verbs:
        negated = _negated(lem, v.start)
        if negated and v.kind != "generic":
            notes.append(f"'{' '.join(raw[v.start:v.end])}' is negated in the text: not read "
                         "as the action")
            continue
        described = raw[v.start] in lx.PARTICIPLES or (raw[v.start].endswith("ing")
                                                       and v.kind in ("strong", "weak"))
        gap = lem[v.start - 2:v.start] if v.start >= 2 else []
        after_object = v.start in mention_ends or (
            gap in (["that", "be"], ["which", "be"], ["that", "s"]) and v.start - 2 in mention_ends)
        if described and after_object and v.kind in ("strong", "weak"):
            continue  # "the lamp sitting on the table": describes the object
        if _says_where_you_are(lem, v.start) and v.kind in ("strong", "weak"):
            notes.append(f"'{' '.join(raw[v.start:v.end])}' says where you are: not read as "
                         "the action")
            continue
        kept.append(v)
    verbs = kept
    for v in verbs:
        free[v.start:v.end] = [False] * (v.end - v.start)
    # each verb's object: the first name after it (before the next verb or sentence end)
    for k, v in enumerate(verbs):
        if v.kind == "generic":
            v.target = next(m for m in mentions if m[0] == v.start)
            continue
        if v.kind == "idiom" and v.value[1] is not None:
            v.target = next(m for m in mentions if m[0] == v.start)
            continue
        stop = min([verbs[k + 1].start] if k + 1 < len(verbs) else [n])
        stop = min(stop, min(b for b in breaks if b >= v.end))
        v.target = next((m for m in mentions if v.end <= m[0] < stop), None)
    for k, v in enumerate(verbs):
        if v.target is None:  # "walk to the bed and lie down", "the chair: sit on it"
            prev = [u.target for u in verbs[:k] if u.target is not None]
            before = [m for m in mentions if m[1] <= v.start]
            v.target = prev[-1] if prev else _clause_head(before, breaks)
    for k, v in enumerate(verbs):
        v.action = _verb_action(v)
        u = verbs[k - 1] if k else None
        if (v.kind == "weak" and u is not None and u.action in ("sit", "lie")
                and lem[u.end:v.start] in ([], ["and"]) and v.target is not None
                and (v.target[3] or v.target[2] in action_classes(u.action))):
            v.action = u.action  # "lie down and relax on the sofa": one motion, lying
    acting = [v for v in verbs if v.action is not None]
    chosen = max(acting, key=lambda v: (_PRIORITY[v.action], v.target is not None, -v.start),
                 default=None)
    # "get up from the chair and walk to the door": two motions (walking to an object
    # before lying on it is one)
    several = len({v.target[:2] for v in acting if v.target is not None}) > 1 or len(
        {v.action for v in acting} - {"walk"}) > 1
    target = chosen.target if chosen is not None else None
    if target is None:  # "stand up and leave the chair": the object of another verb
        others = sorted((v for v in verbs if v.target is not None),
                        key=lambda v: abs(v.start - (chosen.start if chosen else 0)))
        target = others[0].target if others else (mentions[0] if mentions else None)
    for v in verbs:
        if v.action is None and v.kind == "weak":
            notes.append(f"'{' '.join(raw[v.start:v.end])}' is read as an action only on a "
                         "bed or seat")
    out = {"words": tuple(lem), "several": several,
           "steps": tuple((v.action, v.start) for v in acting)}
    if chosen is not None:
        out.update(action=chosen.action, action_words=" ".join(raw[chosen.start:chosen.end]),
                   action_how="object" if chosen.kind == "weak" else "words")
    if target is not None:
        out.update(_target_fields(raw, lem, free, target, mentions, verbs, breaks, notes,
                                  chosen.action if chosen is not None else None))
    if chosen is None and out.get("preposition") in _TOWARDS:
        # "mosey over to the door": an unknown verb with a destination is going there
        s = target[0] - len(out["preposition"].split())
        k = s
        while k > 0 and free[k - 1] and raw[k - 1] not in ("|", "and") and s - k < 2:
            k -= 1
        out.update(action="walk", action_how="destination",
                   action_words=" ".join(raw[k:target[0]]))
    if target is not None and out.get("target") is not None:
        _by_preposition(out, raw, target, chosen, notes)
    out["object_phrase"] = "" if target is not None else _object_phrase(raw, free, chosen)
    out["query"] = _query(raw, lem, mentions, ix)
    return Reading(**out, notes=tuple(notes))


#: words right after a verb ("sink into", "seat yourself", "bed down"): a class name
#: followed by one, and not by an article or preposition before it, is used as a verb
_VERB_PARTICLES = ("into", "onto", "down", "back", "up", "yourself", "yourselves", "in", "on",
                   "out", "off", "over")
#: prepositions of leaving an object ("hop down off the stool", "push up out of the chair")
_SOURCE = ("off", "off of", "out of", "from")
#: prepositions of getting onto or into an object ("hop up onto the stool")
_ONTO = ("onto", "into")
_ON = ("on", "upon", "atop", "in", "on top of", *_ONTO)


#: words after which a clause's verb comes ("please sink into…", "and then seat yourself…",
#: "you are seated…")
_VERB_POSITION = ("|", "and", "then", "or", "so", "please", "pls", "kindly", "just", "now",
                  "first", "finally", "you", "be")


def _used_as_verb(raw, lem, s: int, e: int) -> bool:
    """Whether the one-word name ``raw[s:e]`` is used as a verb: where a clause's verb goes
    (the text's start, after "and", "please", "you are", …) and followed by a particle or
    "yourself" ("sink into the armchair", "seat yourself", "you are seated on the chair");
    not "the sink in the corner", "the leather armchair in the corner", "no fridge in
    here"."""
    if e - s != 1 or e >= len(raw) or raw[e] not in _VERB_PARTICLES:
        return False
    return s == 0 or lem[s - 1] in _VERB_POSITION


def _before_determiners(raw, s: int) -> int:
    """Where the determiners before the name at ``s`` start ("onto that big | chair"): the
    preposition ends there. "of" is a determiner ("the edge of the bed") except in "out of" /
    "off of"."""
    k = s
    while k > 0 and raw[k - 1] in lx.DETERMINERS and raw[k - 1] not in lx.DIRECT_PREPOSITIONS \
            and " ".join(raw[k - 2:k]) not in lx.DIRECT_PREPOSITIONS:
        k -= 1
    return k


def _says_where_you_are(lem, start: int) -> bool:
    """Whether the verb at ``start`` describes the present state ("you are seated on the
    chair", "you're sitting on it", "you've been sitting there"), not a request."""
    p = start + (1 if lem[start] == "be" else 0)
    return lem[max(p - 2, 0):p] == ["you", "be"] or lem[max(p - 3, 0):p] in (
        ["you", "have", "been"], ["you", "have", "be"]) or (p == start + 1 and lem[
            max(start - 1, 0):start] == ["you"])


def _clause_head(before, breaks):
    """Of the names ``before`` a verb (``(start, end, class, generic)``), the first of the
    last clause that has one: "you are on the chair by the table; stand up" is the chair's
    (not the table's, which says where the chair is)."""
    if not before:
        return None
    last = before[-1][0]
    cut = max([b + 1 for b in breaks if b < last] + [0])
    return next(m for m in before if m[0] >= cut)


def _by_preposition(out: dict, raw, target, chosen, notes) -> None:
    """The action from the preposition before a seat when the verb does not say it (or says
    the other way): leaving it ("hop down off the stool", "stand yourself up out of the
    chair": getting up) and getting onto it ("hop up onto the stool": sitting; "plant
    yourself on the chair", a verb the word lists do not know: sitting). Updates ``out`` in
    place."""
    prep, cls, action = out.get("preposition", ""), out["target"], out.get("action")
    k = _before_determiners(raw, target[0]) - len(prep.split())
    if cls not in SEAT_CATEGORIES or not prep or (k > 0 and raw[k - 1] == "away"):
        return
    if prep in _SOURCE and action in (None, "walk"):
        new = "stand_up"
    elif (prep in _ONTO and action == "stand_up") or (
            prep in _ON and action is None and cls != "bed"):
        new = "sit"
    else:
        return
    if chosen is None:
        j = k
        while j > 0 and raw[j - 1] not in ("|", "and") and k - j < 3:
            j -= 1
        out["action_words"] = " ".join(raw[j:k])
    notes.append(f"read '{out.get('action_words', '')} {prep} the {out['target_words']}' as "
                 f"{new} ({'leaving' if prep in _SOURCE else 'getting onto'} a seat)")
    out.update(action=new, action_how="preposition")


def _negated(lem, start: int) -> bool:
    """Whether the verb at ``start`` is negated: "not" / "never" / "without" / "instead of"
    / "rather than" right before it ("don't sit", "do not ever lie", "rather than sitting");
    not the suggestion "why don't you sit", "why not sit"."""
    k = start - 1
    while k >= 0 and lem[k] in ("do", "just", "even", "really", "ever", "to", "you", "please"):
        k -= 1
    if k < 0:
        return False
    if lem[k] == "not" and "why" in (lem[k - 1:k] + lem[k - 2:k - 1]):
        return False  # "why not sit", "why do not you sit" (why don't you)
    return lem[k] in ("not", "never", "dont", "without") or lem[k - 1:k + 1] in (
        ["instead", "of"], ["rather", "than"])


def _verb_action(v: _Verb) -> str | None:
    if v.kind == "strong":
        return v.value
    if v.kind in ("idiom", "generic"):
        return v.value[0] if v.kind == "idiom" else v.value
    cls = v.target[2] if v.target is not None else None
    generic = v.target is not None and v.target[3]
    if v.value == "rest":
        if cls == "bed" or (generic and cls == "lie"):
            return "lie"
        return "sit" if cls in SEAT_CATEGORIES or (generic and cls == "sit") else None
    return "stand_up" if cls in SEAT_CATEGORIES or generic else None  # leave


def _target_fields(raw, lem, free, target, mentions, verbs, breaks, notes, action) -> dict:
    """The target's class, its preposition, and its relation to the anchors named after it."""
    s, e, cls, generic = target
    out = {"target_words": " ".join(raw[s:e])}
    if generic:
        out["target"] = None
        out["generic"] = True
        return out
    out["target"] = cls
    k = _before_determiners(raw, s)
    prep = ""
    for size in (3, 2, 1):
        if k - size >= 0 and " ".join(raw[k - size:k]) in (
                *lx.DIRECT_PREPOSITIONS, *_BESIDE, "to", "towards", "toward", "over to",
                "up to"):
            prep = " ".join(raw[k - size:k])
            break
    out["preposition"] = prep
    if not prep and k > 0 and raw[k - 1] in ("opposite", "facing", "beside", "around"):
        prep = out["preposition"] = raw[k - 1]
    stop = min([b for b in breaks if b >= e] + [v.start for v in verbs if v.start >= e]
               + [len(raw)])
    after = [m for m in mentions if e <= m[0] < stop and not m[3]]
    window = list(free)
    for m in mentions:
        window[m[0]:m[1]] = [False] * (m[1] - m[0])
    rels = [r for r in spans(lem, indexes()["relations"], window) if e <= r[0] < stop]
    relation, anchors, words = None, (), ""
    for r0, r1, rel in rels:
        later = [m for m in after if m[0] >= r1]
        need = 2 if rel == "between" else 1
        if len(later) >= need:
            relation, anchors = rel, tuple(m[2] for m in later[:need])
            words = " ".join(raw[r0:r1])
            break
        if later or rel == "between":
            notes.append(f"'{' '.join(raw[r0:r1])}' needs {need} object(s) after it; ignored")
    if relation is None and s > 0 and raw[s - 1] in lx.SUPERLATIVES:
        later = [m for m in after if m[0] > e]
        if later:  # "the nearest chair to the door"
            relation, anchors, words = lx.SUPERLATIVES[raw[s - 1]], (later[0][2],), raw[s - 1]
        else:
            notes.append(f"'{raw[s - 1]} {' '.join(raw[s:e])}' names nothing to be "
                         f"{raw[s - 1]} to; every {cls} is a candidate")
    for r0, r1, _ in rels:  # "right" of "right next to" is no unsupported "right"
        window[r0:r1] = [False] * (r1 - r0)
    for r0, r1, _ in spans(lem, indexes()["unsupported"], window):
        if e <= r0 < stop:
            notes.append(f"'{' '.join(raw[r0:r1])}' is not a relation the scene graph has "
                         f"({_RELATION_WORDS}); ignored")
    if relation is not None and cls in anchors:
        notes.append(f"'{words}' relates the {cls} to another {cls}; ignored")
        relation, anchors, words = None, (), ""
    out.update(relation=relation, anchors=anchors, relation_words=words,
               side=lx.ANCHOR_SIDES.get(words) if words else None)
    allowed = action_classes(action)
    if allowed is not None and (prep in _BESIDE or (cls not in allowed and (
            action == "stand_up" or prep not in lx.DIRECT_PREPOSITIONS))):
        # "sit at the desk", "lie down by the window", "sit across from the sofa": the
        # object of the action's classes nearest the named one
        out["seat_at"] = True
        if relation is None and prep in lx.ANCHOR_SIDES:
            out["side"] = lx.ANCHOR_SIDES[prep]
    return out


_ARTICLES = ("the", "a", "an", "that", "this", "my", "your", "some", "our")


def _object_phrase(raw, free, chosen) -> str:
    """Words in an object's place that name no known class ("sit on the credenza" ->
    "credenza"): the free words after the first article after the verb (or in the text
    without a verb), adjectives skipped, at most three."""
    k = chosen.end if chosen is not None else 0
    while k < len(raw) and not (free[k] and raw[k] in _ARTICLES):
        k += 1
    words = []
    for j in range(k + 1, len(raw)):
        if not free[j] or raw[j] == "|" or raw[j] in lx.DIRECT_PREPOSITIONS or raw[j] in (
                "to", "towards", "toward", "at", "by", "near", "and", "it", "s", "there"):
            break
        if raw[j] not in lx.DETERMINERS:
            words.append(raw[j])
        if len(words) == 3:
            break
    if words and words[-1] in lx.ROOM_WORDS:  # "the (living) room", "the kitchen": no object
        return ""
    return " ".join(words)


def _query(raw, lem, mentions, ix) -> str:
    """The text for the action prototypes: object names replaced by "it", politeness and
    adverbs dropped (:data:`jaxmotion.grounding.lexicon.FILLER`)."""
    keep = [True] * len(raw)
    words = list(raw)
    for s, e, *_ in mentions:
        words[s] = "it"
        keep[s + 1:e] = [False] * (e - s - 1)
    for s, e, _ in spans(lem, ix["filler"], [True] * len(raw)):
        keep[s:e] = [False] * (e - s)
    out = [w for w, k in zip(words, keep) if k and w != "|"]
    cleaned = [w for k, w in enumerate(out) if not (w in ("the", "a", "an") and k + 1 < len(out)
                                                    and out[k + 1] == "it")]
    return " ".join(cleaned)
