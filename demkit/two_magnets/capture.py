"""Capture threshold: the largest impact parameter at which two magnets still end up stuck.

:func:`capture_threshold` bisects on the simulated outcome of a :class:`demkit.two_magnets.TwoMagnets`
set-up; :func:`central_capture` is the closed-form answer for a central attraction
U(r) = -alpha / r^3 (exact for the power-law model, where touching at these speeds means sticking):
with reduced mass mu = m/2, relative speed 2v, L = mu (2v) b, energy E = mu (2v)^2/2 - alpha/r0^3 at
the start (r0 = sqrt(4 x0^2 + b^2)), the spheres touch iff E exceeds the top of the effective
potential U_eff(r) = -alpha/r^3 + L^2/(2 mu r^2) on [2R, r0]; its maximum is at r* = 3 alpha mu / L^2.
From infinity with r* > 2R this gives b_c^3 = 3 sqrt(3) alpha / (mu (2v)^2), i.e. b_c ~ v^(-2/3).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

from ..integrators import EulerCromer


@dataclass(frozen=True)
class Threshold:
    """Result of a bisection: the largest b/R seen to stick (``stick``), the smallest seen not to
    (``escape``), their midpoint ``b_over_R`` (uncertainty +- half the bracket), the evaluations
    [(b/R, outcome), ...] in order, and the non-sticking outcome at ``escape`` ('miss' or 'bounce')."""

    b_over_R: float
    stick: float
    escape: float
    escape_outcome: str
    evaluations: list = field(default_factory=list)

    @property
    def half_width(self):
        return 0.5 * (self.escape - self.stick)


def capture_threshold(setup, lo, hi, tol=0.02, dt=0.01, integrator=EulerCromer, expand=4):
    """Bisect b/R in [lo, hi] for the stick / no-stick boundary of ``setup`` (a TwoMagnets whose
    b_over_R is replaced) until the bracket is narrower than ``tol``. The ends are checked first and
    moved outwards (by 15 %, at most ``expand`` times) if they do not bracket the boundary.
    Assumes one boundary (sticking below, not above); returns a :class:`Threshold`.
    """
    if not 0 < lo < hi or tol <= 0:
        raise ValueError(f"need 0 < lo < hi and tol > 0, got lo={lo}, hi={hi}, tol={tol}")
    evaluations = []

    def sticks(b):
        fate, _ = setup.with_(b_over_R=b).fate(dt=dt, integrator=integrator)
        evaluations.append((b, fate))
        return fate == "stick", fate

    for _ in range(expand + 1):
        if sticks(lo)[0]:
            break
        hi, lo = lo, lo / 1.15
    else:
        raise ValueError(f"no sticking found down to b/R = {lo:.4g}")
    for _ in range(expand + 1):
        ok, hi_fate = sticks(hi)
        if not ok:
            break
        lo, hi = hi, hi * 1.15
    else:
        raise ValueError(f"still sticking at b/R = {hi:.4g}")
    while hi - lo > tol:
        mid = 0.5 * (lo + hi)
        ok, fate = sticks(mid)
        if ok:
            lo = mid
        else:
            hi, hi_fate = mid, fate
    return Threshold(b_over_R=0.5 * (lo + hi), stick=lo, escape=hi, escape_outcome=hi_fate,
                     evaluations=evaluations)


def touches_central(b, speed, radius, x0, alpha=2.0 / 3.0, mass=1.0):
    """True if two spheres (each mass, speed, at x = -+x0, impact parameter b) touch under a
    central U = -alpha / r^3 (conservative: energy and orbital angular momentum conserved)."""
    mu = 0.5 * mass
    u = 2.0 * speed
    r0 = math.hypot(2.0 * x0, b)
    energy = 0.5 * mu * u * u - alpha / r0 ** 3
    if b == 0:
        return True
    ang2 = (mu * u * b) ** 2

    def u_eff(r):
        return -alpha / r ** 3 + ang2 / (2.0 * mu * r * r)

    r_top = min(max(3.0 * alpha * mu / ang2, 2.0 * radius), r0)
    return energy >= u_eff(r_top)


def central_capture(speed, radius, x0=math.inf, alpha=2.0 / 3.0, mass=1.0, tol=1e-10):
    """b/R at which the spheres stop touching under the central U = -alpha / r^3 (the power-law
    model in paper units: alpha = 2 A |m|^2 = 2/3). ``x0 = inf`` starts from infinity."""
    x0 = 1e12 if math.isinf(x0) else x0
    lo, hi = 0.0, 1.0
    while touches_central(hi * radius, speed, radius, x0, alpha, mass):
        lo, hi = hi, 2.0 * hi
        if hi > 1e9:
            raise ValueError("the spheres touch at every impact parameter")
    while hi - lo > tol * hi:
        mid = 0.5 * (lo + hi)
        if touches_central(mid * radius, speed, radius, x0, alpha, mass):
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)
