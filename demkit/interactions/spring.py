"""The spring-dashpot-slider with history that sliding friction and rolling resistance share.

A contact with unit normal n keeps a displacement xi (history, 3 values, plus the spring stiffness
at its last update). Given a tangential rate u (u.n = 0: the slip velocity for friction, the rolling
velocity for rolling resistance), one committed update

1. turns xi into the current tangent plane keeping its length (only if its normal part matters, as
   LAMMPS does: |xi.n| k > EPSILON limit),
2. advances xi += u dt,
3. forms the trial force F = -k xi - eta u and, beyond the limit |F| > limit, scales F to the limit
   and sets xi = -F/k (while sliding the spring holds the whole limiting force; LAMMPS' rule,
   xi = -(F + eta u)/k, is available for comparisons: ``Friction(sliding="lammps")``).

Energy: the spring stores U = k |xi|^2 / 2. A committed update books the dissipated power
P = -(F + F_last).u / 2 - dU/dt (dU over the step, F_last the force of the last committed update,
kept in the history), so kinetic + potential + dissipated is conserved to second order in dt: a
force acts through the kick that ends at its update's velocities and the one that starts from them
(velocity Verlet's two half kicks, or Euler-Cromer's one), so its work is F.(u + u_next) dt / 2 with
u and u_next the rates its update and the next one see (exactly, for the same contact geometry).
Booking F.u dt alone, as before, left the balance of sliding contacts first order while their
motion was exact (docs/accuracy.md: a frictional gas drifted by 19.7 %, its motion right to 1.8 %). An
evaluation that does not commit reports the dissipation rate of that instant: eta |u|^2 while
sticking, -F.u while sliding. When the contact ends, whatever energy the springs still hold (a
Kelvin-Voigt contact may end under tension, with a Coulomb limit above zero) is booked as
dissipated.
"""
from __future__ import annotations

import math

from numba import njit

from ..engine.motion import HELPER_OPTIONS

#: history values per spring: displacement (3), the stiffness at the last update, and the force of
#: the last update (3: the second half of its work is booked at the next update)
HISTORY = 7
#: a displacement is turned into the tangent plane only if its normal part matters (as in LAMMPS)
EPSILON = 1e-10


@njit(**HELPER_OPTIONS)
def spring_force(nx, ny, nz, tx, ty, tz, limit, k, eta, share, history, p, o, commit, dt):
    """Force (3 values) and dissipated power of the spring-dashpot-slider for rate (tx, ty, tz) and
    force limit ``limit``; reads history[p, o:o+HISTORY] and writes it when ``commit``. ``share`` 1
    keeps LAMMPS' sliding rule xi = -(F + eta u)/k instead of xi = -F/k."""
    sx = history[p, o]
    sy = history[p, o + 1]
    sz = history[p, o + 2]
    old = 0.5 * history[p, o + 3] * (sx * sx + sy * sy + sz * sz)
    if commit:
        sn = sx * nx + sy * ny + sz * nz
        if abs(sn) * k > EPSILON * limit:  # turn into the tangent plane, keeping the length
            before = sx * sx + sy * sy + sz * sz
            sx -= sn * nx
            sy -= sn * ny
            sz -= sn * nz
            after = sx * sx + sy * sy + sz * sz
            scale = math.sqrt(before / after) if after > 0.0 else 0.0
            sx *= scale
            sy *= scale
            sz *= scale
        sx += tx * dt
        sy += ty * dt
        sz += tz * dt
    fx = -k * sx - eta * tx
    fy = -k * sy - eta * ty
    fz = -k * sz - eta * tz
    f = math.sqrt(fx * fx + fy * fy + fz * fz)
    sliding = f > limit
    if sliding:
        if sx * sx + sy * sy + sz * sz > 0.0:
            scale = limit / f
            fx *= scale
            fy *= scale
            fz *= scale
            sx = -(fx + share * eta * tx) / k  # sliding: the spring holds the whole limiting force
            sy = -(fy + share * eta * ty) / k  # (LAMMPS, share 1: minus the dashpot's part)
            sz = -(fz + share * eta * tz) / k
        else:  # no stored displacement (only when not committing): no force, as LAMMPS
            fx = 0.0
            fy = 0.0
            fz = 0.0
    power = -(fx * tx + fy * ty + fz * tz)
    if commit:
        # this force's work through the kick that ends here, and the last one's through the kick
        # that starts here (both at this rate): the module docstring
        power = 0.5 * (power - (history[p, o + 4] * tx + history[p, o + 5] * ty + history[p, o + 6] * tz))
        history[p, o] = sx
        history[p, o + 1] = sy
        history[p, o + 2] = sz
        history[p, o + 3] = k
        history[p, o + 4] = fx
        history[p, o + 5] = fy
        history[p, o + 6] = fz
        if dt > 0.0:
            power -= (0.5 * k * (sx * sx + sy * sy + sz * sz) - old) / dt
    elif not sliding:
        power = eta * (tx * tx + ty * ty + tz * tz)
    return fx, fy, fz, power


@njit(**HELPER_OPTIONS)
def spring_energy(history, p, o):
    """Elastic energy k |xi|^2 / 2 stored in a spring."""
    sx = history[p, o]
    sy = history[p, o + 1]
    sz = history[p, o + 2]
    return 0.5 * history[p, o + 3] * (sx * sx + sy * sy + sz * sz)


@njit(**HELPER_OPTIONS)
def release(history, p, o, springs, dt):
    """A contact that has ended keeps no displacement (``springs`` springs of HISTORY values); the
    energy its springs still held is dissipated: returns it as a power over the step."""
    energy = 0.0
    for s in range(springs):
        energy += spring_energy(history, p, o + HISTORY * s)
    for h in range(o, o + HISTORY * springs):
        history[p, h] = 0.0
    return energy / dt if dt > 0.0 else 0.0
