"""Slab sums: Ewald and P3M in a box periodic along two axes and open along the third (a layer).

The layer is summed as a 3-D periodic box drawn out along its open axis a, from the box's length t
(where the spheres are: they start in the box) to L' = t + G with an empty gap G, by the 3-D sum
with metallic surroundings, plus the term of Yeh and Berkowitz (J. Chem. Phys. 111, 3155 (1999);
for dipoles, Brodka and Grzybowski, J. Chem. Phys. 117, 8208 (2002)), the depolarisation of an
infinite flat layer that the metallic 3-D sum leaves out. With M_a the total moment across the
layer, S the area of the periodic face and V' = S L':

    U_layer = (2 pi A / V') M_a^2,    field -(4 pi A / V') M_a along a on every sphere (no force).

What remains is the pull of the layer's copies at +-L', +-2L', ... . The field of a periodic layer
falls off with the height h above it as exp(-q h), q >= q1 = 2 pi / L_max its in-plane wave numbers
(L_max the longer periodic side), so the gap is chosen from the estimate of the lowest modes (random
moments, N spheres, sum |m|^2 over them; the nearest copy is at least G away)

    dF_gap = (8 sqrt(2) pi / 3) A q1^2 (sum |m|^2) / (S sqrt(N)) exp(-q1 G),

for its share of the accuracy, and no shorter than the real-space cutoff (no copy within it); the
tuning then measures the whole error on a sample against a sum with a gap far longer. The sum holds
while the spheres span at most t along a: a sphere that leaves the layer stops a run (``LEFT_LAYER``, checked
at every evaluation of the forces), and diagnostics refuse such a state (:meth:`Layer.check`).
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from ..engine.state import LEFT_LAYER, OK

#: room the check of the layer leaves for round-off (relative to its thickness)
SLACK = 1e-9


def open_axis(box, what, otherwise):
    """The open axis of a box periodic along exactly two axes (0, 1 or 2), or -1 when periodic along
    all three; ValueError for any other box (``otherwise`` says what to do instead)."""
    if box is not None and all(box.periodic):
        return -1
    if box is not None and int(np.count_nonzero(box.periodic)) == 2:
        return int(np.flatnonzero(~np.asarray(box.periodic))[0])
    axes = "no box" if box is None else f"periodic={[bool(f) for f in box.periodic]}"
    raise ValueError(f"{what} needs a box periodic along x, y and z, or along two of them (a slab), got {axes}; "
                     f"{otherwise}")


def thick_box_hint(box, axis, position):
    """A sentence for a refused slab sum whose box is much thicker than its spheres span ("" otherwise)."""
    if axis < 0:
        return ""
    span = float(np.ptp(np.asarray(position)[:, axis])) if len(position) else 0.0
    thickness = float(box.size[axis])
    if span >= 0.5 * thickness:
        return ""
    return (f" The spheres span {span:.6g} of the box's {thickness:.6g} along {'xyz'[axis]}, the layer the slab "
            f"sum is drawn out from: a box about as thick as the layer they form makes the sum far cheaper.")


def gap_error(prefactor, squares, n, area, longest, gap):
    """The estimate dF_gap of the force error from the layer's copies across a gap (module docstring)."""
    q = 2.0 * math.pi / longest
    return 8.0 * math.sqrt(2.0) * math.pi / 3.0 * prefactor * q * q * squares / (area * math.sqrt(n)) \
        * math.exp(-q * gap)


def gap_for(target, prefactor, squares, n, area, longest):
    """The shortest gap whose estimated error :func:`gap_error` is at most ``target`` (0 if none is needed)."""
    first = gap_error(prefactor, squares, n, area, longest, 0.0)
    return 0.0 if first <= target else longest / (2.0 * math.pi) * math.log(first / target)


