"""A run's recorded frames: :class:`Trajectory` (what ``Simulation.run`` returns, what scene files save and
``dk.io`` writes), with its periodic images unwrapped and consecutive runs joined."""
from __future__ import annotations

import numpy as np


class Trajectory:
    """Recorded frames of a run.

    time (T,); position, velocity (T,N,3); angular_velocity, dipole (T,N,3) or None when the scene
    has no such field; energy: dict of (T,) arrays (kinetic, rotational, magnetic, contact, ...,
    total, dissipated); angular_momentum (T,3) about the origin (orbital + spin); and the constant
    particle properties radius, mass, inertia, ids (N,). In a periodic box, positions are wrapped
    into it, ``image`` (T,N,3) holds the integer image counts and ``box`` the :class:`demkit.Box`
    (both None in open space); :meth:`unwrapped` gives continuous paths (:meth:`unwrapped_velocity` their
    velocities, which differ from ``velocity`` in a sheared box only). ``walls``: (number, wall) of the
    scene's walls whose place at a time their motion gives (not a servo's: it keeps no past positions),
    which pictures draw (:mod:`demkit.io.walls`).
    """

    def __init__(self, time, position, velocity, angular_velocity, dipole, energy,
                 angular_momentum, radius, mass, inertia, ids, image=None, box=None, walls=()):
        self.time = time
        self.position = position
        self.velocity = velocity
        self.angular_velocity = angular_velocity
        self.dipole = dipole
        self.energy = energy
        self.angular_momentum = angular_momentum
        self.radius, self.mass, self.inertia, self.ids = radius, mass, inertia, ids
        self.image, self.box = image, box
        self.walls = list(walls)

    def unwrapped(self):
        """Positions (T,N,3) continued across periodic boundaries: position + image * box size (in a
        sheared box also + n_b gammadot L_b t along the flow: the sliding images' offset, not wrapped;
        :meth:`demkit.Box.continued`)."""
        if self.image is None:
            return self.position
        return self.box.continued(self.position, self.velocity, self.image, np.asarray(self.time)[:, None])[0]

    def unwrapped_velocity(self):
        """Velocities (T,N,3) continued across periodic boundaries: the recorded ones, and in a sheared box
        + n_b gammadot L_b along the flow (a sphere that crossed the gradient axis n_b times was given its
        sliding image's velocity at each crossing): the time derivative of :meth:`unwrapped`."""
        if self.image is None:
            return self.velocity
        return self.box.continued(self.position, self.velocity, self.image, np.asarray(self.time)[:, None])[1]

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
                   ids=first.ids, box=first.box, walls=first.walls, **fields)

    def linear_momentum(self):
        """Total linear momentum per frame, (T,3)."""
        return (self.mass[None, :, None] * self.velocity).sum(axis=1)

    def __repr__(self):
        return (f"Trajectory({len(self)} frames, {self.position.shape[1]} particles, "
                f"t = {self.time[0]:.6g} .. {self.time[-1]:.6g})")
