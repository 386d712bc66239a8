"""Independent brute-force references for the N-body tests: plain numpy over all pairs i < j,
minimum image along periodic axes, formulas written out from docs/theory.md."""
import math

import numpy as np
from scipy.spatial import cKDTree


def separations(position, box):
    """d[i, j] = x_j - x_i (minimum image along the box's periodic axes), (N, N, 3)."""
    d = position[None, :, :] - position[:, None, :]
    if box is not None:
        for a in np.flatnonzero(box.periodic):
            d[..., a] -= box.size[a] * np.round(d[..., a] / box.size[a])
    return d


def pairs_within(position, reach, box=None):
    """Set of pairs (i, j), i < j, closer than ``reach`` (scipy's k-d tree; periodic via boxsize)."""
    if box is None or not box.any_periodic:
        return {tuple(p) for p in cKDTree(position).query_pairs(reach)}
    if box.periodic.all():
        return {tuple(p) for p in cKDTree(position % box.size, boxsize=box.size).query_pairs(reach)}
    r = np.linalg.norm(separations(position, box), axis=-1)
    i, j = np.nonzero(np.triu(r < reach, 1))
    return set(zip(i.tolist(), j.tolist()))


def dipole_forces(position, dipole, prefactor, cutoff=None, box=None):
    """(force, torque, energy) of the point-dipole interaction summed over all pairs."""
    n = len(position)
    d = separations(position, box)
    i, j = np.triu_indices(n, 1)
    d = d[i, j]
    r = np.linalg.norm(d, axis=1)
    keep = r < cutoff if cutoff is not None else np.ones(len(r), dtype=bool)
    i, j, d, r = i[keep], j[keep], d[keep], r[keep]
    u = d / r[:, None]
    a, b = dipole[i], dipole[j]
    ab = (a * b).sum(1)
    an = (a * u).sum(1)
    bn = (b * u).sum(1)
    c = prefactor / r**3
    fj = (3 * c / r)[:, None] * (ab[:, None] * u + an[:, None] * b + bn[:, None] * a - 5 * (an * bn)[:, None] * u)
    ti = c[:, None] * (3 * bn[:, None] * np.cross(a, u) - np.cross(a, b))
    tj = c[:, None] * (3 * an[:, None] * np.cross(b, u) - np.cross(b, a))
    force = np.zeros((n, 3))
    torque = np.zeros((n, 3))
    np.add.at(force, j, fj)
    np.add.at(force, i, -fj)
    np.add.at(torque, i, ti)
    np.add.at(torque, j, tj)
    energy = float((c * (ab - 3 * an * bn)).sum())
    return force, torque, energy


def kelvin_voigt_forces(position, velocity, radius, stiffness, damping, box=None):
    """(force, elastic energy) of the linear spring-dashpot contact summed over all pairs."""
    n = len(position)
    d = separations(position, box)
    i, j = np.triu_indices(n, 1)
    d = d[i, j]
    r = np.linalg.norm(d, axis=1)
    overlap = radius[i] + radius[j] - r
    keep = overlap > 0
    i, j, d, r, overlap = i[keep], j[keep], d[keep], r[keep], overlap[keep]
    u = d / r[:, None]
    rate = -((velocity[j] - velocity[i]) * u).sum(1)
    fn = stiffness * overlap + damping * rate
    force = np.zeros((n, 3))
    np.add.at(force, j, fn[:, None] * u)
    np.add.at(force, i, -fn[:, None] * u)
    return force, float((0.5 * stiffness * overlap**2).sum())


def reciprocal_energy_strained(position, dipole, box, prefactor, alpha, vacuum, kmax, kcut, strain):
    """The reciprocal and surface energy of the spheres and box deformed by (1 + strain) (any 3x3
    strain, shears too: the box's wave vectors become (1 + strain)^-T k), for checking the virial by
    finite differences; the wave vectors are those of the undeformed box (the same sum): a formula of
    its own for the energy, beside demkit.interactions.ewald_virial's derivative of it."""
    from demkit.interactions.ewald_virial import half_space
    deform = np.eye(3) + np.asarray(strain, dtype=np.float64)
    x = np.asarray(position, dtype=np.float64) @ deform.T
    m = np.asarray(dipole, dtype=np.float64)
    volume = float(np.prod(box)) * float(np.linalg.det(deform))
    k = half_space(box, kmax, kcut) @ np.linalg.inv(deform)   # rows: (F^-T k)^T
    k2 = np.einsum("ij,ij->i", k, k)
    phase = np.exp(1j * (k @ x.T))
    big_s = np.einsum("ka,ka->k", k, phase @ m)
    energy = 4.0 * math.pi * prefactor / volume * float(np.sum(np.exp(-k2 / (4.0 * alpha * alpha)) / k2
                                                              * (big_s * big_s.conj()).real))
    if vacuum:
        total = m.sum(axis=0)
        energy += 2.0 * math.pi * prefactor / (3.0 * volume) * float(total @ total)
    return energy
