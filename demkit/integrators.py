"""Time integrators. They see only force and torque arrays, never which interactions exist.

Each integrator names a *loop template*: a plain Python function whose source is pasted into the
scene's generated kernel module (:mod:`demkit.kernels`) and compiled there, so that many steps run
in compiled code between Python-level events. A template has the signature

    template(nsteps, first_step, stride, dt, forces_ready, s, record) -> int

where ``s`` is the scene's named state (:mod:`demkit.state`: ``s.position``, ``s.velocity``,
``s.angular_velocity``, ``s.dipole``, ``s.mass``, ``s.inertia``, ``s.force``, ``s.torque``,
``s.accum`` (accum[0]: dissipated work), ...). It may call ``forces_of(s, commit)`` (fills
``s.force``/``s.torque`` and keeps neighbour lists up to date; returns the dissipated power),
``end_step(step, countdown, stride, s, record)`` (list upkeep, finiteness check and recording;
returns the steps left until the next frame, or -1 when the run must stop) and the helpers of
:mod:`demkit.motion`. Pass fields straight into calls (``kick(s.velocity, s.force, s.mass, h)``);
binding them to local names makes numba count references at every use. It records frame
``step // stride`` after every step that is a multiple of ``stride`` (global count
``first_step + n + 1``) and returns -1, or the index n of the step after which the run stopped.
Per-particle arrays may be re-ordered or wrapped only in ``end_step``, between steps.

Planned without rework: a 4th-order symplectic composition (velocity-Verlet sub-steps with
Yoshida coefficients, same template shape), classic RK4 (stages on copies of the state arrays),
an adaptive reference solver (scipy on ``forces_of``), and multiple time stepping (the kernel
generator emits one ``forces_of`` per interaction group: stiff contacts inside, dipoles outside).
"""
from __future__ import annotations

import math

from .motion import advance_spin, drift, kick  # noqa: F401 (used by templates)


def euler_cromer_template(nsteps, first_step, stride, dt, forces_ready, s, record):
    countdown = stride - first_step % stride  # steps until the next recorded frame
    for n in range(nsteps):
        s.accum[0] += dt * forces_of(s, True)  # noqa: F821 (defined in the generated module)
        kick(s.velocity, s.force, s.mass, dt)
        drift(s.position, s.velocity, dt)
        advance_spin(s.angular_velocity, s.dipole, s.torque, s.inertia, dt, dt)
        countdown = end_step(first_step + n + 1, countdown, stride, s, record)  # noqa: F821
        if countdown < 0:
            return n
    return -1


def velocity_verlet_template(nsteps, first_step, stride, dt, forces_ready, s, record):
    half = 0.5 * dt
    if not forces_ready:
        forces_of(s, False)  # noqa: F821
    countdown = stride - first_step % stride  # steps until the next recorded frame
    for n in range(nsteps):
        kick(s.velocity, s.force, s.mass, half)
        advance_spin(s.angular_velocity, s.dipole, s.torque, s.inertia, half, dt)
        drift(s.position, s.velocity, dt)
        s.accum[0] += dt * forces_of(s, True)  # noqa: F821
        kick(s.velocity, s.force, s.mass, half)
        advance_spin(s.angular_velocity, s.dipole, s.torque, s.inertia, half, 0.0)
        countdown = end_step(first_step + n + 1, countdown, stride, s, record)  # noqa: F821
        if countdown < 0:
            return n
    return -1


#: every loop template, compiled lazily into each scene's kernel module
TEMPLATES = {
    "euler_cromer": euler_cromer_template,
    "velocity_verlet": velocity_verlet_template,
}


class Integrator:
    """Base class: a fixed time step ``dt`` and the name of a loop template in :data:`TEMPLATES`."""

    template = None
    order = None

    def __init__(self, dt):
        dt = float(dt)
        if not math.isfinite(dt) or dt <= 0:
            raise ValueError(f"time step dt must be a positive finite number, got {dt}")
        self.dt = dt

    def __repr__(self):
        return f"{type(self).__name__}(dt={self.dt!r})"


class EulerCromer(Integrator):
    """Semi-implicit (symplectic) Euler, the seed paper's method; first order.

    v += F(x)/m dt; x += v dt; w += tau/I dt; dipoles rotate about the new w by |w| dt.
    """

    template = "euler_cromer"
    order = 1


class VelocityVerlet(Integrator):
    """Kick-drift-kick velocity Verlet with exact free rotation of the dipoles; second order.

    v += F/m dt/2, w += tau/I dt/2; x += v dt, dipoles rotate by |w| dt; new F, tau; v, w += dt/2.
    Velocity-dependent forces (dashpots) see the half-step velocities.
    """

    template = "velocity_verlet"
    order = 2
