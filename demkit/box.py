"""The simulation box: a rectangular cell with its lower corner at the origin.

Each axis is periodic or open. Along a periodic axis of length L, positions are kept in [0, L)
(wrapped at neighbour-list rebuilds and in recorded frames) with an integer image count, so the
unwrapped position is ``position + image * size``; pair separations use the minimum image
d - L round(d / L). Along an open axis the box only states where the spheres start (a sphere
outside it is an error before the run) and frames pictures: spheres may leave it, as in open space
(walls are separate interactions). No box at all (``box=None``) is open space in every direction.

A periodic box may be sheared (:class:`Shear`, Lees-Edwards sliding images): the images one period
up the gradient axis b slide along the flow axis a by the offset delta(t) = gammadot L_b t (mod L_a)
and move at gammadot L_b along a relative to the box.

A periodic box may deform (:class:`Deform`): each deforming axis has the length L_a(t) = L_a0 (1 + rate_a t)
at the scene's time t, the positions remapped affinely with it after every step.
"""
from __future__ import annotations

import math

import numpy as np

from .checks import real_array


AXES = "xyz"


class Shear:
    """Simple shear of a periodic box by Lees-Edwards sliding images.

    rate : the shear rate gammadot (1/s; any finite number, 0 included), the imposed flow being
        u_a = gammadot * x_b (velocity along ``flow`` growing along ``gradient``);
    flow, gradient : the axes a and b ("x", "y" or "z"; different), both periodic in the box.

    The image of sphere j one period up b (x_j + L_b e_b) sits at x_j + L_b e_b + delta(t) e_a, with
    delta(t) = gammadot L_b t mod L_a (from the scene's clock, not accumulated), and moves at
    v_j + gammadot L_b e_a. A sphere crossing b is wrapped with its position along a shifted by
    -+delta and its velocity along a by -+gammadot L_b.
    """

    def __init__(self, rate, flow="x", gradient="y"):
        if isinstance(rate, bool) or not isinstance(rate, (int, float, np.integer, np.floating)):
            raise ValueError(f"Shear rate must be a number (1/s), got {rate!r}")
        if not math.isfinite(float(rate)):
            raise ValueError(f"Shear rate must be finite, got {rate!r}")
        for name, axis in (("flow", flow), ("gradient", gradient)):
            if not isinstance(axis, str) or len(axis) != 1 or axis not in AXES:
                raise ValueError(f"Shear {name} axis must be 'x', 'y' or 'z', got {axis!r}")
        if flow == gradient:
            raise ValueError(f"Shear flow and gradient axes must differ, got both {flow!r}")
        self.rate, self.flow, self.gradient = float(rate), flow, gradient

    @property
    def axes(self):
        """(a, b): the indices of the flow and gradient axes."""
        return AXES.index(self.flow), AXES.index(self.gradient)

    def jump(self, size):
        """gammadot L_b: the velocity of the images one period up the gradient, along the flow."""
        return self.rate * float(size[self.axes[1]])

    def offset(self, size, time):
        """delta(t) = gammadot L_b t mod L_a, in [0, L_a) (the same arithmetic as the compiled loops)."""
        a, _ = self.axes
        d = self.jump(size) * float(time)
        return d - float(size[a]) * math.floor(d / float(size[a]))

    def __eq__(self, other):
        return (isinstance(other, Shear) and self.rate == other.rate and self.flow == other.flow
                and self.gradient == other.gradient)

    def __repr__(self):
        return f"Shear({self.rate!r}, flow={self.flow!r}, gradient={self.gradient!r})"


