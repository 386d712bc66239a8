"""Run a LAMMPS deck and read its speed: one rank (``lmp``) or several (``mpirun -np K lmp``).

    sys.path.insert(0, "benchmarks")
    from lammps_run import run_deck
    rate = run_deck("benchmarks/lammps/in.reference", {"data": "/tmp/scene_N8000.data", "model": "full"}, ranks=2)
    rate["atom_steps_per_s"] if rate else "LAMMPS is not installed"

The deck runs in a fresh temporary folder (its log and output files vanish afterwards; pass
``workdir`` to keep them), so give file variables as absolute paths (``run_deck`` makes existing
relative paths absolute). The numbers are those of the longest run of the deck (the timed one),
from LAMMPS' "Loop time of T on P procs for S steps with N atoms" and "Performance: ..." lines.
LAMMPS 29 Sep 2021 prints timesteps/s but not atom-step/s (later versions print both); when absent
the atom-step rate is S N / T.

Parallel runs use ``mpirun``. Open MPI refuses to start as root unless told to
(``--allow-run-as-root``); the environment variables OMPI_ALLOW_RUN_AS_ROOT(_CONFIRM) say the same
and are ignored by other MPI implementations (MPICH), so they are set when running as root.
"""
from __future__ import annotations

import os
import re
import shutil
import subprocess
import tempfile
from pathlib import Path

LOOP = re.compile(r"^Loop time of ([-+.\deE]+) on (\d+) procs for (\d+) steps with (\d+) atoms", re.M)
PERFORMANCE = re.compile(r"^Performance:(.*)$", re.M)


def lammps_available(ranks=1):
    """Whether ``lmp`` (and for ranks > 1 also ``mpirun``) is on the PATH."""
    return shutil.which("lmp") is not None and (ranks == 1 or shutil.which("mpirun") is not None)


def command(ranks=1):
    """The command line prefix for ``ranks`` MPI ranks, or None when the programs are missing."""
    lmp = shutil.which("lmp")
    if lmp is None:
        return None
    if ranks == 1:
        return [lmp]
    mpirun = shutil.which("mpirun")
    if mpirun is None:
        return None
    return [mpirun, "-np", str(ranks), lmp]


def environment(ranks=1):
    env = dict(os.environ, OMP_NUM_THREADS="1")
    if ranks > 1 and hasattr(os, "geteuid") and os.geteuid() == 0:
        env.update(OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1")
    return env


def parse_log(text):
    """Speed of the longest run in a LAMMPS log: dict with steps, atoms, procs, loop_time_s,
    timesteps_per_s and atom_steps_per_s (None if the log has no completed run)."""
    best = None
    for m in LOOP.finditer(text):
        seconds, procs, steps, atoms = float(m.group(1)), int(m.group(2)), int(m.group(3)), int(m.group(4))
        if steps == 0 or (best is not None and steps <= best["steps"]):
            continue
        # the Performance line follows its Loop line (it is printed for every run with steps)
        tail = text[m.end():]
        perf = PERFORMANCE.search(tail)
        line = perf.group(1) if perf else ""
        ts = re.search(r"([-+.\deE]+) timesteps/s", line)
        atom = re.search(r"([-+.\deE]+) (k|M)?atom-step/s", line)
        timesteps = float(ts.group(1)) if ts else steps / seconds
        if atom:
            scale = {"k": 1e3, "M": 1e6, None: 1.0}[atom.group(2)]
            atom_steps = float(atom.group(1)) * scale
        else:
            atom_steps = timesteps * atoms
        best = {"steps": steps, "atoms": atoms, "procs": procs, "loop_time_s": seconds,
                "timesteps_per_s": timesteps, "atom_steps_per_s": atom_steps,
                "performance_line": ("Performance:" + line).strip()}
    return best


def run_deck(deck, variables=None, ranks=1, workdir=None, timeout=None):
    """Run ``deck`` with ``-var NAME VALUE`` for each item of ``variables`` on ``ranks`` MPI ranks.

    Returns the dict of :func:`parse_log` plus "log" (the log text) and "ranks", or None when ``lmp``
    (or, for ranks > 1, ``mpirun``) is not installed. Raises RuntimeError with the end of the log
    when LAMMPS fails.
    """
    prefix = command(ranks)
    if prefix is None:
        return None
    deck = Path(deck).resolve()
    args = [*prefix, "-in", str(deck), "-screen", "none", "-log", "log.lammps", "-nocite"]
    for name, value in (variables or {}).items():
        value = str(value)
        if os.path.exists(value) and not os.path.isabs(value):
            value = os.path.abspath(value)
        args += ["-var", name, value]
    tmp = None
    if workdir is None:
        tmp = tempfile.TemporaryDirectory(prefix="demkit-lammps-")
        workdir = tmp.name
    try:
        Path(workdir).mkdir(parents=True, exist_ok=True)
        done = subprocess.run(args, cwd=workdir, env=environment(ranks), capture_output=True, text=True,
                              timeout=timeout)
        log_path = Path(workdir, "log.lammps")
        log = log_path.read_text() if log_path.exists() else ""
        if done.returncode != 0:
            raise RuntimeError(f"LAMMPS failed ({' '.join(args)}; exit {done.returncode}):\n"
                               + "\n".join((log + done.stdout + done.stderr).splitlines()[-25:]))
        result = parse_log(log)
        if result is None:
            raise RuntimeError(f"no completed run in the LAMMPS log of {deck}")
        result.update(ranks=ranks, log=log)
        return result
    finally:
        if tmp is not None:
            tmp.cleanup()
