"""`jaxmotion generate` and `jaxmotion.generate`: inputs, errors, outputs, determinism.

Uses the tiny trained runs (conftest ``tiny_runs``) so it does not depend on the shipped
checkpoints; ``test_shipped_default`` runs the real default when it is installed."""

import json
import re

import numpy as np
import pytest

import jaxmotion
import jaxmotion.export
import jaxmotion.options
import jaxmotion.scene.demo
from jaxmotion.errors import GenerateError

FAST = dict(steps=2, adm_steps=2, fit_iters=5, pipeline="affordance")  # the tiny AMDM


@pytest.fixture(scope="module")
def ckpt(tiny_runs):
    root, _ = tiny_runs
    return (str(root / "adm"), str(root / "amdm"))


@pytest.fixture(scope="module")
def result(ckpt):
    return jaxmotion.generate("demo", "sit on the chair next to the table", samples=2, seed=3,
                              checkpoints=ckpt, **FAST)


def test_shipped_demo_room_is_the_seeded_room():
    from jaxmotion.scene.demo import build_demo_scene, demo_scene

    a, b = demo_scene(), build_demo_scene()
    for k in ("xyz", "rgb", "normal", "semantic", "instance"):
        np.testing.assert_array_equal(getattr(a, k), getattr(b, k), err_msg=k)
    assert a.objects == b.objects and a.name == "demo"
    assert {"chair", "table"} <= {o["category"] for o in a.objects}


def test_target_category_is_the_first_one_the_text_names():
    from jaxmotion.grounding import mentioned_objects
    from jaxmotion.scene.demo import demo_scene

    room = demo_scene()
    ids = lambda t: [o["id"] for o in mentioned_objects(room, t)]  # noqa: E731
    chair = [o["id"] for o in room.objects if o["category"] == "chair"]
    stools = [o["id"] for o in room.objects if o["category"] == "stool"]
    assert ids("sit on the chair next to the table") == chair
    assert ids("Walk over to the STOOLS, then stop.") == stools
    assert ids("dance") == [] and ids("sit on the chairman") == []


def test_object_table_from_point_labels_and_synonyms():
    import dataclasses

    from jaxmotion.grounding import mentioned_objects, object_table
    from jaxmotion.scene.demo import demo_scene

    room = demo_scene()
    bare = dataclasses.replace(room, objects=())  # a labelled scan: per-point ids only
    derived = {o["id"]: o for o in object_table(bare)}
    for o in room.objects:
        assert derived[o["id"]]["category"] == o["category"]
        np.testing.assert_array_less(np.asarray(o["bbox_min"]) - 0.05, derived[o["id"]]["bbox_min"])
    fridge = [o["id"] for o in room.objects if o["category"] == "fridge"]
    assert [o["id"] for o in mentioned_objects(bare, "open the refrigerator")] == fridge


def test_shapes_frame_and_fit(result):
    r = result
    assert r.joints.shape == (2, 120, 22, 3) and np.isfinite(r.joints).all()
    assert r.smplx["body_pose"].shape == (2, 120, 21, 3) and r.smplx["betas"].shape == (2, 10)
    assert r.affordance.shape[0] == 2 and r.affordance.shape[2] == 6
    # the crop frame maps back onto the scene: crop points are scene points
    lo, hi = r.scene.xyz.min(0), r.scene.xyz.max(0)
    assert np.all(r.crop_xyz >= lo - 1e-5) and np.all(r.crop_xyz <= hi + 1e-5)
    assert r.fit_error.shape == (2,) and np.isfinite(r.fit_error).all()
    assert "sample" in r.timings and "region" in r.timings
    chair = next(o for o in r.scene.objects if o["category"] == "chair")
    assert r.target_id == chair["id"]  # the only chair of the demo room


def test_same_seed_same_output_and_seeds_differ(result, ckpt):
    called = []  # meanwhile: once, as the sampling starts
    again = jaxmotion.generate("demo", "sit on the chair next to the table", samples=2, seed=3,
                               checkpoints=ckpt, meanwhile=lambda: called.append(1),
                               **FAST)  # now from the cached exported programs
    assert called == [1]
    np.testing.assert_array_equal(again.joints, result.joints)
    np.testing.assert_array_equal(again.smplx["body_pose"], result.smplx["body_pose"])
    assert not np.array_equal(result.joints[0], result.joints[1])
    traced = jaxmotion.generate("demo", "sit on the chair next to the table", samples=2, seed=3,
                                checkpoints=ckpt, aot=False, **FAST)
    np.testing.assert_allclose(traced.joints, result.joints, atol=1e-5)


