"""What a run records: the frames of a run, allocated before it (refused when they would not fit in this
machine's memory), kept as a :class:`demkit.Trajectory`, and a warning before a run writes very much.
A part of :class:`demkit.Simulation` (it inherits :class:`Recording`)."""
from __future__ import annotations

import os
import warnings

import numpy as np

from .diagnostics import energy_dict
from .interactions.wall import numbered_walls
from .trajectory import Trajectory

#: a run that will write more files or bytes than this is announced (LargeOutputWarning)
LARGE_OUTPUT_FILES = 10_000
LARGE_OUTPUT_BYTES = 10 * 2**30


class LargeOutputWarning(UserWarning):
    """A run is about to write very many files or bytes."""


class Recording:
    """The recording of :class:`demkit.Simulation` (see the module docstring)."""

    def _check_record_size(self, nframes):
        p = self.scene.particles
        vectors = 2 + (p.angular_velocity is not None) + (p.dipole is not None) + (p.image is not None)
        size = nframes * (len(p) * 3 * 8 * vectors + 8 * (4 + len(self.scene.energy_kinds) + 3))
        memory = _physical_memory()
        if memory and size > 0.8 * memory:
            raise ValueError(
                f"recording {nframes} frames of {len(p)} particles needs {size / 2**30:.3g} GiB, more than this "
                f"machine can hold ({memory / 2**30:.3g} GiB of memory): record fewer frames (a larger "
                f"record_every) or write them to disk with a VTKWriter")

    def _warn_large_output(self, nsteps, writer_steps):
        files = size = 0
        for w, ws in zip(self.writers, writer_steps):
            if hasattr(w, "planned_output"):
                f, b = w.planned_output(nsteps // ws, self.scene.particles)
                files, size = files + f, size + b
        if files > LARGE_OUTPUT_FILES or size > LARGE_OUTPUT_BYTES:
            warnings.warn(f"this run will write about {files} files and {size / 2**30:.3g} GiB "
                          f"({nsteps} steps); a larger writer interval writes less", LargeOutputWarning,
                          stacklevel=3)

    def _allocate(self, nframes):
        p = self.scene.particles
        n = len(p)
        shape = (nframes, n, 3)
        omega = np.zeros(shape) if p.angular_velocity is not None else np.zeros((0, 0, 3))
        dipole = np.zeros(shape) if p.dipole is not None else np.zeros((0, 0, 3))
        image = np.zeros(shape, dtype=np.int64) if p.image is not None else np.zeros((0, 0, 3), dtype=np.int64)
        energy = np.zeros((nframes, 3 + len(self.scene.energy_kinds)))
        return (np.zeros(shape), np.zeros(shape), omega, dipole, energy, np.zeros((nframes, 3)), image)

    def _keep(self, record, start_step, steps):
        """Make ``self.trajectory`` the frames of ``record`` taken at the run-local ``steps``."""
        self.trajectory = self._trajectory(record, (start_step + np.asarray(steps)) * self.integrator.dt)
        return self.trajectory

    def _trajectory(self, record, times):
        p = self.scene.particles
        t = len(times)
        pos, vel, omega, dipole, energy, momentum, image = (r[:t] for r in record)
        traj = Trajectory(
            time=times, position=pos, velocity=vel,
            angular_velocity=omega if p.angular_velocity is not None else None,
            dipole=dipole if p.dipole is not None else None,
            energy=energy_dict(energy[:, :-1], self.scene.energy_kinds, energy[:, -1]),
            angular_momentum=momentum, radius=p.radius.copy(), mass=p.mass.copy(),
            inertia=p.inertia.copy(), ids=p.ids.copy(), image=image if p.image is not None else None,
            box=self.scene.box, walls=[(e, w) for e, w in numbered_walls(self.scene.effects) if w.servo is None])
        if getattr(self.scene.box, "shear", None) is not None:  # about the continued paths (the compiled record
            # takes position + image L and the wrapped velocity: neither has the sliding images' share)
            traj.angular_momentum = continued_angular_momentum(traj)
        return traj


def continued_angular_momentum(traj):
    """(T, 3) sum_i m_i x_i x v_i + I_i w_i about the origin, of the unwrapped positions and velocities."""
    position, velocity = traj.box.continued(traj.position, traj.velocity, traj.image, np.asarray(traj.time)[:, None])
    momentum = np.cross(position, traj.mass[None, :, None] * velocity).sum(axis=1)
    if traj.angular_velocity is not None:
        momentum += (traj.inertia[None, :, None] * traj.angular_velocity).sum(axis=1)
    return momentum


def _frame_of(record, k):
    """Copies of frame k of every record array (None for absent fields)."""
    return tuple(r[k].copy() if len(r) else None for r in record)


def _physical_memory():
    """Bytes of memory of this machine (0 when unknown)."""
    try:
        return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (ValueError, OSError, AttributeError):
        return 0
