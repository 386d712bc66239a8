"""VTKWriter: a simulation writer that saves a ParaView time series while a run goes on.

Usage::

    writer = dk.VTKWriter("out", every=100.0)          # a frame every 100 time units
    sim = dk.Simulation(scene, integrator, writers=[writer])
    sim.run(5000.0)
    sim.close()                                         # writes the trails file

or ``with dk.VTKWriter("out", every=100.0) as writer: ...`` (a writer never closed writes its
trails when it is garbage-collected or the program exits). Each frame is complete on disk before
the .pvd names it, and the .pvd grows by one entry per frame at a cost independent of the length
of the series, so a run killed at any moment leaves a valid series of the frames written so far
(the trails can then be rebuilt with ``demkit.io.write_polylines("out", "out/particles_trails.vtp")``).
A run resumed from a checkpoint continues the series: ``VTKWriter("out", every, resume=True)``
and :meth:`VTKWriter.resume` instead of ``open``.
"""
from __future__ import annotations

import math
import warnings
import weakref

import numpy as np

from ..checks import writer_interval
from .box_outline import write_outline
from .frames import CONSTANT_FIELDS, VECTOR_FIELDS, FrameWriter, choose_fields, read_frame
from .polylines import write_vtp_polygons
from .series import write_polylines
from .series import TIME_TOLERANCE, SeriesFolder
from .walls import WallSurfaces


