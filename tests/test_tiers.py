"""The two tiers of compiled code (demkit.engine.tiers): the generic module (tier 1) and a scene's own code
(tier 2: its fused module in open space and on threads, its own pair and sphere loops called by the
generic time loops with neighbour lists) give byte-equal trajectories and energies (and diagnostics,
which tier 2 computes only for functions of your own), and a run that switches from one to the other in its middle gives the same bits as either. The scenes
are chosen to cover every shipped pair law and effect, every integrator, open and periodic boxes,
lists and all pairs, blocked dipole loops, sorting, chunks on threads and multiple time stepping,
with few tier-2 modules (each costs seconds to compile; the generic module is shared by the whole
suite)."""
from types import SimpleNamespace

import numpy as np
import pytest

import demkit as dk
from demkit.engine import catalogue, generic_modules
from demkit.engine import program as layout


@pytest.fixture(autouse=True)
def automatic_tier(monkeypatch):
    """Scenes here choose their tier themselves (the suite's conftest sets DEMKIT_TIER=1)."""
    monkeypatch.delenv("DEMKIT_TIER", raising=False)


def small_scene(tier):
    """Six spheres in open space (all pairs, no lists) above a vibrated floor, under a servo-controlled
    lid, between walls and inside a turning, shaken cylinder: Kelvin-Voigt contacts with friction,
    rolling and twisting resistance, a switched dipole, gravity and a field."""
    rng = np.random.default_rng(4)
    pos = np.array([[0.0, 0.0, 0.6], [1.05, 0.1, 0.62], [0.1, 1.02, 0.7], [1.1, 1.1, 0.8], [0.5, 0.5, 1.5],
                    [1.6, 0.4, 1.4]])
    d = rng.normal(size=(6, 3))
    p = dk.Particles(position=pos, velocity=0.3 * rng.normal(size=(6, 3)), radius=0.5, mass=1.0,
                     angular_velocity=rng.normal(size=(6, 3)), dipole=0.3 * d / np.linalg.norm(d, axis=1)[:, None])
    law = dk.KelvinVoigt(3000.0, 4.0, friction=dk.Friction(0.4), rolling=dk.RollingResistance(0.05),
                         twisting=dk.TwistingResistance())
    walls = [dk.Wall((0, 0, 0), (0, 0, 1), amplitude=(0, 0, 0.01), frequency=3.0), dk.Wall((-0.5, -0.5, 0), (1, 0, 0)),
             dk.Wall((2.2, 2.2, 0), (-1, 0, 0)),
             dk.Cylinder((0.8, 0.8, 0.0), (0, 0, 1), 1.62, angular_velocity=0.5,  # (pressing the first sphere)
                         contact=dk.KelvinVoigt(3000.0, 4.0, friction=dk.Friction(0.4)), amplitude=(0.01, 0.0, 0.0),
                         frequency=2.0),
             dk.Wall((0, 0, 2.01), (0, 0, -1), servo=dk.Servo(force=0.5, max_speed=0.5))]  # (a lid coming down)
    return dk.Scene(p, [dk.Dipole(prefactor=0.05, cutoff=2.5, switch_width=0.5), law, dk.Gravity((0, 0, -1.0)),
                        dk.UniformField((0.0, 0.05, 0.02)), *walls], tier=tier)


def gas(tier, n=240, parallel=False, sort_every=None, power_law=False, kelvin_voigt=False, cutoff=3.0, deform=None):
    """A periodic frictional magnetic gas: neighbour lists, blocked dipole loops (in a box deforming by
    ``deform``, a dk.Deform)."""
    R = 0.5
    box = dk.build.box_for(n, R, 0.25)
    box = dk.Box(box.size, periodic=True, deform=deform) if deform is not None else box
    pos = dk.build.random_packing(n, R, box, seed=1)
    rng = np.random.default_rng(2)
    d = rng.normal(size=(n, 3))
    p = dk.Particles(position=pos, velocity=rng.normal(size=(n, 3)), radius=R, mass=1.0,
                     dipole=d / np.linalg.norm(d, axis=1)[:, None])
    law = (dk.KelvinVoigt(2000.0, 3.0) if kelvin_voigt else
           dk.Hertz(young=2e4, poisson=0.3, restitution=0.5, friction=dk.Friction(0.5),
                    rolling=dk.RollingResistance(0.02)))
    dipole = dk.PowerLawDipole(prefactor=1.0, cutoff=cutoff, switch_width=1.0) if power_law else \
        dk.Dipole(prefactor=1.0, cutoff=cutoff)
    return dk.Scene(p, [dipole, law], box=box, tier=tier, parallel=parallel, sort_every=sort_every)