@pytest.mark.parametrize("kwargs, match", [
    (dict(text=""), "text is empty"),
    (dict(text="   "), "text is empty"),
    (dict(text="walk " * 400), "too long"),
    (dict(text="walk " * 255), "too long"),
    (dict(object_id=999), "unknown object id 999"),
    (dict(samples=0), "samples must be"),
    (dict(steps=0), "steps must be"),
    (dict(scene="no/such/room.ply"), "no such file"),
    (dict(guidance=0.0), "guidance must be"),
    (dict(guidance=(1.0, 2.0, 3.0)), "guidance must be"),
    (dict(guidance=("a", 1.0)), "guidance must be"),
    (dict(guidance=float("nan")), "guidance must be"),
    (dict(consistency=1.5), "consistency must be"),
    (dict(consistency="strong"), "consistency must be"),
    (dict(consistency=True), "consistency must be"),
])
def test_bad_input_is_a_clear_error(ckpt, kwargs, match):
    args = {"scene": "demo", "text": "sit on the chair", **FAST, **kwargs}
    late = lambda: pytest.fail("meanwhile is called only once the input is known to be good")
    with pytest.raises(GenerateError, match=match):
        jaxmotion.generate(args.pop("scene"), args.pop("text"), checkpoints=ckpt, meanwhile=late,
                           **args)


@pytest.mark.slow  # ~50 s on 2 cores: two more generate calls
def test_guidance_per_stage(result, ckpt):
    """One scale sets both stages, a pair sets each; the scales change the motion (the ADM's
    scale also its maps) and are recorded; an AMDM-only scale leaves the ADM maps as they were."""
    from jaxmotion.options import DEFAULT_GUIDANCE

    assert result.guidance == DEFAULT_GUIDANCE
    kw = dict(samples=2, seed=3, checkpoints=ckpt, **FAST)
    both = jaxmotion.generate("demo", "sit on the chair next to the table", guidance=3.0, **kw)
    assert both.guidance == (3.0, 3.0)
    assert not np.allclose(both.joints, result.joints, atol=1e-4)
    base = jaxmotion.generate("demo", "sit on the chair next to the table", guidance=(1.0, 1.0),
                              **kw)
    motion_only = jaxmotion.generate("demo", "sit on the chair next to the table",
                                     guidance=(1.0, 3.0), **kw)
    assert motion_only.guidance == (1.0, 3.0)
    np.testing.assert_allclose(motion_only.affordance, base.affordance, atol=1e-6)
    assert not np.allclose(motion_only.joints, base.joints, atol=1e-4)


def test_consistency_guidance(result, ckpt):
    """The default strength is recorded; 0 turns it off: the same maps, another motion."""
    from jaxmotion.options import DEFAULT_CONSISTENCY

    assert result.consistency == DEFAULT_CONSISTENCY > 0
    kw = dict(samples=2, seed=3, checkpoints=ckpt, **FAST)
    on = jaxmotion.generate("demo", "sit on the chair next to the table", **kw)
    off = jaxmotion.generate("demo", "sit on the chair next to the table", consistency=0, **kw)
    assert (on.consistency, off.consistency) == (DEFAULT_CONSISTENCY, 0.0)
    np.testing.assert_allclose(on.affordance, off.affordance, atol=1e-6)
    assert not np.allclose(on.joints, off.joints, atol=1e-4)


def test_checkpoints_that_do_not_match(ckpt, tmp_path):
    with pytest.raises(GenerateError, match="no such checkpoint"):
        jaxmotion.generate("demo", "sit", checkpoints=tmp_path, **FAST)
    with pytest.raises(GenerateError, match="do not load together|not an AMDM"):
        jaxmotion.generate("demo", "sit", checkpoints=(ckpt[0], ckpt[0]), **FAST)


def test_empty_scene_is_an_error(ckpt, tmp_path):
    p = tmp_path / "empty.ply"
    p.write_text("ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\nproperty float y\n"
                 "property float z\nend_header\n")
    with pytest.raises(GenerateError):
        jaxmotion.generate(p, "sit", checkpoints=ckpt, **FAST)


