"""`jaxmotion eval --protocol generate` (crops where generate puts them) and the ADM's
``exclude`` (the other objects of the target's class left out of its map)."""

import json

import jax
import numpy as np
import pytest

from jaxmotion.eval.runner import ModelSpec, evaluate, format_markdown, load_eval_cases, score_cases


def _pipe(root):
    from jaxmotion.pipelines.affordance import AffordancePipeline

    return AffordancePipeline.from_workdirs(root / "adm", root / "amdm")


def test_crop_sample_at_a_given_centre():
    from jaxmotion.data.crop import CropSpec, crop_sample

    rng = np.random.default_rng(0)
    xyz = rng.uniform([0, 0, 0], [6, 5, 2], (4000, 3)).astype(np.float32)
    inst = (xyz[:, 0] > 3).astype(np.int32)
    joints = np.zeros((10, 22, 3), np.float32) + [1.0, 1.0, 0.9]
    spec = CropSpec(size=2.0, num_points=256, rotate=False)
    c = crop_sample(rng, xyz, xyz[:, :3] / 6, inst, joints, np.ones(10, bool), 1, spec,
                    centre=(4.5, 2.5))
    np.testing.assert_allclose(c.shift[:2], [4.5, 2.5])
    world = c.to_world(c.points)
    assert np.all(np.abs(world[:, :2] - [4.5, 2.5]) <= 1.0 + 1e-5)
    assert c.target_mask.all()  # every point of the square is on object 1 (x > 3)
    np.testing.assert_allclose(c.to_world(c.joints), joints, atol=1e-5)
    with pytest.raises(ValueError, match="no scene point"):
        crop_sample(rng, xyz, xyz, inst, joints, np.ones(10, bool), 1, spec, centre=(40, 40))


def test_same_class_others():
    from jaxmotion.grounding import same_class_others

    objects = [{"id": 1, "category": "chair"}, {"id": 2, "category": "chair"},
               {"id": 3, "category": "table"}, {"id": 4, "category": "chair"}]
    assert same_class_others(objects, 2) == [1, 4]
    assert same_class_others(objects, 3) == []
    assert same_class_others(objects, None) == [] and same_class_others(objects, 9) == []


def _two_cases(tiny_runs):
    """The pipeline, two test cases and their stacked points, colours and text."""
    from jaxmotion.data.cases import case_inputs, load_cases

    root, out = tiny_runs
    pipe = _pipe(root)
    cases, _ = load_cases(out["data"], "test", pipe.amdm_config, num_cases=2)
    x = case_inputs(cases, [0, 1])
    return pipe, cases, x, pipe.embed_text([c["text"] for c in cases])


def test_exclude_keeps_the_map_off_those_points(tiny_runs):
    from jaxmotion.diffusion import SamplerSpec

    pipe, cases, x, emb = _two_cases(tiny_runs)
    pts, col = x["points"], x["colors"]
    spec, key = SamplerSpec("ddim", 3), jax.random.key(4)
    free = np.asarray(pipe.sample_affordance(key, pts, col, emb, spec))
    none = np.asarray(pipe.sample_affordance(key, pts, col, emb, spec,
                                             np.zeros(pts.shape[:2], bool)))
    np.testing.assert_array_equal(free, none)  # nothing excluded: the same maps
    ex = np.zeros(pts.shape[:2], bool)
    ex[:, ::3] = True
    got = np.asarray(pipe.sample_affordance(key, pts, col, emb, spec, ex))
    assert np.abs(got[ex]).max() <= 1e-6 and free[ex].max() > 1e-3
    assert not np.allclose(got[~ex], free[~ex])  # the rest is sampled around the hole
    with pytest.raises(ValueError, match="exclude must be"):
        pipe.sample_affordance(key, pts, col, emb, spec, ex[:, :10])
    view = {"points": pts, "colors": col, "in_crop": pts}
    with pytest.raises(ValueError, match="leave exclude out"):
        pipe.sample(key, pts, col, emb, x["mask"], adm=spec,
                    amdm=spec, view=view, exclude=ex)


