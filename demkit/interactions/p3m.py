"""Dipolar particle-mesh Ewald sum (P3M in its smooth-PME form): the reciprocal part of the Ewald sum
of :mod:`demkit.interactions.ewald` on a mesh with fast Fourier transforms, O(N log N).

The real-space pair, the self and surface terms are the Ewald sum's. The wave-vector sum
U_k = (2 pi A / V) sum_k g(k) |S(k)|^2 is approximated by interpolating exp(i k.x) with cardinal
B-splines M_p of order p on a K_x x K_y x K_z mesh (Essmann et al., J. Chem. Phys. 103, 8577 (1995);
for dipoles, Toukmaji et al., J. Chem. Phys. 113, 10913 (2000)). With u_a = K_a x_a / L_a and
W_j(g) = prod_a M_p(u_ja - g_a) (periodic in g):

    Q(g)  = sum_j m_j . grad_j W_j(g)                  (the dipoles spread on the mesh)
    U_k  ~= sum_m C(m) |Q^(m)|^2,   C(m) = (2 pi A / V) g(k_m) |B(m)|^2,  C(0) = 0
    Phi   = dU/dQ = 2 K^3 IFFT(C Q^)                   (one FFT forward, one back)
    H_j   = -sum_g Phi(g) grad_j W_j(g),   tau_j = m_j x H_j
    F_j   = -sum_g Phi(g) (Hess_j W_j(g)) m_j

with |B(m)|^2 = prod_a 1/|sum_{l=0}^{p-2} M_p(l+1) exp(2 pi i m_a l / K_a)|^2. Forces and torques are
the exact derivatives of this approximate energy (a run conserves it). The splines' derivatives
come from M_p' (x) = M_{p-1}(x) - M_{p-1}(x-1), the second ones likewise.

Tuning (``accuracy`` as for :class:`demkit.Ewald`: the RMS force error relative to the touching
pull): for each candidate real-space cutoff, alpha from the Wang-Holm real-space estimate (half
of the squared error budget), then the smallest mesh (sizes 2^a 3^b 5^c) for which the whole sum's
force error, *measured* on a sample of up to SAMPLE spheres at random places in the same box with
the scene's moments against an Ewald sum converged ten times further, scaled by sqrt(N / sample)
(errors of random sums add in quadrature), meets the accuracy; the cutoff with the least estimated
time is kept.
"""
from __future__ import annotations

import math

import numpy as np
import numba
from numba import njit, objmode, prange

from .. import memory
from .ewald import Ewald, Sample, _alpha_for, real_space_error, scales, screened_pair, self_field, slab_layer
from .slab import Layer, check_layer, gap_error, layer_terms, table_entries, thick_box_hint

#: mesh sizes tried (products of 2, 3 and 5)
MESH_SIZES = sorted({2 ** a * 3 ** b * 5 ** c for a in range(9) for b in range(4) for c in range(3)
                     if 4 <= 2 ** a * 3 ** b * 5 ** c <= 256})
#: estimated seconds: per real-space pair within the cutoff, per sphere and spline point (spread +
#: gather), per mesh point and log2 of the mesh size (FFT), measured by benchmarks/bench_ewald.py
PAIR_SECONDS, POINT_SECONDS, FFT_SECONDS = 7.5e-8, 7.0e-9, 2.0e-9
#: bytes per mesh point: the peak of one evaluation (grid, its transform, the potential: 26 measured
#: with tracemalloc on 32^3 and 64^3 meshes) and the influence table in the scene's params (4)
MESH_BYTES = 32
#: head of a tuned sum's table in the scene's params: A, alpha, vacuum, Kx, Ky, Kz, order, the lengths of
#: the periodic box summed (a slab's drawn out), the open axis (-1: none), the layer's thickness; then C
HEAD = 12
OPTIONS = dict(cache=True, fastmath={"contract", "arcp"}, error_model="numpy")
#: the mesh's loops over spheres and mesh planes run on numba's threads (as many as the run's chunk
#: uses: demkit.engine.threads sets them; one outside a run on threads). Each sphere's weights and forces,
#: and each mesh point's sum, are added in the same order on any number of threads: the same bits.
THREADS = dict(OPTIONS, parallel=True)


