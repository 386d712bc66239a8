"""MagnetField: the field of magpylib sources, tabulated as a tricubic B-spline.

Truths used: magpylib's own getB (the tabulation), the analytic SI dipole-dipole force and torque
(a uniformly magnetised sphere's outside field is exactly a point dipole's), energy conservation
of a Hamiltonian system under velocity Verlet (error O(dt^2)).
"""
import math
import re
import sys

import numpy as np
import pytest

import demkit as dk
from conftest import energy_gradient

MU0 = 4e-7 * math.pi


@pytest.fixture(scope="module")
def magpy():
    return pytest.importorskip("magpylib")


def dipole_field(m1, r):
    """B (T) at r (m) of a point dipole m1 (A m^2) at the origin: mu0/(4 pi r^3) (3 n (m1.n) - m1)."""
    d = np.linalg.norm(r)
    n = r / d
    return MU0 / (4 * math.pi * d ** 3) * (3 * n * (m1 @ n) - m1)


def dipole_dipole_force(m1, m2, r):
    """Force (N) on dipole m2 at r from dipole m1 at the origin: F = grad(m2.B1), i.e.

        F = 3 mu0 / (4 pi r^4) [(m1.n) m2 + (m2.n) m1 + (m1.m2) n - 5 (m1.n)(m2.n) n],  n = r/|r|.
    """
    d = np.linalg.norm(r)
    n = r / d
    return 3 * MU0 / (4 * math.pi * d ** 4) * ((m1 @ n) * m2 + (m2 @ n) * m1 + (m1 @ m2) * n
                                               - 5 * (m1 @ n) * (m2 @ n) * n)


def test_analytic_dipole_force_is_the_gradient_of_m_dot_b():
    """The truth of the force test checked on its own: F = grad(m2.B1) by central differences."""
    m1, m2, r = np.array([0.3, -0.2, 1.0]), np.array([-0.5, 0.4, 0.2]), np.array([0.011, -0.004, 0.017])
    h = 1e-7
    grad = [(m2 @ dipole_field(m1, r + h * e) - m2 @ dipole_field(m1, r - h * e)) / (2 * h) for e in np.eye(3)]
    # central differences: truncation ~ (h/r)^2 |F| ~ 1e-10 |F|, round-off ~ eps |U| / h ~ eps r / h |F| ~ 1e-10 |F|
    np.testing.assert_allclose(dipole_dipole_force(m1, m2, r), grad, rtol=1e-7)


def test_tabulated_field_matches_magpylib_to_fourth_order(magpy):
    """|B_spline - B| at random points <= 14 (h/d)^4 max|B| and halves of the spacing cut it ~16x.

    Tolerance: a cubic spline's error is about 5/384 h^4 max|f''''| per axis; for a dipole field at
    distance >= d, |f''''| <~ 360 max|B| / d^4 (the fourth derivative of r^-3 is 360 r^-7); three axes
    give 3 * 5/384 * 360 = 14. Measured: 0.5-0.9 (h/d)^4 max|B| (3.2e-3, 1.3e-4, 1.3e-5 at h = 5, 2.5,
    1.25 mm); orders of the RMS error 4.1, 3.8.
    """
    source = magpy.misc.Dipole(moment=(0.3, -0.2, 1.0))
    lo, hi = np.array([-0.02, -0.02, 0.02]), np.array([0.02, 0.02, 0.05])
    d = 0.02  # distance from the source to the region
    points = np.random.default_rng(1).uniform(lo, hi, size=(5000, 3))
    exact = source.getB(points)
    scale = np.linalg.norm(exact, axis=1).max()
    rms = []
    for spacing in (0.005, 0.0025, 0.00125):
        field = dk.MagnetField(source, (lo, hi), spacing=spacing)
        error = np.linalg.norm(field.field(points) - exact, axis=1)
        h = field.spacing.max()
        assert error.max() < 14 * (h / d) ** 4 * scale
        rms.append(np.sqrt(np.mean(error ** 2)))
    orders = np.log2(np.array(rms[:-1]) / rms[1:])
    assert ((orders > 3.5) & (orders < 4.6)).all(), orders  # fourth order (measured 4.1, 3.8)
    # exact at the sample sites: the corners of the region are sites
    np.testing.assert_allclose(field.field(np.array([lo, hi])), source.getB(np.array([lo, hi])), rtol=1e-12,
                               atol=1e-12 * scale)


