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

from jaxmotion.errors import GenerateError
from jaxmotion.options import DEFAULT_TEXT, GenerateOptions
from jaxmotion.request import check_models, finish, prepare, sample
from jaxmotion.result import Generation

__all__ = ["DEFAULT_TEXT", "GenerateError", "Generation", "GenerateOptions", "generate"]


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
    models = check_models(opts)
    request = prepare(scene, check_text(text), opts, models, progress, meanwhile)
    return finish(request, *sample(request))

