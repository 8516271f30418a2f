"""The error a user's bad input raises: its message names the problem and the fix.

Every stage of ``generate`` (options, scene, grounding, checkpoints, text, output folder)
raises :class:`GenerateError` for input it cannot use, before any heavy work; the command line
prints the message on one line and exits with code 2, without a traceback.
"""

from __future__ import annotations

__all__ = ["GenerateError", "SceneError", "SceneNote"]


class GenerateError(ValueError):
    """Bad input to :func:`jaxmotion.generate`; the message names the problem and the fix."""


class SceneError(ValueError):
    """A scene file or scan folder is missing, unsupported, unreadable or holds no usable
    geometry; the message names the file and the fix."""


class SceneNote(UserWarning):
    """What preparing a room did (a unit read, an up axis found, the floor moved, objects
    found): a note, not a fault; the command line lists these under the summary's ``notes``."""
