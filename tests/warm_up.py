"""Tier 1 compiled by the suite's workers side by side, before their first test.

On empty caches the suite compiles demkit's generic module (tier 1: ~190 CPU s, once per install) as its
tests first need each function. Whichever worker needs a function first compiles it while the other, if
it needs it too, waits for it (demkit.engine.numba_cache's lock): measured, a worker stood ~30 s waiting in
one test, and the compiles came in the long tests' middle. Here each worker of ``pytest -n N`` compiles
its share of the pieces the suite uses, chosen so that the shares hardly overlap, by stepping tiny scenes
of each kind; with a warm cache this loads them (a few seconds). Anything missed compiles when a test
first needs it, as before. Nothing is asserted: the tests check what these scenes run.
"""
from __future__ import annotations

import os

import numpy as np

import demkit as dk


def _frictional_law():
    return dk.KelvinVoigt(1000.0, 1.0, friction=dk.Friction(0.5), rolling=dk.RollingResistance(0.05),
                          twisting=dk.TwistingResistance())


def _open_pair(law, effects=()):
    p = dk.Particles(position=[[0.0, 0.0, 0.6], [1.02, 0.0, 0.6]], velocity=[[0.1, 0, 0], [-0.1, 0, 0]],
                     radius=0.5, mass=1.0, dipole=[[0, 0, 0.1], [0, 0, 0.1]])
    return dk.Scene(p, [dk.Dipole(0.01), law, *effects], tier=1)


def _gas(n=64, parallel=False, sort_every=None, law=None, dipole=None):
    box = dk.build.box_for(n, 0.5, 0.2)
    rng = np.random.default_rng(1)
    p = dk.Particles(position=dk.build.random_packing(n, 0.5, box, seed=1), velocity=rng.normal(size=(n, 3)),
                     radius=0.5, mass=1.0, dipole=np.tile([0.0, 0.0, 1.0], (n, 1)))
    return dk.Scene(p, [dipole or dk.Dipole(0.01, cutoff=2.0), law or dk.KelvinVoigt(1000.0, 1.0)], box=box,
                    tier=1, parallel=parallel, sort_every=sort_every)


def _step(scene, integrator, steps=2, diagnostics=True):
    sim = dk.Simulation(scene, integrator)
    sim.run(steps * integrator.dt, progress=False)
    if diagnostics:
        scene.energy()
        scene.forces()


def open_space():
    """The full family of pieces and the time loops of every integrator, in open space."""
    def full():
        walls = [dk.Wall((0, 0, 0), (0, 0, 1)), dk.Wall((0, 0, 1.5), (0, 0, -1), amplitude=(0, 0, 0.01), frequency=2.0)]
        return _open_pair(_frictional_law(), [dk.Gravity((0, 0, -1.0)), dk.UniformField((0, 0.1, 0)), *walls])
    _step(full(), dk.VelocityVerlet(1e-3))
    for integrator in (dk.EulerCromer(1e-3), dk.MultipleTimeStep(1e-3, inner=2)):
        _step(full(), integrator, diagnostics=False)
    plain = _open_pair(dk.KelvinVoigt(1000.0, 1.0))  # the plain family (the paper's scene)
    _step(plain, dk.EulerCromer(1e-3))
    for integrator in (dk.RK4(1e-3), dk.ForestRuth(1e-3), dk.VelocityVerlet(1e-3, resolve_contacts=True),
                       dk.MultipleTimeStep(1e-3, inner=2, resolve_contacts=True)):
        _step(_open_pair(dk.KelvinVoigt(1000.0, 1.0)), integrator, diagnostics=False)


def induced():
    """Magnetisable spheres: the induced moments solved in compiled code."""
    p = dk.Particles(position=[[0, 0, 0], [0, 0, 1.05]], radius=0.5, mass=1.0, susceptibility=3.0)
    _step(dk.Scene(p, [dk.Dipole(1.0), dk.KelvinVoigt(1000.0, 1.0), dk.UniformField((0, 0, 0.5))], tier=1),
          dk.VelocityVerlet(1e-3))


def lists():
    """Neighbour lists, blocked dipole loops and sorting, serial."""
    _step(_gas(sort_every=1, law=_frictional_law()), dk.VelocityVerlet(1e-3))


def threads():
    """The same on threads."""
    _step(_gas(parallel=True, sort_every=1, law=_frictional_law()), dk.VelocityVerlet(1e-3))


def long_range():
    """Ewald and P3M sums."""
    for method in (dk.Ewald, dk.P3M):
        _step(_gas(n=27, dipole=dk.Dipole(0.01, long_range=method(1e-3))), dk.VelocityVerlet(1e-3))


#: the shares, with their cost in CPU s on empty caches (measured on this 2-core machine), from the largest
TASKS = ((open_space, 85.0), (lists, 40.0), (threads, 30.0), (long_range, 20.0), (induced, 12.0))


def share(worker, workers):
    """The tasks of worker ``worker`` of ``workers``: the largest first to the least loaded."""
    loads, shares = [0.0] * workers, [[] for _ in range(workers)]
    for task, cost in TASKS:
        k = loads.index(min(loads))
        loads[k] += cost
        shares[k].append(task)
    return shares[worker]


def warm_up():
    """Run this worker's share, when the suite runs on two workers or more (``pytest -n N``)."""
    worker, workers = os.environ.get("PYTEST_XDIST_WORKER", ""), int(os.environ.get("PYTEST_XDIST_WORKER_COUNT", "1"))
    if workers < 2 or not worker.startswith("gw"):
        return
    for task in share(int(worker[2:]), workers):
        task()
