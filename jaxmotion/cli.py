"""The ``jaxmotion`` command line.

Subcommands import their heavy modules lazily, so ``jaxmotion --help`` and
``jaxmotion version`` start in well under a second and compile nothing.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Sequence
from typing import NoReturn

from jaxmotion._version import __version__


def _cmd_version(args: argparse.Namespace) -> int:
    print(f"jaxmotion {__version__}")
    if args.verbose:
        from importlib import metadata

        for pkg in ("jax", "jaxlib", "flax", "optax", "orbax-checkpoint", "numpy", "trimesh"):
            try:
                print(f"  {pkg} {metadata.version(pkg)}")
            except metadata.PackageNotFoundError:
                print(f"  {pkg} (not installed)")
        import jax

        print(f"  devices: {', '.join(str(d) for d in jax.devices())}")
    return 0


def _object_row(o: dict) -> dict:
    """One object of ``scene info``: id, category, centre and size (m), and the point count
    and confidence where the table has them."""
    import numpy as np

    lo, hi = np.asarray(o["bbox_min"], float), np.asarray(o["bbox_max"], float)
    row = {"id": o["id"], "category": o["category"],
           "centre": np.round((lo + hi) / 2, 3).tolist(), "size": np.round(hi - lo, 3).tolist()}
    row.update({k: o[k] for k in ("points", "confidence", "source", "surface_height", "affords")
                if k in o})
    return row


def _prepared(args: argparse.Namespace):
    """The room of ``scene info`` / ``scene segment``: levelled and labelled as ``generate``
    makes it (:func:`jaxmotion.scene.prepare.prepare_room`)."""
    from jaxmotion.scene.demo import demo_scene
    from jaxmotion.scene.prepare import prepare_room

    return prepare_room(demo_scene() if args.path == "demo" else args.path,
                        num_points=args.points, seed=args.seed, up=args.up, unit=args.unit)


def _cmd_scene_info(args: argparse.Namespace) -> int:
    from jaxmotion.scene.checks import scene_warnings

    room = _prepared(args)
    scene, notes = room.scene, room.notes
    if scene.num_points == 0:
        raise ValueError(f"{args.path}: the scene has no points")
    lo, hi = scene.bounds()
    info = {
        "name": scene.name,
        "points": scene.num_points,
        "bounds_min": [round(float(v), 4) for v in lo],
        "bounds_max": [round(float(v), 4) for v in hi],
        "has_normals": bool((abs(scene.normal).sum(axis=1) > 0).any()),
        "labelled_points": int((scene.semantic >= 0).sum()),
        "instances": int(len(set(scene.instance[scene.instance >= 0].tolist()))),
        "objects": len(scene.objects),
        "labels": room.labels,
    }
    if scene.objects:
        info["object_table"] = [_object_row(o) for o in scene.objects]
    if notes:
        info["notes"] = list(notes)
    for message in scene_warnings(scene):
        print(f"warning: {message}", file=sys.stderr)
    print(json.dumps(info, indent=2))
    return 0


def _cmd_scene_segment(args: argparse.Namespace) -> int:
    from jaxmotion.scene import save_scene
    from jaxmotion.scene.io import save_scene_ply

    if not str(args.out).lower().endswith((".npz", ".ply")):
        raise ValueError(f"--out {args.out}: give a .npz or .ply file name")
    room = _prepared(args)
    out = (save_scene if str(args.out).lower().endswith(".npz") else save_scene_ply)(
        room.scene, args.out)
    for note in room.notes:
        print(f"note: {note}", file=sys.stderr)
    rows = [_object_row(o) for o in room.scene.objects]
    print(json.dumps({"out": str(out), "points": room.scene.num_points, "labels": room.labels,
                      "objects": rows, "notes": list(room.notes)}, indent=1))
    return 0


def _cmd_scene_convert(args: argparse.Namespace) -> int:
    from jaxmotion.scene import save_scene
    from jaxmotion.scene.prepare import prepare_room

    room = prepare_room(args.src, num_points=args.points, seed=args.seed, up=args.up,
                        unit=args.unit, segment=False, cache=False)  # levelled, as it is
    out = save_scene(room.scene, args.dst)
    for note in room.notes:
        print(f"note: {note}", file=sys.stderr)
    print(f"wrote {out} ({room.scene.num_points} points)")
    return 0


def _cmd_synth(args: argparse.Namespace) -> int:
    from pathlib import Path

    from jaxmotion.data.synth import SynthSettings, build_dataset, render_dataset_previews

    out = Path(args.out)
    if not args.preview_only:
        settings = SynthSettings(scenes=args.scenes, per_scene=args.per_scene, seed=args.seed,
                                 points_per_scene=args.points, split_scenes=args.split_scenes,
                                 phrasing=args.phrasing)
        manifest = build_dataset(out, settings, workers=args.workers, stats=not args.no_stats,
                                 motions=args.motions, motions_fit_iters=args.motions_fit_iters)
        print(f"dataset in {out}: samples {manifest['samples']}, scenes {manifest['scenes']}, "
              f"{manifest['build_seconds_this_run']} s")
        if args.motions is not None:
            lib = manifest["motion_library"]
            print(f"motion library {args.motions}: {lib['files']} files, clips {lib['clips']} "
                  f"(labels: {lib['labels']}; rejected: {lib['rejected']}); samples "
                  f"{manifest['samples_by_origin']}")
    if args.preview or args.preview_only:
        paths = render_dataset_previews(out, count=args.preview_count, split=args.preview_split)
        print(f"previews: {len(paths)} PNG files in {out / 'preview'}")
    return 0


def _cmd_data_inspect(args: argparse.Namespace) -> int:
    """One motion file as jaxmotion reads it: format, frames, rate, unit, up axis and, for a
    BVH, the joint of the file each SMPL-X joint is read from, with the mapping's confidence."""
    import numpy as np

    from jaxmotion.io import load_motion

    options = {}
    if (args.up, args.unit, args.joint_map) != ("auto", "auto", "auto"):
        options.update(up=args.up, unit=args.unit, joint_map=args.joint_map)
    m = load_motion(args.file, **options)
    j = np.asarray(m.joints)
    feet = j[:, [7, 8, 10, 11], 2]
    out = {"file": str(args.file), "format": m.info.get("format"), "frames": int(j.shape[0]),
           "fps": float(m.fps), "seconds": round(j.shape[0] / float(m.fps), 3),
           "body_height_m": round(float(j[0, 15, 2] - feet[0].min()) + 0.1, 3),
           "lowest_foot_m": round(float(feet.min()), 3)}
    for key in ("unit", "up", "rest_frame_dropped", "joint_map", "joint_map_confidence"):
        if key in m.info:
            value = m.info[key]
            out[key] = round(value, 6) if isinstance(value, float) else value
    if "joints_from" in m.info:
        out["joints_from"] = {k: (v if v is not None else "(filled in: no such joint)")
                              for k, v in m.info["joints_from"].items()}
    print(json.dumps(out, indent=2))
    return 0


