"""Redraw ``docs/images/demo.png``, the README's picture: the default ``jaxmotion generate`` on
the demo room (seed 0), rendered as ``motion.mp4`` is (:mod:`jaxmotion.render`: the fitted
mannequin shaded in the lit room, the target chair highlighted), at its last frame, with a faint
body where the motion began.

    python docs/images/make_demo.py
"""

from pathlib import Path

import jaxmotion
from jaxmotion.render import render_still
from jaxmotion.render.results import clip_for_motion

r = jaxmotion.generate("demo", "sit on the chair next to the table", seed=0)
out = Path(__file__).with_name("demo.png")
clip = clip_for_motion(r.scene, r.smplx, r.joints, r.fps, text=r.text, target_id=r.target_id,
                       mask=r.mask, size=(960, 540), room_supersample=2)
render_still(out, clip, ghosts=1)
print(f"wrote {out}: {r.pipeline} pipeline, fit error {float(r.fit_error[0]) * 100:.2f} cm, "
      f"grounding {r.grounding!r}, camera {clip.mode}")
