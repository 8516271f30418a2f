"""The studio's warm process without the web: rooms, a queue of jobs, one worker, results on disk.

A :class:`Studio` keeps one room loaded (the demo, a file, or an upload), takes requests
(:meth:`Studio.submit`: a text, a clicked object, a clicked floor point, a plan of steps) and
runs them one at a time on its worker thread, so two requests never share a model or a
result folder. Each job's state, stage and progress are kept in memory and in
``<folder>/jobs/<id>/job.json`` (written atomically), its files beside it: the motion first
(the job is *done* as soon as it is sampled), then ``viewer.html``, then the other files
:meth:`jaxmotion.result.Generation.save` writes, on a second thread so that the next job
samples meanwhile. Rooms uploaded are kept under ``<folder>/rooms/`` by their content's
digest. A studio started again on the same folder lists its earlier results; a job cut off by
the stop is marked failed ("interrupted") and its half-built files are removed.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import queue
import re
import shutil
import threading
import time
import warnings
from pathlib import Path

import numpy as np

from jaxmotion._atomic import atomic_open
from jaxmotion.errors import GenerateError

__all__ = ["MAX_SAMPLES", "MAX_UPLOAD", "UPLOAD_EXTENSIONS", "Job", "Room", "Studio",
           "StudioError"]

#: Largest room file accepted by :meth:`Studio.upload` (bytes).
MAX_UPLOAD = 256 * 2**20
#: The room files an upload may be (a glTF's separate buffers cannot come with it: use GLB).
UPLOAD_EXTENSIONS = (".ply", ".obj", ".glb", ".off", ".stl", ".npz")
#: Most samples one studio request may ask for.
MAX_SAMPLES = 8
_JOB_ID = re.compile(r"^[0-9]{8}-[0-9]{6}-[0-9a-f]{6}$")
_FILE = re.compile(r"^[A-Za-z0-9_][A-Za-z0-9_.-]{0,63}$")


class StudioError(Exception):
    """A request the studio refuses; ``status`` is the HTTP status that says why."""

    def __init__(self, message: str, status: int = 400):
        super().__init__(message)
        self.status = status


@dataclasses.dataclass
class Room:
    """A room the studio can use: ``key`` (``demo`` or the file's digest), the name shown,
    the file (None for the demo), the prepared scene and the notes preparing it gave."""

    key: str
    name: str
    path: Path | None
    scene: object
    notes: tuple[str, ...] = ()

    def objects(self) -> list[dict]:
        """The object table as the API gives it: id, category, centre, size (and confidence,
        affordances where segmentation found the object)."""
        out = []
        for o in self.scene.objects:
            lo, hi = np.asarray(o["bbox_min"], float), np.asarray(o["bbox_max"], float)
            row = {"id": int(o["id"]), "category": str(o["category"]),
                   "center": np.round((lo + hi) / 2, 3).tolist(),
                   "size": np.round(hi - lo, 3).tolist()}
            for key in ("confidence", "affords", "surface_height"):
                if o.get(key) is not None:
                    v = o[key]
                    row[key] = (round(float(v), 3) if isinstance(v, (float, np.floating))
                                else list(v) if isinstance(v, (list, tuple)) else v)
            out.append(row)
        return out

    def describe(self) -> dict:
        xyz = self.scene.xyz
        return {"key": self.key, "name": self.name, "points": int(len(xyz)),
                "bounds_min": np.round(xyz.min(0), 3).tolist(),
                "bounds_max": np.round(xyz.max(0), 3).tolist(),
                "notes": list(self.notes), "objects": self.objects()}


@dataclasses.dataclass
class Job:
    """One request and what became of it (see :meth:`Studio.submit`)."""

    id: str
    request: dict
    room: str
    state: str = "queued"  # queued | running | done | failed
    stage: str = "queued"
    progress: float = 0.0
    created: float = dataclasses.field(default_factory=time.time)
    finished: float | None = None
    summary: dict | None = None  # what generate understood and did (the CLI's JSON summary)
    error: str | None = None
    files: list = dataclasses.field(default_factory=list)
    files_state: str = "none"  # none | writing | ready | failed
    timings: dict = dataclasses.field(default_factory=dict)
    joints: np.ndarray | None = dataclasses.field(default=None, repr=False)
    version: int = 0  # bumped on every change: event streams wait on it

    def public(self, joints: bool = False) -> dict:
        """The job as the API gives it (``result`` once done; its joints with ``joints``)."""
        out = {"id": self.id, "state": self.state, "stage": self.stage,
               "progress": round(self.progress, 3), "request": self.request, "room": self.room,
               "created": self.created, "finished": self.finished, "error": self.error,
               "files": list(self.files), "files_state": self.files_state,
               "timings_s": self.timings, "result": None}
        if self.state == "done" and self.summary is not None:
            res = dict(self.summary)
            res["files"] = list(self.files)
            if joints and self.joints is not None:
                res["joints"] = np.round(self.joints, 4).tolist()
            out["result"] = res
        return out

    def record(self) -> dict:
        return {k: v for k, v in self.public().items() if k != "result"} | {
            "summary": self.summary}


class Studio:
    """Rooms, the job queue and its worker (see the module docstring).

    Args:
      folder: where uploads, results and their records are kept (created).
      room: the first room: ``"demo"`` or a file path.
      options: :class:`jaxmotion.options.GenerateOptions` fields every job uses (``up``,
        ``unit``, ``steps``, checkpoints ...); a request's own ``seed`` and ``samples`` win.
      video: the video kind written with the results (``"mp4"``, ``"gif"`` or None).
      warm: run a warm-up job when started (the programs compiled before the first click).
    """

    def __init__(self, folder, room="demo", *, options: dict | None = None,
                 video: str | None = "mp4", warm: bool = True):
        self.folder = Path(folder).expanduser().resolve()
        (self.folder / "jobs").mkdir(parents=True, exist_ok=True)
        (self.folder / "rooms").mkdir(parents=True, exist_ok=True)
        self.options = dict(options or {})
        self.video = video
        self._lock = threading.RLock()
        self._changed = threading.Condition(self._lock)
        self.rooms: dict[str, Room] = {}
        self.jobs: dict[str, Job] = {}
        self._queue: queue.PriorityQueue = queue.PriorityQueue()
        self._writes: queue.Queue = queue.Queue()
        self._count = 0
        self.warm = False
        self._load_records()
        self.room = self.open_room(room)
        self._stop = threading.Event()
        self._threads = [threading.Thread(target=self._work, name="studio-worker", daemon=True),
                         threading.Thread(target=self._write, name="studio-files", daemon=True)]
        for t in self._threads:
            t.start()
        if warm:
            self._queue.put((1, self._next(), None))  # after any request already queued
        else:
            self.warm = True

    # ---- rooms
    def open_room(self, room) -> Room:
        """Load ``room`` (``"demo"``, a file path, or the key of a room already opened) and
        make it the current one; :class:`StudioError` when it cannot be read."""
        from jaxmotion.errors import SceneNote
        from jaxmotion.scene.demo import load_scene_arg

        key = str(room)
        with self._lock:
            if key in self.rooms:
                self.room = self.rooms[key]
                return self.room
        if key == "demo":
            path, name = None, "demo"
        else:
            path = Path(room).expanduser().resolve()
            if not path.exists():
                raise StudioError(f"{room}: no such room file or folder", 404)
            name = path.name
            key = _digest(path) if path.is_file() else "dir-" + hashlib.sha256(
                str(path).encode()).hexdigest()[:16]
        opts = {k: self.options[k] for k in ("up", "unit", "num_points") if k in self.options}
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            try:
                scene = load_scene_arg("demo" if path is None else str(path), **opts)
            except GenerateError as e:
                raise StudioError(str(e)) from e
            except Exception as e:  # a file the readers choke on: said, never a dead server
                raise StudioError(f"{name}: cannot read it as a room ({type(e).__name__}: {e})"
                                  ) from e
        notes = tuple(str(w.message) for w in caught if issubclass(w.category, SceneNote))
        opened = Room(key, name, path, scene, notes)
        with self._lock:
            self.rooms[key] = opened
            self.room = opened
        return opened

    def upload(self, filename: str, data: bytes) -> Room:
        """Keep an uploaded room file (checked: extension, size) under ``rooms/`` by its
        digest and open it. The client's file name is only shown, never used as a path."""
        suffix = Path(str(filename or "")).suffix.lower()
        if suffix not in UPLOAD_EXTENSIONS:
            raise StudioError(f"{filename!r} is not a room file the studio takes; upload one of "
                              f"{', '.join(UPLOAD_EXTENSIONS)} (a .gltf with separate buffers: "
                              "export it as .glb)", 415)
        if len(data) > MAX_UPLOAD:
            raise StudioError(f"the file is {len(data) / 2**20:.0f} MiB; the studio takes rooms "
                              f"up to {MAX_UPLOAD // 2**20} MiB (subsample the cloud or "
                              "decimate the mesh)", 413)
        if not data:
            raise StudioError("the uploaded file is empty")
        key = hashlib.sha256(data).hexdigest()[:16]
        with self._lock:
            if key in self.rooms:
                self.room = self.rooms[key]
                return self.room
        folder = self.folder / "rooms" / key
        path = folder / ("room" + suffix)
        if not path.exists():
            with atomic_open(path, "wb") as f:
                f.write(data)
        (folder / "name.txt").write_text(_shown(Path(str(filename)).name))
        room = self.open_room(path)
        room.name = _shown(Path(str(filename)).name)
        return room

    def rooms_on_disk(self) -> list[dict]:
        """The rooms this studio has opened or keeps uploads of (``key``, ``name``)."""
        out = {k: r.name for k, r in self.rooms.items()}
        for d in sorted((self.folder / "rooms").iterdir()):
            files = [f for f in d.glob("room.*") if f.suffix in UPLOAD_EXTENSIONS]
            if d.is_dir() and files and d.name not in out:
                name = d / "name.txt"
                out[d.name] = name.read_text()[:200] if name.exists() else files[0].name
        return [{"key": k, "name": v, "current": k == self.room.key} for k, v in out.items()]

    def select_room(self, key: str) -> Room:
        """Make a room this studio knows (:meth:`rooms_on_disk`) the current one."""
        with self._lock:
            if key in self.rooms:
                self.room = self.rooms[key]
                return self.room
        if not re.fullmatch(r"[0-9a-f]{16}", str(key)):
            raise StudioError(f"no room {key!r} in this studio (GET /api/rooms lists them)", 404)
        files = sorted(f for f in (self.folder / "rooms" / key).glob("room.*")
                       if f.suffix in UPLOAD_EXTENSIONS)
        if not files:
            raise StudioError(f"no room {key!r} in this studio (GET /api/rooms lists them)", 404)
        room = self.open_room(files[0])
        name = files[0].parent / "name.txt"
        if name.exists():
            room.name = name.read_text()[:200]
        return room

    def room_page(self, room: Room | None = None) -> Path:
        """The viewer page of a room alone (clickable when embedded), written once."""
        from jaxmotion.export import write_viewer_html
        from jaxmotion.geometry.skeleton import NUM_JOINTS

        room = room or self.room
        path = self.folder / "rooms" / room.key / "room.html"
        if not path.exists():
            s = room.scene
            write_viewer_html(path, scene_xyz=s.xyz, scene_rgb=s.rgb,
                              joints=np.zeros((0, 1, NUM_JOINTS, 3), np.float32), fps=30.0,
                              text=room.name, scene_normal=s.normal,
                              scene_instance=s.instance, objects=s.objects)
        return path

    # ---- requests
    def check(self, request: dict, room: Room | None = None) -> dict:
        """A request made ready to run, or :class:`StudioError` naming what is wrong (cheap:
        nothing is sampled). Keys: ``text``, ``object_id``, ``point`` ([x, y] or [x, y, z]),
        ``plan`` (steps ``{"action", "object"}`` or ``{"action": "walk", "point": [x, y]}``),
        ``seed``, ``samples``."""
        from jaxmotion.grounding import read_instruction
        from jaxmotion.grounding.phrasing import takes
        from jaxmotion.planning.story import read_plan
        from jaxmotion.text.condition import check_text

        room = room or self.room
        allowed = {"text", "object_id", "point", "plan", "seed", "samples"}
        if unknown := sorted(set(request) - allowed):
            raise StudioError(f"unknown field(s) {', '.join(unknown)}; a request takes "
                              f"{', '.join(sorted(allowed))}", 422)
        text = request.get("text") or ""
        if not isinstance(text, str):
            raise StudioError("text must be a string", 422)
        if len(text) > 500:
            raise StudioError(f"the text is {len(text)} characters; say it in at most 500", 422)
        seed, samples = request.get("seed", 0), request.get("samples", 1)
        for name, v, hi in (("seed", seed, 2**31 - 1), ("samples", samples, MAX_SAMPLES)):
            if isinstance(v, bool) or not isinstance(v, int) or not (name == "seed" or v >= 1) \
                    or v < 0 or v > hi:
                raise StudioError(f"{name} must be a whole number in {0 if name == 'seed' else 1}"
                                  f"..{hi}, got {v!r}", 422)
        out = {"text": text.strip(), "seed": seed, "samples": samples}
        oid, point, plan = request.get("object_id"), request.get("point"), request.get("plan")
        if sum(x is not None for x in (oid, point, plan)) > 1:
            raise StudioError("give one of object_id, point or plan (a plan holds clicked "
                              "objects and points as its steps)", 422)
        objects = {int(o["id"]): o for o in room.scene.objects}
        if point is not None:
            plan = [{"action": "walk", "point": point}]
            if out["text"] and read_instruction(out["text"]).action != "walk":
                raise StudioError("a point of the floor can only be walked to; click an object "
                                  f"to {text!r} it, or leave the text empty", 422)
        if plan is not None:
            if not isinstance(plan, list) or not plan:
                raise StudioError("plan must be a non-empty list of steps", 422)
            steps = []
            for step in plan:
                if isinstance(step, dict) and "point" in step and isinstance(step["point"],
                                                                             (list, tuple)):
                    step = {**step, "point": list(step["point"])[:2]}
                steps.append(step)
            try:
                read_plan(steps, room.scene)
            except GenerateError as e:
                raise StudioError(str(e), 422) from e
            out["plan"] = steps
            return out
        if oid is not None:
            if isinstance(oid, bool) or not isinstance(oid, int) or oid not in objects:
                listed = ", ".join(f"{k} ({o['category']})" for k, o in sorted(objects.items()))
                raise StudioError(f"object {oid!r} is not in the room; its objects: "
                                  f"{listed or 'none'}", 422)
            out["object_id"] = oid
            if not out["text"]:
                o = objects[oid]
                verb = ("sit on" if takes("sit", o) else "lie down on" if takes("lie", o)
                        else "walk to")
                out["text"] = f"{verb} the {o['category']}"
        if not out["text"]:
            raise StudioError("say what the person does (text), click an object or a point of "
                              "the floor, or compose a plan", 422)
        try:
            out["text"] = check_text(out["text"])
        except GenerateError as e:
            raise StudioError(str(e), 422) from e
        return out

    def submit(self, request: dict) -> Job:
        """Check ``request`` (:meth:`check`) and queue it; returns its :class:`Job`."""
        room = self.room
        ready = self.check(request, room)
        job = Job(_job_id(), ready, room.key)
        with self._lock:
            self.jobs[job.id] = job
        self._save(job)
        self._queue.put((0, self._next(), job.id))
        return job

    def job(self, job_id: str) -> Job:
        with self._lock:
            if job_id in self.jobs:
                return self.jobs[job_id]
        raise StudioError(f"no job {job_id!r} (GET /api/jobs lists them)", 404)

    def file(self, job_id: str, name: str) -> Path:
        """The path of a job's file ``name``; only names of files in its folder (no path)."""
        job = self.job(job_id)
        if not _FILE.match(name or "") or name not in job.files:
            raise StudioError(f"job {job_id} has no file {name!r}; its files: "
                              f"{', '.join(job.files) or 'none yet'}", 404)
        return self.folder / "jobs" / job.id / name

    def wait(self, job_id: str, version: int = -1, timeout: float = 30.0) -> Job:
        """The job once its version is past ``version`` (or when ``timeout`` passes)."""
        job = self.job(job_id)
        with self._changed:
            self._changed.wait_for(lambda: job.version > version, timeout)
        return job

    def done(self, job_id: str, timeout: float | None = None) -> Job:
        """The job once it is done or failed (sampled; its files may still be written)."""
        job = self.job(job_id)
        with self._changed:
            self._changed.wait_for(lambda: job.state in ("done", "failed"), timeout)
        return job

    def idle(self, timeout: float | None = None) -> bool:
        """Wait until nothing is queued, sampling or writing (tests, shutdown)."""
        end = None if timeout is None else time.monotonic() + timeout
        with self._changed:
            return self._changed.wait_for(
                lambda: self.warm and all(j.state in ("done", "failed") and j.files_state !=
                                          "writing" and (j.state == "failed" or j.files_state
                                                         != "none") for j in self.jobs.values()),
                None if end is None else max(0.0, end - time.monotonic()))

    def close(self) -> None:
        self._stop.set()
        self._queue.put((-1, self._next(), "stop"))
        self._writes.put(None)

    # ---- the worker
    def _next(self) -> int:
        with self._lock:
            self._count += 1
            return self._count

    def _update(self, job: Job, **fields) -> None:
        with self._changed:
            for k, v in fields.items():
                setattr(job, k, v)
            job.version += 1
            self._changed.notify_all()

    def _work(self) -> None:
        while not self._stop.is_set():
            _, _, job_id = self._queue.get()
            if job_id == "stop":
                return
            if job_id is None:
                self.warm_up()
                continue
            self._run(self.jobs[job_id])

    def warm_up(self) -> None:
        """One small generate in the current room, discarded, and a story's conversions at
        the common lengths: the programs are compiled (or loaded from the on-disk cache)
        before the first click."""
        import jaxmotion

        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                jaxmotion.generate(self.room.scene, "walk to the table", **self._opts(1, 0))
        except Exception:  # noqa: BLE001  a room the default text does not fit: still warm
            pass
        from jaxmotion.planning.story import LENGTH_BUCKET, story_arrays

        for n in (LENGTH_BUCKET, 2 * LENGTH_BUCKET, 4 * LENGTH_BUCKET):  # stories' lengths
            story_arrays(np.zeros((n, 135), np.float32))
        with self._changed:
            self.warm = True
            self._changed.notify_all()

    def _opts(self, samples: int, seed: int) -> dict:
        keep = {k: v for k, v in self.options.items() if k not in ("num_points",)}
        return {**keep, "samples": samples, "seed": seed}

    def _run(self, job: Job) -> None:
        import jaxmotion
        from jaxmotion.errors import SceneNote
        from jaxmotion.export.folder import summary
        from jaxmotion.progress import listening

        room = self.rooms.get(job.room) or self.room
        req = job.request
        self._update(job, state="running", stage="starting", progress=0.02)
        self._save(job)
        t0 = time.perf_counter()

        def told(stage, fraction):
            self._update(job, stage=stage, progress=job.progress if fraction is None
                         else max(job.progress, fraction))

        try:
            with warnings.catch_warnings(record=True) as caught, listening(told):
                warnings.simplefilter("always")
                res = jaxmotion.generate(room.scene, req["text"], plan=req.get("plan"),
                                         object_id=req.get("object_id"),
                                         **self._opts(1 if req.get("plan") else req["samples"],
                                                      req["seed"]))
        except GenerateError as e:
            self._fail(job, str(e))
            return
        except Exception as e:  # noqa: BLE001  said in the job, the server lives on
            self._fail(job, f"internal error: {type(e).__name__}: {e}")
            return
        said = [str(w.message) for w in caught if not issubclass(w.category, SceneNote)
                and issubclass(w.category, UserWarning)]
        info = json.loads(summary(res, room.notes, said))
        info.update(fps=float(res.fps), samples=int(res.num_samples),
                    paths=[np.round(np.asarray(q, float), 3).tolist() for q in res.paths])
        self._update(job, state="done", stage="sampled; writing files", progress=1.0,
                     summary=info, joints=np.asarray(res.joints, np.float32),
                     timings={"sample": round(time.perf_counter() - t0, 3)},
                     finished=time.time(), files_state="writing")
        self._save(job)
        self._writes.put((job, res))

    def _fail(self, job: Job, message: str) -> None:
        self._update(job, state="failed", stage="failed", error=message, finished=time.time())
        self._save(job)

    def _write(self) -> None:
        from jaxmotion.export.folder import write_generation, write_viewer

        while True:
            item = self._writes.get()
            if item is None:
                return
            job, res = item
            out = self.folder / "jobs" / job.id
            t0 = time.perf_counter()
            try:
                write_viewer(res, out / "viewer.html")
                self._update(job, files=["viewer.html"])
                self._save(job)
                written = write_generation(res, out, video=self.video)
                names = sorted(n for n in written if n != "job.json")
                self._update(job, files=names, files_state="ready", stage="done",
                             timings={**job.timings, "files": round(time.perf_counter() - t0,
                                                                    3)})
            except Exception as e:  # noqa: BLE001
                self._update(job, files_state="failed", stage=f"files failed: {e}")
            self._save(job)

    # ---- records on disk
    def _save(self, job: Job) -> None:
        path = self.folder / "jobs" / job.id / "job.json"
        with self._lock:
            record = json.dumps(job.record(), indent=1)
        with atomic_open(path, "w") as f:
            f.write(record)

    def _load_records(self) -> None:
        for d in sorted((self.folder / "jobs").iterdir()):
            if not (d.is_dir() and _JOB_ID.match(d.name) and (d / "job.json").is_file()):
                continue
            for tmp in d.glob(".*.generate-*"):  # a write cut off by the stop
                shutil.rmtree(tmp, ignore_errors=True)
            try:
                rec = json.loads((d / "job.json").read_text())
                job = Job(d.name, rec["request"], rec["room"], state=rec["state"],
                          stage=rec["stage"], progress=rec["progress"], created=rec["created"],
                          finished=rec["finished"], summary=rec.get("summary"),
                          error=rec["error"], files=rec["files"],
                          files_state=rec["files_state"], timings=rec.get("timings_s", {}))
            except (OSError, ValueError, KeyError, TypeError):
                continue
            if job.state in ("queued", "running"):
                job.state, job.stage = "failed", "failed"
                job.error = "interrupted: the studio stopped before this job finished"
            if job.files_state == "writing":
                job.files_state = "failed"
            job.files = [f for f in job.files if (d / f).is_file()]
            if job.state == "done" and (d / "motion.npz").is_file():
                try:
                    with np.load(d / "motion.npz", allow_pickle=False) as z:
                        job.joints = np.asarray(z["joints"], np.float32)
                except (OSError, ValueError, KeyError):
                    pass
            self.jobs[job.id] = job
            self._save(job)


def _digest(path: Path) -> str:
    with open(path, "rb") as f:
        return hashlib.file_digest(f, "sha256").hexdigest()[:16]


def _job_id() -> str:
    import secrets

    return time.strftime("%Y%m%d-%H%M%S") + "-" + secrets.token_hex(3)


def _shown(name: str) -> str:
    """A client's file name as it may be shown: printable, at most 100 characters."""
    return "".join(c for c in name if c.isprintable())[:100] or "room"