def outcome(scene, integrator, duration, switch=False, diagnostics=False):
    """Everything a run records (and with ``diagnostics`` the forces, per-pair energies and forces
    after it), as one array of bits. Diagnostics run on tier 1 whenever it can run the scene (tier 2
    compiles time loops only), so they differ between tiers only with functions of your own; the
    trajectory itself depends on every force of every step."""
    sim = dk.Simulation(scene, integrator)
    if switch:  # compile tier 2 at once, switch when ready (here: at once, the module is in memory)
        sim._tiers._worth = lambda: 0.0
    traj = sim.run(duration=duration, record_every=duration / 4, progress=False)
    energies = np.stack(list(traj.energy.values())[:-1]) if isinstance(traj.energy, dict) else traj.energy
    parts = [traj.position, traj.velocity, np.asarray(energies, dtype=float)]
    if traj.angular_velocity is not None:
        parts.append(traj.angular_velocity)
    if diagnostics:
        force, torque = scene.forces()
        parts += [force, torque, scene.pair_energies()[1]]
        parts += [f for *_, f in scene.pair_forces()]
    return sim, np.concatenate([np.ravel(a) for a in parts])


def assert_same_bits(a, b):
    assert a.shape == b.shape
    assert a.tobytes() == b.tobytes(), f"{np.sum(a != b)} of {a.size} values differ between the tiers"


def same_bits(make, integrator, duration, diagnostics=False):
    """The run of make(1) and of make(2) give the same bits; returns their two Simulations."""
    # tier 2 first: a worker opening the suite on this test compiles the scene's own code while the
    # other compiles the generic module (tests/conftest.py's SECOND_HALF_OPENS)
    second, b = outcome(make(2), integrator, duration, diagnostics=diagnostics)
    first, a = outcome(make(1), integrator, duration, diagnostics=diagnostics)
    assert_same_bits(a, b)
    return first, second


def test_small_scene_with_multiple_time_steps_same_bits():
    """Kelvin-Voigt contacts with friction, rolling and twisting resistance, a switched dipole, walls,
    gravity and a field, in open space, stepped by multiple time stepping: its time loop calls every
    force of the scene, split into fast and slow (each time loop of a fused module compiles for 20-30
    CPU s, so this scene runs one; velocity Verlet's loop runs the scenes with lists below)."""
    same_bits(small_scene, dk.MultipleTimeStep(4e-4, inner=2), 0.05)


def frictionless_gas(tier, **options):
    """The gas with Kelvin-Voigt contacts and dipoles of the contacts' reach (one pair loop): the tier-2
    pieces of every test of a periodic gas here (one module compiled; each costs seconds). Frictional
    history over periodic lists on tier 2 is the sheared gas's (tests/test_shear.py), the walled pour's
    and the threaded scene's of functions of your own (below)."""
    return gas(tier, kelvin_voigt=True, cutoff=1.0, **options)


@pytest.mark.parametrize("integrator", [dk.VelocityVerlet(1e-3), dk.RK4(1e-3), dk.ForestRuth(1e-3),
                                        dk.VelocityVerlet(1e-3, resolve_contacts=True), dk.EulerCromer(1e-3)],
                         ids=["verlet", "rk4", "forest_ruth", "contact_events", "euler_cromer"])
def test_periodic_gas_same_bits(integrator):
    # every integrator's time loop over the scene's own pieces (contact events need frictionless contacts)
    same_bits(frictionless_gas, integrator, 0.2)


def test_a_deforming_box_same_bits():
    """The gas compressed along x and drawn out along y (the box and positions remapped after each step
    by end_step, the lists rebuilt as the remap squeezes the skin): tier 2's pieces are the fixed box's
    (the deformation is data: params and the program), the same bits as tier 1."""
    make = (lambda tier: frictionless_gas(tier, deform=dk.Deform(x=-0.4, y=0.25)))
    same_bits(make, dk.VelocityVerlet(1e-3), 0.2)
    assert make(1).program[0, layout.H_DEFORM] >= 0


