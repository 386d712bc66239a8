"""Scene: particles + the chosen interactions, fused into one compiled pair loop.

Only what the interactions declare is allocated: no dipole arrays without a dipole interaction
(or user-given moments), no angular velocity unless something produces torque (or the user gave
spins), no history unless an interaction keeps some.
"""
from __future__ import annotations

import math

import numpy as np

from .integrators import TEMPLATES
from .interactions.base import PairInteraction
from .kernels import build_module, energy_kinds
from .motion import empty_vectors
from .neighbours import AllPairs
from .particles import Particles

#: initial overlap, as a fraction of the smaller radius, above which a start is rejected
MAX_INITIAL_OVERLAP = 0.5


class Scene:
    """Particles and pair interactions.

    Parameters
    ----------
    particles : Particles
    interactions : list of PairInteraction (e.g. ``[Dipole(prefactor=1/3), KelvinVoigt(1.0, 0.1)]``)
    pairs : pair list (default :class:`demkit.neighbours.AllPairs`)
    """

    def __init__(self, particles, interactions, pairs=None):
        if not isinstance(particles, Particles):
            raise TypeError(f"particles must be a demkit.Particles, got {type(particles).__name__}")
        if isinstance(interactions, PairInteraction):
            interactions = [interactions]
        interactions = list(interactions)
        for inter in interactions:
            if not isinstance(inter, PairInteraction):
                raise TypeError(f"interactions must be PairInteraction objects, got {inter!r}")
        self.particles = particles
        self.interactions = tuple(interactions)
        for inter in self.interactions:
            inter.check(particles)
        if any(inter.torque or "angular_velocity" in inter.reads for inter in self.interactions):
            particles.require("angular_velocity")
        self.box = None  # open space (periodic boxes: see the N-body engine)
        self.pair_list = AllPairs() if pairs is None else pairs
        self.pairs = self.pair_list.build(particles)
        width = sum(inter.history_size for inter in self.interactions)
        self.history = np.zeros((len(self.pairs), width)) if width else np.zeros((0, 0))
        cut2 = [inter.cutoff_distance ** 2 if inter.cutoff_distance is not None else math.inf
                for inter in self.interactions]
        values = [inter.parameter_values() for inter in self.interactions]
        self.params = np.concatenate(values + [np.array(cut2)]) if values else np.zeros(0)
        self.energy_kinds = energy_kinds(self.interactions)
        self.kernels = build_module(self.interactions, TEMPLATES)
        n = len(particles)
        self.force = np.zeros((n, 3))
        self.torque = np.zeros((n, 3))
        self.accum = np.zeros(1)  # accum[0]: work dissipated so far
        self.validate()

    # ---- state ---------------------------------------------------------------------------
    @property
    def dissipated(self):
        """Work dissipated by the interactions since the scene was made."""
        return float(self.accum[0])

    def state(self, force=None, torque=None):
        """The tuple of arrays the compiled kernels work on (views of the particle arrays)."""
        p = self.particles
        omega = p.angular_velocity if p.angular_velocity is not None else empty_vectors()
        dipole = p.dipole if p.dipole is not None else empty_vectors()
        return (p.position, p.velocity, omega, dipole, p.radius, p.mass, p.inertia, self.pairs,
                self.history, self.params, self.force if force is None else force,
                self.torque if torque is None else torque, self.accum)

    def validate(self):
        """Raise ValueError for non-finite state, coincident or deeply overlapping spheres."""
        p = self.particles
        p.check_finite()
        if len(self.pairs) == 0:
            return
        i, j = self.pairs[:, 0], self.pairs[:, 1]
        r = np.linalg.norm(p.position[j] - p.position[i], axis=1)
        overlap = (p.radius[i] + p.radius[j] - r) / np.minimum(p.radius[i], p.radius[j])
        k = int(np.argmax(overlap))
        if r[k] == 0.0:
            raise ValueError(f"particles {p.ids[i[k]]} and {p.ids[j[k]]} are coincident "
                             f"(both at {p.position[i[k]].tolist()})")
        if overlap[k] > MAX_INITIAL_OVERLAP:
            raise ValueError(
                f"particles {p.ids[i[k]]} and {p.ids[j[k]]} overlap deeply: centre distance {r[k]:.6g} "
                f"with radii {p.radius[i[k]]:.6g} and {p.radius[j[k]]:.6g} (overlap {overlap[k]:.3g} of the "
                f"smaller radius; at most {MAX_INITIAL_OVERLAP} is accepted at the start)")

    def max_time_step(self):
        """Largest safe time step over all interactions (math.inf when none limits it)."""
        return min([inter.max_time_step(self.particles) for inter in self.interactions] + [math.inf])

    # ---- diagnostics ---------------------------------------------------------------------
    def forces(self):
        """(force, torque), each (N,3), at the current state; changes nothing."""
        n = len(self.particles)
        force, torque = np.zeros((n, 3)), np.zeros((n, 3))
        self.kernels.forces_of(self.state(force, torque), False)
        return force, torque

    def energy(self):
        """Energies: kinetic, rotational, one per energy kind (magnetic, contact, ...), total and
        dissipated. total = kinetic + rotational + potentials; total + dissipated is conserved."""
        out = np.zeros(2 + len(self.energy_kinds))
        self.kernels.energies_of(self.state(), out)
        return energy_dict(out, self.energy_kinds, self.dissipated)

    def pair_energies(self):
        """(pairs, energies): the (P,2) pair indices and a (P, n_interactions) array of the
        potential energy of each pair under each interaction, in ``self.interactions`` order."""
        out = np.zeros((len(self.pairs), len(self.interactions)))
        self.kernels.pair_energies_of(self.state(), out)
        return self.pairs.copy(), out

    def angular_momentum(self, origin=(0.0, 0.0, 0.0)):
        """Orbital + spin angular momentum about ``origin``, shape (3,)."""
        return self.particles.angular_momentum(origin)

    def linear_momentum(self):
        """Total linear momentum, shape (3,)."""
        return self.particles.linear_momentum()

    def __repr__(self):
        return f"Scene({len(self.particles)} particles, {list(self.interactions)}, {self.pair_list})"


def energy_dict(values, kinds, dissipated):
    """Name the columns [kinetic, rotational, *kinds] (arrays or scalars) and add total, dissipated."""
    out = {"kinetic": values[..., 0], "rotational": values[..., 1]}
    for k, kind in enumerate(kinds):
        out[kind] = values[..., 2 + k]
    out["total"] = values[..., : 2 + len(kinds)].sum(axis=-1)
    out["dissipated"] = dissipated
    if np.ndim(out["total"]) == 0:
        out = {key: float(value) for key, value in out.items()}
    return out
