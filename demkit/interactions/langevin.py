"""Langevin thermostat: drag and random kicks on translation and rotation (spheres in a bath).

Each sphere feels

    F_i   = -gamma v_i     + sqrt(2 gamma kT / dt)   xi_i       (xi: independent standard normals,
    tau_i = -gamma_r w_i   + sqrt(2 gamma_r kT / dt) zeta_i      new at every step)

with drag gamma (force per velocity), rotational drag gamma_r (torque per angular velocity;
default the Stokes ratio gamma_r = (4/3) R_i^2 gamma of a sphere in a viscous fluid, since
gamma = 6 pi eta R and gamma_r = 8 pi eta R^3) and kT the bath temperature in energy units.

In a sheared box (:class:`demkit.Shear`: flow along a, gradient along b) the drag acts on the velocity
relative to the imposed flow, v_i - gammadot (x_ib - L_b / 2) e_a: the bath is a solvent moving
with the flow. A free sphere's peculiar velocity c then has <c_b c_b> = kT/m, <c_a c_b> =
-gammadot kT / (2 gamma), <c_a c_a> = kT/m + gammadot^2 m kT / (2 gamma^2) (the shear couples c_b
into c_a), checked in tests/test_shear.py.

Fluctuation-dissipation with velocity Verlet, the only integrator it runs with: the forces of a
step are evaluated at the half-kicked velocity u, so free spheres follow u' = (1 - a) u + (dt/m) R
with a = gamma dt / m. Its stationary variance is kT / (m (1 - a/2)), and the on-step velocity
v = (1 - a/2) u + (dt/2m) R then has variance exactly kT/m, and the positions diffuse with exactly
D = kT / gamma, for any 0 < a < 2 (the same for rotation with I and gamma_r). Interactions between
spheres add the usual O(dt^2) error of velocity Verlet. A step must keep a <= 1 (max_time_step).

The random numbers come from a counter-based generator (splitmix64 mixing of the seed, a
per-sphere key and a per-sphere step counter, kept in the sphere's history): they do not depend on
the thread count, the order of the spheres or when a run was interrupted, and a checkpoint carries
them, so a restart is bit-identical. The step counter advances on each committing force
evaluation; an evaluation that does not commit (the forces at the start of a run, diagnostics)
repeats the kicks of the last step.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit, uint64

from ..engine.motion import KERNEL_OPTIONS

from .base import inverse_inertia, non_negative, positive
from .sphere import SphereInteraction

_MIX1 = uint64(0xBF58476D1CE4E5B9)
_MIX2 = uint64(0x94D049BB133111EB)
_GOLDEN = uint64(0x9E3779B97F4A7C15)
#: the largest gamma dt / m (and gamma_r dt / I) a time step may reach (stable up to 2)
MAX_DRAG_STEP = 1.0


@njit(**KERNEL_OPTIONS)
def mix64(z):
    """splitmix64's finaliser: a bijective scramble of a 64-bit word."""
    z = (z ^ (z >> uint64(30))) * _MIX1
    z = (z ^ (z >> uint64(27))) * _MIX2
    return z ^ (z >> uint64(31))


@njit(**KERNEL_OPTIONS)
def normal_pair(seed, key, counter, k):
    """Two independent standard normals, number k (0, 1, 2) of (seed, key, counter): Marsaglia's
    polar method on uniforms drawn by hashing (no trigonometry: 3x faster than Box-Muller here)."""
    base = mix64(mix64(uint64(seed) ^ mix64(uint64(key) * _GOLDEN)) + uint64(counter) * uint64(1024))
    draw = uint64(k * 256)
    while True:  # accepts with probability pi/4; 128 tries fail with probability 1e-86
        u = (mix64(base + draw) >> uint64(11)) * (2.0 / 9007199254740992.0) - 1.0  # [-1, 1)
        v = (mix64(base + draw + uint64(1)) >> uint64(11)) * (2.0 / 9007199254740992.0) - 1.0
        draw += uint64(2)
        q = u * u + v * v
        if 0.0 < q < 1.0:
            f = math.sqrt(-2.0 * math.log(q) / q)
            return u * f, v * f


