"""Lees-Edwards shear (dk.Shear, demkit.engine.shear): the sliding images against spheres drawn out by
hand in open space, both tiers' bits, a sheared elastic gas's linear profile and conserved peculiar
momentum, exact restarts, and what a sheared box refuses."""
import numpy as np
import pytest

import demkit as dk
from restart_scenes import assert_dipole_pairs_by_brute_force, assert_identical, state_of

L = 10.0
RATE = 0.3  # gammadot: the images one period up y move at u = RATE * L = 3 along x


@pytest.fixture(autouse=True)
def automatic_tier(monkeypatch):
    """Scenes here choose their tier themselves (the suite's conftest sets DEMKIT_TIER=1)."""
    monkeypatch.delenv("DEMKIT_TIER", raising=False)


def barbell():
    """Two magnetic spheres stuck head to tail in a frictional, rolling contact, spinning, the pair
    drifting up y at 1.3 (and along x and z): it crosses the sliding boundary y = L every 7.7 time
    units, at offsets delta = u t mod L that differ from crossing to crossing, its contact's springs loaded."""
    n = np.array([0.6, 0.8, 0.0])
    centre = np.array([4.0, 5.0, 5.0])
    pos = np.array([centre - 0.4988 * n, centre + 0.4988 * n])  # (about the dipoles' pull on the spring)
    spin = np.array([0.0, 0.0, 1.2])  # the pair turns about z: tangential relative motion
    vel = np.array([0.4, 1.3, 0.2]) + np.cross(spin, pos - centre)
    dip = np.array([n, n]) * 2.0
    return pos, vel, dip


def barbell_scene(box, pos, vel, tier=1):
    p = dk.Particles(position=pos, velocity=vel, radius=0.5, mass=1.0, dipole=barbell()[2],
                     angular_velocity=[[0.0, 0.0, 1.0], [0.0, 0.0, -0.5]])
    law = dk.KelvinVoigt(1e4, 2.0, friction=dk.Friction(0.5), rolling=dk.RollingResistance(0.05))
    return dk.Scene(p, [dk.Dipole(prefactor=1.0, cutoff=3.0), law], box=box, tier=tier)


def test_a_pair_across_the_sliding_boundary_moves_as_drawn_out_by_hand():
    """The sheared box's pair against the same pair in open space (no images at all: what the sliding
    image stands for, drawn out). The unwrapped path (position + n L + n_b u t along x), the velocity
    seen in open space (v + n_b u along x), the spins and the contact's forces and torques agree to
    round-off over 13 crossings of y = L, the pair straddling it in 32 of 501 frames at offsets delta
    from 0 to 7.6 (the pair's own motion, not chaotic: the two runs differ by the rounding of
    coordinates that differ by whole periods and delta, measured 2e-13 of the largest coordinate after
    50 000 steps, tolerance 1e-9; a lost friction history or a missing velocity shift of u = 3 differs
    by O(1) at the first crossing)."""
    pos, vel, _ = barbell()
    dt, duration = 1e-3, 50.0
    box = dk.Box(L, periodic=True, shear=dk.Shear(RATE, flow="x", gradient="y"))
    sheared = barbell_scene(box, pos, vel)
    opened = barbell_scene(None, pos, vel)
    a = dk.Simulation(sheared, dk.VelocityVerlet(dt)).run(duration=duration, record_every=0.1, progress=False)
    b = dk.Simulation(opened, dk.VelocityVerlet(dt)).run(duration=duration, record_every=0.1, progress=False)
    crossings = np.abs(np.diff(a.image[:, :, 1], axis=0)).sum()
    assert crossings >= 12, f"the spheres crossed y = L {crossings} times"
    straddling = a.image[:, 0, 1] != a.image[:, 1, 1]
    assert straddling.sum() >= 10, "frames with the pair across the sliding boundary"
    u = RATE * L
    scale = np.abs(b.position).max()
    assert np.allclose(a.unwrapped(), b.position, rtol=0, atol=1e-9 * scale)
    seen = a.velocity.copy()
    seen[..., 0] += a.image[..., 1] * u
    assert np.allclose(seen, b.velocity, rtol=0, atol=1e-9 * np.abs(b.velocity).max())
    assert np.allclose(a.angular_velocity, b.angular_velocity, rtol=0, atol=1e-9 * np.abs(b.angular_velocity).max())
    # the contact stayed made (and so kept its springs) all along
    assert np.all(np.linalg.norm(np.diff(b.position, axis=1), axis=2) < 1.0)
    # the forces and torques (dipoles, contact, friction and rolling springs) when the pair last straddled
    until = float(a.time[np.flatnonzero(straddling)[-1]])
    sheared, opened = barbell_scene(box, pos, vel), barbell_scene(None, pos, vel)
    dk.Simulation(sheared, dk.VelocityVerlet(dt)).run(duration=until, progress=False)
    dk.Simulation(opened, dk.VelocityVerlet(dt)).run(duration=until, progress=False)
    assert sheared.particles.image[0, 1] != sheared.particles.image[1, 1]
    fa, ta = sheared.forces()
    fb, tb = opened.forces()
    assert np.abs(fb).max() > 0.1 and np.abs(tb).max() > 1e-3
    assert np.allclose(fa, fb, rtol=0, atol=1e-8 * np.abs(fb).max())
    assert np.allclose(ta, tb, rtol=0, atol=1e-8 * np.abs(tb).max())
    _, history = sheared.history(sheared.interactions[1])
    _, truth = opened.history(opened.interactions[1])
    assert np.any(truth != 0.0), "the friction spring is loaded"
    assert np.allclose(history, truth, rtol=0, atol=1e-8 * np.abs(truth).max())


