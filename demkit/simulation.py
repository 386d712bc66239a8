"""Simulation: advance a scene with an integrator, record a trajectory, call writers.

The time loop runs in compiled code; Python regains control only at events (writers' output
times and the end of the run). Frames are recorded inside the compiled loop.
"""
from __future__ import annotations

import math
import time

import numba
import numpy as np

from . import guards
from .scene import energy_dict
from .state import INNER_STEPS, MOVED_TOO_FAR, OK, REBUILDS


class SimulationError(RuntimeError):
    """A run stopped because it could not be trusted (e.g. NaN or inf appeared).

    Attributes: ``step``, ``time``, ``particle`` (id), ``trajectory`` (frames recorded so far).
    """

    def __init__(self, message, step, time, particle, trajectory):
        super().__init__(message)
        self.step, self.time, self.particle, self.trajectory = step, time, particle, trajectory


class Trajectory:
    """Recorded frames of a run.

    time (T,); position, velocity (T,N,3); angular_velocity, dipole (T,N,3) or None when the scene
    has no such field; energy: dict of (T,) arrays (kinetic, rotational, magnetic, contact, ...,
    total, dissipated); angular_momentum (T,3) about the origin (orbital + spin); and the constant
    particle properties radius, mass, inertia, ids (N,). In a periodic box, positions are wrapped
    into it, ``image`` (T,N,3) holds the integer image counts and ``box`` the :class:`demkit.Box`
    (both None in open space); :meth:`unwrapped` gives continuous paths.
    """

    def __init__(self, time, position, velocity, angular_velocity, dipole, energy,
                 angular_momentum, radius, mass, inertia, ids, image=None, box=None):
        self.time = time
        self.position = position
        self.velocity = velocity
        self.angular_velocity = angular_velocity
        self.dipole = dipole
        self.energy = energy
        self.angular_momentum = angular_momentum
        self.radius, self.mass, self.inertia, self.ids = radius, mass, inertia, ids
        self.image, self.box = image, box

    def unwrapped(self):
        """Positions (T,N,3) continued across periodic boundaries: position + image * box size."""
        if self.image is None:
            return self.position
        return self.position + self.image * self.box.size

    def __len__(self):
        return len(self.time)

    @classmethod
    def concatenate(cls, parts):
        """One Trajectory from consecutive runs of one Simulation. Each later run's first frame
        repeats the previous run's last one and is dropped; a gap in time raises ValueError."""
        parts = list(parts)
        if not parts:
            raise ValueError("concatenate needs at least one trajectory")
        for before, after in zip(parts, parts[1:]):
            if after.time[0] != before.time[-1]:
                raise ValueError(f"trajectories are not consecutive: one ends at t = {before.time[-1]:.6g}, "
                                 f"the next starts at t = {after.time[0]:.6g}")

        def joined(arrays):
            return None if arrays[0] is None else np.concatenate([arrays[0]] + [a[1:] for a in arrays[1:]])

        first = parts[0]
        fields = {name: joined([getattr(p, name) for p in parts])
                  for name in ("time", "position", "velocity", "angular_velocity", "dipole", "angular_momentum",
                               "image")}
        energy = {key: joined([np.asarray(p.energy[key]) for p in parts]) for key in first.energy}
        return cls(energy=energy, radius=first.radius, mass=first.mass, inertia=first.inertia,
                   ids=first.ids, box=first.box, **fields)

    def linear_momentum(self):
        """Total linear momentum per frame, (T,3)."""
        return (self.mass[None, :, None] * self.velocity).sum(axis=1)

    def __repr__(self):
        return (f"Trajectory({len(self)} frames, {self.position.shape[1]} particles, "
                f"t = {self.time[0]:.6g} .. {self.time[-1]:.6g})")


