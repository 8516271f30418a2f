"""From a room and a sentence to a motion: the main job of jaxmotion, stage by stage.

:func:`generate` runs a pipeline end to end on any scene::

    import jaxmotion
    res = jaxmotion.generate("demo", "sit on the chair next to the table", samples=4, seed=0)
    res.joints        # [K, T, 22, 3] world frame (the scene's), metres, z-up
    res.smplx         # SMPL-X parameters fitted to the joints (jaxopt LBFGS)
    res.save("out")   # motion.npz, motion.bvh, motion.glb, motion.mp4, viewer.html

This module only orchestrates; each stage lives in its own module:

1. **validate** the options (:class:`jaxmotion.options.GenerateOptions`), the text and the
   checkpoints (:mod:`jaxmotion.pipelines.checkpoints`) before anything heavy is loaded;
2. **load** the scene (:func:`jaxmotion.scene.demo.room_for`: ``"demo"``, a path or a
   :class:`~jaxmotion.scene.Scene`), levelled, its objects found when it has no labels
   (:mod:`jaxmotion.scene.prepare`); an empty room or one without objects is refused;
3. **ground** (:mod:`jaxmotion.grounding`): the target object from ``object_id``, the scene
   graph, the only object of the named class, or, among several or none named, the room's
   free floor (:mod:`jaxmotion.grounding.reach`) or the ADM's map (``grounding="adm"``, a
   scene without labels); the crop square the models see is centred on it;
4. **synthesize** the K samples in one compiled, vmapped program (kept on disk by
   :mod:`jaxmotion.compiled`, loaded while stage 3 runs): ``pipeline="auto"`` (the default)
   runs the object-centric pipeline (:mod:`jaxmotion.pipelines.object_centric`: sensors, root
   trajectory, body) when the target is known, else the affordance one (ADM maps, then AMDM
   motions: :mod:`jaxmotion.pipelines.affordance`; a known target's class mates kept out);
   ``motion_candidates`` motions per sample, the plausible one reaching the target kept;
   ``pipeline="cvae"``: the HUMANISE baseline (:mod:`jaxmotion.pipelines.cvae`) on the square;
5. **fit** SMPL-X bodies to the joints; the **result** (:class:`~jaxmotion.result.Generation`)
   writes the files with ``save`` (whatever it would refuse is checked before sampling).
"""

from __future__ import annotations

import dataclasses
import functools
import warnings
from pathlib import Path

import numpy as np

from jaxmotion._version import __version__
from jaxmotion.constants import SCENE_FPS
from jaxmotion.errors import GenerateError
from jaxmotion.options import DEFAULT_TEXT, GenerateOptions
from jaxmotion.result import Generation

__all__ = ["DEFAULT_TEXT", "GenerateError", "Generation", "GenerateOptions", "generate"]


@dataclasses.dataclass(frozen=True)
class _Models:
    """The checkpoints of one call, checked to fit together (configs only, no weights)."""

    adm: Path
    amdm: Path
    text_adm: Path  # the ADM used when no target is known
    adm_config: dict
    spec: object  # the AMDM's CropSpec, no rotation
    frames: int
    room_view: bool
    files: tuple | None = None  # the object-centric (trajectory, completion) or cVAE files

    def pipeline(self, adm: Path):
        from jaxmotion.pipelines.checkpoints import load_pipeline
        return load_pipeline(str(adm), str(self.amdm))


def _check_models(opts: GenerateOptions) -> _Models:
    from jaxmotion.data.crop import crop_spec_from_config
    from jaxmotion.pipelines.checkpoints import (adm_text_tokens, adm_view, pipeline_files,
                                                 resolve_checkpoints, text_adm_for, weights_config)

    adm_file, amdm_file = resolve_checkpoints(opts.checkpoints)
    mcfg = weights_config(amdm_file)
    if mcfg.get("task") != "amdm" or "crop" not in mcfg:
        raise GenerateError(f"checkpoints {adm_file} and {amdm_file} do not load together: "
                            f"{amdm_file} is a {mcfg.get('task')!r} checkpoint, not an AMDM one")
    adm_cfg = weights_config(adm_file)
    text_adm = text_adm_for(adm_file)
    if text_adm != Path(adm_file):
        t_cfg = weights_config(text_adm)
        if adm_text_tokens(t_cfg) != adm_text_tokens(adm_cfg) or adm_view(t_cfg) != adm_view(
                adm_cfg):
            raise GenerateError(f"{text_adm} and {adm_file} must read the text the same way "
                                "(model.text_tokens) and see the same view (crop.centre); "
                                f"remove {text_adm.name} to use {Path(adm_file).name} alone")
    files = pipeline_files(opts)  # the object-centric models' or the cVAE's (None: neither)
    if opts.pipeline in ("object-centric", "cvae"):  # their crops and motions' length
        mcfg = weights_config(files[-1])
    return _Models(Path(adm_file), Path(amdm_file), text_adm, adm_cfg,
                   crop_spec_from_config(mcfg), int(mcfg["max_frames"]),
                   adm_view(adm_cfg) == "room", files)


