"""Simulation: advance a scene with an integrator, record a trajectory, call writers.

The time loop runs in compiled code; Python regains control only at events (writers' output
times and the end of the run). Frames are recorded inside the compiled loop. This module is the run
loop; what a run records is :mod:`demkit.recording`, why a run stops :mod:`demkit.stops` (both parts of
:class:`Simulation`), what it returns :mod:`demkit.trajectory`.
"""
from __future__ import annotations

import math
import signal
import threading
import time
import warnings

import numba
import numpy as np

from . import checks, guards
from .engine.notice import compile_estimate, compile_notice
from .engine.state import INNER_STEPS, LAST_SORT, OK, REBUILDS, RUN_START
from .engine.threads import ThreadChoice
from .engine.tiers import TierChoice
from .notes import RunNotes, say as say_notes
from .progress import Progress, check_progress
from .recording import LARGE_OUTPUT_BYTES, LARGE_OUTPUT_FILES, LargeOutputWarning, Recording, _frame_of  # noqa: F401
from .stops import SimulationError, Stops  # noqa: F401 (demkit.simulation.SimulationError, as before)
from .trajectory import Trajectory  # noqa: F401 (demkit.simulation.Trajectory, as before)

#: wall-clock seconds between the compiled loop's returns to Python (signals, writers, guards)
CHUNK_SECONDS = 0.2
#: ... and at least this many times what the last return to Python took to copy the arrays back to
#: the user's order and check them (~0.1 s for a million spheres: chunks of 0.2 s doubled the cost
#: of a step)
CHUNK_OVERHEAD_RATIO = 20.0


class CheckpointWarning(UserWarning):
    """A checkpoint could not be written (the run goes on; the previous checkpoint is kept)."""


