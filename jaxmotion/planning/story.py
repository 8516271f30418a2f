"""Stories in a room: steps (stand up from chair 3, walk to table 4, sit on chair 7) joined
into one motion.

A plan is a list of steps, each an action (walk / sit / stand_up / lie) and an object id of
the scene (:func:`read_plan` checks every step before any sampling: the id exists, the object
takes the action, a free place near it can be reached from the previous one). :func:`tell`
makes the motion with the object-centric models, step after step, each starting from the last
:data:`PREFIX` frames of the one before (inpainted into both stages, so the joins do not jump):

- **sit / lie / stand up** on object X: one window of the models (4 s at 30 fps) sampled in
  the crop around X, anchor guidance putting the pelvis on X's seat or mattress
  (:mod:`jaxmotion.diffusion.anchor_guidance`; its horizontal offset grows from the joined
  frames to the anchor, so it never moves them; join guidance makes the model's path continue
  from them). A sit or lie more than :data:`NEAR` from the person first walks to
  :data:`~jaxmotion.planning.paths.SIT_REACH` of it (in front of it when the object has a
  ``front``), where the models' own walk-in-and-sit takes over: close, so that the model's
  path (which sees obstacles only through 0.5 m voxels) has little room to cross furniture.
- **walk** to a point ``(x, y)`` of the floor (a step ``{"action": "walk", "point": [x, y]}``,
  ``object`` −1): the same, ending at the free place nearest the point; a story that starts
  with one starts standing at a free place :data:`POINT_START` from it, drawn with the seed.
- **walk** to X: a path on the scene's points (:mod:`jaxmotion.planning.paths`) from where the
  person stands to the nearest free place within reach of X, timed by a human speed profile
  and turned to face X at the end (:mod:`jaxmotion.planning.trajectory`); the completion model
  writes the body along it (trajectory control: the pelvis follows the path exactly), in
  overlapping windows, each crop centred on its stretch of the path.

Everything is in the scene's frame (z-up, metres, 30 fps); the same seed gives the same story.
"""

from __future__ import annotations

import dataclasses
import functools
import itertools
import json
import sys
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

from jaxmotion.constants import PASSABLE
from jaxmotion.errors import GenerateError
from jaxmotion.scene.furniture import LIE_CATEGORIES, SEAT_CATEGORIES

__all__ = ["PASSABLE", "PREFIX", "Step", "Story", "Teller", "choose", "describe", "head_for",
           "plan_paths", "read_plan", "reachable_mates", "stood_up", "story_arrays",
           "story_generation", "story_result", "tell"]

#: Frames of the previous motion each step or window starts from (held by inpainting).
PREFIX = 10
#: Frames over which consecutive windows of a walk crossfade the body, after the prefix.
BLEND = 20
#: The same for a sit / lie window after a walk.
SIT_BLEND = 0
#: Motions drawn per sit / lie window, one kept by :func:`choose` (plausible, clear of other
#: furniture, nearest its object); a stand-up draws one (the brisk ones best of M avoids
#: are the ones that get up in time).
CANDIDATES = 4
#: A sit or lie farther than this (m, pelvis to the nearest point of the object) walks first,
#: to a place :data:`~jaxmotion.planning.paths.SIT_REACH` from it.
NEAR = 1.2
#: How far (m, straight line) from its point a story that starts by walking to a point starts.
POINT_START = (1.5, 3.5)
#: How far (m) from a walk's point the free place it ends at may be.
POINT_REACH = 0.5
ACTIONS = ("walk", "sit", "stand_up", "lie")
_STAND_UP = 2  # its index in jaxmotion.models.object_centric.ACTION_CLASSES
_TAKES = {"sit": SEAT_CATEGORIES, "stand_up": SEAT_CATEGORIES, "lie": LIE_CATEGORIES}
_TEXT = {"walk": "walk to the {}", "sit": "sit on the {}", "stand_up": "stand up from the {}",
         "lie": "lie down on the {}"}


@dataclasses.dataclass(frozen=True)
class Step:
    """One step of a plan: ``action`` (walk / sit / stand_up / lie) on object ``object``;
    or a walk to ``point`` (x, y on the floor, scene frame), with ``object`` −1."""

    action: str
    object: int
    point: tuple[float, float] | None = None


@dataclasses.dataclass
class Story:
    """A story's motion in the scene frame.

    Attributes:
      motion: ``[T, 135]`` features (pelvis, 6D orientation, 21 body rotations).
      joints: ``[T, 22, 3]`` metres. fps: frames per second.
      segments: per step done (a sit far away adds its walk): ``{"action", "object",
        "first", "last"}`` (frame indices, inclusive).
      paths: the planned ground paths ``[M, 2]`` of the walks, in order.
    """

    motion: np.ndarray
    joints: np.ndarray
    fps: float
    segments: list
    paths: list


