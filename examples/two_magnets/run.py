"""The main job: one collision with its conservation figures, the paper's replication, and a
VTK series + animation of one collision (see README.md)."""
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import collision  # noqa: E402


def main():
    print("=== one collision " + "=" * 60)
    collision.main([])


if __name__ == "__main__":
    main()
