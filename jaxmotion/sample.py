"""``jaxmotion sample``: sample the affordance pipeline over a dataset split into an ``.npz``."""

from __future__ import annotations

from pathlib import Path

import jax
import numpy as np

from jaxmotion.constants import TEXT_ENCODER
from jaxmotion.data.cases import case_inputs, load_cases
from jaxmotion.diffusion.samplers import SamplerSpec
from jaxmotion.pipelines.affordance import AffordancePipeline, take_text

__all__ = ["sample_split"]


def sample_split(data_dir, split, adm_workdir, amdm_workdir, out, *, num_cases: int = 8,
                 samples_per_case: int = 1, seed: int = 0, adm=SamplerSpec(), amdm=SamplerSpec(),
                 num_points: int | None = None, batch_size: int = 8, progress: bool = True) -> Path:
    """Sample motions for the first ``num_cases`` examples of a split; write an ``.npz``.

    Keys of the file: ``text`` [C], ``points`` [C,N,3], ``joints`` [C,K,T,22,3] (crop frame),
    ``joints_world`` [C,K,T,22,3], ``affordance`` [C,K,N,6] (two-stage), ``mask`` [C,T],
    ``gt_joints`` [C,T,22,3], ``target_mask`` [C,N], ``sample_file`` [C].
    """
    from tqdm.auto import tqdm

    from jaxmotion._atomic import atomic_open
    from jaxmotion.text import load_text_encoder

    pipe = AffordancePipeline.from_workdirs(adm_workdir, amdm_workdir)
    cases, spec = load_cases(data_dir, split, pipe.amdm_config, num_cases=num_cases, seed=seed,
                             num_points=num_points, adm_config=pipe.adm_config)
    max_frames = len(cases[0]["mask"])
    emb = pipe.embed_text([c["text"] for c in cases], load_text_encoder(TEXT_ENCODER))
    rows = [(ci, k) for ci in range(len(cases)) for k in range(samples_per_case)]
    joints = np.zeros((len(cases), samples_per_case, max_frames, 22, 3), np.float32)
    affs = np.zeros((len(cases), samples_per_case, spec.num_points, 6), np.float32)
    key = jax.random.key(seed)
    for start in tqdm(range(0, len(rows), batch_size), desc="sampling", disable=not progress):
        chunk = rows[start:start + batch_size]
        pad = batch_size - len(chunk)
        idx = [ci for ci, _ in chunk] + [chunk[-1][0]] * pad  # static batch: pad the last one
        x = case_inputs(cases, idx)
        res = pipe.sample(jax.random.fold_in(key, start), x["points"], x["colors"],
                          take_text(emb, idx), x["mask"], adm=adm, amdm=amdm, view=x["view"])
        res = jax.device_get(res)
        for j, (ci, k) in enumerate(chunk):
            joints[ci, k] = res["joints"][j]
            if "affordance" in res:
                affs[ci, k] = res["affordance"][j]
    world = np.stack([joints[ci] @ cases[ci]["rotation"] + cases[ci]["shift"]
                      for ci in range(len(cases))])
    out_path = Path(out)
    with atomic_open(out_path, "wb") as f:
        np.savez(f, text=np.array([c["text"] for c in cases]),
                 points=np.stack([c["points"] for c in cases]), joints=joints,
                 joints_world=world.astype(np.float32), affordance=affs,
                 mask=np.stack([c["mask"] for c in cases]),
                 gt_joints=np.stack([c["gt"] for c in cases]),
                 target_mask=np.stack([c["target_mask"] for c in cases]),
                 sample_file=np.array([c["file"] for c in cases]))
    return out_path
