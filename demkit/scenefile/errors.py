"""What a scene file gets wrong: :class:`SceneFileError`, one message naming the file, line and key path."""
from __future__ import annotations

import re

from ..schema import dotted


#: scene files larger than this are refused before parsing (bytes)
MAX_FILE_BYTES = 64 * 2**20


class SceneFileError(ValueError):
    """A scene file that cannot be used: one message with the file, line and key path (several, one
    a line, when the file's keys hold several problems: ``errors`` lists them)."""

    def __init__(self, message, source=None, path=(), line=None):
        where = str(source) if source is not None else "<scene>"
        if line is not None:
            where += f":{line}"
        super().__init__(f"{where}: {dotted(path)}: {message}" if path else f"{where}: {message}")
        self.source, self.path, self.line = source, tuple(path), line
        self.errors = [self]

    @classmethod
    def several(cls, errors):
        """One error saying all of ``errors`` (SceneFileErrors), a line each, in the file's order."""
        errors = sorted(errors, key=lambda e: (e.line is None, e.line or 0))
        first = errors[0]
        combined = cls.__new__(cls)
        ValueError.__init__(combined, "\n".join(str(e) for e in errors))
        combined.source, combined.path, combined.line, combined.errors = first.source, first.path, first.line, errors
        return combined


class _At:
    """Turn a ValueError or TypeError of a constructor into a SceneFileError at ``path``; with
    ``keys`` (the table's keys), at the first of them the message names (as a whole word), in the
    table ``keyed`` (default: ``path``)."""

    def __init__(self, src, *path, keys=(), keyed=None):
        self.src, self.path, self.keys = src, path, keys
        self.keyed = path if keyed is None else keyed  # where the keys are (default: in ``path``)

    def __enter__(self):
        return self

    def __exit__(self, kind, err, tb):
        if kind is not None and issubclass(kind, (ValueError, TypeError, OverflowError, MemoryError)) \
                and not isinstance(err, SceneFileError):
            message = str(err)
            named = [(m.start(), key) for key in self.keys
                     for m in [re.search(rf"(?<![\w.]){re.escape(key)}(?!\w)", message)] if m]
            path = self.keyed + (min(named)[1],) if named else self.path
            raise self.src.error(path, message + self.src.units_note) from None
        return False
