"""Batch generation: many requests (rooms × instructions × seeds) in one warm process, the
object-centric samples of many requests sampled together, over every local device and over
several hosts.

::

    jaxmotion generate --batch cases.jsonl --out runs/          # or, from Python:
    rows = jaxmotion.generate_batch("cases.jsonl", "runs/")

Each line of ``cases.jsonl`` is one request, a JSON object with ``text`` or ``plan`` and
optionally ``scene`` (a path or ``"demo"``, the default), ``object_id``, ``seed`` (default 0),
``samples`` (default 1) and ``name`` (its folder, default the line number ``00000``,
``00001``, ...). Each request gets the folder ``OUT/<name>/`` with the files ``generate``
writes (``motion.npz``, ``motion.bvh``, ``motion.glb``, ``viewer.html``, a video only when
asked for) and ``summary.json``: what was understood (as ``generate``'s JSON line) and the
plausibility figures of each sample. ``OUT/summary.jsonl`` holds every request's row in the
file's order (``"status": "done"`` or ``"failed"`` with the message).

How it runs:

- Every request is prepared as ``generate`` prepares it (room loaded once per file, target
  grounded, refusals said before sampling); a refused request is recorded, the others go on.
- Requests sampled by the object-centric pipeline (a target found: the usual case) are
  sampled together (unless the process has a single CPU device and no ``batch_size`` is
  given: there each is sampled by ``generate``'s own programs, which is faster on a CPU):
  their samples are rows of one compiled program, ``batch_size`` rows per
  device, the rows sharded over the local devices (a 1-D ``jax.sharding.Mesh``, ``shard_map``:
  every device runs the same program on its own rows). Each row draws with its request's seed
  exactly the keys ``generate`` draws (motions agree with ``generate``'s to float rounding,
  which the guided steps can grow to centimetres). A row's motion does not depend on the
  other rows of its call nor on its place there; one process per device gives one device's
  motions bit for bit, several devices of one process agree with them to 1e-6 m (XLA's
  partitioned program rounds the last bits differently). Stories, followed paths and the
  other pipelines run one request at a time in the same process.
- Several hosts: start one process per host with :func:`jax.distributed.initialize` (the
  command line's ``--coordinator HOST:PORT --processes N --process-id I``); process ``i``
  takes requests ``i, i + N, ...``; ``OUT`` must be a folder all of them see. Process 0 writes
  ``summary.jsonl`` once every process is done.
- Resumable: a request's folder appears whole (built beside its name and renamed), so a run
  that is stopped and started again skips every finished request.
"""

from __future__ import annotations

import dataclasses
import json
import re
import sys
import time
import warnings
from pathlib import Path

import numpy as np

from jaxmotion.errors import GenerateError

__all__ = ["CASE_FIELDS", "BatchCase", "generate_batch", "read_cases"]

#: The fields a request (one line of the cases file) may have.
CASE_FIELDS = ("name", "scene", "text", "plan", "object_id", "seed", "samples")
_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9._-]{0,127}$")
#: Rows (samples) each device samples in one call of the batched program, where rows are
#: batched (see :func:`generate_batch`'s ``batch_size``).
DEFAULT_BATCH_SIZE = 8


@dataclasses.dataclass(frozen=True)
class BatchCase:
    """One request of a batch (a line of the cases file, checked)."""

    index: int
    name: str
    scene: str = "demo"
    text: str | None = None
    plan: object = None  # a list of steps, or a JSON file's path
    object_id: int | None = None
    seed: int = 0
    samples: int = 1


