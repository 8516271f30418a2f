"""Visualisation: still previews (and, later, videos and the web viewer)."""

from jaxmotion.viz.preview import render_preview

__all__ = ["render_preview"]
