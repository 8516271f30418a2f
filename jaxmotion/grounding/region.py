"""Where in the room the models look: the crop square for a text, and how it was chosen.

The AMDM sees a ``crop.size`` square (4 m) of the room, as in training, where the target object
was always inside it. With a known target the square is centred on it; otherwise the
candidates are the objects the text names (:func:`jaxmotion.grounding.target.candidate_objects`).
When they are several, or none, :func:`find_region` leaves the choice to the room's free
floor (:mod:`jaxmotion.grounding.reach`, the default ``auto`` grounding) or to the ADM's map
(``grounding="adm"``, and any scene without object labels):

- a **crop-view ADM** (the shipped one; trained on the AMDM's squares) is run on a square
  centred on each candidate, and the one its map lights up most is chosen (affordance
  grounding); without candidates, the room is tiled with half-overlapping squares and the tile
  with the strongest predicted pelvis-affordance peak is used;
- a **room-view ADM** (trained with ``crop.centre=room``; experimental) is run once on its view
  of the whole room (rooms wider than its 8 m square are tiled) for every sample; the candidate
  the maps light up most is chosen, or without candidates the square is centred on the
  strongest pelvis affordance. Its maps are the AMDM's input too, so with it they choose
  whatever the grounding.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from jaxmotion.errors import GenerateError
from jaxmotion.grounding.target import ground_candidates

__all__ = ["AdmChooser", "centre_on_object", "choose_region", "clamp_centre", "find_region",
           "lit", "peak_object", "region_from_view", "room_view_maps", "sampled_action",
           "tile_centres"]


@dataclass(frozen=True)
class AdmChooser:
    """What region choice needs to run a crop-view ADM: ``get_pipe()`` returns the pipeline
    (called only when the ADM runs), ``text`` its text condition for one text (batch of one)
    or a function returning it (called only when the ADM runs),
    ``key()`` the ADM's PRNG key (called only when the ADM runs), ``sampler`` its
    :class:`~jaxmotion.diffusion.SamplerSpec`, ``seed`` the seed of the crops' point sampling;
    ``programs``: ``(folder, fingerprint)`` to keep the ADM's traced program on disk
    (:func:`jaxmotion.compiled.cached_call`; the fingerprint names the ADM and the sampler), so
    a new process skips loading and tracing it; None runs it directly. With ``split`` = i,
    ``key()`` gives a key's data (``uint32[2]``) and the ADM draws with split i of that key,
    taken inside the program (an eager split compiles three small programs in every fresh
    process, ~0.3 s). ``blank_text``: a condition of ``text``'s shapes
    (:func:`jaxmotion.text.condition.blank_condition`), with which the kept program starts
    loading before ``text`` is called."""

    get_pipe: Callable[[], Any]
    text: Any
    key: Callable[[], Any]
    sampler: Any
    seed: int
    programs: tuple | None = None
    split: int | None = None
    blank_text: Any = None


def _crops(room, centres, spec, seed: int, tag: int):
    """Crops at several centres, skipping ones with no point: a list of
    ``(index into centres, pick, points, colours)``."""
    from jaxmotion.data.crop import crop_at, model_colors

    out = []
    for i, c in enumerate(centres):
        try:
            pick, p, _, _ = crop_at(np.random.default_rng([int(seed), tag, i]), room.xyz, c, spec)
        except ValueError:  # a tile outside an L-shaped room
            continue
        out.append((i, pick, p, model_colors(room.rgb[pick])))
    return out


def _adm_maps(adm: AdmChooser, crops) -> np.ndarray:
    """The ADM's maps ``[len(crops), N, 6]`` on ``crops``. With ``adm.programs`` the batch is
    padded to a power of two (repeating the last crop; example i keeps its key, since
    ``split`` is prefix-consistent) so that a few traced programs on disk serve every room."""
    import jax

    b = len(crops)
    size = b if adm.programs is None else 1 << max(0, b - 1).bit_length()
    rows = [crops[min(i, b - 1)] for i in range(size)]
    key = adm.key()
    tile = lambda text: jax.tree.map(lambda a: np.ascontiguousarray(
        np.broadcast_to(a[0], (size, *a.shape[1:]))), text)
    args = (np.asarray(key if adm.split is not None else jax.random.key_data(key)),
            np.stack([c[2] for c in rows]), np.stack([c[3] for c in rows]))
    if adm.programs is not None and adm.blank_text is not None:  # loads while the text encodes
        from jaxmotion.compiled import prefetch, specs_of

        folder, fingerprint = adm.programs
        prefetch(folder, "adm_region", fingerprint, specs_of((*args, tile(adm.blank_text))))
    args = (*args, tile(adm.text() if callable(adm.text) else adm.text))
    sampler = adm.sampler

    def build():
        pipe = adm.get_pipe()
        split = adm.split

        def run(kd, p, c, e):
            key = jax.random.wrap_key_data(kd)
            key = key if split is None else jax.random.split(key)[split]
            return pipe.sample_affordance(key, p, c, e, sampler)

        return run

    if adm.programs is None:
        maps = build()(*args)
    else:
        from jaxmotion.compiled import cached_call

        folder, fingerprint = adm.programs
        maps = cached_call(folder, "adm_region", fingerprint, build, args)
    return np.asarray(jax.device_get(maps))[:b]


def lit(maps, instance, object_id) -> float:
    """How much ``maps [N,6]`` light up an object: the mean over its points (``instance [N]``
    == ``object_id``) of the strongest channel; −1 when none of its points is there."""
    on = instance == object_id
    return float(maps[on].max(axis=-1).mean()) if on.any() else -1.0


def find_region(room, text, grounding: str, spec, *, view=None,
                adm: AdmChooser | None = None, seed: int = 0):
    """The crop square for ``text`` when no target object is given: ``(centre [2], chosen
    object id or None, how)``; ``text``: the instruction or its
    :class:`~jaxmotion.grounding.target.Instruction`.

    The text alone may single the object out (``how``
    :attr:`~jaxmotion.grounding.target.Candidates.how`: ``scene graph``, ``class``, ``seat
    at``, ...). When it leaves several objects or names none, ``grounding`` decides:

    - ``auto`` / ``llm`` in a labelled room: the room's free floor
      (:mod:`jaxmotion.grounding.reach`): ``how`` is ``reach`` (the candidate a body reaches
      most freely) or ``wander`` (no object named: a walk to an object drawn with ``seed``);
    - ``adm``, or a scene without object labels: the ADM's map: ``view``, a room-view ADM's
      ``(view_index, maps)`` (:func:`room_view_maps`), or ``adm`` running a crop-view ADM
      (:func:`choose_region`); ``how`` is ``adm`` (among several) or ``adm peak`` (none named).

    :class:`~jaxmotion.errors.GenerateError` when the action needs an object the room does not
    have ("lie down" with no bed or sofa)."""
    from jaxmotion.grounding.objects import object_table
    from jaxmotion.grounding.target import Instruction, read_instruction

    ins = text if isinstance(text, Instruction) else read_instruction(text)
    lo, hi = room.xyz[:, :2].min(0), room.xyz[:, :2].max(0)
    if grounding == "llm":  # the language model's choice, asked once per instruction
        from jaxmotion.grounding.llm import llm_candidates

        found = llm_candidates(room, ins)
    else:
        found = ground_candidates(room, ins, grounding)
    if found.error:  # "lie down" in a room with nothing to lie on
        raise GenerateError(found.error)
    candidates, how = found.objects, found.how
    if len(candidates) == 1:
        return centre_on_object(candidates[0], lo, hi, spec.size), candidates[0]["id"], how
    objects = object_table(room)
    if view is None and grounding != "adm" and objects:  # the room's free floor chooses
        from jaxmotion.grounding.reach import most_reachable, wander_target

        if candidates:
            best = most_reachable(room, candidates, ins.action)
            if best is not None:
                o = candidates[best]
                return centre_on_object(o, lo, hi, spec.size), o["id"], "reach"
        else:
            o = wander_target(room, objects, seed)
            if o is not None:
                return centre_on_object(o, lo, hi, spec.size), int(o["id"]), "wander"
    if view is not None:
        centre, chosen = region_from_view(room, candidates, *view, spec, lo, hi)
    else:
        if adm is None:
            raise ValueError("find_region needs a room-view ADM's view or an AdmChooser")
        centre, chosen = choose_region(adm, room, candidates, spec, lo, hi)
    return centre, chosen, "adm" if candidates else "adm peak"


def choose_region(adm: AdmChooser, room, candidates, spec, lo, hi):
    """The crop centre for a text without a known target (see the module docstring):

    - with ``candidates`` (:func:`~jaxmotion.grounding.target.candidate_objects`): the ADM
      is run on a crop centred on each and the one whose points it lights up most (mean over
      its points of the strongest channel) wins;
    - otherwise the room is tiled with half-overlapping squares and the tile holding the
      strongest pelvis-affordance peak (mean of its 32 strongest points) wins; the target is
      the object of the room's table that the map lights most there (as among candidates),
      the square centred on it; None (and the tile's centre) when the tile holds no object.
    ``lo``, ``hi``: the room's xy bounds. Returns ``(centre, chosen object id or None)``.
    """
    if candidates:
        centres = [centre_on_object(o, lo, hi, spec.size) for o in candidates]
        if len(candidates) == 1:
            return centres[0], candidates[0]["id"]
        crops = _crops(room, centres, spec, adm.seed, 2)
        maps = _adm_maps(adm, crops)
        scores = [lit(a, room.instance[pick], candidates[i]["id"])
                  for (i, pick, *_), a in zip(crops, maps, strict=True)]
        i = crops[int(np.argmax(scores))][0]
        return centres[i], candidates[i]["id"]
    tiles = tile_centres(lo, hi, spec.size)
    if len(tiles) == 1:
        return tiles[0], None
    crops = _crops(room, tiles, spec, adm.seed, 3)
    maps = _adm_maps(adm, crops)
    scores = [float(np.sort(a[:, 0])[-32:].mean()) for a in maps]
    best = int(np.argmax(scores))
    (i, pick, *_), a = crops[best], maps[best]
    target = peak_object(room, room.instance[pick], a)
    if target is None:
        return np.asarray(tiles[i]), None
    return centre_on_object(target, lo, hi, spec.size), int(target["id"])


def sampled_action(action, how: str, chosen):
    """The action the motion is sampled as: the instruction's (``Instruction.action``), or,
    when it names none and no object either (``how`` ``"wander"`` or ``"adm peak"``) but a
    target was chosen for it (``chosen``), a walk to it; else None (the models read the text
    as written)."""
    if action is None and how in ("wander", "adm peak") and chosen is not None:
        return "walk"
    return action


def peak_object(room, instance, maps):
    """The object of ``room``'s table (:func:`~jaxmotion.grounding.objects.object_table`) that
    ``maps [N,6]`` light most (:func:`lit`) among those with points in the crop (``instance
    [N]``: the crop points' ids), or None when no object is there or none is lit."""
    from jaxmotion.grounding.objects import object_table

    present = set(np.unique(instance).tolist())
    scored = [(lit(maps, instance, int(o["id"])), o) for o in object_table(room)
              if int(o["id"]) in present]
    scored = [(s, o) for s, o in scored if s > 0.0]
    return max(scored, key=lambda so: so[0])[1] if scored else None


def room_view_maps(room, adm_cfg, emb, key, sampler, k: int, seed: int, aot_dir, fingerprint,
                   get_pipe):
    """A room-view ADM's maps for ``k`` samples: ``(view_index [M] into the scene's points,
    maps [K,M,6])``.

    The view is the ADM's training square (``crop.size``, no rotation) centred on the room; a
    room wider than it is tiled with half-overlapping squares (:func:`tile_centres`) and the
    tiles' points are concatenated."""
    import jax

    from jaxmotion.compiled import cached_call
    from jaxmotion.data.crop import crop_spec_from_config

    view_spec = crop_spec_from_config(adm_cfg)
    lo, hi = room.xyz[:, :2].min(0), room.xyz[:, :2].max(0)
    views = _crops(room, tile_centres(lo, hi, view_spec.size), view_spec, seed, 4)
    v = len(views)
    pts = np.stack([c[2] for c in views])
    col = np.stack([c[3] for c in views])
    # every sample sees every tile: a batch of K x V
    def rep(x):
        return np.ascontiguousarray(np.repeat(x[None], k, 0).reshape(k * v, *x.shape[1:]))

    args = (np.asarray(jax.random.key_data(key)), rep(pts), rep(col),
            jax.tree.map(lambda a: np.ascontiguousarray(np.broadcast_to(a, (k * v, *a.shape))),
                         emb))

    def build():
        pipe = get_pipe()
        return lambda kd, p, c, e: pipe.sample_affordance(jax.random.wrap_key_data(kd), p, c, e,
                                                          sampler)

    if aot_dir is None:  # sample_affordance is jitted itself: no tracing per call
        maps = build()(*args)
    else:
        maps = cached_call(aot_dir, "adm_view", fingerprint, build, args)
    maps = np.asarray(jax.device_get(maps))
    return np.concatenate([c[1] for c in views]), maps.reshape(k, v * pts.shape[1], -1)


def region_from_view(room, candidates, view_index, view_maps, spec, lo, hi):
    """The AMDM's square from a room-view ADM's maps (module docstring, step 2): the candidate
    the mean map lights up most (mean over its view points of the strongest channel), else
    the strongest pelvis affordance. Returns ``(centre, chosen object id or None)``."""
    mean = view_maps.mean(axis=0)  # [M, 6], over samples
    if len(candidates) == 1:
        return centre_on_object(candidates[0], lo, hi, spec.size), candidates[0]["id"]
    if candidates:
        inst = room.instance[view_index]
        scores = [lit(mean, inst, o["id"]) for o in candidates]
        best = candidates[int(np.argmax(scores))]
        return centre_on_object(best, lo, hi, spec.size), best["id"]
    peak = room.xyz[view_index[int(np.argmax(mean[:, 0]))]]
    return clamp_centre(peak[:2], lo, hi, spec.size), None


def tile_centres(lo, hi, size: float) -> list[np.ndarray]:
    """Square centres tiling [lo, hi] (xy) with half-square overlap."""
    axes = []
    for a in range(2):
        ext = hi[a] - lo[a]
        if ext <= size:
            axes.append([0.5 * (lo[a] + hi[a])])
        else:
            n = int(np.ceil((ext - size) / (0.5 * size))) + 1
            axes.append(list(np.linspace(lo[a] + 0.5 * size, hi[a] - 0.5 * size, n)))
    return [np.array([x, y]) for x in axes[0] for y in axes[1]]


def centre_on_object(obj, lo, hi, size: float) -> np.ndarray:
    """A square centre on the object's xy box centre, kept inside the room
    (:func:`clamp_centre`)."""
    c = 0.5 * (np.asarray(obj["bbox_min"][:2]) + np.asarray(obj["bbox_max"][:2]))
    return clamp_centre(c, lo, hi, size)


def clamp_centre(c, lo, hi, size: float) -> np.ndarray:
    """Move a square centre so the square stays inside [lo, hi] where the room allows."""
    half = 0.5 * size
    out = np.array(c, np.float64)
    for a in range(2):
        if hi[a] - lo[a] > size:
            out[a] = np.clip(out[a], lo[a] + half, hi[a] - half)
        else:
            out[a] = 0.5 * (lo[a] + hi[a])
    return out
