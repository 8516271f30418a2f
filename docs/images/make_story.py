"""Redraw ``docs/images/story.png``, the README's story picture: the demo room's story "stand up
from chair 4, walk to the fridge 9, sit on the armchair 6" (seed 0), seen from above (the
objects' boxes and ids, the planned path, the pelvis coloured by step, the feet every half
second) beside the pelvis speed and height over time.

    python docs/images/make_story.py
"""

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

import jaxmotion

PLAN = [{"action": "stand_up", "object": 4}, {"action": "walk", "object": 9},
        {"action": "sit", "object": 6}]
COLOURS = {"stand_up": "tab:orange", "walk": "tab:blue", "sit": "tab:green", "lie": "tab:red"}

res = jaxmotion.generate("demo", plan=PLAN, seed=0)
room, j = res.scene, res.joints[0]
fig, (top, side) = plt.subplots(1, 2, figsize=(11, 5), gridspec_kw={"width_ratios": [1, 1.3]})
wall = (room.xyz[:, 2] > 0.1) & (room.xyz[:, 2] < 1.9)
top.scatter(room.xyz[wall, 0], room.xyz[wall, 1], s=0.2, c="0.75")
for o in room.objects:
    lo, hi = o["bbox_min"], o["bbox_max"]
    if o["category"] in ("door", "window"):
        continue
    top.add_patch(plt.Rectangle(lo[:2], hi[0] - lo[0], hi[1] - lo[1], fill=False, lw=0.8))
    top.text(lo[0] + 0.03, lo[1] + 0.05, f"{o['category']} {o['id']}", fontsize=7)
for path in res.paths:
    top.plot(path[:, 0], path[:, 1], "k:", lw=1)
for s in res.segments:
    f = slice(s["first"], s["last"] + 1)
    top.plot(j[f, 0, 0], j[f, 0, 1], color=COLOURS[s["action"]], lw=2,
             label=f"{s['action'].replace('_', ' ')} {s['object']}")
    side.axvspan(s["first"] / res.fps, (s["last"] + 1) / res.fps,
                 color=COLOURS[s["action"]], alpha=0.12)
top.plot(j[::15, 10, 0], j[::15, 10, 1], ".", c="0.3", ms=3)
top.plot(j[::15, 11, 0], j[::15, 11, 1], ".", c="0.3", ms=3)
top.set_aspect("equal")
top.set_title("from above: pelvis by step, planned paths dotted", fontsize=9)
top.legend(fontsize=7, loc="upper right")
t = np.arange(len(j)) / res.fps
speed = np.linalg.norm(np.diff(j[:, 0, :2], axis=0), axis=1) * res.fps
side.plot(t[1:], speed, label="pelvis speed (m/s)")
side.plot(t, j[:, 0, 2], label="pelvis height (m)")
side.set_xlabel("seconds")
side.legend(fontsize=8)
side.set_title(res.text, fontsize=9)
out = Path(__file__).with_name("story.png")
fig.tight_layout()
fig.savefig(out, dpi=80)
print(f"wrote {out}: {len(j)} frames, steps {[s['action'] for s in res.segments]}")
