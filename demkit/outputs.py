"""Output files: checked writable before a run, written whole or not at all, rescued when they cannot be.

    check_writable(path, "trajectory")        # ValueError naming the path and the problem, before a run
    write_atomically(path, lambda tmp: ...)   # a temporary file in the same folder, synced, renamed over path
    saved = write_or_rescue(path, write, "trajectory")   # elsewhere (and says where) when path fails

A file written by :func:`write_atomically` is at every moment either the previous one or the new one
whole: the data go to ``<stem>.<random>.partial<suffix>`` in the same folder (the suffix kept, so
writers that choose a format by it work), are flushed and synced, and the temporary file is renamed
over ``path`` (and the folder synced); on any error or Ctrl-C the temporary file is removed.
"""
from __future__ import annotations

import os
import re
import sys
import tempfile
from pathlib import Path


def check_writable(path, what):
    """Raise ValueError unless a file can be written at ``path`` (a file name, not a folder): its
    folder is made when missing and a probe file is created in it and removed (this also catches
    read-only file systems, where permission bits say nothing for root). Returns ``path``."""
    path = Path(path)
    if path.is_dir():
        raise ValueError(f"cannot write the {what} {path}: it is a folder (name a file)")
    folder = path.parent if str(path.parent) else Path(".")
    blocked = next((p for p in [folder, *folder.parents] if p.exists() and not p.is_dir()), None)
    if blocked is not None:
        raise ValueError(f"cannot write the {what} {path}: {blocked} is a file, not a folder")
    try:
        folder.mkdir(parents=True, exist_ok=True)
        fd, probe = tempfile.mkstemp(dir=folder, prefix=f".{path.name}.", suffix=".probe")
        os.close(fd)
        os.unlink(probe)
    except OSError as err:
        raise ValueError(f"cannot write the {what} {path}: {err.strerror or err}") from None
    return path


def write_atomically(path, write):
    """Call ``write(tmp)`` to write a temporary file beside ``path``, then sync it and rename it to
    ``path``. Raises what ``write`` or the file system raises; ``path`` is then as it was and the
    temporary file removed. Returns ``path``."""
    path = Path(path)
    folder = path.parent if str(path.parent) else Path(".")
    fd, tmp = tempfile.mkstemp(dir=folder, prefix=path.stem + ".", suffix=".partial" + path.suffix)
    os.close(fd)
    try:
        write(tmp)
        with open(tmp, "rb+") as fh:
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        raise
    sync_folder(folder)
    return path


def remove_partials(path):
    """Remove the temporary files :func:`write_atomically` left beside ``path`` when a process was
    killed while writing it (``<stem>.<8 characters>.partial<suffix>``). Call only where no other
    process writes ``path``. Returns the paths removed."""
    path = Path(path)
    folder = path.parent if str(path.parent) else Path(".")
    pattern = re.compile(re.escape(path.stem) + r"\.[A-Za-z0-9_]{8}\.partial" + re.escape(path.suffix) + "$")
    removed = []
    try:
        for candidate in folder.iterdir():
            if pattern.match(candidate.name) and candidate.is_file():
                candidate.unlink()
                removed.append(candidate)
    except OSError:
        pass
    return removed


def sync_folder(folder):
    """fsync a folder so that a rename in it survives a power cut (best effort)."""
    try:
        fd = os.open(folder, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)
    except OSError:
        pass


def rescue_folders():
    """Where an output that cannot be written goes instead, in order: the temporary folder, the
    current folder, the home folder."""
    return [Path(tempfile.gettempdir()), Path.cwd(), Path.home()]


def write_or_rescue(path, write, what):
    """Write ``path`` atomically with ``write(tmp)``; when that fails (a full disk, a folder gone
    read-only), write it under a new name in the first of :func:`rescue_folders` that takes it and
    say so on stderr. Returns the path written. Raises OSError (naming every place tried) only when
    nowhere takes it."""
    path = Path(path)
    try:
        return write_atomically(path, write)
    except OSError as first:
        tried = [f"{path} ({first.strerror or first})"]
    for folder in rescue_folders():
        name = None
        try:
            fd, name = tempfile.mkstemp(dir=folder, prefix=f"demkit-rescued-{path.stem}-", suffix=path.suffix)
            os.close(fd)
            write_atomically(name, write)
        except OSError as err:
            tried.append(f"{folder} ({err.strerror or err})")
            if name is not None:
                Path(name).unlink(missing_ok=True)
            continue
        print(f"demkit: could not write the {what} {tried[0]}; saved it instead in {name}", file=sys.stderr)
        return Path(name)
    raise OSError(f"could not write the {what} anywhere: tried {'; '.join(tried)}")