def test_the_pair_force_sees_the_image_velocity_across_the_boundary():
    """One step's forces of a pair straddling the boundary at t = 0: the dashpot acts on v_j + u - v_i
    (the sliding image's velocity). Both spheres at rest in the box, the upper one across y = L: seen
    from the lower one its image moves at +u along x, so the tangential friction pushes it along +x."""
    box = dk.Box(L, periodic=True, shear=dk.Shear(RATE, "x", "y"))
    pos = np.array([[5.0, 9.6, 5.0], [5.0, 0.35, 5.0]])  # 0.75 apart across y = L
    p = dk.Particles(position=pos, velocity=np.zeros((2, 3)), radius=0.5, mass=1.0,
                     angular_velocity=np.zeros((2, 3)))
    scene = dk.Scene(p, [dk.KelvinVoigt(1e4, 5.0, friction=dk.Friction(0.5))], box=box)
    force, _ = scene.forces()
    # the lower sphere (0) is dragged along +x by the image moving at +u, the upper (1) along -x
    assert force[0, 0] > 0.0 and force[1, 0] < 0.0
    assert force[0, 1] < 0.0 < force[1, 1]  # the normal push, along y across the boundary
    unsheared = dk.Scene(dk.Particles(position=pos, velocity=np.zeros((2, 3)), radius=0.5, mass=1.0,
                                      angular_velocity=np.zeros((2, 3))),
                         [dk.KelvinVoigt(1e4, 5.0, friction=dk.Friction(0.5))], box=dk.Box(L, periodic=True))
    assert unsheared.forces()[0][0, 0] == 0.0


def sheared_gas(tier, n=240, rate=0.8, flow="x", gradient="y", sort_every=None, parallel=False, magnetisable=False):
    """The frictional magnetic gas of tests/test_tiers.py in a sheared box (blocked dipole loops, Hertz
    contacts with friction and rolling), velocities about the imposed flow; with ``magnetisable`` one
    sphere in four magnetisable (its moment induced by the others' through the sliding images)."""
    R = 0.5
    size = dk.build.box_for(n, R, 0.25).size
    pos = dk.build.random_packing(n, R, dk.Box(size, periodic=True), seed=1)
    rng = np.random.default_rng(2)
    d = rng.normal(size=(n, 3))
    vel = rng.normal(size=(n, 3))
    a, b = "xyz".index(flow), "xyz".index(gradient)
    vel[:, a] += rate * (pos[:, b] - 0.5 * size[b])
    chi = np.where(np.arange(n) % 4 == 1, 3.0, 0.0) if magnetisable else None
    p = dk.Particles(position=pos, velocity=vel, radius=R, mass=1.0, dipole=d / np.linalg.norm(d, axis=1)[:, None],
                     susceptibility=chi)
    law = dk.Hertz(young=2e4, poisson=0.3, restitution=0.5, friction=dk.Friction(0.5),
                   rolling=dk.RollingResistance(0.02))
    box = dk.Box(size, periodic=True, shear=dk.Shear(rate, flow, gradient))
    return dk.Scene(p, [dk.Dipole(prefactor=1.0, cutoff=3.0), law], box=box, tier=tier, sort_every=sort_every,
                    parallel=parallel)


def test_a_sheared_frictional_magnetic_gas_gives_the_same_bits_on_both_tiers():
    """Tier 1 (the generic module, axes read from the shear block) and tier 2 (the scene's own pieces,
    axes written in) step the sheared gas to the same bits, diagnostics included; flow along z with
    the gradient along x so that neither axis is the default's; one sphere in four magnetisable."""
    import test_tiers
    sim, second = test_tiers.same_bits(lambda tier: sheared_gas(tier, flow="z", gradient="x", magnetisable=True),
                                       dk.VelocityVerlet(1e-3), 0.3, diagnostics=True)
    assert sim.statistics["tier"] == 1 and sim.scene.counters[0] > 1  # lists rebuilt (the shear slides)
    assert sim.scene.induction.solves > 300  # the induced moments solved at every step
    assert second.statistics["tier"] == 2


def test_an_unsheared_scene_generates_the_code_it_did():
    """Unused, shear costs nothing: the tier-2 code of an unsheared periodic gas has no line of it; on
    tier 1 it is given the plain periodic wrap and no frame folding (generic.SHEARED_CALLS), and the
    paper's laws run on the plain family, whose pair loops have no line of it either."""
    import test_tiers
    from demkit.engine import generic, generic_modules
    from demkit.engine import program as layout
    from demkit.engine.kernels import _Source
    scene = test_tiers.gas(1)
    assert scene.program[0, layout.H_SHEAR] == -1
    text = _Source(scene.plan, True).pieces_text((layout.G_GROUP, layout.G_SPEED))
    assert "shear" not in text and "sx, sy, sz" not in text
    sheared = sheared_gas(1)
    text = _Source(sheared.plan, True).pieces_text((layout.G_GROUP, layout.G_SPEED))
    assert "sheared_image(dx, dy, dz, 0, 1, la, lb, delta, jump, True, lc)" in text and "(sx, sy, sz))" in text
    plain = generic._Generic(False, "plain").pieces_text()
    full = generic._Generic(False, "full").pieces_text()
    assert "if edge:" not in plain and "shear_offset(" not in plain and "delta" not in plain
    assert "if edge:" in full and "shear_offset(" in full  # (owners near a face across b: sliding images)
    for make, sliding in ((lambda: sheared_gas(1), True), (lambda: test_tiers.gas(1, kelvin_voigt=True), False)):
        scene = make()
        needs = generic_modules.needs_of(scene.program)
        assert ("fold_frame" in needs) == sliding and "wrap_positions" in needs
        assert generic_modules.family_of(scene.program) == ("full" if sliding else "plain")
        dk.Simulation(scene, dk.VelocityVerlet(1e-3)).run(0.002, progress=False)
        (calls,) = [c for (_, only), c in scene.kernels._calls.items() if only is None]  # the time loops' tuple
        names = [c.cres.fndesc.qualname for c in calls if hasattr(c, "cres")]  # (and the threads flag)
        assert ("wrap_positions_sheared" in names) == sliding and ("no_fold_frame" in names) != sliding


def elastic_gas(shear, n=400, rate=1.0, seed=5):
    """A dilute (volume fraction 0.05) gas of nearly elastic frictionless spheres (restitution 0.98) started
    in the linear profile v_x = rate (y - L/2) plus thermal motion of the same size, no net momentum
    along y. ``shear``: a sheared box, else a plain periodic one."""
    R = 0.5
    size = dk.build.box_for(n, R, 0.05).size
    box = dk.Box(size, periodic=True, shear=dk.Shear(rate, "x", "y") if shear else None)
    pos = dk.build.random_packing(n, R, dk.Box(size, periodic=True), seed=seed)
    vel = dk.build.thermal_velocities(n, 1.0, 1.0, seed=seed)
    vel -= vel.mean(axis=0)
    vel[:, 0] += rate * (pos[:, 1] - 0.5 * size[1])
    p = dk.Particles(position=pos, velocity=vel, radius=R, mass=1.0)
    law = dk.KelvinVoigt(2e4, 2.0 * 0.00643 * np.sqrt(2e4 * 0.5))  # zeta 0.00643: restitution 0.98
    return dk.Scene(p, [law], box=box), size


