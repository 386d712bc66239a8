"""Reading a scene file: the text into checked data (the schema, the rules between keys, ``--set``
overrides). Reading executes nothing from the file."""
from __future__ import annotations

from ..schema import SchemaError, dotted, key_lines, line_of
from .errors import SceneFileError


class _Source:
    """The text of a scene file, for messages with lines."""

    def __init__(self, text, name, overrides):
        self.text, self.name = text, name
        self.overridden = [tuple(_split(k)) for k in (overrides or {})]
        self.units_note = ""  # units = "si": constructors' messages quote converted numbers; this says so
        self._lines = None

    def error(self, path, message):
        path = tuple(path)
        for key in self.overridden:
            if path[:len(key)] == key or key[:len(path)] == path and path:
                return SceneFileError(f"{message} (set by override {dotted(key)})", self.name, path)
        if self._lines is None:
            self._lines = key_lines(self.text)
        return SceneFileError(message, self.name, path, line_of(self._lines, path))


def _split(key):
    parts = []
    for part in str(key).split("."):
        parts.append(int(part) if part.isdigit() else part)
    return parts


def apply_overrides(data, overrides, source=None):
    """Set each dotted key path of ``overrides`` in the raw dict ``data`` (tables are created as needed;
    a number selects an item of an array of tables: ``interactions.wall.0.point``)."""
    for key, value in (overrides or {}).items():
        parts = _split(key)
        if not parts or any(p == "" for p in parts):
            raise SceneFileError(f"override key {key!r} is not a dotted key path", source)
        node = data
        for k, part in enumerate(parts[:-1]):
            where = parts[:k + 1]
            if isinstance(node, list):
                if not isinstance(part, int) or part >= len(node):
                    raise SceneFileError(f"override {key!r}: no item {part} in {dotted(where[:-1])}", source)
                node = node[part]
            elif isinstance(node, dict):
                if isinstance(part, int):
                    raise SceneFileError(f"override {key!r}: {dotted(where[:-1])} is not an array of tables", source)
                node = node.setdefault(part, {})
            else:
                raise SceneFileError(f"override {key!r}: {dotted(where[:-1])} is a value, not a table", source)
        if not isinstance(node, dict) or isinstance(parts[-1], int):
            raise SceneFileError(f"override {key!r}: {dotted(parts[:-1])} is not a table", source)
        node[parts[-1]] = value
    return data


def _check_prefactors(raw, data):
    """In plain units a dipole's prefactor is given: its default, mu0/4pi = 1e-7, is SI's constant."""
    if data["units"] == "si":
        return
    for name in ("dipole", "power_law_dipole"):
        table = (raw.get("interactions") or {}).get(name)
        if isinstance(table, dict) and "prefactor" not in table:
            raise SchemaError(("interactions", name, "prefactor"),
                              "is required in plain units (A in F = A (...) m m / r^4: 1/3 with unit moments in "
                              "the seed paper's units; mu0/4pi = 1e-7 only in SI, with units = \"si\")")


def _check_rules(data):
    """What the schema cannot say: rules between tables."""
    if data["units"] == "si" and data["scales"] is None:
        raise SchemaError(("units",), 'units = "si" needs a [scales] table (the reference sphere)')
    if data["units"] != "si" and data["scales"] is not None:
        raise SchemaError(("scales",), 'is used only with units = "si"')
    scales = data["scales"] or {}
    if scales.get("field") is not None and scales.get("susceptibility") is None:
        raise SchemaError(("scales", "field"), "needs susceptibility: the reference sphere's moment is the one the "
                                               "field induces in it")
    if scales.get("susceptibility") is not None and scales.get("field") is None:
        raise SchemaError(("scales", "susceptibility"), "goes with field (the field that induces the reference "
                                                        "moment)")
    inter = data["interactions"] or {}
    contact = inter.get("kelvin_voigt") or inter.get("hertz")
    for name in ("friction", "rolling_resistance", "twisting_resistance"):
        if inter.get(name) is not None and contact is None:
            raise SchemaError(("interactions", name), "needs a contact law: [interactions.kelvin_voigt] or "
                                                      "[interactions.hertz]")
    for name in ("rolling_resistance", "twisting_resistance"):
        if inter.get(name) is not None and inter.get("friction") is None:
            raise SchemaError(("interactions", name), "needs [interactions.friction]")
    if inter.get("wall") and contact is None:
        raise SchemaError(("interactions", "wall", 0), "walls use the scene's contact law: add "
                                                       "[interactions.kelvin_voigt] or [interactions.hertz]")
    build = (data["particles"] or {}).get("build")
    if build is not None and data["box"] is not None and (
            build["kind"] == "lattice" or (build["kind"] == "random_packing" and build["volume_fraction"])):
        raise SchemaError(("box",), f"the {build['kind']} builder makes the box"
                                    f"{' (volume_fraction)' if build['kind'] == 'random_packing' else ''}: "
                                    f"leave out [box]")
    out = data["outputs"] or {}
    if out.get("stress") is not None and data["run"]["stress_every"] is None:
        raise SchemaError(("outputs", "stress"), "is the series measured every run.stress_every: add stress_every "
                                                 "to [run]")
    if out.get("animation") is not None and out.get("vtk") is None:
        raise SchemaError(("outputs", "animation"), "is made from the VTK series: add [outputs.vtk]")
    integ = data["integrator"]
    if ":" in integ["method"] and (integ["inner"] is not None or integ["resolve_contacts"]):
        raise SchemaError(("integrator", "method"), "give inner and resolve_contacts either in the name "
                                                    "(MultipleTimeStep:8:resolve) or as keys, not both")
