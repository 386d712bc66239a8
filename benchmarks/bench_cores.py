"""What two threads can gain on this machine, for two kinds of loop. Writes benchmarks/results/cores.json.

* ``latency``: each element a chain of dependent square roots (the arithmetic waits for itself,
  as a scalar pair loop like LAMMPS' does);
* ``throughput``: independent fused multiply-adds over a vector held in the L1 cache (the arithmetic
  units are kept full, as demkit's vectorised dipole loop does).

The same work split in two halves runs on 1 and on 2 threads (numba prange); best of 5 each. Two
cores that are two hardware threads of one physical core (or that share a clock budget) give
nearly 2x on the first loop and much less on the second: that ceiling applies to every code whose
arithmetic is vectorised, and two MPI ranks of a scalar code do not meet it.

Usage: python benchmarks/bench_cores.py
"""
from __future__ import annotations

import json
import math
import os
import time
from pathlib import Path

import numba
import numpy as np
from numba import njit, prange

RESULTS = Path(__file__).resolve().parent / "results" / "cores.json"


@njit(parallel=True, fastmath=True)
def latency_bound(a, reps):
    for t in prange(2):
        for i in range(a.shape[1]):
            x = a[t, i]
            for _ in range(reps):
                x = math.sqrt(x * x + 1.0) * 0.999
            a[t, i] = x


@njit(parallel=True, fastmath=True)
def throughput_bound(a, b, reps):
    for t in prange(2):
        for _ in range(reps):
            for i in range(a.shape[1]):
                a[t, i] = a[t, i] * b[i] + b[i]


def best_of(fn, repeats=5):
    fn()
    best = math.inf
    for _ in range(repeats):
        start = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - start)
    return best


def main():
    rng = np.random.default_rng(1)
    results = {}
    for name, fn in (("latency", lambda: latency_bound(rng.random((2, 2000)), 20000)),
                     ("throughput", lambda: throughput_bound(rng.random((2, 512)) * 0.5, rng.random(512) * 0.5,
                                                             2000000))):
        seconds = {}
        for threads in (1, 2):
            numba.set_num_threads(threads)
            seconds[threads] = best_of(fn)
        results[name] = {"seconds_1_thread": seconds[1], "seconds_2_threads": seconds[2],
                         "speedup": seconds[1] / seconds[2]}
        print(name, json.dumps(results[name]))
    results["machine"] = f"{os.uname().machine}, {os.cpu_count()} cores"
    results["date"] = time.strftime("%Y-%m-%d")
    RESULTS.parent.mkdir(exist_ok=True)
    RESULTS.write_text(json.dumps(results, indent=2) + "\n")


if __name__ == "__main__":
    main()
