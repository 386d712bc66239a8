"""Induced dipoles: magnetisable spheres polarised by the applied field and by each other.

A sphere of magnetic susceptibility chi > 0 (``Particles(susceptibility=...)``) carries the moment

    m_i = alpha_i B_i,    alpha_i = beta_i R_i^3 / A,    beta_i = (mu_r - 1)/(mu_r + 2) = chi/(chi + 3)

the point-dipole polarisability of a linear sphere (Clausius-Mossotti; in SI, A = mu0/4pi and
m = 4 pi R^3 beta H; beta -> 1 for soft iron). B_i is the field at its centre: the applied field
(:class:`~demkit.UniformField`, :class:`~demkit.MagnetField`) plus the dipole field of every other
sphere, summed as the scene's :class:`~demkit.Dipole` sums it (all pairs, a cutoff with or without
switch, Ewald, P3M or FMM). Spheres with chi = 0 keep their permanent moments; a sphere with chi > 0
has no permanent moment (what its ``dipole`` row holds is only the solve's starting guess).

**The solve**, before every force evaluation: with a = diag(alpha) over the magnetisable spheres,
T the dipole field operator (B = T m) and m_p the permanent moments,

    (I - a^1/2 T a^1/2) y = a^1/2 (B_0 + T m_p),    m_induced = a^1/2 y,

a symmetric positive-definite system (T is symmetric) solved by conjugate gradients (compiled;
object mode only for a long-range sum's field and magpylib fields) until |residual| <= tolerance
|right-hand side|, from the current moments or, in a time loop, from 2 m(t) - m(t - dt). Each
iteration costs one field evaluation.

**Energy** (linear induction): U = U_dipole + U_field + sum_i |m_i|^2 / (2 alpha_i), the last term
reported as "induction". U is stationary in the induced moments at the solution, so the forces and
torques are those of fixed moments (the Dipole's and the fields' own), and for magnetisable spheres
alone U = -1/2 sum_i m_i.B_0(x_i). The torque on a magnetisable sphere, m_i x B_i = alpha B_i x B_i,
vanishes (to the tolerance).
"""
from __future__ import annotations

import itertools
import math
import weakref

import numpy as np
from numba import njit, objmode

from .base import number
from .special_functions import screened

#: the solvers of the live scenes, by the key the kernels find in their params table
_SOLVERS = weakref.WeakValueDictionary()
_KEYS = itertools.count(1)
#: codes the kernels' solve returns (0: converged)
CONVERGED, NOT_CONVERGED, NOT_POSITIVE = 0, 1, 2
FIELD_OPTIONS = dict(cache=True, fastmath={"contract", "arcp"}, error_model="numpy")
#: per-sphere history of the solve: the previous solution's three components and 1 once it is set
HISTORY = 4


def clausius_mossotti(susceptibility):
    """beta = chi / (chi + 3) = (mu_r - 1)/(mu_r + 2), the reduced polarisability of a linear sphere."""
    chi = np.asarray(susceptibility, dtype=np.float64)
    return chi / (chi + 3.0)


def polarisability(radius, susceptibility, prefactor):
    """alpha = beta R^3 / A (moment per field, in the units the Dipole's prefactor A sets)."""
    return clausius_mossotti(susceptibility) * np.asarray(radius, dtype=np.float64) ** 3 / prefactor


class Induction:
    """Settings of the induced-moment solve: ``Dipole(prefactor, induction=Induction(1e-6))``.

    tolerance : relative residual |r| / |b| at which conjugate gradients stop (0 < tolerance < 1).
        The moments are then accurate to about tolerance times the condition number (below 10 for
        touching spheres of beta <= 1).
    max_iterations : iterations allowed per solve; a solve that needs more stops the run.
    """

    def __init__(self, tolerance=1e-6, max_iterations=100):
        tolerance = number("Induction tolerance", tolerance)
        if not 0.0 < tolerance < 1.0:
            raise ValueError(f"Induction tolerance must lie between 0 and 1 (a relative residual), got {tolerance!r}")
        self.tolerance = tolerance
        iterations = number("Induction max_iterations", max_iterations)
        if iterations < 1 or iterations != int(iterations):
            raise ValueError(f"Induction max_iterations must be a whole number >= 1, got {max_iterations!r}")
        self.max_iterations = int(iterations)

    def __repr__(self):
        return f"Induction(tolerance={self.tolerance!r}, max_iterations={self.max_iterations!r})"