class _Trails:
    """Positions of every written frame in id order (unwrapped in a periodic box), written as
    poly-lines when finished."""

    image = None  # for write_polylines: the positions kept are unwrapped already

    def __init__(self, path, compress, box=None):
        self.path, self.compress, self.box = path, compress, box
        self.time, self.position, self.ids, self.radius = [], [], None, None
        self.broken = False

    def add(self, time, ids, radius, position, image=None):
        """Add a frame: ids, radius (N,), position (N,3) and image counts (N,3) or None."""
        ids = np.asarray(ids)
        order = np.argsort(ids, kind="stable")
        if self.ids is None:
            self.ids, self.radius = ids[order].copy(), np.asarray(radius, dtype=np.float64)[order]
        elif not np.array_equal(ids[order], self.ids):
            warnings.warn("the particles changed during the run: no trails file will be written")
            self.broken = True
        if not self.broken:
            position = np.array(np.asarray(position)[order], dtype=np.float64)
            if image is not None and self.box is not None:
                position += np.asarray(image)[order] * self.box.size_at(float(time))  # (a deforming box's then)
            self.time.append(float(time))
            self.position.append(position)

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
        deletes only this series' own files, or ``resume=True``.
    every : time between frames (simulation time units; rounded to whole steps by the simulation,
        counted from step 0). The state each run ends in is written too, also when it falls
        between two frames.
    compress : False (default, fastest), True or 'zlib', or 'lzma' (smallest, slowest).
    trails : also write the paths as poly-lines (``<name>_trails.vtp``) when the writer is closed;
        keeps every frame's positions in memory (N*3*8 bytes per frame): use False for large runs.
    fields : names among velocity, angular_velocity, dipole, force, torque to write (default: all
        the scene has; force and torque need one extra force evaluation per frame). id, radius and
        mass are always written, and ``image`` (periodic image counts) when the particles have it.
        The scene's box (``scene.box``) is stored in the .pvd, and the trails are unwrapped; a box
        that deforms (``Box(deform=...)``) is also written at every frame as its outline, a series
        ``<name>_box.pvd`` (:mod:`demkit.io.box_outline`), which ParaView shows frame by frame.
    dtype : 'float64' (default) or 'float32' (half the bytes).
    name : base name of the series files.
    overwrite : replace this series' files in a non-empty folder (other files are left alone).
    contacts : also write the contact network of every frame (``<name>_contacts.pvd`` and
        ``<name>_contacts_000000.vtp``, ...: one line per contact with its forces, overlap, sliding
        state and dissipated power, see :mod:`demkit.contacts`), to draw force chains in ParaView.
    resume : accept a folder holding this series already, for a run resumed from a checkpoint:
        :meth:`resume` (instead of ``open``) keeps its frames up to the checkpoint's time and
        continues it. ``open`` still refuses to overwrite it.
    walls : also write the scene's walls at every frame, when it has any (default True): a series
        ``<name>_walls.pvd`` of ``<name>_walls_000000.vtp``, ... with each plane as a rectangle over
        the region of the spheres and each cylinder as a tube, where each stands at the frame's time
        (pistons, vibrated plates and servo lids moved, drums turned), with cell data ``wall`` and
        ``force`` (the spheres' push on the wall); see :mod:`demkit.io.walls`. Written only by a
        Simulation (``write``), which knows the scene.
    measures : per-sphere measurements to add to every frame (:func:`demkit.measure.sphere_arrays`):
        ``"pressure"`` (array ``pressure_volume``: each sphere's share of the pressure times the
        volume), ``"coordination"`` (contacts of each sphere), ``"field"`` (``local_field``, the
        magnetic field at each centre). ~1 us a pair per frame (0.5 s for 8000 dipoles cut at
        4 d): meant for frames some hundred steps apart.
    """

    def __init__(self, folder, every, compress=False, trails=True, fields=None, dtype="float64",
                 name="particles", overwrite=False, contacts=False, resume=False, measures=(), walls=True):
        self.every = writer_interval(every, overwrite, resume, "series")
        self._frames = FrameWriter(compress, dtype)
        if fields is not None:
            choose_fields(VECTOR_FIELDS, fields)  # reject unknown names now
        self._requested = fields
        from ..measure import SPHERE_MEASURES, known_sphere_measures
        self.measures = measures = known_sphere_measures(measures)
        self._measured = tuple(SPHERE_MEASURES[m] for m in measures)  # (array name, components)
        self.series = SeriesFolder(folder, name, overwrite, resume=resume)
        self.contact_series = (SeriesFolder(folder, name + "_contacts", overwrite, extension="vtp", resume=resume)
                               if contacts else None)
        self.wall_series = (SeriesFolder(folder, name + "_walls", overwrite, extension="vtp", resume=resume)
                            if walls else None)
        self._walls = None  # the scene's WallSurfaces, when it has walls (set by open/resume)
        self._name, self._folder, self._overwrite, self._resume = name, folder, overwrite, resume
        self.box_series = None  # the outline of a deforming box at every frame (set by open/resume)
        self.trails = bool(trails)
        self._trails = None
        self.fields = None
        self._closed = False
        self._finalizer = None

    # ---- writer protocol ---------------------------------------------------------------------
    def open(self, simulation):
        """Start the series for ``simulation``'s scene (called by the simulation)."""
        surfaces = self._wall_surfaces(simulation.scene)
        if surfaces is not None:
            self.wall_series.check_unclaimed()
        boxes = self._box_series(simulation.scene)
        if boxes is not None:
            boxes.check_unclaimed()
        self.begin(simulation.scene.particles, **self._scene_options(simulation.scene))
        self._walls, self.box_series = surfaces, boxes

    def resume(self, simulation):
        """Continue the series in the folder for ``simulation`` resumed from a checkpoint at
        ``simulation.time``, instead of :meth:`open` (see :meth:`continue_series`). Returns True
        when the current state is to be written now (call :meth:`write`), False when the series
        has a frame at that time already."""
        surfaces = self._wall_surfaces(simulation.scene)
        if surfaces is not None:
            kept, later = self.wall_series.frames_until(float(simulation.time), missing_ok=True)
        boxes = self._box_series(simulation.scene)
        if boxes is not None:
            box_kept, box_later = boxes.frames_until(float(simulation.time), missing_ok=True)
        write = self.continue_series(simulation.time, simulation.scene.particles,
                                     **self._scene_options(simulation.scene))
        if surfaces is not None:
            self.wall_series.take_over(kept, later)
            self._walls = surfaces
        if boxes is not None:
            boxes.take_over(box_kept, box_later)
            self.box_series = boxes
        return write

    def write(self, simulation):
        """Write the current state of ``simulation`` as the next frame (called by the simulation)."""
        force = torque = None
        if self.fields is None:
            raise ValueError("the simulation must call open() before write()")
        if "force" in self.fields or "torque" in self.fields:
            force, torque = simulation.scene.forces()
        measured = None
        if self.measures:
            from ..measure import sphere_arrays
            measured = sphere_arrays(simulation.scene, self.measures)
        self.write_state(simulation.time, simulation.scene.particles, force, torque, measured)
        if self.contact_series is not None:
            contacts = simulation.scene.contacts()
            particles = simulation.scene.particles
            self.contact_series.add_frame(simulation.time, lambda path: contacts.write_vtk(
                path, particles, compress=bool(self._frames.compression)))
        if self._walls is not None:
            points, connectivity, offsets, cells = self._walls.at(simulation.time)
            self.wall_series.add_frame(simulation.time, lambda path: write_vtp_polygons(
                path, points, connectivity, offsets, cells, compress=bool(self._frames.compression)))
        if self.box_series is not None:
            size = simulation.scene.box.size_at(float(simulation.time))
            self.box_series.add_frame(simulation.time, lambda path: write_outline(
                path, size, simulation.time, compress=bool(self._frames.compression)))

    def _wall_surfaces(self, scene):
        """The scene's walls as surfaces (demkit.io.walls), or None: no walls, or not asked for."""
        if self.wall_series is None:
            return None
        surfaces = WallSurfaces(scene)
        if not surfaces.walls:
            return None
        self.wall_series.box = getattr(scene, "box", None)
        return surfaces

    def _box_series(self, scene):
        """The series of a deforming box's outline (demkit.io.box_outline), or None: the box does not deform."""
        box = getattr(scene, "box", None)
        if box is None or getattr(box, "deform", None) is None:
            return None
        return SeriesFolder(self._folder, self._name + "_box", self._overwrite, extension="vtp", resume=self._resume)

    def close(self):
        """Finish the series: write the trails file (once). The frames and .pvd are complete already."""
        if self._finalizer is not None:
            self._finalizer()
        self._closed = True

    @staticmethod
    def _scene_options(scene):
        return {"has_force": bool(scene.interactions),
                "has_torque": any(inter.torque for inter in scene.interactions),
                "box": getattr(scene, "box", None)}

    # ---- lower-level use (without a Simulation) -----------------------------------------------
    def begin(self, particles, has_force=False, has_torque=False, box=None):
        """Choose the fields for ``particles`` and claim the folder; ``box`` (a demkit.Box or None)
        goes into the .pvd. Raises ValueError if this writer was used before or the series exists
        (another run started writing it, or it is there to be resumed)."""
        self._check_unused()
        self.series.check_unclaimed()
        if self.contact_series is not None:
            self.contact_series.check_unclaimed()
        self._start(particles, has_force, has_torque, box)

    def continue_series(self, time, particles, has_force=False, has_torque=False, box=None):
        """Take over the series in the folder (writer made with ``resume=True``) to continue it
        from ``time`` with ``particles``, instead of :meth:`begin`.

        Keeps the frames at times <= ``time`` (relative tolerance 1e-12), deletes the later ones
        (and frame files no .pvd lists numbered after them, temporary files of an interrupted
        write and the trails file), rewrites the .pvd atomically and numbers new frames after the
        kept ones; the contact series likewise. The trails are rebuilt from the kept frames (each
        is read once). Returns True when the state at ``time`` is to be written next, False when
        the last kept frame is at ``time`` already. Raises ValueError when the folder holds no
        such series, the writer was not made with ``resume=True``, or the kept frames carry other
        fields than this writer would write.
        """
        self._check_unused()
        time = float(time)
        # at t = 0 (a run killed between its first checkpoint and its first frame) there may be
        # nothing to continue yet: the series starts afresh
        kept, later = self.series.frames_until(time, missing_ok=time == 0.0)
        if not self.series.resume:
            raise ValueError(f"folder {self.series.folder} holds series {self.series.name!r}: make the "
                             f"VTKWriter with resume=True to continue it")
        if self.contact_series is not None:
            contacts_kept, contacts_later = self.contact_series.frames_until(time, missing_ok=True)
        self._start(particles, has_force, has_torque, box)
        try:
            self._check_kept_fields(kept, particles)
            for t, name in kept if self._trails is not None else ():
                position, data = read_frame(self.series.folder / name)
                self._trails.add(t, data["id"], data["radius"], position, data.get("image"))
        except BaseException:
            self.fields = None  # nothing taken over: the writer may be used again
            if self._finalizer is not None:
                self._finalizer.detach()
            self._trails = self._finalizer = None
            raise
        self.series.take_over(kept, later)
        if self.contact_series is not None:
            self.contact_series.take_over(contacts_kept, contacts_later)
        tolerance = TIME_TOLERANCE * abs(time)
        return not (kept and abs(max(t for t, _ in kept) - time) <= tolerance)

    def write_state(self, time, particles, force=None, torque=None, measured=None):
        """Write ``particles`` at ``time`` as the next frame; ``force``/``torque`` (N,3) are needed
        only when those fields are written, ``measured`` (``demkit.measure.sphere_arrays``) only
        with ``measures``. Returns the .vtu path."""
        if self.fields is None:
            raise ValueError("call begin() (or let a Simulation call open()) before writing")
        if self._closed:
            raise ValueError("this VTKWriter is closed")
        data = self._point_data(particles, {"force": force, "torque": torque})
        for name, _ in self._measured:
            if measured is None or name not in measured:
                raise ValueError(f"{name} must be given to write_state (measured=dk.measure.sphere_arrays(scene, "
                                 f"{list(self.measures)})): the writer writes it")
            data[name] = measured[name]
        path = self.series.add_frame(time, lambda p: self._frames.write(p, particles.position, data))
        if self._trails is not None:
            self._trails.add(time, particles.ids, particles.radius, particles.position,
                             getattr(particles, "image", None))
        return path

    def planned_output(self, frames, particles, contacts_per_particle=3.0):
        """(files, bytes) that writing ``frames`` more frames of ``particles`` adds, estimated.

        Counts the frame files, the .pvd (created or grown by ~90 bytes per frame), the trails
        file (written at close; it holds every frame of the run) and, with ``contacts=True``, the
        contact frames (``contacts_per_particle`` contacts per sphere; 3 in a dense packing).
        The walls' frames are counted once the writer is opened on its scene. The fields are this
        writer's once it is opened; before that every field the particles
        have plus force, and torque when they spin. Sizes are those of uncompressed output: with
        compression the files are 20-30 % smaller (simulation data compresses poorly).
        """
        frames = int(frames)
        if frames < 0:
            raise ValueError(f"frames must be >= 0, got {frames}")
        n = len(particles)
        fields = self.fields
        if fields is None:
            available = [f for f in ("velocity", "angular_velocity", "dipole") if getattr(particles, f) is not None]
            available += ["force"] + ["torque"] * (particles.angular_velocity is not None)
            requested = available if self._requested is None else choose_fields(VECTOR_FIELDS, self._requested)
            fields = [f for f in available if f in requested]
        real = np.dtype(self._frames.dtype).itemsize
        index = 4 if n < 2**31 - 1 else 8
        # (components, bytes per value) of each array of a .vtu, base64-encoded with an 8-byte header
        arrays = [(3, real), (1, index), (1, index), (1, 8), (1, 8), (1, real), (1, real)]
        arrays += [(3, real)] * len(fields) + [(3, 8)] * (getattr(particles, "image", None) is not None)
        arrays += [(components, 8) for _, components in self._measured]
        frame = 250 + sum(90 + 4 * math.ceil((8 + n * c * b) / 3) for c, b in arrays)
        files, size = frames, frames * (frame + 80)
        files += not self.series.pvd.exists() and frames > 0
        if self.trails and frames > 0:
            total = len(self.series.entries) + frames  # the trails file holds every frame
            files += not self.series.trails.exists()
            size += 1500 + n * (total * (3 * 8 + 8 + 8) + 8 + 8 + 16)
        if self.contact_series is not None and frames > 0:
            c = contacts_per_particle * n
            # two points and their connectivity, an offset, 16 numbers per contact (see Contacts.write_vtk)
            size += frames * (2000 + int(c * (2 * 3 * 8 + 2 * 8 + 8 + 16 * 8)) + 90)
            files += frames + (not self.contact_series.pvd.exists())
        if self._walls is not None and frames > 0:  # (known once the writer is opened on its scene)
            points, connectivity, offsets, _ = self._walls.at(0.0, forces=False)
            size += frames * (1000 + 90 + 24 * len(points) + 8 * len(connectivity) + 40 * len(offsets))
            files += frames + (not self.wall_series.pvd.exists())
        return int(files), int(size)

    # ---- helpers -----------------------------------------------------------------------------
    def _check_unused(self):
        if self.fields is not None or self._closed:
            raise ValueError("this VTKWriter has been used already: create a new one for a new run")

    def _start(self, particles, has_force, has_torque, box):
        available = [f for f in ("velocity", "angular_velocity", "dipole")
                     if getattr(particles, f) is not None]
        available += ["force"] * has_force + ["torque"] * has_torque
        self.fields = choose_fields(available, self._requested)
        self.series.box = box
        if self.contact_series is not None:
            self.contact_series.box = box
        if self.trails:
            self._trails = _Trails(self.series.trails, bool(self._frames.compression), box)
            self._finalizer = weakref.finalize(self, self._trails.write)

    def _point_data(self, particles, given):
        data = {"id": particles.ids, "radius": particles.radius, "mass": particles.mass}
        for name in self.fields:
            value = given[name] if name in given else getattr(particles, name)
            if value is None:
                raise ValueError(f"{name} must be given to write_state: the writer writes {name}")
            data[name] = value
        if getattr(particles, "image", None) is not None:
            data["image"] = np.asarray(particles.image, dtype=np.int64)
        return data

    def _check_kept_fields(self, kept, particles):
        if not kept:
            return
        _, data = read_frame(self.series.folder / kept[-1][1])
        expected = set(CONSTANT_FIELDS) | set(self.fields) | {name for name, _ in self._measured}
        expected |= {"image"} if getattr(particles, "image", None) is not None else set()
        if set(data) != expected:
            raise ValueError(
                f"the series in {self.series.folder} has the fields {sorted(set(data))} and this writer "
                f"would write {sorted(expected)}: make the VTKWriter with the fields of the series "
                f"(fields=[...]) to continue it")

    # ---- conveniences -------------------------------------------------------------------------
    @property
    def pvd(self):
        """Path of the series' .pvd collection."""
        return self.series.pvd

    @property
    def frames_written(self):
        """Number of frames in the series (those kept by a resume included)."""
        return len(self.series.entries)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
        return False

    def __repr__(self):
        return (f"VTKWriter({str(self.series.folder)!r}, every={self.every!r}, "
                f"{self.frames_written} frames written)")
