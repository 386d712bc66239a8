"""demkit.export_lammps: a scene as a LAMMPS data file and input deck.

Always tested: the data file read back gives the scene (positions, images, radii, masses, moments,
velocities, spins), the deck holds the mapped parameters, and what LAMMPS cannot represent or would
run differently is refused with a message naming it. Where ``lmp`` is installed (Debian package
``lammps``, 29 Sep 2021) the exported decks run 100 steps and are compared with demkit's
VelocityVerlet (measured figures in docs/lammps_export.md):

* two magnets in contact with friction in a uniform field: positions 2e-11, velocities 3e-10,
  spins 7e-9, moments 9e-9 (LAMMPS turns the moments by the DLM splitting, demkit exactly);
* 27 spheres in a box periodic in x and y on a wall, Hooke contacts with friction and rolling
  resistance, gravity: round-off (2e-14);
* Hertz spheres with Mindlin friction, Hertz spheres on a Hertz wall, a fixed sphere: round-off.
"""
import math
import shutil
import subprocess
import textwrap

import numpy as np
import pytest

import demkit as dk
from demkit.lammps import read_dump, tsuji_coefficient, tsuji_polynomial

needs_lammps = pytest.mark.skipif(shutil.which("lmp") is None,
                                  reason="LAMMPS (lmp, Debian package 'lammps') is not installed")
DT = 1e-3
STEPS = 100


def read_data(path):
    """(atoms, velocities) of an exported data file, rows sorted by id: atoms columns id type x y z
    diameter density q mux muy muz ix iy iz; velocities id vx vy vz wx wy wz."""
    lines = path.read_text().splitlines()

    def section(name):
        start = lines.index(name) + 2
        rows = []
        for line in lines[start:]:
            if not line.strip():
                break
            rows.append([float(v) for v in line.split()])
        return np.array(rows)

    return section("Atoms # hybrid"), section("Velocities")


def two_magnets(field=True):
    """Two magnets touching and turning, with friction (LAMMPS' rule), unequal masses, a uniform field."""
    pos = np.array([[0.0, 0.0, 0.0], [0.98, 0.15, 0.05]])
    n = (pos[1] - pos[0]) / np.linalg.norm(pos[1] - pos[0])
    p = dk.Particles(position=pos, velocity=[[0.3, 0.05, 0], [-0.3, 0, 0.02]], radius=0.5, mass=[1.0, 1.3],
                     dipole=[n, [0.6, 0.8, 0.0]], angular_velocity=[[0.1, 2.0, -0.5], [0.3, 0.2, 1.0]])
    contact = dk.KelvinVoigt(2000.0, 2.0, friction=dk.Friction(0.4, slip_radius="full", sliding="lammps"))
    effects = [dk.UniformField([0.2, -0.1, 0.3])] if field else []
    return dk.Scene(p, [dk.Dipole(prefactor=0.7), contact] + effects)


def granular_box():
    """27 spheres (unequal radii and masses, spinning) in a box periodic in x and y on a frictionless
    wall at z = 0, Hooke contacts with friction and rolling resistance, gravity."""
    rng = np.random.default_rng(3)
    grid = np.array([(i, j, k) for i in range(3) for j in range(3) for k in range(3)], float)
    pos = grid * 0.97 + np.array([0.012, 0.5, 0.49]) + rng.uniform(-0.01, 0.01, (27, 3))
    velocity = rng.normal(0, 0.5, (27, 3))
    velocity[:9, 0] -= 0.6  # the layer at x = 0.012 crosses the periodic boundary
    p = dk.Particles(position=pos, velocity=velocity, radius=0.5 * rng.uniform(0.95, 1.0, 27),
                     mass=rng.uniform(0.8, 1.2, 27), angular_velocity=rng.normal(0, 2, (27, 3)))
    contact = dk.KelvinVoigt(1000.0, 1.5, friction=dk.Friction(0.5, slip_radius="full", sliding="lammps"),
                             rolling=dk.RollingResistance(0.1))
    wall = dk.Wall([0, 0, 0], [0, 0, 1], contact=dk.KelvinVoigt(1000.0, 1.5))
    box = dk.Box([2.91, 2.91, 6.0], periodic=(True, True, False))
    return dk.Scene(p, [contact, wall, dk.Gravity([0, 0, -9.81])], box=box)


def hertz_pairs():
    """Four Hertz spheres with Mindlin friction colliding in open space."""
    pos = np.array([[0.0, 0.0, 0.0], [0.99, 0.1, 0.0], [0.0, 1.0, 0.05], [2.5, 0.0, 0.0]])
    p = dk.Particles(position=pos, velocity=[[0.5, 0.0, 0.1], [-0.4, 0.1, 0.0], [0.1, -0.6, 0.0], [0.0, 0.0, 0.0]],
                     radius=[0.5, 0.5, 0.48, 0.5], mass=[1.0, 1.1, 0.9, 1.0],
                     angular_velocity=[[0, 0, 3.0], [1.0, 0, 0], [0, 2.0, 0], [0, 0, 0]])
    law = dk.Hertz(young=2e4, poisson=0.3, restitution=0.8,
                   friction=dk.Friction(0.3, slip_radius="full", sliding="lammps"))
    return dk.Scene(p, [law])