def read_plan(plan, scene) -> tuple[Step, ...]:
    """The steps of ``plan`` (a list of ``{"action", "object"}`` or ``{"action": "walk",
    "point": [x, y]}`` dicts or :class:`Step`, or a JSON file holding that list), checked
    against ``scene``'s objects and bounds; :class:`GenerateError`
    naming the bad step and the fix. A step after a sit or lie that is not the stand-up from
    it gets that stand-up inserted before it (the returned steps include it)."""
    from jaxmotion.grounding.objects import object_table
    from jaxmotion.grounding.phrasing import takes

    if isinstance(plan, (str, Path)):
        try:
            plan = json.loads(Path(plan).read_text())
        except (OSError, ValueError) as e:
            raise GenerateError(f"cannot read the plan {plan}: {e}") from e
    if not isinstance(plan, (list, tuple)) or not plan:
        raise GenerateError('a plan is a non-empty list of steps such as {"action": "sit", '
                            '"object": 3}')
    objects = {int(o["id"]): o for o in object_table(scene)}
    steps = []
    for i, raw in enumerate(plan, 1):
        step = raw if isinstance(raw, Step) else None
        if step is None:
            if not isinstance(raw, dict) or set(raw) not in ({"action", "object"},
                                                             {"action", "point"}):
                raise GenerateError(f'step {i}: {raw!r} is not {{"action": ..., "object": id}} '
                                    'or {"action": "walk", "point": [x, y]}')
            step = (Step(str(raw["action"]), raw["object"]) if "object" in raw else
                    Step(str(raw["action"]), -1, raw["point"]))
        if step.action not in ACTIONS:
            raise GenerateError(f"step {i}: unknown action {step.action!r}; valid: "
                                f"{', '.join(ACTIONS)}")
        if step.point is not None:
            steps.append(Step(step.action, -1, _check_point(i, step, scene)))
            continue
        if not objects:
            raise GenerateError("the scene has no objects (no per-point instance labels): a plan "
                                "names objects by id, or walks to points of the floor")
        try:
            oid = int(step.object)
        except (TypeError, ValueError):
            raise GenerateError(f"step {i}: object {step.object!r} is not an id") from None
        if oid not in objects:
            valid = ", ".join(f"{k} ({o['category']})" for k, o in sorted(objects.items()))
            raise GenerateError(f"step {i}: the scene has no object {oid}; its objects: {valid}")
        cat = objects[oid]["category"]
        if step.action in _TAKES and not takes(step.action, objects[oid]):
            raise GenerateError(f"step {i}: cannot {step.action.replace('_', ' ')} "
                                f"{'on' if step.action != 'stand_up' else 'from'} a {cat} "
                                f"(object {oid}); that takes {', '.join(_TAKES[step.action])}")
        steps.append(Step(step.action, oid))
    out = [steps[0]]
    for i, (a, b) in enumerate(itertools.pairwise(steps), 2):
        seated = a.action in ("sit", "lie")
        if b.action == "stand_up" and not (seated and a.object == b.object):
            raise GenerateError(f"step {i}: stand up from object {b.object} follows a sit or "
                                f"lie on it (the previous step is {a.action} on {a.object})")
        if seated and b.action != "stand_up":  # up first: "sit on 3, walk to 4"
            out.append(Step("stand_up", a.object))
        out.append(b)
    return tuple(out)


def _check_point(i: int, step: Step, scene) -> tuple[float, float]:
    """A walk step's point as ``(x, y)`` floats, checked: a walk, two finite numbers, inside
    the room's points' box (:class:`GenerateError` naming the fix)."""
    if step.action != "walk":
        raise GenerateError(f"step {i}: a point of the floor can only be walked to; "
                            f"{step.action.replace('_', ' ')} takes an object id")
    try:
        xy = np.asarray(step.point, np.float64).reshape(-1)
    except (TypeError, ValueError):
        xy = np.zeros(0)
    if xy.shape != (2,) or not np.all(np.isfinite(xy)):
        raise GenerateError(f"step {i}: point {step.point!r} is not [x, y] (two numbers, metres, "
                            "scene frame)")
    lo, hi = scene.xyz[:, :2].min(0), scene.xyz[:, :2].max(0)
    if np.any(xy < lo) or np.any(xy > hi):
        raise GenerateError(f"step {i}: point ({xy[0]:.2f}, {xy[1]:.2f}) is outside the room "
                            f"(x {lo[0]:.2f}..{hi[0]:.2f}, y {lo[1]:.2f}..{hi[1]:.2f}); give it in "
                            "the scene's frame, metres")
    return float(xy[0]), float(xy[1])


def head_for(scene, end) -> int:
    """The object a path ends at (its points nearest the last point, walls and floors aside):
    the completion model's target sensor reads it, as in the walks it learned; -1: none."""
    from jaxmotion.constants import STRUCTURE

    best, oid = np.inf, -1
    for o in scene.objects:
        if o["category"] in PASSABLE or o["category"] in STRUCTURE:
            continue
        pts = scene.xyz[scene.instance == o["id"], :2]
        if len(pts):
            d = float(np.min(np.linalg.norm(pts - end, axis=1)))
            if d < best:
                best, oid = d, int(o["id"])
    return oid


