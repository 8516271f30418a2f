"""`jaxmotion eval`: the runner over tiny trained runs; the report's tables and intervals."""

import json

import numpy as np
import pytest

from jaxmotion.eval.runner import (ModelSpec, evaluate, format_markdown, mean_ci95, parse_model,
                                   write_report)


def test_parse_model():
    assert parse_model("a=x,y") == ModelSpec("a", "x", "y", "ddim", 50)
    assert parse_model("b=x,y,ddim10").steps == 10
    assert parse_model("c=x,y,DDPM").method == "ddpm"
    for bad in ("a", "a=x", "=x,y", "a=x,y,ddim0", "a=x,y,euler", "a=x,adm_guidance=2,y",
                "a=x,y,ddim5,guidance=2", "a=x,y,adm_guidance=two", "a=x,y,amdm_guidance=0"):
        with pytest.raises(ValueError, match="--model"):
            parse_model(bad)


def test_parse_model_guidance_per_stage():
    m = parse_model("g=x,y,ddim20,adm_guidance=2.5")
    assert (m.steps, m.adm_guidance, m.amdm_guidance) == (20, 2.5, 1.0)
    assert m.sampler_label == "DDIM-20 (ADM w=2.5)"
    m = parse_model("g=x,y,amdm_guidance=3,adm_guidance=2")
    assert (m.method, m.steps, m.adm_guidance, m.amdm_guidance) == ("ddim", 50, 2.0, 3.0)
    assert m.sampler_label == "DDIM-50 (ADM w=2, AMDM w=3)"
    assert parse_model("g=x,y").sampler_label == "DDIM-50"
    m = parse_model("o=x,y,ddim4,affordance=gt")
    assert m.affordance == "gt" and m.sampler_label == "DDIM-4 (ground-truth maps)"
    with pytest.raises(ValueError, match="affordance must be adm"):
        parse_model("o=x,y,affordance=oracle")


def test_parse_model_consistency():
    m = parse_model("c=x,y,ddim20,adm_guidance=5,consistency=0.5")
    assert m.consistency == 0.5 and m.sampler_label == "DDIM-20 (ADM w=5, consistency 0.5)"
    assert parse_model("c=x,y").consistency == 0.0
    m = parse_model("c=x,y,ddim4,consistency=1,affordance=gt")
    assert m.sampler_label == "DDIM-4 (consistency 1, ground-truth maps)"
    for bad in ("c=x,y,consistency=2", "c=x,y,consistency=-0.5", "c=x,y,consistency=some"):
        with pytest.raises(ValueError, match="consistency must be a number in"):
            parse_model(bad)


def test_parse_model_object_centric_options():
    base = "o=x,y,ddim20,trajectory=t,completion=c"
    m = parse_model(base)
    assert m.object_centric and m.anchor == 1.0 and m.keep_trajectory
    assert m.sampler_label == "object-centric, DDIM-20"
    m = parse_model(base + ",anchor=0,keep_trajectory=0")
    assert m.anchor == 0.0 and not m.keep_trajectory
    assert "no anchor guidance" in m.sampler_label
    assert "anchor guidance 0.5" in parse_model(base + ",anchor=0.5").sampler_label
    for bad in ("anchor=2", "anchor=-1", "anchor=yes"):
        with pytest.raises(ValueError, match="anchor must be a strength"):
            parse_model(f"{base},{bad}")
    with pytest.raises(ValueError, match="keep_trajectory must be"):
        parse_model(base + ",keep_trajectory=yes")
    m = parse_model(base + ",standing=0,feet=0.5")
    assert (m.standing, m.feet) == (0.0, 0.5)
    assert "no standing guidance" in m.sampler_label
    assert "foot guidance 0.5" in m.sampler_label
    with pytest.raises(ValueError, match="feet must be a strength"):
        parse_model(base + ",feet=3")


