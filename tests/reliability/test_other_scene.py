"""A checkpoint from another scene: `demkit run` refuses it naming the parameter that differs, with
one line and exit 2, before it says it resumes; the checkpoint and the trajectory are left as they were."""
import pytest

import demkit as dk
from demkit.cli import main

from .conftest import arrays, injected, scene_file

pytestmark = pytest.mark.reliability


@pytest.mark.parametrize("change, named", [
    ("interactions.kelvin_voigt.stiffness=500.0",
     "interaction 0 KelvinVoigt stiffness: checkpoint 1000.0, scene 500.0"),
    ("particles.radius=[0.5,0.5,0.5,0.45]", "radius of sphere id 3: checkpoint 0.5, scene 0.45"),
    ("box.size=7.0", "box size: checkpoint [6.0, 6.0, 6.0], scene [7.0, 7.0, 7.0]"),
])
def test_the_refusal_names_the_parameter_and_comes_before_resuming(tmp_path, capsys, change, named):
    path = scene_file(tmp_path)
    dk.load_scene(path, overrides={"run.duration": 0.02}).run(progress=False)
    before = (tmp_path / "out" / "run.ckpt").read_bytes(), arrays(tmp_path / "out" / "traj.npz")
    capsys.readouterr()
    with pytest.raises(SystemExit) as exit:
        main(["run", str(path), "--set", change, "--no-progress"])
    injected("checkpoint of another scene")
    out, err = capsys.readouterr()
    assert exit.value.code == 2
    assert named in err and len(err.strip().splitlines()) == 1, err
    assert "resuming from" not in out, out
    assert (tmp_path / "out" / "run.ckpt").read_bytes() == before[0]
    assert arrays(tmp_path / "out" / "traj.npz")["time"].tolist() == before[1]["time"].tolist()
