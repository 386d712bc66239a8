"""Pictures and animations without a display (pyvista, off-screen).

    demkit.viz.snapshot("out", "frame.png")          # last frame of the series in folder out/
    demkit.viz.animate(trajectory, "run.gif")        # or .mp4

Sources: a written series (.pvd or its folder), one .vtu frame, a :class:`demkit.Trajectory` or
a :class:`demkit.io.SeriesData`. Spheres are drawn to scale (coloured per particle), dipoles as
arrows through the sphere centres, recent paths as trails fading into the background.
Before the first picture, a child process checks which OpenGL path works here (EGL, OSMesa or X;
see :mod:`demkit.viz.backend`); when none does, :class:`RenderingUnavailable` is raised.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from .backend import RenderingUnavailable, ensure_rendering, rendering_info

__all__ = ["snapshot", "animate", "rendering_info", "RenderingUnavailable"]


def _select(frames, time_range):
    """Indices of the frames with time in ``time_range`` (None: all)."""
    t = np.asarray(frames.time)
    if time_range is None:
        return np.arange(len(t))
    lo, hi = time_range
    lo = -np.inf if lo is None else lo
    hi = np.inf if hi is None else hi
    index = np.flatnonzero((t >= lo) & (t <= hi))
    if len(index) == 0:
        raise ValueError(f"no frame has a time in {time_range}; the frames span t = {t[0]:.6g} .. {t[-1]:.6g}")
    return index


def snapshot(source, path, time=None, frame=-1, trail=None, window_size=(1024, 768),
             background="white", arrows=True, view="auto", label=True):
    """Draw one frame of ``source`` to an image file (PNG, JPEG, ... by the suffix of ``path``).

    time : draw the frame nearest this simulation time (overrides ``frame``, default the last).
    trail : length of the fading trails in time units (0: none; None: a quarter of the time up to
        the frame for at most 1000 particles, none above).
    view : 'auto' (a plane view when the particles lie in one, else isometric), 'xy', 'xz', 'yz', 'iso'.
    Returns the path. Raises RenderingUnavailable if nothing can render here.
    """
    from .render import FrameDrawer, Style, load

    style = Style(trail, window_size, background, arrows, view, label)
    path = Path(path)
    if not path.parent.is_dir():
        raise ValueError(f"folder {path.parent} does not exist")
    frames = load(source)
    n = len(frames.time)
    if time is not None:
        k = int(np.argmin(np.abs(np.asarray(frames.time) - time)))
    else:
        if not -n <= frame < n:
            raise ValueError(f"frame {frame} is out of range for {n} frames")
        k = frame % n
    ensure_rendering()
    drawer = FrameDrawer(frames, style, np.array([k]))
    try:
        drawer.draw(k)
        drawer.plotter.screenshot(str(path))
    finally:
        drawer.close()
    return path


def animate(source, path, fps=20, max_frames=200, time_range=None, trail=None,
            window_size=(800, 600), background="white", arrows=True, view="auto", label=True):
    """Render the frames of ``source`` to an animation, ``path`` ending in .gif or .mp4.

    max_frames : at most this many frames, evenly chosen from those in ``time_range``
        (a (start, stop) pair of simulation times, either may be None).
    fps : frames per second of the animation. trail, view, ...: as for :func:`snapshot`.
    The camera stays fixed, framing everything shown. Returns the path.
    Raises RenderingUnavailable if nothing can render here.
    """
    from .movie import MovieWriter
    from .render import FrameDrawer, Style, load

    style = Style(trail, window_size, background, arrows, view, label)
    movie = MovieWriter(path, fps)
    if int(max_frames) < 1:
        raise ValueError(f"max_frames must be at least 1, got {max_frames}")
    frames = load(source)
    index = _select(frames, time_range)
    if len(index) > max_frames:
        index = index[np.unique(np.round(np.linspace(0, len(index) - 1, int(max_frames))).astype(int))]
    ensure_rendering()
    drawer = FrameDrawer(frames, style, index)
    try:
        for k in index:
            movie.add(drawer.draw(k))
    finally:
        drawer.close()
    return movie.close()
