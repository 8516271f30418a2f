"""The affordance pipeline (Wang et al., CVPR 2024): ADM (affordance map) then AMDM (motion).

:class:`AffordancePipeline` holds the trained networks, loaded frozen from their weights
files (a training workdir's ``model.safetensors``, or the shipped ones), and exposes one
jitted, vmapped function per stage. The per-example functions are written for a single crop
and lifted with ``jax.vmap``, so one compiled program samples any batch of scenes × texts ×
seeds::

    pipe = AffordancePipeline.from_files("adm.safetensors", "amdm.safetensors")
    text = pipe.embed_text(["sit on the chair", ...])   # the text condition, B texts
    out = pipe.sample(key, points [B,N,3], colors [B,N,3], text, mask [B,T])
    out["joints"]      # [B, T, 22, 3] crop frame, metres
    out["affordance"]  # [B, N, 6] in [0, 1]

The text condition is the pooled sentence embedding ``[B, D]``, or, for an ADM that reads
words (``ADMConfig.text_tokens > 0``), the mapping ``{"pooled" [B, D], "tokens" [B, L, D],
"mask" [B, L]}``: :meth:`AffordancePipeline.embed_text` builds the right one, and
:func:`take_text` indexes either.

A known target object (``target``: its points in the crop) is told to an ADM that reads one,
lets the ADM draw several maps and keep the one lighting the target most (``candidates``),
and the AMDM several motions and keep the one reaching it (``motion_candidates``).

An ADM trained on the room view (its ``crop.centre`` is ``room``: the whole room, not the
AMDM's crop around the motion) takes its own points: ``sample(..., view={"points", "colors",
"in_crop"})`` runs the ADM on the view and carries its map to the crop's points (``in_crop``:
the view's points in the crop frame) with :func:`jaxmotion.geometry.carry_field`.
Dataset cases as inputs: :mod:`jaxmotion.data.cases`.
"""

from __future__ import annotations

import functools
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
from flax import nnx

from jaxmotion.constants import TEXT_ENCODER
from jaxmotion.diffusion.samplers import SamplerSpec

__all__ = ["AffordancePipeline", "adm_map_one", "adm_maps_one", "off_floor", "sample_in_room",
           "select_motion", "take_text"]


def take_text(text, index):
    """Rows ``index`` of a text condition (an array, or the word-level mapping)."""
    return jax.tree.map(lambda a: np.asarray(a)[index], text)


def adm_map_one(net, schedule, stats, key, points, colors, text, spec: SamplerSpec,
                exclude=None, target=None):
    """One ADM map ``[N, 6]`` in [0, 1] for one crop (``points``, ``colors`` ``[N, 3]``) and one
    text condition (unbatched): ``net`` is the frozen backbone + ADM (:func:`load_adm`'s, or
    the training model), ``stats`` the affordance ``(mean, std)``; ``exclude`` ``[N]`` as in
    :meth:`AffordancePipeline.sample_affordance`; ``target`` ``[N]``, a known target object's
    points, for an ADM with the target input (None: no target known). Written for one
    example: ``jax.vmap`` it."""
    return _adm_draw(net, schedule, stats, points, colors, text, spec, exclude, target)(key)


def adm_maps_one(net, schedule, stats, keys, points, colors, text, spec: SamplerSpec,
                 exclude=None, target=None):
    """As :func:`adm_map_one`, one map per key of ``keys`` ``[C]``: ``[C, N, 6]``. The crop's
    backbone features are computed once and shared by the C draws."""
    return jax.vmap(_adm_draw(net, schedule, stats, points, colors, text, spec, exclude,
                              target))(keys)