def profile_slope(traj, size, frames):
    """The least-squares slope of v_x against y over the recorded frames ``frames`` (wrapped y)."""
    y = traj.position[frames, :, 1].ravel() - 0.5 * size[1]
    v = traj.velocity[frames, :, 0].ravel()
    return float(np.sum(y * (v - v.mean())) / np.sum(y * y))


def test_a_dilute_elastic_gas_keeps_its_linear_profile_and_its_peculiar_momentum():
    """In the sheared box the profile stays linear with the imposed slope: fitted over the last 10
    frames, 0.519 for 0.5 (tolerance 15 %: the shear heats the gas from temperature 1 to 22, and single
    frames' slopes then scatter by +-20 %), where the plain periodic box loses the profile it started
    with (slope 0.27 after 2 time units, about 0 from 12 on; asserted below half); the momentum of the
    motion relative to the flow, sum m (v - gammadot (y - L/2) e_x), is conserved to round-off times
    steps (measured 1e-14 of sum m|v| over 27 000 steps and 1494 crossings of the sliding boundary,
    tolerance 1e-9: each wrap changes v_x by gammadot L_y and y by L_y, which cancel; pair forces,
    across the boundary too, cancel in pairs)."""
    rate = 0.5
    dt, duration = 1.5e-3, 40.0
    results = {}
    for shear in (True, False):
        scene, size = elastic_gas(shear, rate=rate)
        traj = dk.Simulation(scene, dk.VelocityVerlet(dt)).run(duration=duration, record_every=2.0, progress=False)
        results[shear] = traj
    late = slice(-10, None)
    slope = profile_slope(results[True], size, late)
    assert slope == pytest.approx(rate, rel=0.15)
    assert profile_slope(results[False], size, late) < 0.5 * rate
    traj = results[True]
    assert np.abs(np.diff(traj.image[:, :, 1], axis=0)).sum() > 50, "spheres crossed the sliding boundary"
    peculiar = traj.velocity.copy()
    peculiar[..., 0] -= rate * (traj.position[..., 1] - 0.5 * size[1])
    momentum = peculiar.sum(axis=1)  # masses 1
    scale = np.abs(traj.velocity).sum(axis=1).max()
    assert np.abs(momentum - momentum[0]).max() < 1e-9 * scale


def test_a_stopped_and_resumed_sheared_run_is_bit_identical(tmp_path):
    """delta comes from the clock and the offset of the lists' last build is saved with the state: a
    run stopped twice and resumed in new scenes gives the uninterrupted run's bits (re-sorting every
    40 steps, friction history, wraps across the sliding boundary)."""
    until = 0.4
    scene = sheared_gas(None, n=120, sort_every=40)
    dk.Simulation(scene, dk.VelocityVerlet(2e-3)).run(until=until)
    truth = state_of(scene)
    path = tmp_path / "shear.ckpt"
    ends = [0.062, 0.25, until]
    for k, end in enumerate(ends):
        again = sheared_gas(None, n=120, sort_every=40)
        sim = dk.Simulation(again, dk.VelocityVerlet(2e-3), checkpoint=dk.Checkpoint(path))
        if k:
            sim.resume()
        sim.run(until=end)
    assert truth["image"][:, 1].any(), "spheres crossed the sliding boundary"
    assert any(np.any(v[1]) for key, v in truth.items() if key.startswith("history")), "contacts kept history"
    assert_identical(state_of(again), truth)


def test_a_vtk_series_keeps_the_shear_and_its_frames_read_back_with_their_sliding_images(tmp_path):
    """The .pvd's Box element holds the shear (rate, flow, gradient): dk.read_series gives it back, so
    contacts and clusters of a read frame take the sliding images at the frame's time, as the run's own
    trajectory does (the barbell stays one cluster while it crosses the sliding boundary)."""
    from demkit import clustering
    pos, vel, _ = barbell()
    box = dk.Box(L, periodic=True, shear=dk.Shear(RATE, "x", "y"))
    scene = barbell_scene(box, pos, vel)
    writer = dk.VTKWriter(tmp_path / "vtk", every=0.25, trails=False)
    traj = dk.Simulation(scene, dk.VelocityVerlet(1e-3), writers=[writer]).run(duration=5.0, record_every=0.25,
                                                                               progress=False)
    series = dk.read_series(tmp_path / "vtk")
    assert series.box.shear == box.shear and np.array_equal(series.box.size, box.size)
    assert np.allclose(series.time, traj.time, rtol=0, atol=1e-12)
    across = 0
    for k in range(len(series.time)):
        ours = clustering.clusters(traj.position[k], traj.radius, traj.box, gap=0.05, time=traj.time[k])
        read = clustering.clusters(series.position[k], series.radius, series.box, gap=0.05, time=series.time[k])
        assert np.array_equal(ours, read) and read.max() == 0  # one cluster: the pair holds together
        across += abs(series.position[k, 0, 1] - series.position[k, 1, 1]) > L / 2
    assert across > 0  # frames where the pair straddles the sliding boundary


def test_bad_shear_is_refused():
    with pytest.raises(ValueError, match="finite"):
        dk.Shear(float("nan"))
    with pytest.raises(ValueError, match="finite"):
        dk.Shear(float("inf"))
    with pytest.raises(ValueError, match="number"):
        dk.Shear("fast")
    with pytest.raises(ValueError, match="flow axis"):
        dk.Shear(1.0, flow="w")
    with pytest.raises(ValueError, match="gradient axis"):
        dk.Shear(1.0, gradient=1)
    with pytest.raises(ValueError, match="differ"):
        dk.Shear(1.0, flow="y", gradient="y")
    with pytest.raises(ValueError, match="gradient axis y must be periodic"):
        dk.Box(10.0, periodic=(True, False, True), shear=dk.Shear(1.0))
    with pytest.raises(ValueError, match="flow axis z must be periodic"):
        dk.Box(10.0, periodic=(True, True, False), shear=dk.Shear(1.0, flow="z", gradient="x"))
    with pytest.raises(ValueError, match="demkit.Shear"):
        dk.Box(10.0, periodic=True, shear=1.0)
    assert dk.Box(10.0, periodic=(True, True, False), shear=dk.Shear(2.0)).shear == dk.Shear(2.0, "x", "y")