#: pairs per block of the field loop (the gather and output buffers hold one block)
FIELD_BLOCK = 64


@njit(**FIELD_OPTIONS)
def pair_field(position, dipole, box, periodic, start, end, partner, all_pairs, prefactor, cutoff, switch_on,
               inv_width, alpha, field, frame):
    """Add to ``field`` the dipole field of each pair's partner: over all pairs i < j
    (``all_pairs``) or the half list (start, end, partner), minimum image along periodic axes,
    within ``cutoff``: A [C (m_j.d) d - B m_j] with B = 1/r^3, C = 3/r^5 (times the switch S(r)
    when inv_width > 0), or their Ewald-screened forms when alpha > 0 (demkit.interactions.ewald).

    Each owner's pairs go in blocks of FIELD_BLOCK, as in the force loops (demkit.engine.kernels): a
    copy loop gathers the partners' positions and moments, a branch-free loop the compiler
    vectorises evaluates every pair (minimum image by rounding; the prefactor is 0 beyond the
    cutoff), a scalar loop scatters the partners' fields: 1.7-1.8x faster than one scalar loop with
    branches (14 against 24 ns a listed pair). The screened forms keep one scalar loop that skips
    the pairs beyond the cutoff (:func:`screened_pair_field`).

    ``frame``: [a, b, delta] of a sheared box (Lees-Edwards images: the partner seen one period up the
    gradient axis b is shifted by delta along the flow axis a; demkit.engine.shear), or empty. The
    gather shifts the partner's coordinate along a by -k delta, k = rint((x_j - x_i)_b / L_b), and the
    minimum image then folds a and b as in a fixed box: the nearest sliding image."""
    if alpha > 0.0:
        screened_pair_field(position, dipole, box, periodic, start, end, partner, all_pairs, prefactor, cutoff,
                            alpha, field)
        return
    n = position.shape[0]
    cut2 = cutoff * cutoff
    lx = box[0] if periodic[0] else 0.0  # d -= L rint(d / L): nothing along open axes
    ly = box[1] if periodic[1] else 0.0
    lz = box[2] if periodic[2] else 0.0
    ilx = 1.0 / lx if lx > 0.0 else 0.0
    ily = 1.0 / ly if ly > 0.0 else 0.0
    ilz = 1.0 / lz if lz > 0.0 else 0.0
    gathered = np.empty((6, FIELD_BLOCK))
    out = np.empty((6, FIELD_BLOCK))
    sheared = frame.shape[0] > 0
    fa = int(frame[0]) if sheared else 0
    fb = int(frame[1]) if sheared else 0
    delta = frame[2] if sheared else 0.0
    ilb = 1.0 / box[fb]
    for i in range(n):
        lo = i + 1 if all_pairs else start[i]
        hi = n if all_pairs else end[i]
        xi, yi, zi = position[i, 0], position[i, 1], position[i, 2]
        ax, ay, az = dipole[i, 0], dipole[i, 1], dipole[i, 2]
        fx = fy = fz = 0.0
        for b0 in range(lo, hi, FIELD_BLOCK):
            m = min(FIELD_BLOCK, hi - b0)
            for u in range(m):
                j = np.uint32(b0 + u) if all_pairs else np.uint32(partner[b0 + u])
                for a in range(3):
                    gathered[a, u] = position[j, a]
                    gathered[3 + a, u] = dipole[j, a]
                if sheared:  # the sliding image: shifted along the flow by -k delta
                    gathered[fa, u] -= np.rint((position[j, fb] - position[i, fb]) * ilb) * delta
            for u in range(m):
                dx = gathered[0, u] - xi
                dy = gathered[1, u] - yi
                dz = gathered[2, u] - zi
                dx -= lx * np.rint(dx * ilx)
                dy -= ly * np.rint(dy * ily)
                dz -= lz * np.rint(dz * ilz)
                r2 = dx * dx + dy * dy + dz * dz
                scale = prefactor if r2 < cut2 else 0.0  # beyond the cutoff r2 > 0: finite values times 0
                inv_r2 = 1.0 / r2
                b = inv_r2 * math.sqrt(inv_r2)
                c = 3.0 * b * inv_r2
                x = min(max((r2 * math.sqrt(inv_r2) - switch_on) * inv_width, 0.0), 1.0)
                if inv_width > 0.0:
                    scale *= (1.0 - x) ** 3 * (10.0 - (1.0 - x) * (15.0 - 6.0 * (1.0 - x)))
                b *= scale
                c *= scale
                sj = c * (gathered[3, u] * dx + gathered[4, u] * dy + gathered[5, u] * dz)
                si = c * (ax * dx + ay * dy + az * dz)
                out[0, u] = sj * dx - b * gathered[3, u]
                out[1, u] = sj * dy - b * gathered[4, u]
                out[2, u] = sj * dz - b * gathered[5, u]
                out[3, u] = si * dx - b * ax
                out[4, u] = si * dy - b * ay
                out[5, u] = si * dz - b * az
            for u in range(m):
                j = np.uint32(b0 + u) if all_pairs else np.uint32(partner[b0 + u])
                fx += out[0, u]
                fy += out[1, u]
                fz += out[2, u]
                field[j, 0] += out[3, u]
                field[j, 1] += out[4, u]
                field[j, 2] += out[5, u]
        field[i, 0] += fx
        field[i, 1] += fy
        field[i, 2] += fz


