"""Notes at the end of a run (demkit.notes): overlaps and the energy balance, quiet when all is well."""
import numpy as np
import pytest

import demkit as dk
from demkit import notes


def head_on(speed, overlap=0.0, stiffness=100.0, damping=0.0):
    """Two unit spheres on the x axis, approaching at +-speed, starting ``overlap`` (of R) deep."""
    gap = 2.0 - overlap
    p = dk.Particles(position=[[-gap / 2, 0, 0], [gap / 2, 0, 0]], velocity=[[speed, 0, 0], [-speed, 0, 0]],
                     radius=1.0, mass=1.0)
    return dk.Scene(p, [dk.KelvinVoigt(stiffness, damping)])


def test_a_soft_contact_gets_a_note_with_its_largest_overlap(capsys):
    # at rest and 10 % deep, an undamped spring oscillates between 10 % and 0: the largest overlap
    # is the start's (the first frame), the typical one (mean over the frames) below it
    sim = dk.Simulation(head_on(0.0, overlap=0.1), dk.VelocityVerlet(0.002))
    sim.run(30.0, record_every=0.1)  # 15000 steps: 15 of the 301 frames read, the first among them
    s = sim.statistics
    assert s["overlap_largest"] == pytest.approx(0.1, rel=1e-9)
    assert 0.0 < s["overlap_typical"] <= 0.1 + 1e-12
    assert len(s["notes"]) == 1 and "up to 10.0% of the smaller radius" in s["notes"][0]
    assert "demkit note: contacts overlapped by up to 10.0%" in capsys.readouterr().err


def test_a_too_long_step_gets_an_energy_note_with_the_drift_of_the_trajectory(capsys):
    # a damped head-on impact at the longest step the guards accept (a tenth of the contact): the
    # dissipated energy is booked to first order, the balance ends ~7 % off (3 % at dt / 2, 0.6 % at
    # dt / 10: first order, measured); the drift is the trajectory's own
    scene = head_on(1.0, damping=2.0)
    sim = dk.Simulation(scene, dk.VelocityVerlet(0.02))
    traj = sim.run(3.0, record_every=0.1)
    e = traj.energy
    total = e["kinetic"] + e["rotational"] + e["contact"] + e["magnetic"] + e["dissipated"]
    scale = np.max(np.abs(e["kinetic"]) + np.abs(e["rotational"]) + np.abs(e["contact"]) + np.abs(e["magnetic"]))
    drift = np.max(np.abs(total - total[0])) / scale
    assert drift > notes.ENERGY_DRIFT
    assert sim.statistics["energy_drift"] == pytest.approx(drift, rel=1e-12)
    assert any("energy balance" in n and "dt = 0.02" in n for n in sim.statistics["notes"])
    assert "demkit note: the energy balance" in capsys.readouterr().err
    assert any("resolve_contacts=True" in n for n in sim.statistics["notes"])  # frictionless: events work


def test_the_energy_note_of_a_frictional_run_advises_only_what_runs():
    # friction keeps per-contact history, which contact events cannot integrate (refused): the
    # note must not advise them
    p = dk.Particles(position=[[-1.0, 0, 0], [1.0, 0.3, 0]], velocity=[[1.0, 0, 0], [-1.0, 0, 0]], radius=1.0,
                     mass=1.0)
    scene = dk.Scene(p, [dk.KelvinVoigt(100.0, 2.0, friction=dk.Friction(0.5))])
    sim = dk.Simulation(scene, dk.VelocityVerlet(0.02))
    sim.run(3.0, record_every=0.1)
    energy = [n for n in sim.statistics["notes"] if "energy balance" in n]
    assert energy and "halve it" in energy[0] and "resolve_contacts" not in energy[0]
    with pytest.raises(ValueError, match=r"VelocityVerlet \(without resolve_contacts\) or EulerCromer"):
        dk.Simulation(scene, dk.VelocityVerlet(0.02, resolve_contacts=True))


