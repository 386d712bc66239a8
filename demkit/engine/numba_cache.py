"""numba's disk cache of demkit's own compiled functions, kept fresh across all of demkit's files.

numba stamps a cached function with a hash of *its own* source file. A compiled function holds the
code of every function it calls, so a cached ``wall.py`` function kept the friction spring of the
``spring.py`` it was compiled with after ``spring.py`` changed (found when the spring's history grew
from 4 to 7 values: the cached wall law read the twist spring at the old offset). An upgrade that
leaves numba's files behind (pip does not list them) would run such stale code silently.

:func:`install` (called by ``import demkit``, before any of its functions is defined) puts locators
in front of numba's that serve demkit's modules only: the same cache folders as numba's, but a
stamp that adds a hash of every ``.py`` file of the package, so any change of demkit's source
recompiles its functions. The kernel modules demkit generates carry the same fingerprint in their
names (:func:`demkit.engine.modules._fingerprint`). Hashing the package at import costs ~5 ms.

One compile per machine, not per process (:func:`install_compile_lock`): processes started together
on empty caches (the workers of a sweep, of the test suite) all missed numba's cache for the same
functions and compiled each of them side by side. A miss of one of demkit's functions now takes a
file lock for that function and signature; a process that finds it taken waits, then loads what the
holder compiled and saved. The lock is released when the function is saved (or its compile fails),
and by the system when a process dies; a wait longer than :data:`LOCK_WAIT` seconds compiles anyway.
"""
from __future__ import annotations

import hashlib
import os
import time
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1]  # demkit/ (this file is in demkit/engine/)


def package_fingerprint():
    """sha256 of the package's .py files (paths and contents, in path order)."""
    h = hashlib.sha256()
    for path in sorted(PACKAGE.rglob("*.py")):
        h.update(str(path.relative_to(PACKAGE)).encode())
        h.update(path.read_bytes())
    return h.hexdigest()


FINGERPRINT = package_fingerprint()


def _ours(py_func):
    module = getattr(py_func, "__module__", "") or ""
    return module == "demkit" or module.startswith("demkit.")


def _locator(base):
    """A locator class: ``base``'s folder, the package's fingerprint added to the stamp, demkit only."""

    class Locator(base):
        def get_source_stamp(self):
            return (super().get_source_stamp(), FINGERPRINT)

        @classmethod
        def from_function(cls, py_func, py_file):
            if not _ours(py_func):
                return None
            return super().from_function(py_func, py_file)

    Locator.__name__ = Locator.__qualname__ = f"Demkit{base.__name__.lstrip('_')}"
    return Locator


def install():
    """Put demkit's locators in front of numba's (once)."""
    from numba.core import caching
    impl = getattr(caching, "CacheImpl", None) or getattr(caching, "_CacheImpl")
    if any(getattr(cls, "__name__", "").startswith("Demkit") for cls in impl._locator_classes):
        return
    bases = [getattr(caching, name, None) or getattr(caching, "_" + name) for name in
             ("UserProvidedCacheLocator", "InTreeCacheLocator", "UserWideCacheLocator")]
    impl._locator_classes = [_locator(base) for base in bases] + list(impl._locator_classes)
    install_compile_lock()
    preload_blas_table()


def preload_blas_table():
    """Load SciPy's BLAS table (``scipy.linalg.cython_blas``) alone, without ``scipy.linalg``.

    The first compile or cache load of a process makes numba import ``numba.np.arraymath``, whose
    check for BLAS imports ``scipy.linalg.cython_blas``, and with it the whole of ``scipy.linalg``:
    0.3-0.4 CPU s of the 1.5-2 s a new scene takes to its first step, for a table of function
    pointers that the extension module holds alone (0.03 s). Registered under its own name, the
    module is the one numba (and ``scipy.linalg``, if a program imports it later) finds. Nothing is
    done when ``scipy.linalg`` is imported already or the file is not where SciPy keeps it."""
    import importlib.machinery
    import importlib.util
    import sys
    name = "scipy.linalg.cython_blas"
    if name in sys.modules or "scipy.linalg" in sys.modules:
        return
    try:
        folder = Path(importlib.util.find_spec("scipy").submodule_search_locations[0]) / "linalg"
        found = sorted(folder.glob("cython_blas.*"))
        spec = importlib.util.spec_from_file_location(name, found[0]) if found else None
        if spec is None or not isinstance(spec.loader, importlib.machinery.ExtensionFileLoader):
            return
        module = importlib.util.module_from_spec(spec)
        sys.modules[name] = module
        spec.loader.exec_module(module)
    except Exception:  # an unusual SciPy: numba imports scipy.linalg as before
        sys.modules.pop(name, None)


LOCK_WAIT = 600.0  # seconds a process waits for another's compile of a function before compiling it itself
_HELD = {}  # (id of the function's cache, signature text) -> (open lock file, numba dispatcher's py_func)


def _demkit_function(py_func):
    """demkit's own functions (:func:`_ours`) and those of the modules it generates (``demkit_kernel_*``, ...)."""
    return _ours(py_func) or (getattr(py_func, "__module__", "") or "").startswith("demkit_")


def _lock_path(cache, sig):
    index = Path(cache._cache_file._index_path)
    return index.with_name(f"{index.name}.{hashlib.sha1(str(sig).encode()).hexdigest()[:16]}.lock")


def _acquire(path):
    """An open file holding an exclusive lock on ``path`` (waiting up to LOCK_WAIT s), or None."""
    import fcntl
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        handle = open(path, "a")
    except OSError:
        return None  # a read-only cache: nothing is saved either, so nothing to wait for
    deadline = time.monotonic() + LOCK_WAIT
    while True:
        try:
            fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
            return handle
        except BlockingIOError:
            if time.monotonic() > deadline:
                handle.close()
                return None
            time.sleep(0.02)
        except OSError:  # a file system without locks: compile as before
            handle.close()
            return None


def _release(key):
    held = _HELD.pop(key, None)
    if held is not None:
        held[0].close()  # closing the file releases its lock


def install_compile_lock():
    """Wrap numba's function cache so a miss of one of demkit's functions compiles once per machine."""
    from numba.core import caching, event
    cache_class = caching.FunctionCache
    if getattr(cache_class, "_demkit_locked", False):
        return
    load, save = cache_class.load_overload, cache_class.save_overload

    def load_overload(self, sig, target_context):
        found = load(self, sig, target_context)
        if found is not None or not _demkit_function(self._py_func) or os.name != "posix":
            return found
        key = (id(self), str(sig))
        if key in _HELD:  # (a second miss of the same signature in this process: already ours)
            return found
        handle = _acquire(_lock_path(self, sig))
        if handle is None:
            return found
        found = load(self, sig, target_context)  # the holder we waited for may have saved it
        if found is not None:
            handle.close()
            return found
        _HELD[key] = handle, self._py_func  # compiled now by this process: released when saved
        return None

    def save_overload(self, sig, data):
        try:
            save(self, sig, data)
        finally:
            _release((id(self), str(sig)))

    class _FailedCompiles(event.Listener):
        """A compile that raised saves nothing: release the locks it held."""

        def on_start(self, ev):
            pass

        def on_end(self, ev):
            failure = getattr(ev, "_exc_details", None)  # (numba's is_failed reads it the wrong way round)
            if failure is not None and failure[0] is not None:
                py_func = ev.data["dispatcher"].py_func
                for key in [k for k, (_, f) in _HELD.items() if f is py_func]:
                    _release(key)

    cache_class.load_overload, cache_class.save_overload = load_overload, save_overload
    cache_class._demkit_locked = True
    event.register("numba:compile", _FailedCompiles())