@njit(**FIELD_OPTIONS)
def screened_pair_field(position, dipole, box, periodic, start, end, partner, all_pairs, prefactor, cutoff, alpha,
                        field):
    """:func:`pair_field` for the Ewald-screened forms (alpha > 0): one scalar loop that skips the
    pairs beyond the cutoff."""
    n = position.shape[0]
    cut2 = cutoff * cutoff
    lx = box[0] if periodic[0] else math.inf
    ly = box[1] if periodic[1] else math.inf
    lz = box[2] if periodic[2] else math.inf
    hx, hy, hz = 0.5 * lx, 0.5 * ly, 0.5 * lz
    for i in range(n):
        lo = i + 1 if all_pairs else start[i]
        hi = n if all_pairs else end[i]
        xi, yi, zi = position[i, 0], position[i, 1], position[i, 2]
        ax, ay, az = dipole[i, 0], dipole[i, 1], dipole[i, 2]
        fx = fy = fz = 0.0
        for q in range(lo, hi):
            j = q if all_pairs else partner[q]
            dx = position[j, 0] - xi
            dy = position[j, 1] - yi
            dz = position[j, 2] - zi
            dx = dx - lx if dx > hx else (dx + lx if dx < -hx else dx)
            dy = dy - ly if dy > hy else (dy + ly if dy < -hy else dy)
            dz = dz - lz if dz > hz else (dz + lz if dz < -hz else dz)
            r2 = dx * dx + dy * dy + dz * dz
            if r2 >= cut2:
                continue
            r = math.sqrt(r2)
            ar = alpha * r
            erfc, gauss = screened(ar)
            b = prefactor * (erfc + gauss) / (r2 * r)
            c = prefactor * (3.0 * erfc + gauss * (3.0 + 2.0 * ar * ar)) / (r2 * r2 * r)
            bx, by, bz = dipole[j, 0], dipole[j, 1], dipole[j, 2]
            sj = c * (bx * dx + by * dy + bz * dz)
            si = c * (ax * dx + ay * dy + az * dz)
            fx += sj * dx - b * bx
            fy += sj * dy - b * by
            fz += sj * dz - b * bz
            field[j, 0] += si * dx - b * ax
            field[j, 1] += si * dy - b * ay
            field[j, 2] += si * dz - b * az
        field[i, 0] += fx
        field[i, 1] += fy
        field[i, 2] += fz