def read_cases(cases) -> list[BatchCase]:
    """The requests of ``cases``: a ``.jsonl`` file's path (one JSON object a line; blank
    lines and lines starting with ``#`` skipped) or a list of dicts. Every request is checked
    here, before anything is loaded; a bad one is a :class:`GenerateError` naming its line
    and the fix. A relative scene or plan path is read from the working folder, else from the
    cases file's folder."""
    from jaxmotion.options import MAX_SAMPLES, check_positive_int

    base = None
    if isinstance(cases, (str, Path)):
        path = Path(cases)
        if not path.is_file():
            raise GenerateError(f"--batch {path}: no such file; give a .jsonl file with one "
                                'request a line, such as {"scene": "demo", "text": "sit on the '
                                'chair", "seed": 0}')
        base, rows = path.parent, []
        for number, line in enumerate(path.read_text().splitlines(), 1):
            if not line.strip() or line.lstrip().startswith("#"):
                continue
            try:
                rows.append((f"{path.name} line {number}", json.loads(line)))
            except json.JSONDecodeError as e:
                raise GenerateError(f"{path.name} line {number} is not JSON ({e.msg}); each "
                                    "line must be one JSON object") from None
    else:
        rows = [(f"case {i}", row) for i, row in enumerate(cases)]
    if not rows:
        raise GenerateError("the batch has no request; give one JSON object a line")
    out, names = [], {}
    for i, (where, row) in enumerate(rows):
        if not isinstance(row, dict):
            raise GenerateError(f"{where} must be a JSON object, got {type(row).__name__}")
        unknown = sorted(set(row) - set(CASE_FIELDS))
        if unknown:
            raise GenerateError(f"{where}: unknown field(s) {', '.join(unknown)}; a request has "
                                f"{', '.join(CASE_FIELDS)} (other options apply to the whole "
                                "batch: give them to the command)")
        text, plan = row.get("text"), row.get("plan")
        if (text is None) == (plan is None):
            raise GenerateError(f"{where}: give \"text\" (an instruction) or \"plan\" (a story's "
                                "steps, or its JSON file), one of them")
        if text is not None and (not isinstance(text, str) or not text.strip()):
            raise GenerateError(f"{where}: \"text\" must be a non-empty string")
        scene = row.get("scene", "demo")
        if not isinstance(scene, str) or not scene:
            raise GenerateError(f"{where}: \"scene\" must be a path or \"demo\"")
        if scene != "demo":
            scene = _existing(scene, base, where, "scene")
        if isinstance(plan, str):
            plan = _existing(plan, base, where, "plan")
        elif plan is not None and not isinstance(plan, list):
            raise GenerateError(f"{where}: \"plan\" must be a list of steps or a JSON file's "
                                "path")
        try:
            seed = check_positive_int("seed", row.get("seed", 0), 0, 2**31 - 1)
            samples = check_positive_int("samples", row.get("samples", 1), 1, MAX_SAMPLES)
            object_id = (None if row.get("object_id") is None
                         else check_positive_int("object_id", row["object_id"], 0))
        except GenerateError as e:
            raise GenerateError(f"{where}: {e}") from None
        name = row.get("name", f"{i:05d}")
        if not isinstance(name, str) or not _NAME.match(name):
            raise GenerateError(f"{where}: \"name\" {name!r} must be a folder name of letters, "
                                "digits, '.', '_' and '-' (128 at most)")
        if name in names:
            raise GenerateError(f"{where}: \"name\" {name!r} is also {names[name]}'s; names "
                                "must differ")
        names[name] = where
        out.append(BatchCase(i, name, scene, text, plan, object_id, seed, samples))
    return out


def _existing(value: str, base: Path | None, where: str, field: str) -> str:
    p = Path(value)
    if p.exists():
        return str(p)
    if base is not None and not p.is_absolute() and (base / p).exists():
        return str(base / p)
    raise GenerateError(f"{where}: \"{field}\" {value}: no such file or folder")


