"""The package's imports go one way: no circles, and no module imports one of a higher layer.

Read from the source (every ``import`` and ``from ... import`` statement, those inside functions too),
not from what Python happens to have loaded. A name imported from a package that re-exports it
(``from .interactions import Dipole``) counts as an import of the module that defines it.

Layers, from the bottom (docs/architecture.md): the foundations (checks, units, boxes, particles,
memory, output paths, the schema checker, file formats, cluster geometry, the version), the engine
(``demkit/engine``: compiled code), the physics (``demkit/interactions``), scenes, runs, analysis,
input/output and pictures, and on top scene files, sweeps, LAMMPS decks and the command line. A module
may import its own layer and those below.
"""
import ast
import functools
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1] / "demkit"
#: (layer, its modules: names, or package prefixes ending in "."), from the bottom
LAYERS = [
    ("foundations", {"demkit.version", "demkit.checks", "demkit.units", "demkit.box", "demkit.particles",
                     "demkit.memory", "demkit.outputs", "demkit.schema", "demkit.clustering", "demkit.io.frames",
                     "demkit.io.pvd", "demkit.io.polylines", "demkit.io.series"}),
    ("engine", {"demkit.engine", "demkit.engine."}),
    ("physics", {"demkit.interactions", "demkit.interactions."}),
    ("scenes", {"demkit.scene", "demkit.diagnostics", "demkit.contacts", "demkit.build", "demkit.integrators",
                "demkit.trajectory", "demkit.sheared", "demkit.deformed", "demkit.progress", "demkit.guards", "demkit.threads"}),
    ("runs", {"demkit.simulation", "demkit.recording", "demkit.stops", "demkit.checkpoint", "demkit.notes",
              "demkit.cost"}),
    ("analysis", {"demkit.measure", "demkit.stress_series", "demkit.box_servo", "demkit.accuracy", "demkit.accuracy.", "demkit.dipole_sums", "demkit.step_choice",
                  "demkit.two_magnets", "demkit.two_magnets."}),
    ("input/output and pictures", {"demkit.io", "demkit.io.", "demkit.viz", "demkit.viz."}),
    ("scene files, sweeps and the command line", {"demkit.scenefile", "demkit.scenefile.", "demkit.sweep",
                                                  "demkit.scene_observables", "demkit.lammps", "demkit.commands",
                                                  "demkit.cli", "demkit.__main__", "demkit.viz.command", "demkit"}),
]


def module_name(path):
    parts = list(path.relative_to(PACKAGE.parent).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


@functools.cache
def import_graph():
    """{module: set of demkit modules it imports}, for every module of the package (read once, when a test
    asks: at the module's import it cost each test worker 3 s of collection)."""
    modules = {module_name(p): p for p in PACKAGE.rglob("*.py")}
    packages = {m for m, p in modules.items() if p.name == "__init__.py"}

    def absolute(module, node):
        if not node.level:
            return node.module or ""
        here = module.split(".") if module in packages else module.split(".")[:-1]
        base = here[:len(here) - (node.level - 1)]
        return ".".join(base + ([node.module] if node.module else []))

    reexports = {}  # (package, name) -> the module that defines it
    for package in packages:
        for node in ast.parse(modules[package].read_text()).body:
            if isinstance(node, ast.ImportFrom) and node.level:
                source = absolute(package, node)
                for alias in node.names:
                    full = f"{source}.{alias.name}"
                    reexports[(package, alias.asname or alias.name)] = full if full in modules else source

    def known(name):
        while name not in modules and "." in name:
            name = name.rsplit(".", 1)[0]
        return name if name in modules else None

    graph = {}
    for module, path in modules.items():
        targets = set()
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom):
                source = absolute(module, node)
                if not source.startswith("demkit"):
                    continue
                for alias in node.names:
                    if f"{source}.{alias.name}" in modules:
                        targets.add(f"{source}.{alias.name}")
                    elif (source, alias.name) in reexports and source != module:
                        targets.add(reexports[(source, alias.name)])
                    else:
                        targets.add(source)
            elif isinstance(node, ast.Import):
                targets |= {alias.name for alias in node.names if alias.name.startswith("demkit")}
        graph[module] = {t for t in map(known, targets) if t is not None and t != module}
    return graph


def circles(graph):
    """The strongly connected components of more than one module (Tarjan), each sorted."""
    index, low, stack, on_stack, found = {}, {}, [], set(), []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in graph[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                found.append(sorted(component))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return found


def layer(module):
    """The index of the module's layer in LAYERS: an exact name first, else the longest package prefix."""
    exact = [k for k, (_, members) in enumerate(LAYERS) if module in members]
    if exact:
        return exact[-1]  # (demkit.viz.command is a command, not a picture)
    prefixes = [(len(p), k) for k, (_, members) in enumerate(LAYERS) for p in members
                if p.endswith(".") and module.startswith(p)]
    if not prefixes:
        raise AssertionError(f"{module} is in no layer of tests/test_layers.py: give it one (docs/architecture.md)")
    return max(prefixes)[1]




def test_the_walker_sees_imports_inside_functions_and_through_re_exports():
    # a lazy import inside a function, and a name re-exported by demkit.interactions
    assert "demkit.engine.templates" in import_graph()["demkit.engine.tiers"]
    assert "demkit.interactions.dipole" in import_graph()["demkit.scene"]
    assert {"demkit.interactions.contact", "demkit.interactions.wall"} <= import_graph()["demkit"]  # KelvinVoigt, Wall
    # and finds a circle when there is one
    assert circles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]


def test_no_import_circles():
    assert circles(import_graph()) == []


def test_every_module_has_a_layer():
    assert all(layer(m) >= 0 for m in import_graph())


def upward(graph):
    """Every import of a module of a higher layer, as text."""
    return sorted(f"{m} ({LAYERS[layer(m)][0]}) -> {t} ({LAYERS[layer(t)][0]})"
                  for m, targets in graph.items() for t in targets if layer(t) > layer(m))


def test_no_module_imports_a_higher_layer():
    assert upward({"demkit.checks": {"demkit.scene"}, "demkit.scene": {"demkit.checks"}}) == [
        "demkit.checks (foundations) -> demkit.scene (scenes)"]  # (what a violation looks like)
    assert upward(import_graph()) == []