#: the induction table in the scene's params (from ``slot``): the solver's key and its statistics
#: (zeroed when a checkpoint fingerprints a scene), then settings, the Dipole's sum, B_0, the alphas
KEY, SOLVES, ITERATIONS, MOST, LAST_ITERATIONS, LAST_CODE, LAST_RESIDUAL, START_RESIDUAL = range(8)
STATISTICS = 8
(TOLERANCE, MAX_ITERATIONS, KIND, PREFACTOR, CUTOFF, SWITCH_ON, INV_WIDTH, SCREENING, BX, BY, BZ, LONG_RANGE,
 MAGNETS) = range(8, 21)
HEAD = 21
KINDS = {None: 0.0, "all": 1.0, "list": 2.0}


@njit(cache=True)
def induction_energy(dipole, tag, params, slot):
    """sum_i |m_i|^2 / (2 alpha_i) over the magnetisable spheres (alpha by tag in the table)."""
    energy = 0.0
    for i in range(dipole.shape[0]):
        a = params[slot + HEAD + tag[i]]
        if a > 0.0:
            energy += (dipole[i, 0] ** 2 + dipole[i, 1] ** 2 + dipole[i, 2] ** 2) / (2.0 * a)
    return energy


@njit(cache=True)
def field_of(position, moments, box, periodic, params, slot, start, end, partner, frame):
    """(N, 3) field T m at each sphere from the others' ``moments``, summed as the scene's Dipole
    sums it: its pair loop (compiled; ``frame``: a sheared box's, see :func:`pair_field`) and its
    long-range sum (object mode, the registered solver)."""
    field = np.zeros(moments.shape)
    kind = params[slot + KIND]
    if kind > 0.0:
        pair_field(position, moments, box, periodic, start, end, partner, kind == 1.0, params[slot + PREFACTOR],
                   params[slot + CUTOFF], params[slot + SWITCH_ON], params[slot + INV_WIDTH],
                   params[slot + SCREENING], field, frame)
    if params[slot + LONG_RANGE] != 0.0:
        key = params[slot + KEY]
        x = position.copy()  # fresh arrays into object mode (a view would be boxed as its parent)
        m = moments.copy()
        extra = np.zeros(moments.shape)
        with objmode():
            long_range_field(key, x, m, extra)
        _combine(field, field, 1.0, extra)
    return field


def long_range_field(key, position, moments, out):
    """Add the field of the long-range sum of the solver registered under ``key`` to ``out``."""
    _SOLVERS[int(key)].long_range_field(position, moments, out)


def magnet_field(key, position, out):
    """Add the MagnetFields' field of the solver registered under ``key`` to ``out``."""
    _SOLVERS[int(key)].magnet_field(position, out)


@njit(cache=True)
def _dot(a, b):
    total = 0.0
    for i in range(a.shape[0]):
        total += a[i, 0] * b[i, 0] + a[i, 1] * b[i, 1] + a[i, 2] * b[i, 2]
    return total


# the solve's vector updates as loops: numba compiles each array expression as a function of its own
# (induce compiled in 6.6 CPU s with them); the same arithmetic element by element, the same bits
@njit(cache=True)
def _scaled(scale, a):
    """scale[i] a[i]: the (n, 3) rows of ``a`` scaled."""
    out = np.empty(a.shape)
    for i in range(a.shape[0]):
        for c in range(3):
            out[i, c] = scale[i] * a[i, c]
    return out


@njit(cache=True)
def _combine(out, x, a, y):
    """out = x + a y for (n, 3) arrays and a number a (out may be x or y: element by element)."""
    for i in range(out.shape[0]):
        for c in range(3):
            out[i, c] = x[i, c] + a * y[i, c]


