"""Ready-made scenes: the seed paper's two-magnet non-central collision (Bartz & Shaw).

Paper units: mass m = 1, contact stiffness k = 1, time t_c = sqrt(m/k), length x_c with
3 mu0 m1 m2 / (4 pi) = 1 (unit moments and ``Dipole(prefactor=1/3)``). Sphere 1 starts at
(-x0, -b/2, 0) with velocity (+v, 0, 0), sphere 2 at (x0, +b/2, 0) with (-v, 0, 0), so the centre
of mass rests at the origin, the impact parameter is b and the total angular momentum is m v b.
Dipoles start along the initial line of centres n0 = (x2 - x1)/|x2 - x1|: 'aligned' (m1 = m2 = n0,
head to tail) or 'anti-aligned' (m1 = n0, m2 = -n0, head to head). Contact: Kelvin-Voigt with
dashpot c = 2 Gamma (the paper's Gamma = 0.05). A rigid barbell would spin at
omega_f = v b / (beta R^2) with beta = 14/5 (two spheres I = 2/5 m R^2 touching at distance 2R).
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from . import analysis
from ..integrators import EulerCromer
from ..interactions import Dipole, KelvinVoigt, PowerLawDipole
from ..particles import Particles
from ..scene import Scene
from ..simulation import Simulation
from ..trajectory import Trajectory

#: the seed paper's settings (dimensionless): R~, impact speed of each sphere, dashpot c = 2 Gamma
PAPER_RADIUS, PAPER_SPEED, PAPER_DAMPING = 6.94, 5.78e-3, 0.1
#: moment-of-inertia factors I = beta m R^2 of the final state about the centre of mass
BARBELL_BETA, POINT_MASS_BETA = 14.0 / 5.0, 2.0
#: the dipole prefactor A of the paper's units (3 mu0 m1 m2 / 4 pi = 1 with unit moments)
PAPER_PREFACTOR = 1.0 / 3.0
#: time allowed for the bouncing to stop after the first contact before more is run (t_c);
#: measured: 2000-4000 at the paper's settings
SETTLE_ALLOWANCE = 6000.0

MODELS = {"dipole": Dipole, "power_law": PowerLawDipole}


@dataclass(frozen=True)
class TwoMagnets:
    """The paper's collision of two equal magnetic spheres (all quantities in paper units).

    b_over_R : impact parameter b / R.       speed : v of each sphere (paper: 5.78e-3).
    radius : R~ = R / x_c (paper: 6.94).      x0 : initial |x| of each centre (paper: "far").
    damping : dashpot c = 2 Gamma (0.1).      stiffness : k (1).   mass : m of each sphere (1).
    model : 'dipole' (full force and torque) or 'power_law' (the paper's central approximation).
    dipoles : 'aligned', 'anti-aligned', or a (2, 3) array of moments.
    prefactor : dipole prefactor A (1/3 defines the paper's units; change it only to ask how
        results depend on the strength of the attraction).
    orientation : angle (degrees) by which both 'aligned' / 'anti-aligned' moments are turned in
        the collision plane (about +z) away from the initial line of centres: 0 is head to tail,
        90 side by side (m perpendicular to the line of centres). 0 leaves the moments untouched.
    """

    b_over_R: float
    speed: float = PAPER_SPEED
    radius: float = PAPER_RADIUS
    x0: float = 150.0
    damping: float = PAPER_DAMPING
    stiffness: float = 1.0
    mass: float = 1.0
    model: str = "dipole"
    dipoles: object = "aligned"
    prefactor: float = PAPER_PREFACTOR
    orientation: float = 0.0

    def __post_init__(self):
        for name in ("speed", "radius", "x0", "stiffness", "mass", "prefactor"):
            value = float(getattr(self, name))
            if not math.isfinite(value) or value <= 0:
                raise ValueError(f"TwoMagnets {name} must be positive and finite, got {value}")
        if not math.isfinite(self.b_over_R) or self.b_over_R < 0:
            raise ValueError(f"b_over_R must be >= 0, got {self.b_over_R}")
        if self.model not in MODELS:
            raise ValueError(f"model must be one of {sorted(MODELS)}, got {self.model!r}")
        if self.x0 <= self.radius:
            raise ValueError(f"x0 = {self.x0} must exceed the radius {self.radius} (spheres overlap)")
        if isinstance(self.dipoles, str) and self.dipoles not in ("aligned", "anti-aligned"):
            raise ValueError(f"dipoles must be 'aligned', 'anti-aligned' or moments, got {self.dipoles!r}")
        if not math.isfinite(self.orientation):
            raise ValueError(f"orientation must be a finite angle in degrees, got {self.orientation}")
        if self.orientation != 0 and not isinstance(self.dipoles, str):
            raise ValueError("orientation turns the 'aligned' / 'anti-aligned' moments; with explicit "
                             "moments set their directions yourself (orientation = 0)")

    # ---- set-up ------------------------------------------------------------------------------
    @property
    def b(self):
        """Impact parameter b = (b/R) R."""
        return self.b_over_R * self.radius

    def with_(self, **changes):
        """A copy with some fields changed (e.g. ``setup.with_(b_over_R=5.0)``)."""
        return dataclasses.replace(self, **changes)

    def moments(self):
        """(2, 3) initial dipole moments."""
        if not isinstance(self.dipoles, str):
            return np.array(self.dipoles, dtype=np.float64).reshape(2, 3)
        n0 = np.array([2.0 * self.x0, self.b, 0.0])
        n0 /= np.linalg.norm(n0)
        if self.orientation != 0:
            a = math.radians(self.orientation)
            n0 = np.array([n0[0] * math.cos(a) - n0[1] * math.sin(a),
                           n0[0] * math.sin(a) + n0[1] * math.cos(a), 0.0])
        return np.array([n0, n0 if self.dipoles == "aligned" else -n0])

    def particles(self):
        """The two spheres at t = 0."""
        half = 0.5 * self.b
        return Particles(position=[[-self.x0, -half, 0.0], [self.x0, half, 0.0]],
                         velocity=[[self.speed, 0.0, 0.0], [-self.speed, 0.0, 0.0]],
                         radius=self.radius, mass=self.mass, dipole=self.moments())

    def interactions(self):
        return [MODELS[self.model](prefactor=self.prefactor),
                KelvinVoigt(stiffness=self.stiffness, damping=self.damping)]

    def scene(self):
        return Scene(self.particles(), self.interactions())

    def simulation(self, dt=0.01, integrator=EulerCromer):
        """A Simulation of a fresh scene (``integrator`` is a class taking dt, or an instance)."""
        stepper = integrator if not isinstance(integrator, type) else integrator(dt)
        return Simulation(self.scene(), stepper)

    # ---- expectations ------------------------------------------------------------------------
    @property
    def initial_kinetic(self):
        """K_i = 2 (m v^2 / 2) = m v^2."""
        return self.mass * self.speed ** 2

    def expected_spin(self, beta=BARBELL_BETA):
        """omega_f = v b / (beta R^2) from angular-momentum conservation (m v b = beta m R^2 omega)."""
        return self.speed * self.b / (beta * self.radius ** 2)

    def approach_time(self):
        """Free-flight time to first contact (or closest approach); the attraction only shortens it."""
        reach = 2.0 * self.radius
        gap = math.sqrt(max(reach ** 2 - self.b ** 2, 0.0))
        return (2.0 * self.x0 - gap) / (2.0 * self.speed)

    # ---- runs --------------------------------------------------------------------------------
    def run(self, revolutions=5, dt=0.01, integrator=EulerCromer, record_every=1.0, max_time=None):
        """Run until the outcome is a miss or a bounce, or the pair settled and turned
        ``revolutions`` times (ready for :func:`demkit.two_magnets.analysis.final_spin`); returns the Trajectory.

        Runs in chunks (the first sized from :meth:`approach_time`, :data:`SETTLE_ALLOWANCE` and the
        expected period) and stops at ``max_time`` (default three times the first chunk) regardless.
        """
        period = 2 * math.pi / self.expected_spin() if self.b > 0 else 0.0
        first = self.approach_time() + SETTLE_ALLOWANCE + (revolutions + 0.5) * period
        max_time = 3.0 * first if max_time is None else float(max_time)
        chunk = max(0.5 * period, SETTLE_ALLOWANCE)
        sim = self.simulation(dt, integrator)
        parts = [sim.run(min(first, max_time), record_every)]
        while True:
            trajectory = Trajectory.concatenate(parts)
            if _finished(trajectory, revolutions, self.prefactor) or sim.time >= max_time - 0.5 * dt:
                return trajectory
            parts.append(sim.run(min(chunk, max_time - sim.time), record_every))

    def fate(self, dt=0.01, integrator=EulerCromer, record_every=1.0, max_time=None, chunk=2000.0):
        """(outcome, trajectory): run until :func:`demkit.two_magnets.analysis.outcome` is certain.

        Raises :class:`demkit.two_magnets.analysis.UndeterminedOutcome` if still undecided at ``max_time``
        (default: four approach times plus 20000).
        """
        first = 1.05 * self.approach_time()
        max_time = 4.0 * self.approach_time() + 20000.0 if max_time is None else float(max_time)
        sim = self.simulation(dt, integrator)
        parts = [sim.run(min(first, max_time), record_every)]
        while True:
            trajectory = Trajectory.concatenate(parts)
            try:
                return analysis.outcome(trajectory, prefactor=self.prefactor), trajectory
            except analysis.UndeterminedOutcome:
                if sim.time >= max_time - 0.5 * dt:
                    raise
            parts.append(sim.run(min(chunk, max_time - sim.time), record_every))


def _finished(trajectory, revolutions, prefactor):
    try:
        fate = analysis.outcome(trajectory, prefactor=prefactor)
    except analysis.UndeterminedOutcome:
        return False
    if fate != "stick":
        return True
    try:
        analysis.revolution_times(trajectory, revolutions)
    except ValueError:
        return False
    return True