@njit(**OPTIONS)
def _splines(t, p, table, w, dw, ddw):
    """w[l] = M_p(t + l), dw[l] = M_p'(t + l), ddw[l] = M_p''(t + l) for l = 0..p-1, 0 <= t < 1;
    ``table`` (p + 1, p + 1) is scratch: table[n, l] = M_n(t + l)."""
    table[...] = 0.0
    table[1, 0] = 1.0  # M_1 = 1 on [0, 1)
    for n in range(2, p + 1):
        for l in range(n):
            x = t + l
            table[n, l] = (x * table[n - 1, l] + (n - x) * (table[n - 1, l - 1] if l >= 1 else 0.0)) / (n - 1)
    for l in range(p):
        w[l] = table[p, l]
        dw[l] = table[p - 1, l] - (table[p - 1, l - 1] if l >= 1 else 0.0)
        ddw[l] = (table[p - 2, l] - 2.0 * (table[p - 2, l - 1] if l >= 1 else 0.0)
                  + (table[p - 2, l - 2] if l >= 2 else 0.0))


@njit(**THREADS)
def _weights(position, box, mesh, p, chunks):
    """Base mesh index and spline values, first and second derivatives per sphere and axis (the
    spheres in ``chunks`` chunks on threads, each with its scratch table)."""
    n = position.shape[0]
    base = np.empty((n, 3), dtype=np.int64)
    w = np.empty((n, 3, p))
    dw = np.empty((n, 3, p))
    ddw = np.empty((n, 3, p))
    for k in prange(chunks):
        table = np.empty((p + 1, p + 1))
        for j in range(k * n // chunks, (k + 1) * n // chunks):
            for a in range(3):
                s = position[j, a] / box[a]
                u = (s - math.floor(s)) * mesh[a]
                b = int(math.floor(u))
                if b >= mesh[a]:
                    b -= mesh[a]
                base[j, a] = b
                _splines(u - b, p, table, w[j, a], dw[j, a], ddw[j, a])
    return base, w, dw, ddw


@njit(**THREADS)
def spread(dipole, box, mesh, p, base, w, dw, grid, chunks):
    """grid(g) = sum_j m_j . grad_j W_j(g) (grid zeroed first). Each of ``chunks`` threads fills its own planes
    x = const of the mesh, going through the spheres in order: every mesh point gets its terms in
    the order one thread adds them, whatever the number of threads."""
    grid[...] = 0.0
    sx, sy, sz = mesh[0] / box[0], mesh[1] / box[1], mesh[2] / box[2]
    chunks = min(chunks, mesh[0])
    for k in prange(chunks):
        lo, hi = k * mesh[0] // chunks, (k + 1) * mesh[0] // chunks  # this thread's planes
        iz = np.empty(p, dtype=np.int64)
        for j in range(dipole.shape[0]):
            mx, my, mz = dipole[j, 0] * sx, dipole[j, 1] * sy, dipole[j, 2] * sz
            for c in range(p):
                iz[c] = (base[j, 2] - c) % mesh[2]
            for a in range(p):
                gx = (base[j, 0] - a) % mesh[0]
                if gx < lo or gx >= hi:
                    continue
                xa, xd = w[j, 0, a], mx * dw[j, 0, a]
                for b in range(p):
                    gy = (base[j, 1] - b) % mesh[1]
                    u = xd * w[j, 1, b] + xa * my * dw[j, 1, b]   # times M(z)
                    v = xa * w[j, 1, b] * mz                      # times M'(z)
                    for c in range(p):
                        grid[gx, gy, iz[c]] += u * w[j, 2, c] + v * dw[j, 2, c]


@njit(**THREADS)
def gather(dipole, box, mesh, p, base, w, dw, ddw, phi, force, field, chunks):
    """Add F_j = -sum Phi Hess(W) m_j to force and H_j = -sum Phi grad(W) to field (the spheres in
    ``chunks`` chunks on threads)."""
    sx, sy, sz = mesh[0] / box[0], mesh[1] / box[1], mesh[2] / box[2]
    n = dipole.shape[0]
    for k in prange(chunks):
        iz = np.empty(p, dtype=np.int64)
        for j in range(k * n // chunks, (k + 1) * n // chunks):
            _gather_one(j, dipole, mesh, p, base, w, dw, ddw, phi, force, field, sx, sy, sz, iz)


@njit(**OPTIONS)
def _gather_one(j, dipole, mesh, p, base, w, dw, ddw, phi, force, field, sx, sy, sz, iz):
    """Sphere j's part of :func:`gather`."""
    for c in range(p):
        iz[c] = (base[j, 2] - c) % mesh[2]
    hx = hy = hz = 0.0
    xx = yy = zz = xy = xz = yz = 0.0
    for a in range(p):
        gx = (base[j, 0] - a) % mesh[0]
        wx, dx, ddx = w[j, 0, a], dw[j, 0, a], ddw[j, 0, a]
        for b in range(p):
            gy = (base[j, 1] - b) % mesh[1]
            s0 = 0.0  # sum over z of phi M, phi M', phi M''
            s1 = 0.0
            s2 = 0.0
            for c in range(p):
                f = phi[gx, gy, iz[c]]
                s0 += f * w[j, 2, c]
                s1 += f * dw[j, 2, c]
                s2 += f * ddw[j, 2, c]
            wy, dy, ddy = w[j, 1, b], dw[j, 1, b], ddw[j, 1, b]
            hx += dx * wy * s0
            hy += wx * dy * s0
            hz += wx * wy * s1
            xx += ddx * wy * s0
            yy += wx * ddy * s0
            zz += wx * wy * s2
            xy += dx * dy * s0
            xz += dx * wy * s1
            yz += wx * dy * s1
    field[j, 0] -= hx * sx
    field[j, 1] -= hy * sy
    field[j, 2] -= hz * sz
    mx, my, mz = dipole[j, 0], dipole[j, 1], dipole[j, 2]
    force[j, 0] -= xx * sx * sx * mx + xy * sx * sy * my + xz * sx * sz * mz
    force[j, 1] -= xy * sx * sy * mx + yy * sy * sy * my + yz * sy * sz * mz
    force[j, 2] -= xz * sx * sz * mx + yz * sy * sz * my + zz * sz * sz * mz


def influence(box, mesh, alpha, p, prefactor):
    """C(m) on the half mesh of numpy's rfftn (module docstring)."""
    volume = float(np.prod(box))
    factors = []
    for a in range(3):
        k = mesh[a]
        m = np.fft.fftfreq(k, 1.0 / k) if a < 2 else np.arange(k // 2 + 1)
        x = np.arange(p - 1) + 1.0
        values = np.array([_spline_value(xi, p) for xi in x])
        denominator = np.abs(np.exp(2j * np.pi * np.outer(m, np.arange(p - 1)) / k) @ values) ** 2
        with np.errstate(divide="ignore"):
            factors.append((2 * np.pi * m / box[a], np.where(denominator > 1e-12, 1.0 / denominator, 0.0)))
    kx, bx = factors[0]
    ky, by = factors[1]
    kz, bz = factors[2]
    k2 = kx[:, None, None] ** 2 + ky[None, :, None] ** 2 + kz[None, None, :] ** 2
    with np.errstate(divide="ignore", invalid="ignore"):
        c = 2.0 * math.pi * prefactor / volume * np.exp(-k2 / (4.0 * alpha * alpha)) / k2
    c[0, 0, 0] = 0.0
    return c * bx[:, None, None] * by[None, :, None] * bz[None, None, :]


def _spline_value(x, p):
    """M_p(x) by the recursion (numpy, for the influence function)."""
    if p == 1:
        return 1.0 if 0.0 <= x < 1.0 else 0.0
    return (x * _spline_value(x, p - 1) + (p - x) * _spline_value(x - 1, p - 1)) / (p - 1)


@njit(**OPTIONS)
def _dot(a, b):
    """sum(a * b) over two arrays of one shape, compiled: numpy's dot calls OpenBLAS, whose threads
    then keep spinning beside the pair loops' threads (the N = 8000 reference scene with P3M ran
    at 115 ms a step on two threads against 60 ms with OpenBLAS kept to one thread)."""
    x, y = a.ravel(), b.ravel()
    total = 0.0
    for k in range(x.size):
        total += x[k] * y[k]
    return total


def mesh_terms(position, dipole, box, mesh, p, c, force, field, with_forces):
    """Energy of the mesh sum; with ``with_forces`` its forces added to force, its field to field."""
    import scipy.fft
    workers = numba.get_num_threads()  # the run's chunk sets them (demkit.engine.threads); any number: the same bits
    base, w, dw, ddw = _weights(position, box, mesh, p, workers)
    grid = np.empty(tuple(mesh))
    spread(dipole, box, mesh, p, base, w, dw, grid, workers)
    # (pocketfft gives each worker whole 1-D transforms: the same bits on any number of them)
    phi = 2.0 * float(np.prod(mesh)) * scipy.fft.irfftn(c * scipy.fft.rfftn(grid, workers=workers), s=tuple(mesh),
                                                       workers=workers)
    energy = 0.5 * _dot(grid, phi)
    if with_forces:
        gather(dipole, box, mesh, p, base, w, dw, ddw, phi, force, field, workers)
    return energy


def terms(position, dipole, box, table, force, field, with_forces):
    """Energy of the mesh, self and surface terms with their run-time ``table``; with
    ``with_forces`` their forces added to ``force`` and the field of the mesh and surface terms to
    ``field`` (the torque is m x field)."""
    prefactor, alpha, vacuum = table[0], table[1], table[2] != 0.0
    mesh = np.array([int(x) for x in table[3:6]], dtype=np.int64)
    p = int(table[6])
    summed = np.array(table[7:10])  # the box summed (a slab's drawn out; ``box`` is the scene's)
    axis = int(table[10])
    size = mesh[0] * mesh[1] * (mesh[2] // 2 + 1)  # (a table read from params may go on: other terms)
    c = table[HEAD:HEAD + size].reshape(mesh[0], mesh[1], mesh[2] // 2 + 1)
    energy = mesh_terms(position, dipole, summed, mesh, p, c, force, field, with_forces)
    energy -= prefactor * 2.0 * alpha ** 3 / (3.0 * math.sqrt(math.pi)) * float(np.einsum("ij,ij->", dipole, dipole))
    total = dipole.sum(axis=0)
    volume = float(np.prod(summed))
    if vacuum:
        energy += 2.0 * math.pi * prefactor / (3.0 * volume) * float(np.sum(total * total))
        field -= 4.0 * math.pi * prefactor / (3.0 * volume) * total
    if axis >= 0:
        energy += layer_terms(dipole, axis, volume, prefactor, field, with_forces)
    return energy


def evaluate(position, dipole, box, table, force, torque, with_forces):
    """The mesh, self and surface terms (the kernels' long-range call; see :func:`p3m_sum`)."""
    field = np.zeros((len(position), 3))
    energy = terms(position, dipole, box, table, force, field, with_forces)
    if with_forces:
        torque += np.cross(dipole, field)
    return energy


@njit(cache=True)
def p3m_sum(position, dipole, box, params, start, force, torque, with_forces, status):
    """The mesh part of a P3M sum with its table at params[start:] (scipy's FFT, in object mode): HEAD
    values, then the influence function on the mesh, whose size :func:`terms` reads from the mesh
    (what follows belongs to others, such as the induced moments' solve). A slab's spheres out of
    its layer flag LEFT_LAYER in ``status``."""
    if with_forces:
        check_layer(position, params, start + 10, status)
    # fresh arrays into object mode (a view would be boxed as its parent: see fmm.fmm_sum)
    f = np.zeros(force.shape)
    t = np.zeros(torque.shape)
    table = params[start:].copy()
    with objmode(energy="float64"):
        energy = evaluate(position, dipole, box, table, f, t, with_forces)
    if with_forces:
        force += f
        torque += t
    return energy


class P3M(Ewald):
    """Settings of a dipolar particle-mesh sum: ``Dipole(prefactor, long_range=P3M(accuracy=1e-4))``.

    accuracy, surface, alpha : as for :class:`demkit.Ewald` (the same error measure).
    order : the B-splines' order p (4 to 7; 6 by default); each sphere touches p^3 mesh points.
    mesh : mesh points per axis (one number or three); None: tuned.

    For big periodic scenes, where the Ewald sum's wave vectors cost most; needs scipy (a required
    package). The real-space cutoff is the Dipole's ``cutoff`` (None: tuned).
    """

    def __init__(self, accuracy=1e-4, surface="metallic", alpha=None, order=6, mesh=None):
        super().__init__(accuracy, surface, alpha)
        if isinstance(order, bool) or not isinstance(order, (int, np.integer)) or not 4 <= order <= 7:
            raise ValueError(f"P3M order must be a whole number from 4 to 7, got {order!r}")
        self.order = int(order)
        if mesh is not None:
            sizes = np.atleast_1d(np.asarray(mesh))
            if sizes.size == 1:
                sizes = np.repeat(sizes, 3)
            if sizes.shape != (3,) or not all(float(s).is_integer() and s >= 2 * order for s in sizes):
                raise ValueError(f"P3M mesh must be one or three whole numbers of at least twice the order "
                                 f"({2 * order}), got {mesh!r}")
            mesh = tuple(int(s) for s in sizes)
        self.mesh = mesh

    def tune(self, prefactor, particles, box, cutoff=None):
        """:class:`TunedP3M` for these spheres in this box (module docstring)."""
        n, squares, volume, pull, half, axis = scales(
            "a P3M sum", prefactor, particles, box, "use a cut-off Dipole or, in open space, long_range=dk.FMM(...)")
        self.refuse_surface_of_slab(axis)
        # the squared error budget in equal shares: real space, the mesh (and a slab's copies)
        target = self.accuracy * pull / math.sqrt(2.0 if axis < 0 else 3.0)
        if cutoff is not None:
            candidates = [cutoff]
        else:
            low = min(2.0 * float(np.max(particles.radius)), 0.999 * half)
            candidates = list(np.linspace(low, 0.999 * half, 8))
        if self.mesh is not None:
            memory.refuse_above(MESH_BYTES * float(np.prod(self.mesh)), f"a P3M mesh of {self.mesh} points needs",
                                "ask for a smaller mesh (or mesh=None: tuned) or use long_range=dk.Ewald(...)")
        sample = Sample(particles, box, prefactor, self.accuracy * pull, axis)
        if not sample.ready:
            raise ValueError(f"P3M accuracy {self.accuracy:g} is too close to round-off for its mesh error to be "
                             f"measured against a converged Ewald sum: ask for a lower accuracy")
        best, smallest = None, 0
        density = n / volume
        for rc in sorted(candidates, reverse=True):  # long cutoffs need small meshes: a first cost, quickly
            alpha = self.alpha or _alpha_for(target, prefactor, squares, n, volume, rc)
            if alpha is None or real_space_error(prefactor, squares, n, volume, alpha, rc) > target * 1.0001:
                continue
            real = n * 2.0 * math.pi / 3.0 * density * rc ** 3 * PAIR_SECONDS + n * self.order ** 3 * POINT_SECONDS
            budget = math.inf if best is None else best[0] - real
            if budget <= 0.0:
                continue
            layer = slab_layer(box, axis, target, prefactor, squares, n, rc, sample.radius)  # gap: at least rc
            summed = tuple(float(x) for x in (box.size if layer is None else layer.size))
            found = self._mesh_for(self.accuracy * pull, sample, alpha, rc, summed, budget, smallest)
            if found is None:
                continue
            mesh, error = found
            # a shorter cutoff takes a larger alpha, whose mesh error is larger on any mesh (a slab's
            # mesh along its open axis shrinks with the gap: the periodic axes bound it)
            smallest = max(m for m, flag in zip(mesh, box.periodic) if flag)
            cost = real + _fft_seconds(mesh)
            if best is None or cost < best[0]:
                best = (cost, rc, alpha, mesh, error, layer, summed)
        if best is None:
            room = memory.machine_memory()[0]
            fits = (f" that fits in the {room / memory.GB:.3g} GB of memory available" if room and MESH_BYTES
                    * MESH_SIZES[-1] ** 3 > room else "")
            raise ValueError(f"no real-space cutoff shorter than half the box ({half:.6g}) and mesh of at most "
                             f"{MESH_SIZES[-1]} points per axis{fits} reach P3M accuracy {self.accuracy:g}: ask for a "
                             f"lower accuracy, or use long_range=dk.Ewald(...)."
                             f"{thick_box_hint(box, axis, particles.position)}")
        _, rc, alpha, mesh, error, layer, summed = best
        gap = 0.0 if layer is None else gap_error(prefactor, squares, n, *Layer.periodic_lengths(box), layer.gap)
        return TunedP3M(self, prefactor, float(rc), float(alpha), mesh, summed,
                        real_space_error(prefactor, squares, n, volume, alpha, rc) / pull, error / pull, layer,
                        gap / pull)

    def _mesh_for(self, target, sample, alpha, cutoff, summed, budget, smallest=0):
        """(mesh, the measured RMS force error of the whole sum with it) for the smallest mesh whose
        error is at most ``target``, whose FFTs cost less than ``budget`` seconds and whose longest
        periodic axis has at least ``smallest`` points (bisection: the error falls as the mesh grows),
        or None; ``summed``: the lengths of the periodic box the mesh covers (a slab's drawn out)."""
        real = sample.real_forces(alpha, cutoff), sample.real_field(alpha, cutoff) if sample.fields else None
        if self.mesh is not None:
            return self.mesh, _mesh_error(sample, real, alpha, self.mesh, self.order, summed)
        size = np.asarray(summed)
        sizes = [tuple(int(next(s for s in MESH_SIZES if s >= k * length / size.max())) for length in size)
                 for k in MESH_SIZES if k >= 2 * self.order]
        room = memory.machine_memory()[0] or math.inf
        sizes = [mesh for mesh in sizes if _fft_seconds(mesh) < budget and MESH_BYTES * np.prod(mesh) < room
                 and max(m for m, flag in zip(mesh, sample.periodic) if flag) >= smallest]
        # galloping up from the smallest (an evaluation costs its mesh's FFTs: the large meshes a plain
        # bisection tries first cost most), then bisection between the last mesh too coarse and the first fine
        last, lo, probe, step, found = len(sizes) - 1, 0, 0, 1, None
        while sizes:
            error = _mesh_error(sample, real, alpha, sizes[probe], self.order, summed)
            if error <= target:
                found = sizes[probe], error
                break
            lo = probe + 1
            if probe == last:
                break
            probe, step = min(probe + step, last), 2 * step
        hi = probe - 1
        while found is not None and lo <= hi:
            mid = (lo + hi) // 2
            error = _mesh_error(sample, real, alpha, sizes[mid], self.order, summed)
            if error <= target:
                found, hi = (sizes[mid], error), mid - 1
            else:
                lo = mid + 1
        return found

    def __repr__(self):
        extra = "" if self.alpha is None else f", alpha={self.alpha!r}"
        extra += "" if self.mesh is None else f", mesh={self.mesh!r}"
        return f"P3M(accuracy={self.accuracy!r}, surface={self.surface!r}, order={self.order}{extra})"


def _fft_seconds(mesh):
    points = float(np.prod(mesh))
    return points * math.log2(points) * FFT_SECONDS


def _mesh_error(sample, real, alpha, mesh, order, summed):
    """Measured RMS force error of a candidate on an :class:`~demkit.interactions.ewald.Sample`
    (``real``: its real-space forces and field, and this mesh over a periodic box of lengths ``summed``),
    scaled to the scene's count (with magnetisable spheres, or its field's error if larger: Sample.error_of)."""
    force, field = real[0].copy(), (real[1] if sample.fields else np.zeros((sample.m, 3))).copy()
    table = np.concatenate([[sample.prefactor, alpha, 0.0, *mesh, order, *sample.geometry(summed)],
                            influence(np.asarray(summed), mesh, alpha, order, sample.prefactor).ravel()])
    terms(sample.position, sample.dipole, sample.size, table, force, field, True)
    # terms adds the self energy but no self field: the field of the sample's candidate as Sample.field_term
    return sample.error_of(force, sample.field_term(alpha, field) if sample.fields else None)


class TunedP3M:
    """A P3M sum tuned to a scene: ``cutoff`` (real space), ``alpha``, ``mesh``, ``order``; the
    relative RMS force errors ``real_error`` (the Wang-Holm estimate of the real-space part) and
    ``estimated_error`` (of the whole sum, measured on a sample while tuning). A slab's ``layer`` and
    ``gap_error`` are as for :class:`~demkit.interactions.ewald.TunedEwald` (``box_size`` drawn out)."""

    energy_kind = "magnetic"
    kernel = ("demkit.interactions.p3m", "p3m_sum")

    def __init__(self, settings, prefactor, cutoff, alpha, mesh, box_size, real_error, measured_error, layer=None,
                 gap_error_=0.0):
        self.settings = settings
        self.layer = layer
        self.gap_error = gap_error_
        self.prefactor = prefactor
        self.cutoff = cutoff
        self.alpha = alpha
        self.mesh = mesh
        self.order = settings.order
        self.box_size = box_size
        self.real_error = real_error
        self.measured_error = measured_error

    @property
    def estimated_error(self):
        return self.measured_error

    def adapt(self, dipole):
        """Make the scene's copy of the Dipole the screened real-space pair at the tuned cutoff."""
        screened_pair(dipole, self.cutoff, self.alpha)

    def field(self, particles, box):
        """(N, 3) field at each sphere from the mesh, surface and self terms (the real-space pairs
        are the caller's)."""
        n = len(particles)
        field = np.zeros((n, 3))
        terms(np.ascontiguousarray(particles.position, dtype=np.float64),
              np.ascontiguousarray(particles.dipole, dtype=np.float64), np.array(box.size, dtype=np.float64),
              self.table_values(), np.zeros((n, 3)), field, True)
        return field + self_field(self.prefactor, self.alpha, particles.dipole)

    def virial(self, particles, box):
        """(W (3, 3), each sphere's share (N, 3, 3)) of the mesh and surface terms: the Ewald reciprocal
        sum's at this splitting, with the wave vectors the accuracy asked needs (the mesh sum is that
        sum to this accuracy; :mod:`demkit.interactions.ewald_virial`)."""
        from .ewald import scales, wave_vector_limits
        from .ewald_virial import reciprocal_virial
        n, squares, _, pull, _, _ = scales("a P3M sum", self.prefactor, particles, box, "")
        kmax, kcut = wave_vector_limits(self.settings.accuracy * pull / math.sqrt(2.0), self.prefactor, squares, n,
                                        float(np.prod(self.box_size)), self.alpha, self.box_size)
        return reciprocal_virial(particles.position, particles.dipole, self.box_size, self.prefactor, self.alpha,
                                 self.settings.surface == "vacuum", kmax, kcut, self.layer)

    def table_values(self):
        vacuum = 1.0 if self.settings.surface == "vacuum" else 0.0
        c = influence(np.asarray(self.box_size), self.mesh, self.alpha, self.order, self.prefactor)
        geometry = table_entries(self.box_size) if self.layer is None else self.layer.table()
        return np.concatenate([[self.prefactor, self.alpha, vacuum, *self.mesh, self.order, *geometry], c.ravel()])

    def __repr__(self):
        layer = "" if self.layer is None else f", layer={self.layer!r}"
        return (f"TunedP3M(cutoff={self.cutoff:.6g}, alpha={self.alpha:.6g}, mesh={self.mesh}, order={self.order}, "
                f"surface={self.settings.surface!r}{layer}, estimated_error={self.estimated_error:.3g})")
