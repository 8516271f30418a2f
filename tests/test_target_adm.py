"""The ADM that reads a known target (``model.target_input``): the model's extra input, starting
from an ADM without it (init_from), training with the target dropped, the probe, and the
pipeline telling it the target."""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from flax import nnx

from jaxmotion.models import ADMConfig, make_adm


def _cond(b, n, cfg, rng, target=True):
    cond = {"text": rng.normal(size=(b, cfg.text_dim)).astype(np.float32),
            "features": rng.normal(size=(b, n, cfg.feature_dim)).astype(np.float32),
            "xyz": rng.uniform(-2, 2, (b, n, 3)).astype(np.float32)}
    if target:
        cond["target"] = (rng.uniform(size=(b, n)) < 0.2).astype(np.float32)
    return cond


def test_target_input_is_one_more_point_input_and_is_checked():
    cfg = dataclasses.replace(ADMConfig.tiny(), target_input=True)
    adm = make_adm(cfg, rngs=nnx.Rngs(0))
    adm.eval()
    rng = np.random.default_rng(0)
    x = rng.normal(size=(2, 40, 6)).astype(np.float32)
    cond = _cond(2, 40, cfg, rng)
    assert adm.point_in.kernel[...].shape[0] == 6 + cfg.feature_dim + 1 + 3
    y = adm(x, jnp.array([3, 7]), cond)
    assert y.shape == (2, 40, 6) and np.isfinite(y).all()
    other = adm(x, jnp.array([3, 7]), {**cond, "target": 1.0 - cond["target"]})
    assert not np.allclose(y, other)  # the target changes the prediction
    with pytest.raises(KeyError, match="target"):
        adm(x, jnp.array([3, 7]), _cond(2, 40, cfg, rng, target=False))
    with pytest.raises(ValueError, match="target"):
        adm(x, jnp.array([3, 7]), {**cond, "target": cond["target"][:, :10]})
    with pytest.raises(ValueError, match="target_input needs arch='perceiver'"):
        dataclasses.replace(ADMConfig.tiny(), arch="mlp", target_input=True)


@pytest.fixture(scope="module")
def target_run(fine_tune_adm):
    """A tiny target-reading ADM fine-tuned from the tiny ADM (init_from), probed as it trains."""
    return fine_tune_adm("target", "model.target_input=true", "grounding_every=5",
                         "grounding_cases=4", "grounding_steps=2")


def test_init_from_an_adm_without_the_target_starts_as_that_adm(target_run):
    from jaxmotion.models.weights import load_weights
    from jaxmotion.train.tasks import get_task

    root, data, work, cfg, res = target_run
    assert res.step == 10 and np.isfinite(res.last_loss)
    src, saved = load_weights(root / "adm" / "model.safetensors")
    net = get_task(cfg).build_model(cfg, nnx.Rngs(123))
    kernel = np.asarray(net.adm.point_in.kernel[...])
    old = src["params/adm/point_in/kernel"]
    at = cfg.model.affordance_dim + cfg.model.feature_dim
    np.testing.assert_array_equal(kernel[at], 0.0)  # the target's row starts at zero
    np.testing.assert_array_equal(np.delete(kernel, at, axis=0), old)
    # so the grown ADM is the old one, whatever the target says
    from jaxmotion.config import config_from_dict
    from jaxmotion.models.weights import apply_weights

    base = make_adm(config_from_dict(ADMConfig, saved["model"]), rngs=nnx.Rngs(0))
    apply_weights(base, src, prefix="adm/")
    base.eval()
    net.adm.eval()
    rng = np.random.default_rng(1)
    x = rng.normal(size=(2, 30, 6)).astype(np.float32)
    cond = _cond(2, 30, cfg.model, rng)
    want = base(x, jnp.array([5, 9]), {k: v for k, v in cond.items() if k != "target"})
    np.testing.assert_allclose(net.adm(x, jnp.array([5, 9]), cond), want, atol=1e-5)


