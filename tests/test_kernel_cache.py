"""Kernels loaded from the disk cache in a fresh process run (they compiled in another process)."""
import os
import subprocess
import sys
import textwrap

SCRIPT = textwrap.dedent("""
    import numpy as np
    from numba.core import event
    import demkit as dk
    # one sphere in a periodic box: no neighbour-list call from Python before the cached kernels run
    with event.install_recorder("numba:compile") as compiled:
        p = dk.Particles(position=[[1.0, 2.0, 3.0]], velocity=[[0.5, 0.0, 0.0]], radius=0.1)
        scene = dk.Scene(p, [dk.KelvinVoigt(1.0)], box=dk.Box([10, 10, 10], periodic=[True, True, False]))
        traj = dk.Simulation(scene, dk.VelocityVerlet(dt=0.01)).run(duration=30.0, record_every=10.0)
    print(sorted(ev.data["dispatcher"].py_func.__qualname__ for _, ev in compiled.buffer if ev.is_start))
    print(repr(float(traj.unwrapped()[-1, 0, 0])))
""")


def test_a_scene_whose_kernels_load_from_the_cache_runs_in_a_new_process():
    """The second process loads every kernel from the cache and compiles nothing at all (the scene's
    state once compiled its constructor in every process, ~1 s); it segfaulted (exit -11) when numba's
    threading layer had not been started, which the threaded list builder in the cached code needs.
    The suite's own cache: the first process compiles what no test compiled yet (a cache of its own
    made this test compile the whole list variant, 30 CPU s, in every run of the suite)."""
    env = dict(os.environ, DEMKIT_QUIET="1")
    outputs, compiled = [], []
    for _ in range(2):
        run = subprocess.run([sys.executable, "-c", SCRIPT], capture_output=True, text=True, env=env, timeout=300)
        assert run.returncode == 0, run.stderr[-2000:]
        outputs.append(float(run.stdout.strip().splitlines()[-1]))
        compiled.append(run.stdout.strip().splitlines()[-2])
    assert compiled[1] == "[]", f"the second process compiled {compiled[1]}"
    # free flight across the periodic x boundary: x = 1 + 0.5 t, unwrapped
    assert outputs[0] == outputs[1]
    assert abs(outputs[0] - 16.0) < 1e-9


GETTERS = textwrap.dedent("""
    import numba
    import demkit as dk
    from demkit.engine import state as st
    p = dk.Particles(position=[[1.0, 2.0, 3.0], [4.0, 2.0, 3.0]], velocity=[[0.5, 0.0, 0.0], [0.0, 0.0, 0.0]], radius=0.1)
    scene = dk.Scene(p, [dk.KelvinVoigt(1.0)], box=dk.Box([10, 10, 10], periodic=[True, True, False]))
    state_type = numba.typeof(scene.state)
    pl_type = state_type.field_dict["lists"][0]  # (not read through the proxy: that would compile it)
    have = [any(sig[0] == state_type for sig in st._get_lists.signatures)]
    have += [any(sig[0] == pl_type for sig in getter.signatures)
             for getter in (st._get_reach, st._get_start, st._get_end, st._get_partner, st._get_history, st._get_bounds)]
    print(have)
""")


def test_a_new_scene_has_its_list_getters_compiled_before_any_run(tmp_path):
    """The proxies' compiled getters for a new kind of state exist once the Scene is made, so no
    run has to compile or load them midway: there they waited for numba's compiler lock, held for
    tens of seconds by the background compilation of the thread module (a first run's end and its
    Ctrl-C stalled 5-12 s). Checked in a fresh process, where nothing else compiled them."""
    env = dict(os.environ, DEMKIT_CACHE_DIR=str(tmp_path / "cache"), DEMKIT_QUIET="1")
    run = subprocess.run([sys.executable, "-c", GETTERS], capture_output=True, text=True, env=env, timeout=300)
    assert run.returncode == 0, run.stderr[-2000:]
    assert run.stdout.strip().splitlines()[-1] == "[True, True, True, True, True, True, True]"


