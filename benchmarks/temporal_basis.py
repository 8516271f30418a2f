"""How much of a dataset's motion the AMDM's temporal basis keeps (``model.temporal_basis``).

For each K, every motion of a split is projected onto the first K cosines of its valid frames
(:func:`jaxmotion.models.layers.low_frequency_projection`, the AMDM's output layer) and
compared with itself: the joint error, and the plausibility measures of the projected motions
beside the originals' (the baseline row). A K is safe for a dataset when the error is far
below the model's own (centimetres) and the speeds are the originals'.

    python benchmarks/temporal_basis.py --data data/synth [--split test] [--max 500] [--k 16 24 32]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", required=True)
    ap.add_argument("--split", default="test")
    ap.add_argument("--max", type=int, default=500, help="motions read (default 500)")
    ap.add_argument("--k", type=int, nargs="+", default=[8, 16, 24, 32, 48])
    args = ap.parse_args()

    from jaxmotion.data.format import load_sample
    from jaxmotion.eval.plausibility import plausibility
    from jaxmotion.models.layers import low_frequency_projection

    files = sorted((Path(args.data) / "samples" / args.split).glob("*.npz"))[: args.max]
    if not files:
        raise SystemExit(f"no samples in {args.data}/samples/{args.split}")
    motions = [load_sample(f) for f in files]
    t = max(len(m["joints"]) for m in motions)
    joints = np.zeros((len(motions), t, 22, 3), np.float32)
    mask = np.zeros((len(motions), t), bool)
    for i, m in enumerate(motions):
        n = len(m["joints"])
        joints[i, :n], mask[i, :n] = m["joints"], np.asarray(m["mask"], bool)[:n]
        joints[i, n:] = m["joints"][-1]
    fps = float(motions[0]["fps"])

    def row(name, x, err=None):
        p = {k: np.asarray(v) for k, v in plausibility(x, mask, fps=fps).items()}
        e = "–" if err is None else f"{100 * err.mean():.2f} / {100 * np.percentile(err, 99):.2f}"
        print(f"| {name} | {e} | {np.median(p['pelvis_speed_max']):.2f} / "
              f"{p['pelvis_speed_max'].max():.2f} | {np.median(p['joint_speed_max']):.2f} | "
              f"{p['jerk_mean'].mean():.1f} | {100 * p['teleport'].mean():.1f} % |")

    print(f"{len(files)} motions of {args.data}/{args.split}, up to {t} frames at {fps:g} fps\n")
    print("| K | joint error mean / p99 (cm) | top pelvis speed median / max (m/s) | "
          "top joint speed median (m/s) | jerk (m/s³) | teleport |")
    print("|---|---|---|---|---|---|")
    row("the motions (baseline)", joints)
    flat = joints.reshape(len(motions), t, -1)
    for k in args.k:
        proj = np.asarray(low_frequency_projection(flat, mask, k)).reshape(joints.shape)
        err = np.linalg.norm(proj - joints, axis=-1)[mask].mean(-1)  # per valid frame
        row(str(k), proj, err)


if __name__ == "__main__":
    main()
