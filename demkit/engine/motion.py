"""Compiled building blocks of rigid-sphere motion used by the integrators' time loops.

All take arrays and a step h; none knows which forces exist. Spheres are isotropic, so
d(omega)/dt = tau / I and the free rotation of a body-fixed vector (the dipole) over a step is
an exact rotation about omega by the angle |omega| h (Rodrigues' formula).
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

#: numba options of every hot kernel: no reference counting (kernels never allocate; it costs
#: ~2x on small scenes), fused multiply-add (exact NaN/inf semantics are kept, so the non-finite
#: checks still work) and IEEE division (x/0 gives inf or NaN, caught by those checks, instead of
#: a Python ZeroDivisionError test at every division, which also stops vectorisation).
#: the fast-math flags of demkit's shared helpers, compiled once and called (the same machine code
#: for every scene). The generated modules use none (demkit.engine.kernels, demkit.engine.generic): there LLVM
#: would round differently where the generic and the fused code are shaped differently
FASTMATH = {"contract", "arcp"}
KERNEL_OPTIONS = dict(cache=True, _nrt=False, fastmath=FASTMATH, error_model="numpy",
                      inline="always")
#: options of the helpers the contact laws share (friction, rolling and spring elements): compiled
#: once and called, not inlined into every law and loop that uses them. Inlining them made numba
#: re-type and re-lower the same code in every kernel: a Hertz + friction + rolling + wall scene
#: compiled in 43 s instead of 15 s, and ran no faster (LLVM still inlines them where it pays).
HELPER_OPTIONS = dict(KERNEL_OPTIONS, inline="never")


@njit(**KERNEL_OPTIONS)
def kick(velocity, force, mass, h):
    """v += F/m h."""
    for i in range(velocity.shape[0]):
        s = h / mass[i]
        velocity[i, 0] += s * force[i, 0]
        velocity[i, 1] += s * force[i, 1]
        velocity[i, 2] += s * force[i, 2]


@njit(**KERNEL_OPTIONS)
def drift(position, velocity, h):
    """x += v h."""
    for i in range(position.shape[0]):
        position[i, 0] += h * velocity[i, 0]
        position[i, 1] += h * velocity[i, 1]
        position[i, 2] += h * velocity[i, 2]


@njit(**KERNEL_OPTIONS)
def rotation_coefficients(theta2):
    """(sin t / t, (1 - cos t)/t^2, cos t) for t^2 = theta2, accurate to round-off at any t.

    Small angles use the Taylor series (truncation below 1e-18 relative in every branch),
    larger ones libm. The tiny-angle branch keeps the usual step (|w| dt ~ 1e-5) short.
    """
    if theta2 < 1e-8:
        q = 0.5 - theta2 * (1.0 / 24)
        return 1.0 - theta2 * (1.0 / 6), q, 1.0 - theta2 * q
    if theta2 < 2.5e-3:
        t = theta2
        # Horner forms with constant coefficients (-1)^k/(2k+1)! and (-1)^k/(2k+2)!, no divisions
        s = 1.0 + t * (-1.0 / 6 + t * (1.0 / 120 + t * (-1.0 / 5040 + t * (1.0 / 362880
                                                                          - t * (1.0 / 39916800)))))
        q = 0.5 + t * (-1.0 / 24 + t * (1.0 / 720 + t * (-1.0 / 40320 + t * (1.0 / 3628800
                                                                           - t * (1.0 / 479001600)))))
        return s, q, 1.0 - t * q
    theta = math.sqrt(theta2)
    half = math.sin(0.5 * theta)
    return math.sin(theta) / theta, 2.0 * half * half / theta2, math.cos(theta)


@njit(**KERNEL_OPTIONS)
def rotate_one(vectors, angular_velocity, h, i):
    """Rotate row i of ``vectors`` about its omega by |omega| h (exact, norm-preserving):
    v' = cos(t) v + (sin t / t) (w x v) + ((1 - cos t)/t^2) (w.v) w,  w = omega h, t = |w|."""
    wx = angular_velocity[i, 0] * h
    wy = angular_velocity[i, 1] * h
    wz = angular_velocity[i, 2] * h
    theta2 = wx * wx + wy * wy + wz * wz
    if theta2 == 0.0:
        return
    s, q, c = rotation_coefficients(theta2)
    vx = vectors[i, 0]
    vy = vectors[i, 1]
    vz = vectors[i, 2]
    wv = q * (wx * vx + wy * vy + wz * vz)
    vectors[i, 0] = c * vx + s * (wy * vz - wz * vy) + wv * wx
    vectors[i, 1] = c * vy + s * (wz * vx - wx * vz) + wv * wy
    vectors[i, 2] = c * vz + s * (wx * vy - wy * vx) + wv * wz


