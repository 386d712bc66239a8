"""A scene's walls as surfaces, for ParaView and pictures, where each stands at a frame's time.

An infinite plane is drawn as the rectangle of it that faces the region the spheres fill
(:meth:`WallSurfaces.region`: their bounding box, grown and rounded out to whole multiples of four of
the largest radii; along a periodic axis the box itself); a :class:`demkit.Cylinder` as a tube of
:data:`FACETS` facets over that region's reach along its axis; a :class:`demkit.Cone` as :data:`FACETS`
flat facets (quadrilaterals between two circles, triangles from the apex: a cone's generators are
straight, so they are exact) between its ends, an unbounded end cut where the region ends along the axis. Each moves as the wall does: a piston or
a vibrated plate is where its motion has taken it at the frame's time, a servo-controlled wall where
its servo stands (so frames must be drawn as the run reaches them: :class:`demkit.VTKWriter` does), and
a turning cylinder's or cone's facets turn with it (omega t about its axis). A :class:`demkit.MeshWall` is its own
triangles, where its translation and turning have taken them at the frame's time.

Each polygon carries cell data ``wall`` (the wall's number among the scene's effects, as in
:meth:`demkit.Scene.contacts`) and ``force``, the force the spheres exert on the wall at that time (the
sum over its contacts, force units: a piston's or a servo lid's load).
"""
from __future__ import annotations

import math

import numpy as np

from ..interactions.cone import Cone
from ..interactions.cylinder import Cylinder
from ..interactions.mesh import MeshWall
from ..interactions.wall import numbered_walls
from .polylines import write_vtp_polygons
from .series import SeriesFolder
from .series import write_series as write_particle_series

#: facets around a cylinder
FACETS = 64


def _in_plane_axes(normal):
    """Two unit vectors completing ``normal`` to a right-handed orthonormal frame."""
    helper = np.eye(3)[int(np.argmin(np.abs(normal)))]
    first = np.cross(normal, helper)
    first /= np.linalg.norm(first)
    return first, np.cross(normal, first)


def region(position, radius, box, time=None):
    """(lo, hi): the box the spheres at ``position`` fill, grown by two of the largest radii and out to
    whole multiples of four of them (a surface keeps its size while the spheres move less than that, and
    it depends on the state of its frame alone: a resumed run draws what the whole run drew); along a
    periodic axis of ``box`` (a demkit.Box or None) the box (a deforming box's at ``time``)."""
    step = 4.0 * float(np.max(radius))
    lo = np.floor((np.min(position, axis=0) - 0.5 * step) / step) * step
    hi = np.ceil((np.max(position, axis=0) + 0.5 * step) / step) * step
    if box is not None:
        lo = np.where(box.periodic, 0.0, lo)
        hi = np.where(box.periodic, box.size_at(time), hi)
    return lo, hi


def surfaces(walls, time, lo, hi, push=None):
    """(points (P,3), connectivity, offsets, cell data) of the (number, wall) pairs ``walls`` at ``time``
    over the region lo..hi; ``push``: number -> the force on that wall (cell data ``force``), or None."""
    points, connectivity, sizes, numbers, pushes = [], [], [], [], []
    for e, wall in walls:
        shift = wall.displacement(time)[0]
        if isinstance(wall, MeshWall):
            corners, polygons = wall.vertices_at(time), wall.triangles
        elif isinstance(wall, Cylinder):
            corners, polygons = _tube(wall, shift, lo, hi, time)
        elif isinstance(wall, Cone):
            corners, polygons = _cone(wall, shift, lo, hi, time)
        else:
            corners, polygons = _rectangle(wall, shift, lo, hi)
        base = sum(len(c) for c in points)
        points.append(corners)
        for polygon in polygons:
            connectivity.append(base + np.asarray(polygon, dtype=np.int64))
            sizes.append(len(polygon))
        numbers += [e] * len(polygons)
        if push is not None:
            pushes += [push[e]] * len(polygons)
    if not points:
        return np.zeros((0, 3)), np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64), {}
    cells = {"wall": np.array(numbers, dtype=np.int64)}
    if push is not None:
        cells["force"] = np.array(pushes, dtype=np.float64)
    return (np.concatenate(points), np.concatenate(connectivity), np.cumsum(sizes, dtype=np.int64), cells)


