"""Pair interactions: each module holds one kind of physics."""
from .base import PairInteraction
from .contact import KelvinVoigt
from .dipole import Dipole, PowerLawDipole

__all__ = ["PairInteraction", "Dipole", "PowerLawDipole", "KelvinVoigt"]