def test_ground_truth_affordance_row(tiny_runs, tmp_path):
    """affordance=gt: the AMDM on the dataset's own maps; its own row, no grounding columns
    (there are no ADM maps to score). keep_motions: the joints come back, and to motions.npz."""
    root, out = tiny_runs
    adm, amdm = str(root / "adm"), str(root / "amdm")
    specs = [ModelSpec("adm", adm, amdm, "ddim", 2),
             ModelSpec("oracle", adm, amdm, "ddim", 2, affordance="gt")]
    rep = evaluate(out["data"], specs, num_cases=2, samples=2, replications=1, body=False,
                   batch_size=4, progress=False, keep_motions=True)
    write_report(rep, tmp_path)
    saved = np.load(tmp_path / "motions.npz")
    assert saved["adm/joints"].shape == (1, 2, 2, *saved["mask"].shape[1:], 22, 3)
    np.testing.assert_array_equal(saved["oracle/joints"],
                                  rep["models"]["oracle"]["motions"]["joints"])
    assert list(saved["files"]) == [c["file"] for c in rep["models"]["adm"]["cases"]]
    assert saved["adm/rotation"].shape == (2, 3, 3) and saved["oracle/shift"].shape == (2, 3)
    assert "motions" not in (tmp_path / "results.json").read_text()
    o = rep["models"]["oracle"]
    assert o["affordance"] == "ground truth" and rep["models"]["adm"]["affordance"] == "adm"
    assert "success@0.3" not in o["summary"] and np.isfinite(o["summary"]["goal_distance"]["mean"])
    assert o["summary"]["goal_distance"] != rep["models"]["adm"]["summary"]["goal_distance"]
    md = format_markdown(rep)
    assert "| oracle | DDIM-2 (ground-truth maps) |" in md
    # plausibility: per model and for the dataset's own motions (which never teleport)
    for key in ("teleport", "pelvis_speed_p99", "joint_speed_max", "jerk_mean"):
        assert np.isfinite(o["summary"][key]["mean"]), key
    gt = rep["ground_truth"]
    assert gt["teleport"] == 0.0 and 0.0 < gt["pelvis_speed_p99"] < 3.0
    assert "**Plausibility and action**" in md and md.count("| dataset motions |") == 2
    assert gt["action_judged"] >= 0.75  # the dataset's own motions: the judge's ceiling
    row = rep["models"]["adm"]["cases"][0]
    assert len(row["pelvis_speeds"]) == 2 and 0.0 <= row["teleport"] <= 1.0
    assert 0.0 <= row["judge/over_footprint"] <= 1.0 and "judge/pelvis_above_surface" in row
    assert md.count("| adm | perceiver |") == 1 and "| oracle | perceiver |" not in md


def test_cases_carry_the_target_class_mask(tiny_runs):
    """The class mask (the paper's grounding target) holds every point of the target's semantic
    class: a superset of the instance mask, and exactly the class's points of the crop."""
    from jaxmotion.data.cases import load_cases
    from jaxmotion.data.format import load_sample
    from jaxmotion.models.weights import read_config

    root, out = tiny_runs
    cases, _ = load_cases(out["data"], "test", read_config(root / "amdm"), num_cases=3)
    for c in cases:
        inst, cls = c["target_mask"], c["target_class_mask"]
        assert cls.shape == inst.shape and not (inst & ~cls).any()
        s = load_sample(out["data"] / "samples" / "test" / c["file"])
        with np.load(out["data"] / "scenes" / f"{s['scene_id']}.npz") as sc:
            xyz, sem, ids = sc["xyz"], sc["semantic"], sc["instance"]
        target_class = np.unique(sem[ids == s["target_id"]])
        assert len(target_class) == 1
        # find each crop point in the room (brute force) and read its label there
        world = c["points"] @ c["rotation"] + c["shift"]
        nearest = np.argmin(((world[:, None, :2] - xyz[None, :, :2]) ** 2).sum(-1)
                            + (world[:, None, 2] - xyz[None, :, 2]) ** 2, axis=1)
        np.testing.assert_array_equal(cls, sem[nearest] == target_class[0])


