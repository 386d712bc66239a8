"""Why a run stopped: :class:`SimulationError` (the run cannot be trusted: a non-finite state, a sphere
that moved past the neighbour lists' skin or deep into another, one that left a slab's layer, a solve of
induced moments that failed), its message naming the step, the sphere and what to change, and the frames
recorded before it kept. A part of :class:`demkit.Simulation` (it inherits :class:`Stops`)."""
from __future__ import annotations

import numpy as np

from .engine.state import DEEP_OVERLAP, DEEP_OVERLAP_FRACTION, INDUCTION_FAILED, LEFT_LAYER, MOVED_TOO_FAR, OK


class SimulationError(RuntimeError):
    """A run stopped because it could not be trusted (e.g. NaN or inf appeared).

    Attributes: ``step``, ``time``, ``particle`` (id), ``trajectory`` (frames recorded so far).
    """

    def __init__(self, message, step, time, particle, trajectory):
        super().__init__(message)
        self.step, self.time, self.particle, self.trajectory = step, time, particle, trajectory


class Stops:
    """What :class:`demkit.Simulation` says when a run stops (see the module docstring)."""

    def _fail(self, bad_step, start_step, stride, record):
        dt = self.integrator.dt
        scene = self.scene
        p = scene.particles
        status = scene.status
        code, index, other = int(status[0]), int(status[1]), int(status[3])
        status[:] = OK
        good_frames = (bad_step - 1) // stride + 1
        self._keep(record, start_step, np.arange(good_frames) * stride)
        self.step = start_step + bad_step
        kept = (f"The {good_frames} frames recorded before it are kept in simulation.trajectory")
        tag = scene.arrays["tag"]
        if code in (MOVED_TOO_FAR, DEEP_OVERLAP, LEFT_LAYER):  # the kernels flagged a particle (internal index)
            k = int(tag[index])
            speed = float(np.linalg.norm(p.velocity[k]))
        if code == MOVED_TOO_FAR:
            raise SimulationError(
                f"particle id {p.ids[k]} moved more than the neighbour-list skin ({scene.skin:.6g}) between two "
                f"rebuilds at step {self.step} (t = {self.time:.6g}; speed {speed:.6g}, so {speed * dt:.6g} per "
                f"step): the lists could miss pairs and contacts could be stepped over. Use a smaller time step "
                f"(dt = {dt:.6g}) or a larger skin. {kept}.",
                step=self.step, time=self.time, particle=int(p.ids[k]), trajectory=self.trajectory)
        if code == DEEP_OVERLAP:
            walls = ""
            if other < 0:  # a wall: status[3] = -1 - its index among the effects
                wall = scene.effects[-1 - other]
                what = f"particle id {p.ids[k]} overlaps {wall!r} by more than {DEEP_OVERLAP_FRACTION} of its radius"
                if wall.surface_speed() > 0.0:  # a moving wall hits at its own speed too
                    walls = f"; the wall's surface moves at up to {wall.surface_speed():.6g}"
            else:
                what = f"particles id {p.ids[k]} and {p.ids[int(tag[other])]} overlap by more than " \
                       f"{DEEP_OVERLAP_FRACTION} of the smaller radius"
            raise SimulationError(
                f"{what} at step {self.step} (t = {self.time:.6g}; speed {speed:.6g}{walls}): the contact is too "
                f"soft to stop the sphere, which would pass through. Use a stiffer contact law for speeds like this "
                f"(the overlap of a linear contact is about v sqrt(m/k)) or a smaller time step (dt = {dt:.6g}); "
                f"docs/stability.md says how to size both. {kept}.",
                step=self.step, time=self.time, particle=int(p.ids[k]), trajectory=self.trajectory)
        if code == LEFT_LAYER:
            hint = next(tuned.layer.stop_hint() for tuned in scene.long_range if tuned.layer is not None)
            raise SimulationError(
                f"particle id {p.ids[k]} {hint} It happened at step {self.step} (t = {self.time:.6g}; its speed "
                f"{speed:.6g}, position {p.position[k].tolist()}). {kept}.",
                step=self.step, time=self.time, particle=int(p.ids[k]), trajectory=self.trajectory)
        if code == INDUCTION_FAILED:
            solver = scene.induction
            raise SimulationError(
                f"at step {self.step} (t = {self.time:.6g}) {solver.failure(solver.last_code)}. {kept}.",
                step=self.step, time=self.time, particle=None, trajectory=self.trajectory)
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
