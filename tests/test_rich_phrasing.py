"""The rich instruction phrasing (sample_task(..., phrasing="rich"), jaxmotion synth --phrasing
rich): the default texts unchanged, the size of the space, every rich text read back by the
free-phrasing reader to its action and target, and the description set kept out of it."""

from __future__ import annotations

import json
import re

import numpy as np
import pytest

from jaxmotion.cli import main
from jaxmotion.eval.descriptions import load_descriptions
from jaxmotion.grounding import ground_candidates, read_instruction
from jaxmotion.grounding.phrasing import canonical_category, read_phrasing
from jaxmotion.scene import rich_phrasing as rp
from jaxmotion.scene.graph import SceneGraph
from jaxmotion.scene.instructions import (
    ACTIONS,
    PHRASINGS,
    VERBS,
    phrasing_space,
    rich_templates,
    sample_instruction,
    sample_task,
    seat_at_anchors,
)
from jaxmotion.scene.rooms import sample_room


def _room(seed, i=None):
    return sample_room(np.random.default_rng(seed if i is None else np.random.SeedSequence(
        [seed, i])))


def _norm(text):
    return " " + " ".join(re.sub(r"[^a-z]+", " ", text.lower()).split()) + " "


# texts of sample_task(room, rng) with default arguments before the phrasing option existed
PINNED = ["Stand up from the stool", "please make your way to the bookshelf closest to the lamp",
          "please take a seat on the toilet.", "go sit on the toilet",
          "Get up from the chair nearest the cabinet",
          "Please approach the chair which is closest to the sink."]


def test_default_texts_are_unchanged():
    for s, want in enumerate(PINNED):
        room = _room(s)
        assert sample_task(room, np.random.default_rng(100 + s))[0] == want
        assert sample_task(room, np.random.default_rng(100 + s), phrasing="default")[0] == want


def test_unknown_phrasing_is_refused():
    with pytest.raises(ValueError, match="phrasing"):
        sample_task(_room(0), 0, phrasing="fancy")
    assert PHRASINGS == ("default", "rich")


def test_space_holds_a_thousand_verb_phrases_and_hundreds_of_relation_phrasings():
    rich, default = phrasing_space("rich"), phrasing_space("default")
    assert rich["verb_phrases"] >= 1000
    assert all(n >= 1000 for n in rich["verb_phrases_by_action"].values())
    assert rich["relation_phrasings"] >= 300
    assert rich["verb_cores"] >= 90 and rich["object_words"] > default["object_words"]
    assert default["verb_phrases"] < 1000  # the option is what adds them
    templates = rich_templates()
    assert {"closest", "near", "farthest", "between", "on", "supporting", "above",
            "below"} <= set(templates)  # relations the scene graph checks, no other
    assert not any(w in t for ts in templates.values() for t in ts
                   for w in ("in front of", "across from", "behind", "left", "right of"))


def test_rich_object_words_read_as_their_class():
    for cat, words in rp.RICH_WORDS.items():
        assert all(canonical_category(w) == cat for w in words), cat


def test_every_rich_instruction_is_read_back_to_its_action_and_target():
    """50 rooms x 10: the reader generate uses (read_instruction + ground_candidates) gives
    the generated action and exactly the generated target."""
    bad, forms = [], set()
    for i in range(50):
        room = _room(77, i)
        g = SceneGraph(room.objects)
        for k in range(10):
            text, info = sample_task(room, np.random.default_rng([77, i, k]), graph=g,
                                     phrasing="rich")
            forms.add(info["template"].split("|")[2].split(":")[0])
            ins = read_instruction(text)
            ids = [int(o["id"]) for o in ground_candidates(room, ins).objects]
            if ins.action != info["action"] or ids != [info["target_id"]] or ins.reading.several:
                bad.append((text, info["action"], info["target_id"], ins.action, ids))
    assert not bad, bad
    assert forms == {"frame", "multi"}


