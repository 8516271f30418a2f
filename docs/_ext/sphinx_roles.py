"""A griffe extension for the API pages: the docstrings' Sphinx-style roles as inline code.

jaxmotion's docstrings name other objects as ``:func:`jaxmotion.generate``` or
``:class:`~jaxmotion.scene.Scene``` (a leading ``~`` shows the last name only). mkdocstrings
renders Markdown, where such a role would show as ``:func:`` before the code; this turns each
role into the code alone.
"""

from __future__ import annotations

import re

import griffe

_ROLE = re.compile(r":(?:py:)?(?:func|class|meth|mod|data|attr|obj|exc|const):`(~?)([^`]+)`")


def _code(match: re.Match) -> str:
    short, name = match.groups()
    return f"`{name.rsplit('.', 1)[-1] if short else name}`"


class SphinxRoles(griffe.Extension):
    """Rewrite every docstring's roles as inline code when its object is loaded."""

    def on_instance(self, *, obj: griffe.Object, **kwargs) -> None:
        if obj.docstring is not None:
            obj.docstring.value = _ROLE.sub(_code, obj.docstring.value)