@njit(**KERNEL_OPTIONS)
def rotate(vectors, angular_velocity, h):
    """Rotate each row of ``vectors`` about its particle's omega by |omega| h (see :func:`rotate_one`)."""
    for i in range(vectors.shape[0]):
        rotate_one(vectors, angular_velocity, h, i)


@njit(**KERNEL_OPTIONS)
def advance_spin(angular_velocity, dipole, torque, inertia, kick_h, rotate_h):
    """omega += tau/I kick_h, then rotate the dipoles by omega rotate_h (skips absent fields)."""
    if angular_velocity.shape[0] == 0:
        return
    if kick_h != 0.0:
        kick(angular_velocity, torque, inertia, kick_h)
    if rotate_h != 0.0 and dipole.shape[0] > 0:
        rotate(dipole, angular_velocity, rotate_h)


@njit(**KERNEL_OPTIONS)
def rotation_rate(tx, ty, tz, wx, wy, wz):
    """dexp^-1_theta(omega) = omega - (theta x omega)/2 + theta x (theta x omega)/12: the rate of the
    rotation vector theta of a body turning at omega (series truncated after the terms RK4's
    fourth order needs; exact for theta parallel to omega)."""
    cx = ty * wz - tz * wy
    cy = tz * wx - tx * wz
    cz = tx * wy - ty * wx
    return (wx - 0.5 * cx + (ty * cz - tz * cy) * (1.0 / 12), wy - 0.5 * cy + (tz * cx - tx * cz) * (1.0 / 12),
            wz - 0.5 * cz + (tx * cy - ty * cx) * (1.0 / 12))


@njit(**KERNEL_OPTIONS)
def rk_save(stage, position, velocity, angular_velocity, dipole):
    """Start an RK step: stage[0..3] = x0, v0, w0, m0; the sums stage[4..7] and theta stage[8] = 0."""
    for i in range(position.shape[0]):
        for a in range(3):
            stage[0, i, a] = position[i, a]
            stage[1, i, a] = velocity[i, a]
            for k in range(4, 9):
                stage[k, i, a] = 0.0
    for i in range(angular_velocity.shape[0]):
        for a in range(3):
            stage[2, i, a] = angular_velocity[i, a]
    for i in range(dipole.shape[0]):
        for a in range(3):
            stage[3, i, a] = dipole[i, a]


