"""Time series of frames in one folder, and reading them back.

Layout of a series called ``name`` (default ``particles``) in ``folder``::

    folder/name.pvd             collection: the simulation time of every frame (open this in ParaView)
                                and the box, when there is one (see demkit.io.pvd)
    folder/name_000000.vtu      one file per frame (binary; see demkit.io.frames)
    folder/name_trails.vtp      trajectories as polylines (see demkit.io.polylines)

demkit never silently replaces data: a folder that is not empty is refused unless
``overwrite=True``, which deletes that series' own files (the three patterns above) and leaves any
other file alone.
"""
from __future__ import annotations

import re
import tempfile
from pathlib import Path

import numpy as np

from .frames import CONSTANT_FIELDS, VECTOR_FIELDS, FrameWriter, read_frame
from .pvd import find_pvd, read_box, read_pvd, write_pvd

_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.-]*$")


class SeriesFolder:
    """The files of one series (see the module docstring); checks and claims the folder."""

    def __init__(self, folder, name="particles", overwrite=False, box=None, extension="vtu"):
        if not isinstance(name, str) or not _NAME.match(name):
            raise ValueError(f"series name must be letters, digits, '_', '.' or '-', got {name!r}")
        self.folder = Path(folder)
        self.name = name
        self.extension = extension
        if self.folder.exists() and not self.folder.is_dir():
            raise ValueError(f"output folder {self.folder} exists and is not a folder")
        try:
            self.folder.mkdir(parents=True, exist_ok=True)
            with tempfile.TemporaryFile(dir=self.folder):
                pass
        except OSError as err:
            raise ValueError(f"cannot write to output folder {self.folder}: {err}") from err
        present = sorted(p.name for p in self.folder.iterdir())
        if present and not overwrite:
            shown = ", ".join(present[:3]) + (", ..." if len(present) > 3 else "")
            raise ValueError(
                f"output folder {self.folder} is not empty ({len(present)} entries: {shown}); demkit does "
                f"not overwrite existing data: choose an empty or new folder, or pass overwrite=True to "
                f"replace the series {name!r} there (other files are left alone)")
        if overwrite:
            for path in self.own_files():
                path.unlink()
        self.entries = []
        self.box = box  # written into the .pvd with every frame

    @property
    def pvd(self):
        return self.folder / f"{self.name}.pvd"

    @property
    def trails(self):
        return self.folder / f"{self.name}_trails.vtp"

    def own_files(self):
        """Files of this series now in the folder."""
        frame = re.compile(rf"^{re.escape(self.name)}_\d+\.{self.extension}$")
        own = [p for p in self.folder.iterdir() if p.is_file() and frame.match(p.name)]
        return own + [p for p in (self.pvd, self.trails) if p.exists()]

    def check_unclaimed(self):
        """Raise ValueError if files of this series appeared since the folder was claimed."""
        if not self.entries and self.own_files():
            raise ValueError(f"another run has started writing series {self.name!r} in {self.folder}; "
                             f"refusing to overwrite it")

    def add_frame(self, time, write):
        """Call ``write(path)`` for the next frame file, then record it in the .pvd (rewritten)."""
        path = self.folder / f"{self.name}_{len(self.entries):06d}.{self.extension}"
        write(path)
        self.entries.append((float(time), path.name))
        write_pvd(self.pvd, self.entries, self.box)
        return path


