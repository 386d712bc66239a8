"""Memory: what a scene will need, estimated before anything large is allocated, and a refusal of
what this machine cannot hold.

:func:`estimate` adds up, in bytes, what a run of n spheres keeps (each part from the arrays the
code allocates; measured against the peak memory of real runs in docs/nbody.md):

* ``arrays``: per sphere, the user's :class:`demkit.Particles` (position, velocity, spin and dipole
  when present: 24 bytes each; radius, mass, inertia, ids: 8 each; image counts in periodic boxes:
  24), the kernels' copies of them (sorted scenes), force and torque (48), the threads' own force
  and torque (48 per extra thread), the list-rebuild reference (24), per-sphere history (8 per
  value), the integrator's stages (24 each, 9 for RK4) and the cell list's working arrays (48);
* ``lists``: per neighbour list, the pairs within reach + skin, ``n * pairs_per_sphere`` entries
  with room for 1/8 more (4 bytes of partner index plus 8 per history value each), and 16 bytes per
  sphere of row bounds; all-pairs loops with history keep n (n - 1) / 2 rows;
* ``record``: the frames a run keeps in memory, 24 bytes per sphere and recorded vector (position,
  velocity, spin, dipole, image).

:func:`refuse_above` raises ValueError when the total exceeds the memory available now (MemAvailable
on Linux; else the physical memory), naming what was asked, the estimate and what the machine has.
"""
from __future__ import annotations

import math
import os

#: bytes in a GB (the estimates are printed in GB = 10^9 bytes)
GB = 1e9
#: the densest packing of equal spheres (pi / sqrt(18)): bounds the spheres within a reach when
#: the volume they fill is unknown
DENSEST = math.pi / math.sqrt(18.0)
#: neighbour lists keep room for this fraction more entries than they hold (demkit.engine.neighbours.GROWTH)
LIST_ROOM = 1.0 / 8.0


def machine_memory():
    """(available, total) bytes of memory of this machine: MemAvailable and MemTotal of
    /proc/meminfo (Linux); elsewhere both are the physical memory (0 when unknown)."""
    try:
        with open("/proc/meminfo") as f:
            info = dict(line.split(":", 1) for line in f if ":" in line)
        available = int(info["MemAvailable"].split()[0]) * 1024
        total = int(info["MemTotal"].split()[0]) * 1024
        return available, total
    except (OSError, KeyError, ValueError, IndexError):
        pass
    try:
        total = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (ValueError, OSError, AttributeError):
        total = 0
    return total, total


def pairs_per_sphere(n, reach, radius, volume=None):
    """Expected pairs per sphere within centre distance ``reach`` (each pair counted once): half the
    other spheres in a ball of radius ``reach``, (1/2) rho (4/3) pi reach^3 at the number density
    rho = n / ``volume``; without a volume, the most that spheres of ``radius`` can be there without
    overlapping, (1/2) (DENSEST ((reach + radius) / radius)^3 - 1) (an upper bound); at most
    (n - 1) / 2, all of them for an infinite reach."""
    if n < 2:
        return 0.0
    if not math.isfinite(reach):
        return (n - 1) / 2.0
    try:
        if volume is not None and volume > 0.0:
            count = 0.5 * n / volume * 4.0 / 3.0 * math.pi * reach**3
        else:
            count = 0.5 * max(DENSEST * ((reach + radius) / radius) ** 3 - 1.0, 0.0)
    except OverflowError:  # a reach of 1e300 radii: every other sphere
        count = math.inf
    return min(count, (n - 1) / 2.0)


def estimate(n, *, dipoles=False, spins=False, periodic=False, fixed=False, sorted_copies=True, threads=1,
             stages=0, sphere_history=0, lists=(), all_pairs_history=0, frames=0):
    """{"arrays", "lists", "record", "total"}: bytes a scene of ``n`` spheres needs (module docstring).

    lists : (pairs per sphere, history values per pair) of each neighbour list;
    all_pairs_history : history values per pair of an all-pairs loop (n (n - 1) / 2 rows);
    frames : frames recorded in memory (0: none)."""
    vectors = 2 + bool(spins) + bool(dipoles)
    user = 24 * vectors + 24 * bool(periodic) + 8 * 4 + bool(fixed)
    own = (24 * vectors + 24 * bool(periodic) + 8 * 3) if sorted_copies else 16 * bool(fixed)
    kernel = 8 + 48 + 24 + 48 * max(threads - 1, 0) + 24 * stages + 8 * sphere_history + 48
    arrays = n * (user + own + kernel)
    listed = sum(int(n * count * (1.0 + LIST_ROOM)) * (4 + 8 * width) + 16 * n for count, width in lists)
    listed += (n * (n - 1) // 2) * 8 * all_pairs_history
    record = frames * n * 24 * (vectors + bool(periodic))
    return {"arrays": arrays, "lists": listed, "record": record, "total": arrays + listed + record}


def describe(parts, frames=0):
    """'arrays 1.2 GB, neighbour lists 0.3 GB, record of 11 frames 2 GB' (the non-zero parts)."""
    out = [f"arrays {parts['arrays'] / GB:.3g} GB"]
    if parts["lists"]:
        out.append(f"neighbour lists {parts['lists'] / GB:.3g} GB")
    if parts["record"]:
        out.append(f"record of {frames:,} frames {parts['record'] / GB:.3g} GB")
    return ", ".join(out)


def refuse_above(needed, subject, advice, parts=None, memory=None):
    """Raise ValueError if ``needed`` bytes exceed the memory available (``memory``: (available,
    total) bytes, default :func:`machine_memory`): '<subject> about X GB (<parts>), more than this
    machine has available (Y GB free of Z GB): <advice>'. ``subject`` ends with its verb
    ("10,000 spheres need")."""
    available, total = memory if memory is not None else machine_memory()
    if available and needed > available:
        raise ValueError(f"{subject} about {needed / GB:.3g} GB{f' ({parts})' if parts else ''}, more than this "
                         f"machine has available ({available / GB:.3g} GB free of {total / GB:.3g} GB): {advice}")