class Deform:
    """Homogeneous extension or compression of a periodic box at set engineering strain rates.

    x, y, z : the strain rate of each axis (1/s; 0 leaves the axis alone): L_a(t) = L_a0 (1 + rate_a t),
        L_a0 the box's ``size``, t the scene's time (as LAMMPS' ``fix deform ... erate``).

    After every step the box takes its lengths at the clock and the positions are remapped affinely,
    x_a -> x_a L_a(t) / L_a(t - dt) (LAMMPS' ``remap x``, Yade's homothetic cell): the spheres' velocities
    are those relative to the affine flow u_a = (rate_a / (1 + rate_a t)) x_a, which the kinetic stress,
    a bath's drag and the dashpots read. The box must stay longer than twice the longest reach: a run
    that would shrink it further is refused before it starts.

    servo : a :class:`demkit.PressureServo` that sets the rates of its axes from the measured stress
        (those axes' rates here are where it starts). The box then keeps the history of the rates it
        set (:attr:`history`): L_a(t) = L_a(t_k) (1 + r_a,k (t - t_k)) after the k-th change, at t_k.
    """

    def __init__(self, x=0.0, y=0.0, z=0.0, servo=None):
        rates = []
        for axis, rate in zip(AXES, (x, y, z)):
            if isinstance(rate, bool) or not isinstance(rate, (int, float, np.integer, np.floating)):
                raise ValueError(f"Deform rate {axis} must be a number (1/s), got {rate!r}")
            if not math.isfinite(float(rate)):
                raise ValueError(f"Deform rate {axis} must be finite, got {rate!r}")
            rates.append(float(rate))
        if servo is not None and not all(hasattr(servo, name) for name in ("update", "axes", "every")):
            raise ValueError(f"Deform servo must be a demkit.PressureServo or None, got {type(servo).__name__}")
        if not any(rates) and servo is None:
            raise ValueError("Deform needs a non-zero strain rate along at least one axis (x=, y=, z=, 1/s) or a servo")
        self.rates = np.array(rates)
        self.rates.setflags(write=False)
        self.servo = servo
        #: the rates a servo set: rows (t_k, L_x, L_y, L_z at t_k, r_x, r_y, r_z), in time order
        self.history = np.zeros((0, 7))

    @classmethod
    def recorded(cls, rates, history):
        """The deformation a run recorded (a VTK series', a saved trajectory's): its starting rates and the
        changes a servo made (:attr:`history`), without the servo."""
        deform = cls.__new__(cls)
        deform.rates, deform.servo = np.array(rates, dtype=np.float64), None
        deform.rates.setflags(write=False)
        deform.history = np.array(history, dtype=np.float64).reshape(-1, 7)
        return deform

    @property
    def axes(self):
        """The indices of the deforming axes (those a servo drives, or drove, too)."""
        driven = getattr(self, "servo", None).axes if getattr(self, "servo", None) is not None else ()
        history = getattr(self, "history", np.zeros((0, 7)))
        return [a for a in range(3) if self.rates[a] != 0.0 or a in driven or np.any(history[:, 4 + a] != 0.0)]

    def _segment(self, size, time):
        """(t0, the lengths at t0, the rates from t0) of the stretch holding each time: from the box's
        ``size`` at t0 = 0, or from the last change of rates at or before it (:attr:`history`)."""
        history = getattr(self, "history", np.zeros((0, 7)))
        rows = np.concatenate([[[0.0, *size, *self.rates]], history])
        k = np.searchsorted(rows[:, 0], time, side="right") - 1
        return rows[k, 0], rows[k, 1:4], rows[k, 4:7]

    def size_at(self, size, time):
        """L_a0 (1 + rate_a (t - t0)) for each axis (the bits the compiled loops give), from the box's
        ``size`` at t0 = 0 or from the last change of rates before t (:attr:`history`); ``time`` may be
        an array (shape T: sizes T x 3)."""
        time = np.asarray(time, dtype=np.float64)
        size = np.asarray(size, dtype=np.float64)
        start, lengths, rates = self._segment(size, time)
        out = np.broadcast_to(size, time.shape + (3,)).copy()
        for a in self.axes:
            out[..., a] = lengths[..., a] * (1.0 + rates[..., a] * (time - start))
        return out

    def strain_rate(self, size, time):
        """Ldot_a / L_a = rate_a / (1 + rate_a (t - t0)) for each axis at ``time`` (0 along the others),
        the rate of the stretch holding it (:meth:`size_at`); an array of times gives T x 3."""
        time = np.asarray(time, dtype=np.float64)
        start, _, rates = self._segment(np.asarray(size, dtype=np.float64), time)
        return rates / (1.0 + rates * (time - start)[..., None])

    def change(self, time, lengths, rates):
        """Record a servo's change of rates at ``time``, from the box's ``lengths`` then."""
        if len(self.history) and time < self.history[-1, 0]:
            raise ValueError(f"a deforming box's rates change at t = {time}, before their last change at "
                             f"t = {self.history[-1, 0]}: give each scene its own box")
        self.history = np.vstack([self.history, [[float(time), *lengths, *rates]]])

    def __eq__(self, other):
        return (isinstance(other, Deform) and np.array_equal(self.rates, other.rates)
                and getattr(self, "servo", None) == getattr(other, "servo", None))

    def __repr__(self):
        servo = getattr(self, "servo", None)
        return ("Deform(" + ", ".join([f"{AXES[a]}={float(self.rates[a])!r}" for a in range(3) if self.rates[a]]
                                     + ([f"servo={servo!r}"] if servo is not None else [])) + ")")


