"""VTKWriter: a simulation writer that saves a ParaView time series while a run goes on.

Usage::

    writer = dk.VTKWriter("out", every=100.0)          # a frame every 100 time units
    sim = dk.Simulation(scene, integrator, writers=[writer])
    sim.run(5000.0)
    sim.close()                                         # writes the trails file

or ``with dk.VTKWriter("out", every=100.0) as writer: ...`` (a writer never closed writes its
trails when it is garbage-collected or the program exits). The .pvd collection is rewritten
after every frame, so an interrupted run leaves a valid series of the frames written so far (the
trails can then be rebuilt with ``demkit.io.write_polylines("out", "out/particles_trails.vtp")``).
"""
from __future__ import annotations

import math
import warnings
import weakref

import numpy as np

from .frames import VECTOR_FIELDS, FrameWriter, choose_fields
from .polylines import write_polylines
from .series import SeriesFolder


class _Trails:
    """Positions of every written frame in id order (unwrapped in a periodic box), written as
    poly-lines when finished."""

    image = None  # for write_polylines: the positions kept are unwrapped already

    def __init__(self, path, compress, box=None):
        self.path, self.compress, self.box = path, compress, box
        self.time, self.position, self.ids, self.radius = [], [], None, None
        self.broken = False

    def add(self, time, particles):
        order = np.argsort(particles.ids, kind="stable")
        if self.ids is None:
            self.ids, self.radius = particles.ids[order].copy(), particles.radius[order].copy()
        elif not np.array_equal(particles.ids[order], self.ids):
            warnings.warn("the particles changed during the run: no trails file will be written")
            self.broken = True
        if not self.broken:
            position = particles.position[order]
            image = getattr(particles, "image", None)
            if image is not None and self.box is not None:
                position = position + image[order] * self.box.size
            self.time.append(float(time))
            self.position.append(np.array(position, dtype=np.float64))

    def write(self):
        if self.broken or not self.time:
            return None
        self.time, self.position = np.array(self.time), np.stack(self.position)
        return write_polylines(self, self.path, compress=self.compress)


