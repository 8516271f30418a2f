"""The built-in demo: a synthetic room, an instruction, a motion and its affordance map.

``jaxmotion demo --out out`` runs it. Until the learned pipeline
(``jaxmotion generate``) ships, this is the main job on the built-in default: it
exercises the synthetic world (rooms, referring instructions, the kinematic
character) and the geometry core (the affordance map of the paper's eq. 1–2) and
writes files any viewer opens.

Outputs in ``OUT``:

- ``room.ply``: the room as a coloured triangle mesh (z-up, metres);
- ``scene.npz``: the room's labelled point cloud (jaxmotion scene format);
- ``motion.npz``: the motion in the sample schema (joints, SMPL-X parameters, text);
- ``affordance.npz``: ``xyz [N,3]``, ``affordance [N,6]``, ``distance [N,6]``, ``joints``
  (the six affordance joints' indices);
- ``affordance.ply``: the scene points coloured by the affordance (max over channels,
  dark = far, bright = where the body goes);
- ``preview_top.png`` / ``preview_persp.png``: the motion drawn in the room.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np

from jaxmotion._atomic import atomic_open

__all__ = ["run_demo"]


def run_demo(out, *, seed: int = 0, action: str | None = None, num_points: int = 60_000) -> dict:
    """Run the demo into folder ``out``; returns a JSON-ready summary."""
    import matplotlib

    from jaxmotion.data.format import save_sample
    from jaxmotion.geometry import AFFORDANCE_JOINTS, affordance_distance, distance_to_affordance
    from jaxmotion.motion import MotionError, synthesize
    from jaxmotion.scene import save_scene
    from jaxmotion.scene.instructions import NoUniqueReference, sample_task
    from jaxmotion.scene.rooms import room_to_mesh, room_to_scene, sample_room
    from jaxmotion.viz import render_preview

    action = action or "sit"
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    for attempt in range(50):  # rooms without a seat for "sit" etc. are skipped
        rng = np.random.default_rng([seed, attempt])
        room = sample_room(rng)
        try:
            text, info = sample_task(room, rng, action=action)
            motion = synthesize(action, room.floor_rects, room.objects, info["target_id"], rng)
        except (ValueError, MotionError, NoUniqueReference):
            continue
        break
    else:
        raise RuntimeError(f"demo: no room for action {action!r} in 50 tries (seed {seed})")

    scene = room_to_scene(room, num_points, np.random.default_rng([seed, attempt, 1]))
    scene = dataclasses.replace(scene, name=room.name)
    save_scene(scene, out / "scene.npz")
    mesh = room_to_mesh(room)
    with atomic_open(out / "room.ply", "wb") as f:
        f.write(mesh.export(file_type="ply"))

    t = motion.joints.shape[0]
    save_sample(out / "motion.npz", dict(
        text=text, action=action, scene_id=room.name, target_id=info["target_id"],
        joints=motion.joints, fps=float(motion.fps), mask=np.ones(t, bool), transl=motion.transl,
        global_orient=motion.global_orient, body_pose=motion.body_pose, betas=motion.betas,
    ))  # fmt: skip

    dist = np.asarray(affordance_distance(scene.xyz, motion.joints[:, list(AFFORDANCE_JOINTS)]))
    aff = np.asarray(distance_to_affordance(dist))
    with atomic_open(out / "affordance.npz", "wb") as f:
        np.savez(f, xyz=scene.xyz, affordance=aff, distance=dist,
                 joints=np.array(AFFORDANCE_JOINTS))
    import trimesh

    heat = aff.max(axis=1)
    heat = (heat - heat.min()) / max(float(np.ptp(heat)), 1e-6)
    colors = (matplotlib.colormaps["inferno"](heat) * 255).astype(np.uint8)
    cloud = trimesh.PointCloud(scene.xyz, colors=colors)
    with atomic_open(out / "affordance.ply", "wb") as f:
        f.write(cloud.export(file_type="ply"))

    target = scene.instance == info["target_id"]
    previews = render_preview(scene.xyz, scene.rgb, motion.joints, out / "preview",
                              target_mask=target, title=f"{text}  [{action}]")
    anchor = t - 1 if action != "stand_up" else 0
    pelvis_to_target = float(np.min(np.linalg.norm(scene.xyz[target] - motion.joints[anchor, 0],
                                                   axis=1))) if target.any() else None
    return {
        "room": room.name,
        "text": text,
        "action": action,
        "target": {"id": info["target_id"], "category": info["target_class"]},
        "frames": t,
        "fps": float(motion.fps),
        "pelvis_to_target_at_anchor_m": round(pelvis_to_target, 3) if pelvis_to_target else None,
        "files": sorted(p.name for p in out.iterdir() if p.is_file() and not p.name.startswith(".")),
        "previews": [str(p) for p in previews],
    }
