"""Particles: a structure of arrays describing N rigid spheres.

Always present: ``position`` (N,3), ``velocity`` (N,3), ``radius`` (N,), ``mass`` (N,),
``inertia`` (N,) = inertia_factor * mass * radius**2 (2/5 for a solid sphere) and ``ids`` (N,).
Optional fields exist only when given or when a scene needs them: ``angular_velocity`` (N,3)
and ``dipole`` (N,3, magnetic moment vectors). Absent optional fields are ``None``.
"""
from __future__ import annotations

import numpy as np

from .checks import integer_array, real_array

OPTIONAL_FIELDS = ("angular_velocity", "dipole", "image")


def _vectors(name, value, n):
    """An (n, 3) array, one row per sphere (n None: any number of rows). A bare 3-vector is one
    row: it fits a single sphere and is never copied to several (see :class:`Particles`)."""
    arr = real_array(name, value)
    if arr.shape == (3,):
        arr = arr.reshape(1, 3)
    if arr.ndim != 2 or arr.shape[1] != 3 or (n is not None and arr.shape[0] != n):
        want = f"({n}, 3)" if n is not None else "(N, 3)"
        message = f"{name} must have shape {want}, one row per sphere, got {np.shape(value)}"
        if n is not None and n > 1 and arr.shape in ((1, 3), (3,)):
            message += (f": a single vector is not copied to the {n} spheres; to give them all the same one "
                        f"pass np.tile(v, ({n}, 1))")
        raise ValueError(message)
    _finite(name, arr)
    return np.ascontiguousarray(arr)


def _scalars(name, value, n, positive=True):
    arr = real_array(name, value)
    if arr.ndim == 0:
        arr = np.full(n, float(arr))
    if arr.shape != (n,):
        raise ValueError(f"{name} must be a scalar or have shape ({n},), got {np.shape(value)}")
    _finite(name, arr)
    if positive and np.any(arr <= 0):
        k = int(np.argmax(arr <= 0))
        raise ValueError(f"{name} must be positive; particle {k} has {name} = {arr[k]}")
    return np.ascontiguousarray(arr)


def _images(value, n):
    arr = integer_array("image", value)
    if arr.shape != (n, 3):
        raise ValueError(f"image must be an ({n}, 3) array of integers, got shape {np.shape(value)}")
    return np.ascontiguousarray(arr)


def _flags(name, value, n):
    arr = np.asarray(value)
    if arr.dtype != np.bool_:
        raise ValueError(f"{name} must be booleans (one per particle), got dtype {arr.dtype}")
    if arr.shape != (n,):
        raise ValueError(f"{name} must have shape ({n},), got {arr.shape}")
    return arr.copy()


def _finite(name, arr):
    bad = ~np.isfinite(arr)
    if bad.any():
        k = int(np.argwhere(bad)[0][0])
        raise ValueError(f"{name} contains NaN or inf (particle {k}: {arr[k]})")


