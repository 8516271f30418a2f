"""Redraw ``docs/images/demo.png``, the README's picture: the default ``jaxmotion generate`` on
the demo room (seed 0) over the whole room; with the affordance pipeline, its affordance heat
on the square the models saw.

    python docs/images/make_demo.py
"""

from pathlib import Path

import numpy as np
from scipy.spatial import cKDTree

import jaxmotion
from jaxmotion.export import render_frame

r = jaxmotion.generate("demo", "sit on the chair next to the table", seed=0)
xyz, rgb = r.scene.xyz, r.scene.rgb
heat = None
if r.pipeline == "affordance":  # the crop's map carried to the room's points within 10 cm
    d, i = cKDTree(r.crop_xyz).query(xyz)
    heat = np.where((d < 0.1)[:, None], r.affordance[0][i], 0.0).astype(np.float32)
out = Path(__file__).with_name("demo.png")
render_frame(out, xyz, rgb, r.joints, affordance=heat, text=r.text, seed=0)
print(f"wrote {out}: {r.pipeline} pipeline, fit error {float(r.fit_error[0]) * 100:.2f} cm, "
      f"grounding {r.grounding!r}")
