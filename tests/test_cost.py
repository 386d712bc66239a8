"""The cost model of `demkit info` (demkit.cost): its parts add up as documented, touching pairs are
counted and followed through a run as the module says. (How well it predicts run times is measured
in benchmarks/bench_info.py, not here.)"""
import math

import numpy as np
import pytest

import demkit as dk
from demkit import cost


def test_ramp_mean_is_the_mean_of_the_piecewise_linear_ramp():
    # value t -> start + (end - start) min(t, ramp) / ramp on [0, duration]; mean by the trapezoid rule
    for start, end, ramp, duration in [(0, 100, 10, 15), (5, 50, 10, 4), (3, 9, 0, 7), (2, 2, 5, 5)]:
        t = np.linspace(0.0, duration, 200001)
        value = start + (end - start) * (np.minimum(t, ramp) / ramp if ramp else np.ones_like(t))
        assert cost._ramp_mean(start, end, ramp, duration) == pytest.approx(np.trapezoid(value, t) / duration, rel=1e-6)


def _two_spheres(gap, integrator_steps=1):
    p = dk.Particles(position=[[0, 0, 0], [1.0 + gap, 0, 0], [10, 0, 0]], radius=0.5, mass=1.0)
    return dk.Scene(p, [dk.KelvinVoigt(stiffness=100.0, damping=1.0)])


def test_the_parts_add_up_to_the_step_and_run():
    scene = _two_spheres(-0.01)  # spheres 0 and 1 overlap, sphere 2 is alone
    est = cost.estimate(scene, dk.VelocityVerlet(0.01), duration=1.0)
    assert est.touching == (1, 1.0)
    assert est.parts["touching pairs"] == pytest.approx(cost.TOUCHING[("KelvinVoigt", False)])
    assert est.parts["spheres"] == pytest.approx(3 * cost.SPHERE)
    assert est.per_step == pytest.approx(sum(est.parts.values()) + cost.STEP)
    assert est.stepping == pytest.approx(100 * est.per_step)
    record = 2 * (cost.RECORD_FRAME + 3 * cost.RECORD_SPHERE)  # the first and last frames
    assert est.outputs == pytest.approx(record) and est.total == est.stepping + est.outputs
    rk4 = cost.estimate(scene, dk.RK4(0.01), duration=1.0)  # four force evaluations a step
    assert rk4.per_step == pytest.approx(4 * sum(est.parts.values()) + cost.STEP)
    # outputs: 11 VTK frames and an animation of 5 frames
    out = cost.estimate(scene, dk.VelocityVerlet(0.01), duration=1.0, vtk_every=0.1, animation_frames=5)
    vtk = 11 * (3 * cost.VTK_SPHERE + cost.VTK_FRAME)
    animation = cost.ANIMATION_START + 5 * (cost.ANIMATION_FRAME + 3 * cost.ANIMATION_SPHERE)
    assert out.outputs == pytest.approx(record + vtk + animation)


def test_touching_now_counts_pairs_and_walls():
    p = dk.Particles(position=[[0, 0, 0.4], [0.99, 0, 0.4], [5, 0, 3.0], [5, 3, 0.6]], radius=0.5, mass=1.0)
    scene = dk.Scene(p, [dk.KelvinVoigt(stiffness=100.0), dk.Wall((0, 0, 0), (0, 0, 1))])
    # spheres 0 and 1 touch each other, and both touch the floor; 2 and 3 touch nothing
    assert cost.touching_now(scene) == 3


def test_a_pour_settles_at_the_contacts_of_a_packing_within_its_fall_time():
    n = 50
    pos = np.column_stack([np.zeros(n), np.zeros(n), 1.0 + 2.0 * np.arange(n)])  # a column, top at z = 99
    p = dk.Particles(position=pos, radius=0.5, mass=1.0)
    scene = dk.Scene(p, [dk.Hertz(young=1e4, poisson=0.3, friction=dk.Friction(0.5)), dk.Gravity((0, 0, -2.0)),
                         dk.Wall((0, 0, 0), (0, 0, 1))])
    land = math.sqrt(2 * (99.0 - 0.5) / 2.0)  # the top sphere's fall to its lowest place (z = R)
    long = cost.estimate(scene, dk.VelocityVerlet(1e-3), duration=2 * land)
    settled = cost.SETTLED_CONTACTS * n
    assert long.touching[0] == 0 and long.touching[1] == pytest.approx(settled * 0.75)  # ramp, then settled
    assert "within t = " in long.note
    assert long.parts["touching pairs"] == pytest.approx(0.75 * settled * cost.TOUCHING[("Hertz", True)])
    assert long.later == pytest.approx(long.parts["touching pairs"])  # none touch now
    short = cost.estimate(scene, dk.VelocityVerlet(1e-3), duration=land / 2)
    assert short.touching[1] == pytest.approx(settled / 4)


