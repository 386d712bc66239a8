"""The entry points: :func:`load_scene` (a file) and :func:`parse_scene` (a text)."""
from __future__ import annotations

import tomllib
from pathlib import Path

from ..schema import SchemaError, SchemaErrors, validate
from .building import _build
from .errors import MAX_FILE_BYTES, SceneFileError
from .format import SCHEMA
from .reading import _Source, _check_prefactors, _check_rules, apply_overrides


def load_scene(path, overrides=None):
    """Read, validate and build the scene file ``path``: a :class:`LoadedScene`.

    overrides : {dotted key path: value}, set in the file's data before validation, e.g.
        ``{"interactions.dipole.prefactor": 0.5, "particles.build.b_over_R": 3.0}``; a key the format
        does not know is an error like an unknown key in the file.
    Raises :class:`SceneFileError` (a ValueError) for anything wrong, with file, line and key path.
    """
    path = Path(path)
    try:
        size = path.stat().st_size
        if not path.is_file():
            raise SceneFileError("is not a file", path)
        if size > MAX_FILE_BYTES:
            raise SceneFileError(f"is {size / 2**20:.0f} MB: scene files are at most {MAX_FILE_BYTES // 2**20} MB "
                                 f"(put large particle sets in a .npz file: particles.file)", path)
        raw = path.read_bytes()
    except OSError as err:
        raise SceneFileError(f"cannot be read: {err.strerror or err}", path) from None
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as err:
        line = raw[:err.start].count(b"\n") + 1
        raise SceneFileError(f"is not UTF-8 text (byte {err.start}: {raw[err.start:err.start + 1]!r})",
                             path, line=line) from None
    return parse_scene(text, source=path, overrides=overrides)


def parse_scene(text, source="<string>", overrides=None):
    """Like :func:`load_scene` for the TOML ``text``; relative paths are taken from the folder of
    ``source`` (the current folder for "<string>")."""
    name = source
    base = Path(".") if str(source) == "<string>" else Path(source).resolve().parent
    src = _Source(text, name, overrides)
    try:
        raw = tomllib.loads(text)
    except tomllib.TOMLDecodeError as err:
        message = str(err)
        line = getattr(err, "lineno", None)
        if line is None and "(at line " in message:
            try:
                line = int(message.rsplit("(at line ", 1)[1].split(",")[0])
            except ValueError:
                line = None
        raise SceneFileError(f"not valid TOML: {message.split(' (at ')[0]}", name, line=line) from None
    except RecursionError:
        raise SceneFileError("not readable: arrays or tables nested too deeply", name) from None
    try:
        raw = apply_overrides(raw, overrides, name)
        data = validate(SCHEMA, raw)
        _check_rules(data)
        _check_prefactors(raw, data)
    except SchemaErrors as err:  # every problem of the keys, found in one pass
        raise SceneFileError.several([src.error(e.path, e.problem) for e in err.errors]) from None
    except SchemaError as err:
        raise src.error(err.path, err.problem) from None
    except RecursionError:
        raise SceneFileError("nested too deeply", name) from None
    return _build(data, src, base)
