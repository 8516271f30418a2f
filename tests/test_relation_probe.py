"""The relation probe: canonical rewrites of closest / farthest instructions, and runs."""

import math

import pytest

import jaxmotion.eval.relation_probe as rp
from jaxmotion.eval.relation_probe import canonical_pair, main, relation_probe


@pytest.mark.parametrize("text, want", [
    ("Have a seat on the chair furthest away from the fridge.",
     ("sit on the chair farthest from the fridge", "sit on the chair closest to the fridge")),
    ("please get up off the stool nearest the window",
     ("stand up from the stool closest to the window",
      "stand up from the stool farthest from the window")),
    ("Walk over to the couch right by the tv", ("walk to the sofa closest to the tv",
                                                "walk to the sofa farthest from the tv")),
    # phrasings of `synth --phrasing rich`, read as `generate` reads them
    ("Could you take a seat on the stool that is nearest to the cabinet please",
     ("sit on the stool closest to the cabinet", "sit on the stool farthest from the cabinet")),
    ("plop down on the armchair furthest away from the door",
     ("sit on the armchair farthest from the door", "sit on the armchair closest to the door")),
])
def test_canonical_pair(text, want):
    assert canonical_pair(text) == want


@pytest.mark.parametrize("text", [
    "sit on the chair", "walk to the lamp between the sofa and the tv",
    "lie on the bed with the pillow on it", "dance wildly",
    "sit at the desk closest to the window",  # the seat at the desk: the relation is the desk's
])
def test_other_instructions_are_not_probed(text):
    assert canonical_pair(text) is None


def test_probe_runs_on_tiny_checkpoints(tiny_runs, capsys):
    root, out = tiny_runs
    r = relation_probe(out["data"], root / "adm", root / "amdm", splits=("train", "test"),
                       num_cases=24, steps=2, batch_size=4)
    assert r["cases"] >= 1 and r["steps"] == 2  # the tiny dataset has one such case
    for k in ("hit_original", "hit_true", "hit_opposite", "hit_both"):
        assert 0.0 <= r[k] <= 1.0
    assert r["hit_both"] <= min(r["hit_true"], r["hit_opposite"])
    assert 0 <= r["anchor_visible_cases"] <= r["cases"]
    assert main(["--data", str(out["data"]), "--adm", str(root / "adm"), "--amdm",
                 str(root / "amdm"), "--splits", "test", "--cases", "4", "--steps", "1"]) == 0
    assert "canonical, opposite relation" in capsys.readouterr().out


def test_probe_without_qualifying_cases(tiny_runs, monkeypatch):
    root, out = tiny_runs
    monkeypatch.setattr(rp, "canonical_pair", lambda text: None)
    r = relation_probe(out["data"], root / "adm", root / "amdm", splits=("test",),
                       num_cases=4, steps=1)
    assert r["cases"] == 0
    assert all(math.isnan(r[k]) for k in ("hit_original", "hit_true", "hit_opposite", "hit_both"))


def test_anchor_visible_counts_the_anchor_class_points_in_the_crop():
    import numpy as np

    objects = [{"id": 1, "category": "chair"}, {"id": 2, "category": "chair"},
               {"id": 3, "category": "window"}, {"id": 4, "category": "door"}]
    case = {"text": "sit on the chair closest to the window", "objects": objects,
            "instance": np.array([1] * 40 + [2] * 30 + [4] * 50 + [3] * 4)}
    assert not rp.anchor_visible(case)  # 4 window points: not enough
    assert rp.anchor_visible(case, min_points=4)
    case["instance"] = np.concatenate([case["instance"], [3]])
    assert rp.anchor_visible(case)
    assert not rp.anchor_visible({**case, "text": "sit on the chair closest to the sofa"})
