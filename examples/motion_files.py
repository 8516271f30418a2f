"""Motion files in and out: generate a motion, write it as BVH (SMPL-X and Mixamo rigs),
AMASS-style SMPL-X and glTF, and read every file back with ``jaxmotion.io.load_motion``.

    python examples/motion_files.py [--out DIR]

``load_motion`` is also how your own mocap comes in (BVH of any humanoid rig, skinned glTF,
AMASS, HumanML3D, HUMANISE): every reader returns the same ``Motion``, the 22 SMPL-X body
joints in metres, z-up, with the frame rate and the SMPL-X parameters where the file has
them.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np

import jaxmotion
from jaxmotion.io import load_motion


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", default=None, help="folder for the files (default: a temp folder)")
    args = ap.parse_args()
    out = Path(args.out) if args.out else Path(tempfile.mkdtemp(prefix="jaxmotion-files-"))

    t0 = time.perf_counter()
    res = jaxmotion.generate("demo", "sit on the chair next to the table", samples=1, seed=0)
    files = res.save(out / "smplx", video=None)            # motion.bvh with SMPL-X bone names
    mixamo = res.save(out / "mixamo", video=None, skeleton="mixamo")  # Mixamo's rig, cm
    print(f"generated {res.joints.shape[1]} frames at {res.fps:g} fps in "
          f"{time.perf_counter() - t0:.1f} s; wrote {', '.join(sorted(files))} to {out}/smplx")

    reference = res.joints[0]  # [T, 22, 3], the room's frame (z-up, metres)
    for label, path in (("BVH, SMPL-X bones", files["motion.bvh"]),
                        ("BVH, Mixamo bones", mixamo["motion.bvh"]),
                        ("AMASS SMPL-X .npz", files["motion_smplx.npz"]),
                        ("glTF (.glb)", files["motion.glb"])):
        m = load_motion(path)
        assert m.joints.shape == reference.shape and np.isfinite(m.joints).all()
        err = np.linalg.norm(m.joints - reference, axis=-1).mean()
        params = "SMPL-X parameters" if m.body_pose is not None else "joints only"
        print(f"  {label:18s} {Path(path).name:17s} -> {m.num_frames} frames at {m.fps:g} fps, "
              f"{params}, mean joint error {1000 * err:.3f} mm")
        assert err < 0.05, f"{path} read back {err:.3f} m from the generated joints"
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