def test_force_and_torque_on_a_dipole_near_a_magnetised_sphere(magpy):
    """A uniformly magnetised sphere's outside field is a dipole's with m1 = J V / mu0; the spheres of
    the scene feel the analytic force and torque. Scene in millimetres, fields in tesla: the force
    in scene units is F[N] * 1e-3 (energy m.B in J, lengths in mm)."""
    J, diameter = np.array([0.2, 0.1, 1.2]), 0.01
    source = magpy.magnet.Sphere(polarization=J, diameter=diameter)
    m1 = J * (math.pi / 6 * diameter ** 3) / MU0
    lo, hi = np.array([-10.0, -10, 10]), np.array([10.0, 10, 30])  # mm, at least 10 mm from the centre
    rng = np.random.default_rng(2)
    position = rng.uniform(lo + 1, hi - 1, size=(20, 3))
    moment = rng.normal(size=(20, 3)) * 0.05
    force = np.array([dipole_dipole_force(m1, m, x * 1e-3) for x, m in zip(position, moment)]) * 1e-3
    torque = np.array([np.cross(m, dipole_field(m1, x * 1e-3)) for x, m in zip(position, moment)])
    errors = []
    for spacing in (2.0, 1.0):
        field = dk.MagnetField(source, (lo, hi), spacing=spacing, length_unit=1e-3)
        scene = dk.Scene(dk.Particles(position=position, radius=0.5, mass=1.0, dipole=moment), [field])
        f, t = scene.forces()
        ef = np.linalg.norm(f - force, axis=1) / np.linalg.norm(force, axis=1)
        et = np.linalg.norm(t - torque, axis=1) / np.linalg.norm(torque, axis=1)
        # the force is B's gradient: one order less than B, so relative error <~ (h/d)^3 (d = 10 mm);
        # measured 0.3 (h/d)^3 (2.5e-3 at 2 mm, 3.2e-4 at 1 mm); the torque follows B: 7e-4, 2e-5
        assert ef.max() < (spacing / 10) ** 3
        assert et.max() < 14 * (spacing / 10) ** 4
        errors.append(ef.max())
    assert 5 < errors[0] / errors[1] < 11  # third order: 8x per halving (measured 7.9)
    # energy -m.B_spline, and the force is its exact gradient (central differences, h = 1e-5 mm:
    # truncation ~ (h/d)^2 |F| ~ 1e-12 |F|, round-off ~ eps |U| / h ~ eps d / h |F| ~ 1e-9 |F|)
    e = scene.energy()["field"]
    assert e == pytest.approx(-np.sum(moment * field.field(position)), rel=1e-12)
    for k in (0, 7):
        np.testing.assert_allclose(f[k], -energy_gradient(scene, "field", k, h=1e-5), rtol=1e-7)


def cube_scene(magpy, dt, spacing):
    """A spinning NdFeB sphere (R = 2 mm) flying over a 1 cm cube magnet (J = 1.2 T), SI units."""
    cube = magpy.magnet.Cuboid(polarization=(0, 0, 1.2), dimension=(0.01, 0.01, 0.01))
    radius = 0.002
    volume = 4 / 3 * math.pi * radius ** 3
    field = dk.MagnetField(cube, ((-0.03, -0.03, 0.008), (0.03, 0.03, 0.03)), spacing=spacing)
    p = dk.Particles(position=[[-0.025, 0.004, 0.024]], velocity=[[4.0, 0, 0.3]], radius=radius,
                     mass=7500 * volume, dipole=[[1.2 * volume / MU0, 0, 0]], angular_velocity=[[0, 200.0, 300.0]])
    return dk.Simulation(dk.Scene(p, [field]), dk.VelocityVerlet(dt))


