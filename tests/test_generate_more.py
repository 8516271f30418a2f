"""`jaxmotion generate` end to end, continued: the command line, the region and pipeline choices
(the object id, the text-only ADM, the object-centric default), compiled programs reused.

Split from ``test_generate.py`` so that the two run in parallel test workers; uses the same tiny
trained runs (conftest ``tiny_runs``)."""

import dataclasses
import json

import numpy as np
import pytest

import jaxmotion
import jaxmotion.scene.demo
from jaxmotion.errors import GenerateError
from jaxmotion.pipelines.checkpoints import default_checkpoints

FAST = dict(steps=2, adm_steps=2, fit_iters=5, pipeline="affordance")  # the tiny AMDM


@pytest.fixture(scope="module")
def ckpt(tiny_runs):
    root, _ = tiny_runs
    return (str(root / "adm"), str(root / "amdm"))


def test_object_id_centres_the_crop_on_the_object(ckpt):
    scene = jaxmotion.scene.demo.demo_scene()
    chair = next(o for o in scene.objects if o["category"] == "chair")
    r = jaxmotion.generate(scene, "sit down", object_id=chair["id"], checkpoints=ckpt, fit=False,
                           **FAST)
    assert r.object_id == chair["id"] and not r.smplx
    centre = 0.5 * (np.asarray(chair["bbox_min"][:2]) + np.asarray(chair["bbox_max"][:2]))
    assert np.linalg.norm(r.crop_xyz[:, :2].mean(0) - centre) < 1.5
    with pytest.raises(GenerateError, match="BVH and GLB need it"):
        r.save("unused")


def test_cli_generate_and_its_errors(ckpt, tmp_path, capsys):
    from jaxmotion.cli import main

    assert main(["generate", "--scene", "missing.ply", "--out", str(tmp_path / "x"),
                 "--checkpoints", *ckpt]) == 2
    assert "no such file" in capsys.readouterr().err
    assert not (tmp_path / "x").exists()
    out = tmp_path / "ok"
    assert main(["generate", "--text", "sit on the chair", "--steps", "2", "--video", "none",
                 "--pipeline", "affordance",
                 "--out", str(out), "--checkpoints", *ckpt]) == 0
    captured = capsys.readouterr()
    stdout = captured.out.strip().splitlines()
    assert len(stdout) == 1  # the JSON summary alone (progress goes to stderr): `| jq` works
    line = json.loads(stdout[0])
    assert line["samples"] == 1 and line["frames"] == 120
    assert line["action"] == "sit" and "action: sit (from the words 'sit')" in captured.err
    assert (out / "motion.bvh").is_file() and not (out / "motion.mp4").exists()
    with np.load(out / "motion.npz") as f:
        from jaxmotion.options import DEFAULT_GUIDANCE

        np.testing.assert_allclose(f["guidance"], DEFAULT_GUIDANCE)
    assert main(["generate", "--text", "sit on the chair", "--steps", "2", "--video", "none",
                 "--pipeline", "affordance",
                 "--guidance", "2,1", "--out", str(tmp_path / "g"), "--checkpoints", *ckpt]) == 0
    with np.load(tmp_path / "g" / "motion.npz") as f:
        np.testing.assert_allclose(f["guidance"], [2.0, 1.0])
    assert main(["generate", "--text", "sit on the chair", "--steps", "2", "--video", "none",
                 "--pipeline", "affordance",
                 "--consistency", "0", "--adm-candidates", "2", "--adm-steps", "3",
                 "--out", str(tmp_path / "c"), "--checkpoints", *ckpt]) == 0
    line = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    with np.load(tmp_path / "c" / "motion.npz") as f:
        assert float(f["consistency"]) == 0.0
        # the demo's one chair is the known target: the maps drawn are recorded
        assert int(f["adm_candidates"]) == line["adm_candidates"] == 2
        assert int(f["adm_steps"]) == line["adm_steps"] == 3 and line["steps"] == 2
    for bad in ("1.5", "x"):
        with pytest.raises(SystemExit):
            main(["generate", "--consistency", bad, "--out", str(tmp_path / "bad")])
        assert "--consistency" in capsys.readouterr().err
    for bad in ("0", "1,2,3", "x"):
        with pytest.raises(SystemExit):
            main(["generate", "--guidance", bad, "--out", str(tmp_path / "bad")])
        assert "--guidance" in capsys.readouterr().err
    assert not (tmp_path / "bad").exists()