def test_what_a_sheared_box_does_not_do_yet_is_refused():
    box = dk.Box(10.0, periodic=True, shear=dk.Shear(1.0))
    pos = np.array([[2.0, 2.0, 2.0], [5.0, 5.0, 5.0]])

    def particles(**extra):
        return dk.Particles(position=pos, velocity=np.zeros((2, 3)), radius=0.5, mass=1.0,
                            dipole=[[0, 0, 1.0], [0, 0, 1.0]], **extra)

    with pytest.raises(ValueError, match="reciprocal lattice"):
        dk.Scene(particles(), [dk.Dipole(prefactor=1.0, cutoff=3.0, long_range=dk.Ewald(1e-4))], box=box)
    with pytest.raises(ValueError, match="Wall in a box sheared"):
        dk.Scene(particles(), [dk.KelvinVoigt(1e3, 1.0), dk.Wall((0, 0, 0), (0, 1, 0))], box=box)
    from plugin_interactions import OwnKelvinVoigt
    with pytest.raises(ValueError, match="reads velocities: a function of your own"):
        dk.Scene(particles(), [OwnKelvinVoigt(1e3, 1.0)], box=box)
    # plane walls across the third axis are fine: the plates of a shear cell along z
    plates = dk.Box(10.0, periodic=(True, True, False), shear=dk.Shear(1.0))
    scene = dk.Scene(particles(), [dk.KelvinVoigt(1e3, 1.0), dk.Wall((0, 0, 0), (0, 0, 1))], box=plates)
    with pytest.raises(ValueError, match="sliding images"):
        dk.Simulation(scene, dk.VelocityVerlet(1e-3, resolve_contacts=True))


def test_the_shear_stress_of_a_dilute_elastic_gas_follows_kinetic_theory():
    """dk.measure.stress in the sheared box: its kinetic part is sum m c c with c the velocity relative
    to the imposed flow (to round-off), and the shear stress -P_xy follows Enskog's dense-gas viscosity
    of hard spheres, eta = eta0 [1/chi + 0.8 b rho + 0.761 chi (b rho)^2] with eta0 = 1.016 (5/16 d^2)
    sqrt(m kT / pi), b rho = 4 phi, chi = (1 - phi/2) / (1 - phi)^3 (Chapman & Cowling, ch. 16),
    P_xy = -eta gammadot at the gas's temperature at each moment (it heats from kT = 1 to 20: no
    thermostat). Over 30 samples from t = 11 to 40 (after the start-up, a few mean free times) the
    ratio averages 0.97 (tolerance 25 %: single samples scatter by +-50 %, the gas is slightly
    inelastic and its spheres soft, gammadot tau ~ 0.15)."""
    rate = 0.5
    scene, size = elastic_gas(True, rate=rate)
    series = dk.StressSeries(every=1.0)  # measured during the run (tests/test_stress_series.py)
    dk.Simulation(scene, dk.VelocityVerlet(1.5e-3), writers=[series]).run(duration=40.0, progress=False)
    n = len(scene.particles)
    phi = n * np.pi / 6.0 / np.prod(size)
    chi = (1.0 - phi / 2.0) / (1.0 - phi) ** 3
    p = scene.particles
    c = p.velocity.copy()
    c[:, 0] -= rate * (p.position[:, 1] - 0.5 * size[1])
    assert np.allclose(series.kinetic[-1] * np.prod(size), c.T @ c, rtol=1e-12, atol=0)
    # kT from the kinetic part (the relative motion's momentum stays 0: test above)
    kT = np.trace(series.kinetic, axis1=1, axis2=2) * np.prod(size) / (3 * n)
    eta = 1.016 * 5.0 / 16.0 * np.sqrt(kT / np.pi) * (1.0 / chi + 0.8 * 4 * phi + 0.761 * chi * (4 * phi) ** 2)
    later = series.time >= 11.0 - 1e-9
    assert later.sum() == 30
    ratios = series.pressure_tensor[later, 0, 1] / (-eta[later] * rate)
    assert np.mean(ratios) == pytest.approx(1.0, abs=0.25)
    r = series.rheology(after=11.0)  # the same samples' shear stress (not divided by each moment's eta)
    assert r["shear_stress"] == pytest.approx(-series.pressure_tensor[later, 0, 1].mean(), rel=1e-12)
    assert r["viscosity"] == pytest.approx(r["shear_stress"] / rate, rel=1e-12) and r["shear_stress_error"] > 0


def test_an_affinely_sheared_lattice_has_the_stress_of_its_bonds_and_of_its_energy():
    """An fcc lattice of spheres pressed into each other (Hooke contacts k = 1000, nearest neighbours
    s = 0.98 d apart) moving with the imposed flow (at rest relative to it: no kinetic part), displaced
    affinely, x += gamma y, in a box sheared to the offset
    delta = gamma L_y (the clock set where delta has wrapped past L_x three times, so the sliding images
    continue the strained lattice through the boundary): dk.measure.stress equals the lattice sum by
    hand over the 12 bonds, P_ab = (n / 2) sum_b f(r_b) r_a r_b / r_b with f = k (d - r) and
    n = 4 / a^3 (to 1e-12), and the shear stress equals the energy's derivative, -P_xy = (1/V) dU/dgamma
    (central differences, h = 1e-6: to 1e-6). At gamma = 0 the lattice is isotropic (P = p I)."""
    s, k, rate = 0.98, 1000.0, 0.25
    position, cubic = dk.build.lattice("fcc", 4, spacing=s)
    size = cubic.size
    a = s * np.sqrt(2.0)
    bonds = np.array([[x, y, z] for x in (-1, 0, 1) for y in (-1, 0, 1) for z in (-1, 0, 1)
                      if abs(x) + abs(y) + abs(z) == 2], dtype=float) * a / 2  # the 12 nearest neighbours

    def strained(gamma):
        """The lattice at strain gamma, its scene at the time the box's offset is gamma L_y."""
        x = position.copy()
        x[:, 0] = np.mod(x[:, 0] + gamma * x[:, 1], size[0])
        box = dk.Box(size, periodic=True, shear=dk.Shear(rate, "x", "y"))
        v = np.zeros_like(x)
        v[:, 0] = rate * (x[:, 1] - 0.5 * size[1])
        scene = dk.Scene(dk.Particles(position=x, velocity=v, radius=0.5, mass=1.0), [dk.KelvinVoigt(k, 0.0)],
                         box=box)
        scene.time = (gamma * size[1] + 3 * size[0]) / (rate * size[1])
        return scene

    for gamma in (0.0, 0.004, -0.01, 0.02):
        r = bonds.copy()
        r[:, 0] += gamma * r[:, 1]
        length = np.linalg.norm(r, axis=1)
        f = k * np.clip(1.0 - length, 0.0, None)
        by_hand = 4.0 / a**3 / 2.0 * np.einsum("b,ba,bc->ac", f / length, r, r)
        scene = strained(gamma)
        P = dk.measure.stress(scene).pressure_tensor
        np.testing.assert_allclose(P, by_hand, rtol=0, atol=1e-12 * np.abs(by_hand).max())
        h = 1e-6
        dU = (strained(gamma + h).energy()["contact"] - strained(gamma - h).energy()["contact"]) / (2 * h)
        assert -P[0, 1] == pytest.approx(dU / np.prod(size), rel=1e-6, abs=1e-9 * np.abs(P).max())
        if gamma == 0.0:
            np.testing.assert_allclose(P, P[0, 0] * np.eye(3), rtol=0, atol=1e-12 * P[0, 0])
        else:
            assert abs(P[0, 1]) > 1e-3 * P[0, 0]  # a real shear stress