def test_generate_protocol_cases(tiny_runs):
    """Crops centred where generate would put them, goal points from the whole room, and
    the exclusion mask on the other objects of the chosen object's class."""
    from jaxmotion.data.format import load_sample
    from jaxmotion.diffusion import SamplerSpec
    from jaxmotion.eval.region_probe import case_regions
    from jaxmotion.grounding import find_object, object_table, same_class_others
    from jaxmotion.grounding.region import centre_on_object
    from jaxmotion.scene import load_scene

    root, out = tiny_runs
    pipe = _pipe(root)
    regions = case_regions(out["data"], "test", pipe, num_cases=6, sampler=SamplerSpec("ddim", 2))
    cases = load_eval_cases(out["data"], "test", pipe.amdm_config, 6, 0, regions, exclude=True)
    assert len(cases) == len(regions) >= 2  # the tiny test split has 4 cases
    for c, r in zip(cases, regions, strict=True):
        s = load_sample(out["data"] / "samples" / "test" / c["file"])
        room = load_scene(out["data"] / "scenes" / f"{s['scene_id']}.npz")
        assert r["target"] == int(s["target_id"]) and r["chosen"] == r["target"]
        np.testing.assert_allclose(c["shift"][:2], r["centre"], atol=1e-5)
        lo, hi = room.xyz[:, :2].min(0), room.xyz[:, :2].max(0)
        obj = find_object(room, r["chosen"])
        np.testing.assert_allclose(r["centre"], centre_on_object(obj, lo, hi, 4.0))
        # goal points: the target's points of the room, in the crop frame
        world = c["goal_points"] @ c["rotation"] + c["shift"]
        on = room.xyz[room.instance == r["target"]]
        d = np.sqrt(((world[:, None] - on[None]) ** 2).sum(-1)).min(1)
        assert d.max() < 1e-4 and len(world) == len(c["points"])
        others = same_class_others(object_table(room), r["chosen"])
        np.testing.assert_array_equal(c["exclude"], np.isin(c["instance"], others))
        assert not (c["exclude"] & c["target_mask"]).any()
    with pytest.raises(ValueError, match="crop centres for"):
        from jaxmotion.data.cases import load_cases

        load_cases(out["data"], "test", pipe.amdm_config, num_cases=3, centres=[(0, 0)])


def test_a_target_outside_the_crop_scores_its_true_distance():
    """Generate protocol: a region without the target gives the goal distance to the
    target's points elsewhere in the room (not a missing value) and instance success 0."""
    from jaxmotion.eval.joint_spheres import joints_goal_distance
    from jaxmotion.eval.runner import physical_fn

    rng = np.random.default_rng(1)
    n, t = 256, 8
    points = rng.uniform([-2, -2, 0], [2, 2, 1], (n, 3)).astype(np.float32)
    goal = (rng.uniform([0, 0, 0], [0.4, 0.4, 0.5], (n, 3)) + [3.0, 0, 0]).astype(np.float32)
    joints = np.broadcast_to(rng.uniform(-0.3, 0.3, (1, 22, 3)) + [0, 0, 0.9],
                             (1, t, 22, 3)).astype(np.float32)
    cls = np.zeros(n, bool)
    cls[:20] = True
    case = dict(points=points, goal_points=goal, target_mask=np.zeros(n, bool),
                target_class_mask=cls, mask=np.ones(t, bool), action="sit")
    affs = [[np.full((n, 6), 0.5, np.float32)]]
    rows = score_cases([case], joints[None], affs, physical_fn(False, 30.0), False, 30.0,
                        [], None)
    want = float(joints_goal_distance(goal, joints[0, -1]))
    assert want > 2.0 and rows[0]["goal_distance"] == pytest.approx(want, rel=1e-5)
    assert rows[0]["instance_success@0.3"] == 0.0 and "success@0.3" in rows[0]
    # no object of the class in the crop either: still a miss, no class columns
    rows = score_cases([{**case, "target_class_mask": np.zeros(n, bool)}], joints[None], affs,
                        physical_fn(False, 30.0), False, 30.0, [], None)
    assert rows[0]["instance_success@0.3"] == 0.0 and "success@0.3" not in rows[0]


