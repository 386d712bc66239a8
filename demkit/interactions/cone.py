"""Conical walls: hoppers, funnels and conical posts, with the scene's contact law.

A cone with its apex at ``apex`` opens along the unit ``axis`` a with half-angle alpha (0 < alpha < pi/2):
its surface is the set of points apex + s (cos(alpha) a + sin(alpha) e), e any unit vector across the
axis, for generator lengths s from s0 = lower / cos(alpha) to s1 = upper / cos(alpha) (``lower`` and
``upper`` measured along the axis from the apex; upper None: unbounded). The spheres are inside it
(``inside=True``: a hopper or funnel) or outside it (a conical post or a spreader).

Contact is at the nearest point of the surface to the sphere's centre x. In the meridian half-plane
of x (its height h = r.a along the axis and distance d from it, r = x - apex, radial unit e) the
generator is the ray s g, g = cos(alpha) a + sin(alpha) e, and its nearest point to x is at

    s = t = h cos(alpha) + d sin(alpha);

points of other half-planes are farther (for a given s the nearest point of the circle of radius
s sin(alpha) lies in x's half-plane). For s0 <= t <= s1 the nearest point is on the face: the cone
looks to the sphere like its tangent plane there, which contains the generator (it passes through the
apex), with normal n = sin(alpha) a - cos(alpha) e into the cone (inside) or its opposite (outside);
the signed height of the centre is h sin(alpha) - d cos(alpha) inside, its opposite outside, and the
contact is exactly that plane wall's (:mod:`demkit.interactions.wall`). For t beyond s0 or s1 the
nearest point Q is the end of the generator: the rim circle there (an open hopper's outlet or top
edge: a sphere is pushed off a sharp edge, with normal (x - Q)/|x - Q| and overlap R - |x - Q|), or
the apex itself when s0 = 0 (a vertex contact: spheres outside a cone, behind its tip). Beyond the
rims there is no surface: no contact once the rim is out of reach.

Near the axis inside a cone a sphere touches a whole ring: a centre on the axis is equally near every
point of the circle at t = h cos(alpha), and for d < delta cos(alpha) (delta the overlap) the sphere
is wider than the cone's circle where it touches (the cone's circumferential radius of curvature there
is r / cos(alpha), r the contact point's distance from the axis: the sphere sits beyond the conformal
limit R = r / cos(alpha), as a sphere wider than a tube). A point-contact law has no ring contact:
demkit keeps the single contact at the nearest point (a centre exactly on the axis takes one
direction across it, as :class:`demkit.Cylinder`), as LAMMPS' ``region cone`` does. A sphere settling
in a hopper therefore comes to the axis carried by one contact's axial part, F(delta) sin(alpha) = m g
(its height h = (R - delta) / sin(alpha)), crossing the axis back and forth by about g dt^2 / tan(alpha)
a step; a real ring contact would carry it with less overlap.

The cone may turn about its own axis at ``angular_velocity`` omega: its surface moves at
u = omega a x (S - apex) = omega s sin(alpha) (a x e) where the sphere touches it, and, like a plane
wall, it may be carried by a translation D(t) = V t + A (1 - cos 2 pi f t) (``velocity``, ``amplitude``,
``frequency``). The compiled loops find its tangent plane with
demkit.interactions.wall_motion.wall_plane (shape code 3). A Hertz law takes the contact radius of the
face's curvature across, 1/R_e = 1/R - side cos(alpha) / (2 r) (r the contact point's distance from the
axis; on a rim or the apex the sphere's own: demkit.interactions.wall_motion.contact_radius_factor).
"""
from __future__ import annotations

import math

import numpy as np

from .hertz import Hertz
from .sphere import vector
from .wall import Wall
from .wall_motion import SHAPES, cone_curvature, cone_plane, contact_radius_factor

#: the cone's numbers in its geometry block, in this order (after the shape code and the motion:
#: demkit.interactions.wall_motion): apex, unit axis, sin and cos of the half-angle, the generator's
#: lengths where the surface starts and ends, side (+1 inside, -1 outside), angular velocity
GEOMETRY = ("px", "py", "pz", "ax", "ay", "az", "sin", "cos", "s0", "s1", "side", "omega")