def test_a_tilted_dipole_chain_has_the_stress_of_the_chain_model():
    """The chain model of magneto- and electrorheology (Martin & Anderson, J. Chem. Phys. 104, 4814
    (1996)): a chain of point dipoles spanning the gradient, moments m held along it by the field,
    tilted affinely by the strain gamma = tan(theta) (the gap fixed, so neighbours r = d / cos(theta)
    apart) has the energy per sphere u = -(A m^2 / r^3) S (3 cos^2(theta) - 1) with S = sum_k 1/k^3
    (zeta(3) for an infinite chain; here the k with k r below the dipoles' cutoff), and the shear stress
    sigma = n du/dgamma, whose maximum over gamma is the chain model's yield stress. One chain of 20
    spheres through a sheared box (the sliding images continue it at every offset): -P_yx (the stress of
    the dipoles' virial, not symmetric for non-central forces) = (1/V) dU/dgamma = n du/dgamma to 1e-9
    at strains from 0 to 0.6, and the largest stress on that grid sits at 0.4: the model's yield point,
    du/dgamma ~ 3 gamma (4 - gamma^2) / (1 + gamma^2)^(7/2) largest where 4 gamma^4 - 27 gamma^2 + 4 = 0,
    gamma* = 0.389 (theta = 21 degrees), sigma_y = 2.74 S n A m^2 / d^3 (3.30 n A m^2 / d^3 with zeta(3))."""
    n_chain, m, cutoff = 20, 1.0, 9.0
    size = np.array([20.0, float(n_chain), 20.0])
    rate = 0.1

    def scene_at(gamma):
        y = np.arange(n_chain) + 0.5
        x = np.column_stack([np.mod(5.0 + gamma * y, size[0]), y, np.full(n_chain, 10.0)])
        p = dk.Particles(position=x, radius=0.5, mass=1.0, dipole=np.tile([0.0, m, 0.0], (n_chain, 1)))
        box = dk.Box(size, periodic=True, shear=dk.Shear(rate, "x", "y"))
        scene = dk.Scene(p, [dk.Dipole(prefactor=1.0, cutoff=cutoff)], box=box)
        scene.time = (gamma * size[1] + 2 * size[0]) / (rate * size[1])  # the offset gamma L_y, wrapped twice
        return scene

    def model(gamma):
        """(u, du/dgamma) of the chain model with the cutoff's sum, per sphere."""
        c = 1.0 / np.sqrt(1.0 + gamma**2)
        r = 1.0 / c
        S = sum(1.0 / k**3 for k in range(1, 100) if k * r < cutoff)
        u = lambda g: -(m * m * S / (np.sqrt(1 + g * g)) ** 3) * (3.0 / (1 + g * g) - 1.0)  # noqa: E731
        h = 1e-6
        return u(gamma), (u(gamma + h) - u(gamma - h)) / (2 * h)

    density = n_chain / np.prod(size)
    strains = np.linspace(0.0, 0.6, 13)
    stresses = []
    for gamma in strains:
        s = dk.measure.stress(scene_at(gamma))
        sigma = -s.virial["Dipole"][1, 0] / s.volume
        u, du = model(gamma)
        assert scene_at(gamma).energy()["magnetic"] / n_chain == pytest.approx(u, rel=1e-12)
        assert sigma == pytest.approx(density * du, rel=1e-9, abs=1e-12)
        stresses.append(sigma)
    peak = strains[int(np.argmax(stresses))]
    gamma_star = np.sqrt((27.0 - np.sqrt(27.0**2 - 64.0)) / 8.0)
    assert gamma_star == pytest.approx(0.389, abs=1e-3) and abs(peak - gamma_star) <= 0.025 and max(stresses) > 0


def test_a_langevin_bath_moves_with_the_imposed_flow():
    """Free spheres in a bath sheared with the box (drag relative to the flow) against the
    Ornstein-Uhlenbeck covariance of the peculiar velocity c = v - gammadot (y - L/2) e_x, from
    dc_x = (-g c_x - gammadot c_y) dt + noise, dc_y = -g c_y dt + noise with g = drag / m:
    <c_y c_y> = <c_z c_z> = kT/m, <c_x c_y> = -gammadot kT / (2 drag), <c_x c_x> = kT/m (1 +
    gammadot^2 / (2 g^2)). Here kT = m = drag = 1, gammadot = 1: 1, -0.5 and 1.5, read from the kinetic
    part of the stress (dk.StressSeries). 400 spheres over 60 correlation times, 2.4e4 samples of
    each product: the statistical error of the means is about 1 % (tolerance 5 %); the scheme's own
    error is of order gammadot dt = 0.01. The same bath in a fixed box gives kT/m on every axis and no
    xy correlation."""
    n, kT, rate = 400, 1.0, 1.0
    size = np.array([12.0, 12.0, 12.0])
    rng = np.random.default_rng(3)
    position = dk.build.random_packing(n, 0.1, dk.Box(size, periodic=True), seed=3)
    for sheared in (True, False):
        velocity = rng.normal(size=(n, 3))
        if sheared:
            velocity[:, 0] += rate * (position[:, 1] - 0.5 * size[1])
        box = dk.Box(size, periodic=True, shear=dk.Shear(rate, "x", "y") if sheared else None)
        p = dk.Particles(position=position, velocity=velocity, radius=0.1, mass=1.0)
        scene = dk.Scene(p, [dk.Langevin(temperature=kT, drag=1.0, seed=5)], box=box)
        series = dk.StressSeries(every=0.5)
        dk.Simulation(scene, dk.VelocityVerlet(0.01), writers=[series]).run(62.0, progress=False)
        cc = series.kinetic[series.time >= 2.0 - 1e-9].mean(axis=0) * np.prod(size) / n  # <c_a c_b>
        expected = np.diag([1.0 + 0.5 * rate**2, 1.0, 1.0]) if sheared else np.eye(3)
        expected[0, 1] = expected[1, 0] = -0.5 * rate if sheared else 0.0
        np.testing.assert_allclose(cc, expected, rtol=0, atol=0.05)