@njit(**KERNEL_OPTIONS)
def rk_stage(stage, position, velocity, angular_velocity, dipole, force, torque, mass, inertia, b, c):
    """One Runge-Kutta-Munthe-Kaas stage after its forces: with the stage slopes k = (v, F/m, tau/I,
    dexp^-1_theta(w)) add b k to the sums stage[4..7], and move the arrays to the next stage
    x0 + c k, v0 + c k, w0 + c k, theta = c k, m = exp(theta) m0 (c: the next stage's step, 0 at
    the last; stage[8] holds each sphere's theta)."""
    for i in range(position.shape[0]):
        inv = 1.0 / mass[i]
        for a in range(3):
            kx = velocity[i, a]
            kv = force[i, a] * inv
            stage[4, i, a] += b * kx
            stage[5, i, a] += b * kv
            position[i, a] = stage[0, i, a] + c * kx
            velocity[i, a] = stage[1, i, a] + c * kv
    dipoles = dipole.shape[0] > 0
    for i in range(angular_velocity.shape[0]):
        rate = rotation_rate(stage[8, i, 0], stage[8, i, 1], stage[8, i, 2], angular_velocity[i, 0],
                             angular_velocity[i, 1], angular_velocity[i, 2])
        inv = 1.0 / inertia[i]
        for a in range(3):
            kw = torque[i, a] * inv
            stage[6, i, a] += b * kw
            stage[7, i, a] += b * rate[a]
            angular_velocity[i, a] = stage[2, i, a] + c * kw
            stage[8, i, a] = c * rate[a]
        if dipoles:
            for a in range(3):
                dipole[i, a] = stage[3, i, a]
            rotate_one(dipole, stage[8], 1.0, i)


@njit(**KERNEL_OPTIONS)
def rk_finish(stage, position, velocity, angular_velocity, dipole, h):
    """End an RK step: x = x0 + h sum(b k), likewise v and w, m = exp(h sum(b dexp^-1)) m0."""
    for i in range(position.shape[0]):
        for a in range(3):
            position[i, a] = stage[0, i, a] + h * stage[4, i, a]
            velocity[i, a] = stage[1, i, a] + h * stage[5, i, a]
    dipoles = dipole.shape[0] > 0
    for i in range(angular_velocity.shape[0]):
        for a in range(3):
            angular_velocity[i, a] = stage[2, i, a] + h * stage[6, i, a]
            stage[8, i, a] = h * stage[7, i, a]
        if dipoles:
            for a in range(3):
                dipole[i, a] = stage[3, i, a]
            rotate_one(dipole, stage[8], 1.0, i)


@njit(**KERNEL_OPTIONS)
def kick_all(velocity, angular_velocity, dipole, force, torque, mass, inertia, h, rotate_h):
    """v += F/m h, omega += tau/I h, then the dipoles turn by omega rotate_h (0: not at all)."""
    kick(velocity, force, mass, h)
    advance_spin(angular_velocity, dipole, torque, inertia, h, rotate_h)


#: below this many spheres the finiteness check loops over the rows themselves: a flat view costs
#: ~45 ns a call, which doubled the time of a step of the paper's two spheres
FEW_SPHERES = 32


@njit(**KERNEL_OPTIONS)
def finite_sum(values):
    """The sum of x - x over a C-contiguous array: 0 when every value is finite (x - x is 0 for any
    finite x, however large: no overflow), NaN as soon as one is NaN or inf. Over a flat view, so
    that where the sum may be reordered (:data:`FINITE_CHECK_MATH`) the compiler vectorises it."""
    flat = values.reshape(-1)
    s = 0.0
    for k in range(flat.shape[0]):
        s += flat[k] - flat[k]
    return s


@njit(**KERNEL_OPTIONS)
def state_is_finite(position, velocity, angular_velocity):
    """True if no position, velocity or angular velocity is NaN or inf (sums of x - x, see
    :func:`finite_sum`; 8000 spheres: 9.5 us a call, called with :data:`FINITE_CHECK_MATH`)."""
    if position.shape[0] < FEW_SPHERES:
        s = 0.0
        for i in range(position.shape[0]):
            for a in range(3):
                s += (position[i, a] - position[i, a]) + (velocity[i, a] - velocity[i, a])
        for i in range(angular_velocity.shape[0]):
            for a in range(3):
                s += angular_velocity[i, a] - angular_velocity[i, a]
        return s == 0.0
    return finite_sum(position) + finite_sum(velocity) + finite_sum(angular_velocity) == 0.0


