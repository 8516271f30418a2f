"""Synthetic dataset build: layout, determinism, resume, split by scene, previews; the demo."""

import json

import numpy as np
import pytest

from jaxmotion.cli import main
from jaxmotion.data import Dataset, DatasetError, load_sample
from jaxmotion.data.synth import SynthSettings, build_dataset, split_of_scenes

SETTINGS = SynthSettings(scenes=3, per_scene=2, seed=3, points_per_scene=6000)


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    root = tmp_path_factory.mktemp("synth")
    manifest = build_dataset(root, SETTINGS, progress=False, stats=False)
    return root, manifest


def test_layout_and_manifest(built):
    root, manifest = built
    assert manifest["samples"] == {"train": 2, "val": 2, "test": 2}
    assert manifest["scenes"] == {"train": 1, "val": 1, "test": 1}
    assert json.loads((root / "manifest.json").read_text())["seed"] == 3
    scene_ids = set()
    for split in ("train", "val", "test"):
        for f in (root / "samples" / split).glob("*.npz"):
            s = load_sample(f)
            scene_ids.add((split, s["scene_id"]))
            assert s["action"] in ("walk", "sit", "stand_up", "lie")
            assert 30 <= s["joints"].shape[0] <= 120 and s["fps"] == 30.0
            with np.load(root / "scenes" / f"{s['scene_id']}.npz") as sc:
                assert set(sc.files) >= {"xyz", "rgb", "normal", "semantic", "instance", "objects"}
                assert s["target_id"] in {o["id"] for o in json.loads(str(sc["objects"]))}
                assert np.any(sc["instance"] == s["target_id"])
    # split by scene: no scene in two splits
    assert len({sid for _, sid in scene_ids}) == len(scene_ids)
    assert not list(root.rglob(".*.tmp"))


def test_deterministic_and_resumable(built, tmp_path):
    root, _ = built
    other = tmp_path / "again"
    build_dataset(other, SETTINGS, progress=False, stats=False)
    # interrupt: delete one sample and one scene, then resume with the same command
    victim = sorted((other / "samples" / "train").glob("*.npz"))[0]
    victim.unlink()
    (other / "scenes" / "scene_00001.npz").unlink()
    build_dataset(other, SETTINGS, progress=False, stats=False)
    for f in sorted(root.rglob("*.npz")):
        g = other / f.relative_to(root)
        with np.load(f) as a, np.load(g) as b:
            for k in a.files:
                np.testing.assert_array_equal(a[k], b[k], err_msg=f"{f.name}:{k}")
    with pytest.raises(DatasetError, match="built with"):
        build_dataset(other, SynthSettings(scenes=3, per_scene=2, seed=4), progress=False)


def test_grow_training_rooms_keeps_val_and_test(built, tmp_path):
    """--split-scenes: the first S rooms keep their split, later rooms are train; growing an
    S-room build in place gives the same files as building the larger set fresh."""
    import shutil

    root, _ = built
    grown = tmp_path / "grown"
    shutil.copytree(root, grown)
    more = SynthSettings(scenes=5, per_scene=2, seed=3, points_per_scene=6000, split_scenes=3)
    assert more.split_labels() == split_of_scenes(3, 3) + ["train", "train"]
    manifest = build_dataset(grown, more, progress=False, stats=False)
    assert manifest["samples"] == {"train": 6, "val": 2, "test": 2}
    assert manifest["settings"]["split_scenes"] == 3
    for split in ("val", "test"):
        names = sorted(f.name for f in (root / "samples" / split).glob("*.npz"))
        assert names == sorted(f.name for f in (grown / "samples" / split).glob("*.npz"))
    fresh = tmp_path / "fresh"
    build_dataset(fresh, more, progress=False, stats=False)
    for f in sorted(fresh.rglob("*.npz")):
        with np.load(f) as a, np.load(grown / f.relative_to(fresh)) as b:
            for k in a.files:
                np.testing.assert_array_equal(a[k], b[k], err_msg=f"{f.name}:{k}")
    # growing needs split_scenes equal to the old build's scene count
    with pytest.raises(DatasetError, match="split-scenes"):
        build_dataset(grown, SynthSettings(scenes=6, per_scene=2, seed=3, points_per_scene=6000,
                                           split_scenes=4), progress=False, stats=False)
    with pytest.raises(ValueError, match="split_scenes"):
        SynthSettings(scenes=3, per_scene=2, split_scenes=4)


def test_split_by_scene_counts():
    labels = split_of_scenes(2000, 0)
    assert labels.count("train") == 1600 and labels.count("val") == 200 and labels.count("test") == 200
    assert split_of_scenes(50, 1) == split_of_scenes(50, 1) != split_of_scenes(50, 2)
    assert set(split_of_scenes(3, 0)) == {"train", "val", "test"}


def test_stats_and_preview_from_the_command_line(built, tmp_path, capsys):
    root = tmp_path / "cli"
    assert main(["synth", "--out", str(root), "--scenes", "3", "--per-scene", "2", "--seed", "3",
                 "--points", "6000", "--preview", "--preview-count", "1"]) == 0
    assert "previews: 2 PNG" in capsys.readouterr().out
    assert (root / "stats.npz").is_file()
    pngs = sorted((root / "preview").glob("*.png"))
    assert len(pngs) == 2 and all(p.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" for p in pngs)
    ds = Dataset(root, "train")
    with np.load(root / "stats.npz") as st:
        assert st["motion_mean"].shape == (66,) and np.all(st["affordance_std"] > 0)
    assert len(ds) == 2
    # --split-scenes grows the build in place: one more training room, val and test unchanged
    assert main(["synth", "--out", str(root), "--scenes", "4", "--split-scenes", "3",
                 "--per-scene", "2", "--seed", "3", "--points", "6000", "--no-stats"]) == 0
    assert "'train': 4, 'val': 2, 'test': 2" in capsys.readouterr().out
    assert len(Dataset(root, "train")) == 4


def test_demo(tmp_path, capsys):
    assert main(["demo", "--out", str(tmp_path / "demo"), "--seed", "1"]) == 0
    summary = json.loads(capsys.readouterr().out)
    for name in ("room.ply", "scene.npz", "motion.npz", "affordance.npz", "affordance.ply",
                 "preview_top.png", "preview_persp.png"):
        assert name in summary["files"]
    import trimesh

    assert len(trimesh.load(tmp_path / "demo" / "room.ply").faces) > 100
    with np.load(tmp_path / "demo" / "affordance.npz") as d:
        assert d["affordance"].shape == (len(d["xyz"]), 6)
        assert d["affordance"].max() > 0.99  # the body touches the room somewhere
    assert summary["action"] == "sit" and summary["pelvis_to_target_at_anchor_m"] < 0.35
