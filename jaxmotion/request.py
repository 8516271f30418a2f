"""One ``generate`` request, stage by stage: the checkpoints checked (:func:`check_models`),
the request prepared up to its sampling (:func:`prepare`: room, grounding, pipeline), its
motions drawn (:func:`sample`) and the result made (:func:`finish`).

:func:`jaxmotion.generate` runs the three in a row; batch generation (:mod:`jaxmotion.batch`)
prepares many requests, samples the object-centric ones together, and finishes each.
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
from jaxmotion.options import GenerateOptions
from jaxmotion.result import Generation

__all__ = ["Models", "Request", "check_models", "finish", "prepare", "sample"]


@dataclasses.dataclass(frozen=True)
class Models:
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


def check_models(opts: GenerateOptions) -> Models:
    from jaxmotion.data.crop import crop_spec_from_config
    from jaxmotion.pipelines.checkpoints import (
        adm_text_tokens,
        adm_view,
        pipeline_files,
        resolve_checkpoints,
        text_adm_for,
        weights_config,
    )

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
    return Models(Path(adm_file), Path(amdm_file), text_adm, adm_cfg,
                   crop_spec_from_config(mcfg), int(mcfg["max_frames"]),
                   adm_view(adm_cfg) == "room", files)


@dataclasses.dataclass
class Request:
    """One request made ready to sample (:func:`prepare`): the room loaded and checked, the
    target grounded, the pipeline chosen. :func:`sample` then draws its motions and
    :func:`finish` makes the result; batch generation (:mod:`jaxmotion.batch`) samples the
    object-centric cases of many requests together between the two."""

    text: str
    opts: GenerateOptions
    models: Models
    room: object
    instruction: object
    centre: object
    chosen: int | None
    how: str
    understood: object
    pipeline: str
    view: object
    emb: object  # () -> the sentence embedding
    text_emb: object  # () -> the ADM's text condition
    root: np.ndarray  # the seed's key data
    samplers: tuple
    aot_dir: Path | None
    versions: tuple
    lap: object
    after_loads: object


def prepare(scene, text: str, opts: GenerateOptions, models: Models, progress: bool,
             meanwhile=None) -> Request:
    """Stages 1–3 of :func:`jaxmotion.generate` for one request: load, check and ground (every refusal
    raised here, before sampling)."""
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
        warnings.warn(message, UserWarning, stacklevel=4)
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
    after_loads = when_loaded(meanwhile or (lambda: None))  # the CLI's renderer: beside sampling
    pipeline = pick_pipeline(opts.pipeline, models.files, chosen)  # needs a target or not
    return Request(text, opts, models, room, instruction, centre, chosen, how, understood,
                 pipeline, view, emb, text_emb, root, (adm_sampler, amdm_sampler), aot_dir,
                 versions, lap, after_loads)


def sample(case: Request):
    """Stage 4 for one prepared request: ``(joints [K, T, 22, 3] in the scene frame, maps,
    (crop indices, rotation, shift), excluded ids, maps drawn, motions drawn, SMPL-X
    parameters or None)``."""
    c, opts, k = case, case.opts, case.opts.samples
    exact = None
    if c.pipeline == "cvae":  # the HUMANISE baseline on the square around the target
        from jaxmotion.pipelines import cvae
        joints, crop = cvae.sample_in_room(c.room, c.centre, c.text, c.instruction.action, opts,
                                           c.models.files, c.root, c.aot_dir, c.versions)
    elif c.pipeline == "object-centric":  # sensors around the target
        from jaxmotion.grounding.region import sampled_action
        from jaxmotion.pipelines.object_centric import sample_in_room

        joints, crop, exact = sample_in_room(
            c.room, c.centre, c.chosen, c.instruction.anchor_first, c.emb(), opts,
            c.models.files, c.root, c.aot_dir, c.versions,
            sampled_action(c.instruction.action, c.how, c.chosen))
    if c.pipeline != "affordance":
        return (joints, np.zeros((k, len(crop[0]), 6), np.float32), crop, (), 0,
                1 if c.pipeline == "cvae" else opts.motion_candidates, exact)
    from jaxmotion.pipelines.affordance import sample_in_room

    return (*sample_in_room(c.room, c.centre, c.chosen, c.instruction.anchor_first, c.text_emb(),
                            opts, c.models, c.view, c.root, c.samplers, c.aot_dir, c.versions),
            None)


def finish(case: Request, joints, aff, crop, excluded, n_cand, n_mot, exact) -> Generation:
    """Stage 5: the SMPL-X bodies (the object-centric pipeline's own, else fitted) and the
    :class:`~jaxmotion.result.Generation`."""
    c, opts, k = case, case.opts, case.opts.samples
    c.after_loads.result()
    c.lap("sample")
    smplx, err = {}, np.full(k, np.nan, np.float32)
    if exact is not None:  # sampled as SMPL-X parameters: the joints are theirs
        smplx, err = exact, np.zeros(k, np.float32)
    elif opts.fit:
        from jaxmotion.body.fit import fit_bodies

        smplx, err = fit_bodies(joints, opts.fit_iters, c.aot_dir, c.versions)
        c.lap("fit")
    pick, rot, shift = crop
    view_index, view_maps = c.view if c.view is not None else (None, None)
    room = c.room
    return Generation(
        text=c.text, scene=room, joints=joints, fps=SCENE_FPS,
        mask=np.ones(c.models.frames, bool), smplx=smplx, fit_error=err,
        crop_xyz=room.xyz[pick].astype(np.float32), crop_rgb=room.rgb[pick].astype(np.float32),
        affordance=aff, rotation=rot, shift=shift, object_id=opts.object_id, target_id=c.chosen,
        seed=opts.seed, steps=opts.steps, guidance=opts.guidance, consistency=opts.consistency,
        timings=c.lap.times, grounding=c.how, excluded=tuple(excluded), adm_candidates=n_cand,
        adm_steps=opts.adm_steps, motion_candidates=n_mot, understanding=c.understood,
        pipeline=c.pipeline,
        view_xyz=None if view_index is None else room.xyz[view_index].astype(np.float32),
        view_affordance=None if view_maps is None else np.asarray(view_maps, np.float32),
    )