@pytest.mark.skipif(not all(p.is_file() for p in default_checkpoints()),
                    reason="the default checkpoints are not installed")
def test_shipped_default():
    r = jaxmotion.generate("demo", samples=1, steps=10, fit=False)
    assert r.joints.shape[1:] == (120, 22, 3) and np.isfinite(r.joints).all()
    assert r.joints[..., 2].min() > -0.1  # nobody sinks into the floor


def _bare_demo():
    """The demo room without its labels: its objects are found by segmentation (none are
    known with ``pipeline="affordance"``, whose model then chooses the place)."""
    import dataclasses

    from jaxmotion.scene.demo import load_scene_arg

    room = load_scene_arg("demo", 20000)
    return dataclasses.replace(room, instance=np.full(room.num_points, -1, np.int32),
                               semantic=np.full(room.num_points, -1, np.int32), objects=())


def test_text_naming_no_object_tiles_the_room(ckpt):
    """A text naming no object: by default a walk to an object drawn with the seed; with
    ``grounding="adm"`` the room is tiled and the object the map lights most in the strongest
    tile is the target; in a room without objects the tiles decide and there is none."""
    r = jaxmotion.generate("demo", "dance around for a while", checkpoints=ckpt, fit=False,
                           **FAST)
    assert r.grounding == "wander" and r.joints.shape == (1, 120, 22, 3)
    assert r.target_id in {int(o["id"]) for o in r.scene.objects}
    r = jaxmotion.generate("demo", "dance around for a while", checkpoints=ckpt, fit=False,
                           grounding="adm", **FAST)
    assert r.grounding == "adm peak" and r.target_id in {int(o["id"]) for o in r.scene.objects}
    r = jaxmotion.generate(_bare_demo(), "dance around for a while", checkpoints=ckpt,
                           fit=False, **FAST)
    assert r.target_id is None and r.joints.shape == (1, 120, 22, 3)


def test_exported_programs_are_reused_only_for_the_same_code_and_shapes(tmp_path, monkeypatch):
    import jaxmotion.compiled as C

    calls = []

    def build():
        calls.append(1)
        return lambda x: x * 2.0

    x = np.arange(3, dtype=np.float32)
    np.testing.assert_array_equal(C.cached_call(tmp_path, "f", "v1", build, (x,)), 2 * x)
    np.testing.assert_array_equal(C.cached_call(tmp_path, "f", "v1", build, (x,)), 2 * x)
    assert len(calls) == 1 and len(list(tmp_path.glob("f-*.jaxexport"))) == 1
    C.cached_call(tmp_path, "f", "v1", build, (np.arange(4, dtype=np.float32),))  # new shape
    monkeypatch.setattr(C, "code_digest", lambda: "edited sources")
    C.cached_call(tmp_path, "f", "v1", build, (x,))  # the code changed: traced again
    assert len(calls) == 3 and len(list(tmp_path.glob("f-*.jaxexport"))) == 3


def test_a_prefetched_program_is_the_one_called(tmp_path):
    """prefetch loads a kept program in the background (only one already on disk), and the
    next cached_program / cached_call for the same program and shapes takes it."""
    import jaxmotion.compiled as C

    x = np.arange(3, dtype=np.float32)
    specs = C.specs_of((x,))
    assert not C.prefetch(tmp_path, "p", "v1", specs)  # nothing kept yet: traced on call
    np.testing.assert_array_equal(C.cached_call(tmp_path, "p", "v1", lambda: lambda a: a + 1,
                                                (x,)), x + 1)
    assert not C.prefetch(tmp_path, "p", "v1", specs)  # loaded in this process already
    C.release()  # as a new process
    assert C.prefetch(tmp_path, "p", "v1", specs) and len(C.prefetched()) == 1
    assert not C.prefetch(tmp_path, "p", "v1", specs)  # already on its way
    unused = lambda: pytest.fail("a prefetched program is not traced again")
    np.testing.assert_array_equal(C.cached_call(tmp_path, "p", "v1", unused, (x,)), x + 1)
    assert C.prefetched() == ()
    # other shapes: another program, and the prefetched one stays until asked for
    C.release()
    assert C.prefetch(tmp_path, "p", "v1", specs)
    C.cached_call(tmp_path, "p", "v1", lambda: lambda a: a + 1, (x[:2],))
    assert len(C.prefetched()) == 1
    C.cached_program(tmp_path, "p", "v1", unused, specs)
    assert C.prefetched() == ()