def _cmd_data_convert(args: argparse.Namespace) -> int:
    if args.kind == "humanise":
        return _convert_humanise(args)
    if args.scannet is not None or args.points is not None:
        raise ValueError("--scannet and --points apply to --from humanise only")
    from jaxmotion.io.convert import convert

    options = {"action": args.action, "max_frames": args.max_frames,
               "min_frames": args.min_frames, "captions": args.captions, "split": args.split,
               "fit_iters": args.fit_iters, "floor": not args.keep_height}
    if args.fps is not None:
        options["fps"] = args.fps
    if args.kind in ("bvh", "gltf"):
        options.update(up=args.up, unit=args.unit, joint_map=args.joint_map)
    elif (args.up, args.unit, args.joint_map) != ("auto", "auto", "auto"):
        raise ValueError("--up, --unit and --joint-map apply to BVH and glTF files only")
    manifest = convert(args.kind, args.src, args.out, stats=not args.no_stats, **options)
    src = manifest["sources"]
    print(f"dataset in {args.out}: samples {manifest['samples']}, sources {src['done']} of "
          f"{src['total']} ({src['failed']} failed), {manifest['build_seconds_this_run']} s")
    for e in manifest["errors"][:5]:
        print(f"warning: skipped {e['error']}", file=sys.stderr)
    return 0


def _convert_humanise(args: argparse.Namespace) -> int:
    from jaxmotion.io.humanise_convert import convert_humanise

    others = {"--action": args.action != "walk", "--captions": args.captions != "first",
              "--fps": args.fps is not None,
              "--fit-iters": args.fit_iters != 200, "--keep-height": args.keep_height,
              "--up / --unit / --joint-map": (args.up, args.unit, args.joint_map) != (
                  "auto", "auto", "auto")}
    if given := [k for k, v in others.items() if v]:
        raise ValueError(f"{', '.join(given)} do not apply to HUMANISE (it has its own actions, "
                         "texts, SMPL-X parameters and heights)")
    manifest = convert_humanise(args.src, args.out, scannet=args.scannet,
                                points=50_000 if args.points is None else args.points,
                                max_frames=args.max_frames, min_frames=args.min_frames,
                                split=args.split, stats=not args.no_stats)
    src = manifest["sources"]
    print(f"dataset in {args.out}: samples {manifest['samples']}, scenes "
          f"{manifest['scenes']['total']}, sources {src['done']} of {src['total']} "
          f"({src['failed']} failed), {manifest['build_seconds_this_run']} s")
    for e in manifest["errors"][:5]:
        print(f"warning: skipped {e['error']}", file=sys.stderr)
    return 0


def _cmd_demo(args: argparse.Namespace) -> int:
    from jaxmotion.demo import run_demo

    result = run_demo(args.out, seed=args.seed, action=args.action)
    print(json.dumps(result, indent=2))
    return 0


def _cmd_sample(args: argparse.Namespace) -> int:
    from jaxmotion._jax_setup import enable_compilation_cache
    from jaxmotion.diffusion import SamplerSpec
    from jaxmotion.sample import sample_split

    enable_compilation_cache()
    adm = SamplerSpec(args.adm_sampler or args.sampler, args.adm_steps or args.steps, args.eta,
                      args.guidance)
    amdm = SamplerSpec(args.sampler, args.steps, args.eta, args.guidance, args.consistency)
    out = sample_split(args.data, args.split, args.adm, args.amdm, args.out,
                       num_cases=args.cases, samples_per_case=args.per_case, seed=args.seed,
                       adm=adm, amdm=amdm, batch_size=args.batch_size)
    print(f"wrote {out}")
    return 0


def _guidance_arg(text: str):
    """``--guidance G`` or ``--guidance ADM,AMDM`` (argparse type)."""
    try:
        values = tuple(float(v) for v in text.split(","))
    except ValueError:
        values = ()
    if len(values) not in (1, 2) or not all(v > 0 for v in values):
        raise argparse.ArgumentTypeError(
            f"{text!r}: give one positive scale (both stages) or two, ADM,AMDM, e.g. 2,1")
    return values[0] if len(values) == 1 else values


def _unit_arg(text: str) -> float:
    """A number in [0, 1] (argparse type)."""
    try:
        v = float(text)
    except ValueError:
        v = float("nan")
    if not 0.0 <= v <= 1.0:
        raise argparse.ArgumentTypeError(f"{text!r}: give a number in [0, 1] (0 = off)")
    return v


def _cmd_generate(args: argparse.Namespace) -> int:
    """Validate everything (options, text, checkpoints, output folder, scene file) before any
    model is loaded; progress and warnings go to stderr, stdout gets the JSON summary alone."""
    import time
    import warnings

    from jaxmotion.export.folder import check_outputs, summary
    from jaxmotion.generation import generate
    from jaxmotion.options import DEFAULT_TEXT, GenerateOptions

    t0 = time.perf_counter()
    if args.batch is None and (args.batch_size is not None or args.coordinator is not None):
        raise ValueError("--batch-size and --coordinator go with --batch CASES.jsonl")
    if args.checkpoints and len(args.checkpoints) not in (1, 2):
        raise ValueError("--checkpoints takes a folder, or the ADM and AMDM workdirs / files")
    ckpt = None if not args.checkpoints else (
        args.checkpoints[0] if len(args.checkpoints) == 1 else tuple(args.checkpoints))
    if args.object_checkpoints and len(args.object_checkpoints) not in (1, 2):
        raise ValueError("--object-checkpoints takes a folder, or the trajectory and completion "
                         "workdirs / files")
    objects = None if not args.object_checkpoints else (
        args.object_checkpoints[0] if len(args.object_checkpoints) == 1
        else tuple(args.object_checkpoints))
    options = GenerateOptions.build(
        object_id=args.object, samples=args.samples, seed=args.seed, steps=args.steps,
        adm_steps=args.adm_steps, guidance=args.guidance, consistency=args.consistency,
        grounding=args.grounding, adm_candidates=args.adm_candidates,
        motion_candidates=args.motion_candidates, checkpoints=ckpt, num_points=args.points,
        pipeline=args.pipeline, object_checkpoints=objects, up=args.up, unit=args.unit,
        cvae_checkpoints=None if not args.cvae else tuple(args.cvae))
    if args.batch is not None:
        return _generate_batch(args, options, t0)
    args.video = args.video or "mp4"
    check_outputs(out=args.out, video=None if args.video == "none" else args.video)
    if args.scene != "demo":
        from pathlib import Path

        if not Path(args.scene).exists():
            raise FileNotFoundError(f"--scene {args.scene}: no such file or folder; give a mesh "
                                    "or point cloud (PLY / OBJ / GLB / GLTF / OFF / STL / NPZ), a "
                                    "ScanNet scan folder (scans/scene0000_00) or 'demo'")
    text = DEFAULT_TEXT if args.text is None else args.text
    trajectory = None
    if args.plan is not None:
        if args.text is not None:
            raise ValueError("give --text (one instruction) or --plan (a story), not both")
        from pathlib import Path

        if not Path(args.plan).is_file():
            raise FileNotFoundError(f"--plan {args.plan}: no such file; give a JSON list of "
                                    'steps such as [{"action": "stand_up", "object": 3}, '
                                    '{"action": "walk", "object": 4}]')
        text = f"the story in {args.plan}"
    if args.trajectory is not None:
        if args.plan is not None:
            raise ValueError("give --plan (a story) or --trajectory (a path to follow), not both")
        from jaxmotion.planning.control import check_path, load_path

        trajectory = check_path(load_path(args.trajectory))  # a bad file fails before loading
        text = "walk along the path" if args.text is None else args.text
    print(f"generating {options.samples} motion(s) for {text!r} in {args.scene} ...",
          file=sys.stderr, flush=True)
    prepare = None
    if args.video != "none":  # the renderer's kernels load while the motion is sampled
        from jaxmotion.render import prepare_in_background as prepare
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", UserWarning)
        res = generate(args.scene, text, options=options, progress=True, plan=args.plan,
                       trajectory=trajectory, meanwhile=prepare)
    from jaxmotion.errors import SceneNote

    notes = [str(w.message) for w in caught if issubclass(w.category, SceneNote)]
    warned = [str(w.message) for w in caught if not issubclass(w.category, SceneNote)]
    for message in notes:
        print(f"note: {message}", file=sys.stderr)
    for message in warned:
        print(f"warning: {message}", file=sys.stderr)
    t1 = time.perf_counter()
    files = res.save(args.out, video=None if args.video == "none" else args.video,
                     skeleton=args.skeleton)
    res.timings["write"] = time.perf_counter() - t1
    print(f"  {'write':<10} {res.timings['write']:6.2f} s", file=sys.stderr)
    print(f"wrote {', '.join(sorted(files))} to {args.out} in {time.perf_counter() - t0:.1f} s",
          file=sys.stderr)
    print(summary(res, notes, warned), flush=True)
    return 0