def generate(scene, text: str = DEFAULT_TEXT, *, options: GenerateOptions | None = None,
             progress: bool = False, plan=None, trajectory=None, meanwhile=None,
             **overrides) -> Generation:
    """Generate motions of a person doing ``text`` in ``scene``.

    Args:
      scene: ``"demo"``, a path (mesh / point cloud / ``.npz``) or a ``Scene``.
      text: the instruction (one or two sentences).
      options: a :class:`~jaxmotion.options.GenerateOptions`; or its fields as keyword
        arguments (``object_id``, ``samples``, ``seed``, ``steps``, ``adm_steps``,
        ``guidance``, ``consistency``, ``grounding``, ``adm_candidates``,
        ``motion_candidates``, ``checkpoints``, ``num_points``, ``fit``, ``fit_iters``,
        ``aot``; None = the default), which also override ``options``' fields.
      progress: print the stages with their times (to stderr).
      plan, trajectory: a story (steps on object ids, or their JSON file; a text of several
        steps is one too) or a ground path to follow (``[T, 2]`` at 30 fps) (:mod:`.planning`).
      meanwhile: called (no arguments) once grounded and the samplers' programs are loaded
        (:func:`~jaxmotion.compiled.when_loaded`): the CLI loads the video's renderer there.
    Raises:
      GenerateError: bad text, scene, object id, options or checkpoints (the message names
        the fix), before any model is loaded.
    """
    opts = GenerateOptions.merged(options, **overrides)
    from jaxmotion.planning.control import planned_generation  # a story, or a path to follow
    if (told := planned_generation(scene, text, opts, progress, plan=plan, trajectory=trajectory,
                                   meanwhile=meanwhile)) is not None:
        return told
    from jaxmotion.text.condition import check_text
    models = _check_models(opts)
    return _run(scene, check_text(text), opts, models, progress, meanwhile or (lambda: None))