def _adm_draw(net, schedule, stats, points, colors, text, spec: SamplerSpec, exclude=None,
              target=None):
    """``key -> map [N, 6]`` for one crop and text, with the backbone run once here."""
    from jaxmotion.models import adm_text_cond

    mean, std = stats
    # the target is not guided: it stays in both halves of classifier-free guidance
    fixed = net.condition(points[None], colors[None],
                          None if target is None else jnp.asarray(target)[None])

    def denoise(x, t, cond):  # x may be the doubled batch of guidance
        return net.adm(x, t, {**cond, **_tile(fixed, x.shape[0])}, deterministic=True)

    shape = (1, points.shape[0], 6)
    text = jax.tree.map(lambda a: jnp.asarray(a)[None], text)
    refine = None
    if exclude is not None:  # no affordance there (0, normalised) in every clean estimate
        far = -mean / std
        refine = lambda x0, t: jnp.where(exclude[None, :, None], far, x0)  # noqa: E731
    cond = adm_text_cond(text)

    def draw(key):
        x0 = spec.run(key, denoise, schedule, shape, cond,
                      lambda c: jax.tree.map(jnp.zeros_like, c), refine)
        return jnp.clip(x0[0] * std + mean, 0.0, 1.0)

    return draw


def _tensor(tensors, name, source):
    if name not in tensors:
        raise ValueError(f"{source} has no {name!r}: retrain with this jaxmotion version")
    return jnp.asarray(tensors[name])


