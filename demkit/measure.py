"""The quantities papers report, measured on a scene at its current state (nothing is changed).

    s = dk.measure.stress(scene)        # kinetic + pair virial: s.pressure, s.pressure_tensor, s.per_sphere
    z = dk.measure.coordination(scene)  # contacts per sphere
    B = dk.measure.local_field(scene)   # the magnetic field at each sphere's centre
    M = dk.measure.magnetisation(scene) # total moment per volume
    c = dk.measure.clusters(scene)      # touching groups: c.labels, c.sizes, c.largest

**Pressure tensor** (the virial theorem; the convention of LAMMPS' ``compute pressure``; with an
Ewald or P3M dipole sum its reciprocal and surface terms are added to the Dipole's virial,
:mod:`demkit.interactions.ewald_virial`; an FMM sum's is sum_i (x_i - mean x) F_i from its forces)::

    P_ab = (1/V) [ sum_i m_i v_ia v_ib + sum_(i<j) r_ij,a F_ij,b ],    p = (P_xx + P_yy + P_zz) / 3

with r_ij = x_j - x_i (the minimum image in periodic boxes, as the forces use) and F_ij the force
of the pair on j (:meth:`demkit.Scene.pair_forces`: the compiled pair loops, committing nothing),
summed over every pair interaction of the scene (contact laws with their friction, dipoles,
plug-ins). Repulsion gives positive pressure; the stress is sigma = -P. Forces that are not pair forces (walls, gravity, applied fields) are external and not part of the virial: the
pressure a walled sample exerts is the walls' force per area. Dipole forces are not central, so P
need not be symmetric. Each sphere's share (``per_sphere``, pressure x volume, half of each of its
pairs) adds up to V P. An open scene (no box) has no volume: pass ``volume=``. In a sheared box
(:class:`demkit.Shear`) r_ij is the sliding image's and the kinetic part takes the velocity relative to
the imposed flow, v_i - gammadot (x_ib - L_b / 2) e_a: the shear stress of a sample is -P_ab.

**Local field**: B_i = B_applied(x_i) + sum_j A S(r) [3 (m_j.n) n - m_j] / r^3 over the pairs the
dipole sum reaches (its cutoff, switch S and minimum image; with an Ewald sum, every other sphere and
every image, see :func:`demkit.interactions.ewald.field_of_others`), in the units of the dipole's prefactor
A (tesla in SI), so that the torque on sphere i is m_i x B_i and the magnetic energy
-1/2 sum_i m_i.(B_i - B_applied) - sum_i m_i.B_applied.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .interactions import ewald
from .interactions.dipole import Dipole, PowerLawDipole, switch
from .interactions.fields import UniformField
from .interactions.magnets import MagnetField


@dataclass
class Stress:
    """Pressure tensor of a scene and its parts (see module docstring); arrays in scene units."""

    volume: float
    kinetic: np.ndarray       # (3, 3) sum_i m v_a v_b
    virial: dict              # interaction name -> (3, 3) sum_(i<j) r_a F_b
    per_sphere: np.ndarray    # (N, 3, 3) each sphere's m v v + half of its pairs' r F (sums to V P)

    @property
    def pressure_tensor(self):
        """P (3, 3) = (kinetic + virials) / V."""
        return (self.kinetic + sum(self.virial.values(), np.zeros((3, 3)))) / self.volume

    @property
    def pressure(self):
        """p = trace(P) / 3."""
        return float(np.trace(self.pressure_tensor)) / 3.0

    @property
    def stress(self):
        """The Cauchy stress sigma = -P (tension positive)."""
        return -self.pressure_tensor


def volume_of(scene, volume=None):
    """The volume a measurement divides by: ``volume`` if given (a positive number), else the box's;
    ValueError for a scene without a box and no ``volume``."""
    if volume is not None:
        volume = float(volume)
        if not np.isfinite(volume) or volume <= 0.0:
            raise ValueError(f"volume must be a positive number, got {volume!r}")
        return volume
    box = scene.box
    if box is None or not np.all(np.isfinite(box.size)):
        raise ValueError("this scene has no box, so no volume to divide by: pass volume=... (the region the "
                         "spheres fill, in scene length units cubed)")
    return box.volume_at(scene.time)  # (a deforming box's at the scene's time)


def stress(scene, volume=None):
    """The pressure tensor of ``scene`` now and its parts (a :class:`Stress`; module docstring).
    ``volume``: the volume to divide by (default: the box's; required for open scenes)."""
    volume = volume_of(scene, volume)
    kinetic, virial, per_sphere = _virials(scene)
    return Stress(volume=volume, kinetic=kinetic, virial=virial, per_sphere=per_sphere)


def _virials(scene):
    """(sum m v v, {interaction name: sum r F}, per-sphere shares (N, 3, 3)) of ``scene`` now: the pair
    interactions', and the long-range sums' under "Dipole": the reciprocal and surface terms of Ewald
    and P3M sums with their real-space pairs (:mod:`demkit.interactions.ewald_virial`), an FMM sum
    from its forces (:meth:`demkit.interactions.fmm.TunedFMM.virial`)."""
    sums = list(scene.long_range)
    p = scene.particles
    n = len(p)
    mass = np.broadcast_to(np.asarray(p.mass, dtype=float), (n,))
    moving = np.ones(n, dtype=bool) if p.fixed is None else ~np.asarray(p.fixed)
    v = np.asarray(p.velocity) * moving[:, None]  # fixed spheres do not move
    shear = scene.box.shear if scene.box is not None else None
    if shear is not None:  # a sheared box: the velocity relative to the imposed flow gammadot (x_b - L_b / 2) e_a
        a, b = shear.axes
        v = v.copy()
        v[:, a] -= shear.rate * (np.asarray(p.position)[:, b] - 0.5 * scene.box.size[b]) * moving
    per_sphere = mass[:, None, None] * v[:, :, None] * v[:, None, :]
    kinetic = per_sphere.sum(axis=0)
    virial = {}
    for inter, pairs, d, force in scene.pair_forces():
        w = d[:, :, None] * force[:, None, :]
        name = type(inter).__name__
        virial[name] = virial.get(name, np.zeros((3, 3))) + w.sum(axis=0)
        np.add.at(per_sphere, pairs[:, 0], 0.5 * w)
        np.add.at(per_sphere, pairs[:, 1], 0.5 * w)
    for tuned in sums:
        w, shares = tuned.virial(scene.particles, scene.box)
        virial["Dipole"] = virial.get("Dipole", np.zeros((3, 3))) + w
        per_sphere += shares
    return kinetic, virial, per_sphere


def sphere_arrays(scene, names):
    """{array name: (N, ...) values} of the per-sphere measurements ``names`` (among
    :data:`SPHERE_MEASURES`) now, as VTK frames carry them: ``pressure`` gives ``pressure_volume``
    (tr of each sphere's share / 3: pressure x volume, summing to p V), ``coordination`` the
    contacts of each sphere, ``field`` the ``local_field``."""
    known_sphere_measures(names)
    out = {}
    if "pressure" in names:
        out["pressure_volume"] = np.trace(_virials(scene)[2], axis1=1, axis2=2) / 3.0
    if "coordination" in names:
        out["coordination"] = coordination(scene)
    if "field" in names:
        out["local_field"] = local_field(scene)
    return out


#: per-sphere measurements a VTK series can carry (VTKWriter(measures=...)) and their arrays
SPHERE_MEASURES = {"pressure": ("pressure_volume", 1), "coordination": ("coordination", 1),
                   "field": ("local_field", 3)}


def known_sphere_measures(names):
    """``names`` (a name or several) as a tuple, or ValueError naming those not in :data:`SPHERE_MEASURES`."""
    names = (names,) if isinstance(names, str) else tuple(names or ())
    unknown = [name for name in names if name not in SPHERE_MEASURES]
    if unknown:
        raise ValueError(f"unknown measures {unknown} (per-sphere measurements); known: {list(SPHERE_MEASURES)}")
    return names


@dataclass
class Clusters:
    """Clusters of touching spheres (see :func:`clusters`)."""

    labels: np.ndarray   # (N,) cluster of each sphere: 0 the largest, 1 the next, ...
    sizes: np.ndarray    # (C,) spheres in each cluster, largest first

    @property
    def count(self):
        return len(self.sizes)

    @property
    def largest(self):
        return int(self.sizes[0]) if len(self.sizes) else 0

    @property
    def mean_size(self):
        """Mean size seen by a sphere, sum s^2 / sum s (the weight average of polymer physics)."""
        return float(np.sum(self.sizes.astype(float) ** 2) / max(np.sum(self.sizes), 1))


def clusters(scene, gap=0.0):
    """The :class:`Clusters` of ``scene`` now: connected groups of spheres whose surfaces are closer
    than ``gap`` (length; 0: touching, r < R_i + R_j; minimum image in periodic boxes); a lone
    sphere is a cluster of one."""
    from .clustering import clusters as cluster_labels
    gap = float(gap)
    if not np.isfinite(gap) or gap < 0.0:
        raise ValueError(f"gap must be a non-negative length, got {gap!r}")
    p = scene.particles
    labels = cluster_labels(p.position, p.radius, scene.box, gap=gap)
    return Clusters(labels=labels, sizes=np.bincount(labels) if len(labels) else np.zeros(0, dtype=np.int64))


def coordination(scene, walls=False):
    """(N,) integer: the contacts each sphere has now under the scene's contact laws (spheres it
    touches; with ``walls=True`` walls it touches count too). Its mean is the coordination number z."""
    c = scene.contacts()
    n = len(scene.particles)
    spheres = c.wall < 0
    count = np.bincount(c.pairs[spheres].ravel(), minlength=n)
    if walls:
        count += np.bincount(c.pairs[~spheres, 1], minlength=n)
    return count


def local_field(scene, applied=True):
    """(N, 3): the magnetic field at each sphere's centre from the other spheres' dipoles (and, with
    ``applied``, the scene's UniformField and MagnetField effects), in the units of the dipole
    prefactor (module docstring). The torque on sphere i is m_i x B_i."""
    p = scene.particles
    if p.dipole is None:
        raise ValueError("these spheres have no dipole moments, so there is no field to measure")
    field = np.zeros((len(p), 3))
    for inter in scene.interactions:
        if isinstance(inter, PowerLawDipole):
            raise ValueError("PowerLawDipole is a central force with no torque: it has no field at a sphere "
                             "(use dk.Dipole)")
        if not isinstance(inter, Dipole):
            continue
        if inter.tuned is not None:  # a long-range sum: whatever its pair loop leaves to it
            field += inter.tuned.field(p, scene.box)
        if not inter.pair_loop:
            continue
        pairs = scene.candidate_pairs(inter)
        d = scene.separations(pairs)
        r = np.sqrt(np.einsum("ij,ij->i", d, d))
        i, j = pairs[:, 0], pairs[:, 1]
        mi, mj = p.dipole[i], p.dipole[j]
        if inter.tuned is not None:  # the screened real-space pairs of an Ewald-split sum
            np.add.at(field, i, ewald.real_space_field(inter.tuned, d, r, mj))
            np.add.at(field, j, ewald.real_space_field(inter.tuned, -d, r, mi))
            continue
        scale = inter.prefactor / r**3
        if inter.cutoff_distance is not None:
            scale = np.where(r < inter.cutoff_distance, scale, 0.0)
            if inter.switch_width is not None:
                scale = scale * switch(r, inter.cutoff_distance, inter.switch_width)[0]
        u = d / r[:, None]
        on_i = scale[:, None] * (3.0 * np.einsum("ij,ij->i", mj, u)[:, None] * u - mj)
        on_j = scale[:, None] * (3.0 * np.einsum("ij,ij->i", mi, u)[:, None] * u - mi)
        np.add.at(field, i, on_i)
        np.add.at(field, j, on_j)
    if applied:
        for effect in scene.effects:
            if isinstance(effect, UniformField):
                field += effect.field
            elif isinstance(effect, MagnetField):  # magpylib sources, tabulated
                field += effect.field(p.position)
    return field


def magnetisation(scene, volume=None):
    """(3,): the total dipole moment per volume, sum_i m_i / V (``volume`` as for :func:`stress`)."""
    p = scene.particles
    if p.dipole is None:
        raise ValueError("these spheres have no dipole moments, so no magnetisation")
    return np.asarray(p.dipole).sum(axis=0) / volume_of(scene, volume)