def test_demkits_own_cached_functions_are_stamped_with_the_whole_package(tmp_path):
    """numba stamps a cached function with its own file's hash only; a demkit function holds the code
    of the helpers it calls from other files (a wall law, the friction spring), so its stamp must
    change when any of demkit's files does (demkit.engine.numba_cache). Functions of other packages keep
    numba's own stamp."""
    import numba

    import demkit as dk
    from demkit.engine import numba_cache
    from demkit.interactions import wall

    law = wall.wall_kelvin_voigt_twisting_force
    locator = law._cache._impl._locator
    assert type(locator).__name__.startswith("Demkit")
    stamp = locator.get_source_stamp()
    assert stamp[1] == numba_cache.FINGERPRINT == numba_cache.package_fingerprint()
    # the stamp changes with a file the function does not live in
    source = {p: p.read_bytes() for p in sorted(numba_cache.PACKAGE.rglob("*.py"))}
    spring = next(p for p in source if p.name == "spring.py")
    h = __import__("hashlib").sha256()
    for p, text in source.items():
        h.update(str(p.relative_to(numba_cache.PACKAGE)).encode())
        h.update(text + (b"\n# edited" if p == spring else b""))
    assert h.hexdigest() != numba_cache.FINGERPRINT

    def mine(x):
        return x + 1

    theirs = numba.njit(cache=True)(mine)
    theirs(1)
    assert not type(theirs._cache._impl._locator).__name__.startswith("Demkit")
    dk.engine.numba_cache.install()  # a second install adds nothing
    impl = type(law._cache._impl)
    assert sum(c.__name__.startswith("Demkit") for c in impl._locator_classes) == 3


RACE = textwrap.dedent("""
    import os, sys, time
    import numpy as np
    import demkit
    from demkit.engine import neighbours
    go = sys.argv[1]
    while not os.path.exists(go):  # both processes start compiling together
        time.sleep(0.001)
    neighbours.max_displacement(np.zeros((4, 3)), np.ones((4, 3)))
    stats = neighbours.max_displacement.stats
    print(sum(stats.cache_misses.values()), sum(stats.cache_hits.values()))
""")


def test_processes_starting_together_on_an_empty_cache_compile_each_function_once(tmp_path):
    """Two processes (the workers of a sweep or of this suite) that need the same function of an
    empty cache at the same moment: one compiles it, the other waits for it and loads it
    (demkit.engine.numba_cache's lock). Without the lock both missed the cache and both compiled."""
    env = dict(os.environ, DEMKIT_CACHE_DIR=str(tmp_path / "cache"), NUMBA_CACHE_DIR=str(tmp_path / "cache"),
               DEMKIT_QUIET="1")
    go = tmp_path / "go"
    children = [subprocess.Popen([sys.executable, "-c", RACE, str(go)], stdout=subprocess.PIPE,
                                 stderr=subprocess.PIPE, text=True, env=env) for _ in range(2)]
    import time
    time.sleep(3.0)  # both have imported demkit and wait
    go.touch()
    results = []
    for child in children:
        out, err = child.communicate(timeout=300)
        assert child.returncode == 0, err[-2000:]
        results.append(tuple(int(v) for v in out.split()))
    assert sorted(results) == [(0, 1), (1, 0)], f"(cache misses, hits) of the two processes: {results}"
    assert list((tmp_path / "cache").rglob("*.lock")), "no lock file beside the cache"


def test_a_compile_that_fails_releases_its_lock():
    """A function called with types it cannot take fails to compile and saves nothing: the lock it
    took is released at once (another process would otherwise wait LOCK_WAIT seconds for it)."""
    import numba
    import numpy as np
    import pytest

    from demkit.engine import neighbours, numba_cache
    with pytest.raises(numba.core.errors.TypingError):
        neighbours.max_displacement(np.zeros((4, 3)), "not an array")
    assert numba_cache._HELD == {}