@njit(**dict(HELPER_OPTIONS, fastmath=False))  # once a frame: compiled once and called, not inlined
def kinetic_energies(velocity, angular_velocity, mass, inertia):
    """(sum m v^2/2, sum I w^2/2); fixed spheres (infinite mass, at rest) count zero."""
    kin = 0.0
    for i in range(velocity.shape[0]):
        if mass[i] < math.inf:
            kin += 0.5 * mass[i] * (velocity[i, 0] ** 2 + velocity[i, 1] ** 2 + velocity[i, 2] ** 2)
    rot = 0.0
    for i in range(angular_velocity.shape[0]):
        if inertia[i] < math.inf:
            rot += 0.5 * inertia[i] * (angular_velocity[i, 0] ** 2 + angular_velocity[i, 1] ** 2
                                       + angular_velocity[i, 2] ** 2)
    return kin, rot


@njit(**KERNEL_OPTIONS)
def copy_vectors(out, a):
    """out[:n] = a[:n] for (N,3) arrays, n the smaller length (an absent field is (0,3))."""
    for i in range(min(out.shape[0], a.shape[0])):
        out[i, 0] = a[i, 0]
        out[i, 1] = a[i, 1]
        out[i, 2] = a[i, 2]


@njit(**KERNEL_OPTIONS)
def add_rows(out, a, b):
    """out = a + b, row by row (arrays of the same shape)."""
    for i in range(out.shape[0]):
        out[i, 0] = a[i, 0] + b[i, 0]
        out[i, 1] = a[i, 1] + b[i, 1]
        out[i, 2] = a[i, 2] + b[i, 2]


@njit(**KERNEL_OPTIONS)
def total_forces(force, torque, stage):
    """force, torque = the slow (stage[0], stage[1]) plus the fast (stage[2], stage[3]) parts."""
    add_rows(force, stage[0], stage[2])
    add_rows(torque, stage[1], stage[3])


@njit(**KERNEL_OPTIONS)
def clear(force, torque):
    """Zero the force and torque arrays."""
    for i in range(force.shape[0]):
        for a in range(3):
            force[i, a] = 0.0
    for i in range(torque.shape[0]):
        for a in range(3):
            torque[i, a] = 0.0


@njit(cache=True, _nrt=False, inline="always")
def fold(x, length):
    """(x - k length in [0, length), k): round-off that leaves exactly length counts one period more."""
    k = math.floor(x / length)
    folded = x - k * length
    if folded >= length:
        folded -= length
        k += 1
    return folded, k


@njit(**dict(HELPER_OPTIONS, fastmath=False))  # once a frame: compiled once and called, not inlined
def store_frame(k, position, velocity, angular_velocity, dipole, image, tag, mass, inertia, box, periodic,
                record):
    """Copy the state into frame k of the record arrays, particle i at row tag[i] (the user's order).

    Along periodic axes the recorded position is folded into [0, L) and the recorded image count
    follows. Also stores the angular momentum about 0 of the unwrapped positions.
    """
    rec_position, rec_velocity, rec_omega, rec_dipole, rec_energy, rec_momentum, rec_image = record
    lx = 0.0
    ly = 0.0
    lz = 0.0
    for i in range(position.shape[0]):
        row = tag[i]
        for a in range(3):
            x = position[i, a]
            if periodic[a]:
                folded, shift = fold(x, box[a])
                rec_position[k, row, a] = folded
                rec_image[k, row, a] = image[i, a] + shift
                x += image[i, a] * box[a]
            else:
                rec_position[k, row, a] = x
            rec_velocity[k, row, a] = velocity[i, a]
        ux = position[i, 0] + (image[i, 0] * box[0] if periodic[0] else 0.0)
        uy = position[i, 1] + (image[i, 1] * box[1] if periodic[1] else 0.0)
        uz = position[i, 2] + (image[i, 2] * box[2] if periodic[2] else 0.0)
        m = mass[i] if mass[i] < math.inf else 0.0  # fixed spheres (infinite mass) never move
        px = m * velocity[i, 0]
        py = m * velocity[i, 1]
        pz = m * velocity[i, 2]
        lx += uy * pz - uz * py
        ly += uz * px - ux * pz
        lz += ux * py - uy * px
    for i in range(angular_velocity.shape[0]):
        row = tag[i]
        for a in range(3):
            rec_omega[k, row, a] = angular_velocity[i, a]
        inertia_i = inertia[i] if inertia[i] < math.inf else 0.0
        lx += inertia_i * angular_velocity[i, 0]
        ly += inertia_i * angular_velocity[i, 1]
        lz += inertia_i * angular_velocity[i, 2]
    for i in range(dipole.shape[0]):
        row = tag[i]
        for a in range(3):
            rec_dipole[k, row, a] = dipole[i, a]
    rec_momentum[k, 0] = lx
    rec_momentum[k, 1] = ly
    rec_momentum[k, 2] = lz


