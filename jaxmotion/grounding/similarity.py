"""The sentence encoder's similarity, where the word lists run out.

:class:`TextSimilarity` embeds short phrases with the text encoder every model here reads
(all-MiniLM-L6-v2, :data:`jaxmotion.constants.TEXT_ENCODER`), loaded only when a phrase is
not in its on-disk cache. :func:`guess_action` compares a verb phrase with the prototypes of
the four actions (:data:`jaxmotion.grounding.lexicon.ACTION_PROTOTYPES`) and
:func:`guess_category` an object's words with the room's class names; each answers only
above a cosine threshold and a margin over the runner-up, chosen on MiniLM's scores of
phrasings outside the word lists (``tests/test_grounding_text.py``): "have a nap on it" is
0.84 from "take a nap" but "dance around" only 0.51 from "walk there", and "mattress" is
0.82 from "bed" but "unicorn" at most 0.44 from any class.

Cost: the action prototypes and the class names ("a chair", NYU40's and the synthetic
world's classes) are shipped embedded (:data:`PHRASE_TABLE`, used when the installed encoder's
weights are the ones it was computed with: :func:`jaxmotion.text.minilm.weights_fingerprint`;
``python scripts/make_phrase_table.py`` writes it again). Another phrase not seen before
costs one pass of the encoder on the host (:func:`jaxmotion.text.minilm.encode_one`, tens of
milliseconds); more than :data:`ONE_BY_ONE` at once build the batch encoder (about 5 s). Seen
phrases cost a cache read.
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np

from jaxmotion.constants import TEXT_ENCODER
from jaxmotion.grounding.lexicon import ACTION_PROTOTYPES

__all__ = ["ACTION_MARGIN", "ACTION_THRESHOLD", "CATEGORY_MARGIN", "CATEGORY_THRESHOLD",
           "ONE_BY_ONE", "PHRASE_TABLE", "TextSimilarity", "category_phrase", "guess_action",
           "guess_category", "shipped_embeddings", "table_phrases", "write_phrase_table"]

ACTION_THRESHOLD, ACTION_MARGIN = 0.6, 0.1
CATEGORY_THRESHOLD, CATEGORY_MARGIN = 0.6, 0.04
#: New phrases up to this many are embedded one by one on the host; more build the batch
#: sentence encoder once and go as a batch (:meth:`TextSimilarity.encode`).
ONE_BY_ONE = 16
#: The shipped embeddings of :func:`table_phrases` (``phrases``, ``embeddings`` [P, D] as the
#: encoder gives them, ``weights``: the encoder's :func:`~jaxmotion.text.minilm
#: .weights_fingerprint`).
PHRASE_TABLE = Path(__file__).resolve().parent / "data" / "phrase_embeddings.npz"


def category_phrase(category: str) -> str:
    """How a class name is compared: "a coffee table" for ``coffee_table``."""
    return f"a {category.replace('_', ' ')}"


def table_phrases() -> list[str]:
    """The phrases :data:`PHRASE_TABLE` holds: every action prototype, and
    :func:`category_phrase` of every class the reader, the synthetic world and NYU40 name."""
    from jaxmotion.grounding.lexicon import CATEGORY_WORDS
    from jaxmotion.scene.furniture import CATEGORY_IDS
    from jaxmotion.scene.scans import NYU40_CLASSES

    classes = (*CATEGORY_WORDS, *CATEGORY_IDS, *NYU40_CLASSES)
    phrases = [p for ps in ACTION_PROTOTYPES.values() for p in ps]
    return list(dict.fromkeys([*phrases, *(category_phrase(c) for c in classes)]))


def write_phrase_table(path: str | Path = PHRASE_TABLE) -> Path:
    """Embed :func:`table_phrases` with the installed encoder and write them (atomically) to
    ``path`` with the weights' fingerprint."""
    from jaxmotion._atomic import atomic_open
    from jaxmotion.text.condition import text_encoder
    from jaxmotion.text.minilm import weights_fingerprint

    phrases = table_phrases()
    emb = np.asarray(text_encoder()(phrases), np.float32)
    path = Path(path)
    with atomic_open(path) as f:
        np.savez(f, phrases=np.array(phrases), embeddings=emb,
                 weights=np.array(weights_fingerprint()))
    return path


@functools.lru_cache(maxsize=1)
def shipped_embeddings() -> dict[str, np.ndarray]:
    """:data:`PHRASE_TABLE` as ``{phrase: embedding}``, or ``{}`` when the installed encoder's
    weights are not the ones it was computed with (or the file is missing)."""
    from jaxmotion.text.minilm import weights_fingerprint

    try:
        with np.load(PHRASE_TABLE) as z:
            if str(z["weights"]) != weights_fingerprint():
                return {}
            return dict(zip(z["phrases"].tolist(), np.asarray(z["embeddings"], np.float32)))
    except (OSError, KeyError, ValueError):
        return {}


