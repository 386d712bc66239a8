"""Moved: whether pair loops run on numba's threads is decided in :mod:`demkit.engine.threads`. This name
keeps working for scripts that read ``dk.threads`` (``dk.threads.estimated_force_seconds``, as
docs/nbody.md once said); new code should use ``demkit.engine.threads``."""
from .engine.threads import *  # noqa: F401,F403