def empty_vectors(dtype=np.float64):
    """Placeholder (0,3) array standing for an absent optional field."""
    return np.zeros((0, 3), dtype=dtype)


@njit(**KERNEL_OPTIONS)
def sum_chunks(target, buffers, count):
    """target += buffers[0] + ... + buffers[count - 1], in that order, and the buffers zeroed for
    the next evaluation (chunked pair loops: their buffers are zero on entry, so no separate pass
    clears them)."""
    for i in range(target.shape[0]):
        for a in range(3):
            total = target[i, a]
            for t in range(count):
                total += buffers[t, i, a]
                buffers[t, i, a] = 0.0
            target[i, a] = total


# ---- the same passes compiled once and called, for scenes with neighbour lists (their generated
# module imports these under the plain names). Inlined, each call site of a pass is re-typed and
# re-lowered in every scene's time loop (a 600-sphere magnetic gas: 17 s of compiling at its first
# run against 12 s called); called, they are compiled once per machine, and a call per step costs
# nothing next to a pair loop. Small scenes keep them inlined: a call costs there (two spheres step
# at ~10^7 steps/s inlined, half that called).
def _called(fn):
    """``fn`` compiled as a function of its own (never inlined by numba), without fast-math flags:
    inlined by numba, a pass takes those of the generated module that inlines it (none), and a
    scene must round the same whichever form its time loop calls (the open scenes' fused module
    inlines, the generic module calls: demkit.engine.tiers)."""
    return njit(**dict(HELPER_OPTIONS, fastmath=False))(fn.py_func)


#: the passes the integrators' templates and the generated modules call
CALLED_PASSES = ("kick", "drift", "rotate", "advance_spin", "rk_save", "rk_stage", "rk_finish", "kick_all",
                 "state_is_finite", "kinetic_energies", "copy_vectors", "total_forces", "clear", "store_frame",
                 "sum_chunks")
kick_called = _called(kick)
drift_called = _called(drift)
rotate_called = _called(rotate)
advance_spin_called = _called(advance_spin)
rk_save_called = _called(rk_save)
rk_stage_called = _called(rk_stage)
rk_finish_called = _called(rk_finish)
kick_all_called = _called(kick_all)
#: reassociation alone (no flag that lets the compiler assume finite values, which would fold x - x to 0)
FINITE_CHECK_MATH = {"reassoc"}
state_is_finite_called = njit(**dict(HELPER_OPTIONS, fastmath=FINITE_CHECK_MATH))(state_is_finite.py_func)
kinetic_energies_called = kinetic_energies  # (called by every scene: once a frame)
copy_vectors_called = _called(copy_vectors)
total_forces_called = _called(total_forces)
clear_called = _called(clear)
store_frame_called = store_frame  # (called by every scene: once a frame)
sum_chunks_called = _called(sum_chunks)


