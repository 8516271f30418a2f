"""The hand-written description set: out of the generator's vocabulary, and true of its rooms."""

from __future__ import annotations

import re

import numpy as np
import pytest

from jaxmotion.eval.descriptions import load_descriptions
from jaxmotion.scene.furniture import LIE_CATEGORIES, SEAT_CATEGORIES
from jaxmotion.scene.graph import Reference, SceneGraph
from jaxmotion.scene.instructions import ACTIONS, VERBS, WORDS
from jaxmotion.scene.rooms import sample_room

ROWS, _ = load_descriptions()
SEED = 9001  # data/unseen9001: jaxmotion synth --seed 9001


def _norm(text):
    return " " + " ".join(re.sub(r"[^a-z]+", " ", text.lower()).split()) + " "


def test_set_size_and_fields():
    assert len(ROWS) >= 200
    assert all(r["action"] in ACTIONS for r in ROWS)
    assert len({(r["scene"], r["target_id"], r["text"]) for r in ROWS}) == len(ROWS)
    assert len({r["text"] for r in ROWS}) >= 0.9 * len(ROWS)  # few repeated sentences
    counts = {a: sum(r["action"] == a for r in ROWS) for a in ACTIONS}
    assert min(counts.values()) >= 0.1 * len(ROWS), counts
    assert sum(r["same_class"] > 1 for r in ROWS) >= 0.3 * len(ROWS)  # relations matter


def test_no_verb_phrase_of_the_generator():
    phrases = [v for vs in VERBS.values() for v in vs]
    used = [(r["text"], v) for r in ROWS for v in phrases if f" {v} " in _norm(r["text"])]
    assert not used


@pytest.fixture(scope="module")
def graphs():
    ids = sorted({int(r["scene"].split("_")[1]) for r in ROWS})
    return {f"scene_{i:05d}": SceneGraph(sample_room(
        np.random.default_rng(np.random.SeedSequence([SEED, i]))).objects) for i in ids}


def test_targets_exist_with_the_class_the_text_names(graphs):
    for r in ROWS:
        g, t = graphs[r["scene"]], r["target_id"]
        assert t in g.ids, r
        cat = g.category(t)
        assert cat == r["category"], r
        assert g.count(cat) == r["same_class"], r
        assert f" {r['noun']} " in _norm(r["text"]), r
        if r["action"] in ("sit", "stand_up"):
            assert cat in SEAT_CATEGORIES, r
        if r["action"] == "lie":
            assert cat in LIE_CATEGORIES, r
        if r.get("seat_at"):  # "sit at the desk": the seat nearest one object of that class
            seats = [i for i in g.ids if g.category(i) in SEAT_CATEGORIES and
                     g.category(i) != "bed"]
            assert any(min(seats, key=lambda i, a=a: g.distance(i, a)) == t
                       for a in g.instances(r["noun"])), r
        else:
            assert r["noun"] in WORDS.get(cat, (cat,)), r


def test_relations_single_out_the_target(graphs):
    """Where the words use a relation, it picks exactly the target; where they use none, the
    target is the only one of its class (or the seat at the named object)."""
    for r in ROWS:
        g = graphs[r["scene"]]
        if r.get("relation"):
            ref = Reference(r["category"], r["relation"], tuple(r["anchors"]))
            assert g.resolve(ref) == frozenset([r["target_id"]]), r
        elif not r.get("seat_at"):
            assert g.count(r["category"]) == 1, r