def _run(scene, text: str, opts: GenerateOptions, models: _Models, progress: bool, meanwhile):
    import jax

    from jaxmotion._jax_setup import enable_compilation_cache, seed_key_data
    from jaxmotion.compiled import digest, when_loaded
    from jaxmotion.diffusion.samplers import SamplerSpec
    from jaxmotion.export.folder import check_outputs
    from jaxmotion.grounding import AdmChooser, explain, find_object, find_region, read_instruction
    from jaxmotion.grounding.region import centre_on_object
    from jaxmotion.pipelines.checkpoints import adm_text_tokens, pick_pipeline
    from jaxmotion.pipelines.object_centric import prefetch_sampler
    from jaxmotion.progress import Laps
    from jaxmotion.scene.checks import check_room, scene_warnings
    from jaxmotion.scene.demo import room_for
    from jaxmotion.text.condition import blank_condition, embed_one

    lap = Laps(progress)  # each stage's time, printed with progress, told to a listener
    times = lap.times

    xla_cache = enable_compilation_cache()
    aot_dir = xla_cache / "programs" if opts.aot else None
    versions = (jax.__version__, __version__)
    root = seed_key_data(opts.seed)  # jax.random.key(seed)'s data, made on the host
    if models.files and opts.pipeline in ("auto", "object-centric"):  # loads while grounding
        prefetch_sampler(opts, models.files, root, aot_dir, versions)
    texts = xla_cache / "text-embeddings"
    room = room_for(scene, opts)
    check_room(room, opts.pipeline)  # empty, or no object found: refused with the fix
    for message in scene_warnings(room):
        warnings.warn(message, UserWarning, stacklevel=3)
    target_obj = None if opts.object_id is None else find_object(room, opts.object_id)
    instruction = read_instruction(text, similarity=texts)
    emb = functools.cache(lambda: embed_one(text, texts, 0))  # encoded when first needed
    text_emb = functools.cache(lambda: embed_one(text, texts, t)
                               if (t := adm_text_tokens(models.adm_config)) else emb())
    # the root's stage keys (region / view, sampling): split in the programs, or eagerly here
    stage_key = lambda i: jax.random.split(jax.random.wrap_key_data(root))[i]  # noqa: E731
    adm_w, amdm_w = opts.guidance
    adm_sampler = SamplerSpec(method="ddim", steps=opts.adm_steps, guidance=adm_w)
    amdm_sampler = SamplerSpec(method="ddim", steps=opts.steps, guidance=amdm_w,
                               consistency=opts.consistency)
    spec, k = models.spec, opts.samples
    lap("load")

    # ground: which object, and the square of the room the models see
    view, get_text_pipe = None, functools.partial(models.pipeline, models.text_adm)
    if models.room_view:
        from jaxmotion.grounding.region import room_view_maps

        view = room_view_maps(room, models.adm_config, jax.tree.map(lambda a: a[0], text_emb()),
                              stage_key(0), adm_sampler, k, opts.seed, aot_dir,
                              digest(versions, adm_sampler, models.text_adm), get_text_pipe)
        lap("adm")
    if target_obj is not None:
        lo, hi = room.xyz[:, :2].min(0), room.xyz[:, :2].max(0)
        centre = centre_on_object(target_obj, lo, hi, spec.size)
        chosen, how = int(opts.object_id), "object_id"
    else:
        chooser = AdmChooser(get_text_pipe, text_emb, lambda: root, adm_sampler, opts.seed, None
                             if aot_dir is None else (aot_dir, digest(versions, adm_sampler,
                                                                      models.text_adm)), split=0,
                             blank_text=blank_condition(adm_text_tokens(models.adm_config)))
        centre, chosen, how = find_region(room, instruction, opts.grounding, spec, view=view,
                                          adm=chooser, seed=opts.seed)
        if not models.room_view:
            lap("region")
    understood = explain(room, instruction, chosen, how, opts, echo=progress)  # warns, too
    check_outputs(room, [chosen], video=None)  # what saving would refuse, refused before sampling
    after_loads = when_loaded(meanwhile)  # the CLI's renderer: beside the sampling
    pipeline = pick_pipeline(opts.pipeline, models.files, chosen)  # needs a target or not
    if pipeline == "cvae":  # the HUMANISE baseline on the square around the target
        from jaxmotion.pipelines import cvae
        joints, crop = cvae.sample_in_room(room, centre, text, instruction.action, opts,
                                           models.files, root, aot_dir, versions)
    elif pipeline == "object-centric":  # sensors around the target
        from jaxmotion.grounding.region import sampled_action
        from jaxmotion.pipelines.object_centric import sample_in_room

        joints, crop, exact = sample_in_room(room, centre, chosen, instruction.anchor_first,
                                             emb(), opts, models.files, root, aot_dir, versions,
                                             sampled_action(instruction.action, how, chosen))
    if pipeline != "affordance":
        aff, excluded, n_cand, n_mot = (np.zeros((k, len(crop[0]), 6), np.float32), (), 0,
                                        1 if pipeline == "cvae" else opts.motion_candidates)
    else:
        joints, aff, crop, excluded, n_cand, n_mot = _synthesize(
            room, centre, chosen, instruction.anchor_first, text_emb(), opts, models, view, root,
            (adm_sampler, amdm_sampler), aot_dir, versions)
    after_loads.result()
    lap("sample")
    smplx, err = {}, np.full(k, np.nan, np.float32)
    if pipeline == "object-centric":  # sampled as SMPL-X parameters: the joints are theirs
        smplx, err = exact, np.zeros(k, np.float32)
    elif opts.fit:
        from jaxmotion.body.fit import fit_bodies

        smplx, err = fit_bodies(joints, opts.fit_iters, aot_dir, versions)
        lap("fit")
    pick, rot, shift = crop
    view_index, view_maps = view if view is not None else (None, None)
    return Generation(
        text=text, scene=room, joints=joints, fps=SCENE_FPS, mask=np.ones(models.frames, bool),
        smplx=smplx, fit_error=err, crop_xyz=room.xyz[pick].astype(np.float32),
        crop_rgb=room.rgb[pick].astype(np.float32), affordance=aff, rotation=rot, shift=shift,
        object_id=opts.object_id, target_id=chosen, seed=opts.seed, steps=opts.steps,
        guidance=(adm_w, amdm_w), consistency=opts.consistency, timings=times, grounding=how,
        excluded=tuple(excluded), adm_candidates=n_cand, adm_steps=opts.adm_steps,
        motion_candidates=n_mot, understanding=understood, pipeline=pipeline,
        view_xyz=None if view_index is None else room.xyz[view_index].astype(np.float32),
        view_affordance=None if view_maps is None else np.asarray(view_maps, np.float32),
    )


