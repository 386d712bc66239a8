"""Scenes for the restart and interruption tests (imported by tests and by their child processes).

A periodic box of magnetic spheres with thermal motion, so that within a short run spheres collide
(contact history when ``friction``), cross the box faces (image counts), and the neighbour lists
are rebuilt and, with ``sort_every``, the spheres re-sorted (internal order != user order).
"""
import numpy as np

import demkit as dk


def gas(n=120, friction=True, parallel=None, sort_every=40, seed=3, walls=False, long_range=None):
    rng = np.random.default_rng(seed)
    radius = 0.5
    box = dk.build.box_for(n, radius, 0.25, periodic=(True, True, not walls))
    x = dk.build.random_packing(n, radius, box, seed=rng)
    v = dk.build.thermal_velocities(n, 4.0, 1.0, seed=rng)
    mu = 0.7 * dk.build.random_directions(n, seed=rng)
    p = dk.Particles(position=x, velocity=v, radius=radius, mass=1.0, dipole=mu,
                     angular_velocity=np.zeros((n, 3)))
    contact = dk.KelvinVoigt(2000.0, 3.0, friction=dk.Friction(0.4) if friction else None)
    # (a long-range sum: the settings object, its real-space cutoff 3.0)
    interactions = [dk.Dipole(prefactor=1.0, cutoff=3.0, long_range=long_range), contact]
    if walls:
        side = float(box.size[2])
        interactions += [dk.Wall((0, 0, 0), (0, 0, 1)), dk.Wall((0, 0, side), (0, 0, -1)), dk.Gravity((0, 0, -1.0))]
    return dk.Scene(p, interactions, box=box, parallel=parallel, sort_every=sort_every)


def state_of(scene):
    """Everything that must agree bit for bit between an interrupted and an uninterrupted run."""
    p = scene.particles
    out = {"position": p.position.copy(), "velocity": p.velocity.copy(),
           "angular_velocity": p.angular_velocity.copy(), "dipole": p.dipole.copy() if p.dipole is not None else None,
           "image": p.image.copy() if p.image is not None else None, "dissipated": scene.dissipated}
    for inter in scene.history_keepers():
        if inter in scene.effects:
            out[f"sphere history {inter!r}"] = scene.sphere_history(inter)
            continue
        pairs, values = scene.history(inter)
        order = np.lexsort((pairs[:, 1], pairs[:, 0]))
        out[f"history {inter!r}"] = (pairs[order], values[order])
    return out


def assert_identical(a, b):
    assert a.keys() == b.keys()
    for key in a:
        x, y = a[key], b[key]
        if isinstance(x, tuple):
            for u, w in zip(x, y):
                assert np.array_equal(u, w), key
        elif x is None:
            assert y is None, key
        else:
            assert np.array_equal(np.asarray(x), np.asarray(y)), f"{key} differs"


def assert_dipole_pairs_by_brute_force(scene, cutoff):
    """The pairs the scene's first pair loop (a Dipole's) acts on are exactly those within ``cutoff`` by
    brute force over all pairs with dk.Box.minimum_image at the scene's time (1e-9 of the cutoff left for
    rounding at the edge), their separations the brute force's to round-off (1e-9)."""
    n = len(scene.particles)
    i, j = np.triu_indices(n, k=1)
    x, t = scene.particles.position, scene.time
    d = scene.box.minimum_image(x[j] - x[i], t)
    r = np.linalg.norm(d, axis=1)
    inter, pairs, sep, _ = scene.pair_forces()[0]
    assert isinstance(inter, dk.Dipole)
    listed = {(min(a, b), max(a, b)): (s if a < b else -s) for (a, b), s in zip(pairs.tolist(), sep)}
    inside = {(a, b) for a, b, q in zip(i.tolist(), j.tolist(), r) if q < cutoff - 1e-9}
    near = {(a, b) for a, b, q in zip(i.tolist(), j.tolist(), r) if q < cutoff + 1e-9}
    assert inside <= set(listed) <= near
    truth = dict(zip(zip(i.tolist(), j.tolist()), d))
    assert max(np.abs(listed[key] - truth[key]).max() for key in listed) < 1e-9
