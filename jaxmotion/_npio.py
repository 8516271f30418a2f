"""Reading ``.npz`` files on several threads at once.

NumPy reads each array's header with :func:`ast.literal_eval`, and Python 3.11 and 3.12 build
that tree with a counter shared between threads (CPython gh-106905, fixed in 3.13): two
threads parsing at the same moment can fail with ``SystemError: AST constructor recursion
depth mismatch`` (seen once in ``generate``). The readers that can run beside another go
through :func:`load_npz`, which holds :data:`READ_LOCK` while a file's headers are parsed, so
no two of them parse at once: training's samples and scenes (its loader thread) and text
caches (the main thread), and the body's and the skeleton's assets, which ``generate``'s
video and the files beside it read on two threads.
"""

from __future__ import annotations

import contextlib
import threading

import numpy as np

__all__ = ["READ_LOCK", "load_npz"]

#: Held while a ``.npz`` read by :func:`load_npz` parses its headers (re-entrant: a reader may
#: read another file inside its block).
READ_LOCK = threading.RLock()


@contextlib.contextmanager
def load_npz(path, **kwargs):
    """``np.load(path, **kwargs)`` as a context manager, with :data:`READ_LOCK` held for the
    whole block (a ``.npz`` parses each array's header when the array is first read, so the
    block reads what it needs and leaves)."""
    with READ_LOCK, np.load(path, **kwargs) as data:
        yield data