def _rot6(m):
    from jaxmotion.geometry.rotations import matrix_to_rotation_6d

    return np.asarray(matrix_to_rotation_6d(jnp.asarray(m, jnp.float32)))


def _mat(six):
    from jaxmotion.geometry.rotations import rotation_6d_to_matrix

    return np.asarray(rotation_6d_to_matrix(jnp.asarray(six, jnp.float32)))


def _to_crop(f, rot, shift):
    """Features ``[T, D]`` (D ≥ 9) from the scene frame into a crop frame
    (``x_crop = rot @ (x − shift)``)."""
    out = np.array(f, np.float32)
    out[:, :3] = (f[:, :3] - shift) @ rot.T
    out[:, 3:9] = _rot6(rot[None] @ _mat(f[:, 3:9]))
    return out


def _to_scene(f, rot, shift):
    out = np.array(f, np.float32)
    out[:, :3] = f[:, :3] @ rot + shift
    out[:, 3:9] = _rot6(rot.T[None] @ _mat(f[:, 3:9]))
    return out


def choose(joints, points, target, others, anchor_first):
    """The index of the candidate to keep of ``joints [M, T, 22, 3]`` (crop frame):
    ``generate``'s best of M (:func:`~jaxmotion.pipelines.affordance.select_motion`: never a
    teleporting one while another is smooth, nor one faster than 2 m/s while another is not),
    then the fewest frames with a joint within 5 cm of the ``others`` points (furniture that
    is not the target), then, of those within ``GOAL_SLACK`` of the body closest to the
    ``target`` points at the anchor frame (the first with ``anchor_first``, else the last),
    the one whose feet slide, hover or sink in the fewest frames (the floor at z = 0)."""
    from jaxmotion.pipelines.affordance import select_motion
    from jaxmotion.pipelines.object_centric import BRISK_PELVIS_SPEED

    return select_motion(joints[None], points[None], target[None],
                         jnp.ones((1, joints.shape[1]), bool), jnp.asarray(anchor_first)[None],
                         brisk_pelvis_speed=BRISK_PELVIS_SPEED, avoid=others[None],
                         feet=True, return_index=True)[0]


def _point_goal(grid, point, start):
    """Where a walk from ``start`` (xy) to ``point`` (xy) ends: the point itself when it is
    free floor that a walk from ``start`` reaches, else the nearest such place (within
    :data:`POINT_REACH`)."""
    from jaxmotion.motion.planner import PlanningError
    from jaxmotion.planning.paths import approach_point

    for reach in (0.05, 0.2, POINT_REACH):
        try:
            return approach_point(grid, np.asarray(point, float)[None], start, reach=(0.0, reach))
        except PlanningError:
            if reach == POINT_REACH:
                raise


def point_start(grid, goal, seed: int) -> np.ndarray:
    """Where a story that starts by walking to ``goal`` (xy) starts: a free place (clearance
    :data:`~jaxmotion.planning.paths.WALK_RADIUS`) from which ``goal`` can be walked to,
    :data:`POINT_START` from it in a straight line (the farthest such place nearer than that
    when none is), drawn with ``seed``."""
    from scipy.sparse.csgraph import dijkstra

    from jaxmotion.motion.planner import PlanningError
    from jaxmotion.planning.paths import WALK_RADIUS, free_graph, start_cell

    free = grid.clearance >= WALK_RADIUS
    if not free.any():
        raise PlanningError("the room has no free floor to walk on")
    graph, cell_of = free_graph(free)
    g = start_cell(free, graph, cell_of, grid.index(np.asarray(goal, float)[None])[0])
    reach = np.isfinite(dijkstra(graph, indices=cell_of[g]))
    cells = np.argwhere(free)[reach]
    xy = grid.centers(cells)
    d = np.linalg.norm(xy - np.asarray(goal, float), axis=1)
    ok = np.flatnonzero((d >= POINT_START[0]) & (d <= POINT_START[1]))
    if not len(ok):
        ok = np.flatnonzero(d <= POINT_START[1])
        ok = ok[d[ok] >= d[ok].max() - 0.05]
    return xy[np.random.default_rng([int(seed), 11]).choice(ok)]


def _goal(grid, scene, obj, start, action):
    """Where a walk from ``start`` (xy) for ``action`` on ``obj`` ends: within reach of it
    (:data:`~jaxmotion.planning.paths.SIT_REACH` before a sit or lie), in front of it when it
    has a ``front``. A walk to an object hemmed in by furniture ends at the nearest free place
    farther out (:data:`~jaxmotion.planning.paths.WALK_WIDER`)."""
    from jaxmotion.motion.planner import PlanningError
    from jaxmotion.planning.paths import SIT_REACH, WALK_REACH, WALK_WIDER, approach_point

    pts = scene.xyz[scene.instance == obj["id"], :2]
    if action in ("sit", "lie"):
        return approach_point(grid, pts, start, reach=SIT_REACH, front=obj.get("front"))
    for far in (WALK_REACH[1], *WALK_WIDER):
        try:
            return approach_point(grid, pts, start, reach=(WALK_REACH[0], far),
                                  front=obj.get("front"))
        except PlanningError:
            if far == WALK_WIDER[-1]:
                raise


