"""Free phrasing read with word lists (jaxmotion.grounding.phrasing): a table of the ways people
write instructions -> (action, target class, relation, anchors), the synthetic templates read
the same way as their own parser reads them, and the lexicon's coverage."""

from __future__ import annotations

import numpy as np
import pytest

from jaxmotion.grounding import lexicon as lx
from jaxmotion.grounding.phrasing import canonical_category, read_phrasing, tokenize

# text -> (action, target class, relation, anchor classes)
PHRASINGS = {
    # synonyms and paraphrases of the four actions
    "plop down onto the couch": ("sit", "sofa", None, ()),
    "take a seat on the stool beside the cabinet": ("sit", "stool", "closest", ("cabinet",)),
    "park yourself on the armchair": ("sit", "armchair", None, ()),
    "perch on the bar stool": ("sit", "stool", None, ()),
    "settle into the recliner": ("sit", "armchair", None, ()),
    "have a seat on the settee": ("sit", "sofa", None, ()),
    "stretch out on the sofa": ("lie", "sofa", None, ()),
    "have a nap on the bed": ("lie", "bed", None, ()),
    "take a snooze on the couch": ("lie", "sofa", None, ()),
    "curl up on the mattress": ("lie", "bed", None, ()),
    "go to bed": ("lie", "bed", None, ()),
    "crash on the couch": ("lie", "sofa", None, ()),
    "rest on the bed": ("lie", "bed", None, ()),
    "relax on the couch": ("sit", "sofa", None, ()),
    "get up from the chair": ("stand_up", "chair", None, ()),
    "get out of bed": ("stand_up", "bed", None, ()),
    "rise from the toilet": ("stand_up", "toilet", None, ()),
    "leave the armchair": ("stand_up", "armchair", None, ()),
    "hop off the stool": ("stand_up", "stool", None, ()),
    "head over to the fridge": ("walk", "fridge", None, ()),
    "make your way to the window": ("walk", "window", None, ()),
    "stroll over to the bookcase": ("walk", "bookshelf", None, ()),
    "wander to the cupboard": ("walk", "cabinet", None, ()),
    "approach the telly": ("walk", "tv", None, ()),
    "go stand by the door": ("walk", "door", None, ()),
    "mosey over to the wardrobe": ("walk", "cabinet", None, ()),  # unknown verb + "to"
    # politeness, filler, adverbs, third person, several clauses, negation
    "Could you please slowly sit down on the chair?": ("sit", "chair", None, ()),
    "I'd like you to walk over to the sink, please.": ("walk", "sink", None, ()),
    "Would you mind lying down on the bed for a while": ("lie", "bed", None, ()),
    "go ahead and carefully get up off the sofa": ("stand_up", "sofa", None, ()),
    "A person walks over and sits down on the chair next to the table.":
        ("sit", "chair", "closest", ("table",)),
    "walk to the bed and then lie down": ("lie", "bed", None, ()),
    "the armchair: sit on it": ("sit", "armchair", None, ()),
    "don't sit, just walk to the chair": ("walk", "chair", None, ()),
    "rather than sitting, lie down on the sofa": ("lie", "sofa", None, ()),
    "SIT ON THE CHAIR!!!": ("sit", "chair", None, ()),
    "ｓｉｔ ｏｎ ｔｈｅ ｃｈａｉｒ": ("sit", "chair", None, ()),
    "sít on the cháir": ("sit", "chair", None, ()),
    # relation words beyond the templates
    "sit on the chair by the window": ("sit", "chair", "closest", ("window",)),
    "walk to the lamp near the bed": ("walk", "lamp", "closest", ("bed",)),
    "go to the nearest chair to the door": ("walk", "chair", "closest", ("door",)),
    "sit on the stool in front of the fridge": ("sit", "stool", "closest", ("fridge",)),
    "sit on the chair across from the tv": ("sit", "chair", "closest", ("tv",)),
    "walk to the chair opposite the sofa": ("walk", "chair", "closest", ("sofa",)),
    "head to the armchair that is right next to the bookshelf":
        ("walk", "armchair", "closest", ("bookshelf",)),
    "walk to the chair that is far away from the bed": ("walk", "chair", "farthest", ("bed",)),
    "walk to the table in between the couch and the bed":
        ("walk", "table", "between", ("sofa", "bed")),
    "walk to the table with the lamp on it": ("walk", "table", "supporting", ("lamp",)),
    "walk to the lamp sitting on the nightstand": ("walk", "lamp", "on", ("nightstand",)),
    "go to the picture hanging over the sofa": ("walk", "picture", "above", ("sofa",)),
    "walk to the cabinet under the tv": ("walk", "cabinet", "below", ("tv",)),
    "sit on the desk chair": ("sit", "chair", None, ()),  # "desk chair" is a chair
    "walk to the chair on the left": ("walk", "chair", None, ()),  # no such relation
    "walk to the nearest chair": ("walk", "chair", None, ()),  # nearest to nothing named
    # "sit at the desk": the seat at it
    "sit at the desk": ("sit", "desk", None, ()),
    "take a seat at the dining table": ("sit", "table", None, ()),
    "get up from the desk": ("stand_up", "desk", None, ()),
    "sit by the bed": ("sit", "bed", None, ()),
    "lie down by the window": ("lie", "window", None, ()),
    # a class name used as a verb ("sink", "seat", "bed"), and still a name after an article
    "sink down onto the loveseat": ("sit", "sofa", None, ()),
    "seat yourself on the bench": ("sit", "sofa", None, ()),
    "bed down on the couch for the night": ("lie", "sofa", None, ()),
    "wash your hands at the sink by the mirror": (None, "sink", "closest", ("mirror",)),
    "go over to the sink in the corner": ("walk", "sink", None, ()),
    "sit on the leather armchair in the corner": ("sit", "armchair", None, ()),
    # the object of another clause ("you are on the X by the Y; get up": the X)
    "you are seated on the stool by the door; get up": ("stand_up", "stool", "closest",
                                                        ("door",)),
    "stand up and walk away from the armchair near the lamp":
        ("stand_up", "armchair", "closest", ("lamp",)),
    "grab the stool near the sink and sit down": ("sit", "stool", "closest", ("sink",)),
    # where you are is not a request; a weak verb joins the action before it
    "you're sitting on the stool by the window, please get up":
        ("stand_up", "stool", "closest", ("window",)),
    "lie down and unwind on the couch": ("lie", "sofa", None, ()),
    "please be seated on the bench": ("sit", "sofa", None, ()),
    # the preposition before a seat says the way the body goes
    "scramble out of the recliner": ("stand_up", "armchair", None, ()),
    "jump down off the bar stool": ("stand_up", "stool", None, ()),
    "stand yourself up out of the sofa": ("stand_up", "sofa", None, ()),
    "spring up onto the ottoman": ("sit", "stool", None, ()),
    "plunk yourself onto the chair": ("sit", "chair", None, ()),
    "walk away from the chair": ("walk", "chair", None, ()),  # walking, not getting up
    # no action of the four, or no object
    "dance around": (None, None, None, ()),
    "kick the chair": (None, "chair", None, ()),
    "sit down": ("sit", None, None, ()),
    "find somewhere to sit": ("sit", None, None, ()),
}
SEAT_AT = {"sit at the desk", "take a seat at the dining table", "get up from the desk",
           "sit by the bed", "lie down by the window"}


