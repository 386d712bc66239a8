"""Cylindrical walls: tubes, silos and rotating drums, with the scene's contact law.

A cylinder of radius R_c about the axis through ``point`` along the unit ``axis`` a bounds the spheres
inside it (``inside=True``: a tube or drum) or outside it (a post). A sphere at x touches it where the
radial direction e = (r - (r.a) a) / |r - (r.a) a|, r = x - point, meets the surface, S = point + (r.a) a
+ R_c e. There the cylinder looks to the sphere like the plane through S with normal n = -e (inside) or
+e (outside), and the contact is exactly that plane wall's (:mod:`demkit.interactions.wall`): overlap
delta = R - (x - S).n = R - (R_c - d) inside, R - (d - R_c) outside (d the centre's distance from the
axis), the same normal and tangential laws, friction history per sphere (turned into the new tangent
plane as the sphere moves round), rolling and twisting resistance. A Hertz law takes the contact
radius of the wall's curvature across, 1/R_e = 1/R -+ 1/(2 R_c) (-: inside), as LAMMPS' region walls
(demkit.interactions.wall_motion.contact_radius_factor; a plane's R would be off by about R / (4 R_c)).

The cylinder may turn about its own axis at ``angular_velocity`` omega (rad per unit time, right-handed
about a): its surface then moves at u = omega a x (S - point) = omega R_c (a x e), its geometry does not
change, so a rotating drum is a cylinder with omega != 0. Like a plane wall it may also be carried by
a translation D(t) = V t + A (1 - cos 2 pi f t) (``velocity``, ``amplitude``, ``frequency``; a shaken tube):
the compiled loops find its tangent plane with demkit.interactions.wall_motion.wall_plane. It is
infinitely long: close it with plane walls (:class:`demkit.Wall`) for caps.

A :class:`demkit.Servo` holding a ``stress`` moves its radius instead (a confining pressure on a column of
spheres: a triaxial cell's membrane in its simplest form): after every step the radius moves by
gain (F - sigma 2 pi R_c L) / K away from the spheres or towards them, F the normal force they push on
it with, K the sum of its contacts' secant stiffnesses, L the length of the periodic box along the
axis (the cylinder must run along a periodic axis), at most max_speed dt a step (the plane servo's rule,
demkit.interactions.wall_motion.servo_step). :meth:`Cylinder.servo_state` and :meth:`current_radius` read
it between runs.
"""
from __future__ import annotations

import math

import numpy as np

from .hertz import Hertz
from .sphere import vector
from .wall import Servo, Wall
from .wall_motion import SHAPES, contact_radius_factor, cylinder_plane

#: the cylinder's numbers in its geometry block, in this order (after the shape code and the motion:
#: demkit.interactions.wall_motion)
GEOMETRY = ("px", "py", "pz", "ax", "ay", "az", "radius", "side", "omega")


