"""Rolling resistance: a spring-dashpot-slider on the relative rolling of two surfaces.

For a contact with normal n (from i to j) and rolling radius R* = R_i R_j / (R_i + R_j) (R for a
sphere on a wall), the rolling velocity is

    v_r = R* (w_i - w_j) x n

(zero when the two spheres turn together, whatever their orbit: it sees only rolling, not
sliding or rigid rotation). It drives the spring-dashpot-slider of :mod:`.spring` with limit
mu_r |F_n|: F_r = -k_r xi_r - eta_r v_r, |F_r| <= mu_r |F_n|. The resistance is a pure couple,

    tau_i = R* n x F_r,    tau_j = -tau_i,

no force, so linear and angular momentum are kept; its power tau_i.w_i + tau_j.w_j = F_r.v_r.
The limiting torque is mu_r R* |F_n|: a sphere rolling on a plane in gross rolling slows down at
5/7 mu_r g, and one at rest stays on a slope up to tan(theta) = mu_r. This is the elastic-plastic
spring-dashpot model ("type C") of Ai, Chen, Rotter & Ooi (Powder Technol. 206, 269 (2011)) with
its default stiffness k_r = 2.25 mu_r^2 k_n (a rolling torque stiffness 2.25 mu_r^2 R*^2 k_n,
after Iwashita & Oda 1998), written like LAMMPS' ``rolling sds`` (Luding 2008). Spin about the
normal is resisted by twisting resistance (:mod:`.twisting`), not here.
"""
from __future__ import annotations

from numba import njit

from ..engine.motion import HELPER_OPTIONS

from .base import non_negative, positive
from .spring import spring_force

#: default rolling stiffness as a multiple of mu_r^2 times the normal stiffness (Ai et al. 2011)
STIFFNESS_FACTOR = 2.25


class RollingResistance:
    """Rolling resistance for a contact law with friction.

    coefficient : mu_r >= 0 (dimensionless), the largest rolling torque is mu_r R* |F_n|.
    stiffness : k_r > 0 on the rolling displacement (force per length; the torque per radian is
        R*^2 k_r); None: 2.25 mu_r^2 times the normal stiffness (k for Kelvin-Voigt, the Hertz
        contact stiffness 2 E* a for Hertz), so that the torque is fully mobilised after a rolling
        angle of about 0.44/mu_r times delta/R*.
    damping : eta_r >= 0 (force per velocity); None: the normal damping ratio,
        eta_r = eta_n sqrt(k_r / k_n).
    """

    def __init__(self, coefficient, stiffness=None, damping=None):
        self.coefficient = non_negative("RollingResistance coefficient", coefficient)
        self.stiffness = None if stiffness is None else positive("RollingResistance stiffness", stiffness)
        self.damping = None if damping is None else non_negative("RollingResistance damping", damping)

    def __repr__(self):
        return (f"RollingResistance(coefficient={self.coefficient!r}, stiffness={self.stiffness!r}, "
                f"damping={self.damping!r})")


@njit(**HELPER_OPTIONS)
def rolling_on_i(nx, ny, nz, wx, wy, wz, rolling_radius, normal, mu_r, kr, eta_r, share, history, p, o, commit, dt):
    """Rolling-resistance torque on i (the torque on j is its negative) and dissipated power, for
    relative spin w = w_i - w_j and rolling radius R*."""
    ux = rolling_radius * (wy * nz - wz * ny)
    uy = rolling_radius * (wz * nx - wx * nz)
    uz = rolling_radius * (wx * ny - wy * nx)
    fx, fy, fz, lost = spring_force(nx, ny, nz, ux, uy, uz, mu_r * abs(normal), kr, eta_r, share, history, p, o, commit,
                                    dt)
    return (rolling_radius * (ny * fz - nz * fy), rolling_radius * (nz * fx - nx * fz),
            rolling_radius * (nx * fy - ny * fx), lost)