class Particles:
    """N rigid spheres stored as arrays (structure of arrays).

    Parameters
    ----------
    position : (N,3) array, length units.
    velocity : (N,3) array or None (zeros), length/time.
    radius, mass : scalar or (N,) array, positive.
    inertia_factor : scalar or (N,) array; moment of inertia I = inertia_factor * m * R**2
        (2/5 for a uniform solid sphere).
    dipole : (N,3) array of magnetic moments, or None (no dipole field is stored).
    angular_velocity : (N,3) array, rad/time, or None (created as zeros if a scene needs it).
    ids : (N,) integers, unique and persistent (default 0..N-1).
    image : (N,3) integers, periodic image counts, or None (created as zeros in a periodic box).
    fixed : (N,) booleans or None: fixed spheres neither move nor turn (they must start at rest;
        they still feel and exert forces: the scene gives them infinite mass and inertia).
    susceptibility : scalar or (N,) magnetic susceptibility chi = mu_r - 1 >= 0 (dimensionless), or
        None: spheres with chi > 0 are magnetisable, their moments induced by the field they feel
        (a scene with a Dipole solves them; see :mod:`demkit.interactions.induction`), the others
        keep the permanent moments in ``dipole``.

    Shapes are strict: every per-sphere vector (position, velocity, dipole, angular_velocity) is
    an (N, 3) array with one row per sphere. A bare 3-vector counts as one row, so it is accepted
    only for a single sphere, exactly like its (1, 3) form; for N > 1 both are refused rather than
    copied to every sphere (write ``np.tile(v, (N, 1))`` for equal vectors). Scalars (radius, mass,
    inertia_factor) are the exception: one number applies to all.

    Every number must be an int or float (numpy ones included): strings and bools raise TypeError.
    """

    def __init__(self, position, velocity=None, radius=1.0, mass=1.0, inertia_factor=0.4,
                 dipole=None, angular_velocity=None, ids=None, image=None, fixed=None, susceptibility=None):
        self.position = _vectors("position", position, None)
        n = self.position.shape[0]
        if n < 1:
            raise ValueError("Particles needs at least one particle")
        self.velocity = np.zeros((n, 3)) if velocity is None else _vectors("velocity", velocity, n)
        self.radius = _scalars("radius", radius, n)
        self.mass = _scalars("mass", mass, n)
        self.inertia_factor = _scalars("inertia_factor", inertia_factor, n)
        self.inertia = self.inertia_factor * self.mass * self.radius**2
        self.dipole = None if dipole is None else _vectors("dipole", dipole, n)
        self.angular_velocity = (None if angular_velocity is None
                                 else _vectors("angular_velocity", angular_velocity, n))
        self.image = None if image is None else _images(image, n)
        self.fixed = None if fixed is None else _flags("fixed", fixed, n)
        self.susceptibility = None
        if susceptibility is not None:
            self.susceptibility = _scalars("susceptibility", susceptibility, n, positive=False)
            if np.any(self.susceptibility < 0.0):
                k = int(np.argmax(self.susceptibility < 0.0))
                raise ValueError(f"susceptibility must be >= 0 (chi = mu_r - 1; diamagnetic spheres are not "
                                 f"modelled); particle {k} has {self.susceptibility[k]}")
        if ids is None:
            self.ids = np.arange(n, dtype=np.int64)
        else:
            self.ids = integer_array("ids", ids)
            if self.ids.shape != (n,) or len(np.unique(self.ids)) != n:
                raise ValueError(f"ids must be {n} unique integers, got {ids!r}")

    def __repr__(self):
        r = self.radius
        radius = f"{r[0]:.6g}" if np.all(r == r[0]) else f"{r.min():.6g} to {r.max():.6g}"
        present = [name for name in OPTIONAL_FIELDS if getattr(self, name) is not None]
        fixed = int(self.fixed.sum()) if self.fixed is not None else 0
        soft = int(np.count_nonzero(self.susceptibility)) if self.susceptibility is not None else 0
        return (f"Particles({self.n} sphere{'s' if self.n != 1 else ''}, radius {radius}"
                + "".join(f", {name}" for name in present) + (f", {fixed} fixed" if fixed else "")
                + (f", {soft} magnetisable" if soft else "") + ")")

    def __len__(self):
        return self.position.shape[0]

    @property
    def n(self):
        return self.position.shape[0]

    def require(self, field):
        """Create an optional field as zeros if it is absent (used by scenes that need it)."""
        if field not in OPTIONAL_FIELDS:
            raise ValueError(f"unknown optional field {field!r}; known: {OPTIONAL_FIELDS}")
        if getattr(self, field) is None:
            setattr(self, field, np.zeros((self.n, 3), dtype=np.int64 if field == "image" else np.float64))

    def check_fixed(self):
        """Raise ValueError if a fixed sphere moves or turns."""
        if self.fixed is None:
            return
        for name in ("velocity", "angular_velocity"):
            arr = getattr(self, name)
            if arr is not None and np.any(arr[self.fixed] != 0.0):
                k = int(np.flatnonzero(self.fixed & np.any(arr != 0.0, axis=1))[0])
                raise ValueError(f"fixed particle {self.ids[k]} has {name} {arr[k].tolist()}: fixed spheres "
                                 f"neither move nor turn")

    def check_finite(self):
        """Raise ValueError if any state array holds NaN or inf."""
        for name in ("position", "velocity", "angular_velocity", "dipole"):
            arr = getattr(self, name)
            if arr is not None:
                _finite(name, arr)

    def linear_momentum(self):
        """Total linear momentum sum_i m_i v_i, shape (3,)."""
        return (self.mass[:, None] * self.velocity).sum(axis=0)

    def angular_momentum(self, origin=(0.0, 0.0, 0.0)):
        """Orbital + spin angular momentum about ``origin``: sum_i m_i (x_i - o) x v_i + I_i w_i."""
        rel = self.position - np.asarray(origin, dtype=np.float64)
        total = np.cross(rel, self.mass[:, None] * self.velocity).sum(axis=0)
        if self.angular_velocity is not None:
            total += (self.inertia[:, None] * self.angular_velocity).sum(axis=0)
        return total

    def copy(self):
        """A deep copy (all arrays copied)."""
        new = Particles.__new__(Particles)
        for key, value in self.__dict__.items():
            setattr(new, key, value.copy() if isinstance(value, np.ndarray) else value)
        return new
