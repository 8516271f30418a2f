"""jaxmotion studio: a local web app over one warm process.

``jaxmotion studio [ROOM]`` loads the room (the demo by default), starts the server
(:func:`serve`) and opens the page: click an object or the floor, type or compose a story,
watch the body, download the files. The page and scripts use the same JSON API
(:mod:`jaxmotion.studio.app`); the work itself is :class:`~jaxmotion.studio.engine.Studio`.
"""

from __future__ import annotations

from jaxmotion.studio.engine import Studio, StudioError

__all__ = ["Studio", "StudioError", "create_app", "serve"]


def create_app(studio: Studio):
    """The FastAPI application of ``studio`` (:mod:`jaxmotion.studio.app`)."""
    from jaxmotion.studio.app import create_app as make

    return make(studio)


def serve(room="demo", *, folder=None, host: str = "127.0.0.1", port: int = 8000,
          open_browser: bool = True, options: dict | None = None, video: str | None = "mp4",
          log=print) -> None:
    """Start the studio on ``host:port`` and serve until interrupted (Ctrl-C).

    ``folder`` keeps uploads and results (default: ``jaxmotion-studio`` in the current
    folder); ``options`` are :class:`jaxmotion.options.GenerateOptions` fields every job uses.
    A host other than the loopback is served with a warning: anyone who reaches it can use
    the studio. The browser is opened only when asked and a display is there."""
    import os
    import sys
    import threading
    import webbrowser
    from pathlib import Path

    import uvicorn

    folder = Path(folder or "jaxmotion-studio")
    if host not in ("127.0.0.1", "localhost", "::1"):
        log(f"warning: serving on {host}: anyone who can reach this address can use the studio "
            "and upload files to it; use --host 127.0.0.1 to keep it on this machine",
            file=sys.stderr)
    log(f"loading {room} ...", file=sys.stderr)
    studio = Studio(folder, room, options=options, video=video)
    app = create_app(studio)
    url = f"http://{'[' + host + ']' if ':' in host else host}:{port}/"
    log(f"jaxmotion studio on {url} (results in {studio.folder}; Ctrl-C stops it)",
        file=sys.stderr)
    shown = os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY") or \
        sys.platform in ("darwin", "win32")
    if open_browser and shown:
        threading.Timer(1.0, lambda: webbrowser.open(url)).start()
    try:
        uvicorn.run(app, host=host, port=port, log_level="warning")
    finally:
        studio.close()
