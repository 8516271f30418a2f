"""``jaxmotion eval --descriptions``: both phrasings on the same targets, at tiny size."""

from __future__ import annotations

import json

import numpy as np

from jaxmotion.eval.descriptions import (
    FAILURES,
    evaluate_descriptions,
    failure_class,
    format_markdown,
    summarize,
    template_text,
)


def _case(**kw):
    base = {"phrasing": "descriptions", "index": 0, "action": "sit", "category": "chair",
            "same_class": 2, "text": "x", "action_read": "sit", "class_read": "chair",
            "grounded": True, "judged": 1.0, "chosen_category": "chair"}
    return {**base, **kw}


def test_failure_classes_in_order():
    assert failure_class(_case()) == ""
    assert failure_class(_case(judged=0.0)) == "motion"
    assert failure_class(_case(error="boom", action_read=None)) == "error"
    assert failure_class(_case(action_read=None, pipeline="story")) == "several motions"
    assert failure_class(_case(action_read=None, grounded=False)) == "no action read"
    assert failure_class(_case(action_read="walk")) == "wrong action"
    assert failure_class(_case(grounded=False)) == "wrong instance"
    assert failure_class(_case(grounded=False, class_read=None, chosen_category="sofa")) == (
        "no class read")
    assert failure_class(_case(grounded=False, chosen_category="sofa")) == "wrong class"
    assert set(FAILURES) >= {failure_class(_case(judged=0.0))}


def test_summary_keeps_both_rows_on_the_same_targets():
    cases = [_case(index=0), _case(index=0, phrasing="templates", judged=0.0),
             _case(index=1, action="walk", same_class=1, grounded=False, failure="x"),
             _case(index=1, phrasing="templates", text=None),  # no template: out of both rows
             _case(index=2, action="lie", action_read="walk", failure="wrong action"),
             _case(index=2, phrasing="templates", action="lie", action_read="lie")]
    s = summarize(cases, recognized=False)
    assert s["excluded_no_template"] == 1
    d, t = s["descriptions"], s["templates"]
    assert d["all"]["grounded"]["n"] == t["all"]["grounded"]["n"] == 2
    assert d["all"]["action_read"]["mean"] == 0.5 and t["all"]["action_read"]["mean"] == 1.0
    assert d["all"]["judged"]["mean"] == 1.0 and t["all"]["judged"]["mean"] == 0.5
    assert set(d["by_action"]) == {"sit", "lie"} and "recognized" not in d["all"]


def _rows(data):
    """Descriptions written for two rooms of the tiny build, for objects alone of their class
    (seats for sit / stand up, anything to walk to)."""
    from jaxmotion.scene.demo import load_scene_arg
    from jaxmotion.scene.graph import SceneGraph

    rows = []
    for f in sorted((data / "scenes").glob("*.npz"))[:2]:
        g = SceneGraph(load_scene_arg(str(f)).objects)
        alone = [i for i in g.ids if g.count(g.category(i)) == 1
                 and g.category(i) not in ("door", "window", "picture")]
        seats = [i for i in alone if g.category(i) in ("chair", "armchair", "sofa", "stool")]
        if seats:
            rows.append({"scene": f.stem, "target_id": seats[0], "action": "sit",
                         "text": f"Could you plonk yourself down on the {g.category(seats[0])}?"})
        if alone:
            rows.append({"scene": f.stem, "target_id": alone[-1], "action": "walk",
                         "text": f"Wander over by the {g.category(alone[-1])}, please."})
    return rows[:2]


class _Recognizer:
    """Says every motion walks."""

    def describe(self):
        return "stub"

    def predict(self, joints, mask=None):
        return np.zeros(len(joints), np.int32)  # walk


def test_descriptions_eval_tiny(tiny_runs, tmp_path, monkeypatch):
    import functools

    import jaxmotion.eval.descriptions as mod
    from jaxmotion.cli import main

    root, out = tiny_runs
    rows = _rows(out["data"])
    assert rows
    fast = {"checkpoints": (str(root / "adm"), str(root / "amdm")), "pipeline": "affordance",
            "steps": 2, "adm_steps": 2}
    rep = evaluate_descriptions(out["data"], rows, recognizer=_Recognizer(), seed=3,
                                progress=False, **fast)
    cases = rep["cases"]
    assert len(cases) == 2 * len(rows)
    for d, t in zip(cases[::2], cases[1::2]):  # same target and seed, the two phrasings
        assert (d["phrasing"], t["phrasing"]) == ("descriptions", "templates")
        assert (d["target_id"], d["seed"], d["scene"]) == (t["target_id"], t["seed"], t["scene"])
        assert t["text"] and t["text"] != d["text"]
        assert 0.0 <= d["judged"] <= 1.0 and d["recognized"] == float(d["action"] == "walk")
        assert d["failure"] in ("", *FAILURES) and "failure" not in t
    s = rep["summary"]
    for phrasing in ("descriptions", "templates"):
        assert s[phrasing]["all"]["grounded"]["n"] == len(rows)
        assert set(s[phrasing]["all"]) == {"grounded", "action_read", "judged", "recognized"}
    md = format_markdown(rep)
    assert "| descriptions | all |" in md and "| templates | all |" in md
    # the command line, on a file (with the programs compiled above: 2 steps per stage)
    monkeypatch.setattr(mod, "evaluate_descriptions", functools.partial(
        evaluate_descriptions, steps=2, adm_steps=2, progress=False))
    path = tmp_path / "d.jsonl"
    path.write_text("".join(json.dumps(r) + "\n" for r in rows[:1]))
    args = ["eval", "--data", str(out["data"]), "--descriptions", str(path), "--checkpoints",
            *fast["checkpoints"], "--pipeline", "affordance", "--out", str(tmp_path / "o")]
    assert main(args) == 0
    lines = (tmp_path / "o" / "cases.jsonl").read_text().splitlines()
    assert len(lines) == 2
    res = json.loads((tmp_path / "o" / "results.json").read_text())
    assert res["settings"]["cases"] == 1 and len(res["settings"]["descriptions"]) == 12
    assert main(["eval", "--data", str(out["data"]), "--out", str(tmp_path / "x")]) == 2
    assert main([*args[:4], "--model", "a=b,c"]) == 2  # --descriptions runs generate's own


def test_template_text_names_the_target():
    from jaxmotion.scene.graph import SceneGraph
    from jaxmotion.scene.instructions import resolve
    from jaxmotion.scene.rooms import sample_room

    room = sample_room(np.random.default_rng(np.random.SeedSequence([9001, 0])))
    g = SceneGraph(room.objects)
    text = template_text(g, {"action": "sit", "target_id": 7, "index": 0}, 0)
    assert resolve(g, text) == frozenset([7])
    assert template_text(g, {"action": "lie", "target_id": 7, "index": 0}, 0) is None