def test_runner_generate_protocol(tiny_runs, tmp_path):
    from jaxmotion.cli import main

    root, out = tiny_runs
    spec = [ModelSpec("two", str(root / "adm"), str(root / "amdm"), "ddim", 2)]
    kw = dict(num_cases=3, samples=2, replications=1, body=False, batch_size=4, progress=False)
    rep = evaluate(out["data"], spec, protocol="generate", **kw)
    m = rep["models"]["two"]
    assert rep["settings"]["protocol"] == "generate" and rep["settings"]["grounding"] == "auto"
    assert m["regions"]["hit"] == 1.0 and sum(m["regions"]["how"].values()) == 3
    s = m["summary"]
    for k in ("goal_distance", "contact", "non_collision", "instance_success@0.3"):
        assert np.isfinite(s[k]["mean"]), k
    md = format_markdown(rep)
    assert "Protocol **generate**" in md and "region centred on the target in 100.0 %" in md
    paper = evaluate(out["data"], spec, **kw)
    assert paper["settings"]["protocol"] == "paper" and "regions" not in paper["models"]["two"]
    assert "Protocol" not in format_markdown(paper)
    with pytest.raises(ValueError, match="protocol must be"):
        evaluate(out["data"], spec, protocol="room", **kw)
    with pytest.raises(ValueError, match="grounding must be"):
        evaluate(out["data"], spec, protocol="generate", grounding="graph", **kw)
    args = ["eval", "--data", str(out["data"]), "--model",
            f"two={root / 'adm'},{root / 'amdm'},ddim2", "--cases", "2", "--samples", "1",
            "--replications", "1", "--joints-only", "--protocol", "generate", "--grounding",
            "adm", "--out", str(tmp_path)]
    assert main(args) == 0
    assert "grounding `adm`" in (tmp_path / "results.md").read_text()
    rows = [json.loads(x) for x in (tmp_path / "cases.jsonl").read_text().splitlines()]
    assert len(rows) == 2 and all(r["region_how"] for r in rows)
    hit = json.loads((tmp_path / "results.json").read_text())["models"]["two"]["regions"]["hit"]
    assert np.mean([r["region_object"] == r["target_object"] for r in rows]) == hit


def test_best_of_keeps_the_map_that_lights_the_target(tiny_runs):
    from jaxmotion.diffusion import SamplerSpec
    from jaxmotion.pipelines.affordance import adm_map_one

    pipe, cases, x, emb = _two_cases(tiny_runs)
    pts, col = x["points"], x["colors"]
    spec, key = SamplerSpec("ddim", 3), jax.random.key(5)
    target = np.stack([c["target_mask"] for c in cases])
    maps = np.asarray(pipe.sample_affordances(key, pts, col, emb, spec, None, 3))
    assert maps.shape == (2, 3, pts.shape[1], 6)
    # candidate 0 is the single draw; candidate j of example b is drawn with fold_in(k_b, j)
    # (the same draws in other programs: equal up to float32 summation order)
    first = np.asarray(pipe.sample_affordance(key, pts, col, emb, spec))
    np.testing.assert_allclose(maps[:, 0], first, atol=2e-3)
    kb = jax.random.split(key, 2)
    for b in range(2):
        one = np.asarray(adm_map_one(pipe.adm_net, pipe.adm_schedule, (pipe.a_mean, pipe.a_std),
                                     jax.random.fold_in(kb[b], 2), pts[b], col[b],
                                     jax.tree.map(lambda a: a[b], emb), spec))
        np.testing.assert_allclose(maps[b, 2], one, atol=2e-3)
    assert not np.allclose(maps[:, 0], maps[:, 1])
    got = np.asarray(pipe.best_of(key, pts, col, emb, spec, None, target, 3))
    for b in range(2):  # brute force: the largest mean of the strongest channel on the target
        scores = [m.max(-1)[target[b]].mean() for m in maps[b]]
        np.testing.assert_allclose(got[b], maps[b, int(np.argmax(scores))], atol=1e-5)
    none = np.asarray(pipe.best_of(key, pts, col, emb, spec, None, np.zeros_like(target), 3))
    np.testing.assert_allclose(none, first, atol=2e-3)  # no target: the first map
    mask = x["mask"]
    with pytest.raises(ValueError, match="known target"):
        pipe.sample(key, pts, col, emb, mask, adm=spec, amdm=spec, candidates=2)