def _generate_batch(args: argparse.Namespace, options, t0: float) -> int:
    """``generate --batch``: every request of the file (:mod:`jaxmotion.batch`); stdout gets
    one JSON line with the counts and the summary's path (exit 1 when a request failed)."""
    import os
    import time

    single = [f"--{n.replace('_', '-')}" for n in ("scene", "text", "plan", "trajectory",
                                                  "object", "seed", "samples")
              if getattr(args, n) not in (None, "demo")]
    if single:
        raise ValueError(f"{', '.join(single)}: each request of --batch gives its own (\"scene\","
                         " \"text\", \"plan\", \"object_id\", \"seed\", \"samples\"); the "
                         "other options apply to every request")
    if args.coordinator is not None:
        if args.processes is None or args.process_id is None:
            raise ValueError("--coordinator needs --processes N and --process-id I")
        if not 0 <= args.process_id < args.processes:
            raise ValueError(f"--process-id must be in 0 .. {args.processes - 1}, got "
                             f"{args.process_id}")
        import jax

        jax.distributed.initialize(args.coordinator, num_processes=args.processes,
                                   process_id=args.process_id)
    elif args.processes is not None or args.process_id is not None:
        raise ValueError("--processes and --process-id go with --coordinator HOST:PORT")
    elif os.environ.get("JAXMOTION_DISTRIBUTED") == "1":  # the cluster's environment says
        import jax

        jax.distributed.initialize()
    from jaxmotion.batch import generate_batch

    video = None if args.video in (None, "none") else args.video
    rows = generate_batch(args.batch, args.out, options=options, video=video,
                          batch_size=args.batch_size, skeleton=args.skeleton)
    if args.coordinator is not None or os.environ.get("JAXMOTION_DISTRIBUTED") == "1":
        import jax

        # the processes leave together, just after generate_batch's last barrier: left to the
        # interpreter's exit, the shutdown barrier waited (and aborted process 0 after its
        # 300 s) on a process slow to reach its exit handlers on a loaded machine
        jax.distributed.shutdown()
    counts = {s: sum(r["status"] == s for r in rows) for s in ("done", "failed", "missing")}
    seconds = time.perf_counter() - t0
    print(json.dumps({"requests": len(rows), **counts, "seconds": round(seconds, 1),
                      "summary": os.path.join(args.out, "summary.jsonl")}), flush=True)
    return 0 if counts["failed"] == 0 and counts["missing"] == 0 else 1


def _size_arg(text: str) -> tuple[int, int]:
    import re

    m = re.fullmatch(r"\s*(\d+)\s*[xX×]\s*(\d+)\s*", text)
    if not m or min(int(m[1]), int(m[2])) < 16 or max(int(m[1]), int(m[2])) > 8192:
        raise ValueError(f"--size {text!r}: give WIDTHxHEIGHT in pixels, e.g. 640x480 or "
                         "1280x720 (16 to 8192 each)")
    return int(m[1]), int(m[2])


def _cmd_retarget(args: argparse.Namespace) -> int:
    """A generated motion's SMPL-X body written as a BVH of another rig's skeleton."""
    from pathlib import Path

    import numpy as np

    from jaxmotion.export import write_bvh

    src, out = Path(args.motion), Path(args.out)
    if out.suffix.lower() != ".bvh":
        raise ValueError(f"--out {out}: give a .bvh file")
    if not src.is_file():
        raise ValueError(f"{src}: no such file; give generate's motion.npz or "
                         "motion_smplx.npz (an AMASS-style SMPL-X .npz)")
    with np.load(src, allow_pickle=False) as f:
        generated = {"global_orient", "body_pose", "transl", "fps"} <= set(f.files)
        if generated:
            k = f["global_orient"].shape[0]
            if not 0 <= args.sample < k:
                raise ValueError(f"--sample {args.sample}: {src} has samples 0..{k - 1}")
            go, bp, tr = (f[n][args.sample] for n in ("global_orient", "body_pose", "transl"))
            betas = f["betas"][args.sample] if "betas" in f.files else None
            fps = float(f["fps"])
    if not generated:
        from jaxmotion.io import load_motion

        m = load_motion(src)
        if m.global_orient is None:
            raise ValueError(f"{src} holds joints only, no SMPL-X parameters to retarget; give "
                             "generate's motion.npz or an AMASS-style SMPL-X .npz")
        go, bp, tr, betas, fps = m.global_orient, m.body_pose, m.transl, m.betas, m.fps
    path = write_bvh(out, go, bp, tr, betas, fps, skeleton=args.skeleton)
    print(f"wrote {path} ({args.skeleton} skeleton, {len(go)} frames at {fps:g} fps)",
          file=sys.stderr)
    return 0


