"""Bad input stops before stepping with a ValueError naming the problem."""
import numpy as np
import pytest

import demkit as dk


@pytest.mark.parametrize("kwargs, message", [
    (dict(position=[[0, 0], [1, 1]]), r"position must have shape \(N, 3\)"),
    (dict(position=[[0, 0, 0], [3, 0, 0]], velocity=[[0, 0, 0]]), r"velocity must have shape \(2, 3\)"),
    (dict(position=[[0, 0, np.nan], [3, 0, 0]]), "position contains NaN"),
    (dict(position=[[0, 0, 0], [3, 0, 0]], velocity=[[0, np.inf, 0], [0, 0, 0]]), "velocity contains NaN or inf"),
    (dict(position=[[0, 0, 0], [3, 0, 0]], radius=-1.0), "radius must be positive"),
    (dict(position=[[0, 0, 0], [3, 0, 0]], radius=[1.0, 0.0]), "radius must be positive; particle 1"),
    (dict(position=[[0, 0, 0], [3, 0, 0]], mass=0.0), "mass must be positive"),
    (dict(position=[[0, 0, 0], [3, 0, 0]], mass=[1.0, 2.0, 3.0]), r"mass must be a scalar or have shape \(2,\)"),
    (dict(position=[[0, 0, 0], [3, 0, 0]], dipole=[[0, 0, 1]] * 3), r"dipole must have shape \(2, 3\)"),
    (dict(position=[[0, 0, 0], [3, 0, 0]], ids=[4, 4]), "unique"),
])
def test_bad_particles(kwargs, message):
    with pytest.raises(ValueError, match=message):
        dk.Particles(**kwargs)


def test_dipole_without_moments():
    p = dk.Particles(position=[[0, 0, 0], [3, 0, 0]])
    with pytest.raises(ValueError, match="Dipole needs particle dipole moments"):
        dk.Scene(p, [dk.Dipole(1.0)])


@pytest.mark.parametrize("make", [lambda: dk.Dipole(prefactor=-1.0), lambda: dk.Dipole(1.0, cutoff=0.0),
                                  lambda: dk.KelvinVoigt(stiffness=0.0),
                                  lambda: dk.KelvinVoigt(stiffness=1.0, damping=-0.1),
                                  lambda: dk.KelvinVoigt(stiffness=np.nan)])
def test_bad_interaction_parameters(make):
    with pytest.raises(ValueError, match="must be a"):
        make()


def test_coincident_spheres():
    p = dk.Particles(position=[[1, 2, 3], [5, 5, 5], [1, 2, 3]])
    with pytest.raises(ValueError, match="particles 0 and 2 are coincident"):
        dk.Scene(p, [dk.KelvinVoigt(1.0)])


def test_deeply_overlapping_spheres():
    p = dk.Particles(position=[[0, 0, 0], [0.8, 0, 0]], radius=1.0)
    with pytest.raises(ValueError, match="overlap deeply"):
        dk.Scene(p, [dk.KelvinVoigt(1.0)])
    # a shallow overlap is a legitimate start (e.g. a settled packing)
    dk.Scene(dk.Particles(position=[[0, 0, 0], [1.9, 0, 0]], radius=1.0), [dk.KelvinVoigt(1.0)])


def test_time_step_too_large_names_the_largest_safe_value():
    p = dk.Particles(position=[[0, 0, 0], [3, 0, 0]], radius=1.0, mass=1.0)
    scene = dk.Scene(p, [dk.KelvinVoigt(stiffness=1.0, damping=0.1)])
    safe = scene.max_time_step()
    assert 0.2 < safe < 0.25  # contact of two unit masses with k = 1 lasts ~2.22
    with pytest.raises(ValueError, match=f"largest safe value is {safe:.6g}"):
        dk.Simulation(scene, dk.EulerCromer(dt=0.3))
    dk.Simulation(scene, dk.EulerCromer(dt=safe))  # the limit itself is accepted


def test_nan_set_after_construction_is_caught_before_stepping():
    p = dk.Particles(position=[[0, 0, 0], [3, 0, 0]], radius=1.0)
    scene = dk.Scene(p, [dk.KelvinVoigt(1.0)])
    sim = dk.Simulation(scene, dk.VelocityVerlet(0.01))
    p.velocity[1, 2] = np.nan
    with pytest.raises(ValueError, match="velocity contains NaN or inf .particle 1"):
        sim.run(duration=1.0)
    assert sim.step == 0


