"""A servo on a periodic box's size: its axes extended or compressed so that their normal stresses reach a
set pressure (``dk.Deform(servo=dk.PressureServo(...))``), as Yade's PeriTriaxController drives its cell.

Every ``every`` time units (on the step grid: a run split in two changes nothing), the pressure tensor P
is measured (:func:`demkit.measure.stress`: kinetic and virial parts over the box's volume now) and each
driven axis a takes the strain rate

    rate_a = max_rate * clip((P_aa - p) / p, -1, 1)

(compressive stress positive: a box above the target pressure grows, one below shrinks; the full
``max_rate`` once the stress is off by the target itself). Until the next change the box deforms at these
rates from its lengths now (:class:`demkit.Deform`, the positions remapped affinely after each step). The
rate the stress responds to is set by the packing's stiffness K: the loop settles without overshoot when
``max_rate / p * K * every`` is well below 1.
"""
from __future__ import annotations

import math

import numpy as np

from .box import AXES
from .deformed import change_rates
from .measure import stress


class PressureServo:
    """Drive the box's ``axes`` ("xyz", "xy", ...) to the normal stress ``pressure`` (> 0; the pressure
    tensor's diagonal, compressive positive, in the scene's units), changing their strain rates every
    ``every`` time units, each at most ``max_rate`` (1/s) in size."""

    def __init__(self, pressure, max_rate, every, axes="xyz"):
        for name, value in (("pressure", pressure), ("max_rate", max_rate), ("every", every)):
            if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)) \
                    or not math.isfinite(float(value)) or float(value) <= 0.0:
                raise ValueError(f"PressureServo {name} must be a positive finite number, got {value!r}")
        if not isinstance(axes, str) or not axes or any(c not in AXES for c in axes) or len(set(axes)) != len(axes):
            raise ValueError(f"PressureServo axes must name each of x, y, z at most once (e.g. 'xyz', 'z'), got {axes!r}")
        self.pressure, self.max_rate, self.every = float(pressure), float(max_rate), float(every)
        self.axes = tuple(sorted(AXES.index(c) for c in axes))

    def update(self, simulation):
        """Set the driven axes' rates from the stress now (called by the simulation on its grid)."""
        scene = simulation.scene
        P = stress(scene).pressure_tensor
        rates = scene.params[scene.deform_slot:scene.deform_slot + 3].copy()
        reach = max(scene.reaches, default=0.0)
        for a in self.axes:
            rate = self.max_rate * min(1.0, max(-1.0, (P[a, a] - self.pressure) / self.pressure))
            shortest = scene.arrays["box"][a] * (1.0 + rate * self.every)  # (at the next change)
            if rate < 0.0 and shortest <= 2.0 * reach:
                raise ValueError(f"the pressure servo would shrink the box along {AXES[a]} to {shortest:.6g} by "
                                 f"t = {scene.time + self.every:.6g}, not longer than twice the reach {reach:.6g}: "
                                 f"the minimum image would miss interactions; use a larger box (more spheres) or a "
                                 f"lower pressure (measured {P[a, a]:.6g}, target {self.pressure:.6g})")
            rates[a] = rate
        change_rates(scene, rates)
        return rates

    def __eq__(self, other):
        return (isinstance(other, PressureServo) and (self.pressure, self.max_rate, self.every, self.axes)
                == (other.pressure, other.max_rate, other.every, other.axes))

    def __repr__(self):
        return (f"PressureServo({self.pressure!r}, max_rate={self.max_rate!r}, every={self.every!r}, "
                f"axes={''.join(AXES[a] for a in self.axes)!r})")
