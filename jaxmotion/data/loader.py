"""Batched, seeded iteration over a dataset in the sample schema, and its statistics.

A batch is a dict of stacked numpy arrays (B = batch, N = crop points,
T = ``max_frames``, padded with a frame mask):

====================  ===================  =========================================
key                   shape / dtype        meaning
====================  ===================  =========================================
``points``            [B, N, 3] float32    crop-frame xyz, metres
``colors``            [B, N, 3] float32    rgb in [−1, 1]
``target_mask``       [B, N] bool          points of the target instance
``semantic``          [B, N] int32         semantic class id per point (−1: none)
``affordance``        [B, N, 6] float32    ground-truth map ``exp(−d²/2σ²)``
``joints``            [B, T, 22, 3]        crop-frame joints (zeros past the end)
``motion``            [B, T, 66] float32   the same as features
``mask``              [B, T] bool          valid frames
``action``            [B] int32            index into ``ACTIONS``
``text``              list[str]            the instructions
``normals``           [B, N, 3] float32    crop-frame unit normals (0 where unknown)
``rotation``          [B, 3, 3] float32    the crop's rotation (``x_crop = R (x − shift)``)
``global_orient``     [B, T, 3] float32    SMPL-X axis-angle, world frame (``R ·`` it
                                           for the crop frame)
``body_pose``         [B, T, 21, 3]        SMPL-X axis-angle body pose
``betas``             [B, 10] float32      SMPL-X shape
====================  ===================  =========================================

Determinism: the order of epoch ``e`` is a permutation drawn from
``default_rng([seed, e])`` and batch ``k`` of it crops with
``default_rng([seed, e, k])``, so iteration restarted at any step yields the
same batches (this is what makes resumed training bit-identical). A background
thread prepares the next batches while the training step runs; with ``workers=W``
W processes crop them (a GPU step outruns one thread), and the affordance maps,
computed in JAX, are added in the calling process. The batches are the same with
any number of workers.
"""

from __future__ import annotations

import functools
import queue
import threading
from collections import OrderedDict
from pathlib import Path

import numpy as np

from jaxmotion._atomic import atomic_open
from jaxmotion._npio import load_npz
from jaxmotion.data.crop import CropSpec, crop_sample, motion_features
from jaxmotion.data.format import ACTIONS, DatasetError, load_sample

__all__ = ["Dataset", "Stats", "compute_stats", "load_stats", "save_stats"]


class _SceneCache:
    """LRU cache of the arrays a crop needs (xyz, rgb, instance, semantic) per scene id."""

    def __init__(self, scene_dir: Path, capacity: int):
        self.scene_dir, self.capacity = scene_dir, capacity
        self._items: OrderedDict[str, tuple] = OrderedDict()
        self._lock = threading.Lock()

    def get(self, scene_id: str):
        with self._lock:
            if scene_id in self._items:
                self._items.move_to_end(scene_id)
                return self._items[scene_id]
        path = self.scene_dir / f"{scene_id}.npz"
        if not path.is_file():
            raise DatasetError(f"{path}: scene file missing (referenced by a sample)")
        with load_npz(path, allow_pickle=False) as d:
            normal = (d["normal"] if "normal" in d.files else np.zeros_like(d["xyz"]))
            item = (d["xyz"].astype(np.float32), d["rgb"].astype(np.float32), d["instance"],
                    d["semantic"].astype(np.int32), normal.astype(np.float32))
        with self._lock:
            self._items[scene_id] = item
            while len(self._items) > self.capacity:
                self._items.popitem(last=False)
        return item


@functools.lru_cache(maxsize=None)
def batched_affordance(sigma: float):
    import jax

    from jaxmotion.geometry import AFFORDANCE_JOINTS, affordance_map

    def one(points, joints, mask):
        return affordance_map(points, joints[:, list(AFFORDANCE_JOINTS)], mask, sigma)

    return jax.jit(jax.vmap(one))