def test_not_an_interaction():
    p = dk.Particles(position=[[0, 0, 0], [3, 0, 0]])
    with pytest.raises(TypeError, match="PairInteraction"):
        dk.Scene(p, ["gravity"])


# ---- per-sphere vectors: one row per sphere, never copied ------------------------------------
@pytest.mark.parametrize("field", ["velocity", "dipole", "angular_velocity"])
@pytest.mark.parametrize("single", [[0.0, 0.0, 1.0], [[0.0, 0.0, 1.0]]])
def test_a_single_vector_is_not_copied_to_several_spheres(field, single):
    with pytest.raises(ValueError, match=rf"{field} must have shape \(2, 3\), one row per sphere, got "
                                         rf"\({'1, ' if np.ndim(single) == 2 else ''}3,?\).*np.tile\(v, \(2, 1\)\)"):
        dk.Particles(position=[[0, 0, 0], [3, 0, 0]], **{field: single})
    # with one sphere the bare vector and its (1, 3) form are the same thing
    one = dk.Particles(position=[[0, 0, 0]], **{field: single})
    np.testing.assert_array_equal(getattr(one, field), [[0.0, 0.0, 1.0]])
    # equal vectors for N spheres are written out
    three = dk.Particles(position=[[0, 0, 0], [3, 0, 0], [6, 0, 0]], **{field: np.tile(single, (3, 1))})
    np.testing.assert_array_equal(getattr(three, field), [[0.0, 0.0, 1.0]] * 3)


def test_a_bare_position_is_one_sphere():
    p = dk.Particles(position=[1.0, 2.0, 3.0], velocity=[0.0, 0.5, 0.0])
    assert len(p) == 1
    np.testing.assert_array_equal(p.position, [[1.0, 2.0, 3.0]])
    with pytest.raises(ValueError, match="rectangular"):
        dk.Particles(position=[[0, 0, 0], [1, 2]])


# ---- numbers are numbers: no strings, no bools -----------------------------------------------
class LooseDipole(dk.Dipole):
    """A plug-in that stores its parameter unchecked."""

    def __init__(self, prefactor):
        super().__init__(1.0)
        self.prefactor = prefactor


def _magnet_field(**kwargs):
    magpy = pytest.importorskip("magpylib")
    args = dict(sources=magpy.misc.Dipole(moment=(0, 0, 1.0)), region=((-1, -1, 1), (1, 1, 2)), spacing=0.5)
    return dk.MagnetField(**{**args, **kwargs})


TWO = [[0, 0, 0], [3, 0, 0]]