class Simulation:
    """Advance ``scene`` with ``integrator``.

    writers : objects with ``every`` (a time interval) and ``open(simulation)``,
        ``write(simulation)`` and ``close()``; they are called at the start of the first run and
        then every ``every`` time units (rounded to whole steps).
    Raises ValueError if the time step exceeds the scene's largest safe step.
    """

    def __init__(self, scene, integrator, writers=()):
        self.scene = scene
        self.integrator = integrator
        self.writers = list(writers)
        self.time = 0.0
        self.step = 0
        self.trajectory = None
        self.statistics = {}
        self._opened = False
        guards.before_stepping(scene, integrator)
        integrator.check(scene)
        self._loop = getattr(scene.kernels, f"{integrator.template}_steps")

    def _steps(self, interval, what):
        dt = self.integrator.dt
        interval = float(interval)
        if not math.isfinite(interval) or interval <= 0:
            raise ValueError(f"{what} must be a positive finite time, got {interval}")
        steps = int(round(interval / dt))
        if steps < 1:
            raise ValueError(f"{what} = {interval:.6g} is shorter than the time step dt = {dt:.6g}")
        return steps

    def run(self, duration, record_every=None):
        """Advance by ``duration`` (rounded to whole steps) and return the recorded Trajectory.

        record_every : time between recorded frames (rounded to whole steps); None records only the
            start and the end. The first frame is the state at the start of this run.
        """
        dt = self.integrator.dt
        nsteps = self._steps(duration, "duration")
        stride = nsteps if record_every is None else self._steps(record_every, "record_every")
        scene = self.scene
        scene.validate()
        # every run: another Simulation of the same scene may have changed them since the last one
        scene.reserve_stages(self.integrator.stage_arrays)
        scene.set_time_step(self.integrator.contact_step)
        scene.counters[INNER_STEPS] = self.integrator.inner
        state = scene.state
        kern = scene.kernels
        scene.push()
        nframes = nsteps // stride + 1
        extra_final = nsteps % stride != 0
        record = self._allocate(nframes + extra_final)
        kern.record_frame(0, state, record)
        writer_steps = [self._steps(w.every, "writer interval") for w in self.writers]
        if not self._opened:
            scene.pull()
            for w in self.writers:
                w.open(self)
                w.write(self)
            self._opened = True
        start_time, start_step = self.time, self.step
        rebuilds = int(scene.counters[REBUILDS])
        clock = time.perf_counter()
        done = 0
        forces_ready = False
        while done < nsteps:
            chunk = nsteps - done
            for ws in writer_steps:
                chunk = min(chunk, ws - (start_step + done) % ws)
            try:
                failed = self._loop(chunk, done, stride, dt, forces_ready, state, record)
            finally:
                scene.pull()
            forces_ready = True
            if failed >= 0:
                self._fail(done + failed + 1, start_time, start_step, stride, record)
            done += chunk
            self.step = start_step + done
            self.time = start_time + done * dt
            for w, ws in zip(self.writers, writer_steps):
                if self.step % ws == 0:
                    w.write(self)
        if extra_final:
            kern.record_frame(nframes, state, record)
        self._measure(nsteps, time.perf_counter() - clock, int(scene.counters[REBUILDS]) - rebuilds)
        steps = np.arange(nframes) * stride
        if extra_final:
            steps = np.append(steps, nsteps)
        self.trajectory = self._trajectory(record, start_time + steps * dt)
        return self.trajectory

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
            "threads": numba.get_num_threads() if scene.parallel else 1,
            "chunks": scene.chunks if scene.parallel else 1,
        }

    def close(self):
        """Close the writers (call when done; further runs reopen nothing)."""
        for w in self.writers:
            w.close()

    # ---- helpers ----------------------------------------------------------------------------
    def _allocate(self, nframes):
        p = self.scene.particles
        n = len(p)
        shape = (nframes, n, 3)
        omega = np.zeros(shape) if p.angular_velocity is not None else np.zeros((0, 0, 3))
        dipole = np.zeros(shape) if p.dipole is not None else np.zeros((0, 0, 3))
        image = np.zeros(shape, dtype=np.int64) if p.image is not None else np.zeros((0, 0, 3), dtype=np.int64)
        energy = np.zeros((nframes, 3 + len(self.scene.energy_kinds)))
        return (np.zeros(shape), np.zeros(shape), omega, dipole, energy, np.zeros((nframes, 3)), image)

    def _trajectory(self, record, times):
        p = self.scene.particles
        t = len(times)
        pos, vel, omega, dipole, energy, momentum, image = (r[:t] for r in record)
        return Trajectory(
            time=times, position=pos, velocity=vel,
            angular_velocity=omega if p.angular_velocity is not None else None,
            dipole=dipole if p.dipole is not None else None,
            energy=energy_dict(energy[:, :-1], self.scene.energy_kinds, energy[:, -1]),
            angular_momentum=momentum, radius=p.radius.copy(), mass=p.mass.copy(),
            inertia=p.inertia.copy(), ids=p.ids.copy(), image=image if p.image is not None else None,
            box=self.scene.box)

    def _fail(self, bad_step, start_time, start_step, stride, record):
        dt = self.integrator.dt
        scene = self.scene
        p = scene.particles
        status = scene.status
        code, index = int(status[0]), int(status[1])
        status[:] = OK
        good_frames = (bad_step - 1) // stride + 1
        self.trajectory = self._trajectory(record, start_time + np.arange(good_frames) * stride * dt)
        self.step = start_step + bad_step
        self.time = start_time + bad_step * dt
        kept = (f"The {good_frames} frames recorded before it are kept in simulation.trajectory")
        if code == MOVED_TOO_FAR:
            k = int(scene.arrays["tag"][index])
            speed = float(np.linalg.norm(p.velocity[k]))
            raise SimulationError(
                f"particle id {p.ids[k]} moved more than the neighbour-list skin ({scene.skin:.6g}) between two "
                f"rebuilds at step {self.step} (t = {self.time:.6g}; speed {speed:.6g}, so {speed * dt:.6g} per "
                f"step): the lists could miss pairs and contacts could be stepped over. Use a smaller time step "
                f"(dt = {dt:.6g}) or a larger skin. {kept}.",
                step=self.step, time=self.time, particle=int(p.ids[k]), trajectory=self.trajectory)
        arrays = [p.position, p.velocity] + ([p.angular_velocity] if p.angular_velocity is not None else [])
        bad = np.zeros(len(p), dtype=bool)
        for arr in arrays:
            bad |= ~np.isfinite(arr).all(axis=1)
        k = int(np.argmax(bad))
        where = p.position[k] if np.isfinite(p.position[k]).all() else None
        hints = [hint for effect in scene.effects if (hint := effect.stop_hint(where))]
        if hints:  # an effect knows why (a sphere left a tabulated field, ...)
            raise SimulationError(
                f"the run stopped at step {self.step} (t = {self.time:.6g}): particle id {p.ids[k]} "
                f"{' '.join(hints)} {kept}.",
                step=self.step, time=self.time, particle=int(p.ids[k]), trajectory=self.trajectory)
        raise SimulationError(
            f"the run became non-finite (NaN or inf) at step {self.step} (t = {self.time:.6g}) for "
            f"particle id {p.ids[k]}: position {p.position[k].tolist()}, velocity {p.velocity[k].tolist()}. "
            f"{kept}; a smaller time step or gentler initial conditions may help.",
            step=self.step, time=self.time, particle=int(p.ids[k]), trajectory=self.trajectory)
