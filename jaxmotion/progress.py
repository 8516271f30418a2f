"""Progress of long work, told to whoever listens (the studio streams it to its page).

:func:`report` is called by the stages of :func:`jaxmotion.generate` and of a story
(:func:`jaxmotion.planning.story.tell`) as they finish or start; :func:`listening` installs a
listener for the code run inside it, in this thread (a context variable: a worker thread's
listener never hears another thread's work). With no listener, :func:`report` does nothing.
"""

from __future__ import annotations

import contextlib
import contextvars
from collections.abc import Callable, Iterator

__all__ = ["listening", "report"]

_listener: contextvars.ContextVar[Callable[[str, float | None], None] | None] = \
    contextvars.ContextVar("jaxmotion_progress", default=None)


def report(stage: str, fraction: float | None = None) -> None:
    """Tell the listener (if any) that ``stage`` is under way or done, with the share of the
    whole job done so far (``fraction`` in [0, 1], or None when it is not known)."""
    fn = _listener.get()
    if fn is not None:
        fn(stage, None if fraction is None else min(1.0, max(0.0, float(fraction))))


@contextlib.contextmanager
def listening(fn: Callable[[str, float | None], None]) -> Iterator[None]:
    """Within the block, :func:`report` calls ``fn(stage, fraction)``."""
    token = _listener.set(fn)
    try:
        yield
    finally:
        _listener.reset(token)
