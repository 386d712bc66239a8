"""The N-body magnetic granular reference scene, for benchmarks and cross-checks with LAMMPS.

N spheres of diameter d = 1 and mass m = 1 in a periodic cube at volume fraction phi = 0.2
(random sequential addition, no overlaps), random dipole directions of magnitude 2
(lambda = mu^2 / (d^3 kT) = 4), Maxwell velocities at kT = 1 with zero total momentum, no spin.
Built with demkit.build from one random stream (``seed``), so a given (N, seed) is always the same
scene. The interactions that go with it are in ``benchmarks/lammps/in.reference`` (Hooke contacts
k_n = 1000 with a velocity dashpot 1.5, optional Coulomb friction, dipoles cut at 4 d, dt = 0.001).

Files, in a folder of your choice:

* ``scene_N<N>.npz``: L (box side), x, v, omega, mu (N, 3), d, m, phi, seed;
* ``scene_N<N>.data``: the same state as a LAMMPS data file (atom_style hybrid sphere dipole).

Use from other scripts (benchmarks/ is not a package)::

    sys.path.insert(0, "benchmarks")
    from reference_scene import load_reference_scene, particles_and_box
    scene = load_reference_scene(8000, folder)        # writes the files first if they are missing
    particles, box = particles_and_box(scene)

or from the shell: ``python benchmarks/reference_scene.py 8000 --outdir /tmp/scenes``.
"""
from __future__ import annotations

import argparse
import math
from pathlib import Path

import numpy as np

import demkit as dk

DIAMETER = 1.0
MASS = 1.0
PHI = 0.2
MOMENT = 2.0
KT = 1.0
SEED = 1
KEYS = ("L", "x", "v", "omega", "mu", "d", "m", "phi", "seed")


def make_reference_scene(n, seed=SEED, phi=PHI, moment=MOMENT, kT=KT):
    """The scene as a dict with the keys of KEYS (arrays in float64; d, m, phi, L scalars)."""
    rng = np.random.default_rng(seed)
    radius = DIAMETER / 2
    box = dk.build.box_for(n, radius, phi, periodic=True)
    x = dk.build.random_packing(n, radius, box, seed=rng)
    mu = moment * dk.build.random_directions(n, seed=rng)
    v = dk.build.thermal_velocities(n, kT, MASS, seed=rng)
    return {"L": float(box.size[0]), "x": x, "v": v, "omega": np.zeros((n, 3)), "mu": mu,
            "d": DIAMETER, "m": MASS, "phi": float(phi), "seed": seed}


def paths(n, folder):
    folder = Path(folder)
    return folder / f"scene_N{n}.npz", folder / f"scene_N{n}.data"


def write_lammps_data(scene, path, comment=""):
    """LAMMPS data file for atom_style hybrid sphere dipole: box [0, L)^3, one atom type, per-atom
    diameter and density (mass = density pi d^3 / 6), dipole moments, velocities and spins."""
    x, v, w, mu = scene["x"], scene["v"], scene["omega"], scene["mu"]
    n, side, d = len(x), scene["L"], scene["d"]
    density = scene["m"] / (math.pi / 6 * d**3)
    lines = [f"demkit reference scene: N = {n}, phi = {scene['phi']}, seed = {scene['seed']} {comment}".rstrip(),
             "", f"{n} atoms", "1 atom types", ""]
    lines += [f"0 {side:.17g} {a}lo {a}hi" for a in "xyz"]
    lines += ["", "Masses", "", "1 1.0", "", "Atoms # hybrid", ""]
    # hybrid sphere dipole: id type x y z | diameter density | q mux muy muz
    lines += [f"{i + 1} 1 {x[i, 0]:.17g} {x[i, 1]:.17g} {x[i, 2]:.17g} {d:.17g} {density:.17g} 0 "
              f"{mu[i, 0]:.17g} {mu[i, 1]:.17g} {mu[i, 2]:.17g}" for i in range(n)]
    # hybrid velocities: id vx vy vz | wx wy wz (sphere; dipole adds none)
    lines += ["", "Velocities", ""]
    lines += [f"{i + 1} {v[i, 0]:.17g} {v[i, 1]:.17g} {v[i, 2]:.17g} {w[i, 0]:.17g} {w[i, 1]:.17g} {w[i, 2]:.17g}"
              for i in range(n)]
    Path(path).write_text("\n".join(lines) + "\n")


def write_reference_scene(n, folder, seed=SEED, phi=PHI, moment=MOMENT, kT=KT):
    """Build the scene and write scene_N<n>.npz and scene_N<n>.data into ``folder`` (created if
    needed). Returns (scene dict, npz path, data path)."""
    scene = make_reference_scene(n, seed=seed, phi=phi, moment=moment, kT=kT)
    npz, data = paths(n, folder)
    npz.parent.mkdir(parents=True, exist_ok=True)
    np.savez(npz, **scene)
    write_lammps_data(scene, data, comment=f"mu = {moment} kT = {kT}")
    return scene, npz, data


def load_reference_scene(n, folder, seed=SEED, create=True):
    """The scene stored in ``folder``; with ``create`` the files are written first when missing or
    when they hold another seed. Returns the dict (see KEYS)."""
    npz, data = paths(n, folder)
    if npz.exists() and data.exists():
        with np.load(npz) as f:
            scene = {k: f[k] for k in KEYS}
        for k in ("L", "d", "m", "phi"):
            scene[k] = float(scene[k])
        scene["seed"] = int(scene["seed"])
        if scene["seed"] == seed:
            return scene
    if not create:
        raise FileNotFoundError(f"no reference scene for N = {n}, seed = {seed} in {folder}")
    return write_reference_scene(n, folder, seed=seed)[0]


def particles_and_box(scene):
    """(dk.Particles, dk.Box) of the scene: radius d/2, mass m, solid spheres, dipoles mu."""
    particles = dk.Particles(position=scene["x"], velocity=scene["v"], radius=scene["d"] / 2, mass=scene["m"],
                             dipole=scene["mu"], angular_velocity=scene["omega"])
    return particles, dk.Box(scene["L"], periodic=True)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("N", type=int, nargs="+", help="number of spheres (one or more)")
    ap.add_argument("--outdir", default=".", help="folder for scene_N<N>.npz and .data")
    ap.add_argument("--seed", type=int, default=SEED)
    a = ap.parse_args(argv)
    for n in a.N:
        scene, npz, data = write_reference_scene(n, a.outdir, seed=a.seed)
        print(f"N = {n}: L = {scene['L']:.6f}, wrote {npz} and {data}")


if __name__ == "__main__":
    main()
