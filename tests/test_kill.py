"""kill -9 at random moments: a run writing a VTK series and checkpoints is killed 20 times (during
start-up, stepping, frame writing, checkpoint writing: wherever the signal lands), and after every
kill the series is readable and the checkpoint loads; resumed each time, the run ends in exactly
the state of an uninterrupted run (bit for bit) and its series holds every frame once."""
import os
import random
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np

import demkit as dk
from demkit import checkpoint as ckpt_module
from restart_scenes import gas

N, DT, UNTIL, FRAME_EVERY = 70, 2e-3, 40.0, 0.4

CHILD = textwrap.dedent(f"""
    import sys
    import numpy as np
    import demkit as dk
    from restart_scenes import gas

    folder, path, final = sys.argv[1:4]
    scene = gas(n={N})
    checkpoint = dk.Checkpoint(path, every=2.0, seconds=0.05)
    resuming = checkpoint.exists()
    writer = dk.VTKWriter(folder, every={FRAME_EVERY}, trails=False, resume=resuming)
    sim = dk.Simulation(scene, dk.VelocityVerlet({DT}), writers=[writer], checkpoint=checkpoint)
    if resuming:
        sim.resume()
    print("running", sim.step, flush=True)
    sim.run(until={UNTIL})
    sim.close()
    np.save(final, scene.particles.position)
    print("done", flush=True)
""")


def _child(tmp_path, script):
    env = dict(os.environ)
    tests = str(Path(__file__).parent)
    env["PYTHONPATH"] = tests + os.pathsep + env.get("PYTHONPATH", "")
    return subprocess.Popen([sys.executable, str(script), str(tmp_path / "series"), str(tmp_path / "run.ckpt"),
                             str(tmp_path / "final.npy")], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, env=env)


def _check_after_kill(tmp_path):
    pvd = tmp_path / "series" / "particles.pvd"
    if pvd.exists():
        series = dk.read_series(pvd)  # every listed frame readable
        assert np.all(np.diff(series.time) > 0)
        assert np.allclose(np.diff(series.time), FRAME_EVERY)
    if (tmp_path / "run.ckpt").exists():
        meta, _ = ckpt_module.load(tmp_path / "run.ckpt")
        return meta["step"]
    return 0


def test_sigkill_at_random_moments_loses_nothing_and_resumes_exactly(tmp_path):
    script = tmp_path / "child.py"
    script.write_text(CHILD)
    rng = random.Random(2026)
    kills, steps = 0, []
    while kills < 20:
        child = _child(tmp_path, script)
        line = child.stdout.readline()
        assert line.startswith("running"), child.stderr.read()
        time.sleep(rng.uniform(0.0, 0.3))
        child.kill()
        child.wait()
        kills += 1
        steps.append(_check_after_kill(tmp_path))
    assert steps[-1] > steps[0], "the run made progress across kills"
    assert steps[-1] < round(UNTIL / DT), "the kills landed before the end"
    child = _child(tmp_path, script)
    out, err = child.communicate(timeout=300)
    assert child.returncode == 0, err
    assert "done" in out
    # the truth: the same run, never interrupted
    scene = gas(n=N)
    dk.Simulation(scene, dk.VelocityVerlet(DT)).run(until=UNTIL)
    assert np.array_equal(np.load(tmp_path / "final.npy"), scene.particles.position)
    series = dk.read_series(tmp_path / "series" / "particles.pvd")
    assert np.allclose(series.time, np.arange(len(series.time)) * FRAME_EVERY)
    assert series.time[-1] == UNTIL
    assert np.allclose(series.position[-1], scene.particles.position[np.argsort(scene.particles.ids)])
