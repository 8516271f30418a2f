"""A story told in words: the text split into steps, each grounded to an object id of the room
(ids, classes, relations, "it", a bare "sit" after a walk), and ``generate`` telling a text of
several steps as a story."""

from __future__ import annotations

import pytest

from jaxmotion.errors import GenerateError
from jaxmotion.planning.steps import is_story, plan_from_text, split_steps
from jaxmotion.scene.demo import demo_scene


@pytest.fixture(scope="module")
def room():  # door 0, windows 1-2, table 3, chair 4, cabinet 5, armchair 6, stools 7-8, fridge 9
    return demo_scene()


def plan(room, text):
    steps, notes, _ = plan_from_text(room, text)
    return [(s["action"], s["object"]) for s in steps], notes


def gap(a, b):
    """Brute-force horizontal gap between two objects' boxes (0 when they touch)."""
    d = [max(0.0, a["bbox_min"][k] - b["bbox_max"][k], b["bbox_min"][k] - a["bbox_max"][k])
         for k in (0, 1)]
    return (d[0] ** 2 + d[1] ** 2) ** 0.5


def test_split_steps_cuts_at_each_action():
    assert split_steps("stand up from chair 3, walk to table 4 and sit") == [
        ("stand_up", "stand up from chair 3"), ("walk", "walk to table 4"), ("sit", "sit")]
    assert split_steps("Could you get up from the sofa, then lie down on the bed?") == [
        ("stand_up", "get up from the sofa"), ("lie", "lie down on the bed")]
    assert split_steps("") == [] and split_steps("???") == []


def test_a_walk_to_several_places_is_a_step_per_place(room):
    assert split_steps("walk to the table and then to the fridge") == [
        ("walk", "walk to the table"), ("walk", "walk to the fridge")]
    assert split_steps("go to the table then to the door and then to the fridge") == [
        ("walk", "go to the table"), ("walk", "walk to the door"), ("walk", "walk to the fridge")]
    assert is_story("walk to the table and then to the fridge")
    # a relation is not a second place
    assert split_steps("walk to the chair next to the table") == [
        ("walk", "walk to the chair next to the table")]
    assert not is_story("walk to the chair next to the table")
    assert plan(room, "walk to the table and then to the fridge")[0] == [("walk", 3), ("walk", 9)]


def test_one_instruction_is_not_a_story():
    for text in ("sit on the chair next to the table", "walk to the bed, then lie down",
                 "a person walks over and sits down", "Go ahead and have a seat on the stool",
                 "walk to the chair and sit on it", "", "\u2603" * 50):
        assert not is_story(text), text
    assert is_story("get up from the chair and walk to the door")
    assert is_story("stand up from chair 4, walk to the fridge and sit on the armchair")


def test_steps_are_grounded_to_ids(room):
    assert plan(room, "stand up from chair 4, walk to the fridge and sit on the armchair")[0] == [
        ("stand_up", 4), ("walk", 9), ("sit", 6)]
    # a bare "sit" after a walk to a table: the seat nearest it
    steps, notes = plan(room, "stand up from chair 4, walk to table 3 and sit")
    assert steps == [("stand_up", 4), ("walk", 3), ("sit", 4)]
    assert "nearest the table 3" in notes[2]
    # "it": the previous step's object; of two stools, the one nearest the fridge
    steps, notes = plan(room, "get up from the armchair, go to the fridge, then sit on the "
                              "stool next to it")
    fridge = next(o for o in room.objects if o["id"] == 9)
    stools = [o for o in room.objects if o["category"] == "stool"]
    near = min(stools, key=lambda o: gap(o, fridge))
    assert steps == [("stand_up", 6), ("walk", 9), ("sit", near["id"])]
    assert "of 2 that fit" in notes[2]
    assert plan(room, "sit on chair 4 and then stand up from it")[0] == [("sit", 4),
                                                                           ("stand_up", 4)]
    # the choices the text leaves open are returned as warnings, apart from the notes
    assert plan_from_text(room, "stand up from chair 4, walk to the fridge and sit on the "
                                "armchair")[2] == []
    steps, _, warns = plan_from_text(room, "sit on the stool, then walk to the fridge")
    assert len(warns) == 1 and "2 objects fit" in warns[0] and "name one by id" in warns[0]
    assert str(steps[0]["object"]) in warns[0]


def test_steps_that_cannot_be_grounded_are_refused(room):
    with pytest.raises(GenerateError, match="step 2 .*no beds or sofas to lie on"):
        plan_from_text(room, "stand up from chair 4 and lie down on the bed")
    with pytest.raises(GenerateError, match=r"step 2 .*cannot sit on table 3"):
        plan_from_text(room, "stand up from chair 4 and sit on object 3")
    with pytest.raises(GenerateError, match=r"step 2 \('walk to the bed'\): .*bed"):
        plan_from_text(room, "stand up from chair 4, walk to the bed and sit on the stool")
    with pytest.raises(GenerateError, match="no action read"):
        plan_from_text(room, "hello there")


def test_generate_tells_a_story_text(room, monkeypatch):
    """``generate`` hands a text of several steps to the story teller with the grounded plan
    (checked here without sampling), and refuses ``object_id`` with it."""
    import jaxmotion
    from jaxmotion.planning import story

    seen = {}

    def fake(scene, steps, opts, progress=False, text=None):
        seen.update(steps=steps, text=text)
        return "told"

    monkeypatch.setattr(story, "story_generation", fake)
    text = "stand up from chair 4, walk to the fridge and sit on the armchair"
    assert jaxmotion.generate(room, text) == "told"
    assert seen["text"] == text and [s["object"] for s in seen["steps"]] == [4, 9, 6]
    with pytest.warns(UserWarning, match="one motion: samples=2 is not used"):
        jaxmotion.generate(room, text, samples=2)
    with pytest.raises(GenerateError, match="leave out --object"):
        jaxmotion.generate(room, text, object_id=4)