@njit(cache=True)
def _combine_scaled(out, x, sign, scale, a):
    """out = x + sign scale[i] a[i] for sign +1 or -1 (exact: x - scale[i] a[i] for -1; out may be x)."""
    for i in range(out.shape[0]):
        for c in range(3):
            out[i, c] = x[i, c] + sign * (scale[i] * a[i, c])


@njit(cache=True)
def induce(position, dipole, tag, box, periodic, params, slot, start, end, partner, history, offset, commit, frame):
    """Solve the magnetisable spheres' moments in place in ``dipole`` (module docstring; the table
    at params[slot:]): conjugate gradients from the current moments, or with ``commit`` (a time
    loop) from the linear extrapolation 2 m - m_previous of the last two solutions, the previous one
    kept in history[:, offset:offset + 4] (three components, then 1 once set). Returns 0 when
    converged (the module's codes otherwise); the statistics are counted in the table. ``frame``: a sheared
    box's [a, b, delta(t)] (demkit.engine.shear.list_frame), or empty."""
    n = dipole.shape[0]
    scale = np.zeros(n)  # a^1/2, zero for permanent moments
    any_permanent = False
    for i in range(n):
        a = params[slot + HEAD + tag[i]]
        if a > 0.0:
            scale[i] = math.sqrt(a)
        else:
            any_permanent = True
    if commit:
        for i in range(n):
            if scale[i] > 0.0:
                for c in range(3):
                    now = dipole[i, c]
                    if history[i, offset + 3] > 0.0:
                        dipole[i, c] = 2.0 * now - history[i, offset + c]
                    history[i, offset + c] = now
            history[i, offset + 3] = 1.0
    source = np.empty((n, 3))
    for i in range(n):
        source[i, 0] = params[slot + BX]
        source[i, 1] = params[slot + BY]
        source[i, 2] = params[slot + BZ]
    if params[slot + MAGNETS] != 0.0:
        key = params[slot + KEY]
        x = position.copy()
        extra = np.zeros((n, 3))
        with objmode():
            magnet_field(key, x, extra)
        _combine(source, source, 1.0, extra)
    if any_permanent:
        permanent = dipole.copy()
        for i in range(n):
            if scale[i] > 0.0:
                permanent[i, :] = 0.0
        _combine(source, source, 1.0, field_of(position, permanent, box, periodic, params, slot, start, end, partner,
                                               frame))
    b = np.empty((n, 3))
    y = np.zeros((n, 3))
    for i in range(n):
        for c in range(3):
            b[i, c] = scale[i] * source[i, c]
            if scale[i] > 0.0:
                y[i, c] = dipole[i, c] / scale[i]
    r = np.empty((n, 3))
    _combine(r, b, -1.0, y)  # b - y
    _combine_scaled(r, r, 1.0, scale, field_of(position, _scaled(scale, y), box, periodic, params, slot, start, end,
                                               partner, frame))
    norm_b = math.sqrt(_dot(b, b))
    goal = params[slot + TOLERANCE] * norm_b
    rr = _dot(r, r)
    start_residual = math.sqrt(rr) / max(norm_b, 1e-300)
    code, k = CONVERGED, 0
    p = r.copy()
    limit = int(params[slot + MAX_ITERATIONS])
    while math.sqrt(rr) > goal:
        if k == limit:
            code = NOT_CONVERGED
            break
        k += 1
        ap = np.empty((n, 3))
        _combine_scaled(ap, p, -1.0, scale, field_of(position, _scaled(scale, p), box, periodic, params, slot, start,
                                                     end, partner, frame))
        pap = _dot(p, ap)
        if not pap > 0.0:
            code = NOT_POSITIVE
            break
        step = rr / pap
        _combine(y, y, step, p)
        _combine(r, r, -step, ap)
        old = rr
        rr = _dot(r, r)
        _combine(p, r, rr / old, p)
    for i in range(n):
        if scale[i] > 0.0:
            for c in range(3):
                dipole[i, c] = scale[i] * y[i, c]
    params[slot + SOLVES] += 1.0
    params[slot + ITERATIONS] += k
    params[slot + MOST] = max(params[slot + MOST], k)
    params[slot + LAST_ITERATIONS] = k
    params[slot + LAST_CODE] = code
    params[slot + LAST_RESIDUAL] = math.sqrt(rr) / max(norm_b, 1e-300)
    params[slot + START_RESIDUAL] = start_residual
    return code