def test_interval_is_the_normal_95_percent_half_width():
    v = [1.0, 2.0, 3.0, 4.0]
    s = mean_ci95(v)
    assert s["mean"] == 2.5 and s["n"] == 4
    assert s["ci95"] == pytest.approx(1.96 * np.std(v, ddof=1) / 2.0)
    assert mean_ci95([np.nan])["mean"] is None and mean_ci95([5.0])["ci95"] == 0.0


# body=True (SMPL-X-fitted bodies, ~100 s on 2 cores) runs with -m slow
@pytest.mark.parametrize("body", [False, pytest.param(True, marks=pytest.mark.slow)])
def test_runner_over_tiny_runs(tiny_runs, tmp_path, body):
    from jaxmotion.cli import main

    root, out = tiny_runs
    args = ["eval", "--data", str(out["data"]), "--model", f"two={root / 'adm'},{root / 'amdm'},ddim2",
            "--cases", "2", "--samples", "2", "--replications", "2", "--batch-size", "4",
            "--out", str(tmp_path)]
    assert main(args + ([] if body else ["--joints-only"])) == 0
    rep = json.loads((tmp_path / "results.json").read_text())
    m = rep["models"]["two"]
    assert m["sampler"] == "DDIM-2" and m["two_stage"] and len(m["replications"]) == 2
    s = m["summary"]
    for k in ("goal_distance", "contact", "non_collision", "apd", "skating", "success@0.3",
              "instance_success@0.3"):
        assert s[k]["n"] == 2 and np.isfinite(s[k]["mean"]), k
    assert 0.0 <= s["non_collision"]["mean"] <= 1.0 and s["goal_distance"]["mean"] >= 0.0
    # the class mask contains the instance mask, so class success is never below instance success
    assert s["success@0.3"]["mean"] >= s["instance_success@0.3"]["mean"]
    assert s["apd"]["mean"] > 0.0  # two different samples per case
    assert (m["body_fit_error_m"] is not None) == body
    md = (tmp_path / "results.md").read_text()
    assert md == format_markdown(rep) and "| two | DDIM-2 |" in md and "Table 3" in md
    gt = rep["ground_truth"]
    assert gt["non_collision"] > 0.9 and "| dataset motions |" in md
    # the per-case rows behind the means: 2 replications x 2 cases, in cases.jsonl only
    assert "cases" not in m
    rows = [json.loads(x) for x in (tmp_path / "cases.jsonl").read_text().splitlines()]
    assert [(r["replication"], r["case"]) for r in rows] == [(0, 0), (0, 1), (1, 0), (1, 1)]
    assert {r["model"] for r in rows} == {"two"} and all(r["file"].endswith(".npz") for r in rows)
    for k in ("goal_distance", "contact", "instance_success@0.3"):
        means = [np.mean([r[k] for r in rows if r["replication"] == i]) for i in (0, 1)]
        np.testing.assert_allclose(means, [x[k] for x in m["replications"]], rtol=1e-6)


