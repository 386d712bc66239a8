"""The main job (README's first command): one collision of the seed paper with its conservation
figures, a VTK series + animation of it, then the paper's full replication (figures, CSVs and
docs/two_magnets.md regenerated)."""
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import collision  # noqa: E402
import replicate  # noqa: E402
import watch  # noqa: E402


def section(title):
    print(f"\n=== {title} " + "=" * max(0, 70 - len(title)), flush=True)


def main():
    start = time.perf_counter()
    section("one collision (b/R = 4)")
    collision.main([])
    section("VTK series for ParaView and an animation")
    watch.main()
    section("replication of Bartz & Shaw")
    replicate.main()
    print(f"\nmain job done in {time.perf_counter() - start:.0f} s")


if __name__ == "__main__":
    main()
