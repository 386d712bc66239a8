"""Infinite plane walls with the scene's contact law, friction history per sphere.

A wall through ``point`` with unit ``normal`` n bounds the half-space (x - p).n > 0 where spheres
live. A sphere of radius R at height h = (x - p).n overlaps it by delta = R - h; the contact is the
pair contact with the wall as a partner of infinite mass and radius (R* = R, m* = m) whose
material is rigid (Hertz: E* = E/(1 - nu^2), G* = G/(2 - nu)). The wall may move: it is carried by
the displacement D(t) = V t + A (1 - cos 2 pi f t) (``velocity`` V, ``amplitude`` A, ``frequency`` f, any
directions), so it stands at x.n = p.n + D(t).n and its surface moves at D'(t) = V + 2 pi f A sin(2 pi f t):
a velocity in the plane slides it (a conveyor or shear plate), one along n is a piston, an amplitude
along n vibrates it (a vibrated bed: it starts at rest at ``point`` and swings to point + 2 A and back,
as LAMMPS' fix wall/gran ``wiggle``; peak acceleration (2 pi f)^2 |A|). Time is the scene's clock
(:attr:`demkit.Scene.time`, set by the time loops at every force evaluation;
demkit.interactions.wall_motion.wall_plane). A :class:`Servo` moves it instead to hold a force on it.
Friction keeps each sphere's tangential spring against the wall in per-sphere history; with twisting resistance the
wall, which does not spin, resists the sphere's spin about n (Marshall's a = sqrt(R delta)). A law
with friction passes its rolling and twisting numbers to the wall functions as a table
(:meth:`Wall.table_values`, :data:`TABLE`): one more scalar each would exceed the number of
arguments a compiled call can take. The table also holds the wall's own spin (a turning cylinder's or
cone's), which rolling and twisting resistance measure the sphere's spin against: a sphere turning with
the wall as one rigid body feels neither. The twisting functions take the frictional ones' arguments and
give their bits when the table says "no twisting": tier 1 runs both as one kind.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from .. import checks
from ..engine.motion import KERNEL_OPTIONS

from .contact import KelvinVoigt, kelvin_voigt_normal
from .friction import HISTORY, release, springs_energy, wall_friction
from .hertz import Hertz, hertz_normal, tangential_springs
from .sphere import SphereInteraction, vector
from .twisting import twist_energy, twist_release, twisting_on_i
from .wall_motion import S_DT, S_FORCE, S_GAIN, S_MAX_SPEED, S_POINTS, SERVO_STATE

#: a sphere may start overlapping a wall by at most this fraction of its radius
MAX_INITIAL_OVERLAP = 0.5


@njit(**KERNEL_OPTIONS)
def _wall_geometry(i, x, y, z, velocity, radius, plane, nx, ny, nz, ux, uy, uz):
    """(overlap, overlap rate, relative velocity) of sphere i against the wall."""
    overlap = radius[i] - (x * nx + y * ny + z * nz - plane)
    vx = velocity[i, 0] - ux
    vy = velocity[i, 1] - uy
    vz = velocity[i, 2] - uz
    return overlap, -(vx * nx + vy * ny + vz * nz), vx, vy, vz


@njit(**KERNEL_OPTIONS)
def wall_kelvin_voigt_force(i, x, y, z, velocity, radius, plane, nx, ny, nz, ux, uy, uz, stiffness, damping,
                            no_tension):
    overlap, rate, vx, vy, vz = _wall_geometry(i, x, y, z, velocity, radius, plane, nx, ny, nz, ux, uy, uz)
    if overlap <= 0.0:
        return 0.0, 0.0, 0.0, 0.0
    fn, elastic = kelvin_voigt_normal(overlap, rate, stiffness, damping, no_tension)
    return fn * nx, fn * ny, fn * nz, (fn - elastic) * rate


@njit(**KERNEL_OPTIONS)
def wall_kelvin_voigt_energy(i, x, y, z, velocity, radius, plane, nx, ny, nz, ux, uy, uz, stiffness, damping,
                             no_tension):
    overlap = radius[i] - (x * nx + y * ny + z * nz - plane)
    return 0.5 * stiffness * overlap * overlap if overlap > 0.0 else 0.0


@njit(**KERNEL_OPTIONS)
def wall_kelvin_voigt_friction_force(i, x, y, z, velocity, angular_velocity, radius, history, p, offset, commit,
                                     params, start, plane, nx, ny, nz, ux, uy, uz, stiffness, damping, no_tension,
                                     mu, kt, eta_t, style, dt):
    """A Kelvin-Voigt wall contact with friction and rolling resistance (if mu_r > 0); params[start:start +
    10] holds (mu_r, k_r, eta_r, k_tw, eta_tw, l_tw, twist, ox, oy, oz): :data:`TABLE` (twisting, not read
    here: :func:`wall_kelvin_voigt_twisting_force` takes the same arguments). The wall spins at (ox, oy, oz):
    its rolling resistance acts on the sphere's spin relative to the wall's."""
    mu_r = params[start]
    overlap, rate, vx, vy, vz = _wall_geometry(i, x, y, z, velocity, radius, plane, nx, ny, nz, ux, uy, uz)
    if overlap <= 0.0:
        lost = release(history, p, offset, 2 if mu_r > 0.0 else 1, dt) if commit else 0.0
        return 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, lost
    fn, elastic = kelvin_voigt_normal(overlap, rate, stiffness, damping, no_tension)
    ftx, fty, ftz, tx, ty, tz, lost = wall_friction(nx, ny, nz, vx, vy, vz, angular_velocity, i, radius, overlap,
                                                    style, fn, mu, kt, eta_t, mu_r, params[start + 1],
                                                    params[start + 2], history, p, offset, commit, dt,
                                                    params[start + 7], params[start + 8], params[start + 9])
    return fn * nx + ftx, fn * ny + fty, fn * nz + ftz, tx, ty, tz, (fn - elastic) * rate + lost


@njit(**KERNEL_OPTIONS)
def wall_kelvin_voigt_friction_energy(i, x, y, z, velocity, angular_velocity, radius, history, p, offset, commit,
                                      params, start, plane, nx, ny, nz, ux, uy, uz, stiffness, damping, no_tension,
                                      mu, kt, eta_t, style, dt):
    overlap = radius[i] - (x * nx + y * ny + z * nz - plane)
    if overlap <= 0.0:
        return 0.0
    return 0.5 * stiffness * overlap * overlap + springs_energy(history, p, offset, params[start])


@njit(**KERNEL_OPTIONS)
def wall_hertz_force(i, x, y, z, velocity, radius, mass, plane, nx, ny, nz, ux, uy, uz, young_eff, shear_eff,
                     gamma):
    overlap, rate, vx, vy, vz = _wall_geometry(i, x, y, z, velocity, radius, plane, nx, ny, nz, ux, uy, uz)
    if overlap <= 0.0:
        return 0.0, 0.0, 0.0, 0.0
    fn, elastic, _, _ = hertz_normal(overlap, rate, radius[i], mass[i], young_eff, gamma)
    return fn * nx, fn * ny, fn * nz, (fn - elastic) * rate


@njit(**KERNEL_OPTIONS)
def wall_hertz_energy(i, x, y, z, velocity, radius, mass, plane, nx, ny, nz, ux, uy, uz, young_eff, shear_eff,
                      gamma):
    overlap = radius[i] - (x * nx + y * ny + z * nz - plane)
    if overlap <= 0.0:
        return 0.0
    return 8.0 / 15.0 * young_eff * math.sqrt(radius[i]) * overlap ** 2.5


@njit(**KERNEL_OPTIONS)
def wall_hertz_friction_force(i, x, y, z, velocity, angular_velocity, radius, mass, history, p, offset, commit,
                              params, start, plane, nx, ny, nz, ux, uy, uz, young_eff, shear_eff, gamma, mu,
                              kt_fixed, eta_t_fixed, style, dt):
    """:func:`wall_kelvin_voigt_friction_force` for a Hertz contact; params[start:start + 10] holds (mu_r,
    k_r fixed, eta_r fixed, k_tw, eta_tw, l_tw, twist, ox, oy, oz): :data:`TABLE`."""
    mu_r = params[start]
    overlap, rate, vx, vy, vz = _wall_geometry(i, x, y, z, velocity, radius, plane, nx, ny, nz, ux, uy, uz)
    if overlap <= 0.0:
        lost = release(history, p, offset, 2 if mu_r > 0.0 else 1, dt) if commit else 0.0
        return 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, lost
    fn, elastic, stiffness, eta = hertz_normal(overlap, rate, radius[i], mass[i], young_eff, gamma)
    kt, eta_t, kr, eta_r = tangential_springs(kt_fixed, eta_t_fixed, mu_r, params[start + 1], params[start + 2],
                                              shear_eff, radius[i], overlap, stiffness, eta)
    ftx, fty, ftz, tx, ty, tz, lost = wall_friction(nx, ny, nz, vx, vy, vz, angular_velocity, i, radius, overlap,
                                                    style, fn, mu, kt, eta_t, mu_r, kr, eta_r, history, p, offset,
                                                    commit, dt, params[start + 7], params[start + 8],
                                                    params[start + 9])
    return fn * nx + ftx, fn * ny + fty, fn * nz + ftz, tx, ty, tz, (fn - elastic) * rate + lost


@njit(**KERNEL_OPTIONS)
def wall_hertz_friction_energy(i, x, y, z, velocity, angular_velocity, radius, mass, history, p, offset, commit,
                               params, start, plane, nx, ny, nz, ux, uy, uz, young_eff, shear_eff, gamma, mu,
                               kt_fixed, eta_t_fixed, style, dt):
    overlap = radius[i] - (x * nx + y * ny + z * nz - plane)
    if overlap <= 0.0:
        return 0.0
    return (8.0 / 15.0 * young_eff * math.sqrt(radius[i]) * overlap ** 2.5
            + springs_energy(history, p, offset, params[start]))


@njit(**KERNEL_OPTIONS)
def _wall_twist(nx, ny, nz, w, i, a, fn, kt, eta_t, mu, k_tw, eta_tw, lever_tw, style, history, p, o, commit, dt,
                ox, oy, oz):
    """Twisting torque on sphere i (contact radius a) and dissipated power (the wall, "i" of
    :func:`.twisting.twisting_on_i`, spins at (ox, oy, oz): a turning cone's spin about the normal)."""
    mx, my, mz, lost = twisting_on_i(nx, ny, nz, -(w[i, 0] - ox), -(w[i, 1] - oy), -(w[i, 2] - oz), fn, a, mu, kt,
                                     eta_t, k_tw, eta_tw, lever_tw, 1.0 if style >= 2.0 else 0.0, history, p, o,
                                     commit, dt)
    return -mx, -my, -mz, lost


@njit(**KERNEL_OPTIONS)
def wall_kelvin_voigt_twisting_force(i, x, y, z, velocity, angular_velocity, radius, history, p, offset, commit,
                                     params, start, plane, nx, ny, nz, ux, uy, uz, stiffness, damping, no_tension,
                                     mu, kt, eta_t, style, dt):
    """:func:`wall_kelvin_voigt_friction_force` with twisting resistance if the table's twist is 1 (0:
    that function's bits; tier 1 runs every frictional wall as this one, demkit.engine.catalogue)."""
    fx, fy, fz, tx, ty, tz, power = wall_kelvin_voigt_friction_force(
        i, x, y, z, velocity, angular_velocity, radius, history, p, offset, commit, params, start, plane, nx, ny, nz,
        ux, uy, uz, stiffness, damping, no_tension, mu, kt, eta_t, style, dt)
    if params[start + 6] == 0.0:  # no twisting
        return fx, fy, fz, tx, ty, tz, power
    mu_r = params[start]
    ox, oy, oz = params[start + 7], params[start + 8], params[start + 9]
    o = offset + (2 * HISTORY if mu_r > 0.0 else HISTORY)
    overlap, rate, _, _, _ = _wall_geometry(i, x, y, z, velocity, radius, plane, nx, ny, nz, ux, uy, uz)
    if overlap <= 0.0:
        if commit:
            power += twist_release(history, p, o, dt)
        return fx, fy, fz, tx, ty, tz, power
    fn, _ = kelvin_voigt_normal(overlap, rate, stiffness, damping, no_tension)
    mx, my, mz, lost = _wall_twist(nx, ny, nz, angular_velocity, i, math.sqrt(radius[i] * overlap), fn, kt, eta_t,
                                   mu, params[start + 3], params[start + 4], params[start + 5], style, history, p, o,
                                   commit, dt, ox, oy, oz)
    return fx, fy, fz, tx + mx, ty + my, tz + mz, power + lost


@njit(**KERNEL_OPTIONS)
def wall_kelvin_voigt_twisting_energy(i, x, y, z, velocity, angular_velocity, radius, history, p, offset, commit,
                                      params, start, plane, nx, ny, nz, ux, uy, uz, stiffness, damping, no_tension,
                                      mu, kt, eta_t, style, dt):
    energy = wall_kelvin_voigt_friction_energy(i, x, y, z, velocity, angular_velocity, radius, history, p, offset,
                                               commit, params, start, plane, nx, ny, nz, ux, uy, uz, stiffness,
                                               damping, no_tension, mu, kt, eta_t, style, dt)
    if params[start + 6] == 0.0 or radius[i] - (x * nx + y * ny + z * nz - plane) <= 0.0:
        return energy
    return energy + twist_energy(history, p, offset + (2 * HISTORY if params[start] > 0.0 else HISTORY))


@njit(**KERNEL_OPTIONS)
def wall_hertz_twisting_force(i, x, y, z, velocity, angular_velocity, radius, mass, history, p, offset, commit,
                              params, start, plane, nx, ny, nz, ux, uy, uz, young_eff, shear_eff, gamma, mu,
                              kt_fixed, eta_t_fixed, style, dt):
    """:func:`wall_hertz_friction_force` with twisting resistance if the table's twist is 1 (see
    :func:`wall_kelvin_voigt_twisting_force`)."""
    fx, fy, fz, tx, ty, tz, power = wall_hertz_friction_force(
        i, x, y, z, velocity, angular_velocity, radius, mass, history, p, offset, commit, params, start, plane, nx, ny,
        nz, ux, uy, uz, young_eff, shear_eff, gamma, mu, kt_fixed, eta_t_fixed, style, dt)
    if params[start + 6] == 0.0:  # no twisting
        return fx, fy, fz, tx, ty, tz, power
    mu_r = params[start]
    ox, oy, oz = params[start + 7], params[start + 8], params[start + 9]
    o = offset + (2 * HISTORY if mu_r > 0.0 else HISTORY)
    overlap, rate, _, _, _ = _wall_geometry(i, x, y, z, velocity, radius, plane, nx, ny, nz, ux, uy, uz)
    if overlap <= 0.0:
        if commit:
            power += twist_release(history, p, o, dt)
        return fx, fy, fz, tx, ty, tz, power
    fn, _, stiffness, eta = hertz_normal(overlap, rate, radius[i], mass[i], young_eff, gamma)
    kt, eta_t, _, _ = tangential_springs(kt_fixed, eta_t_fixed, 0.0, 0.0, 0.0, shear_eff, radius[i], overlap,
                                         stiffness, eta)
    mx, my, mz, lost = _wall_twist(nx, ny, nz, angular_velocity, i, math.sqrt(radius[i] * overlap), fn, kt, eta_t,
                                   mu, params[start + 3], params[start + 4], params[start + 5], style, history, p, o,
                                   commit, dt, ox, oy, oz)
    return fx, fy, fz, tx + mx, ty + my, tz + mz, power + lost


@njit(**KERNEL_OPTIONS)
def wall_hertz_twisting_energy(i, x, y, z, velocity, angular_velocity, radius, mass, history, p, offset, commit,
                               params, start, plane, nx, ny, nz, ux, uy, uz, young_eff, shear_eff, gamma, mu,
                               kt_fixed, eta_t_fixed, style, dt):
    energy = wall_hertz_friction_energy(i, x, y, z, velocity, angular_velocity, radius, mass, history, p, offset,
                                        commit, params, start, plane, nx, ny, nz, ux, uy, uz, young_eff, shear_eff,
                                        gamma, mu, kt_fixed, eta_t_fixed, style, dt)
    if params[start + 6] == 0.0 or radius[i] - (x * nx + y * ny + z * nz - plane) <= 0.0:
        return energy
    return energy + twist_energy(history, p, offset + (2 * HISTORY if params[start] > 0.0 else HISTORY))


_GEOMETRY = ("plane", "nx", "ny", "nz", "ux", "uy", "uz")
_FUNCTIONS = {
    (KelvinVoigt, False): (wall_kelvin_voigt_force, wall_kelvin_voigt_energy),
    (KelvinVoigt, True): (wall_kelvin_voigt_friction_force, wall_kelvin_voigt_friction_energy),
    (Hertz, False): (wall_hertz_force, wall_hertz_energy),
    (Hertz, True): (wall_hertz_friction_force, wall_hertz_friction_energy),
}
_TWISTING = {KelvinVoigt: (wall_kelvin_voigt_twisting_force, wall_kelvin_voigt_twisting_energy),
             Hertz: (wall_hertz_twisting_force, wall_hertz_twisting_energy)}
#: a frictional law's parameters that its walls take from their table instead, in the table's order
TWIST_TABLE = {KelvinVoigt: ("mu_r", "kr", "eta_r", "k_tw", "eta_tw", "lever_tw"),
               Hertz: ("mu_r", "kr_fixed", "eta_r_fixed", "k_tw", "eta_tw", "lever_tw")}
#: a frictional wall's table (:meth:`Wall.table_values`): those six, then whether the law twists (1) or not
#: (0) and the wall's own spin (ox, oy, oz), which the rolling and twisting springs measure the sphere's spin
#: against (a turning cylinder's or cone's omega a)
TABLE = ("mu_r", "kr", "eta_r", "k_tw", "eta_tw", "lever_tw", "twist", "ox", "oy", "oz")


def numbered_walls(effects):
    """(number, wall) of each wall among ``effects``, a scene's single-sphere effects, numbered as the
    scene numbers them (``Scene.contacts().wall``)."""
    return [(e, effect) for e, effect in enumerate(effects) if isinstance(effect, Wall)]


def _target(name, value):
    """A servo's target: a positive number, or (time, value) points with increasing times and positive
    values, as a tuple of pairs."""
    if np.ndim(value) == 0:
        return checks.positive(f"Servo {name}", value)
    try:
        points = np.array(value, dtype=np.float64)
    except (TypeError, ValueError):
        points = None
    if points is None or points.ndim != 2 or points.shape[1] != 2 or len(points) == 0 or not np.isfinite(points).all():
        raise ValueError(f"Servo {name} must be a positive number or a list of (time, value) points, got {value!r}")
    if np.any(np.diff(points[:, 0]) <= 0.0) or np.any(points[:, 1] <= 0.0):
        raise ValueError(f"Servo {name}'s (time, value) points need increasing times and positive values, got "
                         f"{points.tolist()}")
    return tuple((float(t), float(v)) for t, v in points)


class Servo:
    """A wall that moves along its normal to hold the spheres' push on it at a target: ``force``, or
    ``stress`` (force per area: the wall's area in a box periodic along both axes of its plane, that box's
    cross-section), for oedometric and triaxial tests and a packing under a set pressure.

    After every step the wall moves by gain (F - target) / K towards or away from the spheres (F: the
    normal force they exert on it, K: the sum of the secant stiffnesses F_i / delta_i of its contacts,
    so gain is the fraction of the error it corrects in one step when the packing responds like its
    contacts), at most ``max_speed`` x dt; touching nothing it moves at max_speed towards them.
    force or stress > 0 (one of them); max_speed > 0 (length per time); 0 < gain <= 1 (default 0.2).
    The target may change within a run: force or stress a list of (time, value) points (times of the
    scene's clock, increasing), the target the piecewise-linear function through them, held at the first
    value before its time and at the last after (a ramp: two points; stages: pairs of points at the same
    value). Each may be changed between runs (staged loading: ``wall.servo.stress = 2 * wall.servo.stress``),
    a list of points for one of at most as many as the scene was built with; a run holds the values it
    starts with.
    """

    def __init__(self, force=None, max_speed=None, gain=0.2, stress=None):
        if (force is None) == (stress is None):
            raise ValueError(f"Servo holds a force or a stress (force per area of the wall in a periodic box), one "
                             f"of them: got force={force!r}, stress={stress!r}")
        if max_speed is None:
            raise ValueError("Servo needs max_speed, the fastest the wall moves")
        self._force = self._stress = None
        if force is not None:
            self.force = force
        else:
            self.stress = stress
        self.max_speed = max_speed
        self.gain = gain

    @property
    def force(self):
        """The target force, a number or (time, value) points (None when the target is a stress)."""
        return self._force

    @force.setter
    def force(self, value):
        self._force, self._stress = _target("force", value), None

    @property
    def stress(self):
        """The target stress, a number or (time, value) points (None when the target is a force)."""
        return self._stress

    @stress.setter
    def stress(self, value):
        self._stress, self._force = _target("stress", value), None

    @property
    def points(self):
        """The (time, value) points of a target that changes within a run, as a (K, 2) array; None for a
        fixed target."""
        given = self._force if self._stress is None else self._stress
        return None if np.ndim(given) == 0 else np.array(given, dtype=np.float64)

    def target_at(self, time):
        """The target (a force or a stress, as given) at the scene's ``time``."""
        given = self._force if self._stress is None else self._stress
        if np.ndim(given) == 0:
            return given
        points = np.array(given)
        return float(np.interp(time, points[:, 0], points[:, 1]))

    @property
    def max_speed(self):
        return self._max_speed

    @max_speed.setter
    def max_speed(self, value):
        self._max_speed = checks.positive("Servo max_speed", value)

    @property
    def gain(self):
        return self._gain

    @gain.setter
    def gain(self, value):
        gain = checks.number("Servo gain", value)
        if not 0.0 < gain <= 1.0:
            raise ValueError(f"Servo gain must lie in (0, 1], got {value!r}: it is the fraction of the force error "
                             f"corrected in one step")
        self._gain = gain

    def factor(self, wall, box):
        """What the target's values are multiplied by in the compiled loops: 1 for a force; for a stress the
        wall's area, the cross-section of ``box`` (a demkit.Box or None) across its normal (the normal along
        a closed axis, the two others periodic); a cylinder's 2 pi L (per unit radius: wall_motion.servo_step)."""
        if hasattr(wall, "radius"):  # a cylinder: a stress on its side, per unit radius
            return wall.servo_factor(box)
        if self._stress is None:
            return 1.0
        axes = np.flatnonzero(np.abs(wall.normal) > 1e-12)
        if box is None or len(axes) != 1 or sum(box.periodic) != 2 or box.periodic[axes[0]]:
            raise ValueError(f"{wall!r} holds a stress: its area is the cross-section of a box periodic along both "
                             f"axes of its plane, so its normal must lie along the box's one closed axis (got "
                             f"{'no box' if box is None else box!r}); give the Servo a force instead")
        across = [a for a in range(3) if a != axes[0]]
        return float(box.size[across[0]] * box.size[across[1]])

    def target(self, wall, box, time=0.0):
        """The force to hold for ``wall`` in ``box`` at ``time``: ``force``, or ``stress`` times the wall's
        area (:meth:`factor`; a cylinder's: per unit radius)."""
        return self.target_at(time) * self.factor(wall, box)

    def write(self, block, wall, box):
        """Write the targets, max speed and gain into the servo's part of its wall's geometry block (at each
        run's start: they may change between runs); a list of points longer than the block holds is refused."""
        points = self.points
        room = (len(block) - (S_DT + 1)) // 2
        count = 0 if points is None else len(points)
        if count > room:
            raise ValueError(f"{wall!r}: its servo's target has {count} (time, value) points, but its scene was built "
                             f"for {room}; build the scene again with it (a scene keeps the size of its walls' blocks)")
        factor = self.factor(wall, box)
        block[S_FORCE] = (0.0 if count else self.target_at(0.0)) * factor
        block[S_MAX_SPEED] = self.max_speed
        block[S_GAIN] = self.gain
        block[S_POINTS] = count
        if count:
            block[S_DT + 1:S_DT + 1 + 2 * count] = (points * [1.0, factor]).ravel()

    def values(self):
        """The servo's part of the geometry block (:data:`demkit.interactions.wall_motion.SERVO`): target
        force (set by each run, :meth:`write`), max speed, gain, the number of (time, target) points, then
        its state (offset and speed along the normal, the force and the stiffness summed in the last force
        evaluation), the time step (set by each run) and the points (times and targets, set by each run)."""
        points = self.points
        count = 0 if points is None else len(points)
        return np.array([0.0, self.max_speed, self.gain, count, 0.0, 0.0, 0.0, 0.0, 0.0, *([0.0] * (2 * count))],
                        dtype=np.float64)

    def __repr__(self):
        target = f"force={self._force!r}" if self._stress is None else f"stress={self._stress!r}"
        return f"Servo({target}, max_speed={self.max_speed!r}, gain={self.gain!r})"


class Wall(SphereInteraction):
    """An infinite plane wall (see module docstring).

    point : a point of the plane at time 0; normal : points into the half-space of the spheres (any
    length > 0); velocity : the wall's constant velocity (in its plane: it slides; along the normal:
    a piston; default at rest); amplitude, frequency : a vibration A (1 - cos 2 pi f t) added to its
    motion (length vector, cycles per unit time; default none); contact : the contact law (a
    :class:`KelvinVoigt` or :class:`Hertz`), default the scene's own (which must then have exactly one);
    servo : a :class:`Servo` that moves the wall along its normal to hold a force on it (a velocity
    in its plane may go with it, not along its normal, nor a vibration).
    """

    dissipative = True
    energy_kind = "wall"
    plane_contact = True
    repeatable = True  # a box of walls
    #: the shape's code in the geometry block (demkit.interactions.wall_motion.SHAPES)
    shape = 0
    #: how many of the shape's numbers come before a servo's in its block (wall_motion.SERVO_AFTER)
    servo_after = 0

    def __init__(self, point, normal, velocity=(0.0, 0.0, 0.0), contact=None, amplitude=(0.0, 0.0, 0.0),
                 frequency=0.0, servo=None):
        name = type(self).__name__
        self.point = vector(f"{name} point", point)
        normal = vector(f"{name} normal", normal)
        length = float(np.linalg.norm(normal))
        if length == 0.0:
            raise ValueError(f"{name} normal has zero length")
        self.normal = normal / length
        self.velocity = vector(f"{name} velocity", velocity)
        self.amplitude = vector(f"{name} amplitude", amplitude)
        self.frequency = checks.number(f"{name} frequency", frequency)
        if not math.isfinite(self.frequency) or self.frequency < 0.0:
            raise ValueError(f"{name} frequency must be finite and >= 0, got {frequency!r}")
        if (self.frequency > 0.0) != bool(self.amplitude.any()):
            raise ValueError(f"{name} vibrates with an amplitude and a frequency, both non-zero: got amplitude "
                             f"{self.amplitude.tolist()} and frequency {self.frequency!r}")
        if servo is not None:
            if not isinstance(servo, Servo):
                raise TypeError(f"{name} servo must be a demkit.Servo, got {servo!r}")
            if self.amplitude.any() or abs(float(self.velocity @ self.normal)) > 1e-12 * max(
                    1.0, float(np.linalg.norm(self.velocity))):
                raise ValueError(f"{name} with a servo moves along its normal as the servo says: it takes no "
                                 f"vibration and no velocity along its normal (a velocity in its plane may go with it)")
        self.servo = servo
        if contact is not None and not isinstance(contact, (KelvinVoigt, Hertz)):
            raise TypeError(f"Wall contact must be a KelvinVoigt or Hertz contact law, got {contact!r}")
        self.contact = contact
        self.plane = float(self.point @ self.normal)  # the plane is x.n = plane (at time 0)
        self.nx, self.ny, self.nz = (float(c) for c in self.normal)
        self.ux, self.uy, self.uz = (float(c) for c in self.velocity)  # (a moving wall's come from its block)
        if contact is not None:
            self._adopt(contact)

    def bind(self, interactions):
        if self.contact is not None:
            return
        laws = [inter for inter in interactions if isinstance(inter, (KelvinVoigt, Hertz))]
        if len(laws) != 1:
            raise ValueError(f"Wall needs the scene's contact law, but the scene has {len(laws)} "
                             f"(KelvinVoigt or Hertz): pass Wall(..., contact=...)")
        self._adopt(laws[0])

    def _adopt(self, law):
        """Take the contact law's functions and parameters (the wall itself is rigid)."""
        self.law = law
        base = KelvinVoigt if isinstance(law, KelvinVoigt) else Hertz  # a subclass of yours acts as its base
        friction = law.friction is not None
        self.force_function, self.energy_function = _FUNCTIONS[(base, friction)]
        self.reads = law.reads
        self.torque = friction
        self.history_size = law.history_size
        names = list(law.parameters)
        self.table = np.zeros(0)
        if friction:  # the rolling and twisting numbers in a table, with the wall's spin (table_values)
            if law.twisting is not None:
                self.force_function, self.energy_function = _TWISTING[base]
            table = TWIST_TABLE[base]
            self.table = np.array([getattr(law, name) for name in table], dtype=np.float64)
            names = [name for name in names if name not in table]
        self.parameters = _GEOMETRY + tuple(names)
        for name in names:
            setattr(self, name, getattr(law, name))
        if isinstance(law, Hertz):  # a rigid wall: only the sphere's compliance
            self.young_eff = 2.0 * law.young_eff
            self.shear_eff = 2.0 * law.shear_eff

    @property
    def steady(self):
        """Does the wall's geometry stay as it is (a plane at rest or sliding in itself)? Walls that are
        not steady carry a geometry block (:meth:`geometry_values`) that the compiled loops read the
        motion (at the scene's clock) or the servo's state from."""
        return not self.travels and self.servo is None

    @property
    def travels(self):
        """Does the wall's geometry move with time (a piston, a vibrated plate): where it stands depends on
        the scene's clock (a servo's wall moves with its scene's state instead)."""
        along = float(self.velocity @ self.normal)
        return bool(self.amplitude.any()) or abs(along) > 1e-12 * max(1.0, float(np.linalg.norm(self.velocity)))

    @property
    def flat(self):
        """A plane standing still along its normal: the fall-height bound, VelocityVerlet(resolve_contacts=True)'s
        contact events and the accuracy reference treat only these (a plane that slides in itself is one)."""
        return self.steady

    def motion_values(self):
        """The motion's part of the geometry block: velocity, amplitude, angular frequency 2 pi f."""
        return np.array([*self.velocity, *self.amplitude, 2.0 * math.pi * self.frequency], dtype=np.float64)

    def geometry_values(self):
        """The geometry block of a moving plane (shape 0, then :meth:`motion_values`; with a servo shape 2,
        then :meth:`Servo.values`); empty for a steady one (its plane is its parameters)."""
        if self.steady:
            return np.zeros(0)
        if self.servo is not None:
            return np.array([2.0, *self.motion_values(), *self.servo.values()], dtype=np.float64)
        return np.array([self.shape, *self.motion_values()], dtype=np.float64)

    def displacement(self, time):
        """(D, D'): how far the wall has moved from where it stood at time 0, and its velocity, at ``time``
        (a servo's: where its scene's last step has taken it, see :meth:`servo_state`)."""
        w = 2.0 * math.pi * self.frequency
        shift = self.velocity * time + self.amplitude * (1.0 - math.cos(w * time))
        speed = self.velocity + self.amplitude * (w * math.sin(w * time))
        if self.servo is not None and self.shape == 0:  # (its quasi-static steps add no surface velocity)
            shift = shift + self.servo_state()[0] * self.normal
        return shift, speed

    def servo_state(self):
        """(offset, speed, force, stiffness) of a servo-controlled wall in the scene it was last built into:
        how far it has moved along its normal from ``point``, its speed along it in the last step, the
        normal force the spheres exerted on it and the sum of its contacts' secant stiffnesses in the
        last force evaluation of a step (zeros before the first run)."""
        if self.servo is None:
            raise ValueError(f"{self!r} has no servo")
        block = getattr(self, "block", None)
        if block is None:
            return 0.0, 0.0, 0.0, 0.0
        start = SERVO_STATE + self.servo_after
        return tuple(float(v) for v in block[start:start + 4])

    def table_values(self):
        """A twisting law's rolling and twisting numbers, or a rolling law's against a turning wall, with
        the wall's spin (see :data:`TABLE`), else empty."""
        table = getattr(self, "table", np.zeros(0))
        if not np.size(table):
            return table
        twist = 1.0 if getattr(self.law, "twisting", None) is not None else 0.0
        return np.concatenate([table, [twist], self.spin()])

    def spin(self):
        """The wall's own angular velocity (a plane's: none)."""
        return np.zeros(3)

    def heights(self, position, time=0.0):
        """Signed distance of each centre from the plane at ``time`` (positive on the spheres' side)."""
        return (np.asarray(position) - self.point - self.displacement(time)[0]) @ self.normal

    def check(self, particles, time=0.0):
        """No sphere behind or deep inside the wall where it stands at ``time`` (the scene's clock)."""
        super().check(particles)
        if not hasattr(self, "law"):
            raise ValueError("Wall has no contact law yet: add it to a Scene with one, or pass contact=...")
        overlap = (particles.radius - self.heights(particles.position, time)) / particles.radius
        k = int(np.argmax(overlap))
        if overlap[k] > MAX_INITIAL_OVERLAP:
            raise ValueError(f"particle {particles.ids[k]} at {particles.position[k].tolist()} starts "
                             f"{'behind' if overlap[k] > 1 else 'deep inside'} {self.where()} (overlap "
                             f"{overlap[k]:.3g} of its radius; at most {MAX_INITIAL_OVERLAP} is accepted at the start)")

    def check_box(self, box):
        """A plane wall must not cut a periodic axis: its normal has no component along one (a sphere's
        periodic copy would sit behind the wall; LAMMPS refuses a wall in a periodic dimension too)."""
        for k in np.flatnonzero(box.periodic):
            if abs(float(self.normal[k])) > 1e-12:
                raise ValueError(f"{self!r} cuts the box's periodic axis {'xyz'[k]}: a wall's normal must have no "
                                 f"component along a periodic axis (make the box open along {'xyz'[k]})")

    def where(self):
        """The wall in words, for messages."""
        return f"the wall through {self.point.tolist()} with normal {self.normal.tolist()}"

    def normals(self, position, time=0.0):
        """The unit normal where each sphere touches the wall, into the spheres' side (N, 3)."""
        return np.tile(self.normal, (len(np.atleast_2d(position)), 1))

    def parameters_at(self, position, time=0.0, radius=None):
        """The parameter values the wall's compiled functions take for spheres centred at ``position`` at
        ``time``, (N, P): a plane wall's own wherever the spheres are, its plane and surface velocity
        where its motion has taken it (as demkit.interactions.wall_motion.wall_plane)."""
        values = np.tile(self.parameter_values(), (len(np.atleast_2d(position)), 1))
        if not self.steady:
            shift, speed = self.displacement(time)
            values[:, 0] += float(shift @ self.normal)
            values[:, 4:7] = speed
        return values

    def surface_speed(self):
        """The fastest the wall's surface moves: |V| + 2 pi f |A| (+ a servo's max_speed)."""
        servo = self.servo.max_speed if self.servo is not None else 0.0
        return (float(np.linalg.norm(self.velocity)) + 2.0 * math.pi * self.frequency * float(np.linalg.norm(self.amplitude))
                + servo)

    def max_time_step(self, particles):
        return self.law.max_time_step(particles)

    def motion_repr(self):
        """The motion's arguments for repr, those that are set."""
        text = f", velocity={self.velocity.tolist()}" if self.velocity.any() else ""
        if self.frequency > 0.0:
            text += f", amplitude={self.amplitude.tolist()}, frequency={self.frequency!r}"
        if getattr(self, "servo", None) is not None:
            text += f", servo={self.servo!r}"
        return text

    def __repr__(self):
        return f"Wall(point={self.point.tolist()}, normal={self.normal.tolist()}{self.motion_repr()})"
