"""Pictures and animations without a display (pyvista, off-screen).

    demkit.viz.snapshot("out", "frame.png")          # last frame of the series in folder out/
    demkit.viz.animate(trajectory, "run.gif")        # or .mp4

Sources: a written series (.pvd or its folder), one .vtu frame, a :class:`demkit.Trajectory` or
a :class:`demkit.io.SeriesData`. Spheres are drawn to scale, coloured by a field (``color_by``,
with a colour bar), dipoles as arrows through the sphere centres, recent paths as trails fading
into the background, the box (when there is one) as thin lines. ``frame``, ``bounds`` and
``zoom`` choose what the camera shows, ``subset`` which spheres are drawn.
Before the first picture, a child process checks which OpenGL path works here (EGL, OSMesa or X;
see :mod:`demkit.viz.backend`); when none does, :class:`RenderingUnavailable` is raised.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..clustering import clusters, contacts
from . import analysis  # noqa: F401 (moved to demkit.clustering; dk.viz.analysis keeps working)
from .backend import RenderingUnavailable, ensure_rendering, rendering_info

__all__ = ["snapshot", "animate", "rendering_info", "RenderingUnavailable", "clusters", "contacts"]


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


DRAWING = """
    frame : what the camera fits: 'all' (every sphere drawn), 'cluster' (the largest cluster:
        spheres whose surfaces are closer than 0.1 mean radii; in a periodic box drawn in one
        piece; in a 3-D view the box outline is left out, its lines would cross the cluster), 'box'
        (the simulation box) or 'auto' (default: with a box and no subset, 'box' when the spheres
        span at least half of it along every axis, else 'all' with the box outlined (a pile at the
        bottom of a tall box fills the picture); without, 'cluster' when the largest cluster holds
        more than half the spheres drawn and the others spread over more than 1.5 times its size,
        else 'all').
    bounds : (xmin, xmax, ymin, ymax, zmin, zmax) to fit instead (length units; overrides frame).
    zoom : factor applied after framing (2: twice as close).
    color_by : 'id' (a colour per particle, cycled; the default up to 10 particles), 'speed' (the
        default above 10 particles when the source has velocities), 'contacts' (touching
        neighbours: centre distance < (r_i + r_j)(1 + 0.01)), 'cluster' (largest first), 'dipole'
        (m_z/|m|, the z component of the unit moment, -1..1), 'radius', the name of a point field
        of the source ('velocity', 'angular_velocity', 'force', 'torque': magnitudes; 'mass'), or
        an (N,) or (T, N) array of values. A colour bar shows the field.
    color_label : the colour bar's title (default: the field's name; 'value' for an array).
    cmap : a matplotlib colour map name (default 'viridis'; 'coolwarm' for 'dipole').
    clim : (low, high) colour range (default: the range over the frames shown).
    subset : the spheres to draw: indices (into the particle axis of the source), a boolean mask
        (N,), a callable(frames, k) returning either for frame k, or 'cluster' (the largest
        cluster of each frame). Framing follows the subset.
    trail : length of the fading trails in time units (0: none; None: a quarter of the time shown,
        above 10 spheres at most the time the median sphere takes to move 3 radii, none above
        1000 spheres).
    view : 'auto' (a plane view when the framed spheres lie in one, else isometric), 'xy', 'xz',
        'yz', 'iso'.
    arrows : draw dipoles as dark arrows through the centres. label : show the time.
    The box, when the source has one, is outlined with thin lines."""


def _plan(frames, shown, **style):
    from .plan import Plan, Style

    return Plan(frames, Style(**style), shown)


def snapshot(source, path, time=None, frame_index=-1, *, trail=None, window_size=(1024, 768),
             background="white", arrows=True, view="auto", label=True, frame="auto", bounds=None,
             zoom=1.0, color_by=None, color_label=None, cmap=None, clim=None, subset=None):
    """Draw one frame of ``source`` to an image file (PNG, JPEG, ... by the suffix of ``path``).

    time : draw the frame nearest this simulation time (overrides ``frame_index``, default the last).
    frame_index : the frame to draw (an index; -1: the last).
    {DRAWING}
    Returns the path. Raises ValueError for bad arguments or a path that cannot be written (before
    anything renders) and RenderingUnavailable if nothing can render here. The picture is written
    to a temporary file beside ``path`` and renamed to it: ``path`` is the new picture or as it was.
    """
    from .render import FrameDrawer, load

    from ..outputs import check_writable, write_atomically

    path = Path(path)
    if not path.parent.is_dir():
        raise ValueError(f"folder {path.parent} does not exist")
    check_writable(path, "picture")  # before rendering, not after
    frames = load(source)
    n = len(frames.time)
    if time is not None:
        k = int(np.argmin(np.abs(np.asarray(frames.time) - time)))
    else:
        if not -n <= frame_index < n:
            raise ValueError(f"frame {frame_index} is out of range for {n} frames")
        k = frame_index % n
    plan = _plan(frames, np.array([k]), trail=trail, window_size=window_size, background=background,
                 arrows=arrows, view=view, label=label, frame=frame, bounds=bounds, zoom=zoom,
                 color_by=color_by, color_label=color_label, cmap=cmap, clim=clim, subset=subset)
    ensure_rendering()
    drawer = FrameDrawer(plan)
    try:
        drawer.draw(k)
        write_atomically(path, lambda tmp: drawer.plotter.screenshot(str(tmp)))  # whole or not at all
    finally:
        drawer.close()
    return path


def animate(source, path, fps=20, max_frames=200, time_range=None, *, trail=None, window_size=(800, 600),
            background="white", arrows=True, view="auto", label=True, frame="auto", bounds=None,
            zoom=1.0, color_by=None, color_label=None, cmap=None, clim=None, subset=None, progress=None):
    """Render the frames of ``source`` to an animation, ``path`` ending in .gif or .mp4.

    max_frames : at most this many frames, evenly chosen from those in ``time_range``
        (a (start, stop) pair of simulation times, either may be None).
    fps : frames per second of the animation.
    progress : a progress bar over the frames on stderr: None (default) when stderr is a terminal
        and rendering looks like taking more than about 2 s, True always, False never.
    {DRAWING}
    The camera and the colour range stay fixed for the whole animation (framing the last frame's
    cluster for frame='cluster'). Returns the path. Raises ValueError for bad arguments and
    RenderingUnavailable if nothing can render here. The animation is written to
    ``<name>.partial.<suffix>`` and renamed to ``path`` when complete; on Ctrl-C (within a frame's
    drawing time) or an error the partial file is removed, ``path`` is left as it was, and
    KeyboardInterrupt says how many frames were drawn.
    """
    from ..progress import Progress, check_progress
    from .movie import MovieWriter
    from .render import FrameDrawer, load

    check_progress(progress)
    movie = MovieWriter(path, fps)
    if int(max_frames) < 1:
        raise ValueError(f"max_frames must be at least 1, got {max_frames}")
    frames = load(source)
    index = _select(frames, time_range)
    if len(index) > max_frames:
        index = index[np.unique(np.round(np.linspace(0, len(index) - 1, int(max_frames))).astype(int))]
    plan = _plan(frames, index, trail=trail, window_size=window_size, background=background,
                 arrows=arrows, view=view, label=label, frame=frame, bounds=bounds, zoom=zoom,
                 color_by=color_by, color_label=color_label, cmap=cmap, clim=clim, subset=subset)
    ensure_rendering()
    drawer = FrameDrawer(plan)
    bar = Progress(len(index), progress, desc="rendering frames", unit="frame")
    done = 0
    from ..simulation import CatchInterrupt
    try:
        # Ctrl-C is taken between frames: raised inside VTK's Python callbacks (reading a frame) it
        # would be swallowed by VTK as a pipeline error and the render would go on
        with CatchInterrupt() as stop:
            bar.update(0)
            for k in index:
                movie.add(drawer.draw(k))
                done += 1
                bar.update(done)
                if stop.caught:
                    raise KeyboardInterrupt
    except KeyboardInterrupt:
        movie.abort()
        raise KeyboardInterrupt(f"rendering interrupted after {done} of {len(index)} frames: {movie.path} was not "
                                f"written (the partial file was removed)") from None
    except BaseException:
        movie.abort()
        raise
    finally:
        bar.close()
        drawer.close()
    try:
        return movie.close()
    except KeyboardInterrupt:
        raise KeyboardInterrupt(f"interrupted while writing {movie.path}: it was not written (the partial file "
                                f"was removed)") from None


snapshot.__doc__ = snapshot.__doc__.replace("{DRAWING}", DRAWING.strip("\n").lstrip())
animate.__doc__ = animate.__doc__.replace("{DRAWING}", DRAWING.strip("\n").lstrip())