def test_a_well_resolved_gentle_impact_is_quiet(capsys, monkeypatch):
    # a slow, long contact (pi / omega = 2.2 time units), frames read every 2 (one per 1000 steps)
    sim = dk.Simulation(head_on(0.005, stiffness=1.0, damping=0.2), dk.VelocityVerlet(0.002))
    sim.run(24.0, record_every=0.1)
    s = sim.statistics
    assert s["notes"] == [] and capsys.readouterr().err == ""
    # at most v_rel / omega = 0.01 / sqrt(1 / 0.5) = 0.71 % of R (less with the dashpot)
    assert s["overlap_largest"] < 0.0071
    assert s["energy_drift"] < notes.ENERGY_DRIFT


def test_demkit_quiet_keeps_stderr_quiet_but_the_notes_are_kept(capsys, monkeypatch):
    monkeypatch.setenv("DEMKIT_QUIET", "1")
    sim = dk.Simulation(head_on(0.0, overlap=0.1), dk.VelocityVerlet(0.002))
    sim.run(8.0)  # 4000 steps: 2 frames read, the first 10 % deep
    assert sim.statistics["notes"] and capsys.readouterr().err == ""


def test_a_run_of_a_few_steps_reads_no_overlaps_and_long_runs_read_a_frame_per_1000_steps():
    sim = dk.Simulation(head_on(0.0, overlap=0.1), dk.VelocityVerlet(0.002))
    sim.run(0.002 * (notes.STEPS_PER_FRAME - 1))
    assert sim.statistics["overlap_largest"] is None and sim.statistics["notes"] == []
    assert sim.statistics["energy_drift"] is not None  # the balance still (from the energies)
    run = notes.RunNotes(head_on(0.0, overlap=0.1))
    run.frames(np.zeros((101, 2, 3)) + [[0, 0, 0], [1.9, 0, 0]], np.ones((101, 5)), 10000)
    assert run.read == 10 and run.figures()["overlap_largest"] == pytest.approx(0.1)


def test_no_energy_figure_when_a_moving_wall_works_on_the_spheres():
    p = dk.Particles(position=[[0, 0, 1.0]], velocity=[[0, 0, 0]], radius=1.0, mass=1.0)
    moving = dk.Scene(p, [dk.KelvinVoigt(100.0), dk.Wall((0, 0, 0), (0, 0, 1), velocity=(1.0, 0, 0))])
    resting = dk.Scene(p.copy(), [dk.KelvinVoigt(100.0), dk.Wall((0, 0, 0), (0, 0, 1))])
    assert not notes.RunNotes(moving).balance and notes.RunNotes(resting).balance
    # a sphere resting on a wall (no overlap) and one 3 % into it
    walls = notes.RunNotes(resting).walls
    assert len(notes.frame_overlaps(np.array([[0, 0, 1.0]]), np.ones(1), None, True, walls)) == 0
    assert notes.frame_overlaps(np.array([[0, 0, 0.97]]), np.ones(1), None, True, walls) == pytest.approx([0.03])


@pytest.mark.parametrize("n", [40, 300])  # all pairs, and a k-d tree
def test_frame_overlaps_are_those_of_every_touching_pair_in_a_periodic_box(rng, n):
    box = dk.Box([6.0, 7.0, n / 6.0], periodic=[True, True, False])
    position = rng.uniform(0, 1, (n, 3)) * box.size
    radius = rng.uniform(0.3, 0.6, n)
    got = np.sort(notes.frame_overlaps(position, radius, box, True, []))
    want = []
    for i in range(n):  # brute force, minimum image along x and y only
        for j in range(i + 1, n):
            d = position[j] - position[i]
            d[:2] -= box.size[:2] * np.round(d[:2] / box.size[:2])
            overlap = radius[i] + radius[j] - np.linalg.norm(d)
            if overlap > 0:
                want.append(overlap / min(radius[i], radius[j]))
    assert len(want) > 5 and got == pytest.approx(np.sort(want), rel=1e-12)


def test_notes_must_be_true_or_false():
    with pytest.raises(TypeError, match="notes must be True or False, got 'quiet'"):
        dk.Simulation(head_on(0.0), dk.VelocityVerlet(0.002), notes="quiet")
