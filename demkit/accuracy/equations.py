"""The equations of motion of a small scene as an ODE on its own compiled forces (the reference's right-hand side).

y = [positions (unwrapped), velocities, angular velocities?, dipoles?, dissipated work]; dy/dt from the
scene's ``compute_forces``. :class:`_Borrowed` lends the scene's arrays to the reference and gives them back.
"""
from __future__ import annotations

import numpy as np


class _Equations:
    """y = [positions (unwrapped), velocities, angular velocities?, dipoles?, dissipated work], all
    in the kernels' particle order; dy/dt from ``kernels.compute_forces`` at y."""

    def __init__(self, scene):
        self.scene = scene
        a = scene.arrays
        self.state, self.kernels = scene.state, scene.kernels
        self.n = n = len(scene.particles)
        self.position, self.velocity = a["position"], a["velocity"]
        self.omega = a["angular_velocity"] if a["angular_velocity"].shape[0] else None
        self.dipole = a["dipole"] if a["dipole"].shape[0] else None
        self.mass, self.inertia = a["mass"], a["inertia"]  # infinite for fixed spheres
        self.tag = a["tag"]
        self.periodic = np.array(scene.periodic, dtype=bool)
        self.size = a["box"].copy()
        self.force, self.torque = np.zeros((n, 3)), np.zeros((n, 3))
        parts = [("position", 3 * n), ("velocity", 3 * n)]
        if self.omega is not None:
            parts.append(("angular_velocity", 3 * n))
        if self.dipole is not None:
            parts.append(("dipole", 3 * n))
        parts.append(("dissipated", 1))
        self.slices, start = {}, 0
        for name, size in parts:
            self.slices[name] = slice(start, start + size)
            start += size
        self.size_y = start
        self.evaluations = 0
        self.kinds = scene.energy_kinds
        self._energies = np.zeros(2 + len(self.kinds))

    def part(self, y, name):
        s = self.slices[name]
        return y[s] if name == "dissipated" else y[s].reshape(self.n, 3)

    def initial(self):
        """y from the kernels' arrays (positions unwrapped with the image counts)."""
        y = np.zeros(self.size_y)
        x = self.position.copy()
        if self.periodic.any():
            x += self.scene.arrays["image"] * np.where(self.periodic, self.size, 0.0)
        y[self.slices["position"]] = x.ravel()
        y[self.slices["velocity"]] = self.velocity.ravel()
        if self.omega is not None:
            y[self.slices["angular_velocity"]] = self.omega.ravel()
        if self.dipole is not None:
            y[self.slices["dipole"]] = self.dipole.ravel()
        y[self.slices["dissipated"]] = self.scene.accum[0]
        return y

    def wrapped(self, x):
        if not self.periodic.any():
            return x
        folded = x - np.floor(x / np.where(self.size > 0, self.size, 1.0)) * self.size
        return np.where(self.periodic, folded, x)

    def load(self, y):
        """Write the state y into the kernels' arrays (periodic coordinates folded into the box)."""
        self.position[...] = self.wrapped(self.part(y, "position"))
        self.velocity[...] = self.part(y, "velocity")
        if self.omega is not None:
            self.omega[...] = self.part(y, "angular_velocity")
        if self.dipole is not None:
            self.dipole[...] = self.part(y, "dipole")

    def __call__(self, t, y):
        self.load(y)
        power = self.kernels.compute_forces(self.state, self.force, self.torque, False, False)
        self.evaluations += 1
        dy = np.empty_like(y)
        dy[self.slices["position"]] = y[self.slices["velocity"]]
        dy[self.slices["velocity"]] = (self.force / self.mass[:, None]).ravel()
        if self.omega is not None:
            w = self.part(y, "angular_velocity")
            dy[self.slices["angular_velocity"]] = (self.torque / self.inertia[:, None]).ravel()
            if self.dipole is not None:
                dy[self.slices["dipole"]] = np.cross(w, self.part(y, "dipole")).ravel()
        elif self.dipole is not None:
            dy[self.slices["dipole"]] = 0.0
        dy[self.slices["dissipated"]] = power
        return dy

    def energies(self, y):
        """[kinetic, rotational, potentials by kind] at y (the kernels' own energy sums)."""
        self.load(y)
        self.kernels.energies_of(self.state, self._energies)
        return self._energies.copy()

    def frame(self, y):
        """(position folded, image, velocity, omega, dipole, energies, L) in the user's order."""
        x = self.part(y, "position")
        order = self.tag
        def user(values):
            out = np.empty_like(values)
            out[order] = values
            return out
        image = None
        position = x
        if self.periodic.any():
            length = np.where(self.size > 0, self.size, 1.0)
            shift = np.where(self.periodic, np.floor(x / length), 0.0)
            position = x - shift * self.size
            image = user(shift.astype(np.int64))
        v = self.part(y, "velocity")
        finite = np.where(np.isfinite(self.mass), self.mass, 0.0)
        momentum = np.cross(x, finite[:, None] * v).sum(axis=0)
        omega = dipole = None
        if self.omega is not None:
            omega = self.part(y, "angular_velocity")
            inertia = np.where(np.isfinite(self.inertia), self.inertia, 0.0)
            momentum = momentum + (inertia[:, None] * omega).sum(axis=0)
            omega = user(omega)
        if self.dipole is not None:
            dipole = user(self.part(y, "dipole"))
        return (user(position), image, user(v), omega, dipole, self.energies(y), momentum)


class _Borrowed:
    """Lend a scene's kernel arrays to the reference and give them back as they were."""

    NAMES = ("position", "velocity", "angular_velocity", "dipole", "image", "force", "torque", "accum",
             "status", "counters")

    def __init__(self, scene):
        self.scene = scene

    def __enter__(self):
        scene = self.scene
        scene.validate()
        scene.push()
        self.saved = {name: scene.arrays[name].copy() for name in self.NAMES}
        p = scene.particles
        self.user = {name: getattr(p, name).copy() for name in ("position", "velocity", "angular_velocity",
                                                                   "dipole", "image")
                     if getattr(p, name) is not None}
        return _Equations(scene)

    def __exit__(self, *exc):
        scene = self.scene
        for name, value in self.saved.items():
            scene.arrays[name][...] = value
        for name, value in self.user.items():
            getattr(scene.particles, name)[...] = value
        if scene.plan.lists:  # the lists were built around trial states: rebuild them at the restored one
            scene.arrays["reference"][...] = np.inf
        scene.push()
        scene.arrays["counters"][...] = self.saved["counters"]
        scene.arrays["status"][...] = self.saved["status"]
        return False