def run_lammps(files):
    """The dumped frames of an exported deck run in its folder."""
    folder = files.deck.parent
    done = subprocess.run(["lmp", "-in", files.deck.name, "-screen", "none", "-log", "log.lammps", "-nocite"],
                          cwd=folder, capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, (folder / "log.lammps").read_text()[-2000:]
    return read_dump(folder / "state.dump")


def differences(scene, frames, steps=STEPS):
    """Largest differences (position, velocity, spin, moment) between LAMMPS' frames and demkit's
    VelocityVerlet run of the same scene, over every step."""
    traj = dk.Simulation(scene, dk.VelocityVerlet(DT)).run(duration=steps * DT, record_every=DT)
    x = traj.unwrapped()
    out = np.zeros(4)
    for k in range(steps + 1):
        theirs = frames[k]
        spin = traj.angular_velocity[k] if traj.angular_velocity is not None else np.zeros_like(x[k])
        ours = [x[k], traj.velocity[k], spin,
                traj.dipole[k] if traj.dipole is not None else theirs[:, 10:13]]
        for c, value in enumerate(ours):
            out[c] = max(out[c], np.abs(value - theirs[:, 1 + 3 * c:4 + 3 * c]).max())
    return out, traj


# ---- writing (always) ---------------------------------------------------------------------------

def test_data_file_reads_back_as_the_scene(tmp_path):
    scene = granular_box()
    p = scene.particles
    p.position[0, 0] += 2 * 2.91 + 0.3  # outside the periodic box: wrapped, two images along x
    start = p.position.copy()
    files = dk.export_lammps(scene, dk.VelocityVerlet(DT), tmp_path, duration=0.1)
    atoms, velocities = read_data(files.data)
    np.testing.assert_array_equal(atoms[:, 0], np.arange(1, 28))
    assert set(atoms[:, 1]) == {1.0}
    unwrapped = atoms[:, 2:5] + atoms[:, 11:14] * np.array([2.91, 2.91, 6.0])
    np.testing.assert_allclose(unwrapped, start, rtol=0, atol=1e-14)
    assert atoms[0, 11] == 2 and 0 <= atoms[0, 2] < 2.91
    assert np.all((atoms[:, 2:4] >= 0) & (atoms[:, 2:4] < 2.91)) and np.all(atoms[:, 13] == 0)
    np.testing.assert_array_equal(atoms[:, 5], 2 * p.radius)
    np.testing.assert_allclose(atoms[:, 6] * math.pi / 6 * atoms[:, 5] ** 3, p.mass, rtol=1e-15)
    np.testing.assert_array_equal(velocities[:, 1:4], p.velocity)
    np.testing.assert_array_equal(velocities[:, 4:7], p.angular_velocity)
    header = files.data.read_text().splitlines()
    assert "0 2.9100000000000001 xlo xhi" in header and "0 2.9100000000000001 ylo yhi" in header


def test_deck_maps_the_interactions(tmp_path):
    files = dk.export_lammps(granular_box(), dk.VelocityVerlet(DT), tmp_path, duration=0.1, record_every=0.01)
    deck = files.deck.read_text()
    assert "boundary    p p s" in deck
    # k_t = 2/7 k_n, tangential damping ratio sqrt(k_t/k_n), rolling k_r = 2.25 mu_r^2 k_n
    assert ("pair_coeff  * * hooke 1000 1.5 tangential linear_history 285.71428571428572 0.53452248382484879 0.5 "
            "rolling sds 22.500000000000007 0.22500000000000003 0.10000000000000001 damping velocity") in deck
    assert "wall/gran granular hooke 1000 1.5 tangential linear_nohistory 0.0 0.0 damping velocity zplane 0 NULL" in deck
    assert "gravity 9.8100000000000005 vector 0 0 -9.8100000000000005" in deck
    assert "variable    nsteps index 100" in deck and "variable    dumpevery index 10" in deck
    assert files.notes == ()


def test_moments_are_scaled_by_the_root_of_the_prefactor(tmp_path):
    scene = two_magnets()
    files = dk.export_lammps(scene, dk.VelocityVerlet(DT), tmp_path, duration=0.1)
    atoms, _ = read_data(files.data)
    s = math.sqrt(0.7)
    np.testing.assert_allclose(atoms[:, 8:11] / s, scene.particles.dipole, rtol=1e-15)
    deck = files.deck.read_text()
    e = np.array([0.2, -0.1, 0.3]) / s  # torque mu x E = m x B
    assert f"efield {e[0]:.17g} {e[1]:.17g} {e[2]:.17g}" in deck
    assert "update dipole/dlm" in deck and "neighbor    0.29999999999999999 nsq" in deck
    assert any("no cutoff" in note for note in files.notes)  # open space: the dipole reach chosen is noted


def test_tsuji_coefficient_inverts_lammps_polynomial():
    for gamma in (1e-3, 0.05, 0.3, 0.8):
        alpha = gamma * math.sqrt(1.5)
        c = tsuji_coefficient(alpha)
        assert 0 < c < 1 and abs(tsuji_polynomial(c) - alpha) <= 1e-15 + 1e-15 * alpha  # LAMMPS' round-off
    with pytest.raises(ValueError, match="outside the range"):
        tsuji_coefficient(2.0)


def test_deck_without_duration_asks_for_the_number_of_steps(tmp_path):
    files = dk.export_lammps(two_magnets(), dk.VelocityVerlet(DT), tmp_path)
    deck = files.deck.read_text()
    assert "variable    nsteps" not in deck and "-var nsteps N" in deck


@pytest.mark.parametrize("make, message", [
    (lambda: dk.Scene(dk.Particles([[0, 0, 0], [2, 0, 0]], dipole=[[0, 0, 1], [0, 0, 1]]),
                      [dk.PowerLawDipole(1.0)]), "PowerLawDipole"),
    (lambda: dk.Scene(dk.Particles([[0, 0, 0], [2, 0, 0]], dipole=[[0, 0, 1], [0, 0, 1]]),
                      [dk.Dipole(1.0, cutoff=3.0, switch_width=1.0)]), "switch_width"),
    (lambda: dk.Scene(dk.Particles([[0, 0, 0], [2, 0, 0]], inertia_factor=0.5), [dk.KelvinVoigt(10.0)]),
     "inertia_factor"),
    (lambda: dk.Scene(dk.Particles([[1, 1, 1]]), [dk.KelvinVoigt(10.0), dk.Wall([0, 0, 0], [1, 1, 0],
                                                                                 velocity=[1, -1, 0])]),
     "oblique wall that slides"),
    (lambda: dk.Scene(dk.Particles([[1, 1, 1]]), [dk.KelvinVoigt(10.0), dk.Wall([0, 0, 0], [0, 1, 1])],
                      box=dk.Box(5.0, periodic=(False, True, False))), "periodic axis y"),
    (lambda: dk.Scene(dk.Particles([[1, 1, 1]]), [dk.KelvinVoigt(10.0), dk.Wall([0, 0, 0], [0, 0, 1])],
                      box=dk.Box(5.0, periodic=True)), "periodic axis z"),
    (lambda: dk.Scene(dk.Particles([[0, 0, 0], [2, 0, 0]]),
                      [dk.Hertz(1e4, 0.3, 0.9, friction=dk.Friction(0.3, stiffness=10.0, slip_radius="full",
                                                                    sliding="lammps"))]), "Mindlin"),
    (lambda: dk.Scene(dk.Particles([[0, 0, 0], [2, 0, 0]]),
                      [dk.KelvinVoigt(10.0, friction=dk.Friction(0.3, damping=1.0, slip_radius="full",
                                                                 sliding="lammps"))]), "multiple of the normal"),
])
def test_what_lammps_cannot_represent_is_refused(tmp_path, make, message):
    with pytest.raises(ValueError, match=message):
        dk.export_lammps(make(), dk.VelocityVerlet(DT), tmp_path, duration=0.1)


def test_custom_pair_interaction_is_refused(tmp_path):
    from plugin_interactions import Poison
    scene = dk.Scene(dk.Particles([[0, 0, 0], [2, 0, 0]]), [Poison(1.0)])
    with pytest.raises(ValueError, match="Poison.*no LAMMPS equivalent"):
        dk.export_lammps(scene, dk.VelocityVerlet(DT), tmp_path, duration=0.1)


def test_differences_are_refused_when_strict_and_noted_otherwise(tmp_path):
    p = dk.Particles([[1, 1, 0.55], [1.9, 1, 0.6]], radius=0.5)
    scene = dk.Scene(p, [dk.KelvinVoigt(100.0, 1.0, friction=dk.Friction(0.3)), dk.Wall([0, 0, 0], [0, 0, 1])])
    with pytest.raises(ValueError, match="sliding='lammps'"):
        dk.export_lammps(scene, dk.VelocityVerlet(DT), tmp_path, duration=0.1)
    with pytest.raises(ValueError, match="EulerCromer.*velocity Verlet"):
        dk.export_lammps(granular_box(), dk.EulerCromer(DT), tmp_path, duration=0.1)
    files = dk.export_lammps(scene, dk.EulerCromer(DT), tmp_path, duration=0.1, strict=False)
    notes = " | ".join(files.notes)
    assert "EulerCromer" in notes and "sliding" in notes and "lever arm" in notes  # the wall's friction torque
    assert notes.count("NOTE") == 0 and files.deck.read_text().count("# NOTE:") == len(files.notes) == 4
    with pytest.raises(ValueError, match="whole number of time steps"):
        dk.export_lammps(granular_box(), dk.VelocityVerlet(DT), tmp_path, duration=0.10005)


def test_stored_friction_history_is_refused(tmp_path):
    scene = granular_box()
    dk.Simulation(scene, dk.VelocityVerlet(DT)).run(duration=5 * DT)
    with pytest.raises(ValueError, match="contact history"):
        dk.export_lammps(scene, dk.VelocityVerlet(DT), tmp_path, duration=0.1)


def test_command_line_exports_a_python_scene_file(tmp_path):
    from demkit.cli import main
    (tmp_path / "magnets.py").write_text(textwrap.dedent("""
        import demkit as dk
        p = dk.Particles(position=[[0, 0, 0], [1.5, 0, 0]], dipole=[[1, 0, 0], [1, 0, 0]], radius=0.5)
        scene = dk.Scene(p, [dk.Dipole(1.0), dk.KelvinVoigt(1000.0, 1.0)])
        integrator = dk.VelocityVerlet(1e-3)
        duration = 0.5
    """))
    assert main(["export-lammps", str(tmp_path / "magnets.py"), str(tmp_path / "out")]) == 0
    deck = (tmp_path / "out" / "in.scene").read_text()
    assert "variable    nsteps index 500" in deck and (tmp_path / "out" / "scene.data").exists()


def test_command_line_export_follows_its_own_advice_with_set(tmp_path, capsys):
    """A frictional scene file is refused with advice the command line can follow (--set)."""
    from demkit.cli import main
    scene = tmp_path / "pile.toml"
    scene.write_text(textwrap.dedent("""
        [particles]
        position = [[0.0, 0.0, 0.5], [1.02, 0.0, 0.5]]
        radius = 0.5
        [interactions.kelvin_voigt]
        stiffness = 1000.0
        damping = 1.0
        [interactions.friction]
        coefficient = 0.5
        [integrator]
        method = "VelocityVerlet"
        dt = 0.001
        [run]
        duration = 0.1
    """))
    with pytest.raises(SystemExit):
        main(["export-lammps", str(scene), str(tmp_path / "out")])
    assert ("--set interactions.friction.slip_radius=full --set interactions.friction.sliding=lammps"
            in capsys.readouterr().err)
    assert main(["export-lammps", str(scene), str(tmp_path / "out"), "--set", "interactions.friction.slip_radius=full",
                 "--set", "interactions.friction.sliding=lammps"]) == 0
    assert "pair_style  granular" in (tmp_path / "out" / "in.scene").read_text()
    (tmp_path / "pile.py").write_text("raise RuntimeError('never run')\n")
    with pytest.raises(SystemExit):
        main(["export-lammps", str(tmp_path / "pile.py"), str(tmp_path / "out"), "--set", "run.duration=1"])
    assert "--set changes keys of TOML scene files" in capsys.readouterr().err


# ---- running LAMMPS ----------------------------------------------------------------------------

@needs_lammps
def test_two_magnets_agree_with_lammps_after_100_steps(tmp_path):
    scene = two_magnets()
    files = dk.export_lammps(scene, dk.VelocityVerlet(DT), tmp_path, duration=STEPS * DT, record_every=DT)
    frames = run_lammps(files)
    (dx, dv, dw, dm), traj = differences(scene, frames)
    separation = np.linalg.norm(traj.position[:, 1] - traj.position[:, 0], axis=1)
    assert separation.min() < 0.99 and separation.max() > 1.0  # they touch, press and part
    assert np.abs(traj.angular_velocity).max() > 1.0
    # measured 2e-11, 3e-10, 7e-9, 9e-9: the dipoles turn by DLM splitting in LAMMPS, exactly in demkit
    assert dx < 1e-9 and dv < 1e-8 and dw < 3e-8 and dm < 3e-8
    assert dm > 1e-12  # the dipole updates do differ


@needs_lammps
def test_lammps_default_dipole_update_is_first_order(tmp_path):
    scene = two_magnets(field=False)
    files = dk.export_lammps(scene, dk.VelocityVerlet(DT), tmp_path, duration=STEPS * DT, record_every=DT,
                             dipole_update="euler")
    assert "update dipole\n" in files.deck.read_text()
    (dx, dv, dw, dm), _ = differences(scene, run_lammps(files))
    assert 1e-7 < dm < 1e-4  # measured 1.7e-5: renormalised Euler step, spins not perpendicular to the moments


@needs_lammps
def test_periodic_granular_box_on_a_wall_agrees_to_round_off(tmp_path):
    scene = granular_box()
    files = dk.export_lammps(scene, dk.VelocityVerlet(DT), tmp_path, duration=STEPS * DT, record_every=DT)
    (dx, dv, dw, _), traj = differences(scene, run_lammps(files))
    contacts = scene.contacts()
    assert len(contacts.pairs) > 20 and contacts.sliding.any()  # many contacts, some sliding, at the end
    assert traj.unwrapped()[:, :, 0].min() < 0.0  # spheres cross the periodic boundary
    assert dx < 1e-12 and dv < 1e-12 and dw < 1e-11  # measured 4e-16, 7e-15, 2e-14


@needs_lammps
def test_hertz_with_mindlin_friction_agrees_to_round_off(tmp_path):
    scene = hertz_pairs()
    files = dk.export_lammps(scene, dk.VelocityVerlet(DT), tmp_path, duration=STEPS * DT, record_every=DT)
    assert "damping tsuji limit_damping" in files.deck.read_text()
    (dx, dv, dw, _), traj = differences(scene, run_lammps(files))
    assert np.abs(traj.velocity[-1] - traj.velocity[0]).max() > 0.1  # the collisions changed the motion
    assert dx < 1e-12 and dv < 1e-10 and dw < 1e-10


@needs_lammps
def test_fixed_sphere_and_sliding_wall_agree_to_round_off(tmp_path):
    p = dk.Particles(position=[[1, 1, 0.5], [1.1, 1.05, 1.48], [2.5, 1, 0.52]], radius=0.5,
                     velocity=[[0, 0, 0], [0.2, 0, -0.3], [0, 0, 0]], angular_velocity=[[0, 0, 0], [1, 0, 0], [0, 0, 0]],
                     fixed=[True, False, False])
    law = dk.KelvinVoigt(1000.0, 1.0, friction=dk.Friction(0.4, slip_radius="full", sliding="lammps"))
    wall = dk.Wall([0, 0, 0], [0, 0, 1], velocity=[0.3, 0, 0], contact=dk.KelvinVoigt(1000.0, 1.0))
    scene = dk.Scene(p, [law, wall, dk.Gravity([0, 0, -1])], box=dk.Box([4, 4, 4], periodic=(True, True, False)))
    files = dk.export_lammps(scene, dk.VelocityVerlet(DT), tmp_path, duration=STEPS * DT, record_every=DT)
    deck = files.deck.read_text()
    assert "fix         hold fixed freeze" in deck and "zplane 0 NULL shear x 0.29999999999999999" in deck
    (dx, dv, dw, _), traj = differences(scene, run_lammps(files))
    assert np.all(traj.position[:, 0] == p.position[0]) and abs(traj.velocity[-1, 1, 1]) > 0.1  # deflected
    assert dx < 1e-12 and dv < 1e-12 and dw < 1e-12  # measured 0, 3e-16, 4e-16


@needs_lammps
def test_spheres_on_a_vibrated_wall_agree_with_lammps_wiggle(tmp_path):
    """A plate vibrated along its normal (demkit's amplitude/frequency, LAMMPS' wiggle: both
    A (1 - cos 2 pi f t), the wall evaluated at the end of each step) throws up two spheres with
    friction. LAMMPS' omega is 2 pi / period with the period printed at 17 digits, so the walls may
    differ in the last bit: agreement to 1e-13 (measured 3e-16 in position and velocity, 0 in spin,
    LAMMPS 7 Jan 2022)."""
    p = dk.Particles(position=[[0, 0, 0.499], [1.3, 0.2, 0.52]], velocity=[[0.1, 0, 0.0], [0, 0.1, -0.2]],
                     angular_velocity=[[0, 2.0, 0], [0, 0, 0]], radius=0.5)
    law = dk.KelvinVoigt(1000.0, 1.0, friction=dk.Friction(0.4, slip_radius="full", sliding="lammps"))
    plate = dk.Wall([0, 0, 0], [0, 0, 1], amplitude=[0, 0, 0.02], frequency=5.0,
                    contact=dk.KelvinVoigt(1000.0, 1.0))
    scene = dk.Scene(p, [law, plate, dk.Gravity([0, 0, -1])])
    files = dk.export_lammps(scene, dk.VelocityVerlet(DT), tmp_path, duration=3 * STEPS * DT, record_every=DT)
    assert "zplane 0 NULL wiggle z 0.02 0.2" in files.deck.read_text()
    (dx, dv, dw, _), traj = differences(scene, run_lammps(files), steps=3 * STEPS)
    assert traj.velocity[:, 0, 2].max() > 0.3  # thrown up by the plate (its top speed 0.63)
    assert dx < 1e-13 and dv < 1e-13 and dw < 1e-13


@needs_lammps
def test_hertz_spheres_bouncing_on_a_hertz_wall_agree_to_round_off(tmp_path):
    p = dk.Particles(position=[[0, 0, 0.5], [1.2, 0.2, 0.51]], velocity=[[0.1, 0, -1.0], [0, 0.1, -0.5]],
                     radius=[0.5, 0.52], mass=[1.0, 1.2])
    law = dk.Hertz(young=2e4, poisson=0.3, restitution=0.7)
    scene = dk.Scene(p, [law, dk.Wall([0, 0, 0], [0, 0, 1]), dk.Gravity([0, 0, -1])])
    files = dk.export_lammps(scene, dk.VelocityVerlet(DT), tmp_path, duration=STEPS * DT, record_every=DT)
    young = 2 * 2e4 / 1.3  # LAMMPS' wall formula 4/3 E/(2 (1 - nu)) then gives demkit's 4/3 E/(1 - nu^2)
    assert f"wall/gran granular hertz/material {young:.17g} " in files.deck.read_text()
    (dx, dv, dw, _), traj = differences(scene, run_lammps(files))
    assert traj.velocity[-1, 0, 2] > 0.3  # bounced off the wall (e = 0.7)
    assert dx < 1e-12 and dv < 1e-12 and dw == 0.0


def tilted_walls():
    """A sphere sliding down a tilted Kelvin-Voigt wall (resting on it at its equilibrium overlap) and
    one bouncing off another tilted wall with its own Hertz law, under gravity: oblique walls."""
    na, nb = np.array([0.3, -0.2, 1.0]), np.array([-0.5, 0.1, 1.0])
    na, nb = na / np.linalg.norm(na), nb / np.linalg.norm(nb)
    pa, pb = np.array([0.2, 0.1, 0.3]), np.array([5.0, 0.0, 0.0])
    downhill = np.array([0, 0, -1.0]) + na[2] * na
    x0 = pa + (0.5 - 1.0 * na[2] / 1000.0) * na  # overlap m g n_z / k: pressed on by gravity
    x1 = pb + np.array([0.3, 0.2, 0.0])
    x1 += (0.51 - (x1 - pb) @ nb) * nb
    p = dk.Particles(position=[x0, x1], velocity=[0.5 * downhill, -1.0 * nb + [0.1, 0.2, 0]],
                     angular_velocity=[[0, 0, 0], [1.0, 0, 2.0]], radius=[0.5, 0.52], mass=[1.0, 1.2])
    hertz = dk.Hertz(young=2e4, poisson=0.3, restitution=0.7)
    return dk.Scene(p, [dk.KelvinVoigt(1000.0, 1.0), dk.Wall(pa, na), dk.Wall(pb, nb, contact=hertz),
                        dk.Gravity([0, 0, -1])]), na, nb


@needs_lammps
def test_oblique_walls_agree_to_round_off(tmp_path):
    scene, na, nb = tilted_walls()
    files = dk.export_lammps(scene, dk.VelocityVerlet(DT), tmp_path, duration=STEPS * DT, record_every=DT)
    deck = files.deck.read_text()
    assert "region      wallplane0 plane 0.20000000000000001 0.10000000000000001 0.29999999999999999 " in deck
    assert "wall/gran/region granular hooke 1000 1 " in deck and "wall/gran/region granular hertz/material" in deck
    (dx, dv, dw, _), traj = differences(scene, run_lammps(files))
    height = (traj.position[:, 0] - [0.2, 0.1, 0.3]) @ na
    assert height.max() < 0.5 and abs(traj.velocity[-1, 0] @ na) < 1e-3  # slid in contact, did not bounce
    assert traj.velocity[-1, 0] @ traj.velocity[0, 0] > 1.05 * (traj.velocity[0, 0] @ traj.velocity[0, 0])
    assert traj.velocity[0, 1] @ nb < -0.9 and traj.velocity[-1, 1] @ nb > 0.5  # bounced (e = 0.7)
    assert dx < 1e-12 and dv < 1e-12 and dw == 0.0  # measured 7e-16, 1.2e-14


# ---- twisting resistance --------------------------------------------------------------------------

def twisting_pairs(twisting, hertz=False):
    """Three spheres touching, spinning strongly about their contact normals (the twist springs wind
    up and slide within the 100 steps), friction with LAMMPS' rules, twisting resistance."""
    pos = np.array([[0.0, 0.0, 0.0], [0.97, 0.12, 0.05], [0.1, 0.99, 0.0]])
    p = dk.Particles(position=pos, velocity=[[0.05, 0.0, 0.0], [-0.05, 0.0, 0.0], [0, -0.05, 0]], radius=0.5,
                     mass=[1.0, 1.2, 0.9], angular_velocity=[[0.5, 0.2, 3.0], [-2.0, 0.3, -4.0], [0, 5, 1]])
    friction = dk.Friction(0.4, slip_radius="full", sliding="lammps")
    if hertz:
        return dk.Scene(p, [dk.Hertz(young=2e4, poisson=0.3, restitution=0.8, friction=friction, twisting=twisting)])
    return dk.Scene(p, [dk.KelvinVoigt(2000.0, 2.0, friction=friction, twisting=twisting)])


def spinning_on_a_wall(twisting):
    """Two spheres resting on a Kelvin-Voigt wall under gravity, spinning about its normal (no slip at
    the contact point: the wall's friction lever, R in LAMMPS, R - delta in demkit, plays no part)."""
    p = dk.Particles(position=[[0, 0, 0.49], [1.5, 0, 0.495]], radius=0.5, mass=1.0,
                     angular_velocity=[[0, 0, 4.0], [0, 0, -1.0]])
    law = dk.KelvinVoigt(2000.0, 2.0, friction=dk.Friction(0.4, slip_radius="full", sliding="lammps"),
                         twisting=twisting)
    return dk.Scene(p, [law, dk.Wall((0, 0, 0), (0, 0, 1)), dk.Gravity((0, 0, -9.81))])


def test_twisting_resistance_maps_to_twisting_marshall_or_sds(tmp_path):
    deck = dk.export_lammps(twisting_pairs(dk.TwistingResistance()), dk.VelocityVerlet(DT), tmp_path,
                            duration=0.1).deck.read_text()
    assert ("pair_coeff  * * hooke 2000 2 tangential linear_history 571.42857142857144 0.53452248382484879 "
            "0.40000000000000002 twisting marshall damping velocity") in deck
    deck = dk.export_lammps(twisting_pairs(dk.TwistingResistance(0.5, 0.05, 0.02), hertz=True),
                            dk.VelocityVerlet(DT), tmp_path, duration=0.1).deck.read_text()
    assert "tangential mindlin NULL 0.9074852129730302 0.40000000000000002 twisting sds 0.5 0.050000000000000003 " \
           "0.02 damping tsuji limit_damping" in deck
    files = dk.export_lammps(spinning_on_a_wall(dk.TwistingResistance()), dk.VelocityVerlet(DT), tmp_path,
                             duration=0.1, strict=False)
    assert "twisting marshall damping velocity zplane 0 NULL" in files.deck.read_text()
    with pytest.raises(ValueError, match="either marshall .* or sds"):
        dk.export_lammps(twisting_pairs(dk.TwistingResistance(stiffness=0.5)), dk.VelocityVerlet(DT), tmp_path,
                         duration=0.1)
    scene = twisting_pairs(dk.TwistingResistance())
    dk.Simulation(scene, dk.VelocityVerlet(DT)).run(duration=5 * DT)
    with pytest.raises(ValueError, match="contact history"):  # wound twist springs
        dk.export_lammps(scene, dk.VelocityVerlet(DT), tmp_path, duration=0.1)


@needs_lammps
@pytest.mark.parametrize("twisting, hertz", [("marshall", False), ("sds", False), ("marshall", True)])
def test_twisting_resistance_agrees_with_lammps_to_round_off(tmp_path, twisting, hertz):
    def make():
        return twisting_pairs(dk.TwistingResistance() if twisting == "marshall" else
                              dk.TwistingResistance(0.5, 0.05, 0.02), hertz)

    files = dk.export_lammps(make(), dk.VelocityVerlet(DT), tmp_path, duration=STEPS * DT, record_every=DT)
    (dx, dv, dw, _), traj = differences(make(), run_lammps(files))
    untwisted = dk.Simulation(twisting_pairs(None, hertz), dk.VelocityVerlet(DT)).run(STEPS * DT)
    assert np.abs(traj.angular_velocity[-1] - untwisted.angular_velocity[-1]).max() > 5e-3  # it acted
    assert dx < 1e-12 and dv < 1e-12 and dw < 1e-12  # measured 9e-17, 3e-16, 2e-15


@needs_lammps
def test_twisting_against_a_wall_agrees_with_lammps_to_round_off(tmp_path):
    scene = spinning_on_a_wall(dk.TwistingResistance())
    files = dk.export_lammps(scene, dk.VelocityVerlet(DT), tmp_path, duration=STEPS * DT, record_every=DT,
                             strict=False)
    (dx, dv, dw, _), traj = differences(spinning_on_a_wall(dk.TwistingResistance()), run_lammps(files))
    assert abs(traj.angular_velocity[-1, 0, 2] - 4.0) > 0.01  # the table slowed the spin
    assert dx < 1e-12 and dv < 1e-12 and dw < 1e-12  # measured 0, 8e-17, 0


def drum_scene(friction):
    """Three spheres dropped just above the bottom of a drum (axis z, radius 3) turning at 2 rad/s
    under gravity -y: they land within 0.1 time units and bounce; with friction (LAMMPS' rules and
    lever arms) or without. None touches the drum at the start: LAMMPS takes a region's velocity
    from its motion since the step before, so at step 0 a turning region stands still (its first
    force on a sphere touching it at once lacks the friction of the turning, measured: the first
    velocity 4.9e-3 against 8.1e-3, then the same increments)."""
    pos = 0.985 * np.array([[0.0, -2.5, 0.0], [0.95, -2.33, 0.1], [-0.9, -2.36, -0.05]])
    p = dk.Particles(position=pos, radius=[0.5, 0.48, 0.5], mass=[1.0, 0.9, 1.1],
                     velocity=[[0.1, 0, 0], [0, 0, 0.05], [0, 0.02, 0]], angular_velocity=[[0, 0, 1.0], [0, 0, 0], [0.5, 0, 0]])
    f = dk.Friction(0.5, slip_radius="full", sliding="lammps") if friction else None
    law = dk.KelvinVoigt(2000.0, 2.0, friction=f)
    drum = dk.Cylinder([0, 0, 0], [0, 0, 1], 3.0, angular_velocity=2.0)
    return dk.Scene(p, [law, drum, dk.Gravity([0, -9.81, 0])])




@needs_lammps
@pytest.mark.parametrize("friction", [False, True], ids=["frictionless", "friction"])
def test_spheres_in_a_rotating_drum_agree_with_lammps_rotating_region_to_round_off(tmp_path, friction):
    """A turning dk.Cylinder against LAMMPS' fix wall/gran/region on a cylinder region turned by
    'rotate' through omega t, Hooke contacts between the spheres and with the drum, frictionless or
    with friction (slip_radius="full": the lever arm R on the wall, as LAMMPS), 300 steps: to
    round-off (measured 3e-15 in position and 2e-14 in velocity without friction, 5e-15 with it)."""
    scene = drum_scene(friction)
    files = dk.export_lammps(scene, dk.VelocityVerlet(DT), tmp_path, duration=3 * STEPS * DT, record_every=DT)
    deck = files.deck.read_text()
    assert "region      drum0 cylinder z 0 0 3 INF INF side in units box rotate v_turn0 0 0 0 0 0 1" in deck
    assert "variable    turn0 equal 2*time" in deck and "wall/gran/region granular hooke 2000 2 " in deck
    (dx, dv, dw, _), traj = differences(scene, run_lammps(files), steps=3 * STEPS)
    assert np.hypot(*traj.position[-1, :, :2].T).max() > 2.45  # they reached the drum and bounced
    assert dx < 1e-12 and dv < 1e-12 and dw < 1e-12


@needs_lammps
@pytest.mark.parametrize("inside", [True, False], ids=["drum", "post"])
def test_hertz_spheres_on_a_turning_cylinder_agree_with_lammps_contact_radius_to_round_off(tmp_path, inside):
    """Hertz spheres with Mindlin friction (LAMMPS' rules) dropped into a drum of radius 3 turning at 2 rad/s,
    or onto a post of radius 1: demkit's curved walls take the contact radius 1/R_e = 1/R -+ 1/(2 R_c), as
    LAMMPS' region cylinder (its contact radius -+2 R_c), so they agree to round-off over 300 steps
    (measured 5e-15 in position, 1.4e-13 in velocity, 1.6e-13 in spin for the drum; 5e-16, 2e-14, 4e-14 for
    the post); the export writes no note. (Before demkit took the curvature, the export noted the
    difference: the stiffness about R/(4 R_c) apart.)"""
    law = dk.Hertz(young=2e4, poisson=0.3, restitution=0.7, friction=dk.Friction(0.5, slip_radius="full",
                                                                                   sliding="lammps"))
    if inside:
        pos = 0.985 * np.array([[0.0, -2.5, 0.0], [0.95, -2.33, 0.1], [-0.9, -2.36, -0.05]])
        wall, gravity = dk.Cylinder([0, 0, 0], [0, 0, 1], 3.0, angular_velocity=2.0), [0, -9.81, 0]
    else:
        pos = np.array([[0.0, 1.52, 0.0], [0.3, 1.75, 1.2], [-0.4, 1.6, -1.1]])
        wall, gravity = dk.Cylinder([0, 0, 0], [0, 0, 1], 1.0, inside=False, angular_velocity=2.0), [0, -9.81, 0]
    p = dk.Particles(position=pos, radius=[0.5, 0.48, 0.5], mass=[1.0, 0.9, 1.1],
                     velocity=[[0.1, 0, 0], [0, 0, 0.05], [0, 0.02, 0]], angular_velocity=[[0, 0, 1.0], [0, 0, 0], [0.5, 0, 0]])
    scene = dk.Scene(p, [law, wall, dk.Gravity(gravity)])
    files = dk.export_lammps(scene, dk.VelocityVerlet(DT), tmp_path, duration=3 * STEPS * DT, record_every=DT)
    assert files.notes == ()
    (dx, dv, dw, _), traj = differences(scene, run_lammps(files), steps=3 * STEPS)
    d = np.hypot(traj.position[:, :, 0], traj.position[:, :, 1])
    gap = (3.0 - np.array([0.5, 0.48, 0.5]) - d) if inside else (d - 1.0 - np.array([0.5, 0.48, 0.5]))
    assert (gap.min(axis=0) < 0.0).all()  # each sphere touched the wall
    assert dx < 1e-12 and dv < 1e-12 and dw < 1e-12


@needs_lammps
@pytest.mark.parametrize("wall", ["drum", "plane", "sliding plane"])
def test_a_sphere_driven_by_a_frictional_wall_agrees_with_lammps_to_round_off(tmp_path, wall):
    """A sphere dropped onto a wall with friction 0.5 (slip_radius="full": the lever arm R for the slip
    and the torque, LAMMPS' wall) over 1000 steps: the bottom of a drum turning at 0.5 rad/s (it is
    carried 5 degrees up the side in one time unit, bouncing), a plane at rest and a plane sliding at
    0.4 (conveyor). Measured 5e-15 in position, 2e-14 in velocity, 3e-14 in spin for the drum. (With
    slip_radius="contact" the lever is R - delta and the spins differ by O(delta/R): 3e-2 here.)"""
    friction = dk.Friction(0.5, slip_radius="full", sliding="lammps")
    law = dk.KelvinVoigt(2e3, 2.0, friction=friction)
    if wall == "drum":
        p = dk.Particles(position=[[0.0, -2.45, 0.0]], radius=0.5, velocity=[[0.1, 0, 0]], angular_velocity=[[0, 0, 1.0]])
        scene = dk.Scene(p, [law, dk.Cylinder([0, 0, 0], [0, 0, 1], 3.0, angular_velocity=0.5), dk.Gravity([0, -9.81, 0])])
    else:
        p = dk.Particles(position=[[0.0, 0.0, 0.52]], radius=0.5, velocity=[[0.3, 0.1, 0]], angular_velocity=[[0, 0, 2.0]])
        plane = dk.Wall([0, 0, 0], [0, 0, 1], velocity=[0.4, 0, 0] if wall == "sliding plane" else [0, 0, 0])
        scene = dk.Scene(p, [law, plane, dk.Gravity([0, 0, -9.81])], box=dk.Box([4, 4, 4], periodic=(True, True, False)))
    files = dk.export_lammps(scene, dk.VelocityVerlet(DT), tmp_path, duration=10 * STEPS * DT, record_every=DT)
    assert files.notes == ()
    (dx, dv, dw, _), traj = differences(scene, run_lammps(files), steps=10 * STEPS)
    if wall == "drum":
        x = traj.position[-1, 0]
        assert np.degrees(np.arctan2(x[0], -x[1])) > 3.0  # carried up the rising side
    else:
        assert np.abs(traj.angular_velocity[-1, 0, :2]).max() > 0.1  # friction set it rolling
    assert dx < 1e-12 and dv < 1e-12 and dw < 1e-12


def sheared_gas(flow="x", gradient="y"):
    """64 frictional spheres (LAMMPS' sliding rule) with cut dipoles in a box sheared at rate 1.5: pairs
    across the sliding boundary from the first steps."""
    rng = np.random.default_rng(9)
    box = dk.build.box_for(64, 0.5, 0.3)
    pos = dk.build.random_packing(64, 0.5, box, seed=4)
    b, a = "xyz".index(gradient), "xyz".index(flow)
    velocity = rng.normal(0.0, 0.5, (64, 3))
    velocity[:, a] += 1.5 * (pos[:, b] - 0.5 * box.size[b])
    p = dk.Particles(position=pos, velocity=velocity, radius=0.5, mass=1.0, dipole=0.3 * rng.normal(size=(64, 3)))
    contact = dk.KelvinVoigt(1000.0, 1.5, friction=dk.Friction(0.5, slip_radius="full", sliding="lammps"))
    sheared = dk.Box(box.size, periodic=True, shear=dk.Shear(1.5, flow=flow, gradient=gradient))
    return dk.Scene(p, [dk.Dipole(prefactor=1.0, cutoff=2.0), contact], box=sheared)


@needs_lammps
def test_a_deforming_box_agrees_with_lammps_fix_deform_remap_x(tmp_path):
    """64 frictional spheres in a box compressed along x at 0.5/s and drawn out along z at 0.3/s for 400
    steps (x shrinks by 20 %), exported as fix deform ... erate ... remap x: LAMMPS deforms about the
    box's centre, demkit about the origin, so its unwrapped coordinates are demkit's plus its lower corner
    -(L(t) - L(0)) / 2; both remap the positions after the step's second kick and take the box from the
    clock, so paths, velocities and spins agree to round-off (measured 1.2e-13, 9e-13, 2e-12 after 400
    steps; asserted 1e-11 and 1e-10). Exported later in the run, the rate is LAMMPS' erate from the box
    of that time."""
    rng = np.random.default_rng(5)
    size = dk.build.box_for(64, 0.5, 0.35).size
    pos = dk.build.random_packing(64, 0.5, dk.Box(size, periodic=True), seed=3)
    p = dk.Particles(position=pos, velocity=rng.normal(0, 0.5, (64, 3)), radius=0.5, mass=1.0,
                     angular_velocity=rng.normal(0, 1, (64, 3)))
    contact = dk.KelvinVoigt(1000.0, 1.5, friction=dk.Friction(0.5, slip_radius="full", sliding="lammps"))
    box = dk.Box(size, periodic=True, deform=dk.Deform(x=-0.5, z=0.3))
    scene = dk.Scene(p, [contact], box=box)
    steps = 400
    files = dk.export_lammps(scene, dk.VelocityVerlet(DT), tmp_path, duration=steps * DT, record_every=DT)
    assert "fix         strain all deform 1 x erate -0.5 z erate 0.29999999999999999 remap x" in files.deck.read_text()
    frames = run_lammps(files)
    traj = dk.Simulation(scene, dk.VelocityVerlet(DT)).run(duration=steps * DT, record_every=DT, progress=False)
    x = traj.unwrapped()
    assert np.abs(traj.image).max() >= 1 and traj.box.size_at(steps * DT)[0] < 0.81 * size[0]
    for k in (1, 10, steps // 2, steps):
        theirs = frames[k][:, 1:4] + 0.5 * (box.size_at(k * DT) - size)
        assert np.abs(x[k] - theirs).max() < 1e-11
        assert np.abs(traj.velocity[k] - frames[k][:, 4:7]).max() < 1e-10
        assert np.abs(traj.angular_velocity[k] - frames[k][:, 7:10]).max() < 1e-10
    later = dk.export_lammps(scene, dk.VelocityVerlet(DT), tmp_path / "later", duration=steps * DT, strict=False)
    assert f"x erate {-0.5 / (1.0 - 0.5 * scene.time):.17g} " in later.deck.read_text()  # (-0.625: L(t) (1 + r' dt))


def test_a_sheared_box_is_exported_as_a_tilting_triclinic_box(tmp_path):
    """The deck's triclinic box (its tilt the sliding offset, led by one step, the whole turns folded
    into the image counts) under fix deform ... remap v; axes LAMMPS cannot tilt are refused."""
    scene = sheared_gas()
    scene.time = 2.0  # offset 1.5 L 2 = 3 L: three turns folded away
    files = dk.export_lammps(scene, dk.VelocityVerlet(DT), tmp_path, duration=STEPS * DT)
    deck, data = files.deck.read_text(), files.data.read_text()
    L = scene.box.size[0]
    assert "fix         shear all deform 1 xy erate 1.5 remap v flip yes" in deck
    tilt = next(line for line in data.splitlines() if line.endswith("xy xz yz")).split()
    assert tilt[1:3] == ["0", "0"]
    led = float(next(line for line in data.splitlines() if line.endswith("xy xz yz")).split()[0])
    assert led == pytest.approx(1.5 * L * (2.0 + DT) - 3 * L, abs=1e-12)
    with pytest.raises(ValueError, match="only as xy, xz or yz"):
        dk.export_lammps(sheared_gas("y", "x"), dk.VelocityVerlet(DT), tmp_path / "yx", duration=STEPS * DT)


@needs_lammps
@pytest.mark.parametrize("flow, gradient", [("x", "y"), ("y", "z")])
def test_a_sheared_box_agrees_with_lammps_fix_deform(tmp_path, flow, gradient):
    """A sheared frictional magnetic gas run for 100 steps by demkit and by the exported deck, LAMMPS'
    unwrapped coordinate along the flow taken back by its box's lead (image_b gammadot L_b dt). The
    exported box is led by one step so that the forces of every step after the first see the same tilt
    (the starting forces agree to 3e-15, measured); LAMMPS' first half kick sees the box one step ahead,
    where dipoles reach across the sliding boundary (about 90 of ~590 pairs): a one-time difference,
    4e-5 in the spins after step 1 and no more after 100 (measured 4.0e-5 then 3.8e-5 for xy, 2.8e-5 then
    3.0e-5 for yz), 9e-7 and 6e-7 in the paths (asserted: 1e-4 and 1e-5).
    Spheres cross the sliding boundary. (With nothing across the boundary at the start the paths agree
    to round-off: tests/test_lammps.py, benchmarks/lammps/in.sheared.)"""
    scene = sheared_gas(flow, gradient)
    a, b = scene.box.shear.axes
    files = dk.export_lammps(scene, dk.VelocityVerlet(DT), tmp_path, duration=STEPS * DT, record_every=DT)
    frames = run_lammps(files)
    traj = dk.Simulation(scene, dk.VelocityVerlet(DT)).run(duration=STEPS * DT, record_every=DT, progress=False)
    x = traj.unwrapped()
    L = scene.box.size
    for k in (1, STEPS // 2, STEPS):
        theirs = frames[k][:, 1:4].copy()
        theirs[:, a] -= np.floor(theirs[:, b] / L[b]) * 1.5 * L[b] * DT
        assert np.abs(x[k] - theirs).max() < 1e-5
        assert np.abs(traj.angular_velocity[k] - frames[k][:, 7:10]).max() < 1e-4
    _, pairs, d, _ = scene.pair_forces()[0]  # the dipoles' pairs: many reach across the sliding boundary
    raw = scene.particles.position[pairs[:, 1], b] - scene.particles.position[pairs[:, 0], b]
    assert np.count_nonzero(np.abs(raw - d[:, b]) > 1e-9) >= 10