def test_seat_at_forms_name_the_seat_at_the_desk_or_table():
    seen = 0
    for i in range(60):
        room = _room(78, i)
        g = SceneGraph(room.objects)
        for action in ("sit", "stand_up"):
            for t in g.ids:
                for a in seat_at_anchors(g, action, t):
                    seen += 1
                    for k in range(6):
                        text, info = sample_instruction(room, action, t, [i, t, k], graph=g,
                                                        phrasing="rich")
                        ins = read_instruction(text)
                        found = ground_candidates(room, ins)
                        assert ins.action == action and [o["id"] for o in found.objects] == [t]
                        if info["relation"] == "at":
                            assert info["anchor_ids"][0] in seat_at_anchors(g, action, t)
                            assert ins.reading.seat_at and found.how == "seat at", text
    assert seen >= 3


def test_determinism_per_seed():
    room = _room(5)
    one = [sample_task(room, np.random.default_rng([1, k]), phrasing="rich") for k in range(8)]
    two = [sample_task(room, np.random.default_rng([1, k]), phrasing="rich") for k in range(8)]
    assert one == two


ROWS, _ = load_descriptions()


def test_description_set_stays_out_of_the_rich_vocabulary():
    cores = {c for a in ACTIONS for c in (*VERBS[a], *rp.EXTRA_VERBS[a],
                                          *rp.SEAT_AT_VERBS.get(a, ()))}
    used = [(r["text"], c) for r in ROWS for c in sorted(cores) if f" {c} " in _norm(r["text"])]
    assert not used


def test_no_description_sentence_is_generated_verbatim():
    """Each description's own (action, target) in its room (data/unseen9001), 10 draws, and
    20 free draws per room: no generated text equals a description sentence."""
    want = {_norm(r["text"]) for r in ROWS}
    scenes = sorted({int(r["scene"].split("_")[1]) for r in ROWS})
    rooms = {i: _room(9001, i) for i in scenes}
    graphs = {i: SceneGraph(rooms[i].objects) for i in scenes}
    texts = set()
    for n, r in enumerate(ROWS):
        i = int(r["scene"].split("_")[1])
        for k in range(10):
            texts.add(sample_instruction(rooms[i], r["action"], r["target_id"], [n, k],
                                         graph=graphs[i], phrasing="rich")[0])
    for i in scenes:
        for k in range(20):
            texts.add(sample_task(rooms[i], [i, k], graph=graphs[i], phrasing="rich")[0])
    assert len(texts) > 2000
    assert not {_norm(t) for t in texts} & want


def test_reader_takes_why_dont_you_as_a_request():
    assert read_phrasing("Why don't you lie down on the sofa?").action == "lie"
    assert read_phrasing("why not walk to the door").action == "walk"
    r = read_phrasing("don't lie on the bed, sit on the chair")
    assert (r.action, r.target) == ("sit", "chair")
    r = read_phrasing("get off the toilet which is right next to the window")
    assert r.relation == "closest" and not r.notes  # "right" of "right next to" is no note


def test_synth_records_rich_phrasing_only_when_set(tmp_path):
    args = ["synth", "--scenes", "3", "--per-scene", "1", "--points", "500", "--no-stats"]
    assert main([*args, "--out", str(tmp_path / "d")]) == 0
    assert main([*args, "--out", str(tmp_path / "r"), "--phrasing", "rich"]) == 0
    default = json.loads((tmp_path / "d" / "manifest.json").read_text())["settings"]
    rich = json.loads((tmp_path / "r" / "manifest.json").read_text())["settings"]
    assert "phrasing" not in default and rich == {**default, "phrasing": "rich"}
    texts = {}
    for name in ("d", "r"):
        texts[name] = [str(np.load(f)["text"]) for f in sorted(
            (tmp_path / name / "samples").glob("*/*.npz"))]
    assert len(texts["r"]) == 3 and texts["d"] != texts["r"]