class Box:
    """Rectangular box [0, Lx) x [0, Ly) x [0, Lz).

    size : three positive lengths (or one, for a cube).
    periodic : True/False for all axes, or three booleans (x, y, z).
    shear : a :class:`Shear` (Lees-Edwards simple shear; its flow and gradient axes periodic), or None.
    deform : a :class:`Deform` (extension or compression at set strain rates; its axes periodic), or None.
        ``size`` is then the box at time 0 (:meth:`size_at` gives it at any time).
    """

    shear = None  # (boxes pickled before shear existed)
    deform = None  # (... and before deformation)

    def __init__(self, size, periodic=False, shear=None, deform=None):
        arr = real_array("Box size", size)
        if arr.ndim == 0:
            arr = np.full(3, float(arr))
        if arr.shape != (3,):
            raise ValueError(f"Box size must be one length or three lengths (x, y, z), got {size!r}")
        if not np.all(np.isfinite(arr)) or np.any(arr <= 0):
            raise ValueError(f"Box size must be three positive finite lengths, got {arr.tolist()}")
        flags = np.array(periodic, dtype=object)
        if flags.ndim == 0:
            flags = np.array([periodic] * 3, dtype=object)
        if flags.shape != (3,) or not all(isinstance(f, (bool, np.bool_)) for f in flags):
            raise ValueError(f"Box periodic must be a bool or three bools (x, y, z), got {periodic!r}")
        self.size = arr
        self.size.setflags(write=False)
        self.periodic = np.array([bool(f) for f in flags])
        self.periodic.setflags(write=False)
        if shear is not None:
            if not isinstance(shear, Shear):
                raise ValueError(f"Box shear must be a demkit.Shear or None, got {type(shear).__name__}")
            for name, axis in (("flow", shear.flow), ("gradient", shear.gradient)):
                if not self.periodic[AXES.index(axis)]:
                    raise ValueError(f"Box shear: the {name} axis {axis} must be periodic (Lees-Edwards images "
                                     f"slide along a periodic box), got periodic={self.periodic.tolist()}")
        self.shear = shear
        if deform is not None:
            if not isinstance(deform, Deform):
                raise ValueError(f"Box deform must be a demkit.Deform or None, got {type(deform).__name__}")
            for a in deform.axes:
                if not self.periodic[a]:
                    raise ValueError(f"Box deform: the axis {AXES[a]} deforms but is not periodic (the box remaps "
                                     f"periodic coordinates), got periodic={self.periodic.tolist()}")
            if shear is not None:
                raise ValueError("Box: shear and deform together are not done yet (the sliding images would need the "
                                 "gradient axis's changing length); choose one")
        self.deform = deform

    def size_at(self, time):
        """The box's lengths at ``time`` (its ``size`` unless it deforms; an array of times gives T x 3)."""
        deform = getattr(self, "deform", None)
        if deform is not None and time is None:
            raise ValueError("the lengths of a deforming box need the time: size_at(time)")
        if deform is None:
            return np.broadcast_to(self.size, np.shape(time) + (3,)).copy() if np.ndim(time) else self.size.copy()
        return deform.size_at(self.size, time)

    def volume_at(self, time):
        """The box's volume at ``time`` (``volume`` unless it deforms)."""
        return float(np.prod(self.size_at(float(time))))

    @property
    def any_periodic(self):
        return bool(self.periodic.any())

    @property
    def volume(self):
        return float(np.prod(self.size))

    def wrap(self, position):
        """(wrapped positions, image shifts): periodic coordinates brought into [0, L)."""
        position = np.asarray(position, dtype=np.float64)
        shift = np.zeros(position.shape, dtype=np.int64)
        wrapped = position.copy()
        for a in np.flatnonzero(self.periodic):
            k = np.floor(position[..., a] / self.size[a])
            wrapped[..., a] = position[..., a] - k * self.size[a]
            # round-off can leave exactly L: put it at 0 of the next image
            edge = wrapped[..., a] >= self.size[a]
            wrapped[..., a][edge] -= self.size[a]
            shift[..., a] = k.astype(np.int64) + edge
        return wrapped, shift

    def continued(self, position, velocity, image, time):
        """(positions, velocities) continued across the periodic boundaries, as if never wrapped:
        position + image * size, and in a sheared box + image_b gammadot L_b t along the flow (the sliding
        images' offset, not wrapped) and velocity + image_b gammadot L_b (a sphere crossing the gradient
        axis takes its image's velocity). In a deforming box, position + image * L(t), and the velocity
        with the affine flow (Ldot_a / L_a) x_a added (:meth:`Deform.strain_rate`: the path's own rate of
        change, a servo's rates too).
        ``time`` broadcasts against ``position[..., 0]``; the velocities are those given when the box
        neither shears nor deforms."""
        deform = getattr(self, "deform", None)
        if deform is not None:  # the box's lengths at each time, the velocities with the affine flow
            t = np.asarray(time, dtype=np.float64)
            position = position + image * self.size_at(t)
            return position, velocity + deform.strain_rate(self.size, t) * position
        position = position + image * self.size
        shear = getattr(self, "shear", None)
        if shear is None:
            return position, velocity
        a, b = shear.axes
        jump = shear.jump(self.size)
        position[..., a] += image[..., b] * jump * np.asarray(time)
        velocity = velocity.copy()
        velocity[..., a] += image[..., b] * jump
        return position, velocity

    def minimum_image(self, separation, time=None):
        """Separations (..., 3) reduced to their nearest periodic image (in a sheared box, the
        Lees-Edwards image at ``time``, which it needs: along the gradient first, then the flow shifted
        by k delta)."""
        d = np.array(separation, dtype=np.float64)
        size = self.size
        if getattr(self, "deform", None) is not None:
            if time is None:
                raise ValueError("separations in a deforming box need the time (minimum_image(d, time)): its "
                                 "lengths change")
            size = self.size_at(float(time))
        if self.shear is not None:
            if time is None:
                raise ValueError("separations in a sheared box need the time (minimum_image(d, time)): its "
                                 "images slide along the flow")
            a, b = self.shear.axes
            k = -np.round(d[..., b] / self.size[b])
            d[..., b] += k * self.size[b]
            d[..., a] += k * self.shear.offset(self.size, time)
        for a in np.flatnonzero(self.periodic):
            d[..., a] -= size[a] * np.round(d[..., a] / size[a])
        return d

    def outside(self, position):
        """Indices of positions outside the box along an open (non-periodic) axis."""
        position = np.asarray(position, dtype=np.float64)
        bad = np.zeros(len(position), dtype=bool)
        for a in np.flatnonzero(~self.periodic):
            bad |= (position[:, a] < 0.0) | (position[:, a] > self.size[a])
        return np.flatnonzero(bad)

    def check_reach(self, reach, what):
        """Raise ValueError if a periodic side is not longer than twice ``reach`` (the minimum
        image would miss interactions)."""
        if not math.isfinite(reach):
            if self.any_periodic:
                raise ValueError(f"{what} has no cutoff, which a periodic box cannot hold (the sum over "
                                 f"images is not done): give it a cutoff shorter than half the box")
            return
        for a in np.flatnonzero(self.periodic):
            if self.size[a] <= 2.0 * reach:
                raise ValueError(
                    f"the periodic box side {'xyz'[a]} = {self.size[a]:.6g} is not longer than twice the reach "
                    f"{reach:.6g} of {what}: the minimum image would miss interactions; make the box longer "
                    f"than {2 * reach:.6g} or the reach shorter")

    def __eq__(self, other):
        return (isinstance(other, Box) and np.array_equal(self.size, other.size)
                and np.array_equal(self.periodic, other.periodic) and self.shear == other.shear
                and getattr(self, "deform", None) == getattr(other, "deform", None))

    def __repr__(self):
        flags = self.periodic.tolist()
        periodic = flags[0] if len(set(flags)) == 1 else tuple(flags)
        shear = f", shear={self.shear!r}" if self.shear is not None else ""
        shear += f", deform={self.deform!r}" if getattr(self, "deform", None) is not None else ""
        return f"Box(size={tuple(self.size.tolist())}, periodic={periodic}{shear})"