class Dataset:
    """One split of a dataset directory made by ``jaxmotion synth`` (or any sample-schema data).

    Args:
      data_dir: the dataset root (with ``samples/<split>/`` and ``scenes/``).
      split: ``train``, ``val`` or ``test``.
      spec: crop parameters; max_frames: motion length the batch is padded to.
      sigma: affordance width; scene_cache: scenes kept in memory.
      max_samples: use only the first ``max_samples`` (sorted by id), or all.
    """

    def __init__(self, data_dir, split: str, spec: CropSpec = CropSpec(), *, max_frames: int = 120,
                 sigma: float = 0.8, scene_cache: int = 256, max_samples: int | None = None):
        self.root = Path(data_dir)
        folder = self.root / "samples" / split
        if not folder.is_dir():
            raise DatasetError(
                f"{folder}: no such split folder; is {self.root} a dataset made by "
                f"'jaxmotion synth --out {self.root}'?"
            )
        self.files = sorted(folder.glob("*.npz"))[:max_samples]
        if not self.files:
            raise DatasetError(f"{folder}: the split is empty")
        self.split, self.spec, self.max_frames, self.sigma = split, spec, max_frames, sigma
        self._scenes = _SceneCache(self.root / "scenes", scene_cache)

    def __len__(self) -> int:
        return len(self.files)

    def example(self, i: int, rng: np.random.Generator) -> dict:
        """One cropped, padded example (no affordance; see :meth:`batch`)."""
        s = load_sample(self.files[i])
        t = s["joints"].shape[0]
        if t > self.max_frames:
            raise DatasetError(f"{self.files[i]}: {t} frames > max_frames={self.max_frames}")
        xyz, rgb, inst, sem, normal = self._scenes.get(s["scene_id"])
        c = crop_sample(rng, xyz, rgb, inst, s["joints"], s["mask"], s["target_id"], self.spec)

        def pad(x):
            out = np.zeros((self.max_frames, *x.shape[1:]), np.float32)
            out[:t] = x
            return out

        mask = np.zeros(self.max_frames, bool)
        mask[:t] = c.mask
        return dict(points=c.points, colors=c.colors, target_mask=c.target_mask,
                    joints=pad(c.joints), semantic=sem[c.indices],
                    normals=(normal[c.indices] @ c.rotation.T).astype(np.float32),
                    rotation=c.rotation.astype(np.float32),
                    global_orient=pad(s["global_orient"]), body_pose=pad(s["body_pose"]),
                    betas=np.asarray(s["betas"], np.float32),
                    mask=mask, action=np.int32(ACTIONS.index(s["action"])), text=s["text"])

    def host_batch(self, indices, rng: np.random.Generator) -> dict:
        """Stacked examples and their motion features: everything but the affordance map."""
        ex = [self.example(int(i), rng) for i in indices]
        out = {k: np.stack([e[k] for e in ex]) for k in ex[0] if k != "text"}
        out["text"] = [e["text"] for e in ex]
        out["motion"] = motion_features(out["joints"])
        return out

    def add_affordance(self, out: dict) -> dict:
        """Add the ground-truth affordance map of a :meth:`host_batch` (computed in JAX)."""
        out["affordance"] = np.asarray(
            batched_affordance(self.sigma)(out["points"], out["joints"], out["mask"])
        )
        return out

    def batch(self, indices, rng: np.random.Generator) -> dict:
        """Stack examples and add the ground-truth affordance map (computed in JAX)."""
        return self.add_affordance(self.host_batch(indices, rng))

    def epoch_order(self, seed: int, epoch: int) -> np.ndarray:
        return np.random.default_rng([seed, epoch]).permutation(len(self))

    def step_batch(self, step: int, batch_size: int, seed: int, per_epoch: int) -> dict:
        """The host batch of global step ``step`` (see the module docstring)."""
        epoch, k = divmod(step, per_epoch)
        order = self.epoch_order(seed, epoch)
        idx = order[k * batch_size : (k + 1) * batch_size]
        return self.host_batch(idx, np.random.default_rng([seed, epoch, k]))

    def iterate(self, batch_size: int, seed: int, *, start_step: int = 0, prefetch: int = 2,
                drop_last: bool = True, workers: int = 0):
        """Endless iterator of batches from global step ``start_step`` on (epochs reshuffled).

        ``workers`` > 0: that many processes prepare the host batches, up to
        ``max(prefetch, 2 * workers)`` steps ahead; the batches are the same as with none."""
        per_epoch = len(self) // batch_size if drop_last else -(-len(self) // batch_size)
        if per_epoch == 0:
            raise DatasetError(
                f"{self.split} split has {len(self)} samples, fewer than batch_size={batch_size}"
            )
        if workers > 0:
            yield from self._iterate_pooled(batch_size, seed, per_epoch, start_step, workers,
                                            max(prefetch, 2 * workers))
            return

        def make(step):
            return self.add_affordance(self.step_batch(step, batch_size, seed, per_epoch))

        if prefetch <= 0:
            step = start_step
            while True:
                yield make(step)
                step += 1
        q: queue.Queue = queue.Queue(maxsize=prefetch)
        stop = threading.Event()

        def worker():
            step = start_step
            while not stop.is_set():
                try:
                    item = make(step)
                except BaseException as err:  # surface errors in the consumer
                    item = err
                while not stop.is_set():
                    try:
                        q.put(item, timeout=0.1)
                        break
                    except queue.Full:
                        continue
                if isinstance(item, BaseException):
                    return
                step += 1

        thread = threading.Thread(target=worker, daemon=True, name="jaxmotion-loader")
        thread.start()
        try:
            while True:
                item = q.get()
                if isinstance(item, BaseException):
                    raise item
                yield item
        finally:
            stop.set()

    def _iterate_pooled(self, batch_size, seed, per_epoch, start_step, workers, ahead):
        import collections
        import concurrent.futures as cf
        import multiprocessing as mp

        args = (str(self.root), self.split, self.spec, self.max_frames, self.sigma,
                self._scenes.capacity, len(self.files))
        # spawn: the parent holds JAX (and maybe a GPU); the workers import only NumPy code
        pool = cf.ProcessPoolExecutor(workers, mp_context=mp.get_context("spawn"),
                                      initializer=_init_worker, initargs=(args,))
        pending: collections.deque = collections.deque()
        submitted = start_step
        try:
            while True:
                while len(pending) < ahead:
                    pending.append(pool.submit(_worker_batch, submitted, batch_size, seed,
                                               per_epoch))
                    submitted += 1
                yield self.add_affordance(pending.popleft().result())
        finally:
            pool.shutdown(wait=False, cancel_futures=True)