class Cylinder(Wall):
    """A cylindrical wall (see the module docstring): a tube, silo or rotating drum.

    point : a point of the axis; axis : its direction (any length > 0); radius : R_c > 0;
    inside : the spheres are inside (a tube, drum; default) or outside (a post);
    angular_velocity : the cylinder's rate of turning about its axis (right-handed; default 0);
    velocity, amplitude, frequency : a translation V t + A (1 - cos 2 pi f t) of the whole cylinder (default
    none); contact : the contact law (:class:`KelvinVoigt` or :class:`Hertz`), default the scene's own;
    servo : a :class:`Servo` holding a ``stress`` on the cylinder's side by moving its radius (module
    docstring; with neither a translation nor a vibration).
    """

    steady = False  # the compiled loops read its geometry block (so not flat: see Wall.flat)
    shape = SHAPES["cylinder"]

    def __init__(self, point, axis, radius, inside=True, angular_velocity=0.0, contact=None,
                 velocity=(0.0, 0.0, 0.0), amplitude=(0.0, 0.0, 0.0), frequency=0.0, servo=None):
        point = vector("Cylinder point", point)
        axis = vector("Cylinder axis", axis)
        length = float(np.linalg.norm(axis))
        if length == 0.0:
            raise ValueError("Cylinder axis has zero length")
        radius = float(radius)
        if not math.isfinite(radius) or radius <= 0.0:
            raise ValueError(f"Cylinder radius must be positive and finite, got {radius}")
        if inside not in (True, False):
            raise ValueError(f"Cylinder inside must be True or False, got {inside!r}")
        omega = float(angular_velocity)
        if not math.isfinite(omega):
            raise ValueError(f"Cylinder angular_velocity must be finite, got {angular_velocity!r}")
        # the plane wall's attributes: a placeholder plane (the compiled loops read the geometry block)
        self.angular_velocity = omega  # (before the contact law is adopted: a turning wall's functions)
        super().__init__(point, axis, velocity=velocity, contact=contact, amplitude=amplitude, frequency=frequency)
        self.axis = self.normal
        self.radius, self.inside, self.angular_velocity = radius, bool(inside), omega
        if servo is not None:
            if not isinstance(servo, Servo):
                raise TypeError(f"Cylinder servo must be a demkit.Servo, got {servo!r}")
            if servo.stress is None:
                raise ValueError(f"a Cylinder's servo holds a stress on its side (a confining pressure), not a "
                                 f"force: give Servo(stress=..., max_speed=...), got {servo!r}")
            if self.travels:
                raise ValueError("a Cylinder with a servo moves its radius only: it takes no velocity and no "
                                 "vibration")
            self.shape, self.servo_after = SHAPES["servo cylinder"], len(GEOMETRY) + 1  # (+ its Hertz flag)
        self.servo = servo

    @property
    def travels(self):
        """Is the cylinder carried by a translation (where it stands depends on the scene's clock)?"""
        return bool(self.velocity.any() or self.amplitude.any())

    def shape_values(self):
        """The cylinder's numbers (:data:`GEOMETRY`): axis point at time 0, unit axis, radius, side,
        angular velocity."""
        return np.array([*self.point, *self.axis, self.radius, 1.0 if self.inside else -1.0,
                         self.angular_velocity], dtype=np.float64)

    def geometry_values(self):
        """The geometry block: shape code, motion, :meth:`shape_values` (demkit.interactions.wall_motion),
        then a servo's numbers (:meth:`Servo.values`)."""
        servo = self.servo.values() if self.servo is not None else ()
        hertz = 1.0 if isinstance(getattr(self, "law", None), Hertz) else 0.0
        return np.array([self.shape, *self.motion_values(), *self.shape_values(), hertz, *servo], dtype=np.float64)

    def current_radius(self):
        """The radius now: a servo's where its scene's last step has taken it (R_c - side offset), else R_c."""
        if self.servo is None:
            return self.radius
        return self.radius - (1.0 if self.inside else -1.0) * self.servo_state()[0]

    def servo_factor(self, box):
        """What a servo's stress is multiplied by for the force per unit radius it asks of the cylinder in
        ``box``: 2 pi L, L the box's length along the axis (which must be periodic)."""
        axes = np.flatnonzero(np.abs(self.axis) > 1e-12)
        if box is None or len(axes) != 1 or not box.periodic[axes[0]]:
            raise ValueError(f"{self!r} holds a stress on its side: its area 2 pi R_c L needs the length L of a box "
                             f"periodic along its axis, which must lie along x, y or z (got "
                             f"{'no box' if box is None else box!r})")
        return 2.0 * math.pi * float(box.size[axes[0]])

    def distances(self, position, time=0.0):
        """Distance of each centre from the axis at ``time`` (the shape of ``position`` without its last axis)."""
        r = np.asarray(position, dtype=float) - self.point - self.displacement(time)[0]
        return np.linalg.norm(r - (r @ self.axis)[..., None] * self.axis, axis=-1)

    def heights(self, position, time=0.0):
        """Signed distance of each centre from the surface at ``time`` (positive on the spheres' side)."""
        d = self.distances(position, time)
        radius = self.current_radius()
        return radius - d if self.inside else d - radius

    def planes(self, position, time=0.0):
        """The tangent plane each centre meets at ``time`` and the surface's velocity there, (N, 7):
        plane, n, u (as demkit.interactions.wall_motion.wall_plane)."""
        shift, speed = self.displacement(time)
        values = self.shape_values()
        values[6] = self.current_radius()
        rows = np.array([cylinder_plane(*x, *values) for x in np.atleast_2d(np.asarray(position, dtype=float)) - shift],
                        dtype=np.float64).reshape(-1, 7)
        rows[:, 0] += rows[:, 1:4] @ shift
        rows[:, 4:7] += speed
        return rows

    def normals(self, position, time=0.0):
        """The unit normal of the surface where each sphere touches it, into the spheres' side (N, 3)."""
        return self.planes(position, time)[:, 1:4]

    def parameters_at(self, position, time=0.0, radius=None):
        """The parameter values for spheres centred at ``position`` (of ``radius``) at ``time`` (N, P): the
        tangent plane each meets and the surface's velocity there in place of a plane wall's seven geometry
        values; a Hertz law's E*, G* scaled to the contact radius of the curvature across (as the kernels)."""
        values = np.tile(self.parameter_values(), (len(np.atleast_2d(position)), 1))
        values[:, :7] = self.planes(position, time)
        if isinstance(self.law, Hertz):
            curvature = -(1.0 if self.inside else -1.0) / self.current_radius()
            factor = np.array([contact_radius_factor(r, curvature) for r in np.broadcast_to(radius, len(values))])
            values[:, 7:9] *= factor[:, None]
        return values

    def surface_speed(self):
        """The fastest the surface moves: |omega| R_c + |V| + 2 pi f |A|."""
        return abs(self.angular_velocity) * self.radius + super().surface_speed()

    def spin(self):
        """The wall's own angular velocity, omega a (rolling and twisting resistance act on the sphere's
        spin relative to it)."""
        return self.angular_velocity * self.axis

    def where(self):
        return (f"the cylinder of radius {self.radius:.6g} about the axis through {self.point.tolist()} along "
                f"{self.axis.tolist()} ({'inside' if self.inside else 'outside'})")

    def check(self, particles, time=0.0):
        super().check(particles, time)
        if self.inside and particles.radius.max() >= self.current_radius():
            k = int(np.argmax(particles.radius))
            raise ValueError(f"particle {particles.ids[k]} of radius {particles.radius[k]:.6g} does not fit inside the "
                             f"cylinder of radius {self.current_radius():.6g}")

    def check_box(self, box):
        """Along a periodic axis the spheres' images repeat: the cylinder must run along that axis, or lie
        inside the box across it (a tube within the box), else a periodic copy of a sphere would be
        on the wrong side of the wall."""
        for k in np.flatnonzero(box.periodic):
            along = abs(float(self.axis[k])) == 1.0
            fits = (self.inside and 0.0 <= self.point[k] - self.radius and self.point[k] + self.radius <= box.size[k]
                    and self.velocity[k] == 0.0 and self.amplitude[k] == 0.0)
            if not (along or fits):
                raise ValueError(f"{self!r} crosses the box's periodic axis {'xyz'[k]} (size {box.size[k]:.6g}): a "
                                 f"cylinder in a periodic box must run along each periodic axis or, inside, fit "
                                 f"within the box across it and not move along it")

    def __repr__(self):
        return (f"Cylinder(point={self.point.tolist()}, axis={self.axis.tolist()}, radius={self.radius!r}, "
                f"inside={self.inside}, angular_velocity={self.angular_velocity!r}{self.motion_repr()})")