class Cone(Wall):
    """A conical wall (see the module docstring): a hopper, a funnel or a conical post.

    apex : the cone's tip (length vector); axis : the direction it opens along (any length > 0);
    half_angle : alpha in radians, 0 < alpha < pi/2, between the axis and the surface;
    inside : the spheres are inside (a hopper; default) or outside (a post);
    lower, upper : where the surface starts and ends, as distances from the apex along the axis
    (0 <= lower < upper; default 0 and None, unbounded: an open hopper's outlet is lower > 0);
    angular_velocity : the cone's rate of turning about its axis (right-handed; default 0);
    velocity, amplitude, frequency : a translation V t + A (1 - cos 2 pi f t) of the whole cone (default
    none); contact : the contact law (:class:`KelvinVoigt` or :class:`Hertz`), default the scene's own.
    """

    steady = False  # the compiled loops read its geometry block (so not flat: see Wall.flat)
    shape = SHAPES["cone"]

    def __init__(self, apex, axis, half_angle, inside=True, lower=0.0, upper=None, angular_velocity=0.0,
                 contact=None, velocity=(0.0, 0.0, 0.0), amplitude=(0.0, 0.0, 0.0), frequency=0.0):
        apex = vector("Cone apex", apex)
        axis = vector("Cone axis", axis)
        if float(np.linalg.norm(axis)) == 0.0:
            raise ValueError("Cone axis has zero length")
        alpha = float(half_angle)
        if not 0.0 < alpha < 0.5 * math.pi:
            raise ValueError(f"Cone half_angle must lie strictly between 0 and pi/2 (radians), got {half_angle!r}")
        if inside not in (True, False):
            raise ValueError(f"Cone inside must be True or False, got {inside!r}")
        lower = float(lower)
        top = math.inf if upper is None else float(upper)
        if not (math.isfinite(lower) and lower >= 0.0) or not (lower < top) or math.isnan(top) or top == -math.inf:
            raise ValueError(f"Cone needs 0 <= lower < upper (distances from the apex along the axis; upper None: "
                             f"unbounded), got lower={lower!r}, upper={upper!r}")
        omega = float(angular_velocity)
        if not math.isfinite(omega):
            raise ValueError(f"Cone angular_velocity must be finite, got {angular_velocity!r}")
        self.angular_velocity = omega  # (before the contact law is adopted: a turning wall's functions)
        super().__init__(apex, axis, velocity=velocity, contact=contact, amplitude=amplitude, frequency=frequency)
        self.apex, self.axis = self.point, self.normal
        self.half_angle, self.inside, self.angular_velocity = alpha, bool(inside), omega
        self.lower, self.upper = lower, None if upper is None else top

    @property
    def travels(self):
        """Is the cone carried by a translation (where it stands depends on the scene's clock)?"""
        return bool(self.velocity.any() or self.amplitude.any())

    def shape_values(self):
        """The cone's numbers (:data:`GEOMETRY`) at time 0."""
        sn, cs = math.sin(self.half_angle), math.cos(self.half_angle)
        top = math.inf if self.upper is None else self.upper / cs
        return np.array([*self.apex, *self.axis, sn, cs, self.lower / cs, top, 1.0 if self.inside else -1.0,
                         self.angular_velocity], dtype=np.float64)

    def geometry_values(self):
        """The geometry block: shape code, motion, :meth:`shape_values` (demkit.interactions.wall_motion)."""
        hertz = 1.0 if isinstance(getattr(self, "law", None), Hertz) else 0.0
        return np.array([self.shape, *self.motion_values(), *self.shape_values(), hertz], dtype=np.float64)

    def planes(self, position, time=0.0):
        """The plane each centre meets at ``time`` and the surface's velocity there, (N, 7): plane, n, u
        (as demkit.interactions.wall_motion.wall_plane)."""
        shift, speed = self.displacement(time)
        values = self.shape_values()
        rows = np.array([cone_plane(*x, *values) for x in np.atleast_2d(np.asarray(position, dtype=float)) - shift],
                        dtype=np.float64).reshape(-1, 7)
        rows[:, 0] += rows[:, 1:4] @ shift
        rows[:, 4:7] += speed
        return rows

    def heights(self, position, time=0.0):
        """Signed distance of each centre from the surface at ``time`` (positive on the spheres' side; an
        edge or the apex: the distance from it), the shape of ``position`` without its last axis."""
        x = np.asarray(position, dtype=float)
        rows = self.planes(x.reshape(-1, 3), time)
        return (np.einsum("ij,ij->i", x.reshape(-1, 3), rows[:, 1:4]) - rows[:, 0]).reshape(x.shape[:-1])

    def normals(self, position, time=0.0):
        """The unit normal where each sphere touches the cone, into the spheres' side (N, 3)."""
        return self.planes(position, time)[:, 1:4]

    def parameters_at(self, position, time=0.0, radius=None):
        """The parameter values for spheres centred at ``position`` (of ``radius``) at ``time`` (N, P): the
        plane each meets and the surface's velocity there in place of a plane wall's seven geometry values;
        a Hertz law's E*, G* scaled to the contact radius of the face's curvature (as the kernels)."""
        x = np.atleast_2d(np.asarray(position, dtype=float))
        values = np.tile(self.parameter_values(), (len(x), 1))
        values[:, :7] = self.planes(x, time)
        if isinstance(self.law, Hertz):
            shape = self.shape_values()
            shift = self.displacement(time)[0]
            factor = np.array([contact_radius_factor(r, cone_curvature(*(c - shift), *shape[:-1]))
                               for c, r in zip(x, np.broadcast_to(radius, len(x)))])
            values[:, 7:9] *= factor[:, None]
        return values

    def rim_radius(self):
        """The largest distance of the surface from the axis (inf for an unbounded cone)."""
        return math.inf if self.upper is None else self.upper * math.tan(self.half_angle)

    def surface_speed(self):
        """The fastest the surface moves: |omega| times the rim's radius + |V| + 2 pi f |A| (an unbounded
        turning cone: the widest the spheres reach is not known here; the guards take its rim radius as
        inf only when it turns)."""
        turning = abs(self.angular_velocity) * self.rim_radius() if self.angular_velocity != 0.0 else 0.0
        return turning + super().surface_speed()

    def spin(self):
        """The wall's own angular velocity, omega a (rolling and twisting resistance act on the sphere's
        spin relative to it)."""
        return self.angular_velocity * self.axis

    def where(self):
        reach = f"{self.lower:.6g} to {'inf' if self.upper is None else f'{self.upper:.6g}'}"
        return (f"the cone with apex {self.apex.tolist()} along {self.axis.tolist()}, half-angle "
                f"{self.half_angle:.6g} rad, from {reach} along its axis ({'inside' if self.inside else 'outside'})")

    def check(self, particles, time=0.0):
        super().check(particles, time)
        if self.angular_velocity != 0.0 and self.upper is None:
            raise ValueError(f"{self!r} turns and has no upper end: its surface would move ever faster away from "
                             f"the apex; give it upper=... (the guards bound the time step by its fastest point)")

    def extent(self, k):
        """(lo, hi): the reach of the surface along the coordinate axis k (at time 0)."""
        a = float(self.axis[k])
        across = math.sqrt(max(0.0, 1.0 - a * a))
        sn, cs = math.sin(self.half_angle), math.cos(self.half_angle)
        ends = [self.lower / cs, math.inf if self.upper is None else self.upper / cs]
        reach = [s * (cs * a + sign * sn * across) for s in ends for sign in (-1.0, 1.0) if math.isfinite(s)]
        if not math.isfinite(ends[1]):
            reach += [math.inf if cs * a + sign * sn * across > 0 else -math.inf if cs * a + sign * sn * across < 0
                      else 0.0 for sign in (-1.0, 1.0)]
        return self.apex[k] + min(reach), self.apex[k] + max(reach)

    def check_box(self, box):
        """A cone is not periodic along any axis: along a periodic axis of the box it must lie inside the
        box (bounded by ``upper``, inside, not moving along it), else a sphere's periodic copy would be on
        the wrong side of the wall."""
        for k in np.flatnonzero(box.periodic):
            lo, hi = self.extent(k)
            if not (self.inside and 0.0 <= lo and hi <= box.size[k] and self.velocity[k] == 0.0
                    and self.amplitude[k] == 0.0):
                raise ValueError(f"{self!r} crosses the box's periodic axis {'xyz'[k]} (size {box.size[k]:.6g}): a "
                                 f"cone in a periodic box must, inside, lie within the box along each periodic axis "
                                 f"(give it an upper end) and not move along it")

    def __repr__(self):
        bounds = (f", lower={self.lower!r}" if self.lower else "") + (
            f", upper={self.upper!r}" if self.upper is not None else "")
        return (f"Cone(apex={self.apex.tolist()}, axis={self.axis.tolist()}, half_angle={self.half_angle!r}, "
                f"inside={self.inside}{bounds}, angular_velocity={self.angular_velocity!r}{self.motion_repr()})")
