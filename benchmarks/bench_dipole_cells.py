"""What a dipole loop without a stored pair list would cost (issue: 400 bytes per sphere).

demkit keeps the dipole pairs within cutoff + skin in a list (284 bytes a sphere on the N = 8000
reference scene, a third of its memory). The alternative measured here stores nothing: every force
evaluation walks the cells (a half shell of neighbour cells around each sphere's own; the spheres
sorted by cell, as the best case), gathers the pairs within the cutoff in blocks of 64 and evaluates
them with demkit's dipole force as the list loop does, then scatters the partners' forces and
torques. It is a prototype for this measurement, not part of the engine.

Checked against a brute-force sum over all pairs (relative difference ~1e-15), then timed against
``scene.kernels.compute_forces`` of a dipole-only scene with the stored list (one thread, the same
spheres and cutoff), alternating, least of ``--repeats``. Cells of one cutoff (stencil +-1) and of
half a cutoff (+-2). Writes benchmarks/results/dipole_cells.json.

    python benchmarks/bench_dipole_cells.py [--n 8000] [--repeats 20]
"""
from __future__ import annotations

import os

os.environ.setdefault("NUMBA_NUM_THREADS", "1")

import argparse  # noqa: E402
import json  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
from numba import njit  # noqa: E402

import demkit as dk  # noqa: E402
from demkit.interactions.dipole import dipole_force  # noqa: E402
from demkit.engine.neighbours import bin_particles  # noqa: E402

HERE = Path(__file__).resolve().parent
OPTIONS = dict(fastmath={"contract", "arcp"}, error_model="numpy", cache=True)
BLOCK = 64


def cell_order(position, length, ncell):
    """(order, start): the spheres by cell of a cubic periodic box cut into ncell^3 cells, z fastest
    (demkit's own counting sort, neighbours.bin_particles)."""
    n = position.shape[0]
    order, start = np.empty(n, np.int64), np.empty(ncell ** 3 + 1, np.int64)
    bin_particles(position, np.full(3, length), np.ones(3, np.bool_), np.zeros(3), np.full(3, length / ncell),
                  np.full(3, ncell, np.int64), np.empty(n, np.int64), start, order)
    return order, start


def half_shell(width):
    """Offsets of the neighbour cells a cell pairs with, each neighbour pair once (own cell apart)."""
    r = range(-width, width + 1)
    return np.array([(x, y, z) for z in r for y in r for x in r if (z, y, x) > (0, 0, 0)], dtype=np.int64)


@njit(**OPTIONS)
def evaluate_block(m, partner, rows, gathered, dipole, prefactor, force, torque, own):
    """The m gathered pairs of one sphere: moments gathered, forces evaluated, partners scattered;
    the sphere's own force and torque summed into own."""
    for u in range(m):
        j = partner[u]
        gathered[3, u + 1] = dipole[j, 0]
        gathered[4, u + 1] = dipole[j, 1]
        gathered[5, u + 1] = dipole[j, 2]
    moments = gathered[3:6].T
    for u in range(m):
        fx, fy, fz, tix, tiy, tiz, tjx, tjy, tjz = dipole_force(0, u + 1, rows[0, u], rows[1, u], rows[2, u],
                                                                rows[3, u], moments, prefactor)
        rows[4, u], rows[5, u], rows[6, u] = fx, fy, fz
        rows[7, u], rows[8, u], rows[9, u] = tjx, tjy, tjz
        own[0] -= fx
        own[1] -= fy
        own[2] -= fz
        own[3] += tix
        own[4] += tiy
        own[5] += tiz
    for u in range(m):
        j = partner[u]
        force[j, 0] += rows[4, u]
        force[j, 1] += rows[5, u]
        force[j, 2] += rows[6, u]
        torque[j, 0] += rows[7, u]
        torque[j, 1] += rows[8, u]
        torque[j, 2] += rows[9, u]


