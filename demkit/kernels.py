"""Generate one fused, compiled kernel module for a scene's chosen interactions.

The generated module holds

* ``compute_forces(position, velocity, angular_velocity, dipole, radius, mass, pairs, history,
  params, force, torque, commit) -> dissipated power``: one loop over the pair list calling only
  the chosen interactions' force functions and applying Newton's third law once per pair;
* ``compute_energies(..., out)``: kinetic, rotational, then one potential energy per energy kind;
* one ``<name>_steps`` time loop per integrator template (see :mod:`demkit.integrators`), pasted
  from ordinary Python source so that the whole time step runs in compiled code.

Absent optional fields are passed as (0, 3) arrays. Parameters arrive in ``params`` (an argument,
not a frozen global). The source is written to a cache folder named by a hash of everything it
depends on (its own text and the source of every pair function), so numba's on-disk cache can be
reused safely between runs; set ``DEMKIT_CACHE_DIR`` to move it, ``DEMKIT_NO_CACHE=1`` to disable it.
"""
from __future__ import annotations

import hashlib
import importlib.util
import inspect
import os
import sys
import tempfile
import textwrap
from pathlib import Path

import numba

from .interactions.base import FIELDS

ENERGY_KINDS = ("magnetic", "contact")
_MODULES = {}


def energy_kinds(interactions):
    """Energy categories reported for these interactions: the standard ones, then any new ones."""
    kinds = list(ENERGY_KINDS)
    for inter in interactions:
        if inter.energy_kind not in kinds:
            kinds.append(inter.energy_kind)
    return kinds


def _importable(fn):
    """Can the generated file import ``fn`` by name (needed for the on-disk cache)?"""
    module = getattr(fn, "__module__", None)
    if not module or module == "__main__":
        return False
    try:
        found = getattr(importlib.import_module(module), fn.__name__, None)
    except Exception:  # any import failure just means: compile in memory
        return False
    return found is fn


def _pair_call(k, inter, offset, kind):
    """Source of the call to interaction k's force or energy function."""
    args = ["i", "j", "dx", "dy", "dz", "r2", *inter.reads]
    if inter.history_size:
        args += ["history", "p", str(offset), "commit" if kind == "force" else "False"]
    args += [f"p{k}_{n}" for n in range(len(inter.parameters))]
    return f"{kind}_{k}({', '.join(args)})"