def test_same_seed_same_numbers_and_the_recognizer_columns(tiny_runs, tmp_path):
    """Same seed, same numbers. With a recognizer (an untrained tiny one: the wiring, not its
    skill): action accuracy and FID / diversity / multimodality on its features per
    replication and in the summary of results.json, the dataset's diversity in the "real" row,
    and three columns in the table."""
    from flax import nnx

    from jaxmotion.eval.recognizer import RECOGNIZER_VERSION, Recognizer
    from jaxmotion.models.recognizer import ActionRecognizer, RecognizerConfig

    root, out = tiny_runs
    rec = Recognizer(ActionRecognizer(RecognizerConfig.preset("tiny"), rngs=nnx.Rngs(0)),
                     {"recognizer_version": RECOGNIZER_VERSION, "fps": 30})
    spec = [ModelSpec("two", str(root / "adm"), str(root / "amdm"), "ddim", 2)]
    kw = dict(num_cases=2, samples=2, replications=1, body=False, batch_size=4, progress=False)
    a = evaluate(out["data"], spec, **kw, recognizer=rec)
    plain = evaluate(out["data"], spec, **kw)
    b = plain["models"]["two"]["replications"]
    rec_keys = {"rec_fid", "rec_diversity", "rec_multimodality", "action_recognized"}
    assert [{k: v for k, v in x.items() if k not in rec_keys}
            for x in a["models"]["two"]["replications"]] == b
    write_report(a, tmp_path)
    rep = json.loads((tmp_path / "results.json").read_text())
    assert rep["settings"]["recognizer"] == rec.describe()
    m = rep["models"]["two"]
    for key in rec_keys:
        assert m["summary"][key]["n"] == 1 and np.isfinite(m["replications"][0][key]), key
    assert m["summary"]["rec_fid"]["mean"] > 0
    # 2 cases x 2 samples: Guo et al.'s independent pair draws (as Diversity / MultiModality)
    # give 0 when they coincide, so these can be 0 here
    assert m["summary"]["rec_diversity"]["mean"] >= 0
    assert m["summary"]["rec_multimodality"]["mean"] >= 0
    real = rep["real"]
    assert set(real) == {"rec_diversity"} and real["rec_diversity"] >= 0  # no evaluator given
    md = (tmp_path / "results.md").read_text()
    assert md == format_markdown(rep)
    table = md[md.index("**Plausibility and action**"):md.index("**Affordance")].splitlines()
    cells = {x.split("|")[1].strip(): [c.strip() for c in x.strip("|").split("|")]
             for x in table if x.startswith("| ")}
    assert cells["method"][-3:] == ["FID (rec.) ↓", "diversity (rec.) →",
                                    "multimodality (rec.) ↑"]
    assert cells["dataset motions"][-3:] == ["–", f"{real['rec_diversity']:.3f}", "–"]
    assert cells["two"][-3] == "{mean:.3f} ± {ci95:.3f}".format(**m["summary"]["rec_fid"])
    assert "rec_fid" not in (tmp_path / "cases.jsonl").read_text()  # set-level numbers
    # bodies inside furniture: a per-case column, the dataset's motions as the reference
    assert "in furniture (%) ↓" in cells["method"]
    assert 0.0 <= m["summary"]["in_furniture"]["mean"] <= 1.0
    assert 0.0 <= rep["ground_truth"]["in_furniture"] <= 1.0
    assert "FID (rec.)" not in format_markdown(plain) and "real" not in plain


def test_runner_with_an_evaluator_adds_text_motion_columns(tiny_runs, tmp_path):
    from jaxmotion.config import load_config
    from jaxmotion.train import train
    from jaxmotion.train.tasks import get_task

    root, out = tiny_runs
    cfg = load_config("configs/evaluator.py", [f"data_dir={out['data']}", "preset=tiny",
                                                "steps=5", f"workdir={tmp_path / 'ev'}"])
    train(cfg, get_task(cfg))
    spec = [ModelSpec("two", str(root / "adm"), str(root / "amdm"), "ddim", 2)]
    rep = evaluate(out["data"], spec, num_cases=4, samples=2, replications=2, body=False,
                   evaluator=tmp_path / "ev", batch_size=4, progress=False)
    s = rep["models"]["two"]["summary"]
    for k in ("fid", "r_precision_top3", "multimodal_dist", "diversity", "multimodality"):
        assert s[k]["n"] == 2 and np.isfinite(s[k]["mean"]), k
    assert not [k for k in s if k.endswith("_ci95")]
    assert "r_precision_top3" in rep["real"] and rep["settings"]["evaluator"]
    md = format_markdown(rep)
    assert "FID ↓" in md and "| dataset motions |" in md