def test_a_scene_file_shears_its_box_as_the_python_scene_does(tmp_path, capsys):
    """[box.shear] builds dk.Shear: the barbell's box from a scene file steps to the bits of the Python
    scene, a bad axis is refused naming the key, and a saved trajectory keeps the shear (its unwrapped
    paths are the run's)."""
    pos, vel, dip = barbell()
    rows = lambda a: "[" + ", ".join("[" + ", ".join(repr(float(x)) for x in r) + "]" for r in a) + "]"  # noqa: E731
    text = f"""
[particles]
position = {rows(pos)}
velocity = {rows(vel)}
angular_velocity = [[0.0, 0.0, 1.0], [0.0, 0.0, -0.5]]
dipole = {rows(dip)}
radius = 0.5
mass = 1.0
[box]
size = {L}
periodic = true
[box.shear]
rate = {RATE}
flow = "x"
gradient = "y"
[interactions.dipole]
prefactor = 1.0
cutoff = 3.0
[interactions.kelvin_voigt]
stiffness = 1e4
damping = 2.0
[interactions.friction]
coefficient = 0.5
[interactions.rolling_resistance]
coefficient = 0.05
[integrator]
method = "VelocityVerlet"
dt = 0.001
[run]
duration = 5.0
"""
    loaded = dk.parse_scene(text)
    assert loaded.scene.box.shear == dk.Shear(RATE, "x", "y")
    python = barbell_scene(dk.Box(L, periodic=True, shear=dk.Shear(RATE, "x", "y")), pos, vel)
    a = dk.Simulation(loaded.scene, dk.VelocityVerlet(1e-3)).run(duration=5.0, record_every=1.0, progress=False)
    b = dk.Simulation(python, dk.VelocityVerlet(1e-3)).run(duration=5.0, record_every=1.0, progress=False)
    assert a.position.tobytes() == b.position.tobytes() and a.velocity.tobytes() == b.velocity.tobytes()
    with pytest.raises(dk.SceneFileError, match="box.shear.flow"):
        dk.parse_scene(text.replace('flow = "x"', 'flow = "w"'))
    from demkit.scenefile.running import load_trajectory, save_trajectory
    save_trajectory(a, tmp_path / "run.npz")
    again = load_trajectory(tmp_path / "run.npz")
    assert again.box.shear == a.box.shear
    assert np.array_equal(again.unwrapped(), a.unwrapped())
    # run.stress_every: the stress measured during the file's run, [outputs] stress, sweep observables
    from demkit.scene_observables import observe
    with pytest.raises(dk.SceneFileError, match="stress_every"):
        dk.parse_scene(text + '[outputs]\nstress = "s.csv"\n')
    measured = dk.parse_scene(text.replace("duration = 5.0", "duration = 5.0\nstress_every = 0.5")
                              + '[outputs]\nstress = "s.csv"\n')
    measured.base = tmp_path
    traj = measured.run(progress=False)
    series = measured.stress_series
    assert len(series.time) == 11 and (tmp_path / "s.csv").exists()
    assert series.pressure_tensor[-1].tobytes() == dk.measure.stress(measured.scene).pressure_tensor.tobytes()
    values = observe(["stress", "rheology"], measured, traj)
    later = series.time >= 2.5
    assert values["stress_xy"] == pytest.approx(series.pressure_tensor[later, 0, 1].mean(), rel=1e-12)
    assert values["rheology_shear_stress"] == pytest.approx(-values["stress_xy"], rel=1e-12)
    assert values["rheology_rate"] == RATE and np.isnan(values["rheology_viscosity_error"])  # 6 samples: no blocks
    assert isinstance(observe(["rheology"], loaded, a)["rheology"], ValueError)  # no stress_every
    # demkit info says what the shear does to the sample and whether the stress is measured
    from demkit.cli import main as demkit_main
    (tmp_path / "sheared.toml").write_text(text.replace("duration = 5.0", "duration = 5.0\nstress_every = 0.5"))
    try:
        demkit_main(["info", str(tmp_path / "sheared.toml")])
    except SystemExit as done:
        assert not done.code
    said = capsys.readouterr().out
    assert (f"shear         rate {RATE:g} along x, gradient y: the images slide at {RATE * L:.4g}, a strain of "
            f"{RATE * 5.0:.4g} by t = 5; the stress measured every 0.5 (run.stress_every)") in said, said
    # demkit run names the stress series among what it writes (it said "no outputs requested" before)
    (tmp_path / "sheared.toml").write_text(text.replace("duration = 5.0", "duration = 1.0\nstress_every = 0.5")
                                           + '[outputs]\nstress = "stress.csv"\n')
    assert demkit_main(["run", str(tmp_path / "sheared.toml"), "--no-progress"]) == 0
    said = capsys.readouterr().out
    assert "no outputs requested" not in said and f"wrote stress series: {tmp_path / 'stress.csv'}" in said, said


def test_overlaps_across_the_sliding_boundary_are_found_before_a_run():
    """The scene's check of its start finds spheres overlapping through a sliding image (delta = 0 at
    t = 0: the image of the sphere at y = 0.3 sits straight above it, across y = L)."""
    box = dk.Box(L, periodic=True, shear=dk.Shear(RATE, "x", "y"))
    p = dk.Particles(position=[[5.0, 9.8, 5.0], [5.0, 0.3, 5.0]], radius=0.5, mass=1.0)
    with pytest.raises(ValueError, match="overlap"):
        dk.Scene(p, [dk.KelvinVoigt(1e3, 1.0)], box=box)