def test_magnets_gather_into_chains_and_lists_count_their_pairs():
    n = 300
    box = dk.build.box_for(n, 0.5, 0.1)
    pos = dk.build.random_packing(n, 0.5, box, seed=2)
    p = dk.Particles(position=pos, radius=0.5, mass=1.0, dipole=np.tile([1.0, 0, 0], (n, 1)))
    scene = dk.Scene(p, [dk.Dipole(prefactor=1.0, cutoff=3.0), dk.KelvinVoigt(stiffness=1000.0)], box=box, skin=0.2)
    est = cost.estimate(scene, dk.VelocityVerlet(1e-3), duration=1.0)
    assert est.note == "magnets gathering into chains"
    assert est.touching[1] == pytest.approx(0.5 * (est.touching[0] + cost.CHAINED_CONTACTS * n))
    pairs = {group.members[0][1].__class__.__name__: count for group, _, count in cost.pair_counts(scene)}
    sep = pos[:, None] - pos[None]
    sep -= box.size * np.round(sep / box.size)  # minimum image
    d = np.linalg.norm(sep, axis=-1)[np.triu_indices(n, 1)]
    assert pairs == {"Dipole": int(np.sum(d < 3.2)), "KelvinVoigt": int(np.sum(d < 1.2))}
    assert est.parts["listed dipole pairs"] == pytest.approx(pairs["Dipole"] * cost.DIPOLE_PAIR)
    assert est.parts["listed pairs"] == pytest.approx(pairs["KelvinVoigt"] * cost.LISTED_PAIR)


def test_a_plug_in_contact_law_is_priced_as_a_hertz_law():
    from numba import njit

    @njit
    def soft_force(i, j, dx, dy, dz, r2, stiffness):
        return 0.0, 0.0, 0.0

    @njit
    def soft_energy(i, j, dx, dy, dz, r2, stiffness):
        return 0.0

    class Soft(dk.PairInteraction):  # a contact law of a user's, without the built-in laws' friction
        contact_reach = True
        energy_kind = "contact"
        parameters = ("stiffness",)
        force_function, energy_function = soft_force, soft_energy

        def __init__(self):
            self.stiffness = 1.0

    scene = dk.Scene(_two_spheres(-0.01).particles, [Soft()])
    est = cost.estimate(scene, dk.VelocityVerlet(0.01), duration=1.0)
    assert est.parts["touching pairs"] == pytest.approx(cost.TOUCHING[("Hertz", False)])


def _walled_box(side):
    return [dk.Wall((0, 0, 0), (0, 0, 1)), dk.Wall((0, 0, 0), (1, 0, 0)), dk.Wall((0, 0, 0), (0, 1, 0)),
            dk.Wall((side, side, 0), (-1, 0, 0)), dk.Wall((side, side, 0), (0, -1, 0))]


def _pour(position, side, susceptibility=None):
    extra = {"dipole": np.tile([0.0, 0.0, 1.0], (len(position), 1))} if susceptibility is None else \
        {"susceptibility": susceptibility}
    p = dk.Particles(position=position, radius=0.5, mass=1.0, **extra)
    interactions = [dk.Dipole(prefactor=1.0, cutoff=3.0, switch_width=0.5), dk.Hertz(young=2e4, poisson=0.3),
                    dk.Gravity((0, 0, -1.0)), *_walled_box(side)]
    if susceptibility is not None:
        interactions.append(dk.UniformField((0, 0, 0.05)))
    return dk.Scene(p, interactions, skin=0.3)


def _long_reach(group):
    return not all(inter.contact_reach for _, inter in group.members)