def generate_batch(cases, out, *, options=None, video: str | None = None,
                   batch_size: int | None = None, progress: bool = True,
                   skeleton: str = "smplx", **overrides) -> list[dict]:
    """Generate every request of ``cases`` into folder ``out`` (see the module's docstring).

    Args:
      cases: a ``.jsonl`` file or a list of dicts (:func:`read_cases`).
      out: the output folder (made; requests whose folder is there already are skipped).
      options: :class:`~jaxmotion.options.GenerateOptions` shared by every request (or their
        fields as keyword arguments); a request's ``seed``, ``samples`` and ``object_id``
        replace those.
      video: ``"mp4"`` / ``"gif"`` to render each request's video too (None: none).
      batch_size: rows each device samples per call of the batched program (memory grows
        with it). None: :data:`DEFAULT_BATCH_SIZE`, except in a process with a single CPU
        device, where each request is sampled by ``generate``'s own programs (the same
        motions as ``generate``, bit for bit): on a CPU a batched call costs as much per row
        as single requests or more (measured on 2 cores: 0.9 s a request in calls of 8 rows,
        0.6 s one at a time), so there the gain is the warm process alone.
      progress: a progress bar and one line per request on stderr.
      skeleton: the bone names and hierarchy of each ``motion.bvh`` (``smplx``, ``mixamo``,
        ``ue5``: :func:`jaxmotion.export.bvh.rig_bones`).
    Returns:
      This process's rows of ``summary.jsonl`` (its requests, finished before included).
    Raises:
      GenerateError: a bad request, option or output folder, before any model is loaded.
    """
    import jax

    from jaxmotion.export.folder import check_outputs
    from jaxmotion.options import GenerateOptions, check_positive_int
    from jaxmotion.request import check_models

    opts = GenerateOptions.merged(options, **overrides)
    if batch_size is not None:
        batch_size = check_positive_int("batch_size", batch_size, 1, 1024)
    todo = read_cases(cases)
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise GenerateError(f"--out {out} is a file; give a folder")
    check_outputs(video=video)
    from jaxmotion.export.bvh import check_skeleton

    try:
        check_skeleton(skeleton)
    except ValueError as e:
        raise GenerateError(str(e)) from e
    models = check_models(opts)
    rank, ranks = jax.process_index(), jax.process_count()
    mine = todo[rank::ranks]
    out.mkdir(parents=True, exist_ok=True)
    runner = _Runner(opts, models, out, video, batch_size, progress, skeleton)
    finished = [c for c in mine if (out / c.name / "summary.json").is_file()]
    left = [c for c in mine if c not in finished]
    runner.say(f"{len(todo)} request(s)" + (f", {len(mine)} for process {rank} of {ranks}"
                                             if ranks > 1 else "")
               + (f", {len(finished)} finished before (skipped)" if finished else "")
               + ("; one at a time through generate's programs (one CPU device)"
                  if runner.one_at_a_time else
                  f"; {len(runner.devices)} device(s), "
                  f"{runner.rows_per_call // len(runner.devices)} row(s) each per call"))
    runner.run(left)
    rows = [_read_row(out, c) for c in mine]
    if ranks > 1:  # every process done before the summary is gathered
        wait_for_every_process("jaxmotion-generate-batch")
    if rank == 0:
        _write_summary(out, todo)
    return rows


#: How long a process waits for the others at the end of a batch (their shares of the
#: requests can take hours longer than its own).
WAIT_HOURS = 72


def wait_for_every_process(name: str) -> None:
    """Block until every process of the ``jax.distributed`` run got here (the coordination
    service's barrier, waiting up to :data:`WAIT_HOURS`).

    Not a collective over the devices (``multihost_utils.sync_global_devices``): on CPU that
    sets up a Gloo context, which gives up when the processes arrive more than 30 s apart,
    and a process whose requests were quicker arrives minutes or hours early."""
    from jax._src import distributed  # the client jax.distributed.initialize made

    client = distributed.global_state.client
    if client is None:  # the run was not started by jax.distributed.initialize
        from jax.experimental import multihost_utils

        multihost_utils.sync_global_devices(name)
        return
    client.wait_at_barrier(name, WAIT_HOURS * 3600 * 1000)


def _read_row(out: Path, case: BatchCase) -> dict:
    """A request's row: its folder's ``summary.json``, else its failure, else "missing"."""
    for f in (out / case.name / "summary.json", out / ".failed" / f"{case.name}.json"):
        if f.is_file():
            return json.loads(f.read_text())
    return {"name": case.name, "index": case.index, "status": "missing"}


def _write_summary(out: Path, cases) -> None:
    from jaxmotion._atomic import atomic_open

    with atomic_open(out / "summary.jsonl", "w") as f:
        for case in cases:
            f.write(json.dumps(_read_row(out, case)) + "\n")


