"""Offscreen rendering of skinned bodies in a room (NumPy software rasterizer)."""

from jaxmotion.render.body import Bodies
from jaxmotion.render.camera import CAMERA_MODES, Camera, plan_cameras
from jaxmotion.render.frames import SAMPLE_LAYOUTS, Clip, render_still, render_video

__all__ = ["CAMERA_MODES", "SAMPLE_LAYOUTS", "Bodies", "Camera", "Clip", "plan_cameras",
           "render_still", "render_video"]