def test_energy_is_conserved_to_second_order_in_dt(magpy):
    """Kinetic + rotational + field energy of a spinning magnet passing a cube magnet (600 steps at
    dt = 2e-5 s): velocity Verlet's error is O(dt^2) because the force is the exact gradient of the
    interpolated energy, whatever the spacing."""
    drift = {}
    for spacing in (0.004, 0.002):
        for dt in (2e-5, 1e-5):
            traj = cube_scene(magpy, dt, spacing).run(0.012, record_every=1e-4)
            e = traj.energy
            drift[spacing, dt] = np.abs(e["total"] - e["total"][0]).max() / np.abs(e["field"]).max()
    assert np.ptp(e["field"]) > 3e-4 and e["rotational"].max() > 10 * e["rotational"][0]  # it felt the field
    # measured 7.44e-5 at dt = 2e-5 for both spacings, exactly 4.00x less at dt = 1e-5
    assert drift[0.004, 2e-5] < 2e-4
    for spacing in (0.004, 0.002):
        assert 3.8 < drift[spacing, 2e-5] / drift[spacing, 1e-5] < 4.2
    # the spacing changes the field by ~1e-3 but not the conservation (both 7.44e-5)
    assert drift[0.004, 2e-5] == pytest.approx(drift[0.002, 2e-5], rel=0.05)


@pytest.mark.parametrize("integrator", [dk.VelocityVerlet, dk.EulerCromer])
def test_a_sphere_leaving_the_region_stops_the_run_clearly(magpy, integrator):
    source = magpy.misc.Dipole(moment=(0, 0, 1.0))
    field = dk.MagnetField(source, ((-1, -1, 1), (1, 1, 2)), spacing=0.25)
    p = dk.Particles(position=[[0.0, 0, 1.5], [0.905, 0, 1.5]], velocity=[[0, 0, 0], [1.0, 0, 0]], radius=0.05,
                     mass=1.0, dipole=[[0, 0, 1e3], [0, 0, 1e3]])
    sim = dk.Simulation(dk.Scene(p, [field]), integrator(1e-3))
    with pytest.raises(dk.SimulationError) as err:
        sim.run(1.0, record_every=0.01)
    message = str(err.value)
    assert "particle id 1" in message and "region of MagnetField" in message and "x in [-1, 1]" in message
    if integrator is dk.VelocityVerlet:  # the position is known: it is outside, said without NaNs
        assert "left the region" in message and "nan" not in message  # no NaN values (it says "NaN" once)
    assert err.value.step in (96, 97) and len(err.value.trajectory) == 10  # it leaves after 95 steps