def test_training_probes_the_target_adm_told_the_target(target_run):
    import json

    _, _, work, _, _ = target_run
    rows = [json.loads(line) for line in (work / "metrics.jsonl").read_text().splitlines()]
    probes = [r for r in rows if "grounding/instance_success@0.3" in r]
    assert [r["step"] for r in probes] == [5, 10]
    assert (work / "model_best.safetensors").is_file()


def test_target_drop_is_validated():
    from jaxmotion.config import load_config

    with pytest.raises(ValueError, match="target_drop"):
        load_config("configs/adm.py", ["target_drop=1.5"])


def test_pipeline_tells_a_target_reading_adm_the_target(target_run):
    from jaxmotion.data.cases import case_inputs, load_cases
    from jaxmotion.diffusion import SamplerSpec
    from jaxmotion.pipelines.affordance import AffordancePipeline, take_text

    root, data, work, _, _ = target_run
    pipe = AffordancePipeline.from_workdirs(work, root / "amdm")
    plain = AffordancePipeline.from_workdirs(root / "adm", root / "amdm")
    assert pipe.reads_target and not plain.reads_target
    cases, _ = load_cases(data, "test", pipe.amdm_config, num_cases=2)
    x = case_inputs(cases, [0, 1])
    text = pipe.embed_text([c["text"] for c in cases])
    tgt = np.stack([c["target_mask"] for c in cases])
    s = SamplerSpec("ddim", 2)
    key = jax.random.key(3)
    none = pipe.sample_affordance(key, x["points"], x["colors"], text, s)
    zeros = pipe.sample_affordance(key, x["points"], x["colors"], text, s,
                                   target=np.zeros_like(tgt))
    np.testing.assert_array_equal(none, zeros)  # no target known = an all-zero mask
    told = pipe.sample_affordance(key, x["points"], x["colors"], text, s, target=tgt)
    assert not np.allclose(told, none)
    # sample() passes its target to the ADM, with one map or the best of several
    res = pipe.sample(key, x["points"], x["colors"], take_text(text, [0, 1]), x["mask"],
                      adm=s, amdm=s, target=tgt)
    ka = jax.random.split(key)[0]
    np.testing.assert_allclose(
        res["affordance"],
        pipe.sample_affordance(ka, x["points"], x["colors"], text, s, target=tgt), atol=1e-6)
    best = pipe.sample(key, x["points"], x["colors"], text, x["mask"], adm=s, amdm=s,
                       target=tgt, candidates=3)
    maps = pipe.sample_affordances(ka, x["points"], x["colors"], text, s, candidates=3,
                                   target=tgt)
    assert any(np.allclose(best["affordance"][0], m, atol=1e-5) for m in maps[0])
    with pytest.raises(ValueError, match="no target input"):
        plain.sample_affordance(key, x["points"], x["colors"], text, s, target=tgt)
    # an ADM without the target input ignores sample()'s target, as before
    a = plain.sample(key, x["points"], x["colors"], text, x["mask"], adm=s, amdm=s,
                     target=tgt)["affordance"]
    np.testing.assert_array_equal(
        a, plain.sample_affordance(ka, x["points"], x["colors"], text, s))


@pytest.mark.slow
def test_amdm_trains_on_maps_of_a_target_reading_adm(target_run, tmp_path):
    """An AMDM trained on ADM-predicted maps (predicted_fraction > 0) builds the ADM's
    condition as every other caller does (ADMNet.condition): an ADM that reads a target is
    told the batch's target, and training runs (it failed without the target channel)."""
    from jaxmotion.config import load_config
    from jaxmotion.train import train
    from jaxmotion.train.tasks import get_task

    _, data, adm_work, _, _ = target_run
    cfg = load_config("configs/amdm.py", [
        f"data_dir={data}", "preset=tiny", "steps=2", "log_every=1", "eval_every=2",
        f"workdir={tmp_path / 'amdm'}", f"adm_workdir={adm_work}", "predicted_fraction=1.0",
        "adm_sampler_steps=2"])
    task = get_task(cfg)
    result = train(cfg, task)
    assert task.predicted_fraction == 1.0
    assert result.step == 2 and np.isfinite(result.last_loss)