class SeriesData:
    """Frames read back from a series, particles in increasing id order.

    time (T,); position (T,N,3); velocity, angular_velocity, dipole, force, torque (T,N,3) or
    None when the series lacks them; ids, radius, mass (N,); files: the .vtu paths; pvd: its path;
    image (T,N,3) int64 periodic image counts and box (a :class:`demkit.Box`), or None.
    """

    def __init__(self, time, position, fields, ids, radius, mass, files, pvd, image=None, box=None):
        self.time, self.position = time, position
        for name in VECTOR_FIELDS:
            setattr(self, name, fields.get(name))
        self.ids, self.radius, self.mass = ids, radius, mass
        self.files, self.pvd = files, pvd
        self.image, self.box = image, box

    def unwrapped(self):
        """Positions (T,N,3) continued across periodic boundaries: position + image * box size."""
        if self.image is None or self.box is None:
            return self.position
        return self.position + self.image * self.box.size

    def __len__(self):
        return len(self.time)

    def __repr__(self):
        have = [f for f in VECTOR_FIELDS if getattr(self, f) is not None]
        return (f"SeriesData({len(self)} frames, {len(self.ids)} particles, fields {have}, "
                f"from {self.pvd})")


def read_series(source, frames=None):
    """Read a written series (its .pvd, or the folder holding it) into a :class:`SeriesData`.

    frames : None (all), or an index, slice or sequence of frame indices to load.
    Raises ValueError if the series is missing, empty or its frames hold different particles.
    """
    pvd = find_pvd(source)
    entries = read_pvd(pvd)
    if frames is not None:
        index = np.arange(len(entries))[frames]
        entries = [entries[k] for k in np.atleast_1d(index)]
    if not entries:
        raise ValueError(f"series {pvd} has no frames")
    missing = [str(f) for _, f in entries if not f.exists()]
    if missing:
        raise ValueError(f"series {pvd} lists {len(missing)} missing frame file(s), e.g. {missing[0]}")
    positions, vectors, ids = [], {}, None
    for _, file in entries:
        pos, data = read_frame(file)
        absent = [k for k in CONSTANT_FIELDS if k not in data]
        if absent:
            raise ValueError(f"frame {file} has no {', '.join(absent)} point data: not a demkit frame")
        order = np.argsort(data["id"], kind="stable")
        if ids is None:
            ids = data["id"][order]
            constant = {k: data[k][order] for k in CONSTANT_FIELDS if k != "id"}
        elif not np.array_equal(data["id"][order], ids):
            raise ValueError(f"frame {file} holds other particles than the first frame")
        positions.append(pos[order])
        for name in VECTOR_FIELDS + ("image",):
            if name in data:
                vectors.setdefault(name, []).append(data[name][order])
    fields = {k: np.stack(v) for k, v in vectors.items() if len(v) == len(entries)}
    return SeriesData(np.array([t for t, _ in entries]), np.stack(positions), fields, ids,
                      constant["radius"], constant["mass"], [f for _, f in entries], pvd,
                      image=fields.get("image"), box=read_box(pvd))


def write_series(trajectory, folder, name="particles", compress=False, dtype="float64",
                 overwrite=False, trails=True):
    """Write a recorded :class:`demkit.Trajectory` as a series (one .vtu per frame + .pvd).

    Writes position, velocity and, when recorded, angular_velocity, dipole and the periodic image
    counts (a trajectory holds no forces), the box into the .pvd, plus the polyline trails file
    (unwrapped paths) when ``trails``. Returns the .pvd path.
    """
    from .polylines import write_polylines

    series = SeriesFolder(folder, name, overwrite, box=getattr(trajectory, "box", None))
    image = getattr(trajectory, "image", None)
    writer = FrameWriter(compress, dtype)
    constant = {"id": np.asarray(trajectory.ids, dtype=np.int64),
                "radius": trajectory.radius, "mass": trajectory.mass}
    for k, time in enumerate(trajectory.time):
        data = dict(constant)
        for field in VECTOR_FIELDS:
            value = getattr(trajectory, field, None)
            if value is not None:
                data[field] = value[k]
        if image is not None:
            data["image"] = np.asarray(image[k], dtype=np.int64)
        series.add_frame(time, lambda path: writer.write(path, trajectory.position[k], data))
    if trails:
        write_polylines(trajectory, series.trails, compress=bool(writer.compression))
    return series.pvd