def _table_value(index, kind, doc):
    """A read-only property: the value at ``index`` of the solver's table, as ``kind``."""
    return property(lambda self: kind(self.params[self.slot + index]) if self.params is not None else kind(0),
                    doc=doc)


class _Spheres:
    """What the long-range sums' field() reads of a Particles: positions, moments, a length."""

    def __init__(self, position, dipole):
        self.position, self.dipole = position, dipole

    def __len__(self):
        return len(self.position)


class InducedMoments:
    """A scene's induced-moment solve (module docstring); built by :class:`demkit.Scene`, which puts
    :meth:`table_values` into its params and calls :meth:`bind`. The compiled :func:`induce` does
    the work; this object keeps what only Python can evaluate (a long-range sum's field, magpylib
    fields) and reads the statistics.

    dipole : the scene's Dipole (its tuned copy when it has a long-range sum).
    kind : "all" (all pairs), "list" (the Dipole's neighbour list) or None (no pair loop: a fast
        multipole sum covers every pair).
    effects : the scene's single-sphere effects (UniformField and MagnetField give B_0).
    alpha : (N,) polarisabilities in the user's order (0: a permanent moment).
    """

    energy_kind = "induction"
    history_size = HISTORY

    def __init__(self, dipole, kind, box, effects, alpha, settings):
        self._settings = settings
        self.prefactor = dipole.prefactor
        self.kind = kind
        self.box = box
        self.cutoff = dipole.cutoff_distance if dipole.cutoff_distance is not None else math.inf
        switched = getattr(dipole, "switch_width", None) is not None
        self.switch_on = dipole.switch_on if switched else 0.0
        self.inv_width = dipole.inv_switch_width if switched else 0.0
        self.tuned = dipole.tuned if dipole.long_range is not None else None
        self.screening = getattr(dipole, "alpha", 0.0) if self.tuned is not None else 0.0
        self.uniform, self.magnets = applied_sources(effects)
        self.alpha = np.ascontiguousarray(alpha, dtype=np.float64)
        self.key = next(_KEYS)
        _SOLVERS[self.key] = self
        self.params, self.slot = None, None

    def table_values(self):
        """The table the kernels read (see the module's KEY ... HEAD)."""
        table = np.zeros(HEAD + len(self.alpha))
        table[KEY] = self.key
        table[TOLERANCE] = self._settings.tolerance
        table[MAX_ITERATIONS] = self._settings.max_iterations
        table[KIND] = KINDS[self.kind]
        table[PREFACTOR], table[CUTOFF] = self.prefactor, self.cutoff
        table[SWITCH_ON], table[INV_WIDTH], table[SCREENING] = self.switch_on, self.inv_width, self.screening
        table[BX:BZ + 1] = self.uniform
        table[LONG_RANGE] = 1.0 if self.tuned is not None else 0.0
        table[MAGNETS] = 1.0 if self.magnets else 0.0
        table[HEAD:] = self.alpha
        return table

    def bind(self, params, slot):
        """Read and write the table at params[slot:] (the scene's)."""
        self.params, self.slot = params, slot

    @property
    def settings(self):
        """The :class:`Induction` settings (may be replaced between runs)."""
        return self._settings

    @settings.setter
    def settings(self, settings):
        self._settings = settings
        if self.params is not None:
            self.params[self.slot + TOLERANCE] = settings.tolerance
            self.params[self.slot + MAX_ITERATIONS] = settings.max_iterations

    solves = _table_value(SOLVES, int, "Solves run so far.")
    iterations = _table_value(ITERATIONS, int, "Conjugate-gradient iterations of all solves so far.")
    most_iterations = _table_value(MOST, int, "The most iterations one solve took.")
    last_iterations = _table_value(LAST_ITERATIONS, int, "Iterations of the last solve.")
    last_code = _table_value(LAST_CODE, int, "The last solve's code (CONVERGED, NOT_CONVERGED, NOT_POSITIVE).")
    last_residual = _table_value(LAST_RESIDUAL, float, "|residual| / |right-hand side| where the last solve stopped.")
    start_residual = _table_value(START_RESIDUAL, float, "|residual| / |right-hand side| where it started.")

    @property
    def mean_iterations(self):
        """Iterations per solve so far (0 before any)."""
        return self.iterations / self.solves if self.solves else 0.0

    def long_range_field(self, position, moments, out):
        """Add the long-range sum's field of ``moments`` to ``out`` (object mode)."""
        out += self.tuned.field(_Spheres(position, moments), self.box)

    def magnet_field(self, position, out):
        """Add the MagnetFields' field at ``position`` to ``out`` (object mode)."""
        for magnet in self.magnets:
            out += magnet.field(position)

    def failure(self, code):
        """Why a solve returned ``code``, in words."""
        if code == NOT_POSITIVE:
            return ("the induction system is not positive definite (point dipoles of these susceptibilities "
                    "polarise each other without bound: spheres overlapping deeply?)")
        return (f"the induced moments did not converge in {self.settings.max_iterations} iterations (relative "
                f"residual {self.last_residual:.3g} against the tolerance {self.settings.tolerance:g}); raise "
                f"Induction(max_iterations=...) or the tolerance")

    def __repr__(self):
        return (f"InducedMoments({int(np.count_nonzero(self.alpha))} magnetisable spheres, {self.settings!r}, "
                f"{self.mean_iterations:.1f} iterations per solve)")