def reachable_mates(grid, scene, obj, start, action, objects) -> list[str]:
    """The other objects of ``obj``'s category that a walk from ``start`` (xy) can reach for
    ``action`` (``["chair 5", ...]``): what a story can name instead of an object that cannot
    be approached."""
    from jaxmotion.motion.planner import PlanningError

    out = []
    for o in objects:
        if o["id"] == obj["id"] or o["category"] != obj["category"]:
            continue
        try:
            _goal(grid, scene, o, start, action)
        except PlanningError:
            continue
        out.append(f"{o['category']} {o['id']}")
    return out


def stood_up(pelvis_z, seated: float, stand: float, hold: int = 15) -> int:
    """Frames of a stand-up to keep: until ``hold`` frames after the pelvis has risen 90 % of
    the way from ``seated`` to the height it stands at: ``stand`` (the neutral body's standing
    height) or, when the motion stands a little lower (knees soft), the top of its own rise.
    All the frames when it never rises half of the way to ``stand`` (it did not get up)."""
    z = np.asarray(pelvis_z, float)
    top = min(float(stand), float(z.max()))
    if top - seated < 0.5 * (stand - seated):
        return len(z)
    risen = np.flatnonzero(z >= seated + 0.9 * (top - seated))
    return min(len(z), int(risen[0]) + hold)


def _heading(six) -> float:
    """Facing (radians from +x) of one 6D orientation: the body's forward (z) axis."""
    fwd = _mat(np.asarray(six)[None])[0][:, 2]
    return float(np.arctan2(fwd[1], fwd[0]))


@functools.lru_cache(maxsize=4)
def _programs(files: tuple[str, str], sampler):
    """The object-centric pipeline of ``files`` and the jitted programs a :class:`Teller`
    runs (best-of-m window samplers, the completion along a path), kept for the process:
    a warm process (the studio) tells its next story without tracing them again."""
    from jaxmotion.data.crop import crop_spec_from_config
    from jaxmotion.models.weights import read_config
    from jaxmotion.pipelines.object_centric import load_object_pipeline

    pipe = load_object_pipeline(*files)
    cfg = read_config(files[1])
    spec, t = crop_spec_from_config(cfg), int(cfg["max_frames"])
    betas = jnp.zeros(10, jnp.float32)

    def sampler_of(m):  # best of m motions
        def sample(k, p, n, tgt, others, e, a, pre, pf, field):
            def one(key):
                out = pipe.sample_one(key, p, n, tgt, e, betas, jnp.ones(t, bool),
                                      trajectory_spec=sampler, completion_spec=sampler,
                                      action=a, prefix=pre, prefix_frames=pf, field=field)
                return out["motion"], out["joints"]

            motions, joints = jax.vmap(one)(jax.random.split(k, m))
            return motions[choose(joints, p, tgt, others, a == _STAND_UP)]

        return jax.jit(sample)

    def complete(k, p, n, tgt, e, a, traj, mask, pre, pf, field):
        return pipe.complete_one(k, p, n, tgt, e, betas, traj, mask, spec=sampler,
                                 action=a, prefix=pre, prefix_frames=pf, field=field)["motion"]

    return pipe, spec, t, {1: sampler_of(1), CANDIDATES: sampler_of(CANDIDATES)}, \
        jax.jit(complete)


#: Stories' lengths vary; their features are turned into joints and SMPL-X parameters by
#: programs compiled for lengths rounded up to a power of two of at least this (frames), the
#: extra frames copies of the last (every conversion is per frame), so a warm process compiles
#: a handful of programs instead of one per story length (eagerly, op by op, that was 6 s of a
#: 9 s walk).
LENGTH_BUCKET = 128


@functools.lru_cache(maxsize=1)
def _conversions():
    from jaxmotion.motion.representation import motion_to_joints, motion_to_smplx

    return jax.jit(motion_to_joints), jax.jit(motion_to_smplx)


def story_arrays(motion, betas=None) -> tuple[np.ndarray, dict]:
    """``(joints [T, 22, 3], SMPL-X parameters {global_orient [T, 3], body_pose [T, 21, 3],
    transl [T, 3]})`` of story features ``motion [T, 135]`` (scene frame) for a body of shape
    ``betas`` (None: the neutral body)."""
    motion = np.asarray(motion, np.float32)
    t = len(motion)
    n = max(LENGTH_BUCKET, 1 << (t - 1).bit_length())
    padded = jnp.asarray(np.concatenate([motion, np.repeat(motion[-1:], n - t, axis=0)]))
    to_joints, to_smplx = _conversions()
    betas = jnp.zeros(10, jnp.float32) if betas is None else jnp.asarray(betas, jnp.float32)
    joints = np.asarray(to_joints(padded, betas))[:t]
    return joints, {k: np.asarray(v, np.float32)[:t] for k, v in to_smplx(padded, betas).items()}


