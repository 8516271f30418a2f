"""The studio's HTTP server: the page and the JSON API under ``/api/`` (FastAPI).

Endpoints (an OpenAPI description at ``/api/openapi.json``, browsable at ``/api/docs``):

- ``GET /api/health`` → ``{"status": "ok", "version", "warm", "room", "queued"}``;
- ``GET /api/scene`` → the current room: ``{"key", "name", "points", "bounds_min",
  "bounds_max", "notes", "objects": [{"id", "category", "center", "size", ...}]}``;
  ``POST /api/scene`` loads another: a multipart ``file`` upload, or JSON ``{"room": key}``
  (a room listed by ``GET /api/rooms``); ``GET /api/scene/view`` is its clickable page;
- ``POST /api/generate`` with JSON ``{"text", "object_id", "point", "plan", "seed",
  "samples"}`` → ``{"job": id}`` (202); with ``?wait=true`` it answers once the motion is
  sampled, with the job;
- ``GET /api/jobs`` (every job of the studio's folder, newest first), ``GET /api/jobs/{id}``
  → ``{"state": "queued|running|done|failed", "stage", "progress", "result", "files",
  "files_state", "error"}``, the result holding ``joints`` [K, T, 22, 3], ``fps``,
  ``target_id``, ``notes``, ``warnings`` (``?joints=false`` leaves the joints out);
  ``GET /api/jobs/{id}/events``: the job's changes as a stream of server-sent events
  (``data: <the job as JSON>``), ending when it is done or failed and its files are written;
- ``GET /api/jobs/{id}/files/{name}`` → ``motion.npz``, ``motion.glb``, ``motion.bvh``,
  ``motion.mp4``, ``motion_smplx.npz``, ``viewer.html``;
- ``POST /api/plan`` with ``{"plan": [...]}`` → the plan checked and its walking paths
  ``{"steps": [...], "paths": [[[x, y], ...], ...]}`` (nothing is sampled).

Every error is JSON ``{"error": message}`` with a 4xx status (5xx only for a fault of the
studio itself).
"""

from __future__ import annotations

import asyncio
import json

from fastapi import FastAPI, Request
from fastapi.exceptions import RequestValidationError
from fastapi.responses import FileResponse, HTMLResponse, JSONResponse, StreamingResponse
from starlette.exceptions import HTTPException as StarletteHTTPException

from jaxmotion._version import __version__
from jaxmotion.studio.engine import MAX_UPLOAD, Studio, StudioError

__all__ = ["create_app"]