@pytest.mark.parametrize("make, name", [
    (lambda: dk.Dipole(prefactor="1"), "Dipole prefactor"),
    (lambda: dk.Dipole(True), "Dipole prefactor"),
    (lambda: dk.Dipole(1.0, cutoff="5"), "Dipole cutoff"),
    (lambda: dk.Dipole(1.0, cutoff=5.0, switch_width=True), "Dipole switch_width"),
    (lambda: dk.PowerLawDipole(np.array("1")), "PowerLawDipole prefactor"),
    (lambda: dk.KelvinVoigt("1e3"), "KelvinVoigt stiffness"),
    (lambda: dk.KelvinVoigt(1e3, damping=False), "KelvinVoigt damping"),
    (lambda: dk.KelvinVoigt(1e3, no_tension="no"), "KelvinVoigt no_tension"),
    (lambda: dk.KelvinVoigt(1e3, no_tension=1), "KelvinVoigt no_tension"),
    (lambda: dk.Hertz("1e9", 0.3), "Hertz young"),
    (lambda: dk.Hertz(1e9, "0.3"), "Hertz poisson"),
    (lambda: dk.Hertz(1e9, 0.3, restitution=True), "Hertz restitution"),
    (lambda: dk.Friction("0.5"), "Friction coefficient"),
    (lambda: dk.Friction(0.5, stiffness="1e3"), "Friction stiffness"),
    (lambda: dk.Friction(0.5, damping=True), "Friction damping"),
    (lambda: dk.RollingResistance(True), "RollingResistance coefficient"),
    (lambda: dk.RollingResistance(0.1, stiffness="1"), "RollingResistance stiffness"),
    (lambda: dk.RollingResistance(0.1, damping="0"), "RollingResistance damping"),
    (lambda: dk.Wall(point=("0", "0", "0"), normal=(0, 0, 1)), "Wall point"),
    (lambda: dk.Wall(point=(0, 0, 0), normal=(False, False, True)), "Wall normal"),
    (lambda: dk.Wall(point=(0, 0, 0), normal=(0, 0, 1), velocity=(0, None, 0)), "Wall velocity"),
    (lambda: dk.Gravity("down"), "Gravity acceleration"),
    (lambda: dk.Gravity([0, 0, "-9.81"]), "Gravity acceleration"),
    (lambda: dk.UniformField((0, 0, True)), "UniformField field"),
    (lambda: _magnet_field(spacing="0.5"), "MagnetField spacing"),
    (lambda: _magnet_field(length_unit=True), "MagnetField length_unit"),
    (lambda: _magnet_field(region=(("-1", -1, 1), (1, 1, 2))), "MagnetField region"),
    (lambda: dk.Box("3"), "Box size"),
    (lambda: dk.Box([1, 2, True]), "Box size"),
    (lambda: dk.Particles(TWO, radius="1"), "radius"),
    (lambda: dk.Particles(TWO, radius=[1, "2"]), "radius"),
    (lambda: dk.Particles(TWO, mass=True), "mass"),
    (lambda: dk.Particles(TWO, inertia_factor="0.4"), "inertia_factor"),
    (lambda: dk.Particles([["0", "0", "0"], [3, 0, 0]]), "position"),
    (lambda: dk.Particles(TWO, velocity=[[True, False, False]] * 2), "velocity"),
    (lambda: dk.Particles(TWO, dipole=[[0, 0, None]] * 2), "dipole"),
    (lambda: dk.Particles(TWO, ids=["a", "b"]), "ids"),
    (lambda: dk.build.chain(3, "0.5"), "radius"),
    (lambda: dk.build.chain(3, 0.5, gap="0"), "gap"),
    (lambda: dk.build.chain(3, 0.5, moment=True), "moment"),
    (lambda: dk.build.ring(5, 0.5, centre=("0", 0, 0)), "centre"),
    (lambda: dk.build.box_for(10, 0.5, "0.2"), "volume_fraction"),
    (lambda: dk.build.lattice("sc", 2, spacing="1"), "spacing"),
    (lambda: dk.build.random_packing(3, ["0.5"] * 3, dk.Box(10.0)), "radius"),
    (lambda: dk.build.thermal_velocities(3, kT="1", mass=1.0), "kT"),
    (lambda: dk.build.thermal_spins(3, 1.0, inertia=True), "inertia"),
    (lambda: dk.Scene(dk.Particles(TWO, dipole=[[0, 0, 1]] * 2), [LooseDipole("1")]), "LooseDipole prefactor"),
])
def test_strings_and_bools_are_not_numbers(make, name):
    with pytest.raises(TypeError, match=rf"^{name}( \(.*\))? must (be|hold) .*(numbers?|True or False).*, got"):
        make()


def test_numpy_numbers_and_whole_float_ids_are_numbers():
    assert dk.Dipole(np.float32(0.5)).prefactor == 0.5
    assert dk.KelvinVoigt(np.int64(2), np.array(0.5)).damping == 0.5
    assert dk.KelvinVoigt(1.0, no_tension=np.bool_(True)).no_tension is True
    assert dk.Box(np.float64(3)).volume == 27.0
    p = dk.Particles(TWO, radius=np.float32(0.5), mass=[1, np.int8(2)], ids=np.array([7.0, 9.0]))
    np.testing.assert_array_equal(p.mass, [1.0, 2.0])
    assert p.ids.dtype == np.int64 and p.ids.tolist() == [7, 9]
    big = 2**62 + 1  # ids beyond 2**53 stay exact
    assert dk.Particles(TWO, ids=[big, big + 1]).ids.tolist() == [big, big + 1]
    with pytest.raises(ValueError, match="ids must hold whole numbers"):
        dk.Particles(TWO, ids=[0.5, 1.5])  # was truncated to [0, 1]


