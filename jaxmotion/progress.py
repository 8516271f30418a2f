"""Progress of long work, told to whoever listens (the studio streams it to its page).

:func:`report` is called by the stages of :func:`jaxmotion.generate` and of a story
(:func:`jaxmotion.planning.story.tell`) as they finish or start; :func:`listening` installs a
listener for the code run inside it, in this thread (a context variable: a worker thread's
listener never hears another thread's work). With no listener, :func:`report` does nothing.
"""

from __future__ import annotations

import contextlib
import contextvars
import sys
import time
from collections.abc import Callable, Iterator

__all__ = ["Laps", "listening", "report"]

#: What :func:`jaxmotion.generate` does after each of its stages, and the share of the work
#: done by then.
_AFTER = {"load": ("grounding", 0.1), "adm": ("sampling", 0.3), "region": ("sampling", 0.3),
          "sample": ("fitting the bodies", 0.85), "fit": ("fitted", 0.95)}

_listener: contextvars.ContextVar[Callable[[str, float | None], None] | None] = \
    contextvars.ContextVar("jaxmotion_progress", default=None)


def report(stage: str, fraction: float | None = None) -> None:
    """Tell the listener (if any) that ``stage`` is under way or done, with the share of the
    whole job done so far (``fraction`` in [0, 1], or None when it is not known)."""
    fn = _listener.get()
    if fn is not None:
        fn(stage, None if fraction is None else min(1.0, max(0.0, float(fraction))))


class Laps:
    """The stages of :func:`jaxmotion.generate` timed: ``laps(name)`` ends stage ``name``
    (its seconds in ``laps.times``), prints it to stderr with ``echo`` and :func:`report`s
    what comes next."""

    def __init__(self, echo: bool = False):
        self.times: dict[str, float] = {}
        self.echo = echo
        self._t0 = time.perf_counter()

    def __call__(self, name: str) -> None:
        now = time.perf_counter()
        self.times[name], self._t0 = now - self._t0, now
        report(*_AFTER.get(name, (f"{name} done", None)))
        if self.echo:
            print(f"  {name:<10} {self.times[name]:6.2f} s", file=sys.stderr, flush=True)


@contextlib.contextmanager
def listening(fn: Callable[[str, float | None], None]) -> Iterator[None]:
    """Within the block, :func:`report` calls ``fn(stage, fraction)``."""
    token = _listener.set(fn)
    try:
        yield
    finally:
        _listener.reset(token)