def create_app(studio: Studio):
    """The FastAPI application serving ``studio``."""
    from jaxmotion.studio.page import PAGE

    app = FastAPI(title="jaxmotion studio", version=__version__, openapi_url="/api/openapi.json",
                  docs_url="/api/docs", redoc_url=None,
                  description="Generate human motion in a 3D room from clicks and language.")
    app.state.studio = studio

    @app.exception_handler(StudioError)
    async def _refused(request: Request, exc: StudioError):
        return JSONResponse({"error": str(exc)}, status_code=exc.status)

    @app.exception_handler(StarletteHTTPException)
    async def _http(request: Request, exc: StarletteHTTPException):
        return JSONResponse({"error": str(exc.detail)}, status_code=exc.status_code)

    @app.exception_handler(RequestValidationError)
    async def _invalid(request: Request, exc: RequestValidationError):
        said = "; ".join(f"{'.'.join(str(p) for p in e.get('loc', ())[1:]) or 'body'}: "
                         f"{e.get('msg')}" for e in exc.errors())
        return JSONResponse({"error": f"bad request: {said}"}, status_code=422)

    @app.exception_handler(Exception)
    async def _fault(request: Request, exc: Exception):
        return JSONResponse({"error": f"internal error: {type(exc).__name__}: {exc}"},
                            status_code=500)

    @app.get("/", response_class=HTMLResponse, include_in_schema=False)
    def page():
        return HTMLResponse(PAGE, headers={"Cache-Control": "no-store"})

    @app.get("/api/health")
    def health():
        """200 once the studio serves: its version, whether the models are warm, the room."""
        queued = sum(j.state in ("queued", "running") for j in list(studio.jobs.values()))
        return {"status": "ok", "version": __version__, "warm": studio.warm,
                "room": studio.room.name, "queued": queued}

    @app.get("/api/scene")
    def scene():
        """The current room and its objects."""
        return studio.room.describe()

    @app.post("/api/scene")
    async def load_scene(request: Request):
        """Load another room: a multipart ``file`` upload, or JSON ``{"room": key}``."""
        kind = request.headers.get("content-type", "")
        if kind.startswith("multipart/form-data"):
            length = int(request.headers.get("content-length") or 0)
            if length > MAX_UPLOAD + 2**20:
                raise StudioError(f"the upload is {length / 2**20:.0f} MiB; the studio takes "
                                  f"rooms up to {MAX_UPLOAD // 2**20} MiB", 413)
            form = await request.form(max_files=1, max_fields=4)
            upload = form.get("file")
            if upload is None or not hasattr(upload, "read"):
                raise StudioError("send the room as a multipart field named 'file'", 422)
            data = await upload.read(MAX_UPLOAD + 1)
            room = await asyncio.to_thread(studio.upload, upload.filename or "", data)
        else:
            try:
                body = await request.json()
            except ValueError:
                raise StudioError('send a multipart "file" or JSON {"room": key}', 422) from None
            if not isinstance(body, dict) or not isinstance(body.get("room"), str):
                raise StudioError('send JSON {"room": key} (GET /api/rooms lists the keys) or '
                                  'a multipart "file"', 422)
            room = await asyncio.to_thread(studio.select_room, body["room"])
        return room.describe()

    @app.get("/api/rooms")
    def rooms():
        """The rooms this studio has opened or keeps uploads of."""
        return {"rooms": studio.rooms_on_disk()}

    @app.get("/api/scene/view", response_class=HTMLResponse, include_in_schema=False)
    async def scene_view():
        path = await asyncio.to_thread(studio.room_page)
        return FileResponse(path, media_type="text/html", headers={"Cache-Control": "no-store"})

    @app.post("/api/plan")
    async def plan(request: Request):
        """A plan checked against the room, with the paths its walks would take."""
        body = await _json(request)
        return await asyncio.to_thread(_plan_paths, studio, body.get("plan"),
                                       body.get("seed", 0))

    @app.post("/api/generate", status_code=202)
    async def generate(request: Request, wait: bool = False, joints: bool = True):
        """Queue a request; ``?wait=true`` answers once it is sampled."""
        body = await _json(request)
        job = await asyncio.to_thread(studio.submit, body)
        if not wait:
            return JSONResponse({"job": job.id}, status_code=202)
        job = await asyncio.to_thread(studio.done, job.id)
        out = job.public(joints=joints)
        if job.state == "failed":
            return JSONResponse({"error": job.error, "job": job.id}, status_code=422)
        return JSONResponse({"job": job.id, **out}, status_code=200)

    @app.get("/api/jobs")
    def jobs():
        """Every job of this studio's folder, newest first (without joints)."""
        listed = sorted(list(studio.jobs.values()), key=lambda j: j.created, reverse=True)
        return {"jobs": [j.public() for j in listed]}

    @app.get("/api/jobs/{job_id}")
    def job(job_id: str, joints: bool = True):
        """A job: its state, progress and, once done, its result."""
        return studio.job(job_id).public(joints=joints)

    @app.get("/api/jobs/{job_id}/events")
    def events(job_id: str):
        """The job's changes as server-sent events, until it is finished and written."""
        job = studio.job(job_id)

        def stream():
            version = -1
            while True:
                j = studio.wait(job.id, version, timeout=15.0)
                if j.version == version:
                    yield ": still working\n\n"  # keeps proxies and the browser connected
                    continue
                version = j.version
                yield f"data: {json.dumps(j.public())}\n\n"
                if j.state == "failed" or (j.state == "done" and j.files_state != "writing"):
                    return

        return StreamingResponse(stream(), media_type="text/event-stream",
                                 headers={"Cache-Control": "no-store"})

    @app.get("/api/jobs/{job_id}/files/{name}")
    def job_file(job_id: str, name: str, download: bool = False):
        """One of a job's files (``viewer.html`` is shown in the page; the others download)."""
        path = studio.file(job_id, name)
        inline = name.endswith(".html") and not download
        return FileResponse(path, filename=None if inline else name,
                            media_type="text/html" if inline else None)

    return app


async def _json(request) -> dict:
    try:
        body = await request.json()
    except ValueError:
        raise StudioError("the request body must be a JSON object", 422) from None
    if not isinstance(body, dict):
        raise StudioError("the request body must be a JSON object", 422)
    return body


def _plan_paths(studio: Studio, plan, seed) -> dict:
    """The steps of ``plan`` as the story will take them (stand-ups inserted) and the ground
    paths of its walks, from :func:`jaxmotion.planning.story.plan_paths`."""
    from jaxmotion.errors import GenerateError
    from jaxmotion.planning.story import plan_paths

    ready = studio.check({"plan": plan, "seed": seed if isinstance(seed, int) else 0})
    try:
        steps, paths = plan_paths(studio.room.scene, ready["plan"], seed=ready["seed"])
    except GenerateError as e:
        raise StudioError(str(e), 422) from e
    return {"steps": [{"action": s.action, "object": s.object, "point": s.point} for s in steps],
            "paths": [[[round(float(x), 3), round(float(y), 3)] for x, y in p] for p in paths]}
