"""Reliability (issue 22): faults injected into runs and their outputs — Ctrl-C and kill -9 while
spheres sit across a periodic face, folders that cannot be written, a full disk, truncated and
corrupted files read back. Each test asserts that nothing already written is lost and that the
message names the problem. Every test here is marked ``reliability``: ``pytest -m reliability tests``
runs them alone. ``FAULTS`` counts the faults injected (reported by ``pytest -m reliability -s``)."""
import builtins
import errno
import os
import textwrap
from pathlib import Path

import numpy as np
import pytest

#: fault name -> times injected in this session (each test adds its own)
FAULTS = {}


def injected(name):
    """Count one injected fault."""
    FAULTS[name] = FAULTS.get(name, 0) + 1


def pytest_terminal_summary(terminalreporter):
    if FAULTS:
        total = sum(FAULTS.values())
        terminalreporter.write_line(f"reliability: {total} faults injected and survived ("
                                    f"{', '.join(f'{k}: {v}' for k, v in sorted(FAULTS.items()))})")


#: four spheres in a periodic cube of side 6; sphere 0 starts at x = 5.95 moving +x at 1.0: it crosses
#: the face x = 6 at t = 0.05 and, until the neighbour list is next rebuilt (it has moved skin/2 =
#: 0.15, t ~ 0.15), the kernels keep it unfolded at x > 6 while the recorded frames fold it to x ~ 0
CROSSING = textwrap.dedent("""\
    title = "a sphere across a periodic face"

    [particles]
    position = [[5.95, 1.0, 1.0], [1.0, 3.0, 3.0], [3.0, 1.0, 4.0], [4.5, 4.5, 1.5]]
    velocity = [[1.0, 0.0, 0.0], [-0.5, 0.3, 0.0], [0.0, 0.0, 0.4], [0.2, -0.6, 0.1]]
    radius = 0.5

    [box]
    size = 6.0
    periodic = true

    [interactions.kelvin_voigt]
    stiffness = 1000.0
    damping = 1.0

    [integrator]
    method = "VelocityVerlet"
    dt = 0.001

    [run]
    duration = 0.5
    record_every = 0.03

    [outputs]
    trajectory = "out/traj.npz"
    [outputs.checkpoint]
    path = "out/run.ckpt"
    every = 0.01
    """)
L = 6.0


def scene_file(folder, text=CROSSING):
    """Write ``text`` as folder/s.toml; returns its path."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "s.toml").write_text(text)
    return folder / "s.toml"


def arrays(path):
    """{name: array} of an .npz file."""
    with np.load(path) as z:
        return {name: z[name] for name in z.files}


def assert_same_npz(a, b):
    """Two trajectory files equal array for array, bit for bit."""
    x, y = arrays(a), arrays(b)
    assert sorted(x) == sorted(y)
    for name in x:
        assert np.array_equal(x[name], y[name]), name


@pytest.fixture(scope="session")
def straight(tmp_path_factory):
    """The crossing scene run once, uninterrupted: its trajectory file (compiles the kernels)."""
    import demkit as dk
    path = scene_file(tmp_path_factory.mktemp("straight"))
    dk.load_scene(path).run(progress=False)
    return path.parent / "out" / "traj.npz"


def failing_writes(monkeypatch, folder, code=errno.ENOSPC):
    """Every file opened for writing under ``folder`` fails as a full disk does (``code``): opening
    with os.open (temporary files) and writing through open()."""
    folder = os.path.realpath(folder)
    real_open, real_os_open = builtins.open, os.open

    def under(path):
        try:
            return os.path.realpath(os.fspath(path)).startswith(folder + os.sep)
        except TypeError:  # a file descriptor
            return False

    def fake_open(file, mode="r", *args, **kwargs):
        if under(file) and any(m in mode for m in "wax+"):
            raise OSError(code, os.strerror(code), os.fspath(file))
        return real_open(file, mode, *args, **kwargs)

    def fake_os_open(path, flags, *args, **kwargs):
        if under(path) and flags & (os.O_WRONLY | os.O_RDWR | os.O_CREAT):
            raise OSError(code, os.strerror(code), os.fspath(path))
        return real_os_open(path, flags, *args, **kwargs)
    monkeypatch.setattr(builtins, "open", fake_open)
    monkeypatch.setattr(os, "open", fake_os_open)