def _synthesize(room, centre, chosen, anchor_first: bool, emb, opts: GenerateOptions,
                models: _Models, view, root, samplers, aot_dir, versions):
    """The K motions for the square at ``centre``: ``(joints [K,T,22,3] in the scene frame,
    maps [K,N,6], (crop indices, rotation, shift), excluded ids, maps, motions drawn)``."""
    import jax

    from jaxmotion.compiled import cached_call, digest
    from jaxmotion.data.crop import generate_crop, model_colors
    from jaxmotion.grounding import object_table, same_class_others

    adm_sampler, amdm_sampler = samplers
    k, room_view = opts.samples, models.room_view
    pick, pts, shift, rot = generate_crop(room.xyz, centre, models.spec, opts.seed)
    colors = model_colors(room.rgb[pick])
    # once the target is known (given, or found by the scene graph), its class mates are left out
    excluded = (same_class_others(object_table(room), chosen)
                if opts.object_id is not None or opts.grounding != "adm" else [])
    n_cand = opts.adm_candidates if chosen is not None and not room_view else 1
    n_mot = opts.motion_candidates if chosen is not None else 1
    tile = lambda x: np.ascontiguousarray(np.broadcast_to(x, (k, *np.shape(x))))  # noqa: E731
    on_target = tile(room.instance[pick] == (chosen if chosen is not None else -2))
    args = (np.asarray(root), tile(pts), tile(colors),
            jax.tree.map(lambda a: tile(a[0]), emb), np.ones((k, models.frames), bool))
    if room_view:  # the AMDM on the view's maps, carried to the crop (in the crop frame)
        from jaxmotion.pipelines.affordance import AffordancePipeline

        view_index, view_maps = view
        view_in_crop = ((room.xyz[view_index] - shift) @ rot.T).astype(np.float32)
        args = (*args, np.asarray(AffordancePipeline.carry(tile(pts), tile(view_in_crop),
                                                           view_maps)))
    else:
        args = (*args, tile(np.isin(room.instance[pick], excluded)))
    args = (*args, on_target, np.full(k, anchor_first))
    main_adm = models.adm if chosen is not None else models.text_adm  # else: text-only maps

    def build_sampler():
        pipe = models.pipeline(main_adm)
        main = lambda kd: jax.random.split(jax.random.wrap_key_data(kd))[1]  # noqa: E731
        if room_view:
            return lambda kd, p, c, e, m, a, t, f: pipe.sample(
                main(kd), p, c, e, m, amdm=amdm_sampler, affordance=a, target=t,
                motion_candidates=n_mot, anchor_first=f)
        return lambda kd, p, c, e, m, x, t, f: pipe.sample(
            main(kd), p, c, e, m, adm=adm_sampler, amdm=amdm_sampler, exclude=x, target=t,
            candidates=n_cand, motion_candidates=n_mot, anchor_first=f)

    res = jax.device_get(cached_call(aot_dir, "sample", digest(
        versions, adm_sampler, amdm_sampler, n_cand, n_mot, main_adm, models.amdm),
        build_sampler, args))
    joints = (np.asarray(res["joints"]) @ rot + shift).astype(np.float32)
    aff = np.asarray(res.get("affordance", np.zeros((k, len(pick), 6))), np.float32)
    return joints, aff, (pick, rot, shift), (() if room_view else excluded), n_cand, n_mot