class Layer:
    """The slab geometry of a tuned sum: ``axis`` (open), ``thickness`` t (the box's length along
    it), ``gap`` G and ``size``, the lengths of the drawn-out periodic box (L' = t + G along ``axis``)."""

    def __init__(self, box, axis, gap):
        self.axis = axis
        self.thickness = float(box.size[axis])
        self.gap = float(gap)
        size = np.array(box.size, dtype=np.float64)
        size[axis] = self.thickness + self.gap
        self.size = tuple(float(x) for x in size)

    @staticmethod
    def periodic_lengths(box):
        """(area S of the periodic face, its longer side) of a slab's box."""
        sides = [float(length) for length, flag in zip(box.size, box.periodic) if flag]
        return sides[0] * sides[1], max(sides)

    def table(self):
        """The run-time entries of the layer in a sum's table (:func:`table_entries`)."""
        return table_entries(self.size, self.axis, self.thickness)

    def check(self, position, ids):
        """ValueError when these (N, 3) positions leave the layer (a state its sum cannot hold); ``ids``
        name the spheres."""
        worst = int(outlier(np.ascontiguousarray(position, dtype=np.float64), self.axis, self.thickness))
        if worst >= 0:
            raise ValueError(f"particle id {ids[worst]} {self.stop_hint()}")

    def stop_hint(self):
        name = "xyz"[self.axis]
        return (f"left the layer the slab sum was tuned for: the spheres may span at most the box's length "
                f"{self.thickness:.6g} along {name}, the open axis (the sum adds copies of the layer a gap of "
                f"{self.gap:.6g} beyond it, which would then come too close). Make the box longer along {name} "
                f"(the gap and the sum's cost grow with it), or hold the spheres in with walls.")

    def __repr__(self):
        return f"Layer(axis={'xyz'[self.axis]!r}, thickness={self.thickness:.6g}, gap={self.gap:.6g})"


def table_entries(size, axis=-1, thickness=0.0):
    """The run-time entries of the box a sum covers: its lengths (a slab's drawn out), the open axis
    (-1: none, a box periodic along every axis) and the layer's thickness."""
    return [*(float(x) for x in size), float(axis), float(thickness)]


@njit(cache=True, fastmath={"contract", "arcp"}, error_model="numpy")
def layer_terms(dipole, axis, volume, prefactor, field, with_forces):
    """U_layer = (2 pi A / V') M_a^2 (module docstring), and with ``with_forces`` its field added to ``field``."""
    total = 0.0
    for i in range(dipole.shape[0]):
        total += dipole[i, axis]
    if with_forces:
        h = -4.0 * math.pi * prefactor / volume * total
        for i in range(dipole.shape[0]):
            field[i, axis] += h
    return 2.0 * math.pi * prefactor / volume * total * total


@njit(cache=True, error_model="numpy")
def outlier(position, axis, thickness):
    """-1 while the spheres span at most ``thickness`` along ``axis``; else the sphere farthest from
    their mean position along it."""
    lo, hi = math.inf, -math.inf
    middle = 0.0
    for i in range(position.shape[0]):
        lo = min(lo, position[i, axis])
        hi = max(hi, position[i, axis])
        middle += position[i, axis]
    if not hi - lo > thickness * (1.0 + SLACK):
        return -1
    middle /= position.shape[0]
    worst = 0
    for i in range(position.shape[0]):
        if abs(position[i, axis] - middle) > abs(position[worst, axis] - middle):
            worst = i
    return worst


@njit(cache=True, error_model="numpy")
def check_layer(position, params, start, status):
    """Flag LEFT_LAYER in ``status`` (sphere in status[1]) when the spheres of a slab sum whose open
    axis and thickness are params[start], params[start + 1] left its layer (no flag when axis < 0)."""
    axis = int(params[start])
    if axis < 0 or status[0] != OK:
        return
    worst = outlier(position, axis, params[start + 1])
    if worst >= 0:
        status[0] = LEFT_LAYER
        status[1] = worst
