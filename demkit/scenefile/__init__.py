"""Scene files: a whole simulation (spheres, box, interactions, integrator, run, outputs) in TOML.

    loaded = dk.load_scene("collision.toml")                        # or dk.parse_scene(text)
    loaded = dk.load_scene("collision.toml", overrides={"particles.build.b_over_R": 3.0})
    trajectory = loaded.run()                                       # writes what [outputs] asks for

The format is :data:`SCHEMA` (reference: docs/scene_files.md, generated from it by
:func:`reference`). Reading a file executes nothing from it. Every problem is one
:class:`SceneFileError` naming the file, the line and the key path (``interactions.dipole.prefactor``);
the line comes from a scan of the text (:func:`demkit.schema.key_lines`, tomllib gives none).

``units = "si"`` reads every dimensional number in SI and converts it to the seed paper's
dimensionless units (:mod:`demkit.units`) with the scales of the ``[scales]`` table (mass, radius,
stiffness or Young's modulus, dipole moment or magnetisation of the reference sphere): lengths in
x_c, times in t_c, moments in the reference moment, and the dipole prefactor mu0/4pi (SI) becomes
1/3. The run and its outputs are then in those units (``LoadedScene.units`` converts back).

The parts, in the order they use one another: :mod:`~demkit.scenefile.errors`, :mod:`~demkit.scenefile.format`
(the schema), :mod:`~demkit.scenefile.reading` (text to checked data), :mod:`~demkit.scenefile.si` (SI input),
:mod:`~demkit.scenefile.running` (:class:`LoadedScene`, trajectory files), :mod:`~demkit.scenefile.building`
(checked data to a scene) and :mod:`~demkit.scenefile.loading` (:func:`load_scene`, :func:`parse_scene`).
"""
from .errors import MAX_FILE_BYTES, SceneFileError
from .format import BUILDERS, INTERACTIONS, PARTICLES, SCHEMA, reference
from .reading import apply_overrides
from .running import LoadedScene, frames_digest, load_trajectory, save_trajectory
from .building import magnet_source, read_particle_file
from .loading import load_scene, parse_scene

__all__ = ["load_scene", "parse_scene", "LoadedScene", "SceneFileError", "SCHEMA", "reference", "apply_overrides",
           "load_trajectory", "save_trajectory", "read_particle_file", "magnet_source", "MAX_FILE_BYTES"]