class Teller:
    """The state of one story being told (models, compiled steps, the motion so far): the
    steps of :func:`tell` and the trajectory control of :mod:`jaxmotion.planning.control`."""

    def __init__(self, scene, files, seed, steps_spec):
        from jaxmotion.diffusion.anchor_guidance import standing_height

        self.scene, self.seed = scene, int(seed)
        self.stand = float(standing_height(None))  # the neutral body's standing pelvis height
        self.pipe, self.spec, self.frames, self._sample, self._complete = _programs(
            tuple(str(f) for f in files), steps_spec)
        self.key = jax.random.key(self.seed)
        self.windows = 0
        self.motion = None  # [T, 135] scene frame
        self.segments, self.paths = [], []
        self._emb = {}

    def text(self, action, obj) -> np.ndarray:
        """The pooled sentence embedding of the step's text ("sit on the chair")."""
        return self.embed(_TEXT[action].format(obj["category"]))

    def embed(self, sentence: str) -> np.ndarray:
        """The pooled sentence embedding the models read, ``[text_dim]`` (cached)."""
        from jaxmotion._jax_setup import enable_compilation_cache
        from jaxmotion.text.condition import embed_one, pooled_text

        if sentence not in self._emb:
            emb = embed_one(sentence, enable_compilation_cache() / "text-embeddings")
            self._emb[sentence] = np.asarray(pooled_text(emb), np.float32)[0]
        return self._emb[sentence]

    def crop(self, centre, oid, action, others=False):
        """The crop around ``centre``: points, normals, the object ``oid``'s mask, the crop
        frame (``rot``, ``shift``), with ``others`` the mask of the points a body must keep
        out of (above 0.1 m, the object's own aside: :func:`furniture_mask`), and the room's
        obstacles' distance field for a body doing ``action`` there (:func:`obstacle_field`)."""
        from jaxmotion.data.crop import crop_at

        rng = np.random.default_rng([self.seed, 7, self.windows])
        pick, pts, shift, rot = crop_at(rng, self.scene.xyz, np.asarray(centre, float),
                                        self.spec)
        normals = (np.asarray(self.scene.normal[pick], np.float32) @ rot.T).astype(np.float32)
        inst = self.scene.instance[pick]
        from jaxmotion.pipelines.object_centric import furniture_mask, obstacle_field

        out = (pts.astype(np.float32), normals, inst == oid, rot.astype(np.float32),
               shift.astype(np.float32))
        if others:
            out = (*out, furniture_mask(pts, inst == oid))
        return (*out, obstacle_field(self.scene, oid, action, shift, rot))

    def next_key(self):
        self.windows += 1
        return jax.random.fold_in(self.key, self.windows)

    def prefix(self, rot, shift, blend):
        """The previous motion's frames a window starts from, in the crop frame, and their
        mask: PREFIX frames ending ``blend`` frames before its end (the window's next
        ``blend`` frames then crossfade with those last ones, :meth:`join`)."""
        pre = np.zeros((self.frames, 135), np.float32)
        given = np.zeros(self.frames, bool)
        if self.motion is not None:
            end = len(self.motion) - blend
            pre[:PREFIX] = _to_crop(self.motion[end - PREFIX:end], rot, shift)
            given[:PREFIX] = True
        return pre, given

    def join(self, new, action, oid, blend):
        """Append a window ``new`` (scene frame) that starts from :meth:`prefix` with the
        same ``blend``: its frames after the prefix crossfade with the previous motion's last
        ``blend`` frames, which become the new step's first."""
        if self.motion is None:
            first, self.motion = 0, new
        else:
            first = len(self.motion) - blend
            if blend:
                w = ((np.arange(blend) + 1) / (blend + 1))[:, None]
                self.motion[first:] = (1 - w) * self.motion[first:] + w * new[PREFIX:PREFIX
                                                                              + blend]
                self.segments[-1]["last"] = first - 1
            self.motion = np.concatenate([self.motion, new[PREFIX + blend:]])
        self.segments.append({"action": action, "object": oid, "first": first,
                              "last": len(self.motion) - 1})

    def on_object(self, action, obj):
        """sit / stand_up / lie (or a first walk, from where the model starts it): one window
        in the crop around the object."""
        from jaxmotion.grounding.region import centre_on_object
        from jaxmotion.pipelines.object_centric import action_index

        lo, hi = self.scene.xyz[:, :2].min(0), self.scene.xyz[:, :2].max(0)
        pts, nrm, tgt, rot, shift, others, field = self.crop(
            centre_on_object(obj, lo, hi, self.spec.size), obj["id"], action, others=True)
        if not tgt.any():
            raise GenerateError(f"object {obj['id']} has no point in the crop around it")
        # a stand-up starts from the seated end as it is; after a walk the body crossfades
        blend = 0 if action == "stand_up" else SIT_BLEND
        pre, given = self.prefix(rot, shift, blend)
        draw = self._sample[1 if action == "stand_up" else CANDIDATES]
        out = np.asarray(draw(self.next_key(), pts, nrm, tgt, others, self.text(action, obj),
                              action_index(action), pre, given, field))
        new = _to_scene(out, rot, shift)
        if action == "stand_up":  # up, then the next step walks: cut the model's walk-off
            new = new[:stood_up(new[:, 2], float(new[0, 2]), self.stand)]
        self.join(new, action, obj["id"], blend)

    def walk_to(self, obj, grid, action="walk"):
        """A planned path to the object (:func:`_goal` of ``action``, the step it walks for),
        the body written along it window by window."""
        from jaxmotion.planning.paths import scene_path

        here = self.motion[-1]
        path = scene_path(grid, here[:2], _goal(grid, self.scene, obj, here[:2], action))
        centre = 0.5 * (np.asarray(obj["bbox_min"][:2]) + np.asarray(obj["bbox_max"][:2]))
        self._walk(path, centre, obj["id"], self.text("walk", obj))

    def walk_to_point(self, point, grid):
        """A planned path to the free place nearest ``point`` (xy), the body written along
        it; the first step of a story starts standing at :func:`point_start`, facing the
        way. The walk's target sensor reads the object nearest the point."""
        from jaxmotion.planning.paths import scene_path
        from jaxmotion.planning.trajectory import path_trajectory

        point = np.asarray(point, float)
        start = (point_start(grid, point, self.seed) if self.motion is None
                 else self.motion[-1, :2])
        path = scene_path(grid, start, _point_goal(grid, point, start))
        oid = head_for(self.scene, path[-1])
        cats = {int(o["id"]): o["category"] for o in self.scene.objects}
        emb = self.embed(_TEXT["walk"].format(cats[oid]) if oid >= 0 else "walk forward")
        face = path[-1] - path[-2] if len(path) > 1 else np.array([1.0, 0.0])
        if self.motion is not None:
            self._walk(path, path[-1] + face, -1, emb, oid)
        else:
            heading = float(np.arctan2(face[1], face[0]))
            d0 = path[min(len(path) - 1, 10)] - path[0]
            traj = path_trajectory(path, start_heading=float(np.arctan2(d0[1], d0[0])),
                                   end_heading=heading, height=self.stand)
            self.motion = self.along(traj, 0, oid, emb)
            self.paths.append(path)
            self.segments.append({"action": "walk", "object": -1, "first": 0,
                                  "last": len(self.motion) - 1})
        self.segments[-1]["point"] = [float(point[0]), float(point[1])]  # the point asked for

    def _walk(self, path, centre, oid, emb, sensor=None):
        """The walk along ``path`` from where the motion ends, turning to face ``centre``
        (xy) at its end; its segment names ``oid`` (−1: a point); ``sensor``: the object
        the target sensor reads (None: ``oid``)."""
        from jaxmotion.planning.trajectory import path_trajectory

        here = self.motion[-1]
        if np.linalg.norm(path[0] - here[:2]) > 1e-3:  # off the seat first
            path = np.concatenate([here[None, :2], path])
        face = float(np.arctan2(*(np.asarray(centre) - path[-1])[::-1]))
        traj = path_trajectory(path, start_heading=_heading(here[3:9]), end_heading=face,
                               height=float(here[2]))
        # the pelvis height eases from where it is to the standing height of the walk
        ease = np.clip(np.arange(len(traj)) / 15.0, 0.0, 1.0)
        traj[:, 2] = here[2] + (self.stand - here[2]) * ease * ease * (3 - 2 * ease)
        lead = PREFIX + BLEND  # the previous motion's frames the walk starts over
        full = np.concatenate([self.motion[-lead:, :9], traj[1:]])  # scene frame
        seg = self.along(full, lead, oid if sensor is None else sensor, emb)
        self.paths.append(path)
        first = len(self.motion) - BLEND  # seg[PREFIX:lead]: the last motion's end, crossfaded
        self.segments[-1]["last"] = first - 1
        self.motion = np.concatenate([self.motion[:-BLEND], seg[PREFIX:]])
        self.segments.append({"action": "walk", "object": int(oid), "first": first,
                              "last": len(self.motion) - 1})

    def along(self, full, lead, oid, emb):
        """The body written along the root trajectory ``full [n, 9]`` (scene frame) by the
        completion model (a walk: the pelvis follows ``full`` exactly), in overlapping
        windows, each crop centred on its stretch of the path. Its first ``lead`` frames are
        the motion so far's last ones (kept; 0: a motion from nothing). ``oid``: the object
        the walk heads for (its target sensor; -1: none); ``emb``: the text embedding.
        Returns ``[n, 135]`` features, scene frame."""
        from jaxmotion.pipelines.object_centric import action_index

        act = action_index("walk")
        n, t = len(full), self.frames
        seg = np.zeros((n, 135), np.float32)
        if lead:
            seg[:lead] = self.motion[-lead:]
        s, done = 0, lead  # window start; frames of seg written so far
        while True:
            stop = min(s + t, n)
            win = np.concatenate([full[s:stop], np.repeat(full[stop - 1:stop], t - (stop - s),
                                                          axis=0)])
            pts, nrm, tgt, rot, shift, field = self.crop(win[: stop - s, :2].mean(0), oid,
                                                         "walk")
            pre = np.zeros((t, 135), np.float32)
            given = np.zeros(t, bool)
            if done > s:  # the frames already written that this window starts from
                pre[:PREFIX] = _to_crop(seg[s:s + PREFIX], rot, shift)
                given[:PREFIX] = True
            mask = np.arange(t) < stop - s
            out = np.asarray(self._complete(self.next_key(), pts, nrm, tgt, emb, act,
                                            _to_crop(win, rot, shift), mask, pre, given,
                                            field))
            new = _to_scene(out, rot, shift)[: stop - s]
            both = done - s  # frames the last window wrote too: the body crossfades over them
            if both > PREFIX:
                w = ((np.arange(both) - PREFIX + 1) / (both - PREFIX + 1)).clip(0, 1)[:, None]
                new[:both] = (1 - w) * seg[s:done] + w * new[:both]
            seg[s:stop] = new
            done = stop
            if stop == n:
                return seg
            s = stop - PREFIX - BLEND


