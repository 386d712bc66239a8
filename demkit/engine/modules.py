"""Generated modules on disk and in memory: their names (a fingerprint of their text, the pair functions'
source and demkit's whole source), numba's cache folder, and loading a module from its file (cached) or
from memory (functions defined in ``__main__``). One compile per machine is numba_cache's lock, taken per
function and signature: a lock over a whole module (until 1 Dec 2026) made a process wait while another
compiled a *different* function of the same module (the suite's two workers, 13-16 s at its start)."""
from __future__ import annotations

import hashlib
import importlib.util
import inspect
import os
import sys
import tempfile
from pathlib import Path

import numba

from .kernels import _Source, generate_source
from .plan import functions_importable, importable


#: generated modules loaded in this process, by name (or by plan and threads)
_MODULES = {}


def _cache_dir():
    root = os.environ.get("DEMKIT_CACHE_DIR")
    if root:
        return Path(root)
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "demkit" / "kernels"


def _source_of(inter, fn):
    """The source text of one of an interaction's numba functions, or a clear error without it."""
    try:
        return inspect.getsource(fn.py_func)
    except (OSError, TypeError):
        raise ValueError(f"{type(inter).__name__}: the source of {fn.__name__} cannot be read (made with exec, or "
                         f"typed into an interpreter?); demkit writes your functions into the code it compiles, "
                         f"so define them in a .py file") from None


def _fingerprint(source, interactions):
    """The module's text, numba's version, the source of the interactions' own functions (plug-ins
    live outside demkit) and demkit's whole source (:data:`demkit.engine.numba_cache.FINGERPRINT`): the
    module inlines helpers from many of demkit's files (friction, events, motion, ...), and an edit
    of any of them must give it a new name, not a stale cache."""
    from .numba_cache import FINGERPRINT
    h = hashlib.sha256(source.encode())
    h.update(numba.__version__.encode())
    for inter in interactions:
        for fn in inter.pair_functions():
            h.update(_source_of(inter, fn).encode())
    h.update(FINGERPRINT.encode())
    return h.hexdigest()[:20]


def is_cached(plan, templates, function, threads=False):
    """Is ``function`` of this plan's module (the thread module with ``threads``) in numba's disk
    cache already (loading it then takes a fraction of a second, compiling it many seconds)?"""
    return functions_importable(plan) and cached_function(fused_name(plan, templates, threads), function)


def fused_name(plan, templates, threads=False):
    """The name of this plan's fused module (tier 2): ``demkit_kernel_<fingerprint of its text>``."""
    interactions = plan.interactions + plan.effects
    return f"demkit_kernel_{_fingerprint(generate_source(plan, templates, True, threads), interactions)}"


def cached_function(module, function):
    """Is ``function`` of the generated module named ``module`` in numba's disk cache? (numba puts
    it beside the file, or under NUMBA_CACHE_DIR in a folder of its own when that is set)"""
    pattern = f"{module}.{function}-*.nbi"
    if any((_cache_dir() / "__pycache__").glob(pattern)):
        return True
    root = os.environ.get("NUMBA_CACHE_DIR")
    return bool(root) and any(Path(root).glob(f"*/{pattern}"))


def fused_source(plan, templates, threads=False):
    """The text of the fused module (tier 2) of this plan, as :func:`build_module` would compile it."""
    return generate_source(plan, templates, importable(plan), threads)


def build_module(plan, templates, threads=False):
    """Return the compiled kernel module for this plan and these integrator templates (the thread
    module with ``threads``: the same arithmetic, loops on numba's threads)."""
    interactions = plan.interactions + plan.effects
    for inter in interactions:
        for fn in inter.pair_functions():
            if not hasattr(fn, "py_func"):
                raise TypeError(f"{type(inter).__name__}: pair functions must be numba @njit functions")
    on_disk = importable(plan)
    source = generate_source(plan, templates, on_disk, threads)
    key = _fingerprint(source, interactions)
    name = f"demkit_kernel_{key}"
    if not on_disk:  # in memory: bind to these very function objects, not look-alikes
        key += "".join(f"-{id(fn)}" for inter in interactions for fn in inter.pair_functions())
    if key in _MODULES:
        return _MODULES[key]
    if on_disk:
        module = _load_from_file(name, source)
    else:
        module = _load_in_memory(name, source, plan)
    # Start numba's threading layer before any kernel runs. Kernels loaded from the disk cache call
    # the threaded list builder (neighbours.fill_threads) through code that expects the layer to
    # be running; nothing else starts it when no threaded function was called from Python first
    # (a one-sphere periodic scene segfaulted on its second run). get_num_threads() launches it.
    numba.get_num_threads()
    module.source = source
    _MODULES[key] = module
    return module


def pieces_source(plan, columns, threads=False):
    """(text, module name) of the scene's own pieces (tier 2 of a scene with neighbour lists, see
    :meth:`_Source.pieces_text`; ``columns``: where a program row holds its group and speed;
    ``threads``: its pair loops on threads, calling the serial chunks)."""
    source = _Source(plan, True).pieces_text(columns)
    name = f"demkit_pieces_{_fingerprint(source, plan.interactions + plan.effects)}"
    if threads:
        source = _Source(plan, True, threads=True).pieces_text(columns, serial_name=name)
        name = f"demkit_pieces_threads_{_fingerprint(source, plan.interactions + plan.effects)}"
    return source, name


def build_pieces(plan, columns, threads=False):
    """The compiled module of the scene's own pieces (``columns`` and ``threads``: see
    :func:`pieces_source`): tier 2
    of a scene with neighbour lists that the generic module can run. The generic time loops call
    them through ``calls`` as they call the generic pieces (:class:`demkit.engine.generic_modules.GenericKernels`),
    so tier 2 compiles the scene's pair and sphere loops alone: its time loops, list upkeep and sums
    are tier 1's, compiled once per install."""
    serial = build_pieces(plan, columns) if threads else None  # the serial chunks, imported by the thread pieces
    source, name = pieces_source(plan, columns, threads)
    if name not in _MODULES:
        module = _load_from_file(name, source)
        module.source, module.serial = source, serial or module
        _MODULES[name] = module
    return _MODULES[name]


def _load_from_file(name, source):
    folder = _cache_dir()
    try:
        folder.mkdir(parents=True, exist_ok=True)
        path = folder / f"{name}.py"
        if not path.exists() or path.read_text() != source:
            fd, tmp = tempfile.mkstemp(dir=folder, suffix=".tmp")
            with os.fdopen(fd, "w") as fh:
                fh.write(source)
            os.replace(tmp, path)
    except OSError:
        return _load_in_memory(name, source.replace("cache=True", "cache=False"), None)
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    spec.loader.exec_module(module)
    return module


def _load_in_memory(name, source, plan):
    """Compile without a file (pair functions defined in __main__ or notebooks): no disk cache."""
    import types
    module = types.ModuleType(name)
    if plan is not None:
        for prefix, members in (("", plan.interactions), ("s", plan.effects)):
            for k, inter in enumerate(members):
                force, energy = inter.pair_functions()
                setattr(module, f"{prefix}force_{k}", force)
                setattr(module, f"{prefix}energy_{k}", energy)
    module.DEMKIT_IN_MEMORY = True  # not cached: the compile notice says every run compiles
    exec(compile(source, f"<{name}>", "exec"), module.__dict__)
    return module
