"""The room-view ADM: crops centred on the room, the map carried to the AMDM's crop, init_from,
and the pipeline, eval, probe and generate with such an ADM."""

from __future__ import annotations

import jax
import numpy as np
import pytest

from jaxmotion.data.crop import CropSpec, crop_sample
from jaxmotion.geometry import carry_field


# --- carry_field against numpy -----------------------------------------------------------------
def _carry_numpy(q, p, v, k, eps):
    d = np.sqrt(((q[:, None, :] - p[None, :, :]) ** 2).sum(-1))
    idx = np.argsort(d, axis=1)[:, :k]
    w = 1.0 / (np.take_along_axis(d, idx, 1) + eps)
    w /= w.sum(1, keepdims=True)
    return np.einsum("qk,qkc->qc", w, v[idx])


@pytest.mark.parametrize("k", [1, 4])
def test_carry_field_matches_numpy(k):
    rng = np.random.default_rng(0)
    p = rng.uniform(-2, 2, (300, 3)).astype(np.float32)
    q = rng.uniform(-2, 2, (130, 3)).astype(np.float32)  # not a multiple of the chunk
    v = rng.uniform(0, 1, (300, 6)).astype(np.float32)
    got = np.asarray(carry_field(q, p, v, k=k, query_chunk=64))
    np.testing.assert_allclose(got, _carry_numpy(q, p, v, k, 1e-3), rtol=1e-5, atol=1e-6)


def test_carry_field_copies_coincident_points_and_checks_inputs():
    rng = np.random.default_rng(1)
    p = rng.uniform(-2, 2, (200, 3)).astype(np.float32)
    v = rng.uniform(0, 1, (200, 2)).astype(np.float32)
    got = np.asarray(carry_field(p[:50], p, v, eps=1e-6))
    np.testing.assert_allclose(got, v[:50], atol=1e-3)  # a source point at distance 0 dominates
    assert carry_field(p[:3], p[:2], v[:2], k=4).shape == (3, 2)  # k clipped to the cloud
    with pytest.raises(ValueError, match="one row per point"):
        carry_field(p, p, v[:10])
    with pytest.raises(ValueError, match="k >= 1"):
        carry_field(p, p, v, k=0)
    with pytest.raises(ValueError, match="empty"):
        carry_field(p, p[:0], v[:0])


# --- the room-centred crop ---------------------------------------------------------------------
def _room(w, d, n=4000, seed=0):
    rng = np.random.default_rng(seed)
    xyz = np.c_[rng.uniform(0, w, n), rng.uniform(0, d, n), rng.uniform(0, 2.5, n)]
    return xyz.astype(np.float32), rng.uniform(0, 1, (n, 3)).astype(np.float32), \
        rng.integers(0, 5, n)


def _motion(x, y, t=20):
    j = np.zeros((t, 22, 3), np.float32)
    j[:, :, 0] = np.linspace(x, x + 0.5, t)[:, None]
    j[:, :, 1] = y
    j[:, :, 2] = 0.9
    return j, np.ones(t, bool)


def test_room_centre_ignores_where_the_motion_is():
    xyz, rgb, inst = _room(5.0, 4.0)
    spec = CropSpec(size=8.0, num_points=512, centre="room")
    shifts = []
    for seed, (x, y) in enumerate([(0.5, 0.5), (4.0, 3.5), (2.0, 1.0)]):
        c = crop_sample(np.random.default_rng(seed), xyz, rgb, inst, *_motion(x, y), 1, spec)
        shifts.append(c.shift[:2])
        np.testing.assert_allclose(c.to_world(c.points), xyz[c.indices], atol=1e-5)
    lo, hi = xyz[:, :2].min(0), xyz[:, :2].max(0)
    for s in shifts:
        np.testing.assert_allclose(s, 0.5 * (lo + hi), atol=1e-6)
    # the motion-centred crop of the same size moves with the motion
    c = crop_sample(np.random.default_rng(0), xyz, rgb, inst, *_motion(0.5, 0.5), 1,
                    CropSpec(size=8.0, num_points=512))
    assert np.abs(c.shift[:2] - 0.5 * (lo + hi)).max() > 1e-3