def _places(scene, plan, objects, grid, seed):
    """Where each step's walk starts and ends, ``[(start, goal) or None]`` (None: no walk:
    a stand-up, or a story's first step on an object, which the models walk on their own),
    checked: every place exists and can be reached from the one before
    (:class:`GenerateError` naming the step, and the reachable objects of its class)."""
    from jaxmotion.motion.planner import PlanningError

    where, out = None, []
    for i, step in enumerate(plan, 1):
        if step.action == "stand_up":
            out.append(None)
            continue
        if step.point is not None:
            try:
                start = where if where is not None else point_start(grid, step.point, seed)
                where = _point_goal(grid, step.point, start)
            except PlanningError as e:
                raise GenerateError(f"step {i} (walk to the point ({step.point[0]:.2f}, "
                                    f"{step.point[1]:.2f})): {e}; choose a point of free floor"
                                    ) from e
            out.append((start, where))
            continue
        obj = objects[step.object]
        first = where is None
        start = where if where is not None else scene.xyz[scene.instance == obj["id"],
                                                          :2].mean(0)
        try:
            where = _goal(grid, scene, obj, start, step.action)
        except PlanningError as e:
            others = reachable_mates(grid, scene, obj, start, step.action, objects.values())
            hint = (f"; of its class these can be reached: {', '.join(others)}" if others else
                    f"; no other {obj['category']} of this room can be reached either")
            raise GenerateError(f"step {i} ({step.action} on object {step.object}): {e}"
                                f"{hint}") from e
        near = (step.action in ("sit", "lie") and not first and np.min(np.linalg.norm(
            scene.xyz[scene.instance == step.object, :2] - start, axis=1)) <= NEAR)
        out.append(None if first or near else (start, where))
    return out