class VTKWriter:
    """Write the particles every ``every`` time units as a ParaView series in ``folder``.

    Parameters
    ----------
    folder : output folder (created if needed). Files: ``<name>.pvd``, ``<name>_000000.vtu``, ...,
        ``<name>_trails.vtp``. A non-empty folder is refused unless ``overwrite=True``, which
        deletes only this series' own files.
    every : time between frames (simulation time units; rounded to whole steps by the simulation).
    compress : False (default, fastest), True or 'zlib', or 'lzma' (smallest, slowest).
    trails : also write the paths as poly-lines (``<name>_trails.vtp``) when the writer is closed;
        keeps every frame's positions in memory (N*3*8 bytes per frame): use False for large runs.
    fields : names among velocity, angular_velocity, dipole, force, torque to write (default: all
        the scene has; force and torque need one extra force evaluation per frame). id, radius and
        mass are always written, and ``image`` (periodic image counts) when the particles have it.
        The scene's box (``scene.box``) is stored in the .pvd, and the trails are unwrapped.
    dtype : 'float64' (default) or 'float32' (half the bytes).
    name : base name of the series files.
    contacts : also write the contact network of every frame (``<name>_contacts.pvd`` and
        ``<name>_contacts_000000.vtp``, ...: one line per contact with its forces, overlap, sliding
        state and dissipated power, see :mod:`demkit.contacts`), to draw force chains in ParaView.
    """

    def __init__(self, folder, every, compress=False, trails=True, fields=None, dtype="float64",
                 name="particles", overwrite=False, contacts=False):
        try:
            every = float(every)
        except (TypeError, ValueError):
            raise ValueError(f"every must be a positive time interval, got {every!r}") from None
        if not math.isfinite(every) or every <= 0:
            raise ValueError(f"every must be a positive finite time interval, got {every}")
        self.every = every
        self._frames = FrameWriter(compress, dtype)
        if fields is not None:
            choose_fields(VECTOR_FIELDS, fields)  # reject unknown names now
        self._requested = fields
        self.series = SeriesFolder(folder, name, overwrite)
        self.contact_series = SeriesFolder(folder, name + "_contacts", overwrite, extension="vtp") if contacts else None
        self.trails = bool(trails)
        self._trails = None
        self.fields = None
        self._closed = False
        self._finalizer = None

    # ---- writer protocol ---------------------------------------------------------------------
    def open(self, simulation):
        """Start the series for ``simulation``'s scene (called by the simulation)."""
        scene = simulation.scene
        self.begin(scene.particles, has_force=bool(scene.interactions),
                   has_torque=any(inter.torque for inter in scene.interactions),
                   box=getattr(scene, "box", None))

    def write(self, simulation):
        """Write the current state of ``simulation`` as the next frame (called by the simulation)."""
        force = torque = None
        if self.fields is None:
            raise ValueError("the simulation must call open() before write()")
        if "force" in self.fields or "torque" in self.fields:
            force, torque = simulation.scene.forces()
        self.write_state(simulation.time, simulation.scene.particles, force, torque)
        if self.contact_series is not None:
            contacts = simulation.scene.contacts()
            particles = simulation.scene.particles
            self.contact_series.add_frame(simulation.time, lambda path: contacts.write_vtk(
                path, particles, compress=bool(self._frames.compression)))

    def close(self):
        """Finish the series: write the trails file (once). The frames and .pvd are complete already."""
        if self._finalizer is not None:
            self._finalizer()
        self._closed = True

    # ---- lower-level use (without a Simulation) -----------------------------------------------
    def begin(self, particles, has_force=False, has_torque=False, box=None):
        """Choose the fields for ``particles`` and claim the folder; ``box`` (a demkit.Box or None)
        goes into the .pvd. Raises ValueError if this writer was used before or another run
        started writing the same series."""
        if self.fields is not None or self._closed:
            raise ValueError("this VTKWriter has been used already: create a new one for a new run")
        self.series.check_unclaimed()
        if self.contact_series is not None:
            self.contact_series.check_unclaimed()
            self.contact_series.box = box
        available = [f for f in ("velocity", "angular_velocity", "dipole")
                     if getattr(particles, f) is not None]
        available += ["force"] * has_force + ["torque"] * has_torque
        self.fields = choose_fields(available, self._requested)
        self.series.box = box
        if self.trails:
            self._trails = _Trails(self.series.trails, bool(self._frames.compression), box)
            self._finalizer = weakref.finalize(self, self._trails.write)

    def write_state(self, time, particles, force=None, torque=None):
        """Write ``particles`` at ``time`` as the next frame; ``force``/``torque`` (N,3) are needed
        only when those fields are written. Returns the .vtu path."""
        if self.fields is None:
            raise ValueError("call begin() (or let a Simulation call open()) before writing")
        if self._closed:
            raise ValueError("this VTKWriter is closed")
        data = {"id": particles.ids, "radius": particles.radius, "mass": particles.mass}
        given = {"force": force, "torque": torque}
        for name in self.fields:
            value = given[name] if name in given else getattr(particles, name)
            if value is None:
                raise ValueError(f"{name} must be given to write_state: the writer writes {name}")
            data[name] = value
        if getattr(particles, "image", None) is not None:
            data["image"] = np.asarray(particles.image, dtype=np.int64)
        path = self.series.add_frame(time, lambda p: self._frames.write(p, particles.position, data))
        if self._trails is not None:
            self._trails.add(time, particles)
        return path

    # ---- conveniences -------------------------------------------------------------------------
    @property
    def pvd(self):
        """Path of the series' .pvd collection."""
        return self.series.pvd

    @property
    def frames_written(self):
        return len(self.series.entries)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
        return False

    def __repr__(self):
        return (f"VTKWriter({str(self.series.folder)!r}, every={self.every!r}, "
                f"{self.frames_written} frames written)")