def test_save_writes_every_output_that_readers_open(result, tmp_path):
    import imageio.v3 as iio
    import trimesh

    from jaxmotion.export import read_bvh

    files = result.save(tmp_path / "out")
    assert sorted(files) == sorted(["motion.npz", "motion.bvh", "motion_smplx.npz", "motion.glb",
                                    "motion.mp4", "viewer.html"])
    d = np.load(files["motion.npz"])
    assert d["joints"].shape == (2, 120, 22, 3) and float(d["fps"]) == 30.0
    assert str(d["text"]) == result.text and d["body_pose"].shape == (2, 120, 21, 3)
    assert d["scene_rotation"].shape == (3, 3) and d["scene_shift"].shape == (3,)
    bvh = read_bvh(files["motion.bvh"])
    assert len(bvh.names) == 22 and bvh.frames.shape[0] == 120
    assert len(trimesh.load(files["motion.glb"]).geometry) >= 1
    video = iio.imread(files["motion.mp4"], plugin="FFMPEG").astype(int)
    assert video.shape[1:] == (480, 640, 3) and len(video) == 60  # 120 frames at 15 fps
    # the rendered mannequins, sample 0 blue (the tiny model's bodies are small and tangled),
    # moving between frames
    blue = video[30, ..., 2] > 1.3 * video[30, ..., 0] + 5
    assert blue.mean() > 1e-3 and (np.abs(video[30] - video[0]).sum(-1) > 60).mean() > 1e-3
    html = files["viewer.html"].read_text()
    assert "https://" not in html and "http://" not in html
    page = json.loads(re.search(r'id="jm-data">(.*?)</script>', html, re.DOTALL).group(1))
    assert page["body"]["bones"]["shape"][:2] == [2, 120]  # the skinned mannequins
    assert len(page["objects"]) == len(result.scene.objects)
    if result.target_id is not None:
        assert page["objects"][page["target"]]["id"] == result.target_id
    assert not [p for p in (tmp_path / "out").iterdir() if p.name.startswith(".")]


def test_save_leaves_nothing_half_written(result, tmp_path, monkeypatch):
    from jaxmotion import export

    def boom(*a, **k):
        raise OSError("disk full")

    monkeypatch.setattr(export, "write_glb", boom)
    with pytest.raises(OSError, match="disk full"):
        result.save(tmp_path / "out")
    assert list(tmp_path.iterdir()) == []  # no new folder, no temporary one left
    (tmp_path / "kept").mkdir()
    (tmp_path / "kept" / "notes.txt").write_text("mine")
    with pytest.raises(OSError, match="disk full"):
        result.save(tmp_path / "kept")
    assert [p.name for p in (tmp_path / "kept").iterdir()] == ["notes.txt"]


def test_output_folder_is_checked_before_any_work(tmp_path):
    from jaxmotion.errors import GenerateError
    from jaxmotion.export import check_output_folder

    (tmp_path / "file").write_text("x")
    with pytest.raises(GenerateError, match="is a file"):
        check_output_folder(tmp_path / "file")
    with pytest.raises(GenerateError, match="is a file"):
        check_output_folder(tmp_path / "file" / "sub")
    assert check_output_folder(tmp_path / "new" / "deeper") == tmp_path / "new" / "deeper"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["file"]  # the check leaves nothing


def test_what_was_understood_is_said(result, ckpt):
    """The result and its summary say the action and how the target was chosen; several
    objects that fit, or an action the models do not know, are warnings; an action the room
    has nothing for is a clear error before any model runs."""
    line = json.loads(jaxmotion.export.summary(result))
    assert line["action"] == "sit" and line["target"] == f"chair {result.target_id}"
    assert any(n.startswith(f"target: chair {result.target_id}") for n in line["notes"])
    assert line["warnings"] == [] and result.understanding.how == result.grounding
    stools = [o["id"] for o in jaxmotion.scene.demo.demo_scene().objects
              if o["category"] == "stool"]
    with pytest.warns(UserWarning, match="2 objects fit the text") as rec:
        r = jaxmotion.generate("demo", "Could you park yourself on the stool?",
                               checkpoints=ckpt, fit=False, **FAST)
    assert r.target_id in stools and r.understanding.action == "sit"
    assert "--object ID" in str(rec[0].message)
    with pytest.raises(GenerateError, match="no beds or sofas to lie on"):
        jaxmotion.generate("demo", "lie down on the bed", checkpoints=ckpt, fit=False, **FAST)


def test_text_embedding_cache(tmp_path):
    from jaxmotion.text.cache import close_shared
    from jaxmotion.text.condition import embed_one, text_encoder

    fresh = embed_one("sit on the sofa", tmp_path)
    assert len(list(tmp_path.glob("*.npz"))) == 1
    np.testing.assert_array_equal(embed_one("sit on the sofa", tmp_path), fresh)  # from the file
    np.testing.assert_allclose(fresh, text_encoder()(["sit on the sofa"]), atol=1e-6)
    next(tmp_path.glob("*.npz")).write_bytes(b"broken")  # a damaged entry is recomputed
    close_shared()  # (by a new process: this one holds the entry in memory)
    with pytest.warns(UserWarning, match="unreadable embedding shard"):
        np.testing.assert_array_equal(embed_one("sit on the sofa", tmp_path), fresh)