def test_when_loaded_waits_for_the_prefetched_programs(monkeypatch):
    """when_loaded calls at once with nothing loading; with a load under way, on another
    thread once it has finished (failed, too); the Future gives the result or the error."""
    import threading
    from concurrent.futures import Future

    import jaxmotion.compiled as C

    here = threading.current_thread()
    assert C.when_loaded(lambda: threading.current_thread() is here).result()
    loading = Future()
    monkeypatch.setattr(C, "_PENDING", {"a program": loading})
    seen = []
    done = C.when_loaded(lambda: seen.append(threading.current_thread()) or "ran")
    assert not done.done() and seen == []  # waits for the load
    loading.set_exception(OSError("a load that failed"))
    assert done.result(timeout=10) == "ran" and seen[0] is not here

    def broken():
        raise ValueError("from meanwhile")

    other = Future()
    monkeypatch.setattr(C, "_PENDING", {"a program": other})
    failed = C.when_loaded(broken)
    other.set_result(None)
    with pytest.raises(ValueError, match="from meanwhile"):
        failed.result(timeout=10)


def test_a_new_sentence_is_encoded_on_the_host(tmp_path, monkeypatch):
    """A sentence not in the embedding cache is encoded in NumPy: no program is kept or
    loaded for it and the batch encoder is never built; the embedding is the batch encoder's
    and is kept in the cache (a second ask reads it)."""
    import jaxmotion.compiled as C
    from jaxmotion.text import condition, minilm
    from jaxmotion.text.condition import embed_one, text_encoder

    reference = text_encoder()(["walk to the sofa"])[0]
    cache = tmp_path / "xla" / "text-embeddings"
    monkeypatch.setattr(condition, "text_encoder", lambda: pytest.fail("encoder built"))
    loaded, real = [], C.cached_program
    monkeypatch.setattr(C, "cached_program", lambda *a, **k: loaded.append(a[1]) or real(*a, **k))
    emb = embed_one("walk to the sofa", cache)
    assert loaded == [] and not (tmp_path / "xla" / "programs").exists()
    np.testing.assert_allclose(emb[0], reference, atol=1e-6)
    monkeypatch.setattr(minilm, "encode_one", lambda *a, **k: pytest.fail("encoded again"))
    from jaxmotion.text.cache import close_shared

    close_shared()  # as a new process: from the file
    np.testing.assert_array_equal(embed_one("walk to the sofa", cache), emb)


def test_the_adm_s_kept_program_loads_while_the_text_encodes(ckpt, tmp_path, monkeypatch):
    """With candidates for the ADM to choose among, a repeated generate starts loading its
    kept program before the text condition is computed, and the choice takes it."""
    import jaxmotion.compiled as C

    monkeypatch.setenv("JAXMOTION_CACHE", str(tmp_path / "cache"))
    started, real = [], C.prefetch
    monkeypatch.setattr(C, "prefetch", lambda d, name, *a: started.append(
        (name, real(d, name, *a))) or started[-1][1])
    kw = dict(checkpoints=ckpt, fit=False, grounding="adm", **FAST)
    first = jaxmotion.generate("demo", "sit on the stool", **kw)
    C.release()  # as a new process
    again = jaxmotion.generate("demo", "sit on the stool", **kw)
    assert first.grounding == "adm" and ("adm_region", True) in started
    assert C.prefetched() == () and again.target_id == first.target_id
    np.testing.assert_array_equal(again.joints, first.joints)