# ---- the same passes on threads, for threaded scenes with neighbour lists (their generated module
# imports these under the plain names, so integrator templates stay as they are)
THREAD_OPTIONS = dict(cache=True, _nrt=False, parallel=True, fastmath=FASTMATH, error_model="numpy")


@njit(**THREAD_OPTIONS)
def kick_threads(velocity, force, mass, h):
    """v += F/m h, particles split among threads."""
    for i in prange(velocity.shape[0]):
        s = h / mass[i]
        velocity[i, 0] += s * force[i, 0]
        velocity[i, 1] += s * force[i, 1]
        velocity[i, 2] += s * force[i, 2]


@njit(**THREAD_OPTIONS)
def drift_threads(position, velocity, h):
    """x += v h, particles split among threads."""
    for i in prange(position.shape[0]):
        position[i, 0] += h * velocity[i, 0]
        position[i, 1] += h * velocity[i, 1]
        position[i, 2] += h * velocity[i, 2]


@njit(**THREAD_OPTIONS)
def rotate_threads(vectors, angular_velocity, h):
    """:func:`rotate`, particles split among threads."""
    for i in prange(vectors.shape[0]):
        rotate_one(vectors, angular_velocity, h, i)


@njit(cache=True, _nrt=False, fastmath=FASTMATH, error_model="numpy")
def advance_spin_threads(angular_velocity, dipole, torque, inertia, kick_h, rotate_h):
    """:func:`advance_spin` with its passes on threads."""
    if angular_velocity.shape[0] == 0:
        return
    if kick_h != 0.0:
        kick_threads(angular_velocity, torque, inertia, kick_h)
    if rotate_h != 0.0 and dipole.shape[0] > 0:
        rotate_threads(dipole, angular_velocity, rotate_h)


@njit(cache=True, _nrt=False, fastmath=FASTMATH, error_model="numpy")
def kick_all_threads(velocity, angular_velocity, dipole, force, torque, mass, inertia, h, rotate_h):
    """:func:`kick_all` with its passes on threads."""
    kick_threads(velocity, force, mass, h)
    advance_spin_threads(angular_velocity, dipole, torque, inertia, h, rotate_h)


@njit(**THREAD_OPTIONS)
def sum_chunks_threads(target, buffers, count):
    """:func:`sum_chunks`, particles split among threads (the same sums, the same order; the
    buffers zeroed)."""
    for i in prange(target.shape[0]):
        for a in range(3):
            total = target[i, a]
            for t in range(count):
                total += buffers[t, i, a]
                buffers[t, i, a] = 0.0
            target[i, a] = total


@njit(**THREAD_OPTIONS)
def clear_threads(force, torque):
    """Zero the force and torque arrays, particles split among threads."""
    for i in prange(force.shape[0]):
        for a in range(3):
            force[i, a] = 0.0
    for i in prange(torque.shape[0]):
        for a in range(3):
            torque[i, a] = 0.0


@njit(cache=True, parallel=True, fastmath=FINITE_CHECK_MATH, error_model="numpy")  # reductions need NRT
def state_is_finite_threads(position, velocity, angular_velocity):
    """:func:`state_is_finite` on threads (its sums cut among them)."""
    s = 0.0
    for i in prange(position.shape[0]):
        s += ((position[i, 0] - position[i, 0]) + (position[i, 1] - position[i, 1]) + (position[i, 2] - position[i, 2])
              + (velocity[i, 0] - velocity[i, 0]) + (velocity[i, 1] - velocity[i, 1])
              + (velocity[i, 2] - velocity[i, 2]))
    t = 0.0
    for i in prange(angular_velocity.shape[0]):
        t += ((angular_velocity[i, 0] - angular_velocity[i, 0]) + (angular_velocity[i, 1] - angular_velocity[i, 1])
              + (angular_velocity[i, 2] - angular_velocity[i, 2]))
    return s + t == 0.0
