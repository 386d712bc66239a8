"""Pair interactions: each module holds one kind of physics."""
from .base import PairInteraction
from .contact import KelvinVoigt
from .friction import Friction
from .hertz import Hertz
from .rolling import RollingResistance
from .twisting import TwistingResistance
from .sphere import SphereInteraction
from .fields import Gravity, UniformField
from .magnets import MagnetField
from .langevin import Langevin
from .wall import Servo, Wall
from .cylinder import Cylinder
from .cone import Cone
from .mesh import MeshWall
from .dipole import Dipole, PowerLawDipole
from .ewald import Ewald
from .fmm import FMM
from .p3m import P3M
from .induction import Induction

__all__ = ["PairInteraction", "Dipole", "PowerLawDipole", "KelvinVoigt", "Friction", "RollingResistance",
           "TwistingResistance", "Hertz", "SphereInteraction", "Gravity", "UniformField", "MagnetField", "Wall", "Servo", "Cylinder", "Cone", "MeshWall", "Langevin", "Ewald", "P3M", "FMM",
           "Induction"]
