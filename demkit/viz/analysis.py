"""Moved: clusters and contacts of spheres in one frame are in :mod:`demkit.clustering` (analysis uses them,
not only pictures). This name keeps working for scripts that import ``demkit.viz.analysis``; new code
should use ``demkit.clustering``."""
from ..clustering import *  # noqa: F401,F403
