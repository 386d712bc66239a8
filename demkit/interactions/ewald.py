"""Dipolar Ewald sum: every dipole of a periodic box with every other and all their images.

The dipole-dipole energy of a periodic box, U = (A/2) sum_n sum_ij' [m_i.m_j - 3 (m_i.n)(m_j.n)]/r^3
over the images n (conditionally convergent: its value depends on the shape of the summed region
and what surrounds it), is split with a Gaussian screening of width 1/alpha into

* a real-space pair sum, short-ranged, on the neighbour lists (d = x_j - x_i, r = |d|):

      U_ij = A [(m_i.m_j) B(r) - (m_i.d)(m_j.d) C(r)]
      B = [erfc(a r) + (2 a r/sqrt(pi)) exp(-a^2 r^2)] / r^3
      C = [3 erfc(a r) + (2 a r/sqrt(pi)) (3 + 2 a^2 r^2) exp(-a^2 r^2)] / r^5
      D = [15 erfc(a r) + (2 a r/sqrt(pi)) (15 + 10 a^2 r^2 + 4 a^4 r^4) exp(-a^2 r^2)] / r^7
      F_j = A [(m_i.m_j) C d + (m_j.d) C m_i + (m_i.d) C m_j - (m_i.d)(m_j.d) D d]
      tau_i = A [C (m_j.d)(m_i x d) - B (m_i x m_j)],  tau_j = A [C (m_i.d)(m_j x d) + B (m_i x m_j)]

  (a -> 0 gives the bare dipole pair of :mod:`demkit.interactions.dipole`);
* a reciprocal-space sum over the wave vectors k = 2 pi (p/Lx, q/Ly, r/Lz) != 0 with |k| <= k_c,
  S(k) = sum_j (m_j.k) exp(i k.x_j), g(k) = exp(-k^2 / 4 a^2) / k^2, V the box volume:

      U_k   = (2 pi A / V) sum_k g |S|^2
      F_i   = (4 pi A / V) sum_k g (m_i.k) k Im[S* exp(i k.x_i)]
      H_i   = -(4 pi A / V) sum_k g k Re[S* exp(i k.x_i)],   tau_i = m_i x H_i

  (computed over half the k-space, k and -k giving equal terms);
* the self term U_self = -A (2 a^3 / 3 sqrt(pi)) sum_i |m_i|^2 (no force, no torque);
* the surface term of a large sphere of boxes in vacuum, U_surf = (2 pi A / 3V) |M|^2 with
  M = sum_i m_i (field -(4 pi A / 3V) M on every dipole, no force); none with metallic
  ("tin-foil") surroundings, the default, as in ESPResSo and LAMMPS.

A box periodic along two axes only (a slab) is summed as a 3-D box drawn out along its open axis
with an empty gap, plus the layer term of Yeh and Berkowitz (:mod:`demkit.interactions.slab`): the
lengths L and volume V above are then those of the drawn-out box.

Parameters are tuned to a requested relative root-mean-square force error (``accuracy``) from the
error estimates of Wang and Holm, J. Chem. Phys. 115, 6351 (2001): real space (their eq. 37, M^2 =
sum_i |m_i|^2, N dipoles, r_c the real-space cutoff)

    dF_r = A M^2 / sqrt(V a^4 r_c^9 N) sqrt(13/6 C_c^2 + 2/15 D_c^2 - 13/15 C_c D_c) exp(-a^2 r_c^2),
    C_c = 4 (a r_c)^4 + 6 (a r_c)^2 + 3,  D_c = 8 (a r_c)^6 + 20 (a r_c)^4 + 30 (a r_c)^2 + 15,

and reciprocal space (their eq. 46, per axis of length L with k_max = L k_c / 2 pi)

    dF_k = 8 pi A M^2 a / V sqrt(2 pi k_max^3 / (15 N)) exp(-(pi k_max / (a L))^2).

The error is relative to the pull 6 A m^2 / d^4 of two touching spheres (d the mean diameter, m the
root-mean-square moment) with head-to-tail moments: ``accuracy=1e-6`` asks for an RMS force error
of a millionth of that pull. Each part gets half the squared error budget; among the cutoffs that
meet it, the one with the fewest estimated operations per evaluation is kept. The estimates assume
random moments: the whole error of the choice is then measured on a :class:`Sample` with the
scene's moments and the target tightened while it exceeds MARGIN of the accuracy (polarised samples).
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from ..engine.motion import KERNEL_OPTIONS
from .base import positive
from .special_functions import erfc_scaled, screened
from .slab import Layer, check_layer, gap_error, gap_for, layer_terms, open_axis, table_entries, thick_box_hint

SURFACES = ("metallic", "vacuum")
#: time per (sphere, wave vector) of the reciprocal sum against one real-space pair within the
#: cutoff, which decides the cutoff the tuning keeps: 6 ns against ~75 ns (erfc and exp, and the
#: listed pairs within the skin; benchmarks/bench_ewald.py, benchmarks/results/ewald.json)
RECIPROCAL_COST = 0.08
#: more wave vectors than this are refused (a cutoff far too short for the accuracy asked)
MAX_WAVE_VECTORS = 2e6
#: table of a tuned sum in the scene's params: A, alpha, vacuum (0/1), kx, ky, kz maxima, k_c^2, the three
#: lengths of the periodic box summed (a slab's drawn out along its open axis), the open axis (-1: none)
#: and the layer's thickness (demkit.interactions.slab)
TABLE_SIZE = 12
RECIPROCAL_OPTIONS = dict(cache=True, fastmath={"contract", "arcp"}, error_model="numpy")


@njit(**KERNEL_OPTIONS)
def ewald_real_force(i, j, dx, dy, dz, r2, dipole, prefactor, alpha):
    """Force on j and torques on i and j of the screened real-space pair (module docstring)."""
    r = math.sqrt(r2)
    inv_r2 = 1.0 / r2
    ar = alpha * r
    a2r2 = ar * ar
    erfc, gauss = screened(ar)  # erfc(a r), (2 a r / sqrt(pi)) exp(-a^2 r^2); vectorises
    b = prefactor * (erfc + gauss) * inv_r2 / r
    c = prefactor * (3.0 * erfc + gauss * (3.0 + 2.0 * a2r2)) * inv_r2 * inv_r2 / r
    d = prefactor * (15.0 * erfc + gauss * (15.0 + a2r2 * (10.0 + 4.0 * a2r2))) * inv_r2 * inv_r2 * inv_r2 / r
    ax = dipole[i, 0]
    ay = dipole[i, 1]
    az = dipole[i, 2]
    bx = dipole[j, 0]
    by = dipole[j, 1]
    bz = dipole[j, 2]
    ad = ax * dx + ay * dy + az * dz
    bd = bx * dx + by * dy + bz * dz
    ab = ax * bx + ay * by + az * bz
    radial = ab * c - ad * bd * d
    fx = radial * dx + c * (bd * ax + ad * bx)
    fy = radial * dy + c * (bd * ay + ad * by)
    fz = radial * dz + c * (bd * az + ad * bz)
    cx = ay * bz - az * by
    cy = az * bx - ax * bz
    cz = ax * by - ay * bx
    si = c * bd
    sj = c * ad
    tix = si * (ay * dz - az * dy) - b * cx
    tiy = si * (az * dx - ax * dz) - b * cy
    tiz = si * (ax * dy - ay * dx) - b * cz
    tjx = sj * (by * dz - bz * dy) + b * cx
    tjy = sj * (bz * dx - bx * dz) + b * cy
    tjz = sj * (bx * dy - by * dx) + b * cz
    return fx, fy, fz, tix, tiy, tiz, tjx, tjy, tjz


@njit(**KERNEL_OPTIONS)
def ewald_real_energy(i, j, dx, dy, dz, r2, dipole, prefactor, alpha):
    """U_ij = A [(m_i.m_j) B(r) - (m_i.d)(m_j.d) C(r)]."""
    r = math.sqrt(r2)
    ar = alpha * r
    a2r2 = ar * ar
    erfc, gauss = screened(ar)
    b = (erfc + gauss) / (r2 * r)
    c = (3.0 * erfc + gauss * (3.0 + 2.0 * a2r2)) / (r2 * r2 * r)
    ad = dipole[i, 0] * dx + dipole[i, 1] * dy + dipole[i, 2] * dz
    bd = dipole[j, 0] * dx + dipole[j, 1] * dy + dipole[j, 2] * dz
    ab = dipole[i, 0] * dipole[j, 0] + dipole[i, 1] * dipole[j, 1] + dipole[i, 2] * dipole[j, 2]
    return prefactor * (ab * b - ad * bd * c)


@njit(**dict(RECIPROCAL_OPTIONS, inline="always"))  # (called with the axes 0, 1, 2: compiled on its own, numba
def _phases(position, box, kmax, axis):                # made one copy per literal axis, 0.7 CPU s per install)
    """cos and sin of (2 pi m / L) x along one axis for m = 0..kmax: two (kmax + 1, N) arrays."""
    n = position.shape[0]
    cos_, sin_ = np.empty((kmax + 1, n)), np.empty((kmax + 1, n))
    unit = 2.0 * math.pi / box[axis]
    for j in range(n):
        c1 = math.cos(unit * position[j, axis])
        s1 = math.sin(unit * position[j, axis])
        cos_[0, j] = 1.0
        sin_[0, j] = 0.0
        for m in range(1, kmax + 1):
            cos_[m, j] = cos_[m - 1, j] * c1 - sin_[m - 1, j] * s1
            sin_[m, j] = sin_[m - 1, j] * c1 + cos_[m - 1, j] * s1
    return cos_, sin_


@njit(**RECIPROCAL_OPTIONS)
def reciprocal_sum(position, dipole, box, params, start, force, torque, with_forces, status):
    """The reciprocal, self and surface terms of the dipolar Ewald sum (module docstring) with the
    table at params[start:start + TABLE_SIZE]; adds forces and torques when ``with_forces``;
    returns their energy. A slab's spheres out of its layer flag LEFT_LAYER in ``status`` (the
    run's, as the long-range sums' last argument)."""
    if with_forces:
        check_layer(position, params, start + 10, status)
    field = np.zeros((position.shape[0] if with_forces else 0, 3))
    energy = reciprocal_terms(position, dipole, box, params, start, force, field, with_forces)
    for i in range(field.shape[0]):
        torque[i, 0] += dipole[i, 1] * field[i, 2] - dipole[i, 2] * field[i, 1]
        torque[i, 1] += dipole[i, 2] * field[i, 0] - dipole[i, 0] * field[i, 2]
        torque[i, 2] += dipole[i, 0] * field[i, 1] - dipole[i, 1] * field[i, 0]
    return energy


@njit(**RECIPROCAL_OPTIONS)
def reciprocal_terms(position, dipole, box, params, start, force, field, with_forces):
    """:func:`reciprocal_sum`'s work: its energy, and with ``with_forces`` its forces added to
    ``force`` and the field of the reciprocal and surface terms (torque m x field) to ``field``."""
    prefactor = params[start]
    alpha = params[start + 1]
    vacuum = params[start + 2] != 0.0
    px, py, pz = int(params[start + 3]), int(params[start + 4]), int(params[start + 5])
    kcut2 = params[start + 6]
    size = params[start + 7:start + 10]  # the box summed (a slab's drawn out; ``box`` is the scene's)
    axis = int(params[start + 10])
    n = position.shape[0]
    volume = size[0] * size[1] * size[2]
    ux, uy, uz = 2.0 * math.pi / size[0], 2.0 * math.pi / size[1], 2.0 * math.pi / size[2]
    cx, sx = _phases(position, size, px, 0)
    cy, sy = _phases(position, size, py, 1)
    cz, sz = _phases(position, size, pz, 2)
    re = np.empty(n)
    im = np.empty(n)
    mk = np.empty(n)
    scale = 4.0 * math.pi * prefactor / volume  # half of k-space: twice (2 pi A / V)
    quarter = 0.25 / (alpha * alpha)
    total = 0.0
    for p in range(px + 1):
        for q in range(-py, py + 1):
            for r in range(-pz, pz + 1):
                if p == 0 and (q < 0 or (q == 0 and r <= 0)):
                    continue  # -k of a vector counted already (and k = 0)
                kx, ky, kz = p * ux, q * uy, r * uz
                k2 = kx * kx + ky * ky + kz * kz
                if k2 > kcut2:
                    continue
                g = math.exp(-k2 * quarter) / k2
                qq, rr = abs(q), abs(r)
                sq = 1.0 if q >= 0 else -1.0
                sr = 1.0 if r >= 0 else -1.0
                s_re = 0.0
                s_im = 0.0
                for j in range(n):  # exp(i k.x_j) from the axis phases, and S(k)
                    yr, yi = cy[qq, j], sq * sy[qq, j]
                    zr, zi = cz[rr, j], sr * sz[rr, j]
                    yzr = yr * zr - yi * zi
                    yzi = yr * zi + yi * zr
                    er = cx[p, j] * yzr - sx[p, j] * yzi
                    ei = cx[p, j] * yzi + sx[p, j] * yzr
                    m = dipole[j, 0] * kx + dipole[j, 1] * ky + dipole[j, 2] * kz
                    re[j], im[j], mk[j] = er, ei, m
                    s_re += m * er
                    s_im += m * ei
                total += g * (s_re * s_re + s_im * s_im)
                if not with_forces:
                    continue
                w = 2.0 * scale * g
                for i in range(n):
                    f = w * mk[i] * (s_re * im[i] - s_im * re[i])  # Im[S* exp(i k.x_i)]
                    h = -w * (s_re * re[i] + s_im * im[i])         # Re[S* exp(i k.x_i)]
                    force[i, 0] += f * kx
                    force[i, 1] += f * ky
                    force[i, 2] += f * kz
                    field[i, 0] += h * kx
                    field[i, 1] += h * ky
                    field[i, 2] += h * kz
    energy = scale * total
    squares = 0.0
    mx, my, mz = 0.0, 0.0, 0.0
    for i in range(n):
        squares += dipole[i, 0] ** 2 + dipole[i, 1] ** 2 + dipole[i, 2] ** 2
        mx += dipole[i, 0]
        my += dipole[i, 1]
        mz += dipole[i, 2]
    energy -= prefactor * 2.0 * alpha ** 3 / (3.0 * math.sqrt(math.pi)) * squares
    if vacuum:
        energy += 2.0 * math.pi * prefactor / (3.0 * volume) * (mx * mx + my * my + mz * mz)
    if axis >= 0:
        energy += layer_terms(dipole, axis, volume, prefactor, field, with_forces)
    if not with_forces:
        return energy
    if vacuum:
        surface = 4.0 * math.pi * prefactor / (3.0 * volume)
        for i in range(n):
            field[i, 0] -= surface * mx
            field[i, 1] -= surface * my
            field[i, 2] -= surface * mz
    return energy


def field_of_others(tuned, particles, box):
    """(N, 3) field at each sphere from all the others and their images: the reciprocal and surface
    terms plus the self correction (the real-space part is the caller's: pairs within the cutoff)."""
    n = len(particles)
    field = np.zeros((n, 3))
    reciprocal_terms(np.ascontiguousarray(particles.position, dtype=np.float64),
                     np.ascontiguousarray(particles.dipole, dtype=np.float64), np.array(box.size, dtype=np.float64),
                     tuned.table_values(), 0, np.zeros((n, 3)), field, True)
    return field + self_field(tuned.prefactor, tuned.alpha, particles.dipole)


def self_field(prefactor, alpha, dipole):
    """(4 a^3 / 3 sqrt(pi)) A m_i: what removes each sphere's own share of the wave-vector (or mesh)
    sum from the field it feels (parallel to m_i: no torque)."""
    return prefactor * 4.0 * alpha ** 3 / (3.0 * math.sqrt(math.pi)) * np.asarray(dipole)


def screening(alpha, r):
    """B(r), C(r), D(r) of the real-space pair (module docstring), numpy arrays over r (erfc as the pair
    loops', erfcx(x) exp(-x^2), demkit.interactions.special_functions, in numpy: scipy.special's import
    cost every new Ewald or P3M scene 0.27 CPU s)."""
    ar = np.asarray(alpha * r, dtype=float)
    a2r2 = ar * ar
    gaussian = np.exp(-a2r2)
    gauss = 2.0 / math.sqrt(math.pi) * ar * gaussian
    e = erfc_scaled.py_func(ar) * gaussian
    return ((e + gauss) / r ** 3, (3.0 * e + gauss * (3.0 + 2.0 * a2r2)) / r ** 5,
            (15.0 * e + gauss * (15.0 + a2r2 * (10.0 + 4.0 * a2r2))) / r ** 7)


def real_space_field(tuned, d, r, mj):
    """Field at sphere i of its real-space partners j (separations d = x_j - x_i, distances r,
    moments mj, arrays over the pairs): A [C (m_j.d) d - B m_j], zero beyond the cutoff."""
    b, c, _ = screening(tuned.alpha, r)
    inside = r < tuned.cutoff
    md = np.einsum("ij,ij->i", mj, d)
    return tuned.prefactor * np.where(inside, 1.0, 0.0)[:, None] * (c[:, None] * md[:, None] * d - b[:, None] * mj)


def screened_pair(dipole, cutoff, alpha):
    """Make a (tuned copy of a) Dipole the screened real-space pair of an Ewald-split sum."""
    dipole.cutoff_distance = cutoff
    dipole.alpha = alpha
    dipole.force_function, dipole.energy_function = ewald_real_force, ewald_real_energy
    dipole.parameters = ("prefactor", "alpha")


def wave_vector_limits(target, prefactor, squares, n, volume, alpha, size):
    """(k_max per axis, k_c) for a reciprocal error of at most ``target`` along every axis: each
    axis reaches the sphere |k| <= k_c (a longer axis has finer wave numbers)."""
    kmax = [_kmax_for(target, prefactor, squares, n, volume, alpha, length) for length in size]
    kcut = max(2.0 * math.pi * k / length for k, length in zip(kmax, size))
    return (tuple(max(k, int(math.floor(kcut * length / (2.0 * math.pi) * (1 + 1e-12))))
                  for k, length in zip(kmax, size)), float(kcut))


def reciprocal_table(prefactor, alpha, vacuum, kmax, kcut, geometry):
    """The run-time table of :func:`reciprocal_sum` (its params[start:start + TABLE_SIZE]); ``geometry``:
    the entries of :meth:`demkit.interactions.slab.Layer.table` or :func:`~demkit.interactions.slab.table_entries`."""
    return np.array([prefactor, alpha, 1.0 if vacuum else 0.0, *kmax, kcut ** 2 * (1 + 1e-9), *geometry],
                    dtype=np.float64)


# ---- tuning ------------------------------------------------------------------------------------
def real_space_error(prefactor, squares, n, volume, alpha, cutoff):
    """Wang-Holm estimate of the real-space RMS force error (module docstring)."""
    a2 = (alpha * cutoff) ** 2
    c = 4.0 * a2 * a2 + 6.0 * a2 + 3.0
    d = 8.0 * a2 ** 3 + 20.0 * a2 * a2 + 30.0 * a2 + 15.0
    spread = math.sqrt(max(13.0 / 6.0 * c * c + 2.0 / 15.0 * d * d - 13.0 / 15.0 * c * d, 0.0))
    return prefactor * squares / math.sqrt(volume * alpha ** 4 * cutoff ** 9 * n) * spread * math.exp(-a2)


def reciprocal_error(prefactor, squares, n, volume, alpha, kmax, length):
    """Wang-Holm estimate of the reciprocal-space RMS force error along one axis of this length."""
    return (8.0 * math.pi * prefactor * squares * alpha / volume * math.sqrt(2.0 * math.pi * kmax ** 3 / (15.0 * n))
            * math.exp(-(math.pi * kmax / (alpha * length)) ** 2))


def _alpha_for(target, prefactor, squares, n, volume, cutoff):
    """The smallest splitting alpha whose real-space error at this cutoff is at most ``target``."""
    lo, hi = 1e-3 / cutoff, 1e-3 / cutoff
    while real_space_error(prefactor, squares, n, volume, hi, cutoff) > target:
        hi *= 1.5
        if hi * cutoff > 50.0:
            return None
    while lo > 1e-9 and real_space_error(prefactor, squares, n, volume, lo, cutoff) <= target:
        lo /= 2.0
    for _ in range(60):  # bisection in log alpha
        mid = math.sqrt(lo * hi)
        if real_space_error(prefactor, squares, n, volume, mid, cutoff) > target:
            lo = mid
        else:
            hi = mid
    return hi


def _kmax_for(target, prefactor, squares, n, volume, alpha, length):
    kmax = 1
    while reciprocal_error(prefactor, squares, n, volume, alpha, kmax, length) > target:
        kmax += 1
    return kmax


def scales(what, prefactor, particles, box, otherwise):
    """(N, sum |m|^2, V, the touching pull 6 A m_rms^2 / d^4, half the shortest periodic side, the open
    axis of a slab or -1) of a scene a periodic sum is tuned to; ValueError unless the box is periodic
    along every axis or along two (``otherwise`` says what to do) and some moment is not zero."""
    axis = open_axis(box, what, otherwise)
    n = len(particles)
    squares = float(np.einsum("ij,ij->", particles.dipole, particles.dipole))
    if squares == 0.0:
        raise ValueError(f"{what} needs dipole moments, but every moment is zero")
    diameter = 2.0 * float(np.mean(particles.radius))
    half = 0.5 * min(float(length) for length, flag in zip(box.size, box.periodic) if flag)
    return n, squares, box.volume, 6.0 * prefactor * squares / n / diameter ** 4, half, axis


def slab_layer(box, axis, target, prefactor, squares, n, cutoff, radius=None):
    """The :class:`~demkit.interactions.slab.Layer` of a slab whose copies pull with an estimated RMS
    force error of at most ``target`` (and at least the real-space ``cutoff`` away: no copy within
    it), or None for a box periodic along every axis. ``radius``: of magnetisable spheres, whose
    field error counts (weighted by pull / touching field, as in :class:`Sample`): the copies' field,
    one derivative less than their pull, weighs 3 / (2 q1 R) = 3 L_max / (4 pi R) times more."""
    if axis < 0:
        return None
    area, longest = Layer.periodic_lengths(box)
    if radius is not None:
        target /= max(1.0, 3.0 * longest / (4.0 * math.pi * radius))
    return Layer(box, axis, max(gap_for(target, prefactor, squares, n, area, longest), cutoff))


#: spheres of the sample a tuned sum's whole error is measured on
SAMPLE = 200
#: Ewald tuning: the sample's measured error must be at most MARGIN of the accuracy (a 200-sphere
#: sample measures the error to ~5 %, and a random sample is not the scene: 0.9 leaves two of
#: those); when it is not, the target is tightened by TIGHTEN times the excess, up to MEASURED_TRIES times
MARGIN = 0.9
MEASURED_TRIES = 4
TIGHTEN = 0.85


class Sample:
    """Up to SAMPLE spheres at random places in the scene's box (a slab's across its layer where the
    scene's spheres are) with moments drawn from the scene's,
    and the exact Ewald forces on them (a real-space and a wave-vector sum converged ten times
    below the target): the reference a tuned sum's whole error is measured against (P3M's mesh,
    and Ewald's estimates, which assume random moments, in polarised samples). ``ready`` is False
    when no converged reference can be tuned (accuracies near round-off)."""

    def __init__(self, particles, box, prefactor, target, axis=-1):
        rng = np.random.default_rng(12345)
        n = len(particles)
        self.m = m = min(n, SAMPLE)
        self.scale = math.sqrt(n / m)  # errors of random sums grow as the square root of the count
        # (a writable copy: Box.size is read-only, and numba compiles reciprocal_terms again, 2 CPU s, for a
        # read-only array)
        self.size = size = np.array(box.size, dtype=np.float64)
        self.periodic = np.asarray(box.periodic, dtype=bool)
        self.axis = axis  # a slab's open axis (-1: none)
        self.position = rng.uniform(0.0, 1.0, (m, 3)) * size
        if axis >= 0:  # a slab's sample across the layer as the scene's spheres are (a monolayer stays one)
            self.position[:, axis] = np.asarray(particles.position, dtype=np.float64)[rng.choice(n, m, replace=False),
                                                                                        axis]
        self._separations = None  # (d, r2) of _pairs
        self.dipole = np.asarray(particles.dipole, dtype=np.float64)[rng.choice(n, m, replace=False)]
        self.prefactor = prefactor
        squares = float(np.einsum("ij,ij->", self.dipole, self.dipole))
        # magnetisable spheres: their moments follow the field, whose error counts as much as the
        # forces' (relative to the field of a touching neighbour, 2 A m/d^3, where the pull is 6 A m^2/d^4)
        chi = getattr(particles, "susceptibility", None)
        self.fields = chi is not None and bool(np.any(np.asarray(chi) > 0.0))
        moment = math.sqrt(float(np.einsum("ij,ij->", particles.dipole, particles.dipole)) / n)
        self.field_weight = 3.0 * moment / (2.0 * float(np.mean(particles.radius)))  # pull / touching field
        self.radius = float(np.mean(particles.radius)) if self.fields else None  # (for a slab's gap)
        # the reference converged ten times below the target; for fields a hundred times more (its
        # parameters come from the forces' error estimates, which the field's error exceeds ~6-fold)
        fine = (0.001 if self.fields else 0.1) * target / self.scale
        cutoff = 0.999 * 0.5 * float(size[self.periodic].min())
        alpha = _alpha_for(fine, prefactor, squares, m, box.volume, cutoff)
        self.ready = alpha is not None and squares > 0.0
        if not self.ready:
            return
        # a slab's reference: its copies a gap far longer away (its estimated pull at the fine target)
        self.layer = slab_layer(box, axis, fine, prefactor, squares, m, cutoff, self.radius)
        summed = size if self.layer is None else np.asarray(self.layer.size)
        kmax, kcut = wave_vector_limits(fine, prefactor, squares, m, float(np.prod(summed)), alpha, summed)
        force, field = self.reciprocal(alpha, kmax, kcut, summed)
        self.exact = force + self.real_forces(alpha, cutoff)
        if self.fields:
            self.exact_field = self.field_term(alpha, field + self.real_field(alpha, cutoff))

    def _pairs(self, alpha, cutoff):
        """Minimum-image separations d[i, j] = x_j - x_i and the screening B, C, D within ``cutoff``
        (the separations computed once: the tuning asks for many cutoffs and splittings)."""
        if self._separations is None:
            x = self.position
            d = x[None, :, :] - x[:, None, :]
            d -= np.where(self.periodic, self.size, 0.0) * np.round(d / self.size)
            r2 = np.einsum("ijk,ijk->ij", d, d)
            np.fill_diagonal(r2, np.inf)
            self._separations = d, r2
        d, r2 = self._separations
        inside = r2 < cutoff * cutoff
        b, c, dd = screening(alpha, np.sqrt(np.where(inside, r2, 1.0)))
        return d, np.where(inside, b, 0.0), np.where(inside, c, 0.0), np.where(inside, dd, 0.0)

    def real_field(self, alpha, cutoff):
        """(m, 3) field of the screened real-space pairs within ``cutoff``: A [C (m_j.d) d - B m_j]."""
        d, b, c, _ = self._pairs(alpha, cutoff)
        bd = np.einsum("jk,ijk->ij", self.dipole, d)
        return self.prefactor * ((c * bd)[:, :, None] * d - b[:, :, None] * self.dipole[None, :, :]).sum(axis=1)

    def field_term(self, alpha, field):
        """A candidate's whole field on the sample (its real-space part at ``field``'s splitting added
        by the caller): ``field`` plus the self correction at ``alpha``."""
        return field + self_field(self.prefactor, alpha, self.dipole)

    def real_forces(self, alpha, cutoff):
        """(m, 3) forces of the screened real-space pairs within ``cutoff`` (minimum image)."""
        mu = self.dipole
        d, _, c, dd = self._pairs(alpha, cutoff)
        ab = np.einsum("ik,jk->ij", mu, mu)
        ad = np.einsum("ik,ijk->ij", mu, d)   # m_i . d
        bd = np.einsum("jk,ijk->ij", mu, d)   # m_j . d
        on_j = self.prefactor * ((ab * c - ad * bd * dd)[:, :, None] * d + c[:, :, None]
                                 * (bd[:, :, None] * mu[:, None, :] + ad[:, :, None] * mu[None, :, :]))
        return -on_j.sum(axis=1)  # the force on i of each pair (i, j) is minus that on j

    def reciprocal(self, alpha, kmax, kcut, summed):
        """(forces, field), each (m, 3), of the wave-vector sum with these limits (metallic surroundings)
        over a periodic box of lengths ``summed`` (a slab's: drawn out, with its layer term)."""
        force, field = np.zeros((self.m, 3)), np.zeros((self.m, 3))
        table = reciprocal_table(self.prefactor, alpha, False, kmax, kcut, self.geometry(summed))
        reciprocal_terms(self.position, self.dipole, self.size, table, 0, force, field, True)
        return force, field

    def geometry(self, summed):
        """The table entries of a candidate summing a periodic box of lengths ``summed``."""
        return table_entries(summed, self.axis, self.size[self.axis] if self.axis >= 0 else 0.0)

    def error_of(self, force, field=None):
        """RMS error of these (m, 3) sample forces against the exact ones, scaled to the scene's count;
        for magnetisable spheres (``fields``) the larger of it and the RMS error of the ``field``, in
        force units (times pull / touching field)."""
        error = math.sqrt(np.mean(((force - self.exact) ** 2).sum(1))) * self.scale
        if self.fields and field is not None:
            error = max(error, math.sqrt(np.mean(((field - self.exact_field) ** 2).sum(1))) * self.scale
                        * self.field_weight)
        return error


class Ewald:
    """Settings of a dipolar Ewald sum: ``Dipole(prefactor, long_range=Ewald(...))``.

    accuracy : relative RMS force error the sum is tuned to, 0 < accuracy < 1: the error against
        the pull 6 A m^2/d^4 of two touching head-to-tail spheres (module docstring).
    surface : "metallic" (default; tin-foil surroundings, no surface term) or "vacuum" (a large
        sphere of boxes in vacuum: the surface term (2 pi A / 3V) |M|^2).
    alpha : the splitting parameter (1/length); None: tuned with the cutoff.

    The real-space cutoff is the Dipole's ``cutoff`` (None: tuned); the box must be periodic along
    all three axes, or along two: a slab (:mod:`demkit.interactions.slab`; its spheres stay within the
    box's length along the open axis, and ``surface`` is left out). The tuned values are in
    ``scene.long_range`` (see :class:`TunedEwald`).
    """

    def __init__(self, accuracy=1e-6, surface="metallic", alpha=None):
        accuracy = positive("Ewald accuracy", accuracy)
        if not accuracy < 1.0:
            raise ValueError(f"Ewald accuracy is a relative RMS force error, between 0 and 1, got {accuracy!r}")
        if surface not in SURFACES:
            raise ValueError(f"Ewald surface must be one of {SURFACES}, got {surface!r}")
        self.accuracy = accuracy
        self.surface = surface
        self.alpha = None if alpha is None else positive("Ewald alpha", alpha)

    def tune(self, prefactor, particles, box, cutoff=None):
        """:class:`TunedEwald` for these spheres in this box (ValueError when the box is not
        periodic along every axis or two, or no cutoff shorter than half of it reaches the accuracy).

        The Wang-Holm estimates choose the cutoff, alpha and the wave vectors; the whole error is
        then measured on a :class:`Sample` with the scene's moments, and where it exceeds MARGIN of
        the accuracy (polarised samples: the estimates assume random moments) the target is
        tightened by TIGHTEN times the excess and the choice made again, up to MEASURED_TRIES times."""
        n, squares, volume, pull, half, axis = scales(
            "an Ewald sum", prefactor, particles, box, "use a cut-off Dipole or an open scene without long_range")
        self.refuse_surface_of_slab(axis)
        goal = self.accuracy * pull
        sample = Sample(particles, box, prefactor, goal, axis)
        # the squared error budget in equal shares: real space, wave vectors (and a slab's copies)
        target, measured = goal / math.sqrt(2.0 if axis < 0 else 3.0), None
        hint = thick_box_hint(box, axis, particles.position)
        for _ in range(MEASURED_TRIES):
            def summed_for(rc, target=target):
                """The lengths of the periodic box summed with real-space cutoff rc (a slab's gap: at least rc)."""
                layer = slab_layer(box, axis, target, prefactor, squares, n, rc, sample.radius)
                return tuple(box.size) if layer is None else layer.size
            rc, alpha, kmax, kcut = self._choose(target, prefactor, particles, summed_for, cutoff, n, squares, volume,
                                                 half)
            layer = slab_layer(box, axis, target, prefactor, squares, n, rc, sample.radius)
            summed = tuple(box.size) if layer is None else layer.size
            _refuse_too_many_wave_vectors(rc, kcut, float(np.prod(summed)), n, self.accuracy, hint)
            if not sample.ready:
                break
            force, field = sample.reciprocal(alpha, kmax, kcut, summed)
            field = sample.field_term(alpha, field + sample.real_field(alpha, rc)) if sample.fields else None
            measured = sample.error_of(force + sample.real_forces(alpha, rc), field)
            if measured <= MARGIN * goal:
                break
            target *= TIGHTEN * MARGIN * goal / measured
        volume_summed = float(np.prod(summed))
        _refuse_too_many_wave_vectors(rc, kcut, volume_summed, n, self.accuracy, hint)
        gap = 0.0 if layer is None else gap_error(prefactor, squares, n, *Layer.periodic_lengths(box), layer.gap)
        return TunedEwald(self, prefactor, float(rc), float(alpha), kmax, kcut, tuple(float(x) for x in summed),
                          real_space_error(prefactor, squares, n, volume, alpha, rc) / pull,
                          math.sqrt(sum(reciprocal_error(prefactor, squares, n, volume_summed, alpha, k, length) ** 2
                                        for k, length in zip(kmax, summed)) / 3.0) / pull,
                          None if measured is None else measured / pull, layer, gap / pull)

    def refuse_surface_of_slab(self, axis):
        """ValueError for a ``surface`` other than metallic in a slab (open ``axis`` >= 0)."""
        if axis >= 0 and self.surface != "metallic":
            raise ValueError(f"a slab (a box periodic along two axes) is an infinite layer, whose surface term is its "
                             f"own (demkit.interactions.slab): surface={self.surface!r} is for boxes periodic along "
                             f"x, y and z; leave it out")

    def _choose(self, target, prefactor, particles, summed_for, cutoff, n, squares, volume, half):
        """(cutoff, alpha, kmax, kcut) of the least estimated cost whose estimated real-space and
        per-axis reciprocal errors are at most ``target`` each (``volume``: the box's, where the
        real-space pairs are; ``summed_for(rc)``: the lengths of the periodic box of the wave vectors)."""
        contact = 2.0 * float(np.max(particles.radius))
        if cutoff is not None:
            candidates = [cutoff]
        else:
            low = min(contact, 0.999 * half)
            candidates = list(np.linspace(low, 0.999 * half, 60))
        best = None
        density = n / volume
        for rc in candidates:
            summed = summed_for(rc)
            volume_summed = float(np.prod(summed))
            alpha = self.alpha or _alpha_for(target, prefactor, squares, n, volume, rc)
            if alpha is None:
                continue
            if real_space_error(prefactor, squares, n, volume, alpha, rc) > target * 1.0001:
                continue
            kmax, kcut = wave_vector_limits(target, prefactor, squares, n, volume_summed, alpha, summed)
            vectors = 2.0 * math.pi / 3.0 * kcut ** 3 * volume_summed / (2.0 * math.pi) ** 3  # half of the k-sphere
            cost = n * (2.0 * math.pi / 3.0 * density * rc ** 3 + RECIPROCAL_COST * vectors)
            if best is None or cost < best[0]:
                best = (cost, rc, alpha, kmax, kcut)
        if best is None:
            raise ValueError(f"no real-space cutoff shorter than half the box ({half:.6g}) reaches Ewald accuracy "
                             f"{self.accuracy:g} with alpha={self.alpha}: ask for a lower accuracy or leave alpha "
                             f"to the tuning")
        return best[1:]

    def __repr__(self):
        extra = "" if self.alpha is None else f", alpha={self.alpha!r}"
        return f"Ewald(accuracy={self.accuracy!r}, surface={self.surface!r}{extra})"


def _refuse_too_many_wave_vectors(rc, kcut, volume, n, accuracy, hint=""):
    """ValueError when the wave vectors within ``kcut`` (half of the k-sphere) exceed MAX_WAVE_VECTORS
    (``hint``: a sentence to add)."""
    vectors = 2.0 * math.pi / 3.0 * kcut ** 3 * volume / (2.0 * math.pi) ** 3
    if vectors > MAX_WAVE_VECTORS:
        raise ValueError(f"an Ewald sum with real-space cutoff {rc:.6g} needs about {vectors:.3g} wave vectors "
                         f"(more than {MAX_WAVE_VECTORS:.0e}) for accuracy {accuracy:g}: each force "
                         f"evaluation would take {vectors * n * 6e-9:.3g} s or more; leave the cutoff to the "
                         f"tuning, make it longer, or ask for a lower accuracy.{hint}")


class TunedEwald:
    """An Ewald sum tuned to a scene: ``cutoff`` (real space), ``alpha``, ``kmax`` (largest wave
    number per axis, in units of 2 pi / L), ``kcut`` (|k| kept), the estimated relative RMS force
    errors ``real_error`` and ``reciprocal_error`` (fractions of the touching pull), and
    ``measured_error``, the whole sum's on the tuning's sample (None where none was measured). A
    slab's ``layer`` (:class:`~demkit.interactions.slab.Layer`, else None) holds its gap, whose
    estimated error is ``gap_error``; ``box_size`` is then the drawn-out box summed."""

    energy_kind = "magnetic"
    #: the compiled function the kernels call once per force evaluation (module, name)
    kernel = ("demkit.interactions.ewald", "reciprocal_sum")

    def __init__(self, settings, prefactor, cutoff, alpha, kmax, kcut, box_size, real_error, reciprocal_error_,
                 measured_error=None, layer=None, gap_error_=0.0):
        self.settings = settings
        self.layer = layer
        self.gap_error = gap_error_
        self.measured_error = measured_error
        self.box_size = box_size
        self.prefactor = prefactor
        self.cutoff = cutoff
        self.alpha = alpha
        self.kmax = kmax
        self.kcut = kcut
        self.real_error = real_error
        self.reciprocal_error = reciprocal_error_

    def adapt(self, dipole):
        """Make the scene's copy of the Dipole the screened real-space pair at the tuned cutoff."""
        screened_pair(dipole, self.cutoff, self.alpha)

    def field(self, particles, box):
        """(N, 3) field at each sphere from everything but its real-space partners (see
        :func:`field_of_others`)."""
        return field_of_others(self, particles, box)

    @property
    def estimated_error(self):
        """Relative RMS force error of the whole sum: measured on the tuning's sample, or (where
        none could be) the estimates'."""
        if self.measured_error is not None:
            return self.measured_error
        return math.sqrt(self.real_error ** 2 + self.reciprocal_error ** 2 + self.gap_error ** 2)

    @property
    def wave_vectors(self):
        """Number of wave vectors the reciprocal sum visits (half of those with |k| <= kcut)."""
        axes = [2.0 * math.pi / length * np.arange(-m, m + 1) for m, length in zip(self.kmax, self.box_size)]
        k2 = sum(np.meshgrid(*[a * a for a in axes], indexing="ij"))
        return int((np.count_nonzero(k2 <= self.kcut ** 2 * (1 + 1e-9)) - 1) // 2)

    def virial(self, particles, box):
        """(W (3, 3), each sphere's share (N, 3, 3)) of the reciprocal and surface terms, in the pair
        virial's convention (:mod:`demkit.interactions.ewald_virial`); the real-space pairs are pair forces."""
        from .ewald_virial import reciprocal_virial
        return reciprocal_virial(particles.position, particles.dipole, self.box_size, self.prefactor, self.alpha,
                                 self.settings.surface == "vacuum", self.kmax, self.kcut, self.layer)

    def table_values(self):
        """The sum's run-time table in the scene's params (see :func:`reciprocal_sum`)."""
        return reciprocal_table(self.prefactor, self.alpha, self.settings.surface == "vacuum", self.kmax, self.kcut,
                                table_entries(self.box_size) if self.layer is None else self.layer.table())

    def __repr__(self):
        layer = "" if self.layer is None else f", layer={self.layer!r}"
        return (f"TunedEwald(cutoff={self.cutoff:.6g}, alpha={self.alpha:.6g}, kmax={self.kmax}, "
                f"surface={self.settings.surface!r}{layer}, estimated_error={self.estimated_error:.3g})")
