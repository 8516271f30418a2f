"""Rendering speed of ``motion.mp4`` (:mod:`jaxmotion.render`) against the joints-only drawing
(:func:`jaxmotion.export.render_motion_video` without a body), measured in the same run.

    python benchmarks/render.py [--frames 120] [--sizes 640x480,1280x720] [--repeats 2]

The motion: the kinematic character of the synthetic world sitting down on the demo room's
chair (``jaxmotion.motion.synthesize``, 120 frames at 30 fps: walk, turn, sit), its SMPL-X
parameters skinned onto the mannequin frame by frame. The room: the demo room, 60,000
points. Printed per picture size: rendered frames per second, drawing only (``Clip.draw``) and
end to end (``render_video`` to MP4: the room drawn once, every frame drawn and H.264-encoded),
the one-off set-up, and the ratio to the joints-only drawing at 640×480 (every frame, MP4).
The best of ``--repeats`` runs is kept; the drawing is also timed in CPU seconds of this
process, which a machine shared with other work inflates less than the wall clock (ffmpeg
encodes in its own process). The target is 10 frames per second at 640×480 on one CPU core.
"""

from __future__ import annotations

import argparse
import os
import platform
import tempfile
import time
from pathlib import Path

import numpy as np


def demo_motion(frames: int):
    """The demo room, and a sitting-down motion in it (``frames`` frames, repeated if more)."""
    from jaxmotion.motion import synthesize
    from jaxmotion.scene.demo import DEMO_SEED, demo_scene
    from jaxmotion.scene.rooms import sample_room

    room = sample_room(DEMO_SEED)
    scene = demo_scene()
    chair = next(o["id"] for o in room.objects if o["category"] == "chair")
    from jaxmotion.motion import MotionError

    for attempt in range(20):
        try:
            m = synthesize("sit", room.floor_rects, room.objects, chair,
                           np.random.default_rng(attempt))
            break
        except MotionError:  # a draw that cannot be done here: the next seed
            pass
    idx = np.arange(frames) % len(m.joints)
    return scene, chair, m.joints[idx], m.global_orient[idx], m.body_pose[idx], m.transl[idx], \
        m.betas


def best(fn, repeats: int, clock=time.perf_counter) -> float:
    times = []
    for _ in range(repeats):
        t = clock()
        fn()
        times.append(clock() - t)
    return min(times)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=120, help="motion frames (30 fps)")
    ap.add_argument("--sizes", default="640x480,1280x720")
    ap.add_argument("--repeats", type=int, default=2)
    args = ap.parse_args()

    from jaxmotion.export import render_motion_video
    from jaxmotion.render import Bodies, Clip

    scene, chair, joints, go, bp, tr, betas = demo_motion(args.frames)
    t = len(joints)
    print(f"{platform.processor() or platform.machine()}, {os.cpu_count()} CPUs; motion "
          f"{t} frames at 30 fps, room {scene.num_points} points")
    tmp = Path(tempfile.mkdtemp(prefix="render-bench-"))

    def clip_for(size):
        bodies = Bodies.from_smplx(go, bp, tr, betas)
        return Clip(bodies, joints[None], 30.0, scene.xyz, scene.rgb, scene_normal=scene.normal,
                    highlight=scene.instance == chair, instance=scene.instance,
                    text="sit on the chair next to the table", size=size)

    old = best(lambda: render_motion_video(tmp / "old.mp4", scene.xyz, scene.rgb, joints, 30.0,
                                           size=(640, 480), max_frames=None), args.repeats)
    old_fps = t / old
    print(f"joints only (dots and a skeleton), 640x480, MP4: {old_fps:6.1f} frames/s "
          f"({old:.2f} s)")
    for text in args.sizes.split(","):
        w, h = (int(v) for v in text.lower().split("x"))
        measure((w, h), clip_for, t, args.repeats, tmp, old_fps)


def measure(size, clip_for, t: int, repeats: int, tmp: Path, old_fps: float) -> None:
    """Print the drawing and end-to-end frames per second of the bodies at ``size``."""
    from jaxmotion.render import render_video

    holder = {}

    def setup():
        holder["clip"] = clip_for(size)
        holder["clip"].room()

    t_setup = best(setup, repeats)
    clip = holder["clip"]
    draw = best(lambda: [clip.draw(f) for f in range(t)], repeats)
    cpu = best(lambda: [clip.draw(f) for f in range(t)], repeats, time.process_time)
    total = best(lambda: render_video(tmp / f"new{size[0]}.mp4", clip_for(size)), repeats)
    print(f"rendered bodies, {size[0]}x{size[1]}: drawing {t / draw:6.1f} frames/s "
          f"({t / cpu:.1f} per CPU second of this process); MP4 end to end {t / total:6.1f} "
          f"frames/s ({total:.2f} s, set-up {t_setup:.2f} s of it); {(t / total) / old_fps:.2f}x "
          "the joints-only frames/s")


if __name__ == "__main__":
    main()