@pytest.mark.parametrize("text", list(PHRASINGS))
def test_phrasing_table(text):
    r = read_phrasing(text)
    assert (r.action, r.target, r.relation, r.anchors) == PHRASINGS[text], r
    assert r.seat_at == (text in SEAT_AT), r


def test_what_the_reader_says_it_guessed_or_ignored():
    assert read_phrasing("sit on the chair across from the tv").side == "front"
    assert read_phrasing("sit behind the desk").side == "back"
    assert any("negated" in n for n in read_phrasing("don't sit, walk to the chair").notes)
    assert any("not a relation" in n for n in read_phrasing("walk to the chair on the left").notes)
    notes = read_phrasing("walk to the nearest chair").notes
    assert any("nothing to be nearest" in n for n in notes)
    assert read_phrasing("get up from the chair and walk to the door").several
    assert not read_phrasing("walk to the bed and lie down").several  # one motion
    assert read_phrasing("have a nap on the bed").action_words == "have a nap"
    assert read_phrasing("rest on the bed").action_how == "object"
    assert read_phrasing("mosey over to the door").action_how == "destination"
    assert read_phrasing("sit on the big beanbag thing").object_phrase == "beanbag thing"
    assert read_phrasing("sit on the chairman").object_phrase == "chairman"  # not a chair
    # the room itself, or a kind of room, is no object to find by meaning
    for text in ("dance around the bathroom", "walk around the kitchen",
                 "sit down in the living room", "wander through the hallway"):
        assert read_phrasing(text).object_phrase == "", text
    assert read_phrasing("sit on the kitchen beanbag").object_phrase == "kitchen beanbag"
    assert "it" in read_phrasing("could you kick the chair").query.split()
    assert "could" not in read_phrasing("could you kick the chair").query


