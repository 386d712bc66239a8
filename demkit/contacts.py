"""Per-contact diagnostics: every contact's geometry, forces, sliding state and dissipation.

``scene.contacts()`` evaluates the scene's contact laws (Kelvin-Voigt, Hertz) and its walls on
every touching pair at the current state, without changing anything (history included), and
returns a :class:`Contacts` table. A contact between spheres i and j has ``pairs`` (i, j) and
``wall`` -1; a sphere j touching wall w (``scene.effects`` numbering) has ``pairs`` (-1, j) and
``wall`` w. In both the normal n points from i (or the wall) to j, and forces are those on j:

    force = F_n n + F_t,   F_n > 0 pushes the two apart (the dashpot can make it negative),

``torque_i`` / ``torque_j`` are the contact's torques (friction at the contact point, rolling and
twisting resistance), ``sliding`` says the friction force is at its Coulomb limit |F_t| = mu |F_n|
(frictionless contacts always slide), and ``dissipation`` is the power the contact dissipates at
this instant: the normal dashpot's (F_n - F_elastic) d(delta)/dt plus eta_t |v_t|^2 while the
friction spring sticks or -F_t.v_t while it slides (and likewise for rolling and twisting
resistance: eta_tw w_tw^2 or -M w_tw).

:meth:`Contacts.write_vtk` writes the contact network as VTK lines between the centres (a wall
contact runs from the contact point to the centre): the force chains, coloured by force.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .interactions.contact import KelvinVoigt
from .interactions.hertz import Hertz
from .interactions.wall import numbered_walls

#: a friction force within this fraction of the Coulomb limit counts as sliding
SLIDING_TOLERANCE = 1e-9
FIELDS = ("pairs", "wall", "point", "normal", "overlap", "normal_force", "tangential_force", "force",
          "torque_i", "torque_j", "sliding", "dissipation")


@dataclass
class Contacts:
    """Every contact of a scene at one instant (see the module docstring); arrays of length C."""

    pairs: np.ndarray             # (C, 2) sphere indices i, j (i = -1 for a wall)
    wall: np.ndarray              # (C,) wall number in scene.effects, -1 for two spheres
    point: np.ndarray             # (C, 3) contact point (middle of the overlap; on the wall's plane)
    normal: np.ndarray            # (C, 3) unit normal from i to j
    overlap: np.ndarray           # (C,) delta > 0, length
    normal_force: np.ndarray      # (C,) F_n, positive when pushing apart
    tangential_force: np.ndarray  # (C, 3) friction force on j
    force: np.ndarray             # (C, 3) total contact force on j (its negative acts on i)
    torque_i: np.ndarray          # (C, 3)
    torque_j: np.ndarray          # (C, 3)
    sliding: np.ndarray           # (C,) bool
    dissipation: np.ndarray       # (C,) power >= 0

    def __len__(self):
        return len(self.wall)

    def net_force(self, n):
        """(n, 3) sum of the contact forces on each of n spheres (walls excluded)."""
        out = np.zeros((n, 3))
        np.add.at(out, self.pairs[:, 1], self.force)
        inner = self.pairs[:, 0] >= 0
        np.add.at(out, self.pairs[inner, 0], -self.force[inner])
        return out

    def write_vtk(self, path, particles, compress=False):
        """Write the contacts as VTK poly-lines (.vtp) from centre i (or the contact point on a wall)
        to centre j, with cell data overlap, normal_force, force, force_magnitude, tangential_force,
        sliding (0/1), dissipation, i, j, wall. ``particles``: the scene's (for centres and radii;
        the line runs from j back along the normal, so it never spans a periodic box)."""
        from .io.polylines import write_vtp_lines
        end = np.asarray(particles.position, dtype=np.float64)[self.pairs[:, 1]]
        i = np.maximum(self.pairs[:, 0], 0)
        walls = self.wall >= 0
        back = np.where(walls, 0.0, particles.radius[i] - 0.5 * self.overlap)
        start = self.point - self.normal * back[:, None]
        points = np.empty((2 * len(self), 3))
        points[0::2], points[1::2] = start, end
        cells = {"overlap": self.overlap, "normal_force": self.normal_force, "force": self.force,
                 "force_magnitude": np.linalg.norm(self.force, axis=1) if len(self) else np.zeros(0),
                 "tangential_force": self.tangential_force, "sliding": self.sliding.astype(np.int64),
                 "dissipation": self.dissipation, "i": self.pairs[:, 0], "j": self.pairs[:, 1], "wall": self.wall}
        write_vtp_lines(path, points, np.full(len(self), 2), {}, cells, compress=compress)


def _empty():
    return Contacts(np.zeros((0, 2), dtype=np.int64), np.zeros(0, dtype=np.int64),
                    *(np.zeros((0, 3)) for _ in range(2)), np.zeros(0), np.zeros(0),
                    *(np.zeros((0, 3)) for _ in range(4)), np.zeros(0, dtype=bool), np.zeros(0))


def _concatenate(parts):
    if not parts:
        return _empty()
    return Contacts(*(np.concatenate([getattr(p, name) for p in parts]) for name in FIELDS))


def _fields(scene, reads):
    """The particle arrays a contact law reads (user order; fixed spheres with infinite mass)."""
    p = scene.particles
    out = []
    for name in reads:
        value = getattr(p, name)
        if name == "mass" and p.fixed is not None and p.fixed.any():
            value = np.where(p.fixed, np.inf, value)
        out.append(np.ascontiguousarray(value, dtype=np.float64))
    return out


def _evaluate(law, first, fields, history, params):
    """Call a contact law's (or wall's) force function for each contact; rows (force 3, torque_i 3,
    torque_j 3, power). ``first(k)`` gives the geometric arguments of contact k before the fields;
    ``params``: the parameter values, or one row of them per contact (a cylinder's tangent planes)."""
    force_function = law.pair_functions()[0]
    table = law.table_values() if hasattr(law, "table_values") else np.zeros(0)
    rows = np.zeros((len(history), 10))
    for k in range(len(history)):
        args = first(k) + fields
        if law.history_size:
            args += [history, k, 0, False]
        if table.size:  # a wall of a law with friction: its table (demkit.interactions.wall)
            args += [table, 0]
        out = force_function(*args, *(params[k] if np.ndim(params) == 2 else params))
        rows[k, :3], rows[k, 9] = out[:3], out[-1]
        if len(out) == 10:  # a pair: torques on i and j
            rows[k, 3:9] = out[3:9]
        elif len(out) == 7:  # a wall: the sphere's torque
            rows[k, 6:9] = out[3:6]
    return rows


def _table(pairs, wall, point, normal, overlap, rows, mu):
    force = rows[:, :3]
    fn = np.einsum("ij,ij->i", force, normal)
    ft = force - fn[:, None] * normal
    sliding = np.linalg.norm(ft, axis=1) >= (1.0 - SLIDING_TOLERANCE) * mu * np.abs(fn)
    return Contacts(pairs, wall, point, normal, overlap, fn, ft, force, rows[:, 3:6], rows[:, 6:9], sliding,
                    rows[:, 9])


def _mu(law):
    return law.friction.coefficient if law.friction is not None else 0.0


def pair_contacts(scene, law):
    """Contacts between spheres under one contact law."""
    p = scene.particles
    if law.history_size:
        candidates, history = scene.history(law)
    else:
        candidates, history = scene.candidate_pairs(law), None
    if len(candidates) == 0:
        return _empty()
    d = scene.separations(candidates)
    r = np.linalg.norm(d, axis=1)
    reach = p.radius[candidates[:, 0]] + p.radius[candidates[:, 1]]
    touching = r < reach
    pairs, d, r = candidates[touching], d[touching], r[touching]
    history = np.ascontiguousarray(history[touching]) if history is not None else np.zeros((len(pairs), 0))
    overlap = reach[touching] - r
    normal = d / r[:, None]
    point = p.position[pairs[:, 1]] - normal * (p.radius[pairs[:, 1]] - 0.5 * overlap)[:, None]
    r2 = r * r

    def first(k):
        return [int(pairs[k, 0]), int(pairs[k, 1]), d[k, 0], d[k, 1], d[k, 2], r2[k]]

    rows = _evaluate(law, first, _fields(scene, law.reads), history, law.parameter_values())
    return _table(pairs.astype(np.int64), np.full(len(pairs), -1), point, normal, overlap, rows, _mu(law))


def wall_contacts(scene, wall, number):
    """Contacts of the spheres with one wall."""
    p = scene.particles
    overlap = p.radius - wall.heights(p.position, scene.time)
    spheres = np.flatnonzero(overlap > 0.0)
    if wall.history_size:
        history = np.ascontiguousarray(scene.sphere_history(wall)[spheres])
    else:
        history = np.zeros((len(spheres), 0))
    x = p.position

    def first(k):
        i = int(spheres[k])
        return [i, x[i, 0], x[i, 1], x[i, 2]]

    # (a cylinder: each sphere's parameters hold the plane it meets)
    rows = _evaluate(wall, first, _fields(scene, wall.reads), history,
                     wall.parameters_at(x[spheres], scene.time, p.radius[spheres]))
    n = len(spheres)
    normal = wall.normals(x[spheres], scene.time).reshape(n, 3)
    point = x[spheres] - (p.radius[spheres] - overlap[spheres])[:, None] * normal
    pairs = np.stack([np.full(n, -1), spheres], axis=1).astype(np.int64)
    return _table(pairs, np.full(n, number), point, normal, overlap[spheres], rows, _mu(wall.law))


def contacts_of(scene):
    """:class:`Contacts` of a scene (see :meth:`demkit.Scene.contacts`)."""
    parts = [pair_contacts(scene, inter) for inter in scene.interactions if isinstance(inter, (KelvinVoigt, Hertz))]
    parts += [wall_contacts(scene, wall, e) for e, wall in numbered_walls(scene.effects)]
    return _concatenate(parts)