def generate_source(interactions, templates, importable):
    """Python source of the fused kernel module (see module docstring)."""
    lines = ["import math", "import numpy as np", "from numba import njit",
             "from demkit.motion import kick, drift, rotate, advance_spin, state_is_finite, "
             "kinetic_energies, store_frame", ""]
    if importable:
        for k, inter in enumerate(interactions):
            for kind, fn in zip(("force", "energy"), inter.pair_functions()):
                lines.append(f"from {fn.__module__} import {fn.__name__} as {kind}_{k}")
    lines.append("from demkit.motion import KERNEL_OPTIONS")
    lines.append(f"OPTIONS = dict(KERNEL_OPTIONS, cache={importable})")
    any_torque = any(inter.torque for inter in interactions)
    kinds = energy_kinds(interactions)
    args = "position, velocity, angular_velocity, dipole, radius, mass, pairs, history, params"

    # parameters read once from the params array
    unpack, offset = [], 0
    for k, inter in enumerate(interactions):
        for n in range(len(inter.parameters)):
            unpack.append(f"    p{k}_{n} = params[{offset}]")
            offset += 1
    hist_offsets, h = [], 0
    for inter in interactions:
        hist_offsets.append(h)
        h += inter.history_size

    def pair_loop(body):
        out = ["    for p in range(pairs.shape[0]):",
               "        i = pairs[p, 0]",
               "        j = pairs[p, 1]",
               "        dx = position[j, 0] - position[i, 0]",
               "        dy = position[j, 1] - position[i, 1]",
               "        dz = position[j, 2] - position[i, 2]",
               "        r2 = dx * dx + dy * dy + dz * dz"]
        return out + body

    def guarded(k, inter, statements):
        """Indent ``statements`` under the cutoff test of interaction k, if it has a cutoff."""
        if inter.cutoff_distance is None:
            return ["        " + st for st in statements]
        return [f"        if r2 < params[{offset + k}]:"] + ["            " + st for st in statements]

    # ---- forces
    body = ["        fx = 0.0", "        fy = 0.0", "        fz = 0.0"]
    if any_torque:
        body += [f"        {c} = 0.0" for c in ("tix", "tiy", "tiz", "tjx", "tjy", "tjz")]
    for k, inter in enumerate(interactions):
        outs = ["ax", "ay", "az"]
        acc = ["fx += ax", "fy += ay", "fz += az"]
        if inter.torque:
            outs += ["bix", "biy", "biz", "bjx", "bjy", "bjz"]
            acc += ["tix += bix", "tiy += biy", "tiz += biz", "tjx += bjx", "tjy += bjy", "tjz += bjz"]
        if inter.dissipative:
            outs += ["w"]
            acc += ["power += w"]
        call = f"{', '.join(outs)} = {_pair_call(k, inter, hist_offsets[k], 'force')}"
        body += guarded(k, inter, [call] + acc)
    body += ["        force[i, 0] -= fx", "        force[i, 1] -= fy", "        force[i, 2] -= fz",
             "        force[j, 0] += fx", "        force[j, 1] += fy", "        force[j, 2] += fz"]
    if any_torque:
        body += ["        torque[i, 0] += tix", "        torque[i, 1] += tiy", "        torque[i, 2] += tiz",
                 "        torque[j, 0] += tjx", "        torque[j, 1] += tjy", "        torque[j, 2] += tjz"]
    lines += ["", "@njit(**OPTIONS)",
              f"def compute_forces({args}, force, torque, commit):",
              '    """Forces and torques of all chosen interactions; returns the dissipated power."""',
              "    for i in range(force.shape[0]):",
              "        for a in range(3):",
              "            force[i, a] = 0.0",
              "            torque[i, a] = 0.0"] + unpack + ["    power = 0.0"]
    lines += pair_loop(body) + ["    return power"]

    # ---- energies: totals per kind, and per pair and interaction (diagnostics)
    def energy_body(target):
        body = []
        for k, inter in enumerate(interactions):
            slot = target(k, 2 + kinds.index(inter.energy_kind))
            body += guarded(k, inter, [f"{slot} += {_pair_call(k, inter, hist_offsets[k], 'energy')}"])
        return body

    lines += ["", "@njit(**OPTIONS)",
              f"def compute_energies({args}, inertia, out):",
              '    """out = [kinetic, rotational, <one potential energy per kind>]."""',
              "    out[:] = 0.0",
              "    out[0], out[1] = kinetic_energies(velocity, angular_velocity, mass, inertia)"]
    lines += unpack + (pair_loop(energy_body(lambda k, slot: f"out[{slot}]")) if interactions else [])
    lines += ["", "@njit(**OPTIONS)",
              f"def compute_pair_energies({args}, out):",
              '    """out[p, k] = energy of pair p under interaction k."""',
              "    out[:, :] = 0.0"]
    lines += unpack + (pair_loop(energy_body(lambda k, slot: f"out[p, {k}]")) if interactions else [])

    # ---- state-tuple wrappers used by the time loops
    lines += ["", "", "@njit(**OPTIONS)",
              "def forces_of(state, commit):",
              "    return compute_forces(state[0], state[1], state[2], state[3], state[4], state[5],",
              "                          state[7], state[8], state[9], state[10], state[11], commit)",
              "", "", "@njit(**OPTIONS)",
              "def record_frame(k, state, record):",
              "    store_frame(k, state[0], state[1], state[2], state[3], state[5], state[6], record)",
              "    e = record[4]",
              "    last = e.shape[1] - 1",
              "    energies_of(state, e[k, :last])",
              "    e[k, last] = state[12][0]",
              "", "", "@njit(**OPTIONS)",
              "def energies_of(state, out):",
              "    compute_energies(state[0], state[1], state[2], state[3], state[4], state[5],",
              "                     state[7], state[8], state[9], state[6], out)",
              "", "", "@njit(**OPTIONS)",
              "def pair_energies_of(state, out):",
              "    compute_pair_energies(state[0], state[1], state[2], state[3], state[4], state[5],",
              "                          state[7], state[8], state[9], out)",
              "", "", "@njit(**OPTIONS)",
              "def end_step(step, countdown, stride, state, record):",
              '    """After global step ``step``: -1 if the state went non-finite, else the steps left',
              '    until the next frame (recording frame step // stride when it is due)."""',
              "    if not state_is_finite(state[0], state[1], state[2]):",
              "        return -1",
              "    if countdown == 1:",
              "        record_frame(step // stride, state, record)",
              "        return stride",
              "    return countdown - 1"]

    # ---- integrator time loops
    for name, template in templates.items():
        src = textwrap.dedent(inspect.getsource(template))
        src = src.replace(f"def {template.__name__}(", f"def {name}_steps(", 1)
        lines += ["", "", "@njit(**OPTIONS)"] + src.rstrip().splitlines()
    return "\n".join(lines) + "\n"


