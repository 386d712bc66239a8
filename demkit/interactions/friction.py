"""Coulomb friction with a tangential spring-dashpot, the elastic displacement kept per contact.

A contact law (Kelvin-Voigt, Hertz) calls :func:`pair_friction` (or :func:`wall_friction`) with its
normal force; the same call adds rolling resistance (:mod:`.rolling`) when the law has it (twisting
resistance, :mod:`.twisting`, is added by the law's own twisting kernels after this call). In the
pair's orientation (n = (x_j - x_i)/r, overlap delta), the slip velocity of j's contact point
relative to i's is

    v_c = v_j - v_i - (a_i w_i + a_j w_j) x n,    v_t = v_c - (v_c.n) n,

with lever arms a = R - delta/2 (the contact point; ``slip_radius="full"`` takes a = R there, as
LAMMPS' pair granular does). The slip drives the spring-dashpot-slider of :mod:`.spring`: the
elastic tangential displacement xi (history, 3 values) is first
turned into the current tangent plane keeping its length, then advanced by v_t dt; the trial force
on j is F_t = -k_t xi - eta_t v_t. Beyond the Coulomb limit |F_t| > mu |F_n| the force is scaled
to mu |F_n| and xi set to -F_t/k_t: while sliding, the spring holds the whole Coulomb force. The torques are tau_i = -a_i n x F_t, tau_j = -a_j n x F_t (both at the contact point, so
angular momentum is conserved). This follows LAMMPS' ``tangential linear_history`` (Luding, Granular
Matter 10, 235 (2008), eq. 17), including two details: the limit uses |F_n| (a dashpot-dominated
pulling contact still has friction), and a trial force beyond the limit with no stored displacement
(possible only in an evaluation that does not advance the history, such as the first of a run) is
zero. One place differs on purpose: LAMMPS sets xi = -(F_t + eta_t v_t)/k_t when sliding, so that
the spring holds the Coulomb force minus the dashpot's part; when the dashpot alone exceeds the limit
(the first steps of a fast contact) the spring then stores a force pointing along the slip, which a
growing Mindlin stiffness turns into a friction force that drives the slip (measured: Chung & Ooi
test 6 lost 13 % of its friction impulse that way). demkit's spring holds the whole Coulomb force;
``Friction(sliding="lammps")`` keeps LAMMPS' rule for side-by-side comparisons.

Energy: the spring stores U_t = k_t |xi|^2 / 2 (reported with the contact energy); the dissipated
power booked is P = -F_t.v_t - dU_t/dt, with F_t.v_t the work of the forces through the kicks they
act in (:mod:`.spring`), so kinetic + potential + dissipated is conserved. Hertz-
Mindlin springs change k_t with the contact radius; the history's fourth value keeps the last k_t
so that dU_t is exact.
"""
from __future__ import annotations

from numba import njit

from ..engine.motion import HELPER_OPTIONS

from .base import non_negative, positive
from .rolling import rolling_on_i
from .spring import HISTORY, release, spring_energy, spring_force  # noqa: F401 (re-exported for the laws)


class Friction:
    """Coulomb friction for a contact law.

    coefficient : mu >= 0, |F_t| <= mu |F_n|.
    stiffness : k_t > 0, tangential spring (force per length); None: 2/7 of the normal stiffness for
        Kelvin-Voigt (equal normal and tangential periods of a sphere), Mindlin's 8 G* a for Hertz.
    damping : eta_t >= 0, tangential dashpot (force per velocity); None: the same damping ratio as
        the normal dashpot, eta_t = eta_n sqrt(k_t / k_n).
    slip_radius : "contact" (lever arms R - delta/2 in the slip velocity, energy-consistent with the
        torques; R - delta on a wall) or "full" (R in the slip, LAMMPS' convention; between spheres the
        energy balance is then off by O(delta/R) of the rolling work; on a wall the torque takes R too,
        as LAMMPS' wall does, and the balance stays exact).
    sliding : "coulomb" (while sliding the spring holds the whole Coulomb force) or "lammps" (it holds
        the Coulomb force minus the dashpot's part, xi = -(F_t + eta_t v_t)/k_t, as LAMMPS'
        linear_history and rolling sds: for side-by-side comparisons; see the module docstring).
    """

    def __init__(self, coefficient, stiffness=None, damping=None, slip_radius="contact", sliding="coulomb"):
        self.coefficient = non_negative("Friction coefficient", coefficient)
        self.stiffness = None if stiffness is None else positive("Friction stiffness", stiffness)
        self.damping = None if damping is None else non_negative("Friction damping", damping)
        if slip_radius not in ("contact", "full"):
            raise ValueError(f"Friction slip_radius must be 'contact' or 'full', got {slip_radius!r}")
        self.slip_radius = slip_radius
        if sliding not in ("coulomb", "lammps"):
            raise ValueError(f"Friction sliding must be 'coulomb' or 'lammps', got {sliding!r}")
        self.sliding = sliding

    @property
    def style(self):
        """The kernels' flags: 1 for slip_radius "full", + 2 for sliding "lammps"."""
        return (1.0 if self.slip_radius == "full" else 0.0) + (2.0 if self.sliding == "lammps" else 0.0)

    def __repr__(self):
        return (f"Friction(coefficient={self.coefficient!r}, stiffness={self.stiffness!r}, "
                f"damping={self.damping!r}, slip_radius={self.slip_radius!r}, sliding={self.sliding!r})")