def applied_sources(effects):
    """(B of the UniformFields summed (3,), the MagnetFields): what makes B_0 among ``effects``."""
    from .fields import UniformField
    from .magnets import MagnetField
    uniform = sum((np.asarray(e.field, dtype=np.float64) for e in effects if isinstance(e, UniformField)), np.zeros(3))
    return uniform, [e for e in effects if isinstance(e, MagnetField)]


def prepare(particles, dipoles, effects):
    """Check a scene's magnetisable spheres and give them their moments in the applied field alone
    (m = alpha B_0, the solve's first guess, which long-range sums are tuned with); ``dipoles``: the
    scene's dk.Dipole interactions (and subclasses), the first of which couples the moments. Returns the
    polarisabilities (N,), or None when no sphere has chi > 0 (the scene then does no induction work)."""
    chi = particles.susceptibility
    if chi is None or not np.any(chi > 0.0):
        return None
    if not dipoles:
        raise ValueError("spheres with a susceptibility > 0 need a dk.Dipole among the interactions: its prefactor "
                         "A = mu0/4pi sets their polarisability alpha = beta R^3 / A, and it couples their moments")
    dipole = dipoles[0]
    if not dipole.torque:
        raise ValueError(f"{dipole!r} is a central power law without a field: magnetisable spheres need dk.Dipole")
    alpha = polarisability(particles.radius, chi, dipole.prefactor)
    particles.require("dipole")
    soft = alpha > 0.0
    uniform, magnets = applied_sources(effects)
    b0 = np.tile(uniform, (len(particles), 1))
    for magnet in magnets:
        b0 += magnet.field(particles.position)
    particles.dipole[soft] = alpha[soft, None] * b0[soft]
    if not np.any(particles.dipole):
        raise ValueError("the magnetisable spheres have nothing to magnetise them: no applied field (dk.UniformField, "
                         "dk.MagnetField) and no permanent moments, so every induced moment is zero")
    return alpha