class AffordancePipeline:
    """Frozen ADM (+ backbone) and AMDM with their schedules and normalisation statistics."""

    def __init__(self, adm_net, adm_schedule, adm_stats, amdm, amdm_schedule, amdm_stats):
        self.adm_net, self.adm_schedule = adm_net, adm_schedule
        self.a_mean, self.a_std = adm_stats
        self.amdm, self.amdm_schedule = amdm, amdm_schedule
        self.m_mean, self.m_std, self.am_mean, self.am_std = amdm_stats
        self.sigma = 0.8
        self.amdm_config: dict = {}
        self.adm_config: dict = {}

    @classmethod
    def from_workdirs(cls, adm_workdir, amdm_workdir) -> "AffordancePipeline":
        """From two training workdirs (their ``model.safetensors``), or the files themselves."""
        from jaxmotion.models.weights import weights_path

        return cls.from_files(weights_path(adm_workdir), weights_path(amdm_workdir))

    @classmethod
    def from_files(cls, adm_file, amdm_file) -> "AffordancePipeline":
        """From the exported ``model.safetensors`` of an ADM and an AMDM run. Raises
        ``ValueError`` when the two do not fit together (affordance channels, kernel width)."""
        from jaxmotion.config import config_from_dict
        from jaxmotion.diffusion import make_schedule
        from jaxmotion.models import AMDM, AMDMConfig
        from jaxmotion.models.frozen import load_adm
        from jaxmotion.models.weights import (
            abstract_module,
            apply_weights,
            load_weights,
            read_config,
        )

        adm_net, adm_sched, adm_stats = load_adm(adm_file)
        m_src = Path(amdm_file)
        mt, mcfg = load_weights(m_src)
        if mcfg.get("task") != "amdm":
            raise ValueError(f"{m_src} is a {mcfg.get('task')!r} checkpoint, not an AMDM one")
        a_dim = int(mcfg["model"].get("affordance_dim", adm_stats[0].shape[0]))
        if mcfg["model"].get("scene_input", "affordance") == "affordance" and \
                a_dim != adm_stats[0].shape[0]:
            raise ValueError(f"{m_src} expects {a_dim} affordance channels but the ADM "
                             f"{adm_file} predicts {adm_stats[0].shape[0]}: use checkpoints "
                             "trained together")
        amdm = abstract_module(lambda: AMDM(config_from_dict(AMDMConfig, mcfg["model"]),
                                            rngs=nnx.Rngs(0)))
        apply_weights(amdm, mt, prefix="amdm/", source=str(m_src))
        amdm.eval()
        amdm_stats = tuple(_tensor(mt, f"stats/{n}", m_src) for n in
                           ("motion_mean", "motion_std", "affordance_mean", "affordance_std"))
        sched = make_schedule(mcfg["diffusion"]["schedule"], mcfg["diffusion"]["steps"])
        pipe = cls(adm_net, adm_sched, adm_stats, amdm, sched, amdm_stats)
        pipe.sigma = float(mcfg["affordance"]["sigma"])
        pipe.amdm_config = mcfg  # the AMDM run's config.json (crop, max_frames, ...)
        pipe.adm_config = read_config(adm_file)
        return pipe

    @property
    def room_view(self) -> bool:
        """Whether the ADM reads the room view (``crop.centre == "room"``) rather than the
        AMDM's crop: then :meth:`sample` needs ``view``."""
        return self.adm_config.get("crop", {}).get("centre", "motion") == "room"

    @property
    def text_tokens(self) -> int:
        """Token states per text the ADM reads (0 = the pooled embedding only)."""
        return int(getattr(self.adm_net.adm.cfg, "text_tokens", 0))

    def embed_text(self, texts, encoder=None, *, token_cache=None):
        """The text condition of ``texts`` for :meth:`sample`: pooled MiniLM embeddings
        ``[B, D]``, or, when the ADM reads words, ``{"pooled", "tokens", "mask"}`` (token
        states rounded through float16 by :func:`~jaxmotion.text.pad_tokens`, so cached and
        fresh ones are equal); ``token_cache`` (a :class:`~jaxmotion.text.TokenCache`) reuses
        and fills such a cache."""
        from jaxmotion.text import load_text_encoder, pad_tokens

        texts = list(texts)
        encoder = encoder if encoder is not None else load_text_encoder(TEXT_ENCODER)
        pooled = np.asarray(encoder(texts), np.float32)
        if not self.text_tokens:
            return pooled
        states = (token_cache.states(encoder, texts) if token_cache is not None else
                  encoder.token_states(texts))
        tokens, mask = pad_tokens(states, self.text_tokens, encoder.dim)
        return {"pooled": pooled, "tokens": tokens, "mask": mask}

    # -- one example (vmapped below) ---------------------------------------------------------
    def _check_text(self, text):
        if self.text_tokens and not isinstance(text, dict):
            raise ValueError(f"this ADM reads word-level text ({self.text_tokens} tokens): pass "
                             "the text condition of AffordancePipeline.embed_text, not a pooled "
                             "embedding array")
        return text

    def affordance_one(self, key, points, colors, text, spec: SamplerSpec, exclude=None,
                       target=None):
        """One ADM map ``[N, 6]`` for one example (unbatched; :meth:`sample_affordance` is its
        jitted, vmapped form)."""
        return adm_map_one(self.adm_net, self.adm_schedule, (self.a_mean, self.a_std), key,
                           points, colors, self._check_text(text), spec, exclude, target)

    def motion_one(self, key, points, scene_feat, text, mask, spec: SamplerSpec):
        """One motion ``[T, 22, 3]`` (crop frame) for one example (unbatched;
        :meth:`sample_motion` is its jitted, vmapped form)."""
        return self._motion_draw(points, scene_feat, text, mask, spec)(key)

    def motions_one(self, keys, points, scene_feat, text, mask, spec: SamplerSpec):
        """One motion per key of ``keys`` ``[M]``: ``[M, T, 22, 3]``; the scene and text are
        encoded once and shared by the M draws."""
        return jax.vmap(self._motion_draw(points, scene_feat, text, mask, spec))(keys)

    def _motion_draw(self, points, scene_feat, text, mask, spec: SamplerSpec):
        """``key -> joints [T, 22, 3]`` for one example, with its condition encoded here."""
        from jaxmotion.models import pooled_text

        text_emb = pooled_text(text)
        cfg = self.amdm.cfg
        if cfg.scene_input == "affordance":
            scene = {"xyz": points[None], "affordance": ((scene_feat - self.am_mean) / self.am_std)[None]}
        else:
            scene = {"xyz": points[None], "rgb": scene_feat[None]}
        base = {"text": text_emb[None], "mask": mask[None], **scene}
        base = self.amdm.encode_condition(base, deterministic=True)  # point tokens once
        flags = {"drop_text": jnp.zeros((1,), bool), "drop_affordance": jnp.zeros((1,), bool)}

        def denoise(x, t, cond):
            return self.amdm(x, t, cond, deterministic=True)

        def null(c):
            return {**c, "drop_text": jnp.ones_like(c["drop_text"]),
                    "drop_affordance": jnp.ones_like(c["drop_affordance"])}

        shape = (1, mask.shape[0], cfg.motion_dim)
        refine = None
        if spec.consistency > 0:
            if cfg.scene_input != "affordance" or cfg.motion_dim != 66:
                raise ValueError("consistency guidance needs an AMDM that reads affordance maps "
                                 "and predicts the 66-d joint features; this one reads "
                                 f"{cfg.scene_input!r} and predicts {cfg.motion_dim}-d motion: "
                                 "set consistency to 0")
            from jaxmotion.diffusion.affordance_guidance import ConsistencyGuidance, make_x0_refiner

            refine = make_x0_refiner(points, scene_feat, mask, self.m_mean, self.m_std,
                                     ConsistencyGuidance(strength=float(spec.consistency)),
                                     self.sigma)
        def draw(key):
            x0 = spec.run(key, denoise, self.amdm_schedule, shape, {**base, **flags}, null,
                          refine)
            motion = x0[0] * self.m_std + self.m_mean
            return motion.reshape(mask.shape[0], 22, 3)

        return draw

    # -- batched, jitted entry points --------------------------------------------------------
    @functools.cached_property
    def _jitted(self):
        def aff(spec, keys, points, colors, text, exclude, target):  # both may be None
            return jax.vmap(lambda k, p, c, e, x, g: self.affordance_one(k, p, c, e, spec, x,
                                                                         g))(
                keys, points, colors, text, exclude, target)

        def mot(spec, keys, points, feats, text, mask):
            return jax.vmap(lambda k, p, f, e, m: self.motion_one(k, p, f, e, m, spec))(
                keys, points, feats, text, mask)

        def affs(spec, keys, points, colors, text, exclude, target):  # keys [B, C]
            return jax.vmap(lambda k, p, c, e, x, g: adm_maps_one(
                self.adm_net, self.adm_schedule, (self.a_mean, self.a_std), k, p, c,
                self._check_text(e), spec, x, g))(keys, points, colors, text, exclude, target)

        def mots(spec, keys, points, feats, text, mask):  # keys [B, M]
            return jax.vmap(lambda k, p, f, e, m: self.motions_one(k, p, f, e, m, spec))(
                keys, points, feats, text, mask)

        return tuple(jax.jit(f, static_argnums=0) for f in (aff, mot, affs, mots))

    @staticmethod
    def _candidate_keys(key, batch: int, candidates: int):
        """``[B, C]`` keys: example b's first is ``split(key, B)[b]`` (the key of a single
        draw, so candidate 0 is the draw without candidates), then ``fold_in`` of it by 1 ..
        C − 1."""
        first = jax.random.split(key, batch)
        more = jax.vmap(lambda k: jax.vmap(lambda j: jax.random.fold_in(k, j))(
            jnp.arange(1, candidates)))(first)
        return jnp.concatenate([first[:, None], more], axis=1)

    def sample_affordances(self, key, points, colors, text_emb, spec, exclude=None,
                           candidates: int = 1, target=None):
        """``candidates`` maps per example, ``[B, C, N, 6]`` (see :meth:`sample_affordance`;
        candidate 0 is its map). The backbone runs once per crop."""
        keys = self._candidate_keys(key, points.shape[0], int(candidates))
        return self._jitted[2](spec, keys, points, colors, text_emb,
                               self._exclude(exclude, points),
                               self._exclude(target, points, "target"))

    def sample_motions(self, key, points, scene_feat, text_emb, mask, spec,
                       candidates: int = 1):
        """``candidates`` motions per example, ``[B, M, T, 22, 3]`` (see :meth:`sample_motion`;
        candidate 0 is its motion). The condition is encoded once per example."""
        keys = self._candidate_keys(key, points.shape[0], int(candidates))
        return self._jitted[3](spec, keys, points, scene_feat, text_emb, mask)

    def sample_affordance(self, key, points, colors, text_emb, spec=SamplerSpec(steps=50),
                          exclude=None, target=None):
        """``[B,N,3], [B,N,3], text -> [B,N,6]`` affordance maps in [0, 1] (``text``: see
        :meth:`embed_text`).

        ``exclude``: optional ``[B,N]`` bool, points known not to be the target (e.g. the other
        objects of the target's class once the target is known). At every step the clean
        estimate is set to 0 (no affordance) on them, as in inpainting, so the sampler puts the
        map elsewhere; all False gives the same maps as None.

        ``target``: optional ``[B,N]`` bool, the points of a known target object, for an ADM
        that reads one (:attr:`reads_target`): its maps are then drawn for that object. None
        (or all False) = no target known: the map comes from the text alone."""
        keys = jax.random.split(key, points.shape[0])
        return self._jitted[0](spec, keys, points, colors, text_emb,
                               self._exclude(exclude, points),
                               self._exclude(target, points, "target"))

    @property
    def reads_target(self) -> bool:
        """Whether the ADM reads a known target object (trained with
        ``model.target_input=true``): :meth:`sample` then passes its ``target`` to it."""
        return bool(self.adm_net.adm.cfg.target_input)

    @staticmethod
    def _exclude(exclude, points, name="exclude"):
        if exclude is None:
            return None
        exclude = jnp.asarray(exclude, bool)
        if exclude.shape != points.shape[:2]:
            raise ValueError(f"{name} must be [B, N] = {tuple(points.shape[:2])}, got "
                             f"{tuple(exclude.shape)}")
        return exclude

    def sample_motion(self, key, points, scene_feat, text_emb, mask, spec=SamplerSpec(steps=50)):
        """``scene_feat``: the affordance map [B,N,6] (or rgb for the one-stage model);
        ``mask [B,T]`` valid frames. Returns joints ``[B,T,22,3]`` in the crop frame."""
        keys = jax.random.split(key, points.shape[0])
        return self._jitted[1](spec, keys, points, scene_feat, text_emb, mask)

    def sample(self, key, points, colors, text_emb, mask, *, adm=SamplerSpec(steps=50),
               amdm=SamplerSpec(steps=50), affordance=None, view=None, exclude=None,
               target=None, candidates: int = 1, motion_candidates: int = 1,
               anchor_first=None) -> dict:
        """Both stages: affordance from scene + text, then motion from affordance + text.

        ``affordance``: maps ``[B,N,6]`` in [0, 1] to use instead of sampling the ADM (e.g. the
        ground truth's); the motion then gets the same noise as with the ADM's maps.
        ``view``: for a room-view ADM (:attr:`room_view`), ``{"points" [B,M,3], "colors"
        [B,M,3], "in_crop" [B,M,3]}``: the ADM's input in its own frame, and the same points
        in the crop frame; the ADM's map on them (returned as ``view_affordance``) is carried
        to the crop's points. ``exclude``: ``[B,N]`` crop points the ADM's map must leave out
        (:meth:`sample_affordance`; not with ``view``). ``target`` ``[B,N]`` bool, the points of
        a known target object (an ADM that reads one, :attr:`reads_target`, is told it), and
        ``candidates`` C > 1: the ADM draws C maps per example and
        keeps the one that lights the target most (:meth:`best_of`). ``motion_candidates`` M > 1
        (with ``target``): the AMDM draws M motions per example from the same map and keeps the
        one that comes closest to the target at the anchor frame (:meth:`best_motion`;
        ``anchor_first [B]`` bool, default all False: the last frame)."""
        ka, km = jax.random.split(key)
        if motion_candidates > 1 and target is None:
            raise ValueError("motion_candidates > 1 keeps the motion that comes closest to a "
                             "known target: pass target=[B, N] points of it, or "
                             "motion_candidates=1")
        if candidates > 1 and (target is None or view is not None or affordance is not None):
            raise ValueError("candidates > 1 picks among the ADM's maps on the crop by how much "
                             "they light a known target: pass target=[B, N] points of it (and "
                             "no view or affordance), or candidates=1")
        if exclude is not None and view is not None:
            raise ValueError("exclude applies to an ADM on the crop; a room-view ADM's map is "
                             "carried from its view: leave exclude out")
        def motion(feats):  # [B,N,C] scene features the AMDM reads
            if motion_candidates > 1:
                return self.best_motion(km, points, feats, text_emb, mask, amdm, target,
                                        anchor_first, motion_candidates)
            return self.sample_motion(km, points, feats, text_emb, mask, amdm)

        if self.amdm.cfg.scene_input == "rgb":
            return {"joints": motion(colors)}
        out = {}
        if affordance is not None:
            aff = affordance
        elif view is not None:
            out["view_affordance"] = self.sample_affordance(ka, view["points"], view["colors"],
                                                            text_emb, adm)
            aff = self.carry(points, view["in_crop"], out["view_affordance"])
        else:
            if self.room_view:
                raise ValueError("this ADM was trained on the room view (crop.centre=room): pass "
                                 "view={'points', 'colors', 'in_crop'} (load_cases and "
                                 "case_inputs build it), or maps as affordance=")
            told = target if self.reads_target else None
            if candidates > 1:
                aff = self.best_of(ka, points, colors, text_emb, adm, exclude, target,
                                   candidates)
            else:
                aff = self.sample_affordance(ka, points, colors, text_emb, adm, exclude, told)
        return {**out, "affordance": aff, "joints": motion(aff)}

    def best_of(self, key, points, colors, text_emb, spec, exclude, target, candidates: int):
        """Of ``candidates`` ADM maps per example (:meth:`sample_affordances`; the first is
        :meth:`sample_affordance`'s), the one that lights ``target`` ``[B,N]`` most: the
        largest mean over its points of the strongest channel (the score generate's region
        choice uses). An example with no target point keeps the first. An ADM that reads a
        known target (:attr:`reads_target`) is told ``target``."""
        maps = self.sample_affordances(key, points, colors, text_emb, spec, exclude, candidates,
                                       target if self.reads_target else None)
        t = jnp.asarray(target, jnp.float32)[:, None]  # [B,1,N]
        score = (maps.max(-1) * t).sum(-1) / jnp.maximum(t.sum(-1), 1.0)  # [B,C]
        best = jnp.argmax(score, axis=1)  # ties (no target): the first
        return jnp.take_along_axis(maps, best[:, None, None, None], axis=1)[:, 0]

    def best_motion(self, key, points, feats, text_emb, mask, spec, target, anchor_first,
                    candidates: int):
        """Of ``candidates`` motions per example drawn from the same scene features ``feats``
        (the affordance maps, or the colours of a one-stage AMDM; :meth:`sample_motions`, the
        first is :meth:`sample_motion`'s), the one whose body comes closest to ``target``
        ``[B,N]`` (the points of a known target object) at the anchor frame: the first valid
        frame where ``anchor_first [B]`` (getting up from the object,
        :func:`jaxmotion.scene.instructions.anchor_is_first`; None: all False), else the
        last. Closeness is the smallest distance between a joint and a target point. A motion
        that teleports (:func:`jaxmotion.eval.plausibility.teleports`) is never kept while
        one of its example's candidates does not: proximity is never bought with a jump. An
        example with no target point keeps the first plausible candidate."""
        motions = self.sample_motions(key, points, feats, text_emb, mask, spec, candidates)
        return select_motion(motions, points, target, mask, anchor_first)

    @staticmethod
    @jax.jit
    def carry(points, view_points, view_maps):
        """Maps on the view ``[B,M,6]`` at ``view_points [B,M,3]`` → maps at ``points [B,N,3]``
        (all in one frame; inverse-distance weights over 4 nearest neighbours)."""
        from jaxmotion.geometry import carry_field

        return jax.vmap(carry_field)(points, view_points, view_maps)