def test_room_centre_moves_only_as_far_as_the_motion_needs():
    xyz, rgb, inst = _room(14.0, 4.0)  # wider than the square
    spec = CropSpec(size=8.0, num_points=512, centre="room", margin=0.3)
    joints, mask = _motion(0.5, 2.0)
    c = crop_sample(np.random.default_rng(0), xyz, rgb, inst, joints, mask, 1, spec)
    pelvis_x = joints[:, 0, 0]
    # the padded trajectory fits, and the centre is as close to the room's (x = 7) as it allows
    assert pelvis_x.min() - 0.3 >= c.shift[0] - 4.0 - 1e-5
    np.testing.assert_allclose(c.shift[0], pelvis_x.min() - 0.3 + 4.0, atol=1e-5)
    np.testing.assert_allclose(c.shift[1], 0.5 * (xyz[:, 1].min() + xyz[:, 1].max()), atol=1e-6)


def test_crop_centre_is_validated():
    from jaxmotion.data.config import CropConfig

    with pytest.raises(ValueError, match="crop.centre"):
        CropConfig(centre="object")
    xyz, rgb, inst = _room(4, 4)
    with pytest.raises(ValueError, match="centre"):
        crop_sample(np.random.default_rng(0), xyz, rgb, inst, *_motion(1, 1), 1,
                    CropSpec(centre="middle"))


# --- training, pipeline, eval, probe, generate ---------------------------------------------------
@pytest.fixture(scope="module")
def room_runs(fine_tune_adm):
    """A tiny room-view ADM fine-tuned from the tiny crop-view ADM (init_from)."""
    return fine_tune_adm("room", "crop.centre=room", "crop.size=8")


def test_init_from_starts_from_the_other_runs_weights(room_runs):
    from flax import nnx

    from jaxmotion.config import load_config
    from jaxmotion.models.weights import flatten_state, load_weights
    from jaxmotion.train.tasks import get_task

    root, data, work, cfg, res = room_runs
    assert res.step == 10 and np.isfinite(res.last_loss)
    src, _ = load_weights(root / "adm" / "model.safetensors")
    net = get_task(cfg).build_model(cfg, nnx.Rngs(123))
    mine = flatten_state(nnx.state(net.adm, nnx.Param))
    assert mine and all(np.array_equal(np.asarray(v), src[f"params/adm/{k}"])
                        for k, v in mine.items())
    seg = work.parent / "segmentation"
    bad = load_config("configs/adm.py", [
        f"data_dir={data}", "preset=tiny", f"workdir={work}_bad",
        f"backbone_workdir={seg}", f"init_from={root / 'adm'}", "model.text_tokens=4"])
    with pytest.raises(ValueError, match="differs in text_tokens"):
        get_task(bad).build_model(bad, nnx.Rngs(0))
    other = load_config("configs/adm.py", [
        f"data_dir={data}", "preset=tiny", f"workdir={work}_seg",
        f"backbone_workdir={seg}", f"init_from={seg}"])
    with pytest.raises(ValueError, match="not an ADM"):
        get_task(other).build_model(other, nnx.Rngs(0))


def test_amdm_refuses_a_room_view_adm_for_its_predicted_maps(room_runs, tmp_path):
    from flax import nnx

    from jaxmotion.config import load_config
    from jaxmotion.train.tasks import get_task

    _, data, work, _, _ = room_runs
    cfg = load_config("configs/amdm.py", [f"data_dir={data}", "preset=tiny",
                                          f"workdir={tmp_path / 'amdm'}", f"adm_workdir={work}",
                                          "predicted_fraction=0.5"])
    with pytest.raises(ValueError, match="crop-view ADM"):
        get_task(cfg).build_model(cfg, nnx.Rngs(0))