def test_best_motion_keeps_the_motion_that_reaches_the_target(tiny_runs):
    from jaxmotion.diffusion import SamplerSpec
    from jaxmotion.eval.plausibility import plausibility
    from jaxmotion.scene.instructions import anchor_is_first

    pipe, cases, x, emb = _two_cases(tiny_runs)
    pts, col, mask = x["points"], x["colors"], x["mask"].copy()
    mask[1, -3:] = False  # a shorter motion: its last valid frame is not the last frame
    spec, key = SamplerSpec("ddim", 2), jax.random.key(3)
    target = np.stack([c["target_mask"] for c in cases])
    aff = np.asarray(pipe.sample_affordance(key, pts, col, emb, spec))
    motions = np.asarray(pipe.sample_motions(key, pts, aff, emb, mask, spec, 3))
    assert motions.shape == (2, 3, *cases[0]["gt"].shape)
    first = np.asarray(pipe.sample_motion(key, pts, aff, emb, mask, spec))
    np.testing.assert_allclose(motions[:, 0], first, atol=2e-3)
    kb = jax.random.split(key, 2)
    for b in range(2):
        one = np.asarray(pipe.motion_one(jax.random.fold_in(kb[b], 1), pts[b], aff[b],
                                          jax.tree.map(lambda a: a[b], emb), mask[b], spec))
        np.testing.assert_allclose(motions[b, 1], one, atol=2e-3)
    anchor_first = np.array([False, True])
    got = np.asarray(pipe.best_motion(key, pts, aff, emb, mask, spec, target, anchor_first, 3))
    for b in range(2):  # brute force: the closest joint-to-target distance at the anchor,
        valid = np.flatnonzero(mask[b])  # among the candidates that do not teleport if any
        t = valid[0] if anchor_first[b] else valid[-1]
        jumps = np.asarray(plausibility(motions[b], np.repeat(mask[b][None], 3, 0))["teleport"])
        scores = [(bool(jump), min(np.linalg.norm(p - j) for p in pts[b][target[b]] for j in m[t]))
                  for m, jump in zip(motions[b], jumps)]
        np.testing.assert_allclose(got[b], motions[b, scores.index(min(scores))], atol=1e-5)
    none = np.asarray(pipe.best_motion(key, pts, aff, emb, mask, spec, np.zeros_like(target),
                                       anchor_first, 3))
    np.testing.assert_allclose(none, first, atol=2e-3)  # no target: the first motion
    with pytest.raises(ValueError, match="known target"):
        pipe.sample(key, pts, col, emb, mask, adm=spec, amdm=spec, motion_candidates=2)
    # one candidate is the plain sampler, bit for bit
    a = pipe.sample(key, pts, col, emb, mask, adm=spec, amdm=spec)
    b = pipe.sample(key, pts, col, emb, mask, adm=spec, amdm=spec, target=target,
                    motion_candidates=1)
    np.testing.assert_array_equal(np.asarray(a["joints"]), np.asarray(b["joints"]))
    assert anchor_is_first("Now get up off the chair next to the door.")
    assert anchor_is_first("stand up") and anchor_is_first("Rise from the stool!")
    assert not anchor_is_first("sit on the chair next to the table")
    assert not anchor_is_first("walk up to the stool")