#: With ``select_motion(feet=True)``, candidates this much (m) further from the target than the
#: closest one still compete on their feet.
GOAL_SLACK = 0.1
#: A joint closer than this (m) to a point of ``select_motion``'s ``avoid`` touches it.
AVOID_DISTANCE = 0.05
#: :func:`off_floor` counts a frame whose pelvis is farther than this (m, horizontally) from
#: every floor point of the crop (below :data:`FLOOR_Z`) and every point of the target.
OFF_FLOOR = 0.5
FLOOR_Z = 0.05


def off_floor(motions, points, target):
    """``[B, M, T]`` bool: the frames of ``motions [B, M, T, 22, 3]`` whose pelvis is where the
    crop ``points [B, N, 3]`` have no floor: farther than :data:`OFF_FLOOR` (horizontally) from
    every point below :data:`FLOOR_Z` and from every point of ``target [B, N]`` (a seat or a
    bed is no floor, yet a body on it is in place). A walk that starts beyond a wall of the
    room, or out past the square the models see, does; a body on the room's floor does not."""
    pts = jnp.asarray(points, jnp.float32)
    pel = jnp.asarray(motions)[:, :, :, 0, :2]  # [B, M, T, 2]
    sq = jnp.sum((pel[:, :, :, None] - pts[:, None, None, :, :2]) ** 2, axis=-1)  # [B,M,T,N]
    ground = (pts[:, :, 2] < FLOOR_Z) | jnp.asarray(target, bool)  # [B, N]
    return jnp.min(jnp.where(ground[:, None, None], sq, jnp.inf), axis=-1) > OFF_FLOOR ** 2