def test_a_settled_pile_counts_the_pairs_a_pile_at_rest_has():
    # a pile already at rest on the floor of an 8 x 8 box (300 spheres on a lattice of spacing 1.02,
    # volume fraction 0.49): the dipoles' listed pairs of the model's pile (spread evenly at
    # SETTLED_FRACTION) are those it has, to 20 % (a pile's structure matters little at 6 radii)
    side, n = 8.0, 300
    g = 0.51 + 1.02 * np.arange(7)
    lattice = np.stack(np.meshgrid(g, g, 0.51 + 1.02 * np.arange(7), indexing="ij"), -1).reshape(-1, 3)
    pile = lattice[np.argsort(lattice[:, 2], kind="stable")][:n]
    scene = _pour(pile, side)
    heights, _, _ = dk.guards.fall_heights(scene)
    settled = dict(cost.settled_pairs(scene, heights))
    dipoles = next((group, now) for group, _, now in cost.pair_counts(scene) if _long_reach(group))
    assert settled[id(dipoles[0])] == pytest.approx(dipoles[1], rel=0.2)
    # ... and the same spheres dropped from up to 24 high settle into about as many, far more than now
    high = dk.build.random_packing(n, 0.5, dk.Box((side - 1.0, side - 1.0, 24.0)), seed=4) + 0.5
    dropped = _pour(high, side)
    heights, _, _ = dk.guards.fall_heights(dropped)
    settled_dropped = dict(cost.settled_pairs(dropped, heights))
    group, now = next((group, now) for group, _, now in cost.pair_counts(dropped) if _long_reach(group))
    assert settled_dropped[id(group)] == pytest.approx(dipoles[1], rel=0.2)
    assert settled_dropped[id(group)] > 2.5 * now


def test_a_pour_of_magnetisable_spheres_follows_its_lists_and_solve_as_they_settle():
    side, n = 8.0, 300
    high = dk.build.random_packing(n, 0.5, dk.Box((side - 1.0, side - 1.0, 24.0)), seed=4) + 0.5
    scene = _pour(high, side, susceptibility=20.0)
    heights, g, _ = dk.guards.fall_heights(scene)
    land = math.sqrt(2.0 * float(heights.max()) / g)
    counts = cost.pair_counts(scene)
    settled = dict(cost.settled_pairs(scene, heights))
    dipoles = next((group, now) for group, _, now in counts if not group.members[0][1].contact_reach)
    est = cost.estimate(scene, dk.VelocityVerlet(1e-3), duration=2 * land)
    ramped = cost._ramp_mean(dipoles[1], settled[id(dipoles[0])], land, 2 * land)
    assert est.parts["listed dipole pairs"] == pytest.approx(ramped * cost.DIPOLE_PAIR)
    solve_now = cost._induction_seconds(scene, counts, 0.0)
    solve_settled = cost._induction_seconds(scene, counts, 0.0, settled)
    assert solve_settled > 3 * solve_now  # more pairs in the field, more iterations once piled up
    assert est.parts["induction solve"] == pytest.approx(cost._ramp_mean(solve_now, solve_settled, land, 2 * land))
    # what a timing of the first steps misses: the touching pairs, the lists and the solve growing
    growth = (est.parts["listed dipole pairs"] - dipoles[1] * cost.DIPOLE_PAIR
              + est.parts["induction solve"] - solve_now)
    touching = est.parts["touching pairs"] - est.touching[0] * cost.TOUCHING[("Hertz", False)]
    assert est.later == pytest.approx(touching + growth)
    assert "listed pairs of the settling pile (with the solve of the induced moments)" in est.later_what


def test_the_compile_notice_counts_the_induction_solve_when_it_is_not_cached(monkeypatch):
    from demkit.engine import notice
    p = dk.Particles(position=[[0, 0, 0], [2.0, 0, 0]], radius=0.5, mass=1.0, susceptibility=5.0)
    scene = dk.Scene(p, [dk.Dipole(prefactor=1.0), dk.UniformField((0, 0, 1.0))])
    monkeypatch.setattr(notice, "induction_cached", lambda: False)
    text = notice.compile_estimate(scene.plan, "scene", tier=2)
    lo, hi = notice.ESTIMATES["small"]
    extra = notice.ESTIMATES["induction"]
    assert f"about {lo + extra}-{hi + extra} s" in text and "induced moments" in text
    monkeypatch.setattr(notice, "induction_cached", lambda: True)
    assert notice.compile_estimate(scene.plan, "scene", tier=2) == f"about {lo}-{hi} s on an idle machine"