def test_room_view_cases_and_sampling(room_runs, tmp_path):
    from jaxmotion.data.cases import case_inputs, load_cases
    from jaxmotion.diffusion import SamplerSpec
    from jaxmotion.pipelines.affordance import AffordancePipeline, take_text
    from jaxmotion.sample import sample_split

    root, data, work, _, _ = room_runs
    pipe = AffordancePipeline.from_workdirs(work, root / "amdm")
    assert pipe.room_view and pipe.adm_config["crop"]["size"] == 8.0
    cases, spec = load_cases(data, "test", pipe.amdm_config, num_cases=3,
                             adm_config=pipe.adm_config)
    plain, _ = load_cases(data, "test", pipe.amdm_config, num_cases=3)
    for c, p in zip(cases, plain, strict=True):
        np.testing.assert_array_equal(c["points"], p["points"])  # the crops are unchanged
        assert p["view"] is None
        v = c["view"]
        assert v["points"].shape == (256, 3) and v["in_crop"].shape == (256, 3)
        # the view holds the target, and in_crop is the view in the crop's frame
        assert v["target_mask"].any() and (v["target_class_mask"] >= v["target_mask"]).all()
        # in the crop frame, the view's target points lie on the crop's target points
        d = np.linalg.norm(v["in_crop"][v["target_mask"]][:, None]
                           - c["points"][c["target_mask"]][None], axis=-1)
        assert d.min(axis=1).max() < 0.6
    x = case_inputs(cases, [0, 1])
    assert x["view"]["points"].shape == (2, 256, 3) and case_inputs(plain, [0])["view"] is None
    text = pipe.embed_text([cases[0]["text"], cases[1]["text"]])
    s = SamplerSpec("ddim", 2)
    with pytest.raises(ValueError, match="room view"):
        pipe.sample(jax.random.key(0), x["points"], x["colors"], take_text(text, [0, 1]),
                    x["mask"], adm=s, amdm=s)
    res = pipe.sample(jax.random.key(0), x["points"], x["colors"], text, x["mask"], adm=s,
                      amdm=s, view=x["view"])
    assert res["view_affordance"].shape == (2, 256, 6)
    assert res["affordance"].shape == (2, 256, 6) and np.isfinite(res["joints"]).all()
    # the crop's map is the view's carried over
    want = np.stack([carry_field(x["points"][i], x["view"]["in_crop"][i],
                                 res["view_affordance"][i]) for i in range(2)])
    np.testing.assert_allclose(res["affordance"], want, atol=1e-6)
    path = sample_split(data, "test", work, root / "amdm", tmp_path / "s.npz", num_cases=2,
                        adm=s, amdm=s, batch_size=2, progress=False)
    assert np.isfinite(np.load(path)["joints"]).all()


def test_room_view_eval_and_probe(room_runs):
    from jaxmotion.eval.relation_probe import relation_probe
    from jaxmotion.eval.runner import ModelSpec, evaluate

    root, data, work, _, _ = room_runs
    spec = ModelSpec("room", str(work), str(root / "amdm"), "ddim", 2)
    report = evaluate(data, [spec], split="test", num_cases=2, samples=1, replications=1,
                      body=False, ground_truth=False, progress=False, batch_size=2)
    summ = report["models"]["room"]["summary"]
    assert np.isfinite(summ["goal_distance"]["mean"])
    assert np.isfinite(summ["success@0.3"]["mean"])
    r = relation_probe(data, work, root / "amdm", splits=("val", "test"), num_cases=12, steps=2,
                       batch_size=4)
    # the probe picks its cases on the ADM's view: several objects of the target's class there,
    # and a closest / farthest relation
    from jaxmotion.data.cases import load_cases
    from jaxmotion.eval.relation_probe import canonical_pair
    from jaxmotion.pipelines.affordance import AffordancePipeline

    pipe = AffordancePipeline.from_workdirs(work, root / "amdm")
    want = 0
    for split in ("val", "test"):
        cases, _ = load_cases(data, split, pipe.amdm_config, num_cases=12,
                              adm_config=pipe.adm_config)
        want += sum(c["view"]["target_class_mask"].sum() > c["view"]["target_mask"].sum()
                    and canonical_pair(c["text"]) is not None for c in cases)
    assert r["cases"] == want
    assert all(0.0 <= r[k] <= 1.0 or (want == 0 and np.isnan(r[k]))
               for k in ("hit_original", "hit_true", "hit_opposite", "hit_both"))


