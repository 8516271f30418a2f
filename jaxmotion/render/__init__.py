"""Offscreen rendering of skinned bodies in a room: NumPy, numba and Pillow, no GPU, no display.

``jaxmotion generate`` writes ``motion.mp4`` with it, ``jaxmotion render`` re-renders a saved
motion, ``docs/images/make_demo.py`` draws the README picture.

- :mod:`~jaxmotion.render.kernels`: the z-buffer software rasterizer the frames are drawn
  with (triangles, surfels), skinning, shading and compositing, compiled with numba (cached
  on disk; :func:`prepare_in_background` loads them while ``generate`` samples);
- :mod:`~jaxmotion.render.raster`: the same rasterizer in NumPy array passes (fragments
  resolved by one ``np.minimum.at`` over packed ``depth | id`` keys), the reference the
  kernels are tested against;
- :mod:`~jaxmotion.render.camera`: pinhole cameras that frame the motion, fixed or following;
- :mod:`~jaxmotion.render.scene`: the room as lit surfels (its points, with their normals or
  estimated ones), a floor plane, eye-dome outlines, the cutaway (near walls and furniture
  that would hide the body are left out), contact and drop shadows;
- :mod:`~jaxmotion.render.body`: the mannequin skinned per frame on the host;
- :mod:`~jaxmotion.render.frames`: :class:`Clip` draws a frame (room, shadows, bodies at 2×
  and reduced, caption, clock); :func:`render_video` (MP4 / GIF), :func:`render_still` (PNG);
- :mod:`~jaxmotion.render.results`: a ``Generation``, a saved ``motion.npz`` or a dataset
  sample in its room.

Rooms are point clouds here (:class:`~jaxmotion.scene.Scene` keeps no triangles; a mesh is
sampled on load), so the room is drawn as splats even when it came from a mesh.

Why a software rasterizer (measured on this 2-core machine, the other core busy):

============================  =========  =====================================================
candidate                     installed  what it took / what it gave
============================  =========  =====================================================
moderngl 5.13 + glcontext     1.4 MB     a context opens only through the system's EGL (Mesa's
(EGL standalone)                         llvmpipe is installed here: 57 frames/s for the 48k-
                                         triangle body alone at 1280×960); pip brings no EGL
                                         or OSMesa library, so a pip-only machine has none
pyrender (OSMesa / EGL)       —          not measured: the same system OpenGL libraries
vtk 9.7 (offscreen)           566 MB     139 MB wheel; opened the system's EGL here, 4 frames/s
                                         for the body at 1280×960 (update, render, read back)
mitsuba 3.9 + drjit           206 MB     ``llvm_ad_rgb`` failed to compile its kernels with
                                         the system's LLVM 15; ``scalar_rgb``: 4.7 frames/s for
                                         the body alone, 640×480, 4 samples/pixel (no room)
bpy (Blender as a module)     —          not measured: wheels of ~300 MB for one Python
                                         version, and it needs X11/GL system libraries
this package (NumPy, numba)   ~60 MB     numba + llvmlite wheels (Linux, macOS, Windows);
                                         640×480 with the room, shadows and 2× antialiasing
                                         (numbers below)
============================  =========  =====================================================

A GPU-less, display-less machine installed by ``pip`` alone has no OpenGL implementation,
so every OpenGL route needs system packages (``libegl1``, ``libgl1-mesa-dri`` or
``libosmesa6``); the ray tracers are slower than the target before a room is added. A
software rasterizer needs nothing outside pip and is fast enough because the work is small:
one body of 48k triangles (most a few pixels wide), a room drawn once per clip. Written as
NumPy array passes it took 40–50 ms a frame; the same arithmetic as compiled loops
(:mod:`~jaxmotion.render.kernels`, the same pixels) takes 11–15 ms.

Speed (``python benchmarks/render.py --sizes 640x480 --repeats 3``: the demo room, 60,000
points, a 120-frame sitting-down motion, MP4; this 2-core machine with other work on it, load
average ~4.5, both in one session): drawing 73.9 frames/s (the NumPy passes: 18.1), MP4 end
to end 53.9 frames/s (17.4), set-up 0.27 s (0.52). ``jaxmotion generate`` draws 60 frames
(15 per second of motion) after writing the other files: its ``write`` stage took 1.4–1.8 s
with the video, ~0.5 s of it the other files (the NumPy renderer: 4.5–5.9 s).
"""

from __future__ import annotations

import contextlib
import importlib
import threading

_EXPORTS = {"Bodies": "body", "CAMERA_MODES": "camera", "Camera": "camera",
            "CameraPlan": "camera", "plan_cameras": "camera", "SAMPLE_LAYOUTS": "frames",
            "Clip": "frames", "render_still": "frames", "render_video": "frames"}

__all__ = ["CAMERA_MODES", "SAMPLE_LAYOUTS", "Bodies", "Camera", "CameraPlan", "Clip",
           "plan_cameras", "prepare_in_background", "render_still", "render_video"]


def __getattr__(name: str):
    """The public names load their modules on first use: importing this package (or
    :mod:`~jaxmotion.render.kernels` alone, as :func:`prepare_in_background` does) imports
    nothing else."""
    if name in _EXPORTS:
        value = getattr(importlib.import_module(f"jaxmotion.render.{_EXPORTS[name]}"), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'jaxmotion.render' has no attribute {name!r}")


def prepare_in_background() -> threading.Thread:
    """Start a daemon thread that imports numba and loads the compiled kernels
    (:func:`jaxmotion.render.kernels.warm_up`), so that a rendering started later finds them
    ready (``jaxmotion generate`` calls it before sampling: ~0.5–1 s of a fresh process's
    start-up off the video). The thread imports no other jaxmotion module; a failure there is
    left for the rendering itself to meet."""

    def work():
        with contextlib.suppress(Exception):  # the same error comes again where it matters
            from jaxmotion.render import kernels

            kernels.warm_up()

    thread = threading.Thread(target=work, name="jaxmotion-render-prepare", daemon=True)
    thread.start()
    return thread
