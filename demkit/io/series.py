"""Time series of frames in one folder, and reading them back.

Layout of a series called ``name`` (default ``particles``) in ``folder``::

    folder/name.pvd             collection: the simulation time of every frame (open this in ParaView)
                                and the box, when there is one (see demkit.io.pvd)
    folder/name_000000.vtu      one file per frame (binary; see demkit.io.frames)
    folder/name_trails.vtp      trajectories as polylines (see demkit.io.polylines)

demkit never silently replaces data: a folder that is not empty is refused unless
``overwrite=True``, which deletes that series' own files (the three patterns above, and temporary
``.tmp`` files of an interrupted write) and leaves any other file alone, or ``resume=True``, which
lets a run resumed from a checkpoint continue the series (:meth:`SeriesFolder.take_over`).
"""
from __future__ import annotations

import os
import re
import tempfile
from pathlib import Path

import numpy as np

from .frames import CONSTANT_FIELDS, VECTOR_FIELDS, FrameWriter, read_frame
from .polylines import box_fields, write_vtp_lines
from .pvd import GrowingPvd, find_pvd, read_box, read_entries, read_pvd

#: relative tolerance on times when a series is continued from a time
TIME_TOLERANCE = 1e-12

_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.-]*$")


class SeriesFolder:
    """The files of one series (see the module docstring); checks and claims the folder.

    A frame is written to a temporary file (``<frame>.tmp``), renamed to its name, and only then
    added to the .pvd (see :class:`demkit.io.pvd.GrowingPvd`), so the .pvd never names a frame
    that is not complete. ``resume=True`` accepts a folder holding this series already, for
    :meth:`take_over`.
    """

    def __init__(self, folder, name="particles", overwrite=False, box=None, extension="vtu", resume=False):
        if not isinstance(name, str) or not _NAME.match(name):
            raise ValueError(f"series name must be letters, digits, '_', '.' or '-', got {name!r}")
        self.folder = Path(folder)
        self.name = name
        self.extension = extension
        self.resume = bool(resume)
        if self.folder.exists() and not self.folder.is_dir():
            raise ValueError(f"output folder {self.folder} exists and is not a folder")
        try:
            self.folder.mkdir(parents=True, exist_ok=True)
            with tempfile.TemporaryFile(dir=self.folder):
                pass
        except OSError as err:
            raise ValueError(f"cannot write to output folder {self.folder}: {err}") from err
        present = sorted(p.name for p in self.folder.iterdir())
        if present and not overwrite and not resume:
            shown = ", ".join(present[:3]) + (", ..." if len(present) > 3 else "")
            raise ValueError(
                f"output folder {self.folder} is not empty ({len(present)} entries: {shown}); demkit does "
                f"not overwrite existing data: choose an empty or new folder, pass overwrite=True to "
                f"replace the series {name!r} there (other files are left alone), or resume=True to "
                f"continue it in a run resumed from a checkpoint")
        if overwrite:
            for path in self.own_files():
                path.unlink()
        self.collection = GrowingPvd(self.pvd, box)
        self.next_index = 0  # number of the next frame file

    @property
    def pvd(self):
        return self.folder / f"{self.name}.pvd"

    @property
    def trails(self):
        return self.folder / f"{self.name}_trails.vtp"

    @property
    def entries(self):
        """[(time, file name)] of the frames in the .pvd."""
        return self.collection.entries

    @property
    def box(self):
        return self.collection.box

    @box.setter
    def box(self, box):
        self.collection.box = box  # written into the .pvd

    def frame_path(self, index):
        return self.folder / f"{self.name}_{index:06d}.{self.extension}"

    def _frame_files(self):
        """{path: frame number} of this series' frame files, temporary ones included."""
        frame = re.compile(rf"^{re.escape(self.name)}_(\d+)\.{self.extension}(\.tmp)*$")
        found = {}
        for p in self.folder.iterdir():
            match = frame.match(p.name)
            if match and p.is_file():
                found[p] = int(match.group(1))
        return found

    def own_files(self):
        """Files of this series now in the folder (temporary files of an interrupted write included)."""
        extra = [self.pvd, self.trails]
        extra += [p.with_name(p.name + ".tmp") for p in extra]
        return list(self._frame_files()) + [p for p in extra if p.exists()]

    def check_unclaimed(self):
        """Raise ValueError if files of this series are in the folder and no frame was written."""
        if not self.entries and self.own_files():
            if self.resume:
                raise ValueError(
                    f"folder {self.folder} holds series {self.name!r} already: a run resumed from a "
                    f"checkpoint continues it (VTKWriter.resume); a new run needs an empty folder or "
                    f"overwrite=True")
            raise ValueError(f"another run has started writing series {self.name!r} in {self.folder}; "
                             f"refusing to overwrite it")

    def add_frame(self, time, write):
        """Call ``write(path)`` to write the next frame file, then add it to the .pvd."""
        path = self.frame_path(self.next_index)
        tmp = path.with_name(path.name + ".tmp")
        write(tmp)
        os.replace(tmp, path)
        self.collection.append(time, path.name)
        self.next_index += 1
        return path

    def frames_until(self, time, missing_ok=False):
        """(kept, later): the frames [(time, file name)] of the series on disk at times <= ``time``
        (relative tolerance 1e-12) and the file names listed after it. Raises ValueError when there
        is no series (unless ``missing_ok``: then nothing is kept) or a kept frame is missing."""
        if not self.pvd.exists():
            if missing_ok:
                return [], []
            raise ValueError(
                f"no series {self.name!r} to resume in {self.folder} (no {self.pvd.name}); a run that "
                f"is not resumed from a checkpoint starts a new series with open()/begin()")
        entries, _ = read_entries(self.pvd, salvage=True)
        limit = time + TIME_TOLERANCE * abs(time)
        kept = [(t, name) for t, name in entries if t <= limit]
        later = [name for t, name in entries if t > limit]
        missing = [name for _, name in kept if not (self.folder / name).is_file()]
        if missing:
            raise ValueError(f"series {self.pvd} lists {len(missing)} missing frame file(s) before t = "
                             f"{time!r}, e.g. {missing[0]}: it cannot be continued")
        return kept, later

    def take_over(self, kept, later=()):
        """Continue the series with the frames ``kept`` (from :meth:`frames_until`): rewrite the
        .pvd atomically with them, then delete the frame files ``later``, the unlisted ones
        numbered after the last kept frame, temporary ones and the trails file; number new frames
        after the last kept one. (In this order a kill at any moment leaves a readable series.)"""
        names, later = {name for _, name in kept}, set(later)
        files = self._frame_files()
        last = max((n for p, n in files.items() if p.name in names), default=-1)
        self.collection.rewrite(kept)
        self.next_index = last + 1
        for path, number in files.items():
            if path.name not in names and (path.name in later or number > last or path.name.endswith(".tmp")):
                path.unlink()
        for path in (self.trails, self.trails.with_name(self.trails.name + ".tmp")):
            if path.exists():
                path.unlink()


