"""The output folder of ``generate``: every file written atomically, nothing half-written.

:func:`write_generation` writes ``motion.npz`` (every field of a
:class:`~jaxmotion.result.Generation`), ``motion.bvh``, ``motion_smplx.npz`` (AMASS-style
SMPL-X parameters), ``motion.glb``, the video (``motion.mp4``, the rendered bodies) and
``viewer.html`` (and ``grounding_llm.json``, the language model's prompts and answers, with
``--grounding llm``); :func:`check_output_folder` tells before any work whether a folder can take
them; :func:`summary` is the JSON line the command line prints.
"""

from __future__ import annotations

import json
import os
import tempfile
from pathlib import Path

import numpy as np

from jaxmotion.errors import GenerateError
from jaxmotion.export._common import random_subset

__all__ = ["VIDEO_KINDS", "check_output_folder", "check_outputs", "scene_heat", "summary",
           "write_generation", "write_viewer"]

VIDEO_KINDS = (None, "gif", "mp4")


def write_generation(res, out, *, video: str | None = "mp4", bvh_sample: int = 0,
                     extra: dict | None = None, skeleton: str = "smplx") -> dict[str, Path]:
    """Write the outputs into folder ``out`` (created); returns ``{name: path}``.

    ``motion.npz`` (every field), ``motion.bvh`` and ``motion_smplx.npz`` (sample
    ``bvh_sample``; the second an AMASS-style SMPL-X file, :func:`jaxmotion.export.
    write_amass_npz`), ``motion.glb`` (skinned mannequins with the room), ``motion.mp4`` /
    ``motion.gif`` (``video="mp4"|"gif"``, None to skip: the shaded mannequins in the lit
    room, 640×480 at 15 frames per second, :func:`jaxmotion.render.results.
    render_generation`; the other files are written while it draws) and ``viewer.html``;
    ``skeleton``: the bone names and hierarchy of ``motion.bvh`` (:data:`jaxmotion.export.bvh.
    SKELETONS`: ``smplx``, ``mixamo``, ``ue5``);
    ``extra``: more files ``{name: text or bytes}`` (plain names, no folders). Files are
    built in a temporary folder and moved in at the end, so an error leaves no half-written
    output.
    """
    from jaxmotion.export.bvh import check_skeleton

    check_skeleton(skeleton)
    ids = [res.target_id, *(g["object"] for g in res.segments)]
    out = check_outputs(res.scene, ids, out=out, video=video, fit=bool(res.smplx),
                        sample=bvh_sample, samples=res.num_samples)
    fresh = not out.exists()
    parent = out.parent if fresh else out
    parent.mkdir(parents=True, exist_ok=True)
    written: dict[str, Path] = {}
    # a new folder is built whole beside its final name and renamed into place (one atomic
    # step); into an existing folder each file is moved in whole, once all are built
    with tempfile.TemporaryDirectory(prefix=f".{out.name}.generate-", dir=parent) as tmp:
        tmp = Path(tmp)
        _write_files(res, tmp, video, bvh_sample, skeleton)
        for name, data in (extra or {}).items():
            if Path(name).name != name or name.startswith("."):
                raise ValueError(f"extra file name {name!r} must be a plain file name")
            (tmp / name).write_bytes(data.encode() if isinstance(data, str) else bytes(data))
        if fresh:
            mask = os.umask(0)
            os.umask(mask)
            os.chmod(tmp, 0o777 & ~mask)  # a folder as mkdir makes it, not the temporary 0700
            os.rename(tmp, out)
            tmp.mkdir()  # for the context manager's clean-up
            return {f.name: f for f in sorted(out.iterdir())}
        for f in sorted(tmp.iterdir()):
            os.replace(f, out / f.name)
            written[f.name] = out / f.name
    return written