def test_parse_model_cvae_row():
    m = parse_model("h=x,y,cvae=runs/cvae")
    assert m.cvae == "runs/cvae" and m.pipeline == "cvae" and not m.object_centric
    assert m.sampler_label.startswith("cVAE")
    assert parse_model("t=x,y").pipeline == "affordance"
    with pytest.raises(ValueError, match="one pipeline"):
        parse_model("h=x,y,cvae=c,trajectory=t,completion=c")
    for bad in ("affordance=gt", "consistency=0.5", "adm_candidates=2", "motion_candidates=2"):
        with pytest.raises(ValueError, match="one latent per motion"):
            parse_model(f"h=x,y,cvae=c,{bad}")


def test_runner_with_a_cvae_row(tiny_runs, tmp_path):
    """A cVAE row samples in the cases' crops (one latent per motion), is scored like the
    others, and is reproducible; a cVAE whose crop differs from the cases' is refused."""
    from jaxmotion.config import load_config
    from jaxmotion.train import train
    from jaxmotion.train.tasks import get_task

    root, out = tiny_runs
    cfg = load_config("configs/cvae.py", [f"data_dir={out['data']}", "preset=tiny", "steps=4",
                                          "eval_every=0", f"workdir={tmp_path / 'cvae'}"])
    train(cfg, get_task(cfg))
    spec = parse_model(f"h={root / 'adm'},{root / 'amdm'},cvae={tmp_path / 'cvae'}")
    kw = dict(num_cases=2, samples=2, replications=1, body=False, batch_size=4,
              ground_truth=False, progress=False, keep_motions=True)
    rep = evaluate(out["data"], [spec], **kw)
    m = rep["models"]["h"]
    assert m["pipeline"] == "cvae" and m["scene_input"] == "rgb" and not m["two_stage"]
    joints = m["motions"]["joints"]
    assert joints.shape[:3] == (1, 2, 2) and np.isfinite(joints).all()
    assert not np.allclose(joints[0, :, 0], joints[0, :, 1])  # two latents, two motions
    for k in ("goal_distance", "contact", "skating", "apd"):
        assert np.isfinite(m["summary"][k]["mean"]), k
    again = evaluate(out["data"], [spec], **kw)["models"]["h"]["motions"]["joints"]
    np.testing.assert_array_equal(joints, again)
    # the same weights, saved as a cVAE of 128-point crops (its config is what is checked)
    from safetensors.numpy import save

    from jaxmotion.models.weights import load_weights

    tensors, saved = load_weights(tmp_path / "cvae" / "model.safetensors")
    saved["model"]["num_points"] = saved["crop"]["num_points"] = 128
    (tmp_path / "cvae128.safetensors").write_bytes(save(tensors, metadata={
        "config": json.dumps(saved), "format": "jaxmotion-weights-1"}))
    with pytest.raises(ValueError, match="reads 128 points"):
        evaluate(out["data"], [parse_model(f"h={root / 'adm'},{root / 'amdm'},"
                                           f"cvae={tmp_path / 'cvae128.safetensors'}")], **kw)


def test_backbone_from_an_adm_weights_file(tiny_runs):
    """``backbone_workdir`` may name an ADM's weights: the backbone it embeds is loaded (its
    parameters are the file's ``params/backbone/`` tensors); another task's file is refused.
    (Not the shared segmentation run: a test elsewhere moves it away for a while.)"""
    from flax import nnx

    from jaxmotion.models.frozen import load_backbone
    from jaxmotion.models.weights import flatten_state, load_weights

    root, _ = tiny_runs
    loaded = flatten_state(nnx.state(load_backbone(root / "adm"), nnx.Param))
    tensors, _ = load_weights(root / "adm" / "model.safetensors")
    embedded = {k[len("params/backbone/"):]: v for k, v in tensors.items()
                if k.startswith("params/backbone/")}
    assert loaded.keys() == embedded.keys() and embedded
    for k in embedded:
        np.testing.assert_array_equal(loaded[k], embedded[k])
    with pytest.raises(ValueError, match="'amdm' checkpoint"):
        load_backbone(root / "amdm")
    with pytest.raises(FileNotFoundError, match="no backbone weights"):
        load_backbone(root / "missing")