_WORKER_DATASET: Dataset | None = None


def _init_worker(args):
    global _WORKER_DATASET
    root, split, spec, max_frames, sigma, cache, n = args
    _WORKER_DATASET = Dataset(root, split, spec, max_frames=max_frames, sigma=sigma,
                              scene_cache=cache, max_samples=n)


def _worker_batch(step, batch_size, seed, per_epoch):
    return _WORKER_DATASET.step_batch(step, batch_size, seed, per_epoch)


class Stats(dict):
    """Normalisation statistics: ``motion_mean/std [66]``, ``affordance_mean/std [6]``."""

    def normalize_motion(self, x):
        return (x - self["motion_mean"]) / self["motion_std"]

    def denormalize_motion(self, x):
        return x * self["motion_std"] + self["motion_mean"]

    def normalize_affordance(self, a):
        return (a - self["affordance_mean"]) / self["affordance_std"]

    def denormalize_affordance(self, a):
        return a * self["affordance_std"] + self["affordance_mean"]


def compute_stats(dataset: Dataset, *, num_batches: int = 16, batch_size: int = 32,
                  seed: int = 0, min_std: float = 1e-3) -> Stats:
    """Per-dimension mean / std of motion features (valid frames) and affordance channels.

    Computed over ``num_batches`` random crops (with rotation augmentation, as the
    models see them); stds are floored at ``min_std``.
    """
    m_sum = np.zeros(66)
    m_sq = np.zeros(66)
    m_n = 0
    a_sum = np.zeros(6)
    a_sq = np.zeros(6)
    a_n = 0
    it = dataset.iterate(min(batch_size, len(dataset)), seed, prefetch=0, drop_last=True)
    for _ in range(num_batches):
        b = next(it)
        m = b["motion"][b["mask"]].astype(np.float64)
        m_sum += m.sum(0)
        m_sq += (m * m).sum(0)
        m_n += len(m)
        a = b["affordance"].reshape(-1, 6).astype(np.float64)
        a_sum += a.sum(0)
        a_sq += (a * a).sum(0)
        a_n += len(a)
    mm, am = m_sum / m_n, a_sum / a_n
    return Stats(
        motion_mean=mm.astype(np.float32),
        motion_std=np.maximum(np.sqrt(np.maximum(m_sq / m_n - mm * mm, 0)), min_std).astype(np.float32),
        affordance_mean=am.astype(np.float32),
        affordance_std=np.maximum(np.sqrt(np.maximum(a_sq / a_n - am * am, 0)), min_std).astype(np.float32),
    )


def save_stats(stats: Stats, path) -> Path:
    """Write ``stats.npz`` atomically."""
    path = Path(path)
    with atomic_open(path, "wb") as f:
        np.savez(f, **stats)
    return path


def load_stats(path) -> Stats:
    path = Path(path)
    if not path.is_file():
        raise DatasetError(f"{path}: statistics not found; run 'jaxmotion synth --stats-only --out {path.parent}'")
    with load_npz(path) as d:
        return Stats({k: d[k] for k in d.files})
