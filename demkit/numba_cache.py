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
names (:func:`demkit.kernels._fingerprint`). Hashing the package at import costs ~5 ms.
"""
from __future__ import annotations

import hashlib
from pathlib import Path

PACKAGE = Path(__file__).resolve().parent


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
