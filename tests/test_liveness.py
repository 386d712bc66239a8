"""demkit.engine.numba_patches.liveness: numba's variable liveness computed on bit sets gives numba's own map.

Independent truth: numba's original ``compute_live_map`` (kept by the module) on the same control-flow
graph and use/def maps: the same blocks, each with the same set of live variables, on a function with
nested loops, branches and variables defined on one path only, and at each of numba's calls while it
compiles a function inlining two frictional contact laws (~90 blocks). Compiled code computes what Python
computes.
(``DEMKIT_PLAIN_LIVENESS=1`` keeps the patch out: tests/test_inlining.py.)
"""
import numba
import numpy as np
from numba.core import analysis, ir_utils
from numba.core.compiler import run_frontend

import demkit  # noqa: F401 (installs the patch)
from demkit.engine.numba_patches import liveness
from demkit.interactions.contact import kelvin_voigt_twisting_force
from demkit.interactions.hertz import hertz_twisting_force


def loops(n, x):
    total = 0.0
    for i in range(n):
        if x > i:
            y = x - i
            for j in range(i):
                total += y * j
                if total > 100.0:
                    break
        elif i == 2:
            z = 3.0
            total -= z
        else:
            while total < 0.0:
                total += 1.0
    return total


def _both(function):
    blocks = run_frontend(function).blocks
    cfg = ir_utils.compute_cfg_from_blocks(blocks)
    usedefs = analysis.compute_use_defs(blocks)
    theirs = liveness._numba_live_map(cfg, blocks, usedefs.usemap, usedefs.defmap)
    mine = liveness.compute_live_map(cfg, blocks, usedefs.usemap, usedefs.defmap)
    return theirs, mine, blocks


def test_the_patch_is_in_place_after_importing_demkit():
    assert liveness.INSTALLED
    assert analysis.compute_live_map is liveness.compute_live_map
    assert ir_utils.compute_live_map is liveness.compute_live_map
    assert liveness.install()


def test_the_live_map_is_numbas_own():
    theirs, mine, blocks = _both(loops)
    assert list(mine) == list(theirs) == list(blocks)
    assert mine == theirs
    assert sum(len(live) for live in mine.values()) > 10  # (something is live across blocks)


def test_every_live_map_of_a_large_compile_is_numbas_own(monkeypatch):
    """Each call numba makes while compiling a function that inlines two frictional contact laws (~90
    blocks after inlining), answered by both."""
    calls = []

    def both(cfg, blocks, use, defs):
        theirs = liveness._numba_live_map(cfg, blocks, use, defs)
        mine = liveness.compute_live_map(cfg, blocks, use, defs)
        assert list(mine) == list(theirs) and mine == theirs
        calls.append(len(blocks))
        return mine

    for module in (analysis, ir_utils):
        monkeypatch.setattr(module, "compute_live_map", both)

    @numba.njit
    def two_laws(x, v, w, r, m, history):
        total = 0.0
        for j in range(1, x.shape[0]):
            d = x[j] - x[0]
            r2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2]
            f = kelvin_voigt_twisting_force(0, j, d[0], d[1], d[2], r2, v, w, r, history, j - 1, 0, True, 1e3, 1.0,
                                            0.0, 0.5, 300.0, 0.5, 0.0, 0.1, 50.0, 0.2, -1.0, -1.0, 0.3, 1e-4)
            g = hertz_twisting_force(0, j, d[0], d[1], d[2], r2, v, w, r, m, history, j - 1, 16, True, 1e4, 4e3, 0.3,
                                     0.5, 0.0, -1.0, 0.0, 0.1, 0.0, -1.0, -1.0, -1.0, 0.3, 1e-4)
            total += f[0] + g[1] + f[9] + g[9]
        return total

    x = np.array([[0.0, 0.0, 0.0], [0.95, 0.1, 0.0], [0.0, 0.97, 0.05]])
    v = np.array([[0.1, 0.0, 0.0], [-0.2, 0.1, 0.0], [0.0, -0.3, 0.1]])
    w = np.array([[0.0, 0.0, 1.0], [0.5, 0.0, 0.0], [0.0, 0.2, 0.0]])
    out = two_laws(x, v, w, np.full(3, 0.5), np.ones(3), np.zeros((2, 40)))
    assert np.isfinite(out) and out != 0.0
    assert len(calls) > 20 and max(calls) > 50  # (large maps were compared)


def test_compiled_code_computes_what_python_computes():
    compiled = numba.njit(loops)
    for n, x in ((6, 3.5), (4, -1.0), (12, 9.0)):
        assert compiled(n, x) == loops(n, x)
