"""``units = \"si\"``: SI numbers of a scene file converted to the seed paper's dimensionless units."""
from __future__ import annotations

import numpy as np

from ..schema import Key, Tables, Variant


def si_scales(scales):
    """(PaperUnits, {dimension: SI value of one dimensionless unit}) for a validated [scales] table."""
    from ..units import PaperUnits, dipole_from_magnetisation, induced_dipole
    moment = scales["dipole_moment"]
    if scales["field"] is not None:
        moment = induced_dipole(scales["susceptibility"], scales["radius"], scales["field"])
    units = PaperUnits.from_si(mass=scales["mass"], radius=scales["radius"], stiffness=scales["stiffness"],
                               young_modulus=scales["young_modulus"], dipole_moment=moment,
                               magnetisation=scales["magnetisation"])
    mu = moment or dipole_from_magnetisation(scales["magnetisation"], scales["radius"])
    m, length, t = units.mass, units.length, units.time
    k = m / t**2
    return units, {"length": length, "time": t, "mass": m, "velocity": length / t, "angular_velocity": 1 / t, "frequency": 1 / t,
                   "acceleration": length / t**2, "force": m * length / t**2, "stiffness": k, "damping": m / t, "energy": k * length**2,
                   "angular_momentum": m * length**2 / t,
                   "pressure": k / length, "dipole": mu, "dipole_prefactor": k * length**5 / mu**2,
                   "field": k * length**2 / mu, "inverse_length": 1 / length}


def _convert(schema, data, scale):
    """Divide every dimensional value of ``data`` by its unit's SI value (in place)."""
    if data is None:
        return
    if isinstance(schema, Variant):
        schema = schema.variants[data[schema.key]]
    for name, entry in schema.keys.items():
        value = data.get(name)
        if isinstance(entry, Key):
            if entry.dim is not None and value is not None and not isinstance(value, str):
                data[name] = (np.asarray(value, dtype=np.float64) / scale[entry.dim]).tolist()
        elif isinstance(entry, Tables):
            for item in value or []:
                _convert(entry.table, item, scale)
        else:
            _convert(entry, value, scale)