# ---- one interaction of a kind, unless it repeats by nature ----------------------------------
def test_the_same_interaction_twice_is_refused():
    law = dk.KelvinVoigt(1e3)
    p = dk.Particles(TWO)
    with pytest.raises(ValueError, match=r"the same KelvinVoigt\(.*\) is given twice \(entries 0 and 1 of "
                                         r"interactions\).*give it once"):
        dk.Scene(p, [law, law])
    wall = dk.Wall((0, 0, -2), (0, 0, 1))  # walls may repeat, but not the same wall
    with pytest.raises(ValueError, match=r"the same Wall\(.*\) is given twice \(entries 1 and 2"):
        dk.Scene(p, [law, wall, wall])


@pytest.mark.parametrize("first, second, hint", [
    (dk.Gravity((0, 0, -9.81)), dk.Gravity((1, 0, 0)), r"one Gravity with the summed acceleration"),
    (dk.UniformField((0, 0, 1)), dk.UniformField((0, 1, 0)), r"one UniformField with the summed field"),
    (dk.KelvinVoigt(1e3), dk.KelvinVoigt(2e3), r"one contact law acts on every touching pair"),
    (dk.Hertz(1e9, 0.3), dk.Hertz(1e9, 0.3), r"one contact law"),
    (dk.Dipole(1.0), dk.Dipole(2.0), r"one Dipole"),
    (dk.Dipole(1.0), dk.PowerLawDipole(1.0), r"one Dipole \(or PowerLawDipole, a kind of Dipole\)"),
    (dk.PowerLawDipole(1.0), dk.Dipole(1.0), r"one Dipole"),
])
def test_two_of_a_kind_that_would_add_up_are_refused(first, second, hint):
    p = dk.Particles(TWO, dipole=[[0, 0, 1]] * 2)
    kind = min(type(first), type(second), key=lambda k: len(k.__mro__)).__name__
    with pytest.raises(ValueError, match=rf"two {kind} interactions are given \(entries 0: .* and 2: .*\): their "
                                         rf"forces would add up; .*{hint}"):
        dk.Scene(p, [first, dk.KelvinVoigt(5.0) if isinstance(first, dk.Dipole) else dk.Dipole(1.0), second]
                 if not isinstance(first, (dk.KelvinVoigt, dk.Hertz)) else [first, dk.Gravity((0, 0, -1)), second])


def test_walls_repeat_and_their_forces_add():
    """A sphere in a corner, pressed into the floor and a side wall: each wall pushes on its own."""
    k = 100.0
    p = dk.Particles(position=[[0.9, 0.0, 0.95]], radius=1.0)
    scene = dk.Scene(p, [dk.KelvinVoigt(k), dk.Wall((0, 0, 0), (1, 0, 0)), dk.Wall((0, 0, 0), (0, 0, 1))])
    force, _ = scene.forces()
    np.testing.assert_allclose(force, [[k * 0.1, 0.0, k * 0.05]], rtol=1e-12)
    assert dk.Wall.repeatable and dk.MagnetField.repeatable
    assert not any(c.repeatable for c in (dk.Gravity, dk.UniformField, dk.Dipole, dk.KelvinVoigt, dk.Hertz))


def test_a_single_effect_may_be_given_alone():
    p = dk.Particles(position=[[0, 0, 0]], mass=2.0)
    force, _ = dk.Scene(p, dk.Gravity((0, 0, -9.81))).forces()
    np.testing.assert_allclose(force, [[0, 0, -2 * 9.81]])


# ---- Particles repr ---------------------------------------------------------------------------
def test_particles_repr_is_one_short_line():
    assert repr(dk.Particles(TWO)) == "Particles(2 spheres, radius 1)"
    p = dk.Particles([[0, 0, 0], [3, 0, 0], [6, 0, 0]], radius=[0.5, 1.5, 1.0], dipole=[[0, 0, 1]] * 3,
                     angular_velocity=np.zeros((3, 3)), fixed=np.array([True, False, True]))
    assert repr(p) == "Particles(3 spheres, radius 0.5 to 1.5, angular_velocity, dipole, 2 fixed)"
    assert repr(dk.Particles([0, 0, 0], radius=0.25)) == "Particles(1 sphere, radius 0.25)"
