"""A scene's walls as surfaces, for ParaView and pictures, where each stands at a frame's time.

An infinite plane is drawn as the rectangle of it that faces the region the spheres fill
(:meth:`WallSurfaces.region`: their bounding box, grown and rounded out to whole multiples of four of
the largest radii; along a periodic axis the box itself); a :class:`demkit.Cylinder` as a tube of
:data:`FACETS` facets over that region's reach along its axis. Each moves as the wall does: a piston or
a vibrated plate is where its motion has taken it at the frame's time, a servo-controlled wall where
its servo stands (so frames must be drawn as the run reaches them: :class:`demkit.VTKWriter` does), and
a turning cylinder's facets turn with it (omega t about its axis).

Each polygon carries cell data ``wall`` (the wall's number among the scene's effects, as in
:meth:`demkit.Scene.contacts`) and ``force``, the force the spheres exert on the wall at that time (the
sum over its contacts, force units: a piston's or a servo lid's load).
"""
from __future__ import annotations

import math

import numpy as np

from ..interactions.cylinder import Cylinder
from ..interactions.wall import Wall

#: facets around a cylinder
FACETS = 64


def _in_plane_axes(normal):
    """Two unit vectors completing ``normal`` to a right-handed orthonormal frame."""
    helper = np.eye(3)[int(np.argmin(np.abs(normal)))]
    first = np.cross(normal, helper)
    first /= np.linalg.norm(first)
    return first, np.cross(normal, first)


class WallSurfaces:
    """The walls of ``scene`` (none: :attr:`walls` is empty) as polygons (see the module docstring);
    :meth:`at` gives them at a time."""

    def __init__(self, scene):
        self.scene = scene
        self.walls = [(e, effect) for e, effect in enumerate(getattr(scene, "effects", ())) if isinstance(effect, Wall)]

    def region(self):
        """(lo, hi): the box the spheres fill now, grown by two of the largest radii and out to whole
        multiples of four of them (a surface keeps its size while the spheres move less than that, and
        it depends on the state of its frame alone: a resumed run draws what the whole run drew);
        along a periodic axis the box."""
        p = self.scene.particles
        step = 4.0 * float(np.max(p.radius))
        lo = np.floor((p.position.min(axis=0) - 0.5 * step) / step) * step
        hi = np.ceil((p.position.max(axis=0) + 0.5 * step) / step) * step
        box = getattr(self.scene, "box", None)
        if box is not None:
            lo = np.where(box.periodic, 0.0, lo)
            hi = np.where(box.periodic, box.size, hi)
        return lo, hi

    def at(self, time, forces=True):
        """(points (P,3), connectivity, offsets, cell data) of every wall at ``time`` (the scene's state
        must be that of ``time`` for a servo's wall and for ``forces``, the spheres' push on each wall)."""
        points, connectivity, offsets, numbers, pushes = [], [], [], [], []
        lo, hi = self.region()
        for e, wall in self.walls:
            shift = wall.displacement(time)[0]
            if isinstance(wall, Cylinder):
                corners, polygons = self._tube(wall, shift, lo, hi, time)
            else:
                corners, polygons = self._rectangle(wall, shift, lo, hi)
            push = 0.0 - self._force_on_sphere(wall, e) if forces else np.zeros(3)  # (0.0 -: no -0.0)
            base = sum(len(c) for c in points)
            points.append(corners)
            for polygon in polygons:
                connectivity.extend(base + k for k in polygon)
                offsets.append(len(connectivity))
                numbers.append(e)
                pushes.append(push)
        if not points:
            return np.zeros((0, 3)), np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64), {}
        cells = {"wall": np.array(numbers, dtype=np.int64), "force": np.array(pushes, dtype=np.float64)}
        return np.concatenate(points), np.array(connectivity, dtype=np.int64), np.array(offsets, dtype=np.int64), cells

    @staticmethod
    def _rectangle(wall, shift, lo, hi):
        """The plane's rectangle facing the box lo..hi (its shadow on the plane)."""
        first, second = _in_plane_axes(wall.normal)
        centre = 0.5 * (lo + hi)
        corners = np.array([[(hi if k >> a & 1 else lo)[a] for a in range(3)] for k in range(8)]) - centre
        a, b = corners @ first, corners @ second
        a0, a1, b0, b1 = a.min(), a.max(), b.min(), b.max()
        point = wall.point + shift
        foot = centre - ((centre - point) @ wall.normal) * wall.normal  # the region's centre on the plane
        corners = np.array([foot + a * first + b * second for a, b in ((a0, b0), (a1, b0), (a1, b1), (a0, b1))])
        return corners, [(0, 1, 2, 3)]

    @staticmethod
    def _tube(wall, shift, lo, hi, time):
        """The cylinder's facets over the reach of the box lo..hi along its axis."""
        corners = np.array([[(hi if k >> a & 1 else lo)[a] for a in range(3)] for k in range(8)])
        along = (corners - wall.point - shift) @ wall.axis
        extent = along.min(), along.max()
        first, second = _in_plane_axes(wall.axis)
        turn = wall.angular_velocity * time
        angle = turn + 2.0 * math.pi * np.arange(FACETS) / FACETS
        ring = wall.radius * (np.cos(angle)[:, None] * first + np.sin(angle)[:, None] * second)
        start, end = (wall.point + shift + s * wall.axis for s in extent)
        corners = np.concatenate([start + ring, end + ring])
        polygons = [(k, (k + 1) % FACETS, FACETS + (k + 1) % FACETS, FACETS + k) for k in range(FACETS)]
        return corners, polygons

    def _force_on_sphere(self, wall, number):
        """The sum of the wall's contact forces on the spheres now (3,)."""
        from ..contacts import wall_contacts
        return wall_contacts(self.scene, wall, number).force.sum(axis=0)