class SeriesData:
    """Frames read back from a series, particles in increasing id order.

    time (T,); position (T,N,3); velocity, angular_velocity, dipole, force, torque (T,N,3) or
    None when the series lacks them; ids, radius, mass (N,); files: the .vtu paths; pvd: its path;
    image (T,N,3) int64 periodic image counts and box (a :class:`demkit.Box`), or None; walls: the
    walls' .vtp file of each frame (:mod:`demkit.io.walls`; None for a frame without), or None when the
    series has no walls series beside it.
    """

    def __init__(self, time, position, fields, ids, radius, mass, files, pvd, image=None, box=None, walls=None):
        self.time, self.position = time, position
        for name in VECTOR_FIELDS:
            setattr(self, name, fields.get(name))
        self.ids, self.radius, self.mass = ids, radius, mass
        self.files, self.pvd = files, pvd
        self.image, self.box = image, box
        self.walls = walls

    def unwrapped(self):
        """Positions (T,N,3) continued across periodic boundaries: position + image * box size (a
        deforming box's at each frame's time)."""
        if self.image is None or self.box is None:
            return self.position
        return self.position + self.image * self.box.size_at(np.asarray(self.time, dtype=np.float64)[:, None])

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
                      image=fields.get("image"), box=read_box(pvd), walls=wall_frames(pvd, [t for t, _ in entries]))


def wall_frames(pvd, times):
    """The walls' .vtp file at each of ``times`` from the series ``<name>_walls.pvd`` beside the series
    ``pvd`` (None where it has no frame at that time), or None when there is no such series."""
    walls = pvd.with_name(pvd.stem + "_walls.pvd")
    if not walls.exists():
        return None
    listed = read_pvd(walls)
    stamps = np.array([time for time, _ in listed])  # (in time order, as a series is written)
    found = []
    for t in times:
        k = int(np.searchsorted(stamps, t))
        match = [listed[j][1] for j in (k - 1, k) if 0 <= j < len(listed)
                 and abs(stamps[j] - t) <= TIME_TOLERANCE * max(1.0, abs(t)) and listed[j][1].exists()]
        found.append(match[0] if match else None)
    return found


def write_series(trajectory, folder, name="particles", compress=False, dtype="float64",
                 overwrite=False, trails=True):
    """Write a recorded :class:`demkit.Trajectory` as a series (one .vtu per frame + .pvd).

    Writes position, velocity and, when recorded, angular_velocity, dipole and the periodic image
    counts (a trajectory holds no forces), the box into the .pvd, plus the polyline trails file
    (unwrapped paths) when ``trails``. Returns the .pvd path. (``dk.write_series``,
    :func:`demkit.io.walls.write_series`, adds the walls the trajectory carries.)
    """
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


def write_polylines(source, path, compress=False):
    """Write the paths of all particles of ``source`` as poly-lines to ``path`` (.vtp).

    source : a :class:`demkit.Trajectory`, a :class:`demkit.io.SeriesData`, or a written series
        (its .pvd or folder; frames are read back and matched by particle id). With image counts
        and a box the paths are unwrapped (position + image * size, a deforming box's at each frame).
    Returns the path written.
    """
    if isinstance(source, (str, os.PathLike)):
        source = read_series(source)
    path = Path(path)
    if path.suffix != ".vtp":
        raise ValueError(f"polylines are written as VTK PolyData: the path must end in .vtp, got {path}")
    time = np.asarray(source.time, dtype=np.float64)
    position = np.asarray(source.position)
    image, box = getattr(source, "image", None), getattr(source, "box", None)
    if image is not None and box is not None:
        position = position + np.asarray(image) * box.size_at(time[:, None])
    if position.ndim != 3 or position.shape[0] != len(time) or position.shape[2] != 3:
        raise ValueError(f"position must have shape (T, N, 3) with T = {len(time)} frames, got {position.shape}")
    nframes, n = position.shape[:2]
    ids = np.asarray(source.ids, dtype=np.int64)
    points = position.transpose(1, 0, 2).reshape(-1, 3)  # particle-major: line k is particle k
    return write_vtp_lines(
        path, points, np.full(n, nframes),
        point_data={"time": np.tile(time, n), "id": np.repeat(ids, nframes)},
        cell_data={"id": ids, "radius": np.asarray(source.radius, dtype=np.float64)},
        compress=compress, field_data=box_fields(box))
