"""Walls made of triangle meshes: hoppers, chutes, mixers, any shape the plane and the cylinder do not cover,
read from a file (STL, OBJ, VTK, Gmsh: whatever meshio reads) or given as arrays, at rest or moving rigidly.

Contact. A sphere of radius R centred at x meets the mesh at the point q of the mesh nearest to x; there
the mesh is, for that sphere, the plane wall through q with normal n along x - q (the face's normal when q
lies inside a face, the direction from q to x when q lies on an edge or a corner), and the contact is that
plane wall's (:mod:`demkit.interactions.wall`): overlap delta = R - |x - q|, the scene's law (Kelvin-Voigt or
Hertz, friction, rolling and twisting resistance) with friction history per sphere turned into the new
tangent plane as the sphere moves. On a flat triangulated plane this is exactly the plane wall: a sphere
over a shared edge or corner sees one contact (no double counting), and nothing jumps as it rolls from one
triangle to the next.

What it does not do:

* one contact per sphere and mesh: a sphere touching two faces that meet at an angle (a crease, the
  corner of a box) feels only the nearer. Build a box or a hopper whose faces a sphere may touch at
  once from several meshes (or planes, cylinders): each is its own wall with its own contact;
* two-sided: a mesh is a thin shell, and the normal always points from the surface to the sphere's
  centre, on whichever side it is (no inside or outside, no use of the triangles' winding). A sphere
  pushed so deep that its centre crosses the surface comes out on the other side: the time step
  guards keep overlaps far smaller than that;
* the Hertz law's contact radius takes the wall as flat (R* = R), as for a cylinder.

Motion. Like a plane wall the mesh may be carried by a translation D(t) = V t + A (1 - cos 2 pi f t)
(``velocity``, ``amplitude``, ``frequency``), and it may turn at ``angular_velocity`` omega about the unit
``axis`` a through ``point`` c (carried along by D). At time t a sphere at x meets the mesh as it stood at
time 0 seen from R(-omega t)(x - D - c) + c, and the surface there moves as the rigid body does:
u = D'(t) + omega a x (q - c - D) at the contact point q.

Neighbours. The compiled loops find q through a uniform grid over the mesh's box grown by ``reach`` (the
largest sphere radius it serves: by default the scene's largest when the wall first joins a scene), in
the mesh's own frame, each cell listing the triangles whose box grown by ``reach`` meets it: a sphere
visits only the triangles of its cell (rejecting most by their bounding spheres and planes), and a sphere
outside the grid touches nothing. The mesh, the grid and the lists live in the wall's geometry block in
the scene's parameters (:mod:`demkit.interactions.mesh_geometry`), read by both tiers.
"""
from __future__ import annotations

import math
import warnings
from pathlib import Path

import numpy as np
from numba import njit

from ..engine.motion import KERNEL_OPTIONS
from .mesh_geometry import mesh_numbers
from .sphere import vector
from .wall import Wall
from .wall_motion import SHAPE_AT, SHAPES, geometry_plane

#: a triangle whose area is below this fraction of its longest edge squared is degenerate
DEGENERATE = 1e-12
#: cell types meshio gives that carry no surface: points and curves (Gmsh writes them for its physical
#: groups), left out of a file's mesh
IGNORED_CELLS = ("vertex", "line", "line3", "line4")


@njit(**dict(KERNEL_OPTIONS, inline="never"))
def _planes(position, block, t, out):
    """The plane (plane, n, u: as geometry_plane) the mesh whose geometry block is ``block`` presents to
    each centre of ``position`` at time t, into out (N, 7): the compiled loops' own numbers."""
    for i in range(position.shape[0]):
        p, nx, ny, nz, ux, uy, uz, _, _ = geometry_plane(position[i, 0], position[i, 1], position[i, 2], 0.0, block,
                                                         0, t, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0)
        out[i, 0], out[i, 1], out[i, 2], out[i, 3], out[i, 4], out[i, 5], out[i, 6] = p, nx, ny, nz, ux, uy, uz