@njit(**OPTIONS)
def cell_walk_forces(position, dipole, start, ncell, length, cutoff2, prefactor, force, torque, shell, partner,
                     rows, gathered, own):
    """Dipole forces and torques of all pairs closer than sqrt(cutoff2), spheres sorted by cell;
    returns the candidates looked at."""
    inverse = 1.0 / length
    candidates = 0
    for c in range(ncell ** 3):
        cz, cy, cx = c % ncell, (c // ncell) % ncell, c // (ncell * ncell)  # bin_particles' numbering
        for i in range(start[c], start[c + 1]):
            xi, yi, zi = position[i, 0], position[i, 1], position[i, 2]
            gathered[3, 0], gathered[4, 0], gathered[5, 0] = dipole[i, 0], dipole[i, 1], dipole[i, 2]
            for a in range(6):
                own[a] = 0.0
            m = 0
            for s in range(shell.shape[0] + 1):
                if s == shell.shape[0]:
                    lo, hi = i + 1, start[c + 1]  # the own cell: later spheres only
                else:
                    other = ((((cx + shell[s, 0]) % ncell) * ncell + (cy + shell[s, 1]) % ncell) * ncell
                             + (cz + shell[s, 2]) % ncell)
                    lo, hi = start[other], start[other + 1]
                candidates += hi - lo
                for j in range(lo, hi):
                    dx = position[j, 0] - xi
                    dy = position[j, 1] - yi
                    dz = position[j, 2] - zi
                    dx -= length * np.rint(dx * inverse)
                    dy -= length * np.rint(dy * inverse)
                    dz -= length * np.rint(dz * inverse)
                    r2 = dx * dx + dy * dy + dz * dz
                    if r2 < cutoff2:
                        partner[m] = j
                        rows[0, m], rows[1, m], rows[2, m], rows[3, m] = dx, dy, dz, r2
                        m += 1
                        if m == BLOCK:
                            evaluate_block(m, partner, rows, gathered, dipole, prefactor, force, torque, own)
                            m = 0
            if m:
                evaluate_block(m, partner, rows, gathered, dipole, prefactor, force, torque, own)
            for a in range(3):
                force[i, a] += own[a]
                torque[i, a] += own[3 + a]
    return candidates


@njit(**OPTIONS)
def all_pairs_forces(position, dipole, length, cutoff2, prefactor, force, torque):
    """The brute-force reference: every pair, minimum image."""
    n = position.shape[0]
    for i in range(n):
        for j in range(i + 1, n):
            dx = position[j, 0] - position[i, 0]
            dy = position[j, 1] - position[i, 1]
            dz = position[j, 2] - position[i, 2]
            dx -= length * np.rint(dx / length)
            dy -= length * np.rint(dy / length)
            dz -= length * np.rint(dz / length)
            r2 = dx * dx + dy * dy + dz * dz
            if r2 < cutoff2:
                fx, fy, fz, tix, tiy, tiz, tjx, tjy, tjz = dipole_force(i, j, dx, dy, dz, r2, dipole, prefactor)
                force[j, 0] += fx
                force[j, 1] += fy
                force[j, 2] += fz
                force[i, 0] -= fx
                force[i, 1] -= fy
                force[i, 2] -= fz
                torque[i, 0] += tix
                torque[i, 1] += tiy
                torque[i, 2] += tiz
                torque[j, 0] += tjx
                torque[j, 1] += tjy
                torque[j, 2] += tjz


def least(function, repeats):
    times = []
    for _ in range(repeats):
        began = time.perf_counter()
        function()
        times.append(time.perf_counter() - began)
    return min(times)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=8000)
    parser.add_argument("--repeats", type=int, default=20)
    opts = parser.parse_args()
    n, cutoff = opts.n, 4.0
    box = dk.build.box_for(n, 0.5, 0.2, periodic=True)  # the reference scene's density
    length = float(box.size[0])
    rng = np.random.default_rng(1)
    position = dk.build.random_packing(n, 0.5, box, seed=rng)
    moment = dk.build.random_directions(n, seed=rng)
    scene = dk.Scene(dk.Particles(position=position, radius=0.5, mass=1.0, dipole=moment),
                     [dk.Dipole(prefactor=1.0, cutoff=cutoff)], box=box, skin=0.3, parallel=False)
    scene.forces()
    listed = scene.neighbour_lists()[0]
    list_force, list_torque = np.zeros_like(scene.arrays["force"]), np.zeros_like(scene.arrays["torque"])

    def with_list():
        scene.kernels.compute_forces(scene.state, list_force, list_torque, False, False)

    from scipy.spatial import cKDTree
    within = len(cKDTree(np.mod(position, length), boxsize=length).query_pairs(cutoff))
    rows = []
    for width in (1, 2):
        ncell = int(length // (cutoff / width))
        order, start = cell_order(position, length, ncell)
        x, m = np.ascontiguousarray(position[order]), np.ascontiguousarray(moment[order])
        force, torque = np.zeros((n, 3)), np.zeros((n, 3))
        work = (half_shell(width), np.zeros(BLOCK, np.int64), np.zeros((10, BLOCK)), np.zeros((6, BLOCK + 1)),
                np.zeros(6))
        candidates = cell_walk_forces(x, m, start, ncell, length, cutoff ** 2, 1.0, force, torque, *work)
        ref_force, ref_torque = np.zeros((n, 3)), np.zeros((n, 3))
        all_pairs_forces(x, m, length, cutoff ** 2, 1.0, ref_force, ref_torque)
        error = max(np.abs(force - ref_force).max() / np.abs(ref_force).max(),
                    np.abs(torque - ref_torque).max() / np.abs(ref_torque).max())
        assert error < 1e-12, error

        def walk():
            force[:] = 0.0
            torque[:] = 0.0
            cell_walk_forces(x, m, start, ncell, length, cutoff ** 2, 1.0, force, torque, *work)

        walk()
        with_list()
        walked, listed_s = [], []
        for _ in range(3):  # alternating
            walked.append(least(walk, opts.repeats))
            listed_s.append(least(with_list, opts.repeats))
        row = {"cell_over_cutoff": 1.0 / width, "cells_per_axis": ncell, "candidates_per_sphere": candidates / n,
               "pairs_within_cutoff_per_sphere": within / n,
               "max_relative_difference_from_all_pairs": error, "cell_walk_seconds": min(walked),
               "stored_list_seconds": min(listed_s), "ratio": min(walked) / min(listed_s)}
        rows.append(row)
        print(json.dumps(row), flush=True)
    result = {"n": n, "cutoff": cutoff, "skin": 0.3, "listed_pairs": listed["pairs"],
              "stored_list_bytes_per_sphere": 4 * listed["capacity"] / n, "rows": rows,
              "measured": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime())}
    (HERE / "results" / "dipole_cells.json").write_text(json.dumps(result, indent=1) + "\n")


if __name__ == "__main__":
    main()