def select_motion(motions, points, target, mask, anchor_first=None, brisk_pelvis_speed=None,
                  avoid=None, feet: bool = False, return_index: bool = False):
    """Of the candidates ``motions [B, M, T, 22, 3]`` of each example, the one whose body
    comes closest to ``target [B, N]`` (points of the target object among ``points
    [B, N, 3]``, same frame) at the anchor frame: the first valid frame of ``mask [B, T]``
    where ``anchor_first [B]`` (getting up from the object; None: all False), else the last.
    Closeness is the smallest joint-to-target-point distance. A motion that teleports
    (:func:`jaxmotion.eval.plausibility.teleports`) is never kept while one of its example's
    candidates does not; with ``brisk_pelvis_speed`` (m/s), nor is one whose pelvis moves
    faster than that while another's does not (a walk at a run, beyond the dataset's motions).
    With ``avoid [B, N]`` (points a body must keep out of: furniture that is not the target),
    among the candidates of the best of those tiers the ones with the fewest frames where a
    joint is within :data:`AVOID_DISTANCE` of such a point, or the pelvis is off the crop's
    floor (:func:`off_floor`: beyond a wall), compete. With ``feet``, of those,
    the ones within :data:`GOAL_SLACK` of the closest compete on their feet: the one with the
    fewest frames whose feet slide, hover or sink (:func:`jaxmotion.eval.skating.foot_faults`)
    is kept — closeness is a gate, not the prize, since the anchor guidance already puts
    every candidate at its target. An example with no target point keeps its first plausible
    candidate (with ``feet``, the one with the best feet). Returns ``[B, T, 22, 3]``
    (``return_index``: the chosen candidates' indices ``[B]``); every pipeline's best-of-M
    uses it."""
    from jaxmotion.eval.plausibility import teleports

    mask = jnp.asarray(mask, bool)
    b, m = motions.shape[:2]
    jumps = teleports(motions.reshape(b * m, *motions.shape[2:]),
                      jnp.repeat(mask, m, axis=0)).reshape(b, m)
    t_last = mask.shape[1] - 1 - jnp.argmax(mask[:, ::-1], axis=1)
    first = (jnp.zeros(mask.shape[0], bool) if anchor_first is None
             else jnp.asarray(anchor_first, bool))
    anchor = jnp.where(first, jnp.argmax(mask, axis=1), t_last)
    pose = jnp.take_along_axis(motions, anchor[:, None, None, None, None], axis=2)[:, :, 0]
    d = jnp.linalg.norm(jnp.asarray(points)[:, None, :, None] - pose[:, :, None], axis=-1)
    t = jnp.asarray(target, bool)[:, None, :, None]  # [B,1,N,1]
    score = jnp.where(t, d, jnp.inf).min(axis=(2, 3))  # [B,C]
    score = jnp.where(jnp.isfinite(score), score, 0.0)  # no target point: all tie
    tier = jumps.astype(jnp.int32) * 2  # 0 plausible, 1 brisk, 2 teleports
    if brisk_pelvis_speed is not None:
        brisk = teleports(motions.reshape(b * m, *motions.shape[2:]),
                          jnp.repeat(mask, m, axis=0),
                          teleport_pelvis_speed=brisk_pelvis_speed).reshape(b, m)
        tier = jnp.maximum(tier, brisk.astype(jnp.int32))
    if avoid is not None:  # then the fewest frames touching furniture: the rank under the tier
        # squared distances joint -> point as |j|^2 + |p|^2 - 2 j.p (one matmul, no [.., 3])
        pts = jnp.asarray(points, jnp.float32)  # [B,N,3]
        j = motions.reshape(b, -1, 3)  # [B, M*T*22, 3]
        sq = (jnp.sum(j * j, -1)[:, :, None] + jnp.sum(pts * pts, -1)[:, None, :]
              - 2.0 * jnp.einsum("bjc,bnc->bjn", j, pts))
        sq = jnp.where(jnp.asarray(avoid, bool)[:, None, :], sq, jnp.inf)
        touch = ((jnp.min(sq, axis=-1).reshape(motions.shape[:4]) < AVOID_DISTANCE ** 2).any(
            axis=3) | off_floor(motions, pts, target)) & mask[:, None]
        tier = tier * 1000 + jnp.minimum(jnp.sum(touch, axis=2), 999)
    best_tier = jnp.min(tier, axis=1, keepdims=True)  # only the best tier's candidates compete
    if feet:  # near enough the target, the best-planted feet
        from jaxmotion.eval.skating import foot_faults

        faults = jax.vmap(jax.vmap(foot_faults, in_axes=(0, None)))(motions, mask)  # [B, M]
        near = score <= jnp.min(jnp.where(tier == best_tier, score, jnp.inf), axis=1,
                                keepdims=True) + GOAL_SLACK
        tier = jnp.where(near, tier, tier + 1_000_000)  # too far: out of the best tier
        best_tier = jnp.min(tier, axis=1, keepdims=True)
        score = jnp.nan_to_num(faults, nan=1.0) + 1e-3 * score  # ties: the closer
    best = jnp.argmin(jnp.where(tier == best_tier, score, jnp.inf), axis=1)  # ties: the first
    if return_index:
        return best
    return jnp.take_along_axis(motions, best[:, None, None, None, None], axis=1)[:, 0]


def _tile(tree, b):
    return jax.tree.map(lambda x: jnp.broadcast_to(x, (b, *x.shape[1:])), tree)


def sample_in_room(room, centre, chosen, anchor_first: bool, emb, opts, models, view, root,
                   samplers, aot_dir, versions):
    """``generate``'s synthesis stage with the affordance pipeline: the K motions for the
    square at ``centre`` (``models``: :class:`jaxmotion.request.Models`; ``view``: the room
    view's maps or None): ``(joints [K,T,22,3] in the scene frame, maps [K,N,6], (crop
    indices, rotation, shift), excluded ids, maps drawn, motions drawn)``."""
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