def test_a_sheared_gas_gives_the_same_bits_on_one_thread_and_on_all():
    """The pair loops' chunks and the list build's chunks (the sliding images in each chunk's cells) on
    numba's threads give the bits of the same chunks run on one thread."""
    import numba
    finals = []
    before = numba.get_num_threads()
    try:
        for threads in (1, numba.config.NUMBA_NUM_THREADS):
            numba.set_num_threads(threads)
            scene = sheared_gas(1, parallel=True)
            assert scene.chunks > 1 or numba.config.NUMBA_NUM_THREADS == 1
            dk.Simulation(scene, dk.VelocityVerlet(1e-3)).run(duration=0.2, progress=False)
            finals.append((scene.particles.position.copy(), scene.particles.velocity.copy()))
    finally:
        numba.set_num_threads(before)
    assert finals[0][0].tobytes() == finals[1][0].tobytes() and finals[0][1].tobytes() == finals[1][1].tobytes()


def test_the_lists_hold_every_pair_through_the_sliding_images():
    """At a fast shear (the images slide at u = 3 L = 45 per time unit, 15 skins per 0.1) the pairs the
    dipole loop acts on are exactly those within its cutoff under the sliding images, found here by
    brute force over all pairs with dk.Box.minimum_image at the scene's time (1e-9 of the cutoff left
    for rounding at the edge), and their separations are the brute force's to round-off. The lists,
    which cover 3 skins of sliding ahead, were rebuilt 11 times in the 120 steps (20 when they covered
    none)."""
    scene = sheared_gas(1, rate=3.0)
    sim = dk.Simulation(scene, dk.VelocityVerlet(1e-3))
    for _ in range(6):
        sim.run(duration=0.02, progress=False)
        assert_dipole_pairs_by_brute_force(scene, 3.0)
    assert scene.counters[0] >= 5, "the lists were rebuilt as the images slid (11 times in 120 steps)"


def test_clusters_contacts_and_overlap_notes_take_the_sliding_images_at_the_frames_time():
    """dk.clustering's pairs in a sheared box (a k-d tree over the sliding copies one period up and down
    the gradient) against brute force over every pair with Box.minimum_image at the frame's time: the same
    pairs and distances (to round-off), pairs through the sliding boundary among them, at several times
    (delta from 0 to most of L_a); without a time a sheared box refuses, rather than using delta = 0."""
    from types import SimpleNamespace

    from demkit import clustering, notes
    from demkit.viz.plan import Colouring
    rng = np.random.default_rng(8)
    size = np.array([6.0, 5.0, 4.0])
    box = dk.Box(size, periodic=True, shear=dk.Shear(0.37, "x", "y"))
    x = rng.uniform(0.0, 1.0, (300, 3)) * size
    radius = np.full(300, 0.25)
    i, j = np.triu_indices(300, k=1)
    across = 0
    for t in (0.0, 0.9, 2.3, 3.1):
        d = np.linalg.norm(box.minimum_image(x[j] - x[i], t), axis=1)
        near = d < 0.6
        pairs, r = clustering.close_pairs(x, radius, box, extra=0.1, distances=True, time=t)
        assert {tuple(p) for p in pairs} == set(zip(i[near], j[near]))
        np.testing.assert_allclose(np.sort(r), np.sort(d[near]), rtol=0, atol=1e-12)
        across += int(np.sum(near & (np.abs(x[j, 1] - x[i, 1]) > 2.5)))
        labels = clustering.clusters(x, radius, box, gap=0.1, time=t)
        assert np.all(labels[i[near]] == labels[j[near]])  # every close pair in one cluster
        touching = d < 0.5 * 1.01  # pictures coloured by contacts count them at the frame's time
        frames = SimpleNamespace(position=x[None], radius=radius, box=box, time=np.array([t]))
        count = Colouring(frames, "contacts", None, None, [0], lambda k: np.ones(300, bool), None).values(0)
        assert np.array_equal(count, np.bincount(np.r_[i[touching], j[touching]], minlength=300))
    assert across > 10
    with pytest.raises(ValueError, match="time"):
        clustering.close_pairs(x, radius, box)
    with pytest.raises(ValueError, match="time"):
        box.minimum_image(x[1] - x[0])
    # the run's overlap notes read frames at their times: two spheres overlapping through the boundary
    pair = np.array([[3.0, 0.1, 2.0], [3.0 + box.shear.offset(size, 1.5) - 0.4, 4.95, 2.0]])
    overlap = notes.frame_overlaps(pair, np.full(2, 0.25), box, True, [], time=1.5)
    assert overlap == pytest.approx([(0.5 - np.hypot(0.4, 0.15)) / 0.25], rel=1e-12)


def test_induced_moments_see_the_sliding_images_as_a_box_drawn_out_by_hand():
    """Magnetisable spheres in a sheared box (flow x, gradient y, offset delta = 2.4 at t = 0.4): the
    moments demkit's solve gives (conjugate gradients to 1e-13) against a dense solve of
    m_i = alpha_i (B_0 + sum_j T(d_ij) m_j) over the images written out by hand, x_j + n_b L e_y +
    (n_b delta + n_a L) e_x + n_c L e_z, |n| <= 1, within the cutoff (2 < L/2: one image of each pair at
    most); two spheres meet only through the sliding image (0.6 apart there, 2.4 through the fixed
    box's image, beyond the cutoff). Agreement to 1e-11 of the largest moment (the solves' round-off
    and the tolerance times a condition number below 10); without the slide the moments differ by
    far more."""
    L, R, A, cutoff = 6.0, 0.25, 0.5, 2.0
    pos = np.array([[1.0, 0.3, 3.0], [3.4, 5.7, 3.0], [1.3, 1.2, 3.4], [4.9, 4.8, 2.6], [2.7, 2.9, 2.0],
                    [0.4, 3.9, 4.4], [5.6, 0.8, 1.1], [3.8, 2.2, 5.5]])
    n = len(pos)
    chi = np.array([3.0, 3.0, 0.0, 3.0, 3.0, 0.0, 1.5, 3.0])  # two permanent moments, six induced
    moment = np.zeros((n, 3))
    moment[2] = [0.0, 0.4, 0.1]
    moment[5] = [0.3, 0.0, -0.2]
    field = np.array([0.05, 0.0, 0.1])
    box = dk.Box(L, periodic=True, shear=dk.Shear(1.0, "x", "y"))
    p = dk.Particles(position=pos, radius=R, mass=1.0, dipole=moment, susceptibility=chi)
    scene = dk.Scene(p, [dk.Dipole(prefactor=A, cutoff=cutoff, induction=dk.Induction(1e-13, 200)),
                         dk.UniformField(field)], box=box)
    scene.time = 0.4
    scene.induce()
    delta = box.shear.offset(box.size, scene.time)
    assert abs(delta - 2.4) < 1e-12

    def by_hand(slide):
        alpha = chi / (chi + 3.0) * R ** 3 / A
        tensor = np.zeros((n, 3, n, 3))  # B_i = sum_j tensor[i, :, j, :] m_j
        for i in range(n):
            for j in range(n):
                for nb, na, nc in np.ndindex(3, 3, 3):
                    nb, na, nc = nb - 1, na - 1, nc - 1
                    if i == j and nb == na == nc == 0:
                        continue
                    image = pos[j] + [nb * slide + na * L, nb * L, nc * L]
                    d = image - pos[i]
                    r = np.linalg.norm(d)
                    if r < cutoff:
                        tensor[i, :, j, :] += A * (3.0 * np.outer(d, d) / r ** 5 - np.eye(3) / r ** 3)
        free = np.flatnonzero(chi > 0)
        fixed = np.flatnonzero(chi == 0)
        t_ff = tensor[np.ix_(free, range(3), free, range(3))].reshape(3 * len(free), 3 * len(free))
        t_fp = tensor[np.ix_(free, range(3), fixed, range(3))].reshape(3 * len(free), 3 * len(fixed))
        a = np.repeat(alpha[free], 3)
        rhs = a * (np.tile(field, len(free)) + t_fp @ moment[fixed].ravel())
        solved = moment.copy()
        solved[free] = np.linalg.solve(np.eye(3 * len(free)) - a[:, None] * t_ff, rhs).reshape(-1, 3)
        return solved

    expected = by_hand(delta)
    scale = np.abs(expected).max()
    assert np.abs(scene.particles.dipole - expected).max() < 1e-11 * scale
    assert np.abs(by_hand(0.0) - expected).max() > 1e-3 * scale  # the sliding image matters here