@njit(**KERNEL_OPTIONS)
def langevin_force(i, x, y, z, velocity, angular_velocity, radius, history, p, offset, commit,
                   drag, rotational_drag, kT, seed, flow_rate, flow_axis, gradient_axis, flow_middle, dt):
    if history[p, offset + 1] == 0.0:  # the sphere's key: its index at its first step
        key = i
        if commit:
            history[p, offset + 1] = i + 1.0
    else:
        key = int(history[p, offset + 1]) - 1
    counter = int(history[p, offset])
    if commit:
        history[p, offset] = counter + 1.0
    else:
        counter -= 1  # the kicks of the last step
    gamma_r = rotational_drag if rotational_drag >= 0.0 else 4.0 / 3.0 * radius[i] * radius[i] * drag
    if dt > 0.0:
        st = math.sqrt(2.0 * drag * kT / dt)
        sr = math.sqrt(2.0 * gamma_r * kT / dt)
    else:  # no time step yet (diagnostics before any run): the drag only
        st = 0.0
        sr = 0.0
    a, b = normal_pair(seed, key, counter, 0)
    c, d = normal_pair(seed, key, counter, 1)
    e, f = normal_pair(seed, key, counter, 2)
    # a sheared box's imposed flow u = gammadot (x_b - L_b / 2) along a (0 in a fixed box: v - 0 is v)
    u = flow_rate * ((x if gradient_axis == 0.0 else (y if gradient_axis == 1.0 else z)) - flow_middle)
    vx = velocity[i, 0] - (u if flow_axis == 0.0 else 0.0)
    vy = velocity[i, 1] - (u if flow_axis == 1.0 else 0.0)
    vz = velocity[i, 2] - (u if flow_axis == 2.0 else 0.0)
    return (-drag * vx + st * a, -drag * vy + st * b, -drag * vz + st * c,
            -gamma_r * angular_velocity[i, 0] + sr * d, -gamma_r * angular_velocity[i, 1] + sr * e,
            -gamma_r * angular_velocity[i, 2] + sr * f)


@njit(**KERNEL_OPTIONS)
def langevin_energy(i, x, y, z, velocity, angular_velocity, radius, history, p, offset, commit,
                    drag, rotational_drag, kT, seed, flow_rate, flow_axis, gradient_axis, flow_middle, dt):
    return 0.0


def flow_values(box):
    """The values of the parameters flow_rate, flow_axis, gradient_axis, flow_middle of a Langevin bath
    in ``box``: a sheared box's imposed flow u = gammadot (x_b - L_b / 2) e_a, else none."""
    shear = box.shear if box is not None else None
    if shear is None:
        return (Langevin.flow_rate, Langevin.flow_axis, Langevin.gradient_axis, Langevin.flow_middle)
    a, b = shear.axes
    return (shear.rate, float(a), float(b), 0.5 * float(box.size[b]))


class Langevin(SphereInteraction):
    """A heat bath at temperature ``temperature`` (k_B T, energy units) acting through a drag
    ``drag`` (gamma > 0, force per velocity) and random forces, and on rotation through
    ``rotational_drag`` (gamma_r > 0, torque per angular velocity; None: (4/3) R^2 gamma for each
    sphere, the ratio of Stokes drags) and random torques. ``seed``: an integer 0 <= seed < 2^53;
    the same seed gives the same run on any thread count. Runs with :class:`demkit.VelocityVerlet`
    (see the module docstring for why, and for what is exact)."""

    reads = ("velocity", "angular_velocity", "radius")
    torque = True
    history_size = 2  # per sphere: its step counter and its key
    parameters = ("drag", "rotational_drag", "temperature", "seed", "flow_rate", "flow_axis", "gradient_axis",
                  "flow_middle", "dt")
    #: the imposed flow the bath's drag acts relative to: none here; a scene in a sheared box writes its
    #: own (gammadot, a, b, L_b / 2) into its copy of the parameters (:func:`flow_values`)
    flow_rate, flow_axis, gradient_axis, flow_middle = 0.0, 0.0, 1.0, 0.0
    repeat_hint = "give one Langevin thermostat"
    stochastic = True  # a heat bath: no energy balance, VelocityVerlet only
    force_function = langevin_force
    energy_function = langevin_energy

    def __init__(self, temperature, drag, rotational_drag=None, seed=0):
        self.temperature = non_negative("Langevin temperature", temperature)
        self.drag = positive("Langevin drag", drag)
        if rotational_drag is None:
            self.rotational_drag = -1.0  # the Stokes ratio, per sphere (see the docstring)
        else:
            self.rotational_drag = positive("Langevin rotational_drag", rotational_drag)
        if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or not 0 <= int(seed) < 2**53:
            raise ValueError(f"Langevin seed must be an integer with 0 <= seed < 2**53, got {seed!r}")
        self.seed = int(seed)
        self.dt = 0.0  # set by each run

    def rotational_drags(self, particles):
        """gamma_r of each sphere, (N,)."""
        radius = np.broadcast_to(np.asarray(particles.radius, dtype=np.float64), (len(particles),))
        if self.rotational_drag >= 0.0:
            return np.full(len(particles), self.rotational_drag)
        return 4.0 / 3.0 * radius**2 * self.drag

    def max_time_step(self, particles):
        """gamma dt / m and gamma_r dt / I at most MAX_DRAG_STEP for every sphere (fixed ones aside)."""
        inv_mass, inv_inertia = inverse_inertia(particles)
        rate = max(float(np.max(self.drag * inv_mass, initial=0.0)),
                   float(np.max(self.rotational_drags(particles) * inv_inertia, initial=0.0)))
        return MAX_DRAG_STEP / rate if rate > 0.0 else math.inf

    def __repr__(self):
        rot = None if self.rotational_drag < 0.0 else self.rotational_drag
        return (f"Langevin(temperature={self.temperature!r}, drag={self.drag!r}, rotational_drag={rot!r}, "
                f"seed={self.seed!r})")
