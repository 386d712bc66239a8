"""Spheres poured through a hopper read from an STL file: a triangle-mesh wall (dk.MeshWall).

    python3 examples/mesh_hopper/run.py [--quick] [--output DIR] [--no-picture]

The hopper, a cone narrowing from radius 3.2 at height 4 to an outlet of radius 1.1 at height 0 under a
straight collar up to height 6, is written as an STL file (96 facets around: 384 triangles) with
meshio, as a CAD tool would, and read back by dk.MeshWall. 300 spheres (radius 0.2-0.25, friction 0.4)
start in a loose lattice above it, fall in, and run out of the outlet onto a floor 2 below it. The
run prints how many have passed the outlet over time, checks that none went through the hopper's wall
(from within the cone or the collar straight to beside it, between two frames 0.05 apart), and draws
``hopper.png`` (the spheres and the hopper at t = 2.0, the mesh translucent) with demkit's own
picture tools. ``--quick``: 120 spheres, 1.2 time units (the tests' form; a few seconds after
compiling).
"""
from __future__ import annotations

import argparse
import math
from pathlib import Path

import meshio
import numpy as np

import demkit as dk

HERE = Path(__file__).resolve().parent
#: the hopper: outlet radius and height, the cone's top, the collar's top, facets around
OUTLET, TOP, WIDE, COLLAR, FACETS = 1.1, 4.0, 3.2, 6.0, 96


def hopper_mesh():
    """(vertices, triangles) of the cone from (OUTLET, z = 0) to (WIDE, z = TOP) and the collar up to
    COLLAR: three rings of FACETS vertices, two bands of quads cut in two."""
    angle = 2 * math.pi * np.arange(FACETS) / FACETS
    rings = [(OUTLET, 0.0), (WIDE, TOP), (WIDE, COLLAR)]
    vertices = np.concatenate([np.c_[r * np.cos(angle), r * np.sin(angle), np.full(FACETS, z)] for r, z in rings])
    k = np.arange(FACETS)
    bands = []
    for b in range(len(rings) - 1):
        a, c = b * FACETS + k, b * FACETS + (k + 1) % FACETS
        bands += [np.c_[a, c, a + FACETS], np.c_[c, c + FACETS, a + FACETS]]
    return vertices, np.concatenate(bands)


def leaks(position):
    """The number of times a sphere went from inside the hopper (above the outlet, within the cone or the
    collar) straight to outside it (beside it, above the outlet) or back between two frames: through its
    wall. A sphere that falls out of the outlet and bounces up beside the hopper does not count."""
    r, z = np.hypot(position[..., 0], position[..., 1]), position[..., 2]
    wall = np.where(z >= TOP, WIDE, OUTLET + (WIDE - OUTLET) * np.clip(z, 0.0, TOP) / TOP)
    above = (z > 0.0) & (z < COLLAR)
    inside, beside = above & (r < wall), above & (r >= wall)
    return int(np.sum(inside[:-1] & beside[1:]) + np.sum(beside[:-1] & inside[1:]))


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="120 spheres, a short run")
    parser.add_argument("--output", type=Path, default=HERE)
    parser.add_argument("--no-picture", action="store_true", help="skip hopper.png")
    args = parser.parse_args(argv)
    args.output.mkdir(parents=True, exist_ok=True)
    n, duration = (120, 1.2) if args.quick else (300, 2.5)

    stl = args.output / "hopper.stl"
    vertices, triangles = hopper_mesh()
    meshio.write(stl, meshio.Mesh(vertices, [("triangle", triangles)]))
    hopper = dk.MeshWall(file=stl)

    rng = np.random.default_rng(1)
    k = np.arange(n)  # a loose lattice of 6 x 6 columns, 0.6 apart, from height 3 up
    position = np.c_[(k % 6 - 2.5) * 0.6, (k // 6 % 6 - 2.5) * 0.6, 3.0 + 0.6 * (k // 36)]
    position[:, :2] += rng.uniform(-0.05, 0.05, size=(n, 2))
    radius = rng.uniform(0.2, 0.25, n)
    spheres = dk.Particles(position=position, radius=radius, mass=radius ** 3 / 0.25 ** 3)
    law = dk.KelvinVoigt(5e4, 50.0, friction=dk.Friction(0.4))
    floor = dk.Wall((0, 0, -2.0), (0, 0, 1))
    scene = dk.Scene(spheres, [law, hopper, floor, dk.Gravity((0, 0, -10.0))])
    run = dk.Simulation(scene, dk.VelocityVerlet(3e-4)).run(duration, record_every=0.05, progress=False)

    below = (run.position[:, :, 2] < 0.0).sum(axis=1)
    for t in [*np.arange(0.0, duration - 1e-9, 0.25 if args.quick else 0.5), duration]:
        k = int(np.argmin(np.abs(run.time - t)))
        print(f"t = {run.time[k]:4.2f}: {below[k]:3d} of {n} spheres through the outlet")
    crossings = leaks(run.position)
    print(f"spheres that went through the hopper's wall: {crossings}", flush=True)
    picture = None
    if not args.no_picture:
        picture = dk.viz.snapshot(run, args.output / "hopper.png", time=min(2.0, duration), view="xz",
                                  window_size=(640, 800), label=False, bounds=(-3.4, 3.4, -3.4, 3.4, -2.1, 6.1))
        print(f"wrote {picture}")
    return {"run": run, "radius": radius, "below": below, "leaks": crossings, "picture": picture, "hopper": hopper}


if __name__ == "__main__":
    main()