def plan_paths(scene, plan, *, seed: int = 0):
    """The steps of ``plan`` as :func:`tell` takes them (:func:`read_plan`: stand-ups
    inserted) and the ground paths ``[M, 2]`` its planned walks follow, in order; nothing is
    sampled (the studio shows them while a story is composed). :class:`GenerateError` for a
    plan that cannot be told."""
    from jaxmotion.grounding.objects import object_table
    from jaxmotion.motion.planner import PlanningError
    from jaxmotion.planning.paths import point_grid, scene_path

    steps = read_plan(plan, scene)
    objects = {int(o["id"]): o for o in object_table(scene)}
    grid = point_grid(scene.xyz, scene.instance)
    paths = []
    for i, ends in enumerate(_places(scene, steps, objects, grid, seed), 1):
        if ends is not None:
            try:
                paths.append(scene_path(grid, *ends))
            except PlanningError as e:
                raise GenerateError(f"step {i}: {e}") from e
    return steps, paths


def tell(scene, plan, *, seed: int = 0, files=None, steps: int = 20,
         guidance: float = 1.0, progress: bool = False) -> Story:
    """The story of ``plan`` (see :func:`read_plan`) in ``scene`` (a
    :class:`~jaxmotion.scene.Scene` or what ``generate`` takes), as one motion.

    Args:
      seed: every random choice (the same seed gives the same story).
      files: ``(trajectory, completion)`` weights, or a folder holding both (default: the
        shipped ones).
      steps, guidance: the DDIM steps and text guidance of both stages.
    """
    from jaxmotion.constants import SCENE_FPS
    from jaxmotion.diffusion.samplers import SamplerSpec
    from jaxmotion.grounding.objects import object_table
    from jaxmotion.motion.planner import PlanningError
    from jaxmotion.pipelines.checkpoints import resolve_object_checkpoints
    from jaxmotion.planning.paths import point_grid
    from jaxmotion.progress import report
    from jaxmotion.scene.demo import load_scene_arg

    scene = load_scene_arg(scene)
    plan = read_plan(plan, scene)
    objects = {int(o["id"]): o for o in object_table(scene)}
    grid = point_grid(scene.xyz, scene.instance)
    # every place a walk goes must exist and be reachable from the one before: checked first
    _places(scene, plan, objects, grid, seed)
    files = resolve_object_checkpoints(files)
    teller = Teller(scene, files, seed, SamplerSpec("ddim", steps, guidance=guidance))
    for i, step in enumerate(plan, 1):
        obj = objects.get(step.object)
        said = (f"walk to ({step.point[0]:.2f}, {step.point[1]:.2f})" if step.point is not None
                else f"{step.action.replace('_', ' ')} {obj['category']} {step.object}")
        report(f"step {i}/{len(plan)}: {said}", (i - 1) / len(plan))
        if progress:
            print(f"  step {i}/{len(plan)}: {said}", file=sys.stderr, flush=True)
        try:
            if step.point is not None:
                teller.walk_to_point(step.point, grid)
                continue
            if step.action == "walk":
                if teller.motion is None:  # a story that starts walking: one walk clip to it
                    teller.on_object("walk", obj)
                else:
                    teller.walk_to(obj, grid)
                continue
            if step.action in ("sit", "lie") and teller.motion is not None:
                pts = scene.xyz[scene.instance == step.object, :2]
                if np.min(np.linalg.norm(pts - teller.motion[-1, :2], axis=1)) > NEAR:
                    teller.walk_to(obj, grid, step.action)
            teller.on_object(step.action, obj)
        except PlanningError as e:
            raise GenerateError(f"step {i} ({step.action} on object {step.object}): {e}") from e
    joints, _ = story_arrays(teller.motion)
    return Story(teller.motion, joints, SCENE_FPS, teller.segments, teller.paths)


