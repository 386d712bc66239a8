"""Output for ParaView: VTK time series (.pvd + one .vtu per frame) and trajectory poly-lines.

meshio is imported only when a frame is written or read, so ``import demkit`` stays cheap.
"""
from pathlib import Path

from .frames import VECTOR_FIELDS, read_frame
from .pvd import read_pvd, write_pvd
from .series import SeriesData, read_series, write_polylines
from .walls import write_series
from .writer import VTKWriter

__all__ = ["VTKWriter", "write_polylines", "write_series", "read_series", "SeriesData",
           "read_frame", "read_pvd", "write_pvd", "paraview_script", "VECTOR_FIELDS"]


def paraview_script():
    """Path of the pvpython script that sets up sphere glyphs and dipole arrows for a series:
    ``pvpython <path> series.pvd`` (see ``python -m demkit.io --help``)."""
    return Path(__file__).with_name("paraview_setup.py")
