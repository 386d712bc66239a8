"""Cross-check against LAMMPS (runs only where `lmp` is installed: Debian package `lammps`).

The N = 1000 reference scene (benchmarks/reference_scene.py) with the `nofric` physics of
benchmarks/lammps/in.reference: point dipoles cut at 4 d (plain truncation, as lj/cut/dipole/cut),
Hooke contacts k_n = 1000 with a velocity dashpot 1.5, velocity Verlet dt = 0.001.

* Forces and torques at step 0 agree to 1e-10 of the largest one: the same sums in another order.
* Positions after 100 steps agree to 1e-6 (measured ~2e-7): LAMMPS' `fix nve/sphere update dipole`
  turns each dipole by a renormalised Euler step, demkit rotates it exactly (docs/nbody.md).
"""
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import demkit as dk

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))

pytestmark = pytest.mark.skipif(shutil.which("lmp") is None,
                                reason="LAMMPS (lmp, Debian package 'lammps') is not installed")


def read_dump(path):
    """{step: (N, 16) array sorted by id} from a LAMMPS custom dump (id xu yu zu vx vy vz fx fy fz tq* mu*)."""
    frames, lines = {}, Path(path).read_text().splitlines()
    k = 0
    while k < len(lines):
        step = int(lines[k + 1])
        n = int(lines[k + 3])
        rows = np.array([[float(v) for v in ln.split()] for ln in lines[k + 9:k + 9 + n]])
        frames[step] = rows[np.argsort(rows[:, 0])]
        k += 9 + n
    return frames


@pytest.fixture(scope="module")
def lammps_run(tmp_path_factory):
    from reference_scene import write_reference_scene
    folder = tmp_path_factory.mktemp("lammps")
    scene, _, data = write_reference_scene(1000, folder)
    dump = folder / "state.dump"
    subprocess.run(["lmp", "-in", str(ROOT / "benchmarks" / "lammps" / "in.reference"), "-screen", "none",
                    "-log", str(folder / "log.lammps"), "-var", "data", str(data), "-var", "model", "nofric",
                    "-var", "nsteps", "100", "-var", "dump", str(dump), "-var", "dumpevery", "100"],
                   cwd=folder, check=True, capture_output=True, timeout=300)
    return scene, read_dump(dump)


def demkit_scene(scene):
    from reference_scene import particles_and_box
    p, box = particles_and_box(scene)
    return dk.Scene(p, [dk.Dipole(prefactor=1.0, cutoff=4.0), dk.KelvinVoigt(stiffness=1000.0, damping=1.5)],
                    box=box, skin=0.3)


def test_forces_and_torques_at_step_0_agree_to_1e_10(lammps_run):
    scene_data, frames = lammps_run
    first = frames[0]
    scene = demkit_scene(scene_data)
    np.testing.assert_array_equal(first[:, 0], np.arange(1, 1001))
    np.testing.assert_allclose(scene.particles.position, first[:, 1:4] % scene.box.size, rtol=0, atol=1e-12)
    force, torque = scene.forces()
    lf, lt = first[:, 7:10], first[:, 10:13]
    assert np.abs(lf).max() > 1.0 and np.abs(lt).max() > 1.0  # real dipolar forces
    np.testing.assert_allclose(force, lf, rtol=0, atol=1e-10 * np.abs(lf).max())
    np.testing.assert_allclose(torque, lt, rtol=0, atol=1e-10 * np.abs(lt).max())


def test_positions_after_100_steps_agree_to_1e_6(lammps_run):
    scene_data, frames = lammps_run
    scene = demkit_scene(scene_data)
    traj = dk.Simulation(scene, dk.VelocityVerlet(dt=1e-3)).run(duration=0.1)
    ours = traj.unwrapped()[-1]
    theirs = frames[100][:, 1:4]
    difference = np.abs(ours - theirs).max()
    assert difference < 1e-6
    assert difference > 1e-12  # the dipole updates differ (exact rotation vs renormalised Euler step)
    mu = frames[100][:, 13:16]
    np.testing.assert_allclose(np.linalg.norm(traj.dipole[-1], axis=1), 2.0, rtol=1e-12)  # exact: norms kept
    assert np.abs(np.linalg.norm(mu, axis=1) - 2.0).max() < 1e-12  # LAMMPS renormalises