def describe(plan, scene) -> str:
    """A story's steps said as text: "stand up from the chair 4, walk to the fridge 9, ..."."""
    from jaxmotion.grounding.objects import object_table

    cats = {int(o["id"]): o["category"] for o in object_table(scene)}
    return ", ".join(f"walk to ({s.point[0]:.2f}, {s.point[1]:.2f})" if s.point is not None
                     else _TEXT[s.action].format(f"{cats[s.object]} {s.object}") for s in plan)


def story_generation(scene, plan, opts, progress: bool = False, text: str | None = None):
    """``jaxmotion.generate(scene, plan=...)``: the story as a
    :class:`~jaxmotion.result.Generation` (:func:`story_result`; its text ``text``, or the
    steps said in words). ``opts`` gives ``seed``, ``steps``, the motion stage's ``guidance``
    and ``object_checkpoints``."""
    import time

    from jaxmotion.export.folder import check_outputs
    from jaxmotion.scene.demo import room_for

    t0 = time.perf_counter()
    room = room_for(scene, opts)
    steps = read_plan(plan, room)
    check_outputs(room, [s.object for s in steps], video=None)  # as saving will, before sampling
    story = tell(room, steps, seed=opts.seed, files=opts.object_checkpoints, steps=opts.steps,
                 guidance=opts.guidance[1], progress=progress)
    return story_result(story, room, text or describe(steps, room), opts,
                        {"story": time.perf_counter() - t0}, pipeline="story",
                        grounding="plan" if text is None else "text",
                        target_id=steps[-1].object if steps[-1].object >= 0 else None)


def story_result(story: Story, room, text: str, opts, timings: dict, *, pipeline: str,
                 grounding: str, target_id, object_id=None):
    """A :class:`Story` as a :class:`~jaxmotion.result.Generation`: one sample, its
    ``segments`` and ``paths`` set, with the SMPL-X parameters of the motion itself (the
    object-centric models write joint rotations: no fit is needed, the fit error is 0)."""
    from jaxmotion.constants import SCENE_FPS
    from jaxmotion.result import Generation

    smplx = {k: v[None] for k, v in story_arrays(story.motion)[1].items()}
    smplx["betas"] = np.zeros((1, 10), np.float32)
    n = len(story.joints)
    return Generation(
        text=text, scene=room, joints=story.joints[None].astype(np.float32), fps=SCENE_FPS,
        mask=np.ones(n, bool), smplx=smplx, fit_error=np.zeros(1, np.float32),
        crop_xyz=np.zeros((0, 3), np.float32), crop_rgb=np.zeros((0, 3), np.float32),
        affordance=np.zeros((1, 0, 6), np.float32), rotation=np.eye(3, dtype=np.float32),
        shift=np.zeros(3, np.float32), object_id=object_id, target_id=target_id,
        seed=opts.seed, steps=opts.steps, timings=timings,
        guidance=(0.0, float(opts.guidance[1])), grounding=grounding, pipeline=pipeline,
        motion_candidates=1, segments=tuple(story.segments), paths=tuple(story.paths))