def read_mesh(path):
    """(vertices (V, 3), triangles (T, 3)) of the mesh file at ``path`` (any format meshio reads), its
    triangle cells; points and curves (vertex and line cells) are left out; any other cell (quads,
    polygons, tetrahedra, second-order triangles) is refused: ValueError naming it."""
    import meshio
    path = Path(path)
    if not path.is_file():
        raise ValueError(f"mesh file {path} does not exist")
    try:
        with warnings.catch_warnings():  # (numpy's overflow warnings while meshio sniffs a broken file)
            warnings.simplefilter("ignore", RuntimeWarning)
            mesh = meshio.read(path)
    except Exception as err:  # meshio's own errors have no common base  # noqa: BLE001
        raise ValueError(f"meshio cannot read the mesh file {path}: {err}") from None
    other = sorted({block.type for block in mesh.cells if block.type not in ("triangle", *IGNORED_CELLS)})
    if other:
        raise ValueError(f"mesh file {path} holds {', '.join(other)} cells: a mesh wall takes triangles only "
                         f"(triangulate its surface, e.g. meshio's or your CAD tool's export to STL)")
    triangles = [block.data for block in mesh.cells if block.type == "triangle"]
    if not triangles or not sum(len(t) for t in triangles):
        raise ValueError(f"mesh file {path} holds no triangles")
    points = np.asarray(mesh.points, dtype=np.float64)
    if points.ndim != 2 or points.shape[1] != 3:
        raise ValueError(f"mesh file {path}: its points have {points.shape[-1]} coordinates, a mesh wall needs 3")
    return points, np.concatenate(triangles).astype(np.int64)


def mesh_corners(vertices, triangles, what="MeshWall"):
    """The corners (T, 3, 3) of the triangles (T, 3) of ``vertices`` (V, 3), checked: ValueError for an
    empty mesh, non-finite vertices, indices out of range and degenerate (zero-area) triangles."""
    v = np.asarray(vertices, dtype=np.float64)
    if v.ndim != 2 or v.shape[1] != 3:
        raise ValueError(f"{what} vertices must have shape (V, 3), got {v.shape}")
    bad = np.flatnonzero(~np.isfinite(v).all(axis=1))
    if len(bad):
        raise ValueError(f"{what} vertex {int(bad[0])} is not finite: {v[bad[0]].tolist()}")
    t = np.asarray(triangles)
    if t.size == 0:
        raise ValueError(f"{what} has no triangles")
    if t.ndim != 2 or t.shape[1] != 3:
        raise ValueError(f"{what} triangles must have shape (T, 3), three vertex indices each, got {t.shape}")
    if t.dtype.kind not in "iu":
        if not np.all(np.isfinite(t)) or np.any(t != np.round(t)):
            raise ValueError(f"{what} triangles must hold integer vertex indices")
    t = t.astype(np.int64)
    out = np.flatnonzero((t < 0).any(axis=1) | (t >= len(v)).any(axis=1))
    if len(out):
        raise ValueError(f"{what} triangle {int(out[0])} names vertex {t[out[0]].tolist()}, but there are "
                         f"{len(v)} vertices (0 to {len(v) - 1})")
    corners = v[t]
    edges = np.stack([corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 1], corners[:, 0] - corners[:, 2]],
                     axis=1)
    longest = (edges ** 2).sum(axis=2).max(axis=1)
    twice_area = np.linalg.norm(np.cross(edges[:, 0], -edges[:, 2]), axis=1)
    flat = np.flatnonzero(twice_area <= DEGENERATE * longest)
    if len(flat):
        k = int(flat[0])
        raise ValueError(f"{what} triangle {k} (vertices {t[k].tolist()}) is degenerate: its corners "
                         f"{corners[k].tolist()} lie on a line, zero area (remove it or repair the mesh)")
    return corners


