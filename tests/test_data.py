"""Sample schema round trip, training crops and seeded batching on a tiny generated dataset."""

import json

import numpy as np
import pytest

from jaxmotion.data import (
    CropSpec,
    Dataset,
    DatasetError,
    anchor_frame,
    compute_stats,
    crop_sample,
    load_sample,
    save_sample,
)
from jaxmotion.geometry import AFFORDANCE_JOINTS


def fake_room(rng, n=4000):
    """A 6 m x 5 m floor with one box (instance 3) on it, as a labelled point cloud."""
    floor = np.c_[rng.uniform(0, 6, (n, 2)) * [1, 5 / 6], np.zeros(n)]
    box = rng.uniform([2, 2, 0], [2.6, 2.5, 0.45], (n // 4, 3))
    xyz = np.concatenate([floor, box]).astype(np.float32)
    inst = np.r_[np.full(n, -1), np.full(n // 4, 3)].astype(np.int32)
    return xyz, rng.uniform(0, 1, xyz.shape).astype(np.float32), inst


def fake_motion(rng, t):
    start = rng.uniform([1, 1], [3, 3])
    pelvis = start + np.cumsum(rng.normal(0, 0.03, (t, 2)), 0)
    joints = rng.normal(0, 0.2, (1, 22, 3)) + np.c_[pelvis, np.full(t, 0.9)][:, None]
    return joints.astype(np.float32)


def fake_sample(rng, t, scene_id="room0"):
    return dict(
        text="walk to the box", action="walk", scene_id=scene_id, target_id=3,
        joints=fake_motion(rng, t), fps=30.0, mask=np.ones(t, bool),
        transl=np.zeros((t, 3)), global_orient=np.zeros((t, 3)), body_pose=np.zeros((t, 21, 3)),
        betas=np.zeros(10),
    )  # fmt: skip


@pytest.fixture(scope="module")
def dataset_dir(tmp_path_factory):
    root = tmp_path_factory.mktemp("ds")
    rng = np.random.default_rng(0)
    xyz, rgb, inst = fake_room(rng)
    (root / "scenes").mkdir()
    np.savez(root / "scenes" / "room0.npz", xyz=xyz, rgb=rgb, normal=np.zeros_like(xyz),
             semantic=np.zeros(len(xyz), np.int32), instance=inst, objects=json.dumps([]))
    for i in range(10):
        save_sample(root / "samples" / "train" / f"s{i:03d}.npz", fake_sample(rng, 8 + i))
    (root / "manifest.json").write_text("{}")
    return root


def test_sample_round_trip_and_validation(tmp_path):
    rng = np.random.default_rng(1)
    s = fake_sample(rng, 12)
    path = save_sample(tmp_path / "a.npz", s)
    back = load_sample(path)
    np.testing.assert_array_equal(back["joints"], s["joints"])
    assert back["text"] == s["text"] and back["target_id"] == 3 and back["fps"] == 30.0
    assert not list(tmp_path.glob(".*tmp"))
    bad = dict(s, joints=np.zeros((12, 21, 3)))
    with pytest.raises(DatasetError, match=r"joints must be \[T, 22, 3\]"):
        save_sample(tmp_path / "b.npz", bad)
    with pytest.raises(DatasetError, match="action 'dance'"):
        save_sample(tmp_path / "b.npz", dict(s, action="dance"))
    with pytest.raises(DatasetError, match="no such sample"):
        load_sample(tmp_path / "missing.npz")
    assert anchor_frame("stand_up", np.ones(5, bool)) == 0
    assert anchor_frame("sit", np.array([1, 1, 1, 0, 0], bool)) == 2


def test_crop_geometry():
    rng = np.random.default_rng(2)
    xyz, rgb, inst = fake_room(rng)
    joints = fake_motion(rng, 30)
    spec = CropSpec(num_points=1024)
    c = crop_sample(np.random.default_rng(5), xyz, rgb, inst, joints, np.ones(30, bool), 3, spec)
    assert c.points.shape == (1024, 3) and c.colors.shape == (1024, 3)
    assert c.colors.min() >= -1 and c.colors.max() <= 1
    # rigid: the inverse transform maps back onto the room's points, inside the square
    world = c.to_world(c.points)
    d = np.linalg.norm(world[:, None] - xyz[None, ::7], axis=-1).min(1)
    assert np.all(np.abs(world[:, :2] - c.shift[:2]) <= 2.0 + 1e-4)
    np.testing.assert_allclose(c.to_world(c.joints), joints, atol=1e-5)
    np.testing.assert_allclose(np.linalg.det(c.rotation), 1.0, atol=1e-6)
    assert d.min() < 1e-5
    # the floor sits at z ~ 0 (2nd percentile) and the whole trajectory fits in the square
    assert abs(np.percentile(c.points[:, 2], 2.0)) < 1e-5
    pelvis_local = joints[:, 0, :2] - c.shift[:2]
    assert np.all(np.abs(pelvis_local) <= 2.0)
    # the target mask marks the box's points
    assert np.all(inst[np.argmin(np.linalg.norm(world[:, None] - xyz[None], axis=-1), 1)][c.target_mask] == 3)
    # duplicates when the crop has too few points
    c2 = crop_sample(rng, xyz[:50], rgb[:50], inst[:50], joints, np.ones(30, bool), 3,
                     CropSpec(num_points=512, margin=5.0))
    assert c2.points.shape == (512, 3)
    with pytest.raises(ValueError, match="no valid frame"):
        crop_sample(rng, xyz, rgb, inst, joints, np.zeros(30, bool), 3, spec)
    with pytest.raises(ValueError, match="no scene point"):
        crop_sample(rng, xyz, rgb, inst, joints + 100.0, np.ones(30, bool), 3, spec)


def test_batches_are_seeded_resumable_and_complete(dataset_dir):
    ds = Dataset(dataset_dir, "train", CropSpec(num_points=256), max_frames=20)
    assert len(ds) == 10
    it = ds.iterate(4, seed=7, prefetch=2)
    first = [next(it) for _ in range(4)]
    resumed = next(ds.iterate(4, seed=7, start_step=3, prefetch=0))
    for k in ("points", "joints", "affordance", "mask"):
        np.testing.assert_array_equal(first[3][k], resumed[k])
    other = next(ds.iterate(4, seed=8, prefetch=0))
    assert not np.array_equal(first[0]["points"], other["points"])
    b = first[0]
    assert b["points"].shape == (4, 256, 3) and b["affordance"].shape == (4, 256, 6)
    assert b["joints"].shape == (4, 20, 22, 3) and b["motion"].shape == (4, 20, 66)
    assert len(b["text"]) == 4 and b["action"].dtype == np.int32
    # the affordance map is the paper's formula on the crop (brute force check)
    j = b["joints"][0][b["mask"][0]][:, list(AFFORDANCE_JOINTS)]
    d = np.linalg.norm(b["points"][0][:, None, None] - j[None], axis=-1).min(1)
    np.testing.assert_allclose(b["affordance"][0], np.exp(-d**2 / 1.28), atol=1e-4)
    assert np.all(b["joints"][~b["mask"]] == 0)


def test_worker_processes_give_the_same_batches(dataset_dir):
    ds = Dataset(dataset_dir, "train", CropSpec(num_points=256), max_frames=20)
    plain = ds.iterate(4, seed=7, start_step=1, prefetch=0)
    pooled = ds.iterate(4, seed=7, start_step=1, workers=2)
    for _ in range(4):  # crosses an epoch boundary (2 batches per epoch)
        a, b = next(plain), next(pooled)
        assert a["text"] == b["text"]
        for k in ("points", "colors", "joints", "motion", "affordance", "mask", "semantic"):
            np.testing.assert_array_equal(a[k], b[k], err_msg=k)
    pooled.close()


def test_stats_and_errors(dataset_dir, tmp_path):
    ds = Dataset(dataset_dir, "train", CropSpec(num_points=128), max_frames=20)
    st = compute_stats(ds, num_batches=2, batch_size=4)
    assert st["motion_mean"].shape == (66,) and st["affordance_std"].shape == (6,)
    assert np.all(st["motion_std"] > 0)
    z = st.normalize_motion(np.ones(66, np.float32))
    np.testing.assert_allclose(st.denormalize_motion(z), 1.0, atol=1e-5)
    with pytest.raises(DatasetError, match="jaxmotion synth"):
        Dataset(tmp_path, "train")
    with pytest.raises(DatasetError, match="fewer than batch_size"):
        next(ds.iterate(64, seed=0))
    short = Dataset(dataset_dir, "train", CropSpec(num_points=64), max_frames=5)
    with pytest.raises(DatasetError, match="max_frames"):
        next(short.iterate(2, seed=0, prefetch=1))


def test_threaded_readers_take_turns_parsing(tmp_path):
    """The readers that run beside each other (a sample and a scene on training's loader
    thread, the text caches on the main thread) parse their .npy headers under one lock:
    while it is held elsewhere they wait, then read (Python 3.11/3.12's parser is not safe on
    two threads at once)."""
    import threading

    from jaxmotion._npio import READ_LOCK, load_npz
    from jaxmotion.text import EmbeddingCache

    rng = np.random.default_rng(2)
    sample = save_sample(tmp_path / "a.npz", fake_sample(rng, 10))
    EmbeddingCache(tmp_path / "emb").put(["k"], np.ones((1, 4), np.float32))

    def read_in_turn(read):
        out, started = [], threading.Event()

        def run():
            started.set()
            out.append(read())

        with READ_LOCK:
            t = threading.Thread(target=run)
            t.start()
            started.wait()
            t.join(0.3)
            assert out == [], "read while another thread held the lock"
        t.join(10)
        assert len(out) == 1
        return out[0]

    assert read_in_turn(lambda: load_sample(sample))["text"] == load_sample(sample)["text"]
    assert "k" in read_in_turn(lambda: EmbeddingCache(tmp_path / "emb"))
    with load_npz(sample) as d:  # the lock is re-entrant: a reader may read inside its block
        with load_npz(sample) as again:
            np.testing.assert_array_equal(d["joints"], again["joints"])
