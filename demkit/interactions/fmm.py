"""Dipoles of a large open cluster by a fast multipole method (Flatiron Institute's FMM3D).

``Dipole(prefactor, long_range=FMM(accuracy))`` in open space sums every pair of moments in
O(N log N) instead of the exact O(N^2) loop. FMM3D's Laplace sum with dipole vectors v_j = m_j
returns, at every source x_i without its own term,

    u_i = sum_j m_j.(x_i - x_j) / (4 pi |x_i - x_j|^3),  its gradient g_i and Hessian H_i

(pinned by tests/test_fmm.py against a pair of dipoles). The magnetic scalar potential is
phi = 4 pi A u, the field B = -grad phi, so that for each dipole

    B_i = -4 pi A g_i,   tau_i = m_i x B_i,   F_i = grad(m_i.B)(x_i) = -4 pi A H_i m_i,
    U   = -1/2 sum_i m_i.B_i = 2 pi A sum_i m_i.g_i

(the same force, torque and energy as the exact pair sum of :mod:`demkit.interactions.dipole`).
``accuracy`` is FMM3D's requested precision ``eps`` (its error relative to the sums' size; the
force error against the exact sum is measured in benchmarks/bench_fmm.py and docs/long_range.md).
The sum runs in Python (FMM3D's compiled library, through numba's object mode) once per force
evaluation: tens of microseconds of overhead, nothing against a sum over thousands of dipoles.

Below its crossover the exact sum is cheaper: with ``exact_below="auto"`` (the default) a scene of
fewer than :meth:`FMM.crossover` spheres, N* = 2 c_FMM(eps) / c_pair (the N where N c_FMM equals the
exact loop's N^2/2 pairs; about 3400, 10 600 and 17 800 spheres at eps 1e-3, 1e-6, 1e-9 with the
constants of :mod:`demkit.cost`, measured crossovers 3500, 10 000 and 15 000 in
benchmarks/results/fmm.json), keeps the exact all-pairs sum (exact to round-off, so more accurate
than asked) and says so (``Dipole.long_range_note``, ``demkit info``); ``exact_below=0`` always uses
the FMM.

FMM3D is optional: ``pip install "demkit[fmm]"`` (the package ``fmm3dpy``), imported only when a
scene uses it. Contacts keep their own short neighbour list.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit, objmode

from .base import positive

#: table of a tuned sum in the scene's params: A, eps
TABLE_SIZE = 2
INSTALL = 'pip install "demkit[fmm]"'


def fmm3d():
    """The fmm3dpy module, or ImportError naming how to install it."""
    try:
        import fmm3dpy
    except ImportError:
        raise ImportError(f"Dipole(long_range=FMM(...)) needs FMM3D's Python package fmm3dpy: {INSTALL} "
                          f"(or pip install fmm3dpy)") from None
    return fmm3dpy


def evaluate(position, dipole, prefactor, eps, force, torque, with_forces):
    """Energy of every dipole pair (module docstring); adds forces and torques when asked."""
    n = position.shape[0]
    if n < 2:
        return 0.0
    out = fmm3d().lfmm3d(eps=eps, sources=np.ascontiguousarray(position.T), dipvec=np.ascontiguousarray(dipole.T),
                         pg=3 if with_forces else 2)
    grad = out.grad  # (3, N)
    energy = 2.0 * math.pi * prefactor * float(np.einsum("ij,ji->", dipole, grad))
    if with_forces:
        field = -4.0 * math.pi * prefactor * grad.T
        torque += np.cross(dipole, field)
        h = out.hess  # (6, N): xx, yy, zz, xy, xz, yz
        mx, my, mz = dipole[:, 0], dipole[:, 1], dipole[:, 2]
        c = -4.0 * math.pi * prefactor
        force[:, 0] += c * (h[0] * mx + h[3] * my + h[4] * mz)
        force[:, 1] += c * (h[3] * mx + h[1] * my + h[5] * mz)
        force[:, 2] += c * (h[4] * mx + h[5] * my + h[2] * mz)
    return energy


def field(position, dipole, prefactor, eps):
    """(N, 3) field at each dipole from all the others, B_i = -4 pi A g_i."""
    if len(position) < 2:
        return np.zeros((len(position), 3))
    out = fmm3d().lfmm3d(eps=eps, sources=np.ascontiguousarray(np.asarray(position, dtype=np.float64).T),
                         dipvec=np.ascontiguousarray(np.asarray(dipole, dtype=np.float64).T), pg=2)
    return -4.0 * math.pi * prefactor * out.grad.T


@njit(cache=True)
def fmm_sum(position, dipole, box, params, start, force, torque, with_forces, status):
    """The whole dipole sum by FMM3D (the kernels' long-range call): energy, and with
    ``with_forces`` forces and torques added; params[start:start + 2] = A, eps (``status``: the
    run's, as for every long-range sum; an open sum flags nothing)."""
    prefactor = params[start]
    eps = params[start + 1]
    # fresh arrays into object mode: numba boxes a view of an array (multiple time stepping passes
    # rows of its stage array) as the whole parent array, so Python would see the wrong shape
    f = np.zeros(force.shape)
    t = np.zeros(torque.shape)
    with objmode(energy="float64"):
        energy = evaluate(position, dipole, prefactor, eps, f, t, with_forces)
    if with_forces:
        force += f
        torque += t
    return energy


#: seconds per sphere of a fast multipole sum at eps 1e-3, and more per further digit of eps (FMM3D
#: with gradients and Hessians, N >= 1e4: 3.4e-5, 9.5e-5 and 1.8e-4 s at 1e-3, 1e-6, 1e-9;
#: benchmarks/bench_fmm.py); demkit.cost estimates runs with them
FMM_SPHERE, FMM_SPHERE_PER_DIGIT = 3.4e-5, 2.4e-5
#: seconds per pair of the exact (all-pairs) sum of dipoles, which the FMM replaces above its crossover
ALL_PAIR = 2.0e-8


def fmm_sphere_seconds(accuracy):
    """Seconds per sphere of a fast multipole sum at FMM3D precision ``accuracy`` (one core):
    FMM_SPHERE + FMM_SPHERE_PER_DIGIT per digit of eps beyond the third."""
    digits = max(-math.log10(accuracy), 1.0)
    return FMM_SPHERE + FMM_SPHERE_PER_DIGIT * (digits - 3.0)

class FMM:
    """Settings of a fast multipole sum: ``Dipole(prefactor, long_range=FMM(accuracy=1e-9))``.

    accuracy : FMM3D's precision eps, 0 < accuracy < 1 (module docstring).
    exact_below : scenes of fewer spheres keep the exact all-pairs sum; "auto" (default): the
        crossover :meth:`crossover`; 0: always the FMM.

    Open space only (no box, or a box with no periodic axis), the Dipole without a cutoff; needs
    ``pip install "demkit[fmm]"`` when the FMM is used.
    """

    def __init__(self, accuracy=1e-9, exact_below="auto"):
        accuracy = positive("FMM accuracy", accuracy)
        if not accuracy < 1.0:
            raise ValueError(f"FMM accuracy is FMM3D's relative precision, between 0 and 1, got {accuracy!r}")
        if accuracy < 1e-14:
            raise ValueError(f"FMM accuracy {accuracy!r} is below what double precision can reach (1e-14)")
        if exact_below != "auto":
            if (isinstance(exact_below, (bool, str)) or not isinstance(exact_below, (int, float, np.number))
                    or not (exact_below >= 0 and float(exact_below).is_integer())):
                raise ValueError(f"FMM exact_below is a whole number of spheres (0: always the FMM) or \"auto\" "
                                 f"(the crossover with the exact sum), got {exact_below!r}")
            exact_below = int(exact_below)
        self.accuracy = accuracy
        self.exact_below = exact_below

    def crossover(self):
        """Number of spheres from which the FMM is estimated cheaper than the exact all-pairs sum:
        2 c_FMM / c_pair with :func:`fmm_sphere_seconds` and :data:`ALL_PAIR` (one core)."""
        return int(round(2.0 * fmm_sphere_seconds(self.accuracy) / ALL_PAIR))

    def uses_exact_sum(self, n):
        """Does a scene of n spheres keep the exact sum (fewer than ``exact_below`` spheres)?"""
        threshold = self.crossover() if self.exact_below == "auto" else self.exact_below
        return n < threshold

    def tune(self, prefactor, particles, box, cutoff=None):
        """:class:`TunedFMM` for these spheres, or None where the exact sum is cheaper
        (:meth:`uses_exact_sum`); ValueError in a periodic box or with a cutoff, ImportError
        without fmm3dpy when the FMM is used."""
        if box is not None and any(box.periodic):
            raise ValueError("a fast multipole sum is for open space: this box is periodic along "
                             f"{''.join(a for a, f in zip('xyz', box.periodic) if f)}; use long_range=dk.Ewald(...) "
                             f"in a periodic box")
        if cutoff is not None:
            raise ValueError(f"a Dipole with long_range=FMM(...) takes no cutoff (the sum covers every pair), "
                             f"got cutoff={cutoff!r}")
        if self.uses_exact_sum(len(particles)):
            return None
        fmm3d()
        return TunedFMM(self, prefactor)

    def note(self, n):
        """What a scene of n spheres uses, in words (``Dipole.long_range_note``)."""
        if self.uses_exact_sum(n):
            why = (f"below the crossover of ~{self.crossover()} spheres" if self.exact_below == "auto"
                   else f"fewer than exact_below={self.exact_below}")
            return f"{self!r}: the exact all-pairs sum of {n} spheres ({why}; exact to round-off)"
        return f"{self!r}: a fast multipole sum of {n} spheres"

    def __repr__(self):
        extra = "" if self.exact_below == "auto" else f", exact_below={self.exact_below!r}"
        return f"FMM(accuracy={self.accuracy!r}{extra})"


class TunedFMM:
    """A fast multipole sum bound to a scene: ``accuracy`` (eps), ``prefactor``."""

    energy_kind = "magnetic"
    #: the compiled function the kernels call once per force evaluation (module, name)
    kernel = ("demkit.interactions.fmm", "fmm_sum")
    #: an open-space sum has no slab layer (demkit.interactions.slab)
    layer = None

    def __init__(self, settings, prefactor):
        self.settings = settings
        self.prefactor = prefactor

    @property
    def estimated_error(self):
        return self.settings.accuracy

    def adapt(self, dipole):
        """Make the scene's copy of the Dipole leave every pair to this sum (no pair loop)."""
        dipole.pair_loop = False

    def field(self, particles, box):
        """(N, 3) field at each sphere from all the others."""
        return field(particles.position, particles.dipole, self.prefactor, self.settings.accuracy)

    def virial(self, particles, box):
        """(W (3, 3), each sphere's share (N, 3, 3)) of the sum, in the pair virial's convention
        W = sum over pairs of d_ij (x) f_ij (d_ij = x_j - x_i, f_ij the force on j), which for pair
        forces is sum_i x_i (x) F_i: taken from FMM3D's forces as sum_i (x_i - xbar) (x) F_i, about
        the mean position xbar (the same for exact forces, whose sum is zero; independent of the
        origin for the sum's, whose total is zero only to its accuracy). Each sphere's share is its
        own term (x_i - xbar) (x) F_i: half of each pair, the pair sums' convention, would need the
        pair forces, which an FMM never forms."""
        x = np.asarray(particles.position, dtype=np.float64)
        force = np.zeros_like(x)
        evaluate(x, np.asarray(particles.dipole, dtype=np.float64), self.prefactor, self.settings.accuracy, force,
                 np.zeros_like(x), True)
        shares = (x - x.mean(axis=0))[:, :, None] * force[:, None, :]
        return shares.sum(axis=0), shares

    def table_values(self):
        return np.array([self.prefactor, self.settings.accuracy], dtype=np.float64)

    def __repr__(self):
        return f"TunedFMM(accuracy={self.settings.accuracy!r})"