class MeshWall(Wall):
    """A wall made of a triangle mesh (see the module docstring).

    vertices, triangles : the mesh as arrays, (V, 3) coordinates and (T, 3) vertex indices (or ``file``);
    file : a mesh file meshio reads (STL, OBJ, VTK, Gmsh, ...), its triangle cells; scale : a factor on
    the file's (or the arrays') coordinates (default 1); point, axis, angular_velocity : the mesh turns at
    this rate (right-handed, rad per unit time) about the axis through the point (default: at rest);
    velocity, amplitude, frequency : a translation V t + A (1 - cos 2 pi f t) of the whole mesh;
    contact : the contact law (:class:`KelvinVoigt` or :class:`Hertz`), default the scene's own;
    reach : the largest sphere radius the mesh's grid serves (default: the largest radius of the spheres
    of the first scene it joins); cell : the grid's cell edge (default: the larger of reach and the
    median triangle's size, :func:`demkit.interactions.mesh_geometry.cell_size`).
    """

    shape = SHAPES["mesh"]

    def __init__(self, vertices=None, triangles=None, file=None, scale=1.0, point=(0.0, 0.0, 0.0),
                 axis=(0.0, 0.0, 1.0), angular_velocity=0.0, velocity=(0.0, 0.0, 0.0), amplitude=(0.0, 0.0, 0.0),
                 frequency=0.0, contact=None, reach=None, cell=None):
        if (file is None) == (vertices is None):
            raise ValueError("MeshWall takes a mesh file or vertices and triangles, one of them")
        self.file = None if file is None else str(file)
        if file is not None:
            if triangles is not None:
                raise ValueError("MeshWall takes a mesh file or vertices and triangles, not both")
            vertices, triangles = read_mesh(file)
        elif triangles is None:
            raise ValueError("MeshWall needs triangles with its vertices: (T, 3) vertex indices")
        scale = float(scale)
        if not math.isfinite(scale) or scale <= 0.0:
            raise ValueError(f"MeshWall scale must be positive and finite, got {scale!r}")
        what = "MeshWall" if file is None else f"MeshWall (mesh file {file})"
        self.corners = mesh_corners(vertices, triangles, what) * scale
        # its distinct vertices and the triangles over them (pictures draw the mesh's own edges only)
        self.vertices, inverse = np.unique(self.corners.reshape(-1, 3), axis=0, return_inverse=True)
        self.triangles = inverse.reshape(-1, 3)
        axis = vector("MeshWall axis", axis)
        if not np.linalg.norm(axis) > 0.0:
            raise ValueError("MeshWall axis has zero length")
        omega = float(angular_velocity)
        if not math.isfinite(omega):
            raise ValueError(f"MeshWall angular_velocity must be finite, got {angular_velocity!r}")
        for name, value in (("reach", reach), ("cell", cell)):
            if value is not None and not (math.isfinite(float(value)) and float(value) > 0.0):
                raise ValueError(f"MeshWall {name} must be positive and finite, got {value!r}")
        # the plane wall's attributes: a placeholder plane through the turning point along the axis
        self.angular_velocity = omega  # (before the contact law is adopted: a turning wall's functions)
        super().__init__(point, axis, velocity=velocity, contact=contact, amplitude=amplitude, frequency=frequency)
        self.axis = self.normal
        self.angular_velocity = omega
        self.reach = None if reach is None else float(reach)
        self.cell = None if cell is None else float(cell)
        self._block = None

    @property
    def steady(self):
        """A mesh always has a geometry block (its triangles and grid)."""
        return False

    def spin(self):
        """The mesh's own angular velocity, omega a (rolling and twisting resistance act on the sphere's
        spin relative to it)."""
        return self.angular_velocity * self.axis

    @property
    def travels(self):
        """Does the mesh move (translate or turn), so that where it stands depends on the scene's clock?"""
        return bool(self.velocity.any() or self.amplitude.any() or self.angular_velocity != 0.0)

    @property
    def triangle_count(self):
        return len(self.corners)

    def geometry_values(self):
        """The geometry block: shape code 4, the motion, the mesh and its grid (built once, when the reach
        is known: :mod:`demkit.interactions.mesh_geometry`)."""
        if self._block is None:
            if self.reach is None:
                raise ValueError(f"{self!r} has no reach yet: add it to a Scene (its largest sphere radius sets "
                                 f"it) or pass MeshWall(..., reach=...)")
            numbers = mesh_numbers(self.corners, self.point, self.axis, self.angular_velocity, self.reach,
                                   SHAPE_AT, self.cell)
            self._block = np.concatenate([[float(self.shape)], self.motion_values(), numbers])
        return self._block

    def grid(self):
        """(lo, cell edge, counts, starts, listed) of the mesh's grid, read from its block."""
        b, k = self.geometry_values(), SHAPE_AT
        counts = b[k + 12:k + 15].astype(np.int64)
        starts = b[int(b[k + 17]):int(b[k + 18])].astype(np.int64)
        return b[k + 8:k + 11], float(b[k + 11]), counts, starts, b[int(b[k + 18]):].astype(np.int64)

    def _frame(self, position, time):
        """Centres (N, 3) at ``time`` in the mesh's frame (the translation and turning undone)."""
        shift = self.displacement(time)[0]
        r = np.asarray(position, dtype=float).reshape(-1, 3) - shift - self.point
        if self.angular_velocity != 0.0:
            r = _rotated(r, self.axis, -self.angular_velocity * time)
        return r + self.point

    def vertices_at(self, time=0.0):
        """The mesh's distinct vertices (V, 3) where it stands at ``time`` (:attr:`triangles` index them)."""
        r = self.vertices - self.point
        if self.angular_velocity != 0.0:
            r = _rotated(r, self.axis, self.angular_velocity * time)
        return r + self.point + self.displacement(time)[0]

    def corners_at(self, time=0.0):
        """The triangles' corners (T, 3, 3) where the mesh stands at ``time``."""
        return self.vertices_at(time)[self.triangles]

    def listed(self, position, time=0.0):
        """The number of triangles each centre's grid cell lists at ``time`` (0 outside the grid): the
        triangles a sphere's query visits."""
        lo, side, counts, starts, _ = self.grid()
        f = np.floor((self._frame(position, time) - lo) / side)
        inside = np.all((f >= 0) & (f < counts), axis=1)
        cell = ((f[:, 0] * counts[1] + f[:, 1]) * counts[2] + f[:, 2]).astype(np.int64)
        cell = np.where(inside, cell, 0)
        return np.where(inside, starts[cell + 1] - starts[cell], 0)

    def planes(self, position, time=0.0):
        """The plane each centre meets at ``time`` and the surface's velocity there, (N, 7): plane, n, u
        (the compiled loops' own numbers: demkit.interactions.wall_motion.geometry_plane)."""
        x = np.ascontiguousarray(np.asarray(position, dtype=np.float64).reshape(-1, 3))
        out = np.empty((len(x), 7))
        _planes(x, self.geometry_values(), float(time), out)
        return out

    def heights(self, position, time=0.0):
        """Distance of each centre from the nearest point of the mesh at ``time`` (a very large number,
        FAR, beyond the reach of every triangle); the shape of ``position`` without its last axis."""
        position = np.asarray(position, dtype=np.float64)
        rows = self.planes(position, time)
        h = np.einsum("ij,ij->i", position.reshape(-1, 3), rows[:, 1:4]) - rows[:, 0]
        return h.reshape(position.shape[:-1])

    def normals(self, position, time=0.0):
        """The unit normal where each sphere touches the mesh, towards its centre (N, 3)."""
        return self.planes(position, time)[:, 1:4]

    def parameters_at(self, position, time=0.0, radius=None):
        """The parameter values for spheres centred at ``position`` at ``time`` (N, P): the plane each
        meets and the surface's velocity there in place of a plane wall's seven geometry values (a mesh
        is flat: a Hertz law's moduli as they are, whatever the spheres' ``radius``)."""
        values = np.tile(self.parameter_values(), (len(np.atleast_2d(position)), 1))
        values[:, :7] = self.planes(position, time)
        return values

    def surface_speed(self):
        """The fastest the surface moves: |omega| times the farthest corner's distance from the axis,
        + |V| + 2 pi f |A|."""
        r = self.corners.reshape(-1, 3) - self.point
        across = np.linalg.norm(r - np.outer(r @ self.axis, self.axis), axis=1).max()
        return abs(self.angular_velocity) * float(across) + super().surface_speed()

    def where(self):
        source = f" from {self.file}" if self.file is not None else ""
        return f"the mesh of {self.triangle_count} triangles{source}"

    def check(self, particles, time=0.0):
        largest = float(np.max(particles.radius))
        if self.reach is None:
            self.reach = largest
        elif largest > self.reach:
            raise ValueError(f"{self!r}: a sphere of radius {largest:.6g} is larger than the reach its grid was built "
                             f"for ({self.reach:.6g}): it could touch triangles its cell does not list; give "
                             f"MeshWall(..., reach=...) the largest radius")
        super().check(particles, time)

    def check_box(self, box):
        """Along a periodic axis the spheres' images repeat and the mesh does not: the mesh's grid (its
        box grown by the reach, swept round its axis if it turns) must lie inside the box across that
        axis, and the mesh must not travel along it."""
        lo, side, counts, _, _ = self.grid()
        hi = lo + side * counts
        if self.angular_velocity != 0.0:  # the ball about the turning point that holds the grid
            radius = float(np.linalg.norm(np.maximum(np.abs(lo - self.point), np.abs(hi - self.point))))
            lo, hi = self.point - radius, self.point + radius
        for k in np.flatnonzero(box.periodic):
            fits = 0.0 <= lo[k] and hi[k] <= box.size[k] and self.velocity[k] == 0.0 and self.amplitude[k] == 0.0
            if not fits:
                raise ValueError(f"{self!r} reaches across the box's periodic axis {'xyz'[k]} (size "
                                 f"{box.size[k]:.6g}; its grid spans {lo[k]:.6g} to {hi[k]:.6g}): a mesh in a "
                                 f"periodic box must lie inside it across each periodic axis, at its reach from the "
                                 f"box's faces, and not move along it (a mesh has no periodic images)")

    def __repr__(self):
        source = f"file={self.file!r}" if self.file is not None else f"{self.triangle_count} triangles"
        turn = (f", point={self.point.tolist()}, axis={self.axis.tolist()}, angular_velocity="
                f"{self.angular_velocity!r}") if self.angular_velocity != 0.0 else ""
        return f"MeshWall({source}{turn}{self.motion_repr()})"


def _rotated(r, axis, angle):
    """The vectors r (N, 3) turned by ``angle`` about the unit ``axis`` (Rodrigues)."""
    c, s = math.cos(angle), math.sin(angle)
    return r * c + np.cross(axis, r) * s + np.outer(r @ axis, axis) * (1.0 - c)