def _write_files(res, tmp: Path, video, bvh_sample: int, skeleton: str = "smplx") -> None:
    from jaxmotion import export

    with open(tmp / "motion.npz", "wb") as f:
        np.savez(f, joints=res.joints.astype(np.float32), fps=np.float32(res.fps),
                 mask=res.mask, text=np.array(res.text),
                 **{k: np.asarray(v, np.float32) for k, v in res.smplx.items()},
                 fit_error=res.fit_error.astype(np.float32),
                 scene_rotation=res.rotation.astype(np.float32),
                 scene_shift=res.shift.astype(np.float32),
                 crop_xyz=res.crop_xyz.astype(np.float32),
                 affordance=res.affordance.astype(np.float16),
                 object_id=np.int64(-1 if res.object_id is None else res.object_id),
                 target_id=np.int64(-1 if res.target_id is None else res.target_id),
                 seed=np.int64(res.seed), steps=np.int64(res.steps),
                 guidance=np.asarray(res.guidance, np.float32),
                 consistency=np.float32(res.consistency),
                 scene_name=np.array(res.scene.name),
                 grounding=np.array(res.grounding), pipeline=np.array(res.pipeline),
                 excluded=np.asarray(res.excluded, np.int64),
                 adm_candidates=np.int64(res.adm_candidates),
                 adm_steps=np.int64(res.adm_steps),
                 motion_candidates=np.int64(res.motion_candidates),
                 segments=np.array(json.dumps(list(res.segments))),
                 paths=np.concatenate([np.asarray(q, np.float32).reshape(-1, 2)
                                       for q in res.paths] or [np.zeros((0, 2), np.float32)]),
                 path_lengths=np.asarray([len(q) for q in res.paths], np.int64),
                 **({} if res.view_xyz is None else {
                     "view_xyz": res.view_xyz.astype(np.float32),
                     "view_affordance": res.view_affordance.astype(np.float16)}))
    llm = getattr(res.understanding, "llm", None)
    if llm is not None:  # --grounding llm: the prompts and answers that chose the target
        (tmp / "grounding_llm.json").write_text(json.dumps(llm, indent=1))
    def others():  # the files beside the video, written while its room picture is drawn
        p = res.smplx
        i = int(bvh_sample)
        export.write_bvh(tmp / "motion.bvh", p["global_orient"][i], p["body_pose"][i],
                         p["transl"][i], p["betas"][i], res.fps, skeleton=skeleton)
        export.write_amass_npz(tmp / "motion_smplx.npz", p["global_orient"][i],
                               p["body_pose"][i], p["transl"][i], p["betas"][i], res.fps)
        keep = random_subset(res.scene.num_points, 60_000, res.seed)
        xyz, rgb = res.scene.xyz[keep], res.scene.rgb[keep]
        export.write_glb(tmp / "motion.glb", global_orient=p["global_orient"],
                         body_pose=p["body_pose"], transl=p["transl"], betas=p["betas"],
                         fps=res.fps, scene_xyz=xyz, scene_rgb=rgb, skeleton=skeleton)
        write_viewer(res, tmp / "viewer.html")

    if video:  # the fitted mannequins in the room (jaxmotion.render), the others beside it
        from jaxmotion.render.results import render_generation

        render_generation(res, tmp / f"motion.{video}", meanwhile=others)
    else:
        others()


def write_viewer(res, path) -> Path:
    """The result's ``viewer.html`` (:func:`jaxmotion.export.write_viewer_html`): the room's
    points (60k at most, drawn with the result's seed), the bodies, the target and a story's
    steps and paths; written atomically."""
    from jaxmotion import export

    keep = random_subset(res.scene.num_points, 60_000, res.seed)
    xyz, rgb = res.scene.xyz[keep], res.scene.rgb[keep]
    heat = scene_heat(res, xyz)
    cats = {int(o["id"]): o["category"] for o in res.scene.objects}
    steps = [{**g, "label": g["action"].replace("_", " ") + (
        f" · {cats.get(int(g['object']), 'object')} {g['object']}" if int(g["object"]) >= 0
        else " · to a point" if g.get("point") is not None else "")} for g in res.segments]
    return export.write_viewer_html(path, scene_xyz=xyz, scene_rgb=rgb, joints=res.joints,
                                    fps=res.fps, text=res.text,
                                    affordance=heat if np.any(heat) else None,
                                    smplx=res.smplx or None,
                                    scene_normal=res.scene.normal[keep],
                                    scene_instance=res.scene.instance[keep],
                                    objects=res.scene.objects, target_id=res.target_id,
                                    segments=steps, paths=res.paths)