def test_best_motion_never_keeps_a_jump_while_a_smooth_candidate_exists(tiny_runs, monkeypatch):
    from jaxmotion.diffusion import SamplerSpec

    pipe, cases, x, emb = _two_cases(tiny_runs)
    pts, mask = x["points"], x["mask"]
    target = np.stack([c["target_mask"] for c in cases])
    t = mask.shape[1]
    centre = np.stack([p[m].mean(0) for p, m in zip(pts, target)])  # [2, 3]
    walk = np.linspace(0.0, 1.0, t)[:, None]  # 1 m over the motion: 0.25 m/s or so
    smooth = centre[:, None, None] + np.array([0.3, 0, 0]) + np.array([0.6, 0, 0]) * (
        1 - walk)[None, :, None]  # ends 0.3 m off the target's centre
    jump = np.repeat(centre[:, None, None], t, 1) + np.zeros((1, 1, 22, 3))
    jump[:, : t // 2] += np.array([1.5, 0, 0])  # at the target at the end, but 1.5 m in a frame
    smooth = np.broadcast_to(smooth, jump.shape)
    candidates = np.stack([jump, smooth, jump + 0.4], axis=1).astype(np.float32)  # [2,3,T,22,3]
    monkeypatch.setattr(pipe, "sample_motions", lambda *a, **k: candidates)
    spec = SamplerSpec("ddim", 2)
    got = np.asarray(pipe.best_motion(jax.random.key(0), pts, x["colors"], emb, mask, spec,
                                      target, None, 3))
    np.testing.assert_array_equal(got, candidates[:, 1])  # the smooth one, though farther
    only_jumps = np.stack([jump, jump + 0.4, jump], axis=1).astype(np.float32)
    monkeypatch.setattr(pipe, "sample_motions", lambda *a, **k: only_jumps)
    got = np.asarray(pipe.best_motion(jax.random.key(0), pts, x["colors"], emb, mask, spec,
                                      target, None, 3))
    np.testing.assert_array_equal(got, only_jumps[:, 0])  # all jump: the closest


def _generate_protocol_only(tiny_runs, **option):
    """A candidates option of `jaxmotion eval` is refused under the paper protocol and runs
    under the generate protocol."""
    root, out = tiny_runs
    spec = [ModelSpec("c", str(root / "adm"), str(root / "amdm"), "ddim", 2, **option)]
    kw = dict(num_cases=2, samples=1, replications=1, body=False, batch_size=4, progress=False)
    with pytest.raises(ValueError, match="needs --protocol generate"):
        evaluate(out["data"], spec, **kw)
    rep = evaluate(out["data"], spec, protocol="generate", **kw)
    assert np.isfinite(rep["models"]["c"]["summary"]["goal_distance"]["mean"])


def _demo_chair(root):
    """The demo room, its chair and fast `generate` settings with the tiny checkpoints."""
    from jaxmotion.scene.demo import demo_scene

    scene = demo_scene()
    chair = next(o for o in scene.objects if o["category"] == "chair")
    fast = dict(checkpoints=(str(root / "adm"), str(root / "amdm")), fit=False, steps=2,
                adm_steps=2, seed=1, pipeline="affordance")  # ADM maps and AMDM candidates
    return scene, chair, fast


@pytest.mark.slow
def test_adm_candidates_in_eval_and_generate(tiny_runs):
    import jaxmotion
    from jaxmotion.errors import GenerateError
    from jaxmotion.eval.runner import parse_model

    root, _ = tiny_runs
    m = parse_model("c=x,y,ddim4,adm_candidates=3")
    assert m.adm_candidates == 3 and m.sampler_label == "DDIM-4 (best of 3 ADM maps)"
    m = parse_model("c=x,y,ddim4,adm_candidates=3,adm_steps=2")
    assert m.adm_steps == 2 and m.sampler_label == "DDIM-4 (ADM DDIM-2, best of 3 ADM maps)"
    assert parse_model("c=x,y,ddim4").adm_steps is None
    for bad, msg in (("c=x,y,adm_candidates=0", "adm_candidates must be"),
                     ("c=x,y,adm_candidates=two", "adm_candidates must be"),
                     ("c=x,y,adm_steps=0", "adm_steps must be"),
                     ("c=x,y,ddpm,adm_steps=5", "needs a DDIM sampler")):
        with pytest.raises(ValueError, match=msg):
            parse_model(bad)
    _generate_protocol_only(tiny_runs, adm_candidates=2, adm_steps=1)
    scene, chair, fast = _demo_chair(root)
    a = jaxmotion.generate(scene, "sit down", object_id=chair["id"], adm_candidates=3, **fast)
    b = jaxmotion.generate(scene, "sit down", object_id=chair["id"], adm_candidates=3, **fast)
    np.testing.assert_array_equal(a.joints, b.joints)
    assert a.adm_candidates == 3
    for bad in (0, 33, 2.5):
        with pytest.raises(GenerateError, match="adm_candidates must be"):
            jaxmotion.generate(scene, "sit down", adm_candidates=bad, **fast)
    with pytest.raises(GenerateError, match="adm_steps must be"):
        jaxmotion.generate(scene, "sit down", **{**fast, "adm_steps": 0})


@pytest.mark.slow
def test_motion_candidates_in_eval_and_generate(tiny_runs):
    import jaxmotion
    from jaxmotion.errors import GenerateError
    from jaxmotion.eval.runner import parse_model

    root, _ = tiny_runs
    m = parse_model("c=x,y,ddim4,adm_candidates=3,motion_candidates=2")
    assert m.motion_candidates == 2
    assert m.sampler_label == "DDIM-4 (best of 3 ADM maps, best of 2 motions)"
    assert parse_model("c=x,y").motion_candidates == 1
    for bad in ("c=x,y,motion_candidates=0", "c=x,y,motion_candidates=two"):
        with pytest.raises(ValueError, match="motion_candidates must be"):
            parse_model(bad)
    _generate_protocol_only(tiny_runs, motion_candidates=2)
    scene, chair, fast = _demo_chair(root)
    fast["adm_candidates"] = 1
    one = jaxmotion.generate(scene, "sit down", object_id=chair["id"], motion_candidates=1,
                             **fast)
    a = jaxmotion.generate(scene, "sit down", object_id=chair["id"], motion_candidates=3,
                           **fast)
    b = jaxmotion.generate(scene, "sit down", object_id=chair["id"], motion_candidates=3,
                           **fast)
    np.testing.assert_array_equal(a.joints, b.joints)  # same seed, same pick
    assert a.motion_candidates == 3 and one.motion_candidates == 1

    def reach(res):  # the last frame's closest joint to the chair's points in the crop
        chair_pts = {tuple(p) for p in scene.xyz[scene.instance == chair["id"]].astype(np.float32)}
        pts = np.array([p for p in res.crop_xyz if tuple(p) in chair_pts])
        assert len(pts) > 0
        return np.linalg.norm(pts[:, None] - res.joints[0, -1][None], axis=-1).min()

    assert reach(a) <= reach(one) + 1e-6  # the first candidate is the one-motion result
    for bad in (0, 17, 1.5):
        with pytest.raises(GenerateError, match="motion_candidates must be"):
            jaxmotion.generate(scene, "sit down", motion_candidates=bad, **fast)
