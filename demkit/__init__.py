"""demkit: discrete-element simulation of spinning rigid spheres with pluggable pair interactions."""
from .engine import numba_cache
numba_cache.install()  # before any function is defined: caches stamped with the whole package's source
from .engine import numba_patches  # noqa: F401 (numba's compiler made faster, its output the same)
from . import units
from .box import Box, Deform, Shear
from .integrators import RK4, EulerCromer, ForestRuth, Integrator, MultipleTimeStep, VelocityVerlet
from .interactions import (Cone, Cylinder, Dipole, Friction, Gravity, Hertz, KelvinVoigt, Langevin, MagnetField, MeshWall,
                           PairInteraction, PowerLawDipole, RollingResistance, Servo, SphereInteraction,
                           TwistingResistance, UniformField, Wall)
from .interactions.ewald import Ewald
from .interactions.fmm import FMM
from .interactions.p3m import P3M
from .interactions.induction import Induction
from .particles import Particles
from .scene import Scene
from .checkpoint import Checkpoint
from .simulation import CheckpointWarning, LargeOutputWarning, Simulation, SimulationError
from .trajectory import Trajectory
from . import viz  # pyvista is imported only when drawing
from .io import VTKWriter, read_series, write_polylines, write_series
from . import two_magnets  # the seed paper's two-body study: its scene, analysis, fits, capture
from . import threads  # noqa: F401 (moved to demkit.engine.threads; dk.threads keeps working)
from . import clustering  # clusters, contacts, chains and rings of spheres in one frame
from . import build  # starting scenes: random packings, lattices, chains, rings, thermal states
from . import accuracy  # adaptive reference solutions and work-precision reports
from .dipole_sums import compare_dipole_sums  # which dipole sum for my scene: error against time
from . import guards  # checks before and during runs: time steps, spins, contacts that hold magnets
from .step_choice import choose_time_step  # a time step for an accuracy of the energy balance (dt = "auto")
from . import cost  # what a run will cost in time, estimated before it runs (demkit info)
from . import measure  # what papers report: pressure tensor, coordination, local fields, magnetisation
from .stress_series import StressSeries  # the stress measured during a run; a sheared sample's rheology
from .box_servo import PressureServo  # a deforming box driven to a set pressure
from .scenefile import LoadedScene, SceneFileError, load_scene, parse_scene  # TOML scene files
from .lammps import export_lammps  # a scene as a LAMMPS data file and input deck
from .sweep import sweep, sweep_file  # parameter sweeps (the function dk.sweep hides the module name)

from .version import __version__  # noqa: E402

__all__ = ["Box", "Deform", "Shear", "Particles", "Scene", "Simulation", "SimulationError", "Trajectory", "Checkpoint",
           "LargeOutputWarning", "CheckpointWarning", "Dipole",
           "PowerLawDipole", "KelvinVoigt", "Friction", "RollingResistance", "TwistingResistance", "Hertz",
           "PairInteraction", "SphereInteraction", "Wall", "Servo", "Cylinder", "Cone", "MeshWall", "Gravity", "UniformField", "MagnetField", "Langevin", "Ewald", "P3M", "FMM", "Induction", "EulerCromer", "VelocityVerlet", "ForestRuth", "RK4", "MultipleTimeStep",
           "Integrator", "units", "VTKWriter", "StressSeries", "PressureServo", "write_polylines",
           "write_series", "read_series", "io", "viz", "two_magnets", "build", "clustering", "accuracy", "compare_dipole_sums", "guards", "choose_time_step",
           "load_scene", "parse_scene", "LoadedScene", "SceneFileError", "export_lammps", "sweep", "sweep_file"]