@pytest.mark.slow
def test_room_view_generate(room_runs, tmp_path, monkeypatch):
    import jaxmotion
    import jaxmotion.generation as G
    from jaxmotion.export.folder import scene_heat

    root, _, work, _, _ = room_runs
    monkeypatch.setenv("JAXMOTION_CACHE", str(tmp_path / "xla"))
    kw = dict(samples=2, seed=3, steps=2, adm_steps=2, fit=False, pipeline="affordance",
              checkpoints=(str(work), str(root / "amdm")))
    res = jaxmotion.generate("demo", "sit on the chair next to the table", **kw)
    assert res.joints.shape[0] == 2 and np.isfinite(res.joints).all()
    assert res.view_xyz.shape[1] == 3 and res.view_affordance.shape == (2, len(res.view_xyz), 6)
    assert res.affordance.shape == (2, len(res.crop_xyz), 6)
    # the crop's maps are the view's, carried
    want = np.asarray(carry_field(res.crop_xyz, res.view_xyz, res.view_affordance[0]))
    np.testing.assert_allclose(res.affordance[0], want, atol=1e-4)
    assert "adm" in res.timings and res.grounding == "class"  # the demo room has one chair
    heat = scene_heat(res, res.scene.xyz[:500])
    assert heat.shape == (500,) and (heat > 0).any()
    again = jaxmotion.generate("demo", "sit on the chair next to the table", **kw)
    np.testing.assert_array_equal(again.joints, res.joints)
    # an object named by id: the view is still used for the map
    oid = res.target_id
    one = jaxmotion.generate("demo", "sit on it", object_id=oid, **kw)
    assert one.target_id == oid and one.view_affordance is not None
    assert one.grounding == "object_id"
    with pytest.raises(G.GenerateError, match="grounding"):
        jaxmotion.generate("demo", "sit on it", grounding="graph", **kw)


# --- scene-graph grounding and the region probe ---------------------------------------------------
def _box(i, cat, x, y, w=0.5):
    return {"id": i, "category": cat, "bbox_min": [x, y, 0.0], "bbox_max": [x + w, y + w, 0.9]}


def test_candidate_objects_narrows_by_the_relation():
    from types import SimpleNamespace

    from jaxmotion.grounding import candidate_objects

    room = SimpleNamespace(objects=[_box(1, "chair", 0.5, 0.5), _box(2, "chair", 4.0, 3.0),
                                    _box(3, "door", 0.0, 1.5), _box(4, "table", 2.0, 2.0)])
    ids = lambda c: [o["id"] for o in c[0]]  # noqa: E731
    got = candidate_objects(room, "sit on the chair closest to the door")
    assert ids(got) == [1] and got[1] == "scene graph"
    got = candidate_objects(room, "please sit on the chair farthest from the door")
    assert ids(got) == [2] and got[1] == "scene graph"
    got = candidate_objects(room, "sit on the chair closest to the door", "adm")
    assert ids(got) == [1, 2] and got[1] == "class"
    assert candidate_objects(room, "sit on the chair")[1] == "class"
    assert ids(candidate_objects(room, "walk to the door")) == [3]
    assert candidate_objects(room, "dance a little") == ([], "")
    # a relation that picks none of the named objects leaves them all to the ADM
    got = candidate_objects(room, "sit on the chair on the table")
    assert ids(got) == [1, 2] and got[1] == "class"


def test_region_probe(tiny_runs):
    from jaxmotion.eval.region_probe import main, region_probe

    root, out = tiny_runs
    kw = dict(split="test", num_cases=6, steps=2, seed=0)
    auto = region_probe(out["data"], root / "adm", root / "amdm", **kw)
    adm = region_probe(out["data"], root / "adm", root / "amdm", grounding="adm", **kw)
    assert auto["cases"] == adm["cases"] >= 1 and auto["chance"] == adm["chance"]
    assert 0.0 < auto["chance"] <= 1.0 and 0.0 <= adm["hit"] <= 1.0
    # the synthetic instructions are unique referring expressions: the scene graph resolves
    # every one, so generate's region choice finds every target
    assert auto["hit"] == 1.0
    with pytest.raises(ValueError, match="grounding"):
        region_probe(out["data"], root / "adm", root / "amdm", grounding="graph", **kw)
    assert main(["--data", str(out["data"]), "--adm", str(root / "adm"), "--amdm",
                 str(root / "amdm"), "--split", "test", "--cases", "2", "--steps", "2"]) == 0
