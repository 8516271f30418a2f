"""Files that external tools read, written from a generated motion (host numpy, atomic writes).

- :func:`write_bvh` / :func:`read_bvh`: BVH of the SMPL-X 22-joint body skeleton
  (Blender, MotionBuilder, Maya), y-up, metres.
- :func:`write_amass_npz`: the fitted SMPL-X parameters as an AMASS-style SMPL-X
  ``.npz`` (``trans``, ``poses`` [T,165], ``betas``, ...; the SMPL-X Blender add-on).
- :func:`write_glb`: binary glTF 2.0 with the skinned, animated body of each
  sample and the scene (mesh or point cloud), y-up (Blender, three.js, engines).
- :func:`render_motion_video`: an offscreen GIF or MP4 of the motion in its scene (shaded
  bodies through :mod:`jaxmotion.render` when posed meshes are given, else skeletons);
  :func:`render_frame`: one still PNG of the skeleton at several frames.
- :func:`write_viewer_html`: one self-contained HTML page (WebGL2, no network)
  that plays the skinned bodies in the scene: the target highlighted, hover labels
  naming the objects, the affordance map as a heat layer, a story's path and steps.

All take jaxmotion's z-up world in metres; each module docstring states its
format's frame, units and conventions. A failed write never leaves a partial
file (``jaxmotion._atomic.atomic_open``); bad shapes or values raise ``ValueError``
naming the argument.
"""

from jaxmotion.export.amass import AMASS_KEYS, write_amass_npz
from jaxmotion.export.bvh import BVH, read_bvh, write_bvh
from jaxmotion.export.folder import check_output_folder, check_outputs, summary, write_generation
from jaxmotion.export.gltf import write_glb
from jaxmotion.export.video import render_frame, render_motion_video
from jaxmotion.export.viewer import write_viewer_html

__all__ = [
    "AMASS_KEYS",
    "BVH",
    "check_output_folder",
    "check_outputs",
    "read_bvh",
    "render_frame",
    "render_motion_video",
    "summary",
    "write_amass_npz",
    "write_bvh",
    "write_generation",
    "write_glb",
    "write_viewer_html",
]
