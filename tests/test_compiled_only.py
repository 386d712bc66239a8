"""Functions compiled with ``COMPILED_ONLY`` (demkit.engine.motion: no wrapper for calls from Python,
none for first-class use) are called by compiled code alone: a call from Python would crash the
interpreter, not raise. This test reads every Python file of demkit, the tests, the benchmarks and the
examples and fails if one refers to such a function outside a compiled function's body."""
import ast
import importlib
import pkgutil
from pathlib import Path

import demkit
from demkit.engine.motion import COMPILED_ONLY

ROOT = Path(__file__).resolve().parents[1]


def compiled_only():
    """{name: module} of demkit's functions compiled without the Python wrapper."""
    found = {}
    for info in pkgutil.walk_packages(demkit.__path__, "demkit."):
        path = ROOT / (info.name.replace(".", "/") + ".py")
        if not path.exists() or "COMPILED_ONLY" not in path.read_text():  # (no other module uses it)
            continue
        module = importlib.import_module(info.name)
        for name, obj in vars(module).items():
            options = getattr(obj, "targetoptions", None)
            if options and getattr(obj, "__module__", None) == info.name and all(
                    options.get(key) == value for key, value in COMPILED_ONLY.items()):
                found[name] = info.name
    return found


def _compiled(node):
    return any("njit" in ast.unparse(d) or "jit(" in ast.unparse(d) for d in node.decorator_list)


def python_references(names, paths=None):
    """Where Python code (not the body of a compiled function) of ``paths`` (default: every file of
    demkit, the tests, the benchmarks and the examples) names one of ``names``."""
    found = []
    if paths is None:
        paths = [p for d in ("demkit", "tests", "benchmarks", "examples") for p in (ROOT / d).rglob("*.py")]
    for path in paths:
        tree = ast.parse(path.read_text())

        def visit(node, inside):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                inside = inside or _compiled(node)
            if not inside:
                if isinstance(node, ast.Name) and node.id in names and isinstance(node.ctx, ast.Load):
                    found.append(f"{path.name}:{node.lineno} {node.id}")
                elif isinstance(node, ast.Attribute) and node.attr in names:
                    found.append(f"{path.name}:{node.lineno} {node.attr}")
                elif isinstance(node, ast.ImportFrom):  # imported under another name: that name is unchecked
                    found.extend(f"{path.name}:{node.lineno} {a.name} as {a.asname}" for a in node.names
                                 if a.name in names and a.asname and a.asname != a.name)
            for child in ast.iter_child_nodes(node):
                visit(child, inside)
        visit(tree, False)
    return found


def test_functions_compiled_without_the_python_wrapper_are_never_called_from_python():
    names = compiled_only()
    assert len(names) >= 40  # (the friction and spring helpers, the builder's loops, the solve's pair fields...)
    assert {"pair_friction", "fill_pairs", "geometry_plane", "pair_field"} <= set(names)
    assert python_references(set(names)) == []


def test_the_check_sees_a_python_call_and_leaves_compiled_ones_alone(tmp_path):
    source = tmp_path / "user.py"
    source.write_text(
        "from numba import njit\n"
        "from demkit.engine.neighbours import fill_pairs\n"
        "from demkit.interactions.friction import pair_friction as grip\n"
        "@njit\n"
        "def compiled(*args):\n"
        "    return fill_pairs(*args)\n"
        "def plain(*args):\n"
        "    return fill_pairs(*args)\n")
    assert python_references({"fill_pairs", "pair_friction"}, [source]) == [
        "user.py:3 pair_friction as grip", "user.py:8 fill_pairs"]
