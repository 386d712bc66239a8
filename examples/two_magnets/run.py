"""The main job (README's first command): one collision of the seed paper with its conservation
figures, a VTK series + animation of it, then the paper's full replication (figures, CSVs and
docs/two_magnets.md regenerated).

Every stage says what it does and about how long it takes (measured on a 2-core machine with the
kernels compiled); long stages show a progress bar on a terminal. The first run on a machine also
compiles the kernels (demkit says so on stderr, and how long it took). Wall times are printed
here, never written into tracked files.
"""
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import collision  # noqa: E402
import replicate  # noqa: E402
import watch  # noqa: E402

#: (title, what it does and its usual duration once compiled, 2 cores)
STAGES = {
    "collision": ("one collision (b/R = 4)", "6.4 million Euler-Cromer steps, about 1 s on the scene's own "
                                             "code, cached by earlier runs; about 7 s on a new install"),
    "watch": ("VTK series for ParaView and an animation",
              "451 VTK frames (about 1 s), then 120 animation frames (about 8 s)"),
    "replication": ("replication of Bartz & Shaw",
                    "the paper's sweeps, figures and report; the longest stage"),
}


def section(key):
    title, what = STAGES[key]
    print(f"\n=== {title} " + "=" * max(0, 70 - len(title)), flush=True)
    print(f"({what})", flush=True)


def main():
    start = time.perf_counter()
    sys.stdout.reconfigure(line_buffering=True)  # in a log, lines keep their order with demkit's stderr
    print("demkit main job: a collision, its animation, then the replication of Bartz & Shaw. "
          "The first run on a machine compiles the kernels first (demkit says so below).", flush=True)
    stages = {}
    for key, job in (("collision", lambda: collision.main([])), ("watch", watch.main),
                     ("replication", replicate.main)):
        section(key)
        began = time.perf_counter()
        job()
        stages[key] = time.perf_counter() - began
    took = ", ".join(f"{key} {seconds:.0f} s" for key, seconds in stages.items())
    print(f"\nmain job done in {time.perf_counter() - start:.0f} s ({took})")


if __name__ == "__main__":
    main()