def _cmd_render(args: argparse.Namespace) -> int:
    import time
    from pathlib import Path

    size = _size_arg(args.size)
    out = Path(args.out)
    if out.suffix.lower() == ".mp4" and (size[0] % 2 or size[1] % 2):
        raise ValueError(f"--size {args.size}: an .mp4 needs even width and height")
    if args.fps is not None and not args.fps > 0:
        raise ValueError(f"--fps {args.fps}: give a positive frame rate")
    if not Path(args.motion).is_file():
        raise FileNotFoundError(f"{args.motion}: no such file; give a motion.npz written by "
                                "'jaxmotion generate' or a dataset sample .npz")
    from jaxmotion._jax_setup import enable_compilation_cache
    from jaxmotion.render.results import render_saved

    enable_compilation_cache()  # the mannequin's shape basis at the motion's betas is kept there
    t0 = time.perf_counter()
    path = render_saved(args.motion, out, scene=args.scene, num_points=args.points, size=size,
                        samples=args.samples, camera=args.camera, azimuth=args.azimuth,
                        elevation=args.elevation, video_fps=args.fps, frame=args.frame)
    print(f"wrote {path} in {time.perf_counter() - t0:.1f} s", file=sys.stderr)
    return 0


def _cmd_eval(args: argparse.Namespace) -> int:
    from jaxmotion._jax_setup import enable_compilation_cache
    from jaxmotion.eval.runner import evaluate, format_markdown, parse_model, write_report

    enable_compilation_cache()
    if args.descriptions is not None:
        return _eval_descriptions(args)
    if not args.model:
        raise ValueError("eval needs --model NAME=ADM,AMDM[,...] (or --descriptions)")
    if args.grounding not in ("auto", "adm"):
        raise ValueError(f"--grounding {args.grounding} is for --descriptions; a --model row "
                         "finds its regions with auto or adm")
    models = [parse_model(m) for m in args.model]
    names = [m.name for m in models]
    if len(set(names)) != len(names):
        raise ValueError(f"--model names must be unique, got {names}")
    report = evaluate(args.data, models, split=args.split, num_cases=args.cases or 64,
                      samples=args.samples or 4, replications=args.replications, seed=args.seed,
                      body=not args.joints_only, evaluator=args.evaluator,
                      recognizer=args.recognizer,
                      vertex_stride=args.vertex_stride, batch_size=args.batch_size,
                      protocol=args.protocol, grounding=args.grounding,
                      keep_motions=args.save_motions)
    paths = write_report(report, args.out)
    print(format_markdown(report))
    print(f"wrote {paths[0]} and {paths[1]}", file=sys.stderr)
    return 0


def _eval_descriptions(args: argparse.Namespace) -> int:
    """``jaxmotion eval --descriptions [FILE]``: generate on each description and on the
    template sentence of the same target, scored (:mod:`jaxmotion.eval.descriptions`)."""
    from jaxmotion.eval.descriptions import evaluate_descriptions, format_markdown, write_report

    if args.model:
        raise ValueError("--descriptions runs jaxmotion generate's own pipeline (the shipped "
                         "checkpoints, or --checkpoints ADM AMDM); leave out --model")
    options = {"grounding": args.grounding, "pipeline": args.pipeline}
    if args.checkpoints:
        options["checkpoints"] = tuple(args.checkpoints)
    report = evaluate_descriptions(args.data, args.descriptions or None,
                                   recognizer=args.recognizer, seed=args.seed,
                                   samples=args.samples or 1, num_cases=args.cases,
                                   templates=not args.no_templates, **options)
    paths = write_report(report, args.out)
    print(format_markdown(report))
    print(f"wrote {', '.join(str(p) for p in paths)}", file=sys.stderr)
    return 0