def test_cached_programs_take_large_constants_as_arguments(tmp_path):
    """Weights a program closes over (≥ LIFT_BYTES) leave it as arguments kept in a
    ``.safetensors`` file beside it; the numbers are those of the program with them inside,
    cached or not."""
    import jax
    import jax.numpy as jnp

    import jaxmotion.compiled as C

    rng = np.random.default_rng(0)
    w = rng.normal(size=(512, 600)).astype(np.float32)  # 1.2 MB: lifted
    b = rng.normal(size=(600,)).astype(np.float32)  # small: lifted with it (all or none)
    def build():
        wj, bj = jnp.asarray(w), jnp.asarray(b)
        return lambda x: {"y": jnp.tanh(x @ wj + bj), "n": jnp.sum(x)}

    x = rng.normal(size=(3, 512)).astype(np.float32)
    want = jax.jit(build())(x)
    first = C.cached_call(tmp_path, "g", "v1", build, (x,))
    again = C.cached_call(tmp_path, "g", "v1", build, (x,))
    for k in want:
        np.testing.assert_array_equal(np.asarray(first[k]), np.asarray(want[k]))
        np.testing.assert_array_equal(np.asarray(again[k]), np.asarray(want[k]))
    from safetensors.numpy import load_file

    (prog,) = tmp_path.glob("g-*.jaxexport")
    sizes = sorted(a.size for a in load_file(prog.with_suffix(C.CONSTS_SUFFIX)).values())
    assert sizes[-1] == w.size and prog.stat().st_size < w.nbytes / 4
    # a small program keeps its constants
    C.cached_call(tmp_path, "h", "v1", lambda: (lambda x: x * jnp.asarray(b[:3])), (x[0, :3],))
    (small,) = tmp_path.glob("h-*.jaxexport")
    assert not small.with_suffix(C.CONSTS_SUFFIX).exists()
    # a damaged weights file is rebuilt, not trusted
    C.release()  # read from disk again, as a new process does
    prog.with_suffix(C.CONSTS_SUFFIX).write_bytes(b"not a safetensors file")
    np.testing.assert_array_equal(
        np.asarray(C.cached_call(tmp_path, "g", "v1", build, (x,))["y"]), np.asarray(want["y"]))


def test_known_target_keeps_the_map_off_its_class_mates(tiny_runs, ckpt):
    """With object_id (or grounding=auto) the other objects of the target's class are left
    out of the ADM's map; with grounding=adm and no object_id nothing is left out."""
    from jaxmotion.grounding import object_table, same_class_others
    from jaxmotion.scene import load_scene

    _, out = tiny_runs
    def centre(o):
        return 0.5 * (np.asarray(o["bbox_min"][:2]) + np.asarray(o["bbox_max"][:2]))

    best = None  # the closest pair of same-class objects in the tiny rooms: both in one crop
    for f in sorted((out["data"] / "scenes").glob("*.npz")):
        room = load_scene(f)
        objs = object_table(room)
        for a in objs:
            for b in objs:
                d = np.linalg.norm(centre(a) - centre(b))
                if a["id"] != b["id"] and a["category"] == b["category"] and (
                        best is None or d < best[0]):
                    best = (d, room, objs, a)
    assert best is not None, "the tiny dataset has no room with two objects of one class"
    _, room, objs, dup = best
    others = same_class_others(objs, dup["id"])
    r = jaxmotion.generate(room, f"walk to the {dup['category']}", object_id=dup["id"],
                           checkpoints=ckpt, fit=False, **FAST)
    assert r.excluded == tuple(others) and r.target_id == dup["id"]
    # the crop's points on those objects, found in the room by exact coordinates
    inst = {tuple(p): i for p, i in zip(room.xyz.round(5).tolist(), room.instance)}
    crop_inst = np.array([inst[tuple(p)] for p in r.crop_xyz.round(5).tolist()])
    on = np.isin(crop_inst, others)
    assert on.any(), "no class mate in the crop: pick another room"
    assert np.abs(r.affordance[:, on]).max() <= 1e-6 and r.affordance[:, ~on].max() > 1e-3
    plain = jaxmotion.generate(room, f"walk to the {dup['category']}", grounding="adm",
                               checkpoints=ckpt, fit=False, **FAST)
    assert plain.excluded == ()
    line = json.loads(jaxmotion.export.summary(r))
    assert line["excluded"] == list(others)
    # the target is known: the default number of maps (recorded in the result and its line)
    assert r.adm_candidates == line["adm_candidates"] == jaxmotion.options.DEFAULT_ADM_CANDIDATES