class Simulation(Recording, Stops):
    """Advance ``scene`` with ``integrator``.

    writers : objects with ``every`` (a time interval) and ``open(simulation)``,
        ``write(simulation)`` and ``close()``; they are called at the start of the first run and
        then every ``every`` time units (rounded to whole steps). Optional: ``resume(simulation)``
        (continue an existing output after :meth:`resume`; returns True when the current state
        must be written), ``planned_output(frames, particles)`` ((files, bytes), for the
        warning about large outputs) and ``statistics(since)`` (a dict added to :attr:`statistics`
        at the end of each run, covering its samples from time ``since``: a :class:`demkit.StressSeries`
        gives ``statistics["stress"]``, the run's mean stress).
    checkpoint : a :class:`demkit.Checkpoint` (state saved every so often, at the end of every
        run and on Ctrl-C; :meth:`resume` continues from it bit for bit), or None.
    max_energy_growth : None, or stop the run (SimulationError) when total + dissipated energy has
        grown by more than this fraction of the energy scale (the sum of the magnitudes of the
        kinetic, rotational and potential energies at the start) without a source: a guard for
        conservative and dissipative scenes, checked every chunk (about 0.2 s of wall time) and
        at every recorded frame. Leave None for scenes driven from outside.
    notes : True (default): at the end of a run, say on stderr what a careful user would want to
        know (overlaps of more than a few percent of the radius, an energy balance drifting by more
        than 1 %; see :mod:`demkit.notes`); False: keep the notes in ``statistics["notes"]`` only
        (studies that run a scene at coarse steps on purpose).

    Raises ValueError (before anything runs) for a time step too large for any stiff effect of the
    scene (contacts at the speeds present, dipoles at the closest approach, fields, spins), a
    contact too soft to hold the magnets (:func:`demkit.guards.before_stepping`), and anything the
    integrator cannot do with the scene; :func:`demkit.guards.while_stepping` re-checks what
    changes at the start of every run and every chunk.

    The compiled loop hands control back to Python about every :data:`CHUNK_SECONDS` of wall time,
    or :data:`CHUNK_OVERHEAD_RATIO` times what such a return takes, whichever is longer (at step
    boundaries, which changes no result): Ctrl-C then ends a run cleanly (see :meth:`run`).
    """

    def __init__(self, scene, integrator, writers=(), checkpoint=None, max_energy_growth=None, notes=True):
        from .checkpoint import Checkpoint
        from .integrators import Integrator
        from .scene import Scene
        if not isinstance(scene, Scene):
            raise TypeError(f"scene must be a demkit.Scene, got {type(scene).__name__}")
        if isinstance(integrator, type) and issubclass(integrator, Integrator):
            raise TypeError(f"integrator must be an instance with its time step, e.g. "
                            f"{integrator.__name__}(dt=...), not the class {integrator.__name__}")
        if not isinstance(integrator, Integrator):
            raise TypeError(f"integrator must be a demkit integrator (VelocityVerlet(dt=...), ...), "
                            f"got {integrator!r}")
        if checkpoint is not None and not isinstance(checkpoint, Checkpoint):
            raise TypeError(f"checkpoint must be a demkit.Checkpoint or None, got {checkpoint!r}")
        if max_energy_growth is not None:
            max_energy_growth = checks.positive("max_energy_growth", max_energy_growth)
            if scene.heat_baths:
                raise ValueError(f"max_energy_growth cannot watch a scene with {scene.heat_baths[0]!r}: its bath gives "
                                 f"and takes energy, so the total does not keep")
            moving = [e for e in scene.effects if hasattr(e, "surface_speed") and e.surface_speed() > 0.0]
            if moving:
                raise ValueError(f"max_energy_growth cannot watch a scene with {moving[0]!r}: a moving wall works on "
                                 f"the spheres, so the total does not keep")
        self.scene = scene
        self.integrator = integrator
        self.writers = list(writers)
        for w in self.writers:
            missing = [m for m in ("every", "open", "write", "close") if not hasattr(w, m)]
            if missing:
                raise TypeError(f"writer {w!r} lacks {', '.join(missing)} (see demkit.VTKWriter)")
        self.checkpoint = checkpoint
        self.max_energy_growth = max_energy_growth
        self.step = 0
        self.trajectory = None
        self.statistics = {}
        self._run_started = None  # the time the last run started at (what writers' statistics cover)
        if not isinstance(notes, bool):
            raise TypeError(f"notes must be True or False, got {notes!r}")
        self.notes = notes
        self.energy_origin = None  # (total + dissipated, scale) at the start, for max_energy_growth
        self.resumed_meta = None  # what a resumed checkpoint says about the run that wrote it
        self._notes = self._notes_seed = None  # the running run's notes; a resumed run's saved figures
        self._opened = False
        self._last_frame = None  # the last recorded frame, reused as the first of a continuing run
        self._rate = None  # measured steps per second of wall time (sizes the compiled chunks)
        self.forces_valid = False  # do the scene's force arrays hold the forces of its current state?
        with compile_notice():  # the guards may compile demkit's cell lists (once per install)
            guards.before_stepping(scene, integrator)
            integrator.check(scene)
        self._threads = ThreadChoice(scene, integrator.template)
        self._tiers = TierChoice(scene, f"{integrator.template}_steps")

    @property
    def time(self):
        """Simulation time: steps taken times dt."""
        return self.step * self.integrator.dt

    def _steps(self, interval, what):
        dt = self.integrator.dt
        interval = checks.number(what, interval)
        if not math.isfinite(interval) or interval <= 0:
            raise ValueError(f"{what} must be a positive finite time, got {interval}")
        steps = int(round(interval / dt))
        if steps < 1:
            raise ValueError(f"{what} = {interval:.6g} is shorter than the time step dt = {dt:.6g}")
        return steps

    def run(self, duration=None, record_every=None, until=None, progress=None):
        """Advance by ``duration`` (rounded to whole steps), or up to the time ``until``, and return
        the recorded Trajectory.

        record_every : time between recorded frames (rounded to whole steps); None records only the
            start and the end. The first frame is the state at the start of this run.
        progress : None (default): a progress bar on stderr (simulated time, steps per second,
            time left) when stderr is a terminal and the run looks like taking more than about 2 s
            of wall time; True: a bar always; False: never (see :mod:`demkit.progress`). The bar
            is updated between compiled chunks (about every 0.2 s) and closed however the run ends.
        When the scene's kernels must first be compiled (not in the on-disk cache), a line on stderr
        says so, and another how long it took. A simulation resumed at the time ``until`` already
        (a finished checkpointing script run again) steps and writes nothing and returns the one
        frame of its state, with a note on stderr.

        Ctrl-C (SIGINT) ends the run at the next chunk boundary (within about 0.2 s): the frames
        recorded so far and the state reached are kept in ``trajectory`` (last frame: the state at
        the interruption), ``time``/``step`` say where it stopped, writers are closed, a
        checkpoint is written when there is one, and KeyboardInterrupt is raised again.
        """
        check_progress(progress)
        nsteps = self._run_length(duration, until)
        if nsteps == 0:
            return self._already_there()
        stride = nsteps if record_every is None else self._steps(record_every, "record_every")
        box = self.scene.box
        if box is not None and getattr(box, "deform", None) is not None:  # long enough to the run's end
            from .deformed import check_run
            check_run(box, max(self.scene.reaches, default=0.0), self.time, (self.step + nsteps) * self.integrator.dt)
        # Ctrl-C is caught from here to the run's end (CatchInterrupt): also while the run prepares and
        # after its last chunk, where compiled calls (the first frame, the writers' end frames) run. A
        # KeyboardInterrupt raised inside numba's call machinery came out as a TypeError.
        with CatchInterrupt() as interrupt, \
                compile_notice(lambda: compile_estimate(self.scene.plan, "run", self._tiers.tier)) as notice:  # ended after the first chunk
            return self._advance(nsteps, stride, progress, notice, interrupt)

    def _already_there(self):
        """run(until=t) of a simulation resumed at t: the script that checkpoints and resumes (see
        docs/restart.md) was run again after it finished. Nothing is stepped or written; the
        trajectory is the one frame of the state reached, and a note says so."""
        say_notes([f"t = {self.time:.6g} was already reached (resumed from a checkpoint at the run's end): "
                   f"nothing to run; delete the checkpoint to start over"])
        self._prepare()
        record = self._allocate(1)
        self._threads.kernels.record_frame(0, self.scene.state, record)
        self._last_frame = _frame_of(record, 0)
        self._measure(0, 0.0, 0)
        return self._keep(record, self.step, [0])

    def _advance(self, nsteps, stride, progress, notice, interrupt):
        """The body of :meth:`run` (``interrupt``: its CatchInterrupt)."""
        nframes = nsteps // stride + 1
        extra_final = nsteps % stride != 0
        self._check_record_size(nframes + extra_final)
        scene = self.scene
        forces_ready = self._prepare()
        state = scene.state
        kern = self._threads.kernels  # the module of the runs' loops (record_frame compiled once)
        # the last run's frames (returned to the caller, who keeps them or not) are let go before
        # this run's are allocated: two runs' frames at once were the peak memory of runs of 10^6 spheres
        self.trajectory = self._recording = None
        record = self._allocate(nframes + extra_final)
        if forces_ready and self._last_frame is not None:
            for row, value in zip(record, self._last_frame):
                if value is not None:
                    row[0] = value
        else:
            kern.record_frame(0, state, record)
        self._recording = (record, self.step, stride)  # the frames so far, for Checkpoint.before_save
        # the run's notes (from the checkpoint's figures after a resume: they cover the whole run),
        # and how many of its frames they have read (a checkpoint reads those recorded since)
        self._notes = [RunNotes(scene, self._notes_seed), 0]
        self._notes_seed = None
        writer_steps = [self._steps(w.every, "writer interval") for w in self.writers]
        self._warn_large_output(nsteps, writer_steps)
        if not self._opened and self.checkpoint is not None:
            self._save_checkpoint()  # before any output: no series on disk without a checkpoint
        self._open_writers()
        if self.energy_origin is None and self.max_energy_growth is not None:
            self.energy_origin = self._energy_now(scale=True)
        check_steps = self._steps(self.checkpoint.every, "checkpoint interval") \
            if self.checkpoint is not None and self.checkpoint.every is not None else None
        if self.checkpoint is not None:
            self.checkpoint.last_save = time.perf_counter()
        servo = getattr(getattr(scene.box, "deform", None), "servo", None)  # a box driven to a pressure
        servo_steps = [self._steps(servo.every, "PressureServo every")] if servo is not None else []
        if servo_steps and self.step % servo_steps[0] == 0 and not (
                len(scene.box.deform.history) and scene.box.deform.history[-1, 0] == self.time):
            servo.update(self)  # (its first rates, or those a run ending on its grid left unset)
        start_step = self.step
        self._run_started = self.time  # (writers' statistics cover this run: see _measure)
        rebuilds = int(scene.counters[REBUILDS])
        clock = time.perf_counter()
        done = 0
        chunk_steps = 16 if self._rate is None else max(1, int(self._rate * CHUNK_SECONDS))
        guarding = 0.0
        dt = self.integrator.dt
        bar = Progress(nsteps, progress, desc="demkit run", unit="step", unit_scale=True, scale=dt,
                       start=self.time, span=self.time + nsteps * dt)
        with _Stepping(scene), bar, _MeasuredOnStop(self, start_step, clock, rebuilds):
            while done < nsteps:
                chunk = min(nsteps - done, chunk_steps)
                for every in writer_steps + ([check_steps] if check_steps else []) + servo_steps:
                    chunk = min(chunk, every - (start_step + done) % every)
                self._switch_tier(nsteps - done)
                loop, chunk = self._threads.loop(chunk, nsteps - done)
                bar.extra = f"{self._threads.label}, tier {self._tiers.tier}"
                began = time.perf_counter()
                try:
                    failed = loop(chunk, done, stride, self.integrator.dt, forces_ready, state, record)
                finally:
                    returned = time.perf_counter()
                    scene.pull()
                    between = guarding + time.perf_counter() - returned  # O(N) copies and checks: size the chunks
                forces_ready = self.forces_valid = True
                if failed >= 0:
                    self._fail(done + failed + 1, start_step, stride, record)
                done += chunk
                self.step = start_step + done
                scene.time = self.time  # (the loops keep the clock only where walls move)
                seconds = time.perf_counter() - began
                first = self._rate is None  # the first chunk compiles (or loads) the code: not run time
                if not first:  # (counted, a cold install's compile made a short run compile tier 2 too)
                    self._tiers.ran(seconds)
                probe = self._threads.probing  # a probe's rate does not size the next chunks
                self._threads.measured(chunk, seconds, first=first)
                if not probe:
                    chunk_steps = self._next_chunk(chunk, seconds, chunk_steps, between)
                notice.end()
                bar.update(done)
                if servo_steps and self.step % servo_steps[0] == 0:  # new rates for the next stretch
                    servo.update(self)
                for w, ws in zip(self.writers, writer_steps):
                    if self.step % ws == 0:
                        w.write(self)
                guarding = time.perf_counter()
                self._check_while_stepping(done, start_step, stride, record)
                guarding = time.perf_counter() - guarding
                # the last chunk's state is saved after the end frame is written (below): saved
                # here, a kill before that frame left a checkpoint at the run's end and no end frame
                if self.checkpoint is not None and done < nsteps and (
                        (check_steps and self.step % check_steps == 0) or self.checkpoint.due(time.perf_counter())):
                    self._save_checkpoint()
                if interrupt.caught and done < nsteps:
                    self._interrupted(done, start_step, stride, record)
        if extra_final:
            kern.record_frame(nframes, state, record)
        self._write_end(nsteps, writer_steps)
        self._measure(nsteps, time.perf_counter() - clock, int(scene.counters[REBUILDS]) - rebuilds)
        steps = np.arange(nframes) * stride
        if extra_final:
            steps = np.append(steps, nsteps)
        self._keep(record, start_step, steps)
        notes = self._read_notes(len(steps), nsteps - self._notes[1] * stride)
        self.statistics.update(notes.figures(), notes=notes.notes(dt))
        if self.notes:
            say_notes(self.statistics["notes"])
        self._last_frame = _frame_of(record, len(steps) - 1)
        if self.checkpoint is not None and self.checkpoint.saved_step != self.step:
            self._save_checkpoint()
        self._notes, self._last_notes = None, notes.state()
        if interrupt.caught:  # Ctrl-C during the last chunk or the end's work: the run is complete, still honour it
            self._close_on_interrupt()
            raise KeyboardInterrupt(f"run interrupted at its end (step {self.step}, t = {self.time:.6g})")
        return self.trajectory

    def resume(self, path=None):
        """Continue from a checkpoint file (default: this simulation's ``checkpoint.path``): the
        scene's state, the step count and the integrator's working arrays become the saved ones, so
        that the next :meth:`run` gives bit for bit what the interrupted run would have given.
        Writers with a ``resume`` method take over their existing output up to the checkpoint's
        time. The scene must be built as for the original run (same particles, interactions,
        box, thread count) and the integrator the same; otherwise, or for a truncated, corrupted
        or foreign file, ValueError and nothing is changed. Returns self."""
        from . import checkpoint as ckpt
        if path is None:
            if self.checkpoint is None:
                raise ValueError("resume() needs a path, or a Simulation made with checkpoint=dk.Checkpoint(...)")
            path = self.checkpoint.path
        meta, arrays = ckpt.load(path)
        scene = self.scene
        scene.reserve_stages(self.integrator.stage_arrays)
        ckpt.check_compatible(meta, arrays, self, path)
        ckpt.restore(scene, arrays)
        self.resumed_meta = meta  # what the checkpoint says about the run that wrote it
        self._notes_seed = meta.get("notes")  # the next run's notes go on from the saved figures
        scene.set_time_step(self.integrator.contact_step)
        scene.counters[INNER_STEPS] = self.integrator.inner
        self.step = meta["step"]
        scene.time = self.time  # the state saved is that of this time (moving walls stand where they did then)
        self.forces_valid = bool(meta.get("forces_valid"))
        origin = meta.get("energy_origin")
        self.energy_origin = tuple(origin) if origin is not None else None
        scene.stepped_by = self
        self._last_frame = None
        self._open_writers(resuming=True)
        return self

    def _open_writers(self, resuming=False):
        """Once per simulation: start the writers' output with the current state, or (``resuming``)
        let those that can continue their existing output up to the current time. A resumed series
        gets the current state only when it is due on the writer's grid (a checkpoint saved between
        two frames, as time-based ones are, adds no frame an uninterrupted run would not have)."""
        if self._opened:
            return
        for w in self.writers:
            if resuming and hasattr(w, "resume"):
                if w.resume(self) and self.step % self._steps(w.every, "writer interval") == 0:
                    w.write(self)
            else:
                w.open(self)
                w.write(self)
        self._opened = True

    def _run_length(self, duration, until):
        if (duration is None) == (until is None):
            raise ValueError("give run() either a duration or until= (an end time), not both" if duration is not None
                             else "give run() a duration, or until= (an end time)")
        if duration is not None:
            return self._steps(duration, "duration")
        end = checks.number("until", until)
        if not math.isfinite(end):
            raise ValueError(f"until must be a finite time, got {end}")
        steps = int(round(end / self.integrator.dt)) - self.step
        if steps == 0 and self.resumed_meta is not None:
            return 0  # resumed at the end time already: a finished script run again (see run())
        if steps < 1:
            raise ValueError(f"until = {end:.6g} is not after the current time {self.time:.6g} (dt = "
                             f"{self.integrator.dt:.6g})")
        return steps

    def _prepare(self):
        """Before a run: check and prepare the scene unless it is exactly as this simulation's last
        run (or resume) left it; then the forces of the last evaluation are still valid and nothing
        is recomputed (O(N) re-entry). Returns whether the forces are ready."""
        scene = self.scene
        continuing = scene.in_sync and scene.stepped_by is self
        if scene.time != self.time:  # another simulation moved the scene's clock on
            travelling = [e for e in scene.effects if getattr(e, "travels", False)]
            if travelling:
                raise ValueError(f"the scene's clock stands at t = {scene.time:.6g} (another Simulation stepped it), this "
                                 f"Simulation's at t = {self.time:.6g}: {travelling[0]!r} would jump to where it stands "
                                 f"then. Go on with the Simulation that stepped the scene, or set scene.time = "
                                 f"{self.time!r} to move the wall back on purpose")
        scene.time = self.time  # the clock moving walls follow
        if not continuing:
            self.forces_valid = False
            scene.validate()
            problem = guards.while_stepping(scene, self.integrator)  # the state may have changed since __init__
            if problem:
                raise ValueError(problem)
            self.energy_origin = None  # the user changed the state: the energy guard restarts
            self._last_frame = None
            scene.counters[LAST_SORT] = min(scene.counters[LAST_SORT], self.step)  # another simulation's count
        # every run: another Simulation of the same scene may have changed them since the last one
        scene.reserve_stages(self.integrator.stage_arrays)
        scene.set_time_step(self.integrator.contact_step)
        scene.counters[INNER_STEPS] = self.integrator.inner
        scene.counters[RUN_START] = self.step
        scene.status[:] = OK
        if not continuing:
            scene.push()
        scene.stepped_by = self
        return continuing and self.forces_valid

    def _next_chunk(self, steps, seconds, current, between=0.0):
        """Steps of the next compiled chunk: about CHUNK_SECONDS of wall time, or CHUNK_OVERHEAD_RATIO
        times ``between`` (the seconds the last return to Python spent copying the arrays back and
        checking them; writers and checkpoints, which have their own schedules, not counted) when
        that is longer; growing at most 4x."""
        if seconds > 0:
            rate = steps / seconds
            self._rate = rate if self._rate is None else 0.5 * (self._rate + rate)
        span = max(CHUNK_SECONDS, CHUNK_OVERHEAD_RATIO * between)
        target = int(self._rate * span) if self._rate else 4 * current
        return max(1, min(target, 4 * current))

    def _energy_now(self, scale=False):
        """Total + dissipated energy now (and the energy scale), from the kernels' state."""
        scene = self.scene
        out = np.zeros(2 + len(scene.energy_kinds))
        scene.kernels.energies_of(scene.state, out)
        total = float(out.sum()) + scene.dissipated
        return (total, float(np.abs(out).sum())) if scale else total

    def _check_while_stepping(self, done, start_step, stride, record):
        """Guards at a chunk boundary: what changes during a run (:func:`demkit.guards.while_stepping`:
        speeds against Hertz contacts, spins, magnets against soft contacts) and energy growth."""
        problem = guards.while_stepping(self.scene, self.integrator)
        if problem:
            frames = done // stride + 1
            self._keep(record, start_step, np.arange(frames) * stride)
            raise SimulationError(
                f"the run stopped at step {self.step} (t = {self.time:.6g}): {problem} The {frames} frames recorded "
                f"so far are kept in simulation.trajectory (see docs/stability.md).",
                step=self.step, time=self.time, particle=None, trajectory=self.trajectory)
        if self.max_energy_growth is None or self.energy_origin is None:
            return
        origin, scale = self.energy_origin
        now = self._energy_now()
        growth = (now - origin) / scale if scale > 0 else 0.0
        if growth > self.max_energy_growth:
            frames = done // stride + 1
            self._keep(record, start_step, np.arange(frames) * stride)
            raise SimulationError(
                f"total + dissipated energy grew by {growth:.3g} of the energy scale {scale:.6g} (from {origin:.6g} "
                f"to {now:.6g}) by step {self.step} (t = {self.time:.6g}), more than max_energy_growth = "
                f"{self.max_energy_growth:g}: the run gains energy from nowhere. Use a smaller time step "
                f"(dt = {self.integrator.dt:.6g}) or stiffer contacts. The {frames} frames recorded so far are "
                f"kept in simulation.trajectory.",
                step=self.step, time=self.time, particle=None, trajectory=self.trajectory)

    def _interrupted(self, done, start_step, stride, record):
        """Ctrl-C inside a run: keep what was done, save, close, re-raise."""
        frames = done // stride + 1
        steps = list(np.arange(frames) * stride)
        if done % stride:
            self._threads.kernels.record_frame(frames, self.scene.state, record)
            steps.append(done)
        self._keep(record, start_step, steps)
        self._last_frame = _frame_of(record, len(steps) - 1)
        saved = ""
        if self.checkpoint is not None and self._save_checkpoint():
            saved = f"; state saved in {self.checkpoint.path}"
        self._close_on_interrupt()
        raise KeyboardInterrupt(f"run interrupted at step {self.step} (t = {self.time:.6g}): the {len(steps)} frames "
                                f"so far are in simulation.trajectory{saved}")

    def continue_notes(self):
        """Let the next :meth:`run` go on with the notes of the last one (one set of notes for a run
        made of several calls, as ``demkit run`` makes it)."""
        self._notes_seed = getattr(self, "_last_notes", None)

    def notes_so_far(self):
        """The figures of the running run's notes (:meth:`demkit.notes.RunNotes.state`), after reading
        the frames it recorded since they were last read; None outside a run. A checkpoint keeps
        them: the notes of a run resumed from it cover the whole run, not the part after the resume."""
        if getattr(self, "_notes", None) is None or self._recording is None:
            return None
        record, first, stride = self._recording
        count = min((self.step - first) // stride + 1, len(record[0]))
        return self._read_notes(count, (count - self._notes[1]) * stride).state()

    def _read_notes(self, count, steps):
        """The running run's notes after reading its frames from the last read up to frame ``count``
        (``steps`` of the run's steps: the notes' sampling budget)."""
        notes, read = self._notes
        if count > read:
            record, first, stride = self._recording
            times = np.minimum(first + np.arange(read, count) * stride, self.step) * self.integrator.dt
            notes.frames(record[0][read:count], record[4][read:count], max(steps, 0), times)
            self._notes[1] = count
        return notes

    def _save_checkpoint(self):
        """Save the checkpoint; a failure to write it (a full disk, ...) must not cost the run: the
        previous checkpoint is kept, a CheckpointWarning says why, and the run goes on."""
        try:
            self.checkpoint.save(self)
            return True
        except OSError as err:
            warnings.warn(f"could not save the checkpoint {self.checkpoint.path} at step {self.step} "
                          f"(t = {self.time:.6g}): {err}; the previous checkpoint is kept and the run goes on",
                          CheckpointWarning, stacklevel=3)
            return False

    def _write_end(self, nsteps, writer_steps):
        """The run's end state goes into every writer's output, also when the run ends between two
        of its frames (a duration that is not a whole number of its intervals)."""
        for w, ws in zip(self.writers, writer_steps):
            if nsteps > 0 and self.step % ws != 0:
                w.write(self)

    def _close_on_interrupt(self):
        for w in self.writers:
            try:
                w.close()
            except Exception:  # closing must not hide the interruption  # noqa: BLE001
                pass

    def __repr__(self):
        extra = f", checkpoint={self.checkpoint!r}" if self.checkpoint is not None else ""
        return (f"Simulation({len(self.scene.particles)} particles, {self.integrator!r}, step {self.step}, "
                f"t = {self.time:.6g}, {len(self.writers)} writers{extra})")

    def _measure(self, nsteps, seconds, rebuilds):
        scene = self.scene
        n = len(scene.particles)
        self.statistics = {
            "steps": nsteps, "seconds": seconds,
            "steps_per_second": nsteps / seconds if seconds > 0 else math.inf,
            "particle_steps_per_second": n * nsteps / seconds if seconds > 0 else math.inf,
            "neighbour_list_builds": rebuilds,
            "steps_per_build": nsteps / rebuilds if rebuilds else None,
            "lists": scene.neighbour_lists(), "skin": scene.skin if scene.plan.lists else None,
            **self._threads.statistics(),
            **self._tiers.statistics(),
            "chunks": scene.chunks,
        }
        started = self._run_started
        for w in self.writers:  # what a writer measured over the run (a StressSeries: the mean stress)
            if started is not None and hasattr(w, "statistics"):
                self.statistics.update(w.statistics(since=started))

    def _switch_tier(self, steps_left):
        """Between chunks: run tier 2's loops from now on when it is ready (demkit.engine.tiers)."""
        rate = self._threads.rates.get(self._threads.threads)  # measured after the first chunk (no compiling)
        seconds_left = steps_left / rate if rate else None
        modules = self._tiers.ready(seconds_left, busy=self._threads.compiling)
        if modules is not None:
            self._threads.use_modules(*modules)
            self._tiers.switched(self.step)

    def close(self):
        """Close the writers (call when done; further runs reopen nothing)."""
        for w in self.writers:
            w.close()

    # ---- helpers ----------------------------------------------------------------------------


class _MeasuredOnStop:
    """A run stopped by a SimulationError or Ctrl-C leaves ``sim.statistics`` describing its own
    steps (up to ``sim.step``), not the run before it."""

    def __init__(self, sim, start_step, clock, rebuilds):
        self.sim, self.start_step, self.clock, self.rebuilds = sim, start_step, clock, rebuilds

    def __enter__(self):
        return self

    def __exit__(self, kind, error, trace):
        if kind is not None and issubclass(kind, (SimulationError, KeyboardInterrupt)):
            sim = self.sim
            sim._measure(sim.step - self.start_step, time.perf_counter() - self.clock,
                         int(sim.scene.counters[REBUILDS]) - self.rebuilds)
        return False


class _Stepping:
    """Marks the scene as being stepped (see Scene.push); on leaving, however the run ended, the
    scene is synchronised again, and after an error it no longer counts as this run's to continue."""

    def __init__(self, scene):
        self.scene = scene
        self.threads = None

    def __enter__(self):
        self.scene.stepping = True
        self.threads = numba.get_num_threads()  # the run's chunks set it (demkit.engine.threads): given back

    def __exit__(self, kind, error, tb):
        numba.set_num_threads(self.threads)
        self.scene.stepping = False
        self.scene.pull()
        if kind is not None and not issubclass(kind, KeyboardInterrupt):
            self.scene.stepped_by = None
        return False


class CatchInterrupt:
    """Within a run: SIGINT (Ctrl-C) sets ``caught`` instead of raising wherever Python happens to
    be; the run looks at it between compiled chunks. Only in the main thread (signal handlers can
    only be set there); elsewhere Ctrl-C behaves as usual."""

    def __init__(self):
        self.caught = False
        self._previous = None

    def __enter__(self):
        if threading.current_thread() is threading.main_thread():
            try:
                self._previous = signal.signal(signal.SIGINT, self._handler)
            except ValueError:  # not the main interpreter
                self._previous = None
        return self

    def _handler(self, signum, frame):
        if self.caught and callable(self._previous):  # a second Ctrl-C: the usual behaviour, now
            self._previous(signum, frame)
        self.caught = True

    def __exit__(self, *exc):
        if self._previous is not None:
            signal.signal(signal.SIGINT, self._previous)
        return False
