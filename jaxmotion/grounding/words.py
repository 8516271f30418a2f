"""The words of a text and the lexicon's phrases, indexed for matching.

:func:`tokenize` folds a text into words; :func:`lemma` gives a verb's base form;
:func:`indexes` holds the phrases of :mod:`jaxmotion.grounding.lexicon` by first word, longest
first, and :func:`spans` finds them in a text's words. :func:`canonical_category` maps a class
name (a room's, or a word) to the lexicon's class.
"""

from __future__ import annotations

import re
import unicodedata
from functools import lru_cache

from jaxmotion.grounding import lexicon as lx

__all__ = ["MAX_WORDS", "canonical_category", "indexes", "lemma", "spans", "tokenize"]

#: the words read from a longer text (the models' text encoder reads at most 256 tokens)
MAX_WORDS = 400


def tokenize(text: str) -> list[str]:
    """The words of ``text``: Unicode compatibility-folded (full-width letters, ligatures),
    accents stripped, case folded, contractions expanded ("don't" → "do not"), sentence
    punctuation as ``"|"``; at most :data:`MAX_WORDS`."""
    s = unicodedata.normalize("NFKD", str(text))
    s = "".join(c for c in s if not unicodedata.combining(c)).casefold()
    s = re.sub(r"[\u2018\u2019\u02bc`\u00b4]", "'", s)
    s = re.sub(r"n't\b", " not", s)
    s = re.sub(r"\b(i|you|we|they|he|she)'d\b", r"\1 would", s)
    s = re.sub(r"\blet's\b", "let us", s)
    s = re.sub(r"'(ll|re|ve|m|s)\b", lambda m: {"ll": " will", "re": " are", "ve": " have",
                                                 "m": " am", "s": " s"}[m.group(1)], s)
    s = re.sub(r"[.;!?:]+", " | ", s)
    s = re.sub(r"[^a-z0-9|]+", " ", s)
    return s.split()[:MAX_WORDS]


@lru_cache(maxsize=1)
def _nouns() -> frozenset[str]:
    return frozenset(w for words in lx.CATEGORY_WORDS.values() for p in words for w in p.split())


@lru_cache(maxsize=1)
def _lemmas() -> dict[str, str]:
    """Inflected verb form -> base form, for the verbs of the lexicon's phrases."""
    heads = {w for p in (*lx.ACTION_PHRASES, *lx.WEAK_VERBS, *lx.IDIOMS, *lx.RELATION_PHRASES,
                         *lx.GENERIC_TARGETS) for w in p.split() if w.isalpha() and len(w) >= 3}
    forms: dict[str, str] = {}
    for w in sorted(heads):
        cands = [w + "s", w + "es", w + "ed", w + "ing"]
        if w.endswith("e"):
            cands += [w + "d", w[:-1] + "ing"]
        if w.endswith("y"):
            cands += [w[:-1] + "ies", w[:-1] + "ied"]
        if re.fullmatch(r".*[^aeiou][aeiou][bdglmnprt]", w):
            cands += [w + w[-1] + "ing", w + w[-1] + "ed"]
        for f in cands:
            if f not in heads and f not in _nouns():
                forms.setdefault(f, w)
    forms.update(lx.VERB_FORMS)
    return forms


def lemma(word: str) -> str:
    """The base form of a verb of the lexicon ("sitting" -> "sit"); other words as they are."""
    return _lemmas().get(word, word)


def _phrase_index(phrases) -> dict[str, list[tuple[tuple[str, ...], object]]]:
    """{first word: [(words, value), ...] longest first} of ``phrases`` (``{text: value}``),
    their verbs lemmatised as the text's are."""
    index: dict[str, list] = {}
    for text, value in phrases.items():
        words = tuple(lemma(w) for w in text.split())
        index.setdefault(words[0], []).append((words, value))
    for entries in index.values():
        entries.sort(key=lambda e: -len(e[0]))
    return index


def _plural(word: str) -> tuple[str, ...]:
    if word.endswith(("s", "x", "ch", "sh")):
        return (word + "es",)
    if word.endswith("y") and word[-2:-1] not in "aeiou":
        return (word[:-1] + "ies",)
    return (word + "s",)


@lru_cache(maxsize=1)
def indexes() -> dict[str, dict]:
    """The lexicon's phrase indexes (:func:`spans` reads them): ``idioms`` (with generic
    targets), ``objects`` (class names and their plurals -> class), ``verbs`` (``(strong |
    weak, action)``), ``relations``, ``unsupported`` (relation words the graph lacks),
    ``breaks``, ``negations``, ``filler``."""
    names: dict[str, str] = {}
    for cat, words in lx.CATEGORY_WORDS.items():
        for w in words:
            names.setdefault(w, cat)
    for cat, words in lx.CATEGORY_WORDS.items():
        for w in words:
            *head, last = w.split()
            for p in _plural(last):
                names.setdefault(" ".join([*head, p]), cat)
    objects = {tuple(w.split()): c for w, c in names.items()}
    object_index: dict[str, list] = {}
    for words, c in objects.items():
        object_index.setdefault(words[0], []).append((words, c))
    for entries in object_index.values():
        entries.sort(key=lambda e: -len(e[0]))
    idioms = {**{k: ("idiom", v) for k, v in lx.IDIOMS.items()},
              **{k: ("generic", v) for k, v in lx.GENERIC_TARGETS.items()}}
    verbs = {**{k: ("strong", v) for k, v in lx.ACTION_PHRASES.items()},
             **{k: ("weak", v) for k, v in lx.WEAK_VERBS.items()}}
    return {"idioms": _phrase_index(idioms), "objects": object_index,
            "verbs": _phrase_index(verbs), "relations": _phrase_index(lx.RELATION_PHRASES),
            "unsupported": _phrase_index(dict.fromkeys(lx.UNSUPPORTED_RELATIONS, True)),
            "breaks": _phrase_index(dict.fromkeys(lx.CLAUSE_BREAKS, True)),
            "negations": _phrase_index(dict.fromkeys(lx.NEGATIONS, True)),
            "filler": _phrase_index(dict.fromkeys(lx.FILLER, True))}


def canonical_category(name: str) -> str:
    """The lexicon's class for a class name ("couch" → ``sofa``, "refrigerator" →
    ``fridge``, "night stand" → ``nightstand``); the folded name itself when it is none."""
    words = tuple(tokenize(str(name).replace("_", " ")))
    for entries in indexes()["objects"].get(words[0] if words else "", ()):
        if entries[0] == words:
            return entries[1]
    return " ".join(words)


def spans(words, index, free) -> list[tuple[int, int, object]]:
    """Non-overlapping ``(start, end, value)`` matches of ``index``'s phrases in ``words``
    over positions where ``free`` is True, left to right, longest first."""
    out, i, n = [], 0, len(words)
    while i < n:
        hit = None
        if free[i]:
            for phrase, value in index.get(words[i], ()):
                j = i + len(phrase)
                if j <= n and tuple(words[i:j]) == phrase and all(free[i:j]):
                    hit = (i, j, value)
                    break
        if hit:
            out.append(hit)
            i = hit[1]
        else:
            i += 1
    return out