def test_bad_input(magpy):
    source = magpy.misc.Dipole(moment=(0, 0, 1.0))
    region = ((-1, -1, 1), (1, 1, 2))
    with pytest.raises(ValueError, match="3-vector"):
        dk.MagnetField(source, ((0, 0), (1, 1)), spacing=0.1)
    with pytest.raises(TypeError, match="MagnetField region must be a number or an array of numbers"):
        dk.MagnetField(source, "a box", spacing=0.1)
    with pytest.raises(ValueError, match="x0 < x1"):
        dk.MagnetField(source, ((0, 0, 1), (1, 0, 2)), spacing=0.1)
    for spacing in (0.0, -0.1, float("nan")):
        with pytest.raises(ValueError, match="spacing"):
            dk.MagnetField(source, region, spacing=spacing)
    with pytest.raises(ValueError, match="length_unit"):
        dk.MagnetField(source, region, spacing=0.1, length_unit=0)
    with pytest.raises(ValueError, match="grid nodes"):
        dk.MagnetField(source, region, spacing=1e-4)
    with pytest.raises(TypeError, match="getB"):
        dk.MagnetField(np.zeros(3), region, spacing=0.5)
    with pytest.raises(ValueError, match="magnet material"):  # the region must be outside the magnets
        dk.MagnetField(magpy.magnet.Cuboid(polarization=(0, 0, 1), dimension=(1, 1, 1)), ((-1, -1, 0.4), (1, 1, 2)),
                       spacing=0.25)

    class Flat:
        def getB(self, points):
            return np.zeros((len(points), 2))

    with pytest.raises(ValueError, match="3-vector"):
        dk.MagnetField(Flat(), region, spacing=0.5)
    field = dk.MagnetField(source, region, spacing=0.5)
    with pytest.raises(ValueError, match="particle 1 at .* outside the region of MagnetField"):
        dk.Scene(dk.Particles(position=[[0, 0, 1.5], [0, 0, 2.5]], radius=0.1, dipole=[[0, 0, 1], [0, 0, 1]]),
                 [field])
    with pytest.raises(ValueError, match="dipole"):
        dk.Scene(dk.Particles(position=[[0, 0, 1.5]], radius=0.1), [field])
    # a list of sources is their Collection
    both = dk.MagnetField([source, source], region, spacing=0.5)
    np.testing.assert_allclose(both.field([[0.1, 0.2, 1.3]]), 2 * field.field([[0.1, 0.2, 1.3]]), rtol=1e-12)


def test_without_magpylib_an_import_error_says_what_to_install(monkeypatch):
    monkeypatch.setitem(sys.modules, "magpylib", None)  # import magpylib now raises ImportError
    with pytest.raises(ImportError, match=r"MagnetField needs magpylib: pip install 'demkit\[magnets\]'"):
        dk.MagnetField(object(), ((0, 0, 0), (1, 1, 1)), spacing=0.1)


def test_the_table_lives_in_params_and_other_effects_are_called_as_before(magpy):
    """The table is read at run time from params (a stronger magnet reuses the compiled kernels);
    effects without a table are called exactly as before the table contract existed."""
    region = ((-1, -1, 1), (1, 1, 2))
    p = dk.Particles(position=[[0.1, 0.2, 1.5]], radius=0.1, mass=1.0, dipole=[[0.3, 0, 1.0]])
    scenes = [dk.Scene(p.copy(), [dk.UniformField((0, 0, 0.5)),
                                  dk.MagnetField(magpy.misc.Dipole(moment=(0, 0, s)), region, spacing=0.25)])
              for s in (1.0, 3.0)]
    weak, strong = scenes
    table = weak.effects[1].table_values()
    start = len(weak.params) - len(table)
    assert start == 3 + 12 and np.array_equal(weak.params[start:], table)
    source = weak.fused_source()
    assert "sforce_0(i, x, y, z, dipole, q0_0, q0_1, q0_2)" in source
    # (the slot as np.int64: a literal would compile the helpers it reaches once more, engine.snippets.as_int64)
    assert f"sforce_1(i, x, y, z, dipole, params, np.int64({start}), q1_0, " in source
    assert strong.kernels is weak.kernels  # same code, different params
    np.testing.assert_allclose(strong.forces()[0], 3 * weak.forces()[0], rtol=1e-12)


def test_scenes_without_a_magnet_field_compile_none_of_it():
    p = dk.Particles(position=[[0, 0, 0]], radius=1.0, mass=1.0, dipole=[[1.0, 0, 0]])
    scene = dk.Scene(p, [dk.UniformField((0.5, 0, 0)), dk.Gravity((0, 0, -1))])
    source = scene.fused_source()
    assert "sforce_0(i, x, y, z, dipole, q0_0, q0_1, q0_2)" in source and not re.search(r"params, \d", source)
    assert "magnet" not in source and len(scene.params) == 6  # no table, no call with one