class TextSimilarity:
    """Unit-norm embeddings of short phrases, and the nearest of several options by cosine.

    Args:
      cache_dir: a folder for the embeddings (an
        :class:`~jaxmotion.text.EmbeddingCache`, keyed apart from the models' text
        conditions); None keeps them in memory only.
      embed: ``list[str] -> [B, D]`` used instead of the sentence encoder (another encoder,
        or a test's stand-in); its rows are normalised here.
    """

    def __init__(self, cache_dir: str | Path | None = None, *,
                 embed: Callable[[list[str]], np.ndarray] | None = None):
        self.cache_dir = None if cache_dir is None else Path(cache_dir)
        self.custom = embed
        self.memory: dict[str, np.ndarray] = {}

    def embed(self, texts: Sequence[str]) -> np.ndarray:
        """``[len(texts), D]`` unit-norm float32 embeddings."""
        texts = [str(t) for t in texts]
        missing = [t for t in dict.fromkeys(texts) if t not in self.memory]
        if missing:
            new = np.asarray(self.custom(missing) if self.custom is not None
                             else self.encode(missing), np.float32)
            new = new / np.maximum(np.linalg.norm(new, axis=-1, keepdims=True), 1e-12)
            self.memory.update(zip(missing, new))
        return np.stack([self.memory[t] for t in texts]) if texts else np.zeros((0, 1),
                                                                                 np.float32)

    def encode(self, texts: list[str]) -> np.ndarray:
        """The sentence encoder's embeddings of ``texts`` through the on-disk cache: up to
        :data:`ONE_BY_ONE` new phrases go one by one through the encoder on the host
        (:func:`jaxmotion.text.minilm.encode_one`, ~0.05 s a phrase), more build the batch
        encoder (~2 s) and go as a batch."""
        from jaxmotion.text import EmbeddingCache, cache_key
        from jaxmotion.text.condition import text_encoder
        from jaxmotion.text.minilm import encode_one, weights_version

        def fresh(phrases):
            if len(phrases) <= ONE_BY_ONE:
                return [encode_one(t) for t in phrases]
            return list(text_encoder()(phrases))

        if self.cache_dir is None:
            return np.stack(fresh(texts)) if texts else np.zeros((0, 1), np.float32)
        keys = [cache_key(f"{TEXT_ENCODER}:grounding", weights_version(), t) for t in texts]
        cache = EmbeddingCache.shared(self.cache_dir)
        found = cache.get(keys)
        todo = [(k, t) for k, t in zip(keys, texts) if k not in found]
        shipped = shipped_embeddings() if todo else {}
        found.update((k, shipped[t]) for k, t in todo if t in shipped)
        todo = [(k, t) for k, t in todo if k not in found]
        if todo:
            new = fresh([t for _, t in todo])
            try:
                cache.put([k for k, _ in todo], np.stack(new))
            except OSError:  # a read-only cache: the values are just not kept
                pass
            found.update(zip([k for k, _ in todo], new))
        return np.stack([found[k] for k in keys])

    def nearest(self, query: str, options: dict[str, Sequence[str]]) -> tuple[str, float, float]:
        """The option (``{label: [phrases]}``) one of whose phrases is nearest ``query`` by
        cosine: ``(label, its cosine, the runner-up label's cosine)``."""
        labels = [k for k, ps in options.items() for _ in ps]
        phrases = [p for ps in options.values() for p in ps]
        sims = self.embed(phrases) @ self.embed([query])[0]
        best: dict[str, float] = {}
        for label, s in zip(labels, sims.tolist()):
            best[label] = max(best.get(label, -1.0), s)
        ranked = sorted(best.items(), key=lambda kv: -kv[1])
        second = ranked[1][1] if len(ranked) > 1 else -1.0
        return ranked[0][0], ranked[0][1], second


def guess_action(similarity: TextSimilarity, query: str) -> tuple[str | None, float]:
    """The action whose prototypes are nearest ``query`` (a verb phrase with its objects as
    "it": "snooze on it"), or None below :data:`ACTION_THRESHOLD` or within
    :data:`ACTION_MARGIN` of another action; and the best cosine."""
    if not query.strip():
        return None, 0.0
    label, best, second = similarity.nearest(query, ACTION_PROTOTYPES)
    ok = best >= ACTION_THRESHOLD and best - second >= ACTION_MARGIN
    return (label if ok else None), best


def guess_category(similarity: TextSimilarity, phrase: str,
                   categories: Sequence[str]) -> tuple[str | None, float]:
    """The class of ``categories`` whose name is nearest ``phrase`` ("credenza" among
    "cabinet", "bed", ...; compared as "a <phrase>" / "a <class>"), or None below
    :data:`CATEGORY_THRESHOLD` or within :data:`CATEGORY_MARGIN` of another; and the best
    cosine."""
    categories = list(dict.fromkeys(categories))
    if not phrase.strip() or not categories:
        return None, 0.0
    label, best, second = similarity.nearest(
        f"a {phrase}", {c: (category_phrase(c),) for c in categories})
    ok = best >= CATEGORY_THRESHOLD and best - second >= CATEGORY_MARGIN
    return (label if ok else None), best