def check_outputs(scene=None, ids=(), *, out=None, video: str | None = "mp4", fit: bool = True,
                  sample: int = 0, samples: int | None = None) -> Path | None:
    """Every check :func:`write_generation` makes on its inputs, callable before any sampling.

    ``generate`` calls it once the target is known (the scene and ids), the command line
    before anything is loaded (the folder, the video kind), and :func:`write_generation`
    again with the result: whatever would fail the writing fails here first, before the
    work is done. Checks: ``video`` is ``"mp4"``, ``"gif"`` or None; ``fit`` (BVH, GLB and
    the SMPL-X file need the fitted bodies); every id in ``ids`` (None and −1: no object) is
    in the scene's object table, the table the viewer and the video label; ``sample`` is one
    of ``samples``; ``out`` can take the files (:func:`check_output_folder`).

    Returns ``out`` as a :class:`~pathlib.Path` (None when not given); raises
    :class:`GenerateError` naming the fix.
    """
    if video not in VIDEO_KINDS:
        raise GenerateError(f"video must be 'gif', 'mp4' or None, got {video!r}")
    if not fit:
        raise GenerateError("this result has no SMPL-X fit (fit=False): BVH and GLB need it; "
                            "generate with fit=True to save it")
    if samples is not None and not (isinstance(sample, (int, np.integer))
                                    and 0 <= int(sample) < samples):
        raise GenerateError(f"bvh_sample {sample!r} is not one of the {samples} samples "
                            f"(0..{samples - 1})")
    wanted = sorted({int(i) for i in ids if i is not None and int(i) >= 0})
    objects = scene.objects if scene is not None else ()
    if missing := [i for i in wanted if i not in {int(o["id"]) for o in objects}]:
        listed = ", ".join(f"{o['id']} ({o['category']})" for o in objects) or "none"
        raise GenerateError(f"object {', '.join(map(str, missing))} is not in the scene's "
                            f"object table (its objects: {listed}); see jaxmotion scene info")
    return None if out is None else check_output_folder(out)


def check_output_folder(out) -> Path:
    """``out`` as a :class:`~pathlib.Path` once it is known to take the outputs: an existing
    folder, or a new one whose nearest existing parent can be written (tried, not guessed:
    permissions, a read-only file system). :class:`GenerateError` naming the fix otherwise;
    nothing is left behind by the check."""
    out = Path(out).expanduser()
    if out.exists() and not out.is_dir():
        raise GenerateError(f"--out {out}: is a file, not a folder; choose a folder name "
                            "(it is created)")
    probe = out
    while not probe.exists():
        if probe.parent == probe:
            break
        probe = probe.parent
    if not probe.is_dir():
        raise GenerateError(f"--out {out}: {probe} is a file, so the folder cannot be "
                            "created there; choose another path")
    try:
        with tempfile.TemporaryDirectory(prefix=".jaxmotion-write-test-", dir=probe):
            pass
    except OSError as e:
        raise GenerateError(f"--out {out}: cannot write in {probe} ({e.strerror or e}); "
                            "choose a folder you can write to") from None
    return out


def scene_heat(res, xyz: np.ndarray) -> np.ndarray:
    """The first sample's affordance (strongest channel) carried to ``xyz``: from the room
    view when there is one (nearest view point within 30 cm), else from the crop (within
    10 cm); 0 elsewhere (and everywhere when the pipeline drew no map)."""
    src, maps, reach = res.crop_xyz, res.affordance, 0.1
    if res.view_xyz is not None:
        src, maps, reach = res.view_xyz, res.view_affordance, 0.3
    if not np.any(maps[:1]):  # the object-centric pipeline: no affordance map
        return np.zeros(len(xyz), np.float32)
    from scipy.spatial import cKDTree

    d, idx = cKDTree(src).query(xyz, k=1, distance_upper_bound=reach)
    heat = np.zeros(len(xyz), np.float32)
    ok = np.isfinite(d)
    heat[ok] = maps[0, idx[ok]].max(axis=-1)
    return heat


# --------------------------------------------------------------------------- region


def summary(res, notes=(), warnings=()) -> str:
    """A JSON line describing a result (for the command line): with what was understood from
    the text (``action``, ``action_from``, ``target``, ``notes``, ``warnings``;
    :meth:`jaxmotion.grounding.report.Understanding.as_json`) when the result has it, and
    the ``notes`` and ``warnings`` given (what preparing the room did, every warning the
    command printed), each said once."""
    understood = res.understanding.as_json() if res.understanding is not None else {}
    for key, more in (("notes", notes), ("warnings", warnings)):
        said = list(understood.get(key, []))
        understood[key] = said + [str(m) for m in more if str(m) not in said]
    return json.dumps({"text": res.text, "samples": res.num_samples, "frames": int(res.mask.sum()),
                       **understood, "pipeline": res.pipeline, "target_id": res.target_id,
                       "grounding": res.grounding,
                       "excluded": list(res.excluded), "adm_candidates": res.adm_candidates,
                       "adm_steps": res.adm_steps,
                       "motion_candidates": res.motion_candidates, "steps": res.steps,
                       "fps": res.fps,
                       "fit_error_cm": [round(float(e) * 100, 2) for e in res.fit_error],
                       **({"segments": list(res.segments)} if res.segments else {}),
                       "timings_s": {k: round(v, 3) for k, v in res.timings.items()}})