class WallSurfaces:
    """The walls of ``scene`` (none: :attr:`walls` is empty) as polygons (see the module docstring);
    :meth:`at` gives them at a time."""

    def __init__(self, scene):
        self.scene = scene
        self.walls = numbered_walls(getattr(scene, "effects", ()))  # (none for a stand-in without effects)

    def region(self):
        """(lo, hi): the region the scene's spheres fill now (:func:`region`)."""
        p = self.scene.particles
        return region(p.position, p.radius, getattr(self.scene, "box", None), getattr(self.scene, "time", None))

    def at(self, time, forces=True):
        """(points (P,3), connectivity, offsets, cell data) of every wall at ``time`` (the scene's state
        must be that of ``time`` for a servo's wall and for ``forces``, the spheres' push on each wall)."""
        from ..contacts import wall_contacts
        lo, hi = self.region()
        push = {e: 0.0 - wall_contacts(self.scene, wall, e).force.sum(axis=0) if forces else np.zeros(3)
                for e, wall in self.walls}  # (0.0 -: no -0.0)
        return surfaces(self.walls, time, lo, hi, push)


def _corners(lo, hi):
    """The eight corners of the box lo..hi, (8, 3)."""
    return np.array([[(hi if k >> a & 1 else lo)[a] for a in range(3)] for k in range(8)])


def _rectangle(wall, shift, lo, hi):
    """The plane's rectangle facing the box lo..hi (its shadow on the plane)."""
    first, second = _in_plane_axes(wall.normal)
    centre = 0.5 * (lo + hi)
    corners = _corners(lo, hi) - centre
    a, b = corners @ first, corners @ second
    a0, a1, b0, b1 = a.min(), a.max(), b.min(), b.max()
    point = wall.point + shift
    foot = centre - ((centre - point) @ wall.normal) * wall.normal  # the region's centre on the plane
    corners = np.array([foot + a * first + b * second for a, b in ((a0, b0), (a1, b0), (a1, b1), (a0, b1))])
    return corners, [(0, 1, 2, 3)]


def _tube(wall, shift, lo, hi, time):
    """The cylinder's facets over the reach of the box lo..hi along its axis."""
    along = (_corners(lo, hi) - wall.point - shift) @ wall.axis
    extent = along.min(), along.max()
    first, second = _in_plane_axes(wall.axis)
    turn = wall.angular_velocity * time
    angle = turn + 2.0 * math.pi * np.arange(FACETS) / FACETS
    ring = wall.current_radius() * (np.cos(angle)[:, None] * first + np.sin(angle)[:, None] * second)
    start, end = (wall.point + shift + s * wall.axis for s in extent)
    corners = np.concatenate([start + ring, end + ring])
    polygons = [(k, (k + 1) % FACETS, FACETS + (k + 1) % FACETS, FACETS + k) for k in range(FACETS)]
    return corners, polygons


def _cone(wall, shift, lo, hi, time):
    """The cone's facets between its ends, an unbounded end (or one beyond the region) cut where the box
    lo..hi ends along its axis (no facets when the region misses the cone's reach along it)."""
    along = (_corners(lo, hi) - wall.apex - shift) @ wall.axis
    top = along.max() if wall.upper is None else min(wall.upper, max(along.max(), wall.lower))
    ends = (wall.lower, max(top, wall.lower))
    first, second = _in_plane_axes(wall.axis)
    angle = wall.angular_velocity * time + 2.0 * math.pi * np.arange(FACETS) / FACETS
    across = np.cos(angle)[:, None] * first + np.sin(angle)[:, None] * second
    tan = math.tan(wall.half_angle)
    rings = [wall.apex + shift + h * wall.axis + h * tan * across for h in ends]
    if ends[0] == 0.0:  # from the apex: triangles
        corners = np.concatenate([rings[1], [wall.apex + shift]])
        return corners, [(k, (k + 1) % FACETS, FACETS) for k in range(FACETS)]
    corners = np.concatenate(rings)
    return corners, [(k, (k + 1) % FACETS, FACETS + (k + 1) % FACETS, FACETS + k) for k in range(FACETS)]


def write_series(trajectory, folder, name="particles", compress=False, dtype="float64", overwrite=False,
                 trails=True):
    """Write a recorded :class:`demkit.Trajectory` as a series (:func:`demkit.io.series.write_series`: one
    .vtu per frame + .pvd, the trails) and the walls it carries (``trajectory.walls``: those whose motion
    is prescribed) as ``<name>_walls.pvd``, each frame's surfaces over the region of that frame's spheres
    (without the ``force`` array: a trajectory holds no forces). Returns the particles' .pvd path."""
    walls = list(getattr(trajectory, "walls", None) or ())
    box = getattr(trajectory, "box", None)
    # (claimed before the particles are written: a folder holding them would be refused as not empty)
    wall_series = SeriesFolder(folder, name + "_walls", overwrite, box=box, extension="vtp") if walls else None
    pvd = write_particle_series(trajectory, folder, name, compress, dtype, overwrite, trails)
    for k, time in enumerate(trajectory.time if wall_series is not None else ()):
        mesh = surfaces(walls, float(time), *region(trajectory.position[k], trajectory.radius, box, float(time)))
        wall_series.add_frame(time, lambda path: write_vtp_polygons(path, *mesh, compress=bool(compress)))
    return pvd
