"""Notes at the end of a run: what a careful user would want to know, said plainly; never a stop.

While a run steps, :class:`RunNotes` samples the scene between compiled chunks, at most once per
``1 / BUDGET`` times the cost of a sample, so that sampling costs about 1 % of the wall time
(counted over the runs of a Simulation: many short runs share the budget):

* **contact overlaps**: delta / R_min of every touching pair of a contact law (R_min the smaller
  radius) and delta / R of every sphere on a wall. The *largest* is the maximum over all samples,
  the *typical* the mean over the contacts of a sample, averaged over the samples;

and, from the frames the run recorded (no extra work):

* **the energy balance**: E = kinetic + rotational + potential + dissipated, which the equations of
  motion keep constant. Its drift is max |E - E_start| over the frames, as a fraction of the
  energy scale (kinetic + rotational + the sum of |potential energies|, largest frame), the same
  scale as ``Simulation(max_energy_growth=...)``. Not reported when a moving wall works on the
  spheres (the balance then has a term demkit does not book).

A note is due when the largest overlap exceeds :data:`LARGEST_OVERLAP`, the typical one
:data:`TYPICAL_OVERLAP`, or the drift :data:`ENERGY_DRIFT`. The notes go into
``Simulation.statistics["notes"]`` (with the figures under ``"overlap_largest"``,
``"overlap_typical"`` and ``"energy_drift"``) and on stderr (``DEMKIT_QUIET=1`` keeps stderr quiet).
"""
from __future__ import annotations

import math
import sys
import time

import numpy as np

from . import neighbours
from .interactions.wall import Wall
from .progress import quiet

#: a contact overlapping by more than this fraction of the smaller radius, at any sample, gets a note
LARGEST_OVERLAP = 0.05
#: contacts overlapping on average by more than this fraction of the smaller radius get a note
TYPICAL_OVERLAP = 0.02
#: an energy balance drifting by more than this fraction of the energy scale gets a note
ENERGY_DRIFT = 0.01
#: sampling may take this fraction of the run's wall time
BUDGET = 0.01


def relative_overlaps(scene):
    """delta / R_min of every touching pair of the scene's contact laws and delta / R of every
    sphere on a wall, now (one array; empty without contacts)."""
    p = scene.particles
    parts = [np.zeros(0)]
    tag = scene.arrays["tag"]
    for g, group in enumerate(scene.plan.groups):
        if not any(inter.contact_reach for _, inter in group.members):
            continue
        if group.kind == "list":
            pairs = neighbours.pairs_of(scene._list(g), tag)
        else:
            i, j = np.triu_indices(len(p), k=1)
            pairs = np.stack([i, j], axis=1)
        if len(pairs) == 0:
            continue
        r = np.linalg.norm(scene.separations(pairs), axis=1)
        ri, rj = p.radius[pairs[:, 0]], p.radius[pairs[:, 1]]
        overlap = ri + rj - r
        touching = overlap > 0.0
        parts.append(overlap[touching] / np.minimum(ri, rj)[touching])
    for effect in scene.effects:
        if isinstance(effect, Wall):
            overlap = p.radius - effect.heights(p.position)
            touching = overlap > 0.0
            parts.append(overlap[touching] / p.radius[touching])
    return np.concatenate(parts)


class RunNotes:
    """Samples one run (see the module docstring)."""

    def __init__(self, scene, next_due=-math.inf):
        self.scene = scene
        self.contacts = any(inter.contact_reach for inter in scene.interactions) or any(
            isinstance(e, Wall) for e in scene.effects)
        self.balance = not any(isinstance(e, Wall) and np.any(e.velocity != 0.0) for e in scene.effects)
        self.largest, self.typical, self.samples_with_contacts = 0.0, 0.0, 0
        self.drift, self.scale = 0.0, 0.0
        self.cost, self.next_due = 0.0, next_due

    def sample(self):
        """Take a sample now (see :meth:`maybe_sample`)."""
        began = time.perf_counter()
        if self.contacts:
            rel = relative_overlaps(self.scene)
            if len(rel):
                self.largest = max(self.largest, float(rel.max()))
                self.typical += float(rel.mean())
                self.samples_with_contacts += 1
        now = time.perf_counter()
        self.cost = now - began
        self.next_due = now + self.cost / BUDGET

    def maybe_sample(self):
        """Sample when the budget allows (at the start, between chunks and at the end of a run)."""
        if time.perf_counter() >= self.next_due:
            self.sample()

    def frames(self, energy):
        """The run's recorded energies: (F, K) rows [kinetic, rotational, potentials..., dissipated]."""
        if self.balance and len(energy):
            total = energy.sum(axis=1)
            self.drift = float(np.max(np.abs(total - total[0])))
            self.scale = float(np.max(np.abs(energy[:, :-1]).sum(axis=1)))

    def figures(self):
        """The run's figures: largest and typical relative overlap, energy drift / scale (None: not measured)."""
        typical = self.typical / self.samples_with_contacts if self.samples_with_contacts else 0.0
        drift = self.drift / self.scale if self.balance and self.scale > 0.0 else None
        return {"overlap_largest": self.largest if self.contacts else None,
                "overlap_typical": typical if self.contacts else None, "energy_drift": drift}

    def notes(self, dt):
        """The notes due for this run (strings; empty when nothing happened)."""
        f = self.figures()
        out = []
        if self.contacts and (f["overlap_largest"] > LARGEST_OVERLAP or f["overlap_typical"] > TYPICAL_OVERLAP):
            out.append(f"contacts overlapped by up to {f['overlap_largest']:.1%} of the smaller radius (typically "
                       f"{f['overlap_typical']:.1%}): the contact law is soft for these forces and speeds, and "
                       f"results that depend on where spheres touch are off by as much; a stiffer law (larger "
                       f"stiffness or Young's modulus) keeps overlaps small (a smaller time step does not)")
        if f["energy_drift"] is not None and f["energy_drift"] > ENERGY_DRIFT:
            out.append(f"the energy balance (kinetic + rotational + potential + dissipated) drifted by "
                       f"{f['energy_drift']:.1%} of the energy scale {self.scale:.4g}: the time step dt = {dt:.4g} "
                       f"is too long for this accuracy; halve it (the drift of a dissipative run falls about as "
                       f"dt), or step impacts exactly with VelocityVerlet(dt, resolve_contacts=True)")
        return out


def say(notes):
    """Print the notes on stderr unless DEMKIT_QUIET is set."""
    if quiet():
        return
    for text in notes:
        print(f"demkit note: {text}", file=sys.stderr, flush=True)
