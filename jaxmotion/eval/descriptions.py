"""A description set written apart from the instruction generator, and its evaluation.

``jaxmotion/eval/data/descriptions_unseen9001.jsonl`` holds instructions written by hand, in
the style of people saying what they want ("Plonk yourself on the stool next to the sofa",
"Go raid the fridge", "Sit at the desk, please"), for objects of the rooms of
``jaxmotion synth --seed 9001`` (``data/unseen9001``, rooms no training used). None uses a verb
phrase of the synthetic generator (:data:`jaxmotion.scene.instructions.VERBS`, nor a verb core
of its rich phrasing, :mod:`jaxmotion.scene.rich_phrasing`), so the set
measures how the instruction reader and the models do on phrasing they were not built from
(the affordance paper's Table 4 protocol: people's descriptions, unseen scenes).

One row per line::

    {"scene": "scene_00000", "target_id": 7, "action": "sit",
     "text": "Please park yourself on the chair near the door.", "category": "chair",
     "noun": "chair", "relation": "closest", "anchors": ["door"], "same_class": 2}

``category``: the target's class in the room's object table; ``noun``: the word of the text
naming it (with ``seat_at``: the object the seat is at, "sit at the desk"); ``relation`` /
``anchors``: the scene-graph relation the words mean, where they use one (an annotation for
reading the failures, checked against the room in the tests); ``same_class``: how many
objects of the target's class the room has.
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import numpy as np

__all__ = ["DESCRIPTIONS", "FAILURES", "PHRASINGS", "evaluate_descriptions", "failure_class",
           "format_markdown", "load_descriptions", "summarize", "template_text",
           "write_report"]

#: the shipped description set (rooms of data/unseen9001)
DESCRIPTIONS = Path(__file__).with_name("data") / "descriptions_unseen9001.jsonl"
_KEYS = ("scene", "target_id", "action", "text")


def load_descriptions(path=None) -> tuple[list[dict], str]:
    """The rows of a description file (default: :data:`DESCRIPTIONS`) and the first 12 hex
    digits of its SHA-256 (the set's version in reports). Raises ValueError naming the line
    of a row without ``scene``, ``target_id``, ``action`` and ``text``."""
    path = Path(path) if path is not None else DESCRIPTIONS
    raw = path.read_bytes()
    rows = []
    for n, line in enumerate(raw.decode("utf-8").splitlines(), 1):
        if not line.strip():
            continue
        row = json.loads(line)
        missing = [k for k in _KEYS if k not in row]
        if missing:
            raise ValueError(f"{path}:{n}: missing {', '.join(missing)}")
        rows.append(row)
    return rows, hashlib.sha256(raw).hexdigest()[:12]


# --------------------------------------------------------------------------- evaluation
#: the two phrasings scored on the same targets and seeds
PHRASINGS = ("descriptions", "templates")
#: why a description's case failed, in the order they are told apart (:func:`failure_class`)
FAILURES = ("error", "several motions", "no action read", "wrong action", "no class read", "wrong class",
            "wrong instance", "motion")


def template_text(graph, row: dict, seed: int) -> str | None:
    """The synthetic generator's own sentence for the row's action and target
    (:func:`jaxmotion.scene.instructions.sample_instruction`, drawn with ``[seed, index]``),
    or None when no referring expression of the generator singles the target out."""
    from jaxmotion.scene.instructions import NoUniqueReference, sample_instruction

    try:
        return sample_instruction(None, row["action"], int(row["target_id"]),
                                  np.random.default_rng([seed, int(row["index"])]),
                                  graph=graph)[0]
    except (NoUniqueReference, ValueError):
        return None


def failure_class(case: dict) -> str:
    """The first of :data:`FAILURES` a scored case falls in ("" when it succeeded by the
    judge): generate raised; the text was read as several motions (told as a story); the
    action was not read or read wrong; the target's class not
    read, or another class chosen; another object of the right class chosen; or the text was
    understood (action and object) and the motion failed the judge."""
    if case.get("error"):
        return "error"
    if case.get("pipeline") == "story":
        return "several motions"
    if case["action_read"] is None:
        return "no action read"
    if case["action_read"] != case["action"]:
        return "wrong action"
    if not case["grounded"]:
        if case.get("chosen_category") == case["category"]:
            return "wrong instance"
        return "no class read" if case.get("class_read") is None else "wrong class"
    return "" if case["judged"] else "motion"


def _judge(room, obj, joints, action) -> dict:
    """The geometric judge on the motions ``joints [K,T,22,3]`` (scene frame) against the
    room's object ``obj``: ``success`` and its checks, one value per motion."""
    from jaxmotion.eval.action_judge import judge_on_object

    return judge_on_object(joints, np.ones(joints.shape[:2], bool), action,
                           np.asarray(obj["bbox_min"], np.float32),
                           np.asarray(obj["bbox_max"], np.float32),
                           room.xyz[room.instance == obj["id"]], obj.get("surface_height"))


def evaluate_descriptions(data_dir, rows=None, *, recognizer=None, seed: int = 0,
                          samples: int = 1, num_cases: int | None = None,
                          templates: bool = True, progress: bool = True,
                          generate_fn=None, **options) -> dict:
    """Run ``jaxmotion.generate`` on every description (``rows`` from
    :func:`load_descriptions`; default the shipped set) in its room of ``data_dir``
    (``DIR/scenes/<scene>.npz``), and, with ``templates``, on the generator's own sentence
    for the same action and target (:func:`template_text`) with the same seed, and score:

    - ``grounded``: generate's target is the row's ``target_id``;
    - ``action_read``: the action generate understood is the row's;
    - ``judged``: the geometric judge (:mod:`jaxmotion.eval.action_judge`) says the motion
      does the action on the row's target (the share of the K motions);
    - ``recognized`` (with a ``recognizer``, a workdir or a loaded one): the recognizer
      labels the motion with the row's action (the share of the K motions).

    Case ``i`` (a row's ``index`` when it has one) uses seed ``seed + i`` in both rows. ``options``: :func:`jaxmotion.generate`
    options (``checkpoints``, ``pipeline``, ``steps``, ...; ``fit`` is off unless given).
    Returns a JSON-ready report: ``settings``, ``cases`` (one dict per case and phrasing) and
    ``summary`` (per phrasing: overall, per action, and for the descriptions the failure
    classes of :func:`failure_class`).
    """
    import time
    import warnings

    from jaxmotion.errors import GenerateError
    from jaxmotion.scene.demo import load_scene_arg
    from jaxmotion.scene.graph import SceneGraph

    if generate_fn is None:
        from jaxmotion.generation import generate as generate_fn
    if rows is None or isinstance(rows, (str, Path)):
        rows, version = load_descriptions(rows)
    else:
        version = None
    rows = [dict(r, index=r.get("index", i)) for i, r in enumerate(rows)][:num_cases]
    if samples < 1 or not rows:
        raise ValueError("need samples ≥ 1 and at least one description")
    if recognizer is not None and isinstance(recognizer, (str, Path)):
        from jaxmotion.eval.recognizer import load_recognizer

        recognizer = load_recognizer(recognizer)
    options = {"fit": False, **options}
    phrasings = PHRASINGS if templates else PHRASINGS[:1]
    settings = {"data_dir": str(data_dir), "descriptions": version, "cases": len(rows),
                "samples": samples, "seed": seed, "phrasings": list(phrasings),
                "options": {k: (list(v) if isinstance(v, tuple) else v)
                            for k, v in options.items()},
                "recognizer": recognizer.describe() if recognizer is not None else None}
    rooms: dict = {}
    cases = []
    t0 = time.perf_counter()
    for n, row in enumerate(rows):
        if row["scene"] not in rooms:
            room = load_scene_arg(str(Path(data_dir) / "scenes" / f"{row['scene']}.npz"))
            rooms = {row["scene"]: (room, SceneGraph(room.objects))}  # rows come room by room
        room, graph = rooms[row["scene"]]
        obj = next((o for o in room.objects if int(o["id"]) == int(row["target_id"])), None)
        if obj is None:
            raise ValueError(f"{row['scene']} has no object {row['target_id']}")
        texts = {"descriptions": row["text"]}
        if templates:
            texts["templates"] = template_text(graph, row, seed)
        for phrasing, text in texts.items():
            case = {"phrasing": phrasing, "index": row["index"], "scene": row["scene"],
                    "target_id": int(row["target_id"]), "category": obj["category"],
                    "same_class": graph.count(obj["category"]),
                    "action": row["action"], "text": text, "seed": seed + row["index"]}
            cases.append(case)
            if text is None:
                case["error"] = "no template singles the target out"
                continue
            from jaxmotion.grounding import read_instruction

            ins = read_instruction(text)  # word lists only: what the reader saw, for the failures
            case["class_read"] = ins.reference.target if ins.reference is not None else None
            case["relation_read"] = getattr(ins.reference, "relation", None)
            try:
                with warnings.catch_warnings(record=True) as caught:
                    warnings.simplefilter("always")
                    res = generate_fn(room, text, samples=samples, seed=seed + row["index"],
                                      **options)
            except GenerateError as e:
                case.update(error=str(e), grounded=False, action_read=None, judged=0.0)
                if recognizer is not None:
                    case["recognized"] = 0.0
                continue
            und = res.understanding
            chosen = res.target_id
            case.update(action_read=getattr(und, "action", None),
                        chosen_id=None if chosen is None else int(chosen),
                        chosen_category=next((o["category"] for o in room.objects
                                              if chosen is not None and
                                              int(o["id"]) == int(chosen)), None),
                        how=res.grounding, pipeline=res.pipeline,
                        grounded=chosen is not None and int(chosen) == int(row["target_id"]),
                        warnings=[str(w.message) for w in caught
                                  if issubclass(w.category, UserWarning)])
            joints = np.asarray(res.joints, np.float32)
            rep = _judge(room, obj, joints, row["action"])
            case["judged"] = float(np.mean(rep["success"]))
            if recognizer is not None:
                from jaxmotion.eval.recognizer import action_accuracy

                case["recognized"] = action_accuracy(recognizer, joints, None,
                                                     [row["action"]] * len(joints))
        if progress:
            done = cases[-len(texts):]
            print(f"[{n + 1}/{len(rows)}] {time.perf_counter() - t0:6.0f} s  " + "  ".join(
                f"{c['phrasing'][:4]}: grounded {int(bool(c.get('grounded')))} judged "
                f"{c.get('judged', 0):.0f}" for c in done) + f"  {row['text']!r}",
                flush=True)
    for c in cases:
        if c["phrasing"] == "descriptions":
            c["failure"] = failure_class({**c, "grounded": c.get("grounded", False)})
    return {"settings": settings, "cases": cases,
            "summary": summarize(cases, recognizer is not None)}


def _rate(values) -> dict:
    v = np.asarray(list(values), np.float64)
    return {"mean": float(v.mean()) if v.size else None, "n": int(v.size)}


def summarize(cases, recognized: bool) -> dict:
    """Per phrasing: the rates over its cases (``grounded``, ``action_read``, ``judged``,
    ``recognized``), overall, per action, and for rooms with one / several objects of the
    target's class; for the descriptions, how many cases fall in each failure class.
    Cases whose template could not be written count in neither row (identical targets)."""
    no_template = {c["index"] for c in cases if c["phrasing"] == "templates" and c["text"] is None}
    keys = ("grounded", "action_read", "judged") + (("recognized",) if recognized else ())
    out = {}
    for phrasing in PHRASINGS:
        mine = [c for c in cases if c["phrasing"] == phrasing and c["index"] not in no_template]
        if not mine:
            continue

        def rates(sel):
            return {k: _rate(float(c.get(k) == c["action"]) if k == "action_read"
                             else float(c.get(k) or 0.0) for c in sel) for k in keys}

        by_action = {a: rates([c for c in mine if c["action"] == a])
                     for a in ("walk", "sit", "stand_up", "lie")
                     if any(c["action"] == a for c in mine)}
        out[phrasing] = {"all": rates(mine), "by_action": by_action, "by_class_count": {
            name: rates(sel) for name, sel in (
                ("one", [c for c in mine if c["same_class"] == 1]),
                ("several", [c for c in mine if c["same_class"] > 1])) if sel}}
        if phrasing == "descriptions":
            out[phrasing]["failures"] = {f: sum(c.get("failure") == f for c in mine)
                                         for f in FAILURES}
    out["excluded_no_template"] = len(no_template)
    return out


_COLUMNS = (("grounded", "target grounded"), ("action_read", "action read"),
            ("judged", "action, judge"), ("recognized", "action, recognizer"))


def _pct(r) -> str:
    return "–" if r is None or r["mean"] is None else f"{100 * r['mean']:.1f} %"


def format_markdown(report: dict) -> str:
    """The report's tables: both phrasings overall, per action and by how many objects of
    the target's class the room has; the descriptions' failure classes; and each failed
    description with what was read."""
    st, sm = report["settings"], report["summary"]
    cols = [(k, name) for k, name in _COLUMNS if k in sm["descriptions"]["all"]]
    head = "| phrasing | subset | cases | " + " | ".join(n for _, n in cols) + " |"
    lines = [(f"Description set `{st['descriptions']}` on `{st['data_dir']}`: {st['cases']} "
             f"cases, {st['samples']} sample(s) each, seed {st['seed']} + case index (the same "
             f"for both phrasings); generate options {st['options'] or 'default'}."), "",
             head, "|" + "---|" * (3 + len(cols))]
    for phrasing in PHRASINGS:
        if phrasing not in sm:
            continue
        p = sm[phrasing]
        subsets = [("all", p["all"])] + [(a, r) for a, r in p["by_action"].items()] + [
            (f"{k} of its class", r) for k, r in p["by_class_count"].items()]
        for name, r in subsets:
            n = next(iter(r.values()))["n"]
            lines.append(f"| {phrasing} | {name} | {n} | " +
                         " | ".join(_pct(r.get(k)) for k, _ in cols) + " |")
    if sm.get("excluded_no_template"):
        lines += ["", (f"{sm['excluded_no_template']} case(s) left out of both rows: no "
                  "template singles their target out.")]
    fails = sm["descriptions"].get("failures", {})
    if fails:
        lines += ["", ("**Why descriptions failed** (the first that applies; 'motion': action "
                  "and object understood, the judge says no)"), "",
                  "| " + " | ".join(FAILURES) + " |", "|" + "---|" * len(FAILURES),
                  "| " + " | ".join(str(fails[f]) for f in FAILURES) + " |"]
    bad = [c for c in report["cases"] if c["phrasing"] == "descriptions"
           and c.get("failure") not in ("", "motion", None)]
    if bad:
        lines += ["", "| failure | text | room, target | action read | class read | chosen |",
                  "|---|---|---|---|---|---|"]
        for c in bad:
            chosen = (f"{c.get('chosen_category')} {c.get('chosen_id')}"
                      if c.get("chosen_id") is not None else c.get("error", "–"))
            lines.append(f"| {c['failure']} | {c['text']} | {c['scene']}, {c['category']} "
                         f"{c['target_id']} ({c['action']}) | {c.get('action_read')} | "
                         f"{c.get('class_read')} ({c.get('relation_read')}) | {chosen} |")
    return "\n".join(lines) + "\n"


def write_report(report: dict, out) -> tuple[Path, Path, Path]:
    """``results.json`` (settings and summary), ``results.md`` and ``cases.jsonl`` in ``out``."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    paths = out / "results.json", out / "results.md", out / "cases.jsonl"
    paths[0].write_text(json.dumps({k: v for k, v in report.items() if k != "cases"},
                                   indent=2) + "\n")
    paths[1].write_text(format_markdown(report))
    paths[2].write_text("".join(json.dumps(c) + "\n" for c in report["cases"]))
    return paths