def _cache_dir():
    root = os.environ.get("DEMKIT_CACHE_DIR")
    if root:
        return Path(root)
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "demkit" / "kernels"


def _fingerprint(source, interactions):
    h = hashlib.sha256(source.encode())
    h.update(numba.__version__.encode())
    for inter in interactions:
        for fn in inter.pair_functions():
            h.update(inspect.getsource(fn.py_func).encode())
    from . import motion
    h.update(inspect.getsource(motion).encode())
    return h.hexdigest()[:20]


def build_module(interactions, templates):
    """Return the compiled kernel module for these interactions and integrator templates."""
    for inter in interactions:
        for fn in inter.pair_functions():
            if not hasattr(fn, "py_func"):
                raise TypeError(f"{type(inter).__name__}: pair functions must be numba @njit functions")
    importable = all(_importable(fn) for inter in interactions for fn in inter.pair_functions())
    importable = importable and os.environ.get("DEMKIT_NO_CACHE", "") in ("", "0")
    source = generate_source(interactions, templates, importable)
    key = _fingerprint(source, interactions)
    name = f"demkit_kernel_{key}"
    if not importable:  # in memory: bind to these very function objects, not look-alikes
        key += "".join(f"-{id(fn)}" for inter in interactions for fn in inter.pair_functions())
    if key in _MODULES:
        return _MODULES[key]
    if importable:
        module = _load_from_file(name, source)
    else:
        module = _load_in_memory(name, source, interactions)
    module.source = source
    _MODULES[key] = module
    return module


def _load_from_file(name, source):
    folder = _cache_dir()
    try:
        folder.mkdir(parents=True, exist_ok=True)
        path = folder / f"{name}.py"
        if not path.exists() or path.read_text() != source:
            fd, tmp = tempfile.mkstemp(dir=folder, suffix=".tmp")
            with os.fdopen(fd, "w") as fh:
                fh.write(source)
            os.replace(tmp, path)
    except OSError:
        return _load_in_memory(name, source.replace("cache=True)", "cache=False)"), None)
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    spec.loader.exec_module(module)
    return module


def _load_in_memory(name, source, interactions):
    """Compile without a file (pair functions defined in __main__ or notebooks): no disk cache."""
    import types
    module = types.ModuleType(name)
    if interactions is not None:
        for k, inter in enumerate(interactions):
            force, energy = inter.pair_functions()
            setattr(module, f"force_{k}", force)
            setattr(module, f"energy_{k}", energy)
    exec(compile(source, f"<{name}>", "exec"), module.__dict__)
    return module