def _cmd_studio(args: argparse.Namespace) -> int:
    from jaxmotion.studio import StudioError, serve

    if not 0 < args.port < 65536:
        raise ValueError(f"--port {args.port} is not a port number (1..65535)")
    try:
        import fastapi  # noqa: F401
        import uvicorn  # noqa: F401
    except ImportError as e:
        raise ValueError(f"the studio needs the web packages ({e.name} is missing); they are "
                         "among jaxmotion's dependencies: reinstall it (pip install -c "
                         "requirements.lock -e .)") from None
    options = {k: v for k, v in (("up", args.up), ("unit", args.unit), ("steps", args.steps))
               if v is not None}
    try:
        serve(args.room, folder=args.folder, host=args.host, port=args.port,
              open_browser=not args.no_open, options=options,
              video=None if args.video == "none" else args.video)
    except StudioError as e:
        raise ValueError(str(e)) from None
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="jaxmotion",
        description="Language-guided human motion generation in 3D scenes (JAX/Flax).",
        epilog="Run 'jaxmotion COMMAND --help' for the options of a command.",
    )
    parser.add_argument("--version", action="version", version=f"jaxmotion {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")

    p = sub.add_parser("version", help="print the version (and dependencies with -v)")
    p.add_argument("-v", "--verbose", action="store_true", help="also list dependencies and devices")
    p.set_defaults(func=_cmd_version)

    scene = sub.add_parser("scene", help="inspect or convert a room scan, mesh or point cloud")
    scene_sub = scene.add_subparsers(dest="scene_command", metavar="ACTION", required=True)

    def scene_common(q):
        q.add_argument("--points", type=int, default=None, help="points to sample from a mesh")
        q.add_argument("--seed", type=int, default=0, help="sampling seed")
        q.add_argument("--up", choices=("auto", "z", "y"), default="auto",
                       help="up axis of the file (default auto: found from its floor)")
        q.add_argument("--unit", choices=("auto", "m", "cm", "mm", "ft", "in"), default="auto",
                       help="length unit of the file (default auto: from the room's size)")

    q = scene_sub.add_parser("info", help="load a scene and print a summary as JSON")
    q.add_argument("path", help="PLY / OBJ / GLB / GLTF / OFF / STL / NPZ file, a ScanNet scan "
                   "folder (scans/scene0000_00: objects from its aggregation, axis-aligned), a "
                   "PROX scenes/<Name>.ply, or 'demo'")
    scene_common(q)
    q.set_defaults(func=_cmd_scene_info)

    q = scene_sub.add_parser(
        "segment", help="find the floor, walls and objects of a room without labels and write "
        "it labelled (.npz with the object table, or .ply with label / instance)")
    q.add_argument("path", help="a mesh or point cloud without object labels (PLY / OBJ / GLB "
                   "/ GLTF / OFF / STL), or any scene file")
    q.add_argument("--out", required=True, help="the labelled room: .npz (read by generate "
                   "and scene info, with categories and confidences) or .ply")
    scene_common(q)
    q.set_defaults(func=_cmd_scene_segment)

    q = scene_sub.add_parser("convert", help="load a scene, put it in jaxmotion's frame (metres, "
                             "z-up, floor at 0) and save it as jaxmotion .npz")
    q.add_argument("src", help="input mesh or point cloud, or a ScanNet scan folder")
    q.add_argument("dst", help="output .npz")
    scene_common(q)
    q.set_defaults(func=_cmd_scene_convert)

    p = sub.add_parser(
        "synth",
        help="build the synthetic HUMANISE-like dataset (rooms, instructions, motions)",
        description="Build (or resume, by running the same command again) a synthetic dataset "
        "in the sample schema: DIR/scenes/*.npz, DIR/samples/{train,val,test}/*.npz, "
        "DIR/manifest.json, DIR/stats.npz. Deterministic for a seed.",
    )
    p.add_argument("--out", required=True, help="dataset folder")
    p.add_argument("--scenes", type=int, default=100, help="rooms (default 100)")
    p.add_argument("--per-scene", type=int, default=10, help="instructions per room (default 10)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--workers", type=int, default=1, help="processes (default 1)")
    p.add_argument("--points", type=int, default=50_000, help="points per room scan")
    p.add_argument("--split-scenes", type=int, default=None, metavar="S",
                   help="split only the first S rooms into train / val / test and make every "
                   "later room a training room: more training rooms, the same val and test (run "
                   "on an S-room build's folder, it adds the rooms in place)")
    p.add_argument("--phrasing", choices=("default", "rich"), default="default",
                   help="instruction phrasing: 'default' (the grammar the shipped checkpoints "
                   "were trained on) or 'rich' (many more verb phrases, relation phrasings, "
                   "object words, polite and two-clause forms; one action on one object)")
    p.add_argument("--motions", default=None, metavar="SRC",
                   help="a folder of real motions (AMASS .npz, .bvh, HumanML3D .npy; labelled "
                   "by SRC/labels.json, by name, or by their geometry) to use for the walk / "
                   "sit / stand-up / lie samples where a clip fits the room; the procedural "
                   "character makes the rest")
    p.add_argument("--motions-fit-iters", type=int, default=200,
                   help="SMPL-X fitting iterations for --motions files without SMPL-X "
                   "parameters (BVH, HumanML3D; 0: the analytic start only)")
    p.add_argument("--no-stats", action="store_true", help="skip the normalisation statistics")
    p.add_argument("--preview", action="store_true", help="also render PNG previews of samples")
    p.add_argument("--preview-only", action="store_true",
                   help="only render previews of an existing dataset in --out")
    p.add_argument("--preview-count", type=int, default=4, help="samples to preview")
    p.add_argument("--preview-split", default="train", choices=("train", "val", "test"))
    p.set_defaults(func=_cmd_synth)

    data = sub.add_parser("data",
                          help="bring real motion data (HumanML3D, AMASS, BVH, HUMANISE) in")
    data_sub = data.add_subparsers(dest="data_command", metavar="ACTION", required=True)
    q = data_sub.add_parser(
        "convert",
        help="convert a motion dataset to the sample schema (like 'jaxmotion synth' makes)",
        description="Read HumanML3D (the folder with new_joints/), AMASS (.npz) or BVH files "
        "(a file or a folder, searched recursively) and write DIR/scenes/floor.npz, "
        "DIR/samples/{train,val,test}/*.npz, DIR/manifest.json and DIR/stats.npz: clips of at "
        "most --max-frames (120) frames at --fps (30) on a flat floor, labelled 'walk' unless "
        "--action says otherwise. HUMANISE (--from humanise, with --scannet) keeps its "
        "actions, texts and target objects, each motion in its ScanNet room "
        "(DIR/scenes/<scene_id>.npz). "
        "Resumable: run the same command again to continue.",
    )
    q.add_argument("src", help="the source file or folder")
    q.add_argument("--from", dest="kind", required=True,
                   choices=("humanml3d", "amass", "bvh", "gltf", "humanise"),
                   help="the source format (gltf: skinned .glb / .gltf animations)")
    q.add_argument("--scannet", default=None, metavar="DIR",
                   help="HUMANISE: your ScanNet folder holding scans/<scene_id>/ (required)")
    q.add_argument("--points", type=int, default=None,
                   help="HUMANISE: surface points per ScanNet room (default 50000)")
    q.add_argument("--out", required=True, help="dataset folder")
    q.add_argument("--action", default="walk", choices=("walk", "sit", "stand_up", "lie"),
                   help="action label of every sample (default walk; the sources have none)")
    q.add_argument("--fps", type=float, default=None,
                   help="frame rate of the samples (default 30, the scene data's; 20 keeps "
                   "HumanML3D's own rate, as its text-to-motion protocol uses)")
    q.add_argument("--max-frames", type=int, default=120, help="clip length (default 120)")
    q.add_argument("--min-frames", type=int, default=30,
                   help="drop clips shorter than this (default 30)")
    q.add_argument("--captions", choices=("first", "all"), default="first",
                   help="HumanML3D: the first caption of a clip, or one sample per caption")
    q.add_argument("--split", choices=("auto", "train", "val", "test"), default="auto",
                   help="auto: HumanML3D's lists; HUMANISE's (ScanNet scenes below 600 train, "
                   "the others test); else a hash of the file path (80/10/10)")
    q.add_argument("--fit-iters", type=int, default=200,
                   help="SMPL-X fitting iterations for joint-only sources (0: analytic start)")
    q.add_argument("--keep-height", action="store_true",
                   help="keep the source heights (default: feet put on the floor z = 0)")
    q.add_argument("--up", choices=("auto", "y", "z"), default="auto",
                   help="BVH: up axis of the files (auto: the axis the head is above the "
                   "pelvis along)")
    q.add_argument("--unit", default="auto",
                   help="BVH: metres per file unit, or auto (default)")
    q.add_argument("--joint-map", default="auto",
                   help="BVH: auto, cmu, mixamo, mocapbank, cc (Character Creator / iClone), "
                   "smplx, jaxmotion or a JSON file {smplx_joint: bvh_joint} (End Sites: "
                   "<parent>_End)")
    q.add_argument("--no-stats", action="store_true", help="skip the normalisation statistics")
    q.set_defaults(func=_cmd_data_convert)
    q = data_sub.add_parser(
        "inspect", help="show how a motion file is read (joint mapping, unit, up axis, rate)",
        description="Read one motion file (BVH, AMASS .npz, HumanML3D .npy, ...) as 'data "
        "convert' would and print, as JSON: frames, frame rate, unit, up axis, body height "
        "(first frame: the head joint above the lowest foot, plus 10 cm for the crown), "
        "the lowest foot and, for a BVH, the joint of the file each SMPL-X joint is read "
        "from (the joint map found, automatic when no built-in one names the skeleton) and "
        "the mapping's confidence. A skeleton that cannot be mapped with confidence is an "
        "error that shows the mapping found.")
    q.add_argument("file", help="the motion file")
    q.add_argument("--up", choices=("auto", "y", "z"), default="auto", help="BVH: up axis")
    q.add_argument("--unit", default="auto", help="BVH: metres per file unit, or auto")
    q.add_argument("--joint-map", default="auto",
                   help="BVH: auto, a built-in map name or a JSON file {smplx_joint: bvh_joint}")
    q.set_defaults(func=_cmd_data_inspect)

    p = sub.add_parser(
        "sample",
        help="sample motions with trained ADM + AMDM for cases of a dataset split",
        description="Run the affordance pipeline (ADM -> AMDM) from training workdirs over "
        "the first cases of a split; write joints (crop and world frame), affordance maps, "
        "ground truth and texts to an .npz.",
    )
    p.add_argument("--adm", required=True, help="ADM training workdir (model.safetensors)")
    p.add_argument("--amdm", required=True, help="AMDM training workdir (model.safetensors)")
    p.add_argument("--data", required=True, help="dataset folder (jaxmotion synth)")
    p.add_argument("--split", default="test", choices=("train", "val", "test"))
    p.add_argument("--cases", type=int, default=8, help="cases from the split")
    p.add_argument("--per-case", type=int, default=1, help="samples per case")
    p.add_argument("--sampler", default="ddim", choices=("ddim", "ddpm"))
    p.add_argument("--steps", type=int, default=50, help="DDIM steps (DDPM uses all)")
    p.add_argument("--adm-sampler", default=None, choices=("ddim", "ddpm"))
    p.add_argument("--adm-steps", type=int, default=None)
    p.add_argument("--eta", type=float, default=0.0)
    p.add_argument("--guidance", type=float, default=1.0, help="classifier-free guidance scale")
    p.add_argument("--consistency", type=_unit_arg, default=0.0, metavar="S",
                   help="affordance-consistency guidance strength of the AMDM in [0, 1] "
                   "(default 0 = off)")
    p.add_argument("--batch-size", type=int, default=8)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--out", default="samples.npz")
    p.set_defaults(func=_cmd_sample)

    p = sub.add_parser(
        "generate",
        help="generate motions for a sentence in a room (the main job)",
        description="Load a room (any mesh or point cloud, a labelled ScanNet-style .ply, a ScanNet "
        "scan folder, or 'demo'), find the region the sentence is about (or use --object), sample ADM -> AMDM "
        "with the shipped checkpoints, fit SMPL-X bodies, and write motion.npz, motion.bvh, "
        "motion.glb, motion.mp4 (the bodies rendered in the room; or .gif) and viewer.html to "
        "--out.",
    )
    p.add_argument("--scene", default="demo",
                   help="scene file, ScanNet scan folder, or 'demo' (default)")
    p.add_argument("--text", default=None,
                   help='the instruction (default: "sit on the chair next to the table")')
    p.add_argument("--plan", default=None, metavar="PLAN.json",
                   help='a story instead of --text: a JSON list of steps on object ids (as '
                   '`jaxmotion scene info` lists them), e.g. [{"action": "stand_up", "object": '
                   '3}, {"action": "walk", "object": 4}, {"action": "sit", "object": 7}]; one '
                   "motion, walks on planned paths, written with its segments")
    p.add_argument("--trajectory", default=None, metavar="PATH.npy",
                   help="trajectory control: the pelvis follows this ground path, a .npy array "
                   "[T, 2] (or a .csv of x, y lines) per frame at 30 fps in the scene's frame, "
                   "metres; --text says the manner (default: walk along the path)")
    p.add_argument("--object", type=int, default=None,
                   help="target object's instance id (skips finding it from the text)")
    p.add_argument("--samples", type=int, default=None, help="motions to sample (K, default 1)")
    p.add_argument("--seed", type=int, default=None, help="PRNG seed (default 0)")
    p.add_argument("--steps", type=int, default=None,
                   help="DDIM steps of the motion stage (default 20)")
    p.add_argument("--adm-steps", type=int, default=None, metavar="N",
                   help="DDIM steps of the affordance stage (default 5)")
    p.add_argument("--guidance", type=_guidance_arg, default=None, metavar="G|ADM,AMDM",
                   help="classifier-free guidance scale of both stages, or one per stage "
                   "(default: the shipped checkpoints' tuned scales; 1 = no guidance)")
    p.add_argument("--consistency", type=_unit_arg, default=None, metavar="S",
                   help="strength in [0, 1] of affordance-consistency guidance: the motion is "
                   "steered to match the predicted affordance map (default: the tuned value; "
                   "0 = off)")
    p.add_argument("--grounding", choices=("auto", "adm", "llm"), default=None,
                   help="auto (default): a relation in the text ('the chair closest to the "
                   "door') narrows the named objects by the room's geometry; among several "
                   "left, the one with the most free floor around it is taken, and a text "
                   "naming no object walks to one drawn with the seed (needs an object table: "
                   "synthetic rooms, labelled scans; without one the ADM's map chooses); adm: "
                   "the ADM's map chooses; llm: a language model at JAXMOTION_LLM_URL (any "
                   "OpenAI-compatible server; JAXMOTION_LLM_MODEL, JAXMOTION_LLM_API_KEY) "
                   "chooses the target in two prompts, saved as grounding_llm.json")
    p.add_argument("--adm-candidates", type=int, default=None, metavar="C",
                   help="once the target object is known (--object, or found from the text), "
                   "draw C affordance maps per sample and keep the one that lights it most "
                   "(default 16, at most 32; 1 = one map, ~0.8 s faster)")
    p.add_argument("--motion-candidates", type=int, default=None, metavar="M",
                   help="once the target object is known, draw M motions per sample from its "
                   "map and keep the one whose body comes closest to the object at the anchor "
                   "frame (default 4, at most 16; 1 = one motion)")
    p.add_argument("--points", type=int, default=None, help="points to sample from a mesh")
    p.add_argument("--up", choices=("auto", "z", "y"), default="auto",
                   help="the room file's up axis (default auto: found from its floor, which "
                   "is then levelled and moved to z = 0)")
    p.add_argument("--unit", choices=("auto", "m", "cm", "mm", "ft", "in"), default="auto",
                   help="the room file's length unit (default auto: from the room's size)")
    p.add_argument("--checkpoints", nargs="+", default=None, metavar="PATH",
                   help="a folder with adm.safetensors and amdm.safetensors (and optionally "
                   "adm_text.safetensors, the ADM used when no target object is known), or the "
                   "ADM and AMDM training workdirs (default: the shipped checkpoints)")
    p.add_argument("--pipeline", choices=("auto", "affordance", "object-centric", "cvae"),
                   default="auto",
                   help="object-centric: volumetric sensors around the target -> root "
                   "trajectory -> motion completion (Cen et al. 2024; needs a target object, "
                   "found as for the affordance pipeline); affordance: ADM -> AMDM; auto "
                   "(default): object-centric when the target object is known, else "
                   "affordance; cvae: the HUMANISE cVAE baseline (Wang et al. 2022) on the "
                   "square around the target, from the weights given with --cvae")
    p.add_argument("--object-checkpoints", nargs="+", default=None, metavar="PATH",
                   help="the object-centric models: a folder with trajectory.safetensors and "
                   "completion.safetensors, or their training workdirs (default: the shipped "
                   "ones)")
    p.add_argument("--cvae", nargs="+", default=None, metavar="PATH",
                   help="--pipeline cvae's weights: configs/cvae.py training workdirs or "
                   ".safetensors files, action-specific ones (action=sit ...) and / or an "
                   "action-agnostic one; the one for the instruction's action is used. No "
                   "cVAE weights ship with jaxmotion")
    p.add_argument("--video", choices=("mp4", "gif", "none"), default=None,
                   help="the rendered video: mp4 (default, H.264), gif, or none (the default "
                   "with --batch)")
    p.add_argument("--skeleton", choices=("smplx", "mixamo", "ue5"), default="smplx",
                   help="motion.bvh's bone names and hierarchy: SMPL-X's (default, metres), "
                   "Mixamo's (mixamorig:Hips, ...; centimetres) or Unreal Engine 5's Manny / "
                   "Quinn (root, pelvis, spine_01..05, thigh_l, ...; centimetres); the same "
                   "body and motion in each")
    p.add_argument("--out", required=True, help="output folder")
    b = p.add_argument_group(
        "batch generation", "many requests in one process: a JSON object a line with \"text\" "
        "or \"plan\" and optionally \"scene\", \"object_id\", \"seed\", \"samples\", "
        "\"name\"; each request gets OUT/<name>/ with the files above and summary.json, and "
        "OUT/summary.jsonl lists them all. Finished requests are skipped when run again. The "
        "other options apply to every request")
    b.add_argument("--batch", default=None, metavar="CASES.jsonl",
                   help="the requests (instead of --scene / --text / --plan / --object / "
                   "--seed / --samples)")
    b.add_argument("--batch-size", type=int, default=None, metavar="B",
                   help="samples each device draws per call of the batched program (default: "
                   "8; with a single CPU device, each request by generate's own programs, "
                   "which is faster there)")
    b.add_argument("--coordinator", default=None, metavar="HOST:PORT",
                   help="several hosts: process 0's address; each process is started with the "
                   "same arguments and its --process-id, takes every N-th request and writes "
                   "into the shared --out (jax.distributed)")
    b.add_argument("--processes", type=int, default=None, metavar="N",
                   help="with --coordinator: how many processes")
    b.add_argument("--process-id", type=int, default=None, metavar="I",
                   help="with --coordinator: this process's rank, 0 .. N-1")
    p.set_defaults(func=_cmd_generate)

    p = sub.add_parser(
        "eval",
        help="evaluate checkpoints over a dataset split (tables with 95 %% intervals)",
        description="Sample K motions per case for each --model over R replications and score "
        "them: goal distance, contact, non-collision, APD, foot skating (SMPL-X bodies fitted "
        "to the joints, or --joints-only), affordance grounding of the ADM maps, and with "
        "--evaluator the text-motion metrics (FID, R-precision, ...). Writes results.json and "
        "results.md (mean ± 95 % interval) to --out, and cases.jsonl: each case's metrics, to "
        "find where a model fails.",
    )
    p.add_argument("--data", required=True, help="dataset folder (jaxmotion synth)")
    p.add_argument("--model", action="append", metavar="NAME=ADM,AMDM[,SAMPLER][,OPT=G]",
                   help="a row: name, ADM and AMDM workdirs (or .safetensors), sampler ddimN "
                   "(default ddim50) or ddpm, and optionally adm_guidance=G / amdm_guidance=G "
                   "(classifier-free guidance scale per stage, default 1), consistency=S "
                   "(affordance-consistency guidance strength in [0, 1], default 0) and "
                   "affordance=gt (the "
                   "AMDM on ground-truth maps: the AMDM's own error); trajectory=T,completion=C: "
                   "the object-centric pipeline samples the row; cvae=W: the HUMANISE cVAE "
                   "does (the ADM and AMDM still set the crops); repeat for more rows")
    p.add_argument("--split", default="test", choices=("train", "val", "test"))
    p.add_argument("--cases", type=int, default=None,
                   help="cases from the split (default 64; with --descriptions: all)")
    p.add_argument("--samples", type=int, default=None,
                   help="samples per case, K (default 4; with --descriptions 1)")
    p.add_argument("--replications", type=int, default=3, help="R (default 3)")
    p.add_argument("--evaluator", default=None, help="text-motion evaluator workdir (optional)")
    p.add_argument("--recognizer", default=None,
                   help="action recognizer workdir (python -m jaxmotion.train --config "
                   "configs/recognizer.py); adds the recognizer's action accuracy and FID / "
                   "diversity / multimodality on its features (optional)")
    p.add_argument("--joints-only", action="store_true",
                   help="fast joint-sphere body instead of fitted SMPL-X meshes")
    p.add_argument("--vertex-stride", type=int, default=4,
                   help="use every Nth body vertex for the signed distances (default 4; 1 = all)")
    p.add_argument("--batch-size", type=int, default=16)
    p.add_argument("--protocol", choices=("paper", "generate", "text"), default="paper",
                   help="paper (default): crop each case around the dataset's motion, as the "
                   "papers do; generate: crop where `jaxmotion generate` would, from the room "
                   "and the text alone (scores the whole job, finding the object included); "
                   "text: text to motion on a floor, on converted HumanML3D (`jaxmotion data "
                   "convert --from humanml3d`; needs --evaluator): the affordance paper's "
                   "Table 1 (R-precision, FID, MM dist., diversity, multimodality)")
    p.add_argument("--grounding", choices=("auto", "adm", "llm"), default="auto",
                   help="with --protocol generate: how the region is found, as `jaxmotion "
                   "generate --grounding` (default auto; llm only with --descriptions)")
    p.add_argument("--descriptions", nargs="?", const="", default=None, metavar="FILE",
                   help="instead of --model rows: run `jaxmotion generate` on each "
                   "instruction of a description set (JSONL: scene, target_id, action, text; "
                   "without FILE the shipped set written by hand for the rooms of "
                   "`jaxmotion synth --seed 9001`, --data being that build) and on the "
                   "synthetic generator's sentence for the same target and seed; reports "
                   "target grounding and action accuracy (geometric judge, and --recognizer) "
                   "for both phrasings, and why descriptions failed")
    p.add_argument("--no-templates", action="store_true",
                   help="with --descriptions: score the descriptions only")
    p.add_argument("--pipeline", choices=("auto", "affordance", "object-centric", "cvae"),
                   default="auto",
                   help="with --descriptions: generate's pipeline (default auto)")
    p.add_argument("--checkpoints", nargs=2, metavar=("ADM", "AMDM"), default=None,
                   help="with --descriptions: generate's ADM and AMDM (default: the shipped)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--save-motions", action="store_true",
                   help="also write the sampled joints to OUT/motions.npz (per model, in each "
                   "case's crop frame, with the crop's rotation and shift), to look at them")
    p.add_argument("--out", default="results", help="output folder (default: results)")
    p.set_defaults(func=_cmd_eval)

    p = sub.add_parser(
        "retarget", help="write a generated motion as a BVH of the Mixamo, UE5 or SMPL-X rig",
        description="Write the body of MOTION (generate's motion.npz, or motion_smplx.npz / "
        "any AMASS-style SMPL-X .npz) as a BVH whose bone names and hierarchy are those of a "
        "rig animators use: mixamo (mixamorig:Hips ..., centimetres; Blender's Mixamo "
        "conventions), ue5 (Unreal Engine 5's Manny / Quinn: root, pelvis, spine_01..05, "
        "neck_01, neck_02, head, clavicle_l, upperarm_l, ..., thigh_l, calf_l, foot_l, ball_l; "
        "centimetres) or smplx (SMPL-X's names, metres). The body's own proportions and rest "
        "pose (a T-pose) are kept: the joints read back are generate's.")
    p.add_argument("motion", help="generate's motion.npz or an AMASS-style SMPL-X .npz")
    p.add_argument("--skeleton", required=True, choices=("smplx", "mixamo", "ue5"))
    p.add_argument("--out", required=True, help="the .bvh file to write")
    p.add_argument("--sample", type=int, default=0, help="which sample of a motion.npz "
                   "(default 0)")
    p.set_defaults(func=_cmd_retarget)

    p = sub.add_parser(
        "render",
        help="render a saved motion (generate's motion.npz or a dataset sample) in its room",
        description="Draw the skinned mannequin(s) of MOTION (a motion.npz written by "
        "'jaxmotion generate', or a dataset sample .npz) in the room, shaded and lit, to an "
        ".mp4 / .gif clip or a .png still (NumPy software renderer, no GPU or display).",
    )
    p.add_argument("motion", help="motion.npz from 'jaxmotion generate', or a dataset sample .npz")
    p.add_argument("--scene", default=None,
                   help="the room: a mesh, point cloud, .npz scene, ScanNet scan folder or "
                   "'demo' (default: 'demo' for a motion made there; a dataset sample's "
                   "scenes/<scene_id>.npz)")
    p.add_argument("--out", required=True, help="output .mp4, .gif or .png")
    p.add_argument("--size", default="640x480", help="WIDTHxHEIGHT pixels (default 640x480; "
                   "even numbers for .mp4)")
    p.add_argument("--samples", choices=("overlay", "grid"), default="overlay",
                   help="several samples in one room (overlay, default) or side by side (grid)")
    p.add_argument("--camera", choices=("auto", "fixed", "follow"), default="auto",
                   help="fixed on the whole motion, following it, or auto (default: follow a "
                   "motion too long to show whole)")
    p.add_argument("--azimuth", type=float, default=None, metavar="DEG",
                   help="view direction about the vertical (default: chosen to see the front)")
    p.add_argument("--elevation", type=float, default=None, metavar="DEG",
                   help="view height above the horizontal (default 24)")
    p.add_argument("--fps", type=float, default=None,
                   help="video frame rate (default: the motion's, every frame)")
    p.add_argument("--frame", type=int, default=None, help="the frame of a .png (default: last)")
    p.add_argument("--points", type=int, default=None, help="points to sample from a mesh")
    p.set_defaults(func=_cmd_render)

    p = sub.add_parser(
        "studio",
        help="a local web app: click the object, type or compose the story, watch, download",
        description="Start one warm process serving the studio page and its JSON API (under "
        "/api/, described at /api/docs) and open the page. Results and uploads are kept in "
        "--folder and listed again when the studio starts there.",
    )
    p.add_argument("room", nargs="?", default="demo",
                   help="the room to start with: demo (default) or a scan / mesh / cloud file")
    p.add_argument("--host", default="127.0.0.1",
                   help="address to serve on (default 127.0.0.1: this machine only)")
    p.add_argument("--port", type=int, default=8000, help="port (default 8000)")
    p.add_argument("--folder", default="jaxmotion-studio",
                   help="where uploads and results are kept (default: ./jaxmotion-studio)")
    p.add_argument("--no-open", action="store_true", help="do not open a browser")
    p.add_argument("--video", choices=("mp4", "gif", "none"), default="mp4",
                   help="the video written with each result (default mp4)")
    p.add_argument("--up", choices=("auto", "z", "y"), default=None,
                   help="the room file's up axis (default: found from its floor)")
    p.add_argument("--unit", choices=("auto", "m", "cm", "mm", "ft", "in"), default=None,
                   help="the room file's length unit (default: from its size)")
    p.add_argument("--steps", type=int, default=None, help="DDIM steps (default: the models')")
    p.set_defaults(func=_cmd_studio)

    p = sub.add_parser(
        "demo",
        help="the built-in demo: a room, an instruction, a motion and its affordance map",
        description="Draw a synthetic room, an instruction and a motion performing it; compute "
        "the motion's affordance map on the room; write the room (PLY), the motion (sample "
        "schema .npz), the affordance as a coloured point cloud (PLY) and PNG previews to --out.",
    )
    p.add_argument("--out", default="out", help="output folder (default: out)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--action", choices=("walk", "sit", "stand_up", "lie"), default=None,
                   help="action to perform (default: sit)")
    p.set_defaults(func=_cmd_demo)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return 0
    try:
        return int(args.func(args) or 0)
    except BrokenPipeError:  # output piped into `head` and the like
        sys.stderr.close()
        return 0
    except (ValueError, OSError, KeyError) as err:
        # Expected user errors (bad file, bad config, a folder that cannot be written): one
        # clear line, no traceback.
        msg = err.args[0] if isinstance(err, KeyError) and err.args else err
        print(f"jaxmotion {args.command}: error: {msg}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130
    except Exception as err:  # noqa: BLE001 - a bug: still no traceback unless asked for
        import os

        if os.environ.get("JAXMOTION_DEBUG"):
            raise
        print(f"jaxmotion {args.command}: internal error: {type(err).__name__}: {err} (rerun "
              "with JAXMOTION_DEBUG=1 for the traceback, and please report it)", file=sys.stderr)
        return 1


def run(argv: Sequence[str] | None = None) -> NoReturn:
    """The ``jaxmotion`` command (and ``python -m jaxmotion``): :func:`main`, then the process
    ends without tearing the interpreter down. Tearing down XLA's runtime and the loaded
    modules took 0.2–0.4 s of a 3 s ``generate`` on a 2-core CPU; by then every file is
    written and closed. The exit handlers registered while the command ran (JAX's, the scratch
    cache's removal) still run: the process ends in a handler registered before them, which
    ``atexit`` calls last. :func:`main` itself returns, for callers in Python."""
    import atexit
    import os

    code = [0]

    def leave() -> None:
        for stream in (sys.stdout, sys.stderr):
            try:
                stream.flush()
            except (OSError, ValueError):  # a closed or broken pipe
                pass
        os._exit(code[0])

    atexit.register(leave)
    try:
        code[0] = main(argv)
    except SystemExit as done:  # argparse: --help, --version, a usage error
        if isinstance(done.code, str):
            print(done.code, file=sys.stderr)
        code[0] = 1 if isinstance(done.code, str) else int(done.code or 0)
    sys.exit(code[0])


if __name__ == "__main__":  # pragma: no cover
    run()