@njit(**HELPER_OPTIONS)
def friction_on_j(nx, ny, nz, vx, vy, vz, sx, sy, sz, ai, aj, normal, mu, kt, eta, share, history, p, o, commit, dt):
    """Friction force on j, torques on i and j (at the contact point, arms ai and aj) and dissipated
    power, for relative velocity v = v_j - v_i and lever sum s = a_i w_i + a_j w_j (the slip is
    v_c = v - s x n, its tangential part drives the spring of :mod:`.spring`)."""
    cx = vx - (sy * nz - sz * ny)
    cy = vy - (sz * nx - sx * nz)
    cz = vz - (sx * ny - sy * nx)
    cn = cx * nx + cy * ny + cz * nz
    fx, fy, fz, lost = spring_force(nx, ny, nz, cx - cn * nx, cy - cn * ny, cz - cn * nz, mu * abs(normal), kt, eta,
                                    share, history, p, o, commit, dt)
    qx = ny * fz - nz * fy
    qy = nz * fx - nx * fz
    qz = nx * fy - ny * fx
    return fx, fy, fz, -ai * qx, -ai * qy, -ai * qz, -aj * qx, -aj * qy, -aj * qz, lost


@njit(**HELPER_OPTIONS)
def pair_friction(nx, ny, nz, vx, vy, vz, w, i, j, radius, overlap, style, normal, mu, kt, eta, mu_r, kr, eta_r,
                  history, p, o, commit, dt):
    """:func:`friction_on_j` for two spheres: arms R - delta/2 (the slip uses the full radii when
    ``style`` is odd, as LAMMPS; LAMMPS' sliding rule when ``style`` >= 2, see :class:`Friction`),
    and rolling resistance when mu_r > 0 (history o + HISTORY .. o + 2 HISTORY)."""
    ai = radius[i] - 0.5 * overlap
    aj = radius[j] - 0.5 * overlap
    shift = 0.5 * overlap * (style % 2.0)
    share = 1.0 if style >= 2.0 else 0.0
    bi = ai + shift
    bj = aj + shift
    fx, fy, fz, tix, tiy, tiz, tjx, tjy, tjz, lost = friction_on_j(
        nx, ny, nz, vx, vy, vz, bi * w[i, 0] + bj * w[j, 0], bi * w[i, 1] + bj * w[j, 1], bi * w[i, 2] + bj * w[j, 2],
        ai, aj, normal, mu, kt, eta, share, history, p, o, commit, dt)
    if mu_r > 0.0:
        mx, my, mz, rolled = rolling_on_i(nx, ny, nz, w[i, 0] - w[j, 0], w[i, 1] - w[j, 1], w[i, 2] - w[j, 2],
                                          radius[i] * radius[j] / (radius[i] + radius[j]), normal, mu_r, kr, eta_r,
                                          share, history, p, o + HISTORY, commit, dt)
        tix += mx
        tiy += my
        tiz += mz
        tjx -= mx
        tjy -= my
        tjz -= mz
        lost += rolled
    return fx, fy, fz, tix, tiy, tiz, tjx, tjy, tjz, lost


@njit(**HELPER_OPTIONS)
def wall_friction(nx, ny, nz, vx, vy, vz, w, i, radius, overlap, style, normal, mu, kt, eta, mu_r, kr, eta_r,
                  history, p, o, commit, dt, ox=0.0, oy=0.0, oz=0.0):
    """:func:`friction_on_j` for sphere i on a rigid wall: the lever arm is R - delta (the contact
    point lies on the wall), or R when ``style`` is odd (``slip_radius="full"``: LAMMPS' wall takes
    R for both the slip and the torque); LAMMPS' sliding rule when ``style`` >= 2. With rolling
    resistance when mu_r > 0 (rolling radius R), on the sphere's spin relative to the wall's own
    (ox, oy, oz): a turning cylinder's or cone's omega a (the slip needs none: the wall's surface
    velocity at the contact, in v, carries its turning). Returns the force, the torque on the sphere
    and the power. The slip and the torque share their arm, so the friction's work is booked exactly."""
    a = radius[i] if style % 2.0 > 0.0 else radius[i] - overlap
    share = 1.0 if style >= 2.0 else 0.0
    fx, fy, fz, _, _, _, tx, ty, tz, lost = friction_on_j(nx, ny, nz, vx, vy, vz, a * w[i, 0], a * w[i, 1],
                                                          a * w[i, 2], 0.0, a, normal, mu, kt, eta, share, history,
                                                          p, o, commit, dt)
    if mu_r > 0.0:  # the wall is "i" (spinning at o), the sphere "j"
        # (-(w - o), not o - w: the same bits as -w when o = 0, signed zeros included)
        mx, my, mz, rolled = rolling_on_i(nx, ny, nz, -(w[i, 0] - ox), -(w[i, 1] - oy), -(w[i, 2] - oz), radius[i],
                                          normal, mu_r, kr, eta_r, share, history, p, o + HISTORY, commit, dt)
        tx -= mx
        ty -= my
        tz -= mz
        lost += rolled
    return fx, fy, fz, tx, ty, tz, lost


@njit(**HELPER_OPTIONS)
def springs_energy(history, p, offset, mu_r):
    """Energy of the tangential spring and, with rolling resistance, of the rolling spring."""
    energy = spring_energy(history, p, offset)
    if mu_r > 0.0:
        energy += spring_energy(history, p, offset + HISTORY)
    return energy