def test_a_free_sphere_across_the_sliding_boundary_keeps_its_straight_path_and_its_angular_momentum():
    """A sphere in free flight crossing the gradient axis of a sheared box three times: its continued
    (unwrapped) path is the straight line x_0 + v_0 t and its continued velocity v_0 throughout (to
    round-off), although each crossing shifts its wrapped position by the offset and its velocity by
    gammadot L_b; so its angular momentum about the origin, recorded and from the scene, stays
    m x_0 x v_0 + I w_0 (a free body's, conserved), where the wrapped values jump at each crossing."""
    L = 5.0
    box = dk.Box(L, periodic=True, shear=dk.Shear(0.7, "x", "y"))
    x0, v0, w0 = np.array([[1.0, 4.0, 2.0], [3.0, 1.0, 4.0]]), np.array([[0.3, 2.0, 0.2], [0.0, 0.0, 0.0]]), \
        np.array([[0.1, 0.0, 0.5], [0.0, 0.0, 0.0]])
    p = dk.Particles(position=x0, velocity=v0, angular_velocity=w0, radius=0.25, mass=[2.0, 1.0])
    scene = dk.Scene(p, [dk.KelvinVoigt(100.0, 0.1)], box=box)
    sim = dk.Simulation(scene, dk.VelocityVerlet(1e-3))
    traj = sim.run(7.0, record_every=0.05, progress=False)
    assert traj.image[-1, 0, 1] == 3 and np.ptp(traj.velocity[:, 0, 0]) > 3.0  # wrapped: jumps of 0.7 L
    t = np.asarray(traj.time)[:, None]
    assert np.abs(traj.unwrapped()[:, 0] - (x0[0] + v0[0] * t)).max() < 1e-11
    assert np.abs(traj.unwrapped_velocity()[:, 0] - v0[0]).max() < 1e-12
    expected = 2.0 * np.cross(x0[0], v0[0]) + p.inertia[0] * w0[0]
    assert np.abs(traj.angular_momentum - expected).max() < 1e-10
    assert np.abs(scene.angular_momentum() - expected).max() < 1e-10


def test_the_time_step_limit_of_hertz_contacts_counts_the_imposed_flow():
    """Hertz contacts limit the step by the contact time at the impact speed (2 max|v|; none at rest). In a
    sheared box the flow drives spheres into the images sliding by at u = gammadot L_b, so spheres at rest
    still get a finite limit: the Hertz contact time at impact speed 2 max|v| + |u| (by hand: a tenth of
    2.87 (m*^2 / (R* E*^2 v))^(1/5), Hertz's duration of an impact at v)."""
    n, R = 40, 0.5
    size = dk.build.box_for(n, R, 0.3).size
    pos = dk.build.random_packing(n, R, dk.Box(size, periodic=True), seed=2)
    law = dk.Hertz(young=1e5, poisson=0.3, restitution=0.5)

    def scene(rate, velocity):
        box = dk.Box(size, periodic=True, shear=dk.Shear(rate, "z", "x")) if rate else dk.Box(size, periodic=True)
        return dk.Scene(dk.Particles(position=pos, velocity=velocity, radius=R, mass=1.0), [law], box=box)

    rest = np.zeros((n, 3))
    assert scene(None, rest).max_time_step() == float("inf")
    e_star = 1e5 / (2 * (1 - 0.3 ** 2))
    by_hand = lambda v: 0.1 * 2.87 * ((0.5 ** 2) / ((R / 2) * e_star ** 2 * v)) ** 0.2  # noqa: E731
    u = 0.5 * size[0]
    assert scene(0.5, rest).max_time_step() == pytest.approx(by_hand(u), rel=2e-3)
    moving = np.zeros((n, 3))
    moving[0, 1] = 0.3
    assert scene(-0.5, moving).max_time_step() == pytest.approx(by_hand(0.6 + u), rel=2e-3)
    assert scene(None, moving).max_time_step() == pytest.approx(by_hand(0.6), rel=2e-3)
    # the guards' largest safe step counts the same approach speed: a step between it and the limit
    # without the flow is refused, naming the images' sliding
    fast = scene(20.0, rest)
    limit = fast.max_time_step()
    assert limit == pytest.approx(by_hand(20.0 * size[0]), rel=2e-3)
    with pytest.raises(ValueError, match="sheared box's images slide by"):
        dk.Simulation(fast, dk.VelocityVerlet(1.5 * limit))
    dk.Simulation(fast, dk.VelocityVerlet(limit))  # (accepted: the guards run as the simulation is made)