class _Runner:
    """Prepares requests one by one, samples the object-centric ones together in calls of
    ``batch_size`` rows per device, finishes and writes each request as its rows come back
    (files written on a second thread while the next rows sample)."""

    def __init__(self, opts, models, out: Path, video, batch_size: int | None, progress: bool,
                 skeleton: str = "smplx"):
        import concurrent.futures

        import jax

        self.opts, self.models, self.out, self.video = opts, models, out, video
        self.skeleton = skeleton
        self.progress = progress
        self.devices = jax.local_devices()
        self.one_at_a_time = (batch_size is None and len(self.devices) == 1
                              and self.devices[0].platform == "cpu")
        self.rows_per_call = (batch_size or DEFAULT_BATCH_SIZE) * len(self.devices)
        self.pending: list = []  # (state, row) waiting for a call
        self.rooms: dict = {}
        self.writer = concurrent.futures.ThreadPoolExecutor(1, "jaxmotion-batch-writer")
        self.writes: list = []
        self.program = None
        self.bar = None

    def say(self, message: str) -> None:
        """A line on stderr (above the progress bar while there is one): stdout is the
        command's JSON line alone."""
        if self.progress:
            if self.bar is not None:
                self.bar.write(message, file=sys.stderr)
            else:
                print(message, file=sys.stderr, flush=True)

    def run(self, cases) -> None:
        from tqdm import tqdm

        self.bar = tqdm(total=len(cases), unit="request", file=sys.stderr, dynamic_ncols=True,
                        disable=not self.progress or not cases)
        try:
            for case in cases:
                self._prepare(case)
                while len(self.pending) >= self.rows_per_call:
                    self._call(self.pending[:self.rows_per_call])
                    del self.pending[:self.rows_per_call]
            if self.pending:
                self._call(self.pending)
                self.pending = []
            for w in self.writes:
                w.result()
        finally:
            self.writer.shutdown(wait=True)
            self.bar.close()
            self.bar = None

    # ----------------------------------------------------------------- one request, prepared
    def _room(self, scene: str):
        """The prepared room of a scene file, loaded once (its notes said to every request)."""
        from jaxmotion.errors import SceneNote
        from jaxmotion.scene.demo import room_for

        if scene not in self.rooms:
            if len(self.rooms) >= 4:  # a few rooms kept: requests usually come room by room
                self.rooms.pop(next(iter(self.rooms)))
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always", UserWarning)
                room = room_for(scene, self.opts)
            self.rooms[scene] = (room, [str(w.message) for w in caught
                                        if issubclass(w.category, SceneNote)])
        return self.rooms[scene]

    def _prepare(self, case: BatchCase) -> None:
        from jaxmotion.planning.control import planned_generation
        from jaxmotion.request import finish, prepare, sample
        from jaxmotion.text.condition import check_text

        t0 = time.perf_counter()
        opts = dataclasses.replace(self.opts, seed=case.seed, samples=case.samples,
                                   object_id=case.object_id)
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", UserWarning)
            try:
                room, notes = (case.scene, []) if case.scene == "demo" else self._room(case.scene)
                if case.plan is not None or self._is_story(case.text):
                    res = planned_generation(room, case.text or f"the story of {case.name}",
                                             opts, False, plan=case.plan)
                    state = _State(case, opts, None, caught, notes, t0)
                    self._write(state, res)
                    return
                prepared = prepare(room, check_text(case.text), opts, self.models, False)
                state = _State(case, opts, prepared, caught, notes, t0)
                if prepared.pipeline != "object-centric" or self.one_at_a_time:
                    self._write(state, finish(prepared, *sample(prepared)))
                    return
            except GenerateError as e:
                self._failed(case, str(e))
                self.bar.update(1)
                return
        self._queue(state)

    @staticmethod
    def _is_story(text) -> bool:
        from jaxmotion.planning.steps import is_story

        return text is not None and is_story(text)

    def _queue(self, state) -> None:
        """The request's rows, in the pending calls."""
        from jaxmotion.grounding.region import sampled_action
        from jaxmotion.pipelines.object_centric import candidate_keys, sampler_inputs

        c = state.prepared
        args, crop = sampler_inputs(c.room, c.centre, c.chosen, c.instruction.anchor_first,
                                    c.emb(), state.opts, self.models.files, c.root,
                                    sampled_action(c.instruction.action, c.how, c.chosen))
        state.args, state.crop = args, crop
        state.keys = candidate_keys(c.root, state.opts.samples, state.opts.motion_candidates)
        state.rows = [None] * state.opts.samples
        self.pending.extend((state, r) for r in range(state.opts.samples))

    # ------------------------------------------------------------------ the batched program
    def _compiled(self):
        if self.program is None:
            from jax.sharding import Mesh

            from jaxmotion._jax_setup import enable_compilation_cache
            from jaxmotion.pipelines.object_centric import batch_sampler

            enable_compilation_cache()
            mesh = Mesh(np.array(self.devices), ("batch",))
            self.program, self.mesh = batch_sampler(self.opts, self.models.files, mesh), mesh
        return self.program

    def _call(self, rows) -> None:
        """One call of the batched program on ``rows`` (padded to the full call with copies of
        the first); each request whose rows are all back is finished."""
        import jax
        from jax.sharding import NamedSharding, PartitionSpec

        program = self._compiled()
        full = rows + [rows[0]] * (self.rows_per_call - len(rows))

        def stack(i):
            return np.stack([s.args[i][r] for s, r in full])

        per_case = lambda get: np.stack([get(s) for s, _ in full])
        inputs = (np.stack([s.keys[r] for s, r in full]), *(stack(i) for i in range(1, 10)),
                  per_case(lambda s: s.crop[1]).astype(np.float32),
                  per_case(lambda s: s.crop[2]).astype(np.float32),
                  per_case(lambda s: s.args[12]))  # the crop's obstacle distance field
        sharding = NamedSharding(self.mesh, PartitionSpec("batch"))
        res = jax.device_get(program(*jax.device_put(inputs, sharding)))
        for i, (state, r) in enumerate(rows):
            state.rows[r] = {k: v[i] for k, v in res.items()}
            if all(row is not None for row in state.rows):
                self._finish(state)

    def _finish(self, state) -> None:
        from jaxmotion.pipelines.object_centric import scene_outputs
        from jaxmotion.request import finish

        res = {k: np.stack([row[k] for row in state.rows]) for k in state.rows[0]}
        joints, smplx = scene_outputs(res, state.args[5], *state.crop[1:])
        crop = state.crop
        k = state.opts.samples
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", UserWarning)
            result = finish(state.prepared, joints, np.zeros((k, len(crop[0]), 6), np.float32),
                             crop, (), 0, state.opts.motion_candidates, smplx)
        state.caught.extend(caught)
        state.rows = None
        self._write(state, result)

    # ------------------------------------------------------------------------ the outputs
    def _write(self, state, res) -> None:
        from jaxmotion.errors import SceneNote

        notes = state.notes + [str(w.message) for w in state.caught
                               if issubclass(w.category, SceneNote)]
        warned = [str(w.message) for w in state.caught if not issubclass(w.category, SceneNote)]
        res.timings["total"] = time.perf_counter() - state.t0
        self.writes.append(self.writer.submit(self._save, state.case, res, notes, warned))

    def _save(self, case: BatchCase, res, notes, warned) -> None:
        from jaxmotion.eval.plausibility import plausibility
        from jaxmotion.export.folder import summary

        try:
            row = {"name": case.name, "index": case.index, "status": "done",
                   "scene": case.scene, "seed": case.seed,
                   **json.loads(summary(res, notes, warned))}
            figures = plausibility(res.joints, np.broadcast_to(res.mask, res.joints.shape[:2]),
                                   fps=res.fps)
            row["plausibility"] = {k: np.asarray(v).tolist() for k, v in figures.items()}
            res.save(self.out / case.name, video=self.video, skeleton=self.skeleton,
                     extra={"summary.json": json.dumps(row, indent=1) + "\n"})
            (self.out / ".failed" / f"{case.name}.json").unlink(missing_ok=True)
            self.say(f"{case.name}: {res.pipeline}, target {res.target_id}, "
                     f"{res.timings['total']:.1f} s")
        except Exception as e:  # noqa: BLE001 (recorded; the batch goes on)
            self._failed(case, f"writing the files failed: {type(e).__name__}: {e}")
            return
        finally:
            if self.bar is not None:
                self.bar.update(1)

    def _failed(self, case: BatchCase, message: str) -> None:
        from jaxmotion._atomic import atomic_open

        row = {"name": case.name, "index": case.index, "status": "failed", "scene": case.scene,
               "seed": case.seed, "text": case.text, "error": message}
        with atomic_open(self.out / ".failed" / f"{case.name}.json", "w") as f:
            f.write(json.dumps(row) + "\n")
        self.say(f"{case.name}: failed: {message}")


@dataclasses.dataclass(eq=False)
class _State:
    case: BatchCase
    opts: object
    prepared: object
    caught: list
    notes: list
    t0: float
    args: tuple = ()
    crop: tuple = ()
    keys: np.ndarray | None = None
    rows: list | None = None