def test_templates_read_as_their_parser_reads_them():
    """Every synthetic instruction (600, from 200 rooms) is read as the generator wrote it:
    the free-phrasing reader is a superset of the template grammar."""
    from jaxmotion.scene.graph import SceneGraph
    from jaxmotion.scene.instructions import sample_task
    from jaxmotion.scene.rooms import sample_room

    rng = np.random.default_rng(1)
    for seed in range(200):
        room = sample_room(seed)
        g = SceneGraph(room)
        for _ in range(3):
            text, info = sample_task(room, rng, graph=g)
            r = read_phrasing(text)
            want = (info["action"], info["target_class"], info["relation"],
                    tuple(info["anchor_classes"]))
            assert (r.action, r.target, r.relation, r.anchors) == want, text
            assert not r.seat_at, text


def test_lexicon_covers_the_world_and_the_graph():
    from jaxmotion.grounding.objects import object_table  # noqa: F401 - the NYU40 names
    from jaxmotion.scene.furniture import BUILDERS
    from jaxmotion.scene.graph import RELATIONS
    from jaxmotion.scene.instructions import ACTIONS, WORDS

    for cat in BUILDERS:  # every class of the synthetic world is its own canonical name
        assert canonical_category(cat) == cat, cat
    for cat, words in WORDS.items():  # and the generator's synonyms read as it
        assert {canonical_category(w) for w in words} == {cat}, cat
    assert canonical_category("refrigerator") == "fridge"
    assert canonical_category("Night_Stand") == "nightstand"
    assert canonical_category("otherfurniture") == "otherfurniture"
    assert set(lx.RELATION_PHRASES.values()) == set(RELATIONS)
    assert set(lx.ACTION_PHRASES.values()) == set(ACTIONS) == set(lx.ACTION_PROTOTYPES)
    assert set(lx.ANCHOR_SIDES) <= set(lx.RELATION_PHRASES)
    assert set(lx.SUPERLATIVES.values()) <= set(RELATIONS)


def test_tokenize_folds_unicode_and_contractions():
    assert tokenize("Don't  SIT… on the Café’s chair!") == [
        "do", "not", "sit", "|", "on", "the", "cafe", "s", "chair", "|"]
    assert tokenize("ｓｉｔ") == ["sit"]
    assert tokenize("I'd like you to") == ["i", "would", "like", "you", "to"]
    assert tokenize("椅子") == [] and tokenize("") == []
    assert len(tokenize("chair " * 1000)) == 400


def test_one_motion_told_in_two_verbs_is_not_a_story():
    from jaxmotion.planning.steps import is_story

    for text in ("lie down and unwind on the couch", "you are seated on the armchair; get up",
                 "you've been sitting on the stool for ages, stand up"):
        assert not is_story(text), text
    assert is_story("get up from the chair and lie down on the bed")