def test_multiple_time_steps_with_lists_same_bits():
    """Multiple time stepping over neighbour lists: a slow dipole and a fast contact law of the same
    reach share a pair loop, run as a fast and a slow loop (on tier 2: two pair loops of the scene's
    own pieces, picked by the program row's speed)."""
    scene = frictionless_gas(1)
    assert len(scene.plan.groups) == 1 and scene.program[layout.group_row(0, 1), layout.G_COUNT] == 1
    same_bits(frictionless_gas, dk.MultipleTimeStep(2e-3, inner=2), 0.2)


def walled_pour(tier, n=72):
    """Spheres falling in a box of five walls (one a piston) with rounded corners (a cylinder) in open space: Hertz
    contacts with friction and twisting resistance over neighbour lists, dipoles at every range over
    all pairs, one sphere in four magnetisable (the induced moments solved before the forces of every
    step), gravity, a field and a Langevin bath (tier 2: the scene's own pieces under the generic loops, its sphere loop a switch
    over its effects' kinds; with induced moments an open scene gets pieces, not a fused module)."""
    k = np.arange(n)
    rng = np.random.default_rng(6)
    pos = np.stack([0.75 + 1.25 * (k % 4), 0.75 + 1.25 * ((k // 4) % 4), 1.0 + 1.25 * (k // 16)], axis=1)
    p = dk.Particles(position=pos + rng.uniform(-0.1, 0.1, (n, 3)), velocity=rng.normal(size=(n, 3)), radius=0.5,
                     mass=1.0, dipole=0.1 * rng.normal(size=(n, 3)), susceptibility=np.where(k % 4 == 1, 2.0, 0.0))
    law = dk.Hertz(young=2e4, poisson=0.3, restitution=0.5, friction=dk.Friction(0.5), twisting=dk.TwistingResistance())
    walls = [dk.Wall((0, 0, 0), (0, 0, 1)), dk.Wall((0, 0, 0), (1, 0, 0)), dk.Wall((0, 0, 0), (0, 1, 0)),
             dk.Wall((5.5, 5.5, 0), (-1, 0, 0), velocity=(-0.2, 0.0, 0.0)),  # (a piston)
             dk.Wall((5.5, 5.5, 0), (0, -1, 0)),
             dk.Cylinder((2.75, 2.75, 0.0), (0, 0, 1), 3.3)]  # (rounding the box's corners)
    effects = [dk.Gravity((0, 0, -1.0)), dk.UniformField((0, 0.1, 0.3)), dk.Langevin(drag=0.5, temperature=0.01, seed=4)]
    return dk.Scene(p, [dk.Dipole(prefactor=0.02), law, *effects, *walls], skin=0.4, tier=tier)


def test_walled_pour_with_lists_all_pairs_and_induced_moments_same_bits():
    scene = walled_pour(1)
    assert scene.plan.growing and scene.induction is not None and len(scene.plan.groups) == 2
    assert walled_pour(2).loop_kernels.pieces.__name__.startswith("demkit_pieces_")
    same_bits(walled_pour, dk.VelocityVerlet(1e-3), 0.3)


def long_range_gas(tier, method):
    """Dipoles summed by Ewald or P3M in a periodic box with Hooke contacts."""
    n, R = 64, 0.5
    box = dk.build.box_for(n, R, 0.1)
    rng = np.random.default_rng(5)
    d = rng.normal(size=(n, 3))
    p = dk.Particles(position=dk.build.random_packing(n, R, box, seed=2), velocity=0.1 * rng.normal(size=(n, 3)),
                     radius=R, mass=1.0, dipole=d / np.linalg.norm(d, axis=1)[:, None])
    return dk.Scene(p, [dk.Dipole(prefactor=0.1, long_range=method(1e-4)), dk.KelvinVoigt(2000.0, 2.0)], box=box,
                    tier=tier)


def test_long_range_sum_same_bits():
    """An Ewald sum (P3M and FMM are called the same way, from the same switch)."""
    same_bits(lambda tier: long_range_gas(tier, dk.Ewald), dk.VelocityVerlet(1e-3), 0.05)


def test_switch_in_the_middle_same_bits():
    """A run that starts on tier 1 and switches to tier 2 when it is ready ends with the same bits."""
    plain = outcome(frictionless_gas(1), dk.VelocityVerlet(1e-3), 2.0)[1]
    outcome(frictionless_gas(2), dk.VelocityVerlet(1e-3), 0.01)  # tier 2 compiled in this process
    sim, switched = outcome(frictionless_gas(None), dk.VelocityVerlet(1e-3), 2.0, switch=True)
    assert sim.statistics["tier"] == 2 and 0 < sim.statistics["tier_switch_step"] < 2000
    assert switched.tobytes() == plain.tobytes()


def test_functions_of_your_own_run_on_tier_1_through_adapters_with_the_catalogues_bits():
    """A scene with pair and single-sphere functions of your own is described by the program (their
    kind: catalogue.OWN): tier 1 calls them through the scene's adapters (demkit.engine.own_laws, all it
    compiles), tier 2 runs its own pieces under the generic time loops; both give the bits of the
    shipped laws behind them on tier 1."""
    from numba.core import event
    from plugin_interactions import OwnGravity, OwnKelvinVoigt

    def make(own, tier=None):
        rng = np.random.default_rng(7)
        pos = np.array([[0.0, 0.0, 0.6], [1.05, 0.1, 0.62], [0.1, 1.02, 0.7], [1.1, 1.1, 0.8], [0.5, 0.5, 1.5]])
        p = dk.Particles(position=pos, velocity=0.3 * rng.normal(size=(5, 3)), radius=0.5, mass=1.0,
                         dipole=0.2 * rng.normal(size=(5, 3)))
        contact, gravity = (OwnKelvinVoigt, OwnGravity) if own else (dk.KelvinVoigt, dk.Gravity)
        return dk.Scene(p, [dk.Dipole(prefactor=0.05), contact(3000.0, 4.0), gravity((0, 0, -1.0)),
                            dk.Wall((0, 0, 0), (0, 0, 1))], tier=tier)

    for integrator in (dk.VelocityVerlet(2e-4), dk.RK4(2e-4)):
        expected = outcome(make(False), integrator, 0.05, diagnostics=True)[1]

        class Compiled(event.Listener):  # the modules of the functions compiled at the top level
            modules, depth = set(), 0

            def on_start(self, ev):
                self.depth += 1

            def on_end(self, ev):
                self.depth -= 1
                if self.depth == 0:
                    self.modules.add(ev.data["dispatcher"].py_func.__module__.split("_")[1])

        compiled = Compiled()
        event.register("numba:compile", compiled)
        try:
            own = make(True)
            a = outcome(own, integrator, 0.05, diagnostics=True)[1]
        finally:
            event.unregister("numba:compile", compiled)
        assert own.tier == 1 and own.program_refusal is None
        assert compiled.modules <= {"own"}, compiled.modules  # the adapters alone (if not cached)
        row = own.program[layout.group_row(0, 0)]
        assert row[layout.G_MEMBERS + layout.M_COLUMNS + layout.M_KIND] == catalogue.OWN
        assert own.program[layout.effect_row(0), layout.E_KIND] == catalogue.OWN
        second = make(True, tier=2)
        assert second.loop_kernels.pieces.__name__.startswith("demkit_pieces_")  # no fused module
        b = outcome(second, integrator, 0.05, diagnostics=True)[1]
        for got in (a, b):
            assert got.tobytes() == expected.tobytes(), f"{np.sum(got != expected)} of {got.size} values differ"


def test_functions_of_your_own_with_history_over_lists_on_threads_same_bits():
    """A pair function of your own with per-contact history (a touch counter) beside the gas's
    frictional Hertz contacts and switched power-law dipoles, and a single-sphere function of your
    own, over neighbour lists re-sorted by cell, in chunks on numba's threads (parallel=True): tier 1
    (the adapters, called inside the threads' chunks) and tier 2 (the scene's own pieces) give the
    same bits, history and diagnostics included."""
    from plugin_interactions import PullSmall, TouchCounter

    def make(tier):
        scene = gas(tier, n=240, parallel=True, sort_every=20, power_law=True)
        counter = TouchCounter(cutoff=1.0)
        return dk.Scene(scene.particles, [*scene.interactions, counter, PullSmall(0.6, (0.0, 0.0, -0.5))],
                        box=scene.box, tier=tier, parallel=True, sort_every=20), counter

    first, counter = make(1)
    assert first.tier == 1 and "own_pair_forces" in generic_modules.needs_of(first.program)
    a = outcome(first, dk.VelocityVerlet(1e-3), 0.1, diagnostics=True)[1]
    second, counter_2 = make(2)
    b = outcome(second, dk.VelocityVerlet(1e-3), 0.1, diagnostics=True)[1]
    assert_same_bits(a, b)
    touches = first.history(counter)[1]
    assert touches.max() > 0 and touches.tobytes() == second.history(counter_2)[1].tobytes()


def test_tier_choice_and_refusals(monkeypatch):
    from demkit.engine import tiers
    monkeypatch.setattr(tiers, "_READY", set())  # as in a process that has not run this combination
    monkeypatch.setattr(tiers, "_SPENT", {})
    scene = gas(None)
    assert scene.tier == 1 and scene.kernels.tier == 1
    # tier 2 of a scene with lists: the generic time loops calling the scene's own pieces
    second = frictionless_gas(2)
    assert second.loop_kernels.tier == 2 and second.loop_kernels.pieces.__name__.startswith("demkit_pieces_")
    # ... whose diagnostics run on tier 1 (nothing of tier 2 compiled for them), open or with lists
    for second in (second, small_scene(2)):
        assert second.tier == 2 and second.kernels.tier == 1 and second.loop_kernels is not second.kernels
    sim = dk.Simulation(scene, dk.VelocityVerlet(1e-3))
    sim.run(duration=0.01, progress=False)
    assert sim.statistics["tier"] == 1 and sim.statistics["tier_switch_step"] is None  # too short to compile
    assert "generic" in sim.statistics["tier_reason"]
    with pytest.raises(ValueError, match="tier must be"):
        gas(3)
    from plugin_interactions import ContactCounter, Poison
    p = dk.Particles(position=[[0, 0, 0], [3, 0, 0]], radius=0.5, mass=1.0)
    assert dk.Scene(p, [ContactCounter()]).tier == 1  # your own pair functions: tier 1, through adapters

    class BranchFree(Poison):  # evaluated in blocks of 64 pairs over neighbour lists: no adapter there
        branch_free = True
        cutoff_distance = 1.0

    box = dk.Box(10.0, periodic=True)
    assert dk.Scene(p, [BranchFree(0.1)], box=box).tier == 2
    with pytest.raises(ValueError, match="BranchFree.*blocked"):
        dk.Scene(p, [BranchFree(0.1)], box=box, tier=1)


def test_program_layout():
    """The program holds what the fused module hard-codes: kinds, slots, offsets, flags."""
    scene = small_scene(1)
    program = scene.program
    laws, effects = catalogue.catalogue()
    row = program[layout.group_row(0, 0)]
    assert row[layout.G_COUNT] == 2 and row[layout.G_LIST] == 0 and row[layout.G_TORQUE] == 1
    kinds = [laws[row[layout.G_MEMBERS + layout.M_COLUMNS * m + layout.M_KIND]].force_name for m in range(2)]
    assert kinds == ["switched_dipole_force", "kelvin_voigt_twisting_force"]
    fast = program[layout.group_row(0, 1)]
    assert fast[layout.G_COUNT] == 1  # the contact law alone (the dipole is slow)
    assert program[0, layout.H_EFFECTS] == 7
    names = [effects[program[layout.effect_row(e), layout.E_KIND]].force_name for e in range(6)]
    assert names[:2] == ["gravity_force", "field_torque"] and names[2].startswith("wall_kelvin_voigt_twisting")
    # the cylinder (friction without twisting): a wall kind, with its geometry block, run as the twisting law
    assert names[5] == "wall_kelvin_voigt_twisting_force"
    assert scene.effects[5].force_function.__name__ == "wall_kelvin_voigt_friction_force"
    geometry = [program[layout.effect_row(e), layout.E_GEOMETRY] for e in range(6)]
    # the vibrated floor (shape 0 and its motion: 8 numbers), the cylinder (18: its Hertz flag last) and the lid (shape 2, the
    # motion, the servo with its count of target points: 17) have blocks
    geometry.append(program[layout.effect_row(6), layout.E_GEOMETRY])
    assert geometry[:2] == [-1] * 2 and geometry[3:5] == [-1] * 2
    for e, size in ((2, 8), (5, 18), (6, 17)):
        assert np.array_equal(scene.params[geometry[e]:geometry[e] + size], scene.effects[e].geometry_values())
    assert [program[layout.effect_row(e), layout.E_PLANE] for e in range(7)] == [0, 0, 0, 1, 1, 0, 0]


def shipped_interactions():
    """One of every configuration of demkit's own interactions that the catalogue dispatches to."""
    kv, hertz = dict(stiffness=1000.0, damping=1.0), dict(young=2e4, poisson=0.3, restitution=0.5)
    contacts = [dk.KelvinVoigt(**kv), dk.KelvinVoigt(**kv, friction=dk.Friction(0.5)),
                dk.KelvinVoigt(**kv, friction=dk.Friction(0.5), twisting=dk.TwistingResistance()),
                dk.Hertz(**hertz), dk.Hertz(**hertz, friction=dk.Friction(0.5)),
                dk.Hertz(**hertz, friction=dk.Friction(0.5), twisting=dk.TwistingResistance())]
    pairs = [dk.Dipole(0.1), dk.Dipole(0.1, cutoff=2.5, switch_width=0.5), dk.PowerLawDipole(0.1),
             dk.PowerLawDipole(0.1, cutoff=2.5, switch_width=0.5)]
    effects = [dk.Gravity((0, 0, -1.0)), dk.UniformField((0, 0, 0.1)), dk.Langevin(drag=0.5, temperature=0.01, seed=1)]
    try:
        import magpylib
        effects.append(dk.MagnetField(magpylib.misc.Dipole(moment=(0, 0, 1.0)), ((-3, -3, 1), (3, 3, 4)), spacing=0.5))
    except ImportError:
        pass
    return pairs, contacts, effects


def test_every_shipped_interaction_has_a_kind_of_the_catalogue():
    """A shipped law that matches no line of catalogue.PAIR_LAWS / EFFECTS (Law.fits: functions, torque,
    dissipation, reads, history, parameter count) would still run, through the adapters of your own
    functions (kind OWN) and slower: every shipped configuration gets a kind here, and every line of the
    catalogue is some configuration's kind (a new line needs a configuration above)."""
    pairs, contacts, effects = shipped_interactions()
    p = dk.Particles(position=[[0, 0, 1.5], [1.2, 0, 1.5], [3.0, 0.2, 1.6]], radius=0.5, mass=1.0,
                     dipole=[[0, 0, 1.0]] * 3)
    box = dk.Box(6.0, periodic=True)
    q = dk.Particles(position=[[0.5, 0.5, 0.5], [1.7, 0.5, 0.5], [3.5, 2.0, 2.0]], radius=0.5, mass=1.0,
                     dipole=[[0, 0, 1.0]] * 3)
    scenes = [dk.Scene(p, [pair, contact], tier=1) for pair, contact in zip(pairs + pairs[:2], contacts)]
    scenes += [dk.Scene(p, [contact, dk.Wall((0, 0, 0), (0, 0, 1))], tier=1) for contact in contacts]
    scenes += [dk.Scene(p, [dk.KelvinVoigt(1000.0, 1.0), *effects], tier=1),
               dk.Scene(q, [dk.Dipole(0.1, long_range=dk.Ewald(1e-3)), dk.KelvinVoigt(1000.0, 1.0)], box=box, tier=1)]
    laws, catalogued_effects = catalogue.catalogue()
    seen_laws, seen_effects = set(), set()
    for scene in scenes:
        program = scene.program
        for g in range(layout.MAX_GROUPS):
            row = program[layout.group_row(g, 0)]
            for m in range(row[layout.G_COUNT]):
                kind = row[layout.G_MEMBERS + layout.M_COLUMNS * m + layout.M_KIND]
                assert kind != catalogue.OWN, f"{scene.interactions} runs through the adapters: no catalogue line fits"
                seen_laws.add(int(kind))
        for e in range(program[0, layout.H_EFFECTS]):
            kind = program[layout.effect_row(e), layout.E_KIND]
            assert kind != catalogue.OWN, f"{scene.effects[e]!r} runs through the adapters: no catalogue line fits"
            seen_effects.add(int(kind))
    assert seen_laws == set(range(len(laws)))
    magnets = {law.kind for law in catalogued_effects if law.force_name == "magnet_force"}
    assert seen_effects | (magnets if len(effects) == 3 else set()) == set(range(len(catalogued_effects)))


def test_runs_of_one_combination_add_up_their_seconds_on_tier_1(monkeypatch):
    """Short runs of one combination (a sweep, the paper's replication) pay for tier 2 together: the
    seconds each spent on tier 1 in this process count for the next, and once one run has tier 2,
    the later ones switch to it at once."""
    from demkit.engine import tiers
    monkeypatch.setattr(tiers, "WORTH_COMPILING_OPEN", 1.0)
    monkeypatch.setattr(tiers, "WORTH_LOADING", 1.0)
    monkeypatch.setattr(tiers, "_SPENT", {})
    monkeypatch.setattr(tiers, "_READY", set())
    started = []
    monkeypatch.setattr(tiers.TierChoice, "_start", lambda self: started.append(self))
    p = dk.Particles(position=[[0, 0, 0], [3.0, 0, 0]], radius=1.0, dipole=[[0, 0, 1.0], [0, 0, 1.0]])
    runs = [tiers.TierChoice(dk.Scene(p, [dk.Dipole(1.0), dk.KelvinVoigt(100.0)]), "euler_cromer_steps")
            for _ in range(3)]
    other = tiers.TierChoice(dk.Scene(p, [dk.Dipole(1.0)]), "euler_cromer_steps")  # another combination
    assert len({run.key for run in runs}) == 1 and other.key != runs[0].key
    runs[0].ran(0.6)
    assert runs[0].ready(0.3) is None and not started  # 0.9 s of this combination: not worth it
    runs[1].ran(0.3)
    assert other.ready(0.2) is None and not started  # the other combination has run 0 s
    assert runs[1].ready(0.2) is None and started == [runs[1]]  # 0.6 + 0.3 + 0.2 s: compiled now
    runs[1]._work = SimpleNamespace(is_alive=lambda: False)
    runs[1]._modules = ("tier 2", None)
    assert runs[1].ready(0.1) == ("tier 2", None)
    assert runs[2].ready(0.0) is None and started[-1] is runs[2]  # this process has it: at once


def test_the_first_chunk_which_compiles_is_not_counted_as_time_on_tier_1(monkeypatch):
    """A run's first chunk compiles or loads tier 1's code: on a new install that took 20 s, which
    counted as time on tier 1 made a 1000-step run of two spheres start compiling tier 2."""
    from demkit.engine import tiers
    monkeypatch.setattr(tiers, "_SPENT", {})
    p = dk.Particles(position=[[0, 0, 0], [3.0, 0, 0]], radius=1.0, dipole=[[0, 0, 1.0], [0, 0, 1.0]])
    sim = dk.Simulation(dk.Scene(p, [dk.Dipole(1.0), dk.KelvinVoigt(100.0)]), dk.EulerCromer(1e-3))
    sim.run(duration=16e-3, progress=False)  # one chunk: the first
    assert tiers._SPENT.get(sim._tiers.key, 0.0) == 0.0
    sim.run(duration=0.2, progress=False)
    assert tiers._SPENT[sim._tiers.key] > 0.0


@pytest.mark.parametrize("open_space, parallel", [(False, False), (False, True), (True, False)],
                         ids=["lists", "chunked_lists", "all_pairs"])
def test_per_pair_diagnostics_are_the_pair_loops_own_and_compile_nothing(open_space, parallel):
    """Tier 1's per-pair forces and energies come from the family's pair loops themselves, recording
    each entry (called from Python with the types the run compiled them for: numba compiles none of the
    generic modules' functions for them). Truths: the separations are the minimum images, each sphere's sum of its pairs' forces is
    the scene's force (to round-off: the same terms in another order; the scenes have pair laws only,
    friction and rolling with their history) and the pairs' energies add up to the scene's. A scene
    that may run on threads has its lists in chunks, with room between them."""
    from numba.core import event
    if open_space:  # the six spheres of small_scene, their pair laws alone: all pairs
        scene = small_scene(1)
        laws = [inter for inter in scene.interactions if isinstance(inter, dk.PairInteraction)]
        scene = dk.Scene(scene.particles, laws, tier=1)
    else:
        scene = gas(1, n=240, parallel=parallel)
    assert scene.tier == 1 and scene.plan.growing != open_space
    dk.Simulation(scene, dk.VelocityVerlet(2e-4 if open_space else 1e-3)).run(0.02, progress=False)
    compiled = []

    class Compiles(event.Listener):  # the generic modules' functions (a small helper of demkit.engine.state, which
        def on_start(self, ev):      # reads the state's arrays, may compile the first time it is used)
            function = ev.data["dispatcher"].py_func
            if function.__module__.startswith("demkit_generic"):
                compiled.append(function.__name__)

        def on_end(self, ev):
            pass

    with event.install_listener("numba:compile", Compiles()):
        pairs, energies = scene.pair_energies()
        per_pair = scene.pair_forces()
    assert compiled == []
    x = scene.particles.position
    summed = np.zeros_like(x)
    for inter, ij, separation, f in per_pair:
        d = x[ij[:, 1]] - x[ij[:, 0]]
        if scene.box is not None:
            d -= scene.box.size * np.rint(d / scene.box.size)
        np.testing.assert_allclose(separation, d, rtol=0, atol=1e-12)
        np.add.at(summed, ij[:, 1], f)
        np.add.at(summed, ij[:, 0], -f)
    force, _ = scene.forces()
    assert len(per_pair) == len(scene.interactions) and np.abs(summed - force).max() <= 1e-12 * np.abs(force).max()
    energy = scene.energy()
    for kind in {inter.energy_kind for inter in scene.interactions}:
        columns = [k for k, inter in enumerate(scene.interactions) if inter.energy_kind == kind]
        assert np.isclose(energies[:, columns].sum(), energy[kind], rtol=1e-12, atol=1e-14), kind


def test_a_failed_tier_2_compilation_is_reported_and_the_run_goes_on_on_tier_1(monkeypatch):
    """A background compilation that fails (a full disk, a broken plugin) keeps the run on tier 1
    with the same bits, and the run's statistics say why instead of waiting for it forever."""
    from demkit.engine import tiers
    monkeypatch.setattr(tiers, "WORTH_COMPILING_OPEN", 0.0)
    monkeypatch.setattr(tiers, "WORTH_LOADING", 0.0)
    monkeypatch.setattr(tiers, "_SPENT", {})
    monkeypatch.setattr(tiers, "_READY", set())
    scene = small_scene(None)

    def broken(threads, tier=None):
        if tier == 2:
            raise OSError("No space left on device")
        return original(threads, tier=tier)

    original = scene._kernels
    monkeypatch.setattr(scene, "_kernels", broken)
    sim = dk.Simulation(scene, dk.VelocityVerlet(1e-3))
    for _ in range(40):  # short runs: each looks whether the background work ended
        sim.run(duration=0.005, progress=False)
        if not sim._tiers.switchable:
            break
    stats = sim.statistics
    assert stats["tier"] == 1 and stats["tier_switch_step"] is None
    assert "failed to compile" in stats["tier_reason"] and "No space left" in stats["tier_reason"]


def test_functions_only_compiled_code_calls_have_no_python_wrapper_and_are_refused_from_python():
    """The steps, the sums, the box's functions and the stubs are compiled without numba's wrapper for calls
    from Python (unboxing ``calls`` cost 0.1-0.2 CPU s of each): called from Python they would crash it, so
    the generic module seen from Python refuses them; what Python calls keeps its wrapper."""
    from demkit.engine.generic import COMPILED_ONLY, generic_source

    text = generic_source(False).splitlines()
    decorators = {line[4:line.index("(")]: text[k - 1] for k, line in enumerate(text) if line.startswith("def ")}
    for name in COMPILED_ONLY:
        assert decorators[name].endswith("no_cpython_wrapper=True)"), name
    for name in ("record_frame", "energies_of", "compute_forces", "maintain_lists", "velocity_verlet_steps"):
        assert "no_cpython_wrapper" not in decorators[name], name
    assert all("no_cpython_wrapper" in decorators[name] for name in decorators if name.startswith("no_"))
    scene = dk.Scene(dk.Particles([[0, 0, 0], [0.9, 0, 0]], radius=0.5, mass=1.0), [dk.KelvinVoigt(100.0, 1.0)],
                     tier=1)
    for name in ("forces_of", "end_step", "no_long_range"):
        with pytest.raises(AttributeError, match="compiled code only"):
            getattr(scene.kernels, name)
    dk.Simulation(scene, dk.VelocityVerlet(1e-3)).run(duration=3e-3, progress=False)  # runs through them
    assert scene.particles.position[1, 0] > 0.9  # pushed apart by the contact