def test_text_only_adm_when_no_target_is_known(ckpt, tmp_path, monkeypatch):
    """A folder's adm_text.safetensors draws the maps whenever no target is known (tiles,
    region choice); adm.safetensors those of a known target."""
    import shutil
    from pathlib import Path

    import jaxmotion.pipelines.checkpoints as G

    folder = tmp_path / "ckpt"
    folder.mkdir()
    shutil.copy(Path(ckpt[0]) / "model.safetensors", folder / "adm.safetensors")
    shutil.copy(Path(ckpt[1]) / "model.safetensors", folder / "amdm.safetensors")
    assert G.text_adm_for(folder / "adm.safetensors") == folder / "adm.safetensors"  # none there
    shutil.copy(Path(ckpt[0]) / "model.safetensors", folder / G.TEXT_ADM)
    assert G.text_adm_for(folder / "adm.safetensors") == folder / G.TEXT_ADM
    assert G.text_adm_for(Path(ckpt[0]) / "model.safetensors").name == "model.safetensors"
    used = []
    real = G.load_pipeline

    def spy(adm, amdm):
        used.append(Path(adm).name)
        return real(adm, amdm)

    monkeypatch.setattr(G, "load_pipeline", spy)
    import jaxmotion.compiled as C

    C.release()  # programs traced earlier in this process are kept: trace these anew
    r = jaxmotion.generate(_bare_demo(), "dance around for a while", checkpoints=folder,
                           fit=False, aot=False, **FAST)
    assert r.target_id is None and used and set(used) == {G.TEXT_ADM}
    used.clear()
    r = jaxmotion.generate("demo", "sit on the chair next to the table", checkpoints=folder,
                           fit=False, aot=False, **FAST)
    assert r.target_id is not None and used == ["adm.safetensors"]


def test_the_default_pipeline_is_object_centric_when_the_target_is_known(ckpt, tmp_path):
    """``pipeline="auto"`` (the default): the object-centric models sample when the text's
    target is found, or when the text names no object and one is drawn to walk to; the
    affordance pipeline when no target is (a scene without objects)."""
    from jaxmotion.options import GenerateOptions

    assert GenerateOptions().pipeline == "auto"
    kw = dict(checkpoints=ckpt, steps=2, adm_steps=2, fit=False, aot=False)
    r = jaxmotion.generate("demo", "sit on the chair next to the table", **kw)
    assert r.pipeline == "object-centric" and r.target_id is not None
    assert json.loads(jaxmotion.export.summary(r))["pipeline"] == "object-centric"
    assert np.isfinite(r.joints).all() and r.joints.shape == (1, 120, 22, 3)
    r = jaxmotion.generate("demo", "dance around for a while", **kw)
    assert r.pipeline == "object-centric" and r.grounding == "wander"
    assert r.target_id in {int(o["id"]) for o in r.scene.objects}
    assert any("a walk to" in n for n in r.understanding.notes)
    bare = _bare_demo()  # no labels: its objects are found, and the same pipeline runs
    r = jaxmotion.generate(bare, "dance around for a while", **kw)
    assert r.pipeline == "object-centric" and r.target_id in {o["id"] for o in r.scene.objects}
    assert all(o["source"] == "segment" for o in r.scene.objects)
    r = jaxmotion.generate(bare, "dance around for a while", pipeline="affordance", **kw)
    assert r.pipeline == "affordance" and r.target_id is None  # the ADM chooses the place
    floor_only = dataclasses.replace(bare, xyz=bare.xyz * [1.0, 1.0, 0.0])
    with pytest.raises(GenerateError, match="no object was found"):
        jaxmotion.generate(floor_only, "dance around for a while", **kw)
