"""A loaded scene file, run: :class:`LoadedScene` (its scene, integrator, run and outputs), and the
trajectory files it keeps and resumes from."""
from __future__ import annotations

import sys
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .errors import _At


@dataclass
class LoadedScene:
    """A validated scene file, built: ``scene`` (a fresh dk.Scene), ``integrator``, ``duration``,
    ``record_every``, ``outputs`` (the validated [outputs] table), ``path`` (the file or None),
    ``data`` (the whole validated file as plain values, defaults filled in, in the units simulated)
    and ``units`` (dk.units.PaperUnits for units = "si", else None)."""

    #: set by :meth:`run`: the checkpoint held the run's end already (nothing ran)
    complete = False

    scene: object
    integrator: object
    duration: float
    record_every: float | None
    outputs: dict
    path: Path | None
    data: dict
    units: object = None
    max_energy_growth: float | None = None
    #: with dt = "auto": how the step was chosen (dk.step_choice.StepChoice), else None
    step_choice: object = None
    #: run.stress_every: the stress is measured during the run into :attr:`stress_series`
    stress_every: float | None = None
    #: the dk.StressSeries of the last simulation made (with run.stress_every), else None
    stress_series: object = None
    base: Path = Path(".")
    source: object = None
    #: outputs that could not be written where asked and were saved elsewhere: {name: path}
    rescued: dict = field(default_factory=dict)

    def output_path(self, name, out_dir=None):
        """Where an output path of the file goes: as written when absolute, else in ``out_dir`` or
        the scene file's folder."""
        p = Path(name)
        if p.is_absolute():
            return p
        return (Path(out_dir) if out_dir is not None else self.base) / p

    def check_outputs(self, out_dir=None):
        """Raise SceneFileError (naming the key, the path and the problem) unless every output file
        of ``[outputs]`` can be written: found before the first step, not after the run. The VTK
        series folder is checked by its writer."""
        from ..outputs import check_writable
        out = self.outputs
        for key, name, what in (("trajectory", out.get("trajectory"), "trajectory"),
                                ("animation", (out.get("animation") or {}).get("path"), "animation"),
                                ("stress", out.get("stress"), "stress series"),
                                ("checkpoint", (out.get("checkpoint") or {}).get("path"), "checkpoint")):
            if name:
                with _At(self.source, "outputs", key):
                    check_writable(self.output_path(name, out_dir), what)

    def simulation(self, out_dir=None):
        """A dk.Simulation of the scene with the file's writers and checkpoint; when the checkpoint
        file exists the simulation is resumed from it (and the VTK series continued)."""
        from ..checkpoint import Checkpoint
        from ..io import VTKWriter
        from ..simulation import Simulation
        out = self.outputs
        self.check_outputs(out_dir)
        checkpoint = None
        resume = False
        if out.get("checkpoint") is not None:
            c = out["checkpoint"]
            target = self.output_path(c["path"], out_dir)
            target.parent.mkdir(parents=True, exist_ok=True)
            with _At(self.source, "outputs", "checkpoint"):
                checkpoint = Checkpoint(target, every=c["every"], seconds=c["seconds"])
            resume = checkpoint.exists()
        writers = []
        if out.get("vtk") is not None:
            v = out["vtk"]
            with _At(self.source, "outputs", "vtk"):
                writers.append(VTKWriter(self.output_path(v["folder"], out_dir), every=v["every"], compress=v["compress"],
                                         trails=v["trails"], contacts=v["contacts"], measures=v["measures"],
                                         overwrite=not resume, resume=resume))
        if self.stress_every is not None:
            from ..stress_series import StressSeries
            path = self.output_path(out["stress"], out_dir) if out.get("stress") else None
            with _At(self.source, "run", "stress_every"):
                self.stress_series = StressSeries(self.stress_every, path=path, overwrite=not resume, resume=resume)
            writers.append(self.stress_series)
        with _At(self.source, "run"):
            sim = Simulation(self.scene, self.integrator, writers=writers, checkpoint=checkpoint,
                             max_energy_growth=self.max_energy_growth)
        if resume:
            with _At(self.source, "outputs", "checkpoint"):
                sim.resume()
        return sim

    def run(self, progress=None, out_dir=None, on_resume=None):
        """Run to ``duration`` (from a checkpoint when there is one) and write every output the file
        asks for. ``progress``: as for Simulation.run (None: a bar on a terminal for runs longer than
        a moment).

        Every output path is checked writable before the first step (SceneFileError otherwise).
        Frames are taken on the grid of the whole run (steps 0, s, 2s, ... with s = record_every /
        dt, and the last step), also when resuming. The trajectory file is written atomically at
        the end, on Ctrl-C, when the run stops, and, with a checkpoint, just before every
        checkpoint (the frames recorded so far): a run killed at any moment leaves a file that
        holds at least every frame on the grid up to its checkpoint, and the checkpoint a digest of
        them. A resumed run's file holds the whole run: the earlier frames are taken from the file
        when they are the ones the checkpoint's run recorded (checked by that digest, or, for a
        checkpoint without one, against the checkpoint's state in the file's folded convention);
        otherwise the old file is renamed ``<name>.set-aside.npz`` (never overwritten), the new
        one holds the frames from the resume on, and a line says why. When the file cannot be
        written at the end (a full disk), it is saved elsewhere
        (:func:`demkit.outputs.write_or_rescue`) and a line says where. ``on_resume(path)`` is
        called once the checkpoint has been checked and loaded (not when it holds the run's end:
        then nothing runs, ``self.complete`` is True and the files are left as they are). Returns the
        Trajectory written (the whole run), or without a trajectory file the frames of this call
        (from where it started)."""
        from ..simulation import SimulationError
        sim = self.simulation(out_dir)
        dt = self.integrator.dt
        end = round(self.duration / dt)
        start = sim.step
        #: the checkpoint already held the end of the run: nothing ran, the outputs are as they were (but
        #: an animation whose making was interrupted: made now, ``self.made``)
        self.complete = start >= end
        self.made = None
        if getattr(sim, "resumed_meta", None) is not None and on_resume is not None and not self.complete:
            on_resume(sim.checkpoint.path)
        with _At(self.source, "run", "record_every"):
            stride = end if self.record_every is None else sim._steps(self.record_every, "record_every")
        target = self.output_path(self.outputs["trajectory"], out_dir) if self.outputs.get("trajectory") else None
        if target is not None:
            from ..outputs import remove_partials
            remove_partials(target)  # left by a process killed while writing the file
        earlier = self._earlier_frames(target, sim, stride) if start > 0 and target is not None else None
        if start >= end:  # a finished run's checkpoint: nothing left to do but an animation it did not finish
            sim.close()
            animation = self.outputs.get("animation")
            pvd = self.output_path(self.outputs["vtk"]["folder"], out_dir) / "particles.pvd" if animation else None
            if animation and not self.output_path(animation["path"], out_dir).exists() and pvd.exists():
                self.made = self._animate(pvd, out_dir)
            return earlier if earlier is not None else sim.trajectory
        grid = -(-start // stride) * stride  # the first step of the grid at or after the start
        plan = [] if grid in (start, end) or grid > end else [(grid * dt, None)]
        plan.append((self.duration, self.record_every if grid < end else None))
        parts = []
        written = {"step": None}  # the step the trajectory file was last written at
        if target is not None and sim.checkpoint is not None:
            def before_checkpoint(s):
                so_far = _join(earlier, parts + _current(s), start, stride, end, dt)
                steps = np.rint(so_far.time / dt).astype(np.int64)
                if len(steps) > 1 and steps[-1] <= steps[-2]:  # mid-run: the last frame kept twice
                    so_far = _frames(so_far, np.arange(len(steps) - 1))
                save_trajectory(so_far, target)
                written["step"] = s.step if round(so_far.time[-1] / dt) == s.step else None  # all of it?
                kept = _kept(np.rint(so_far.time / dt).astype(np.int64), stride, s.step)
                return {"trajectory": {"sha256": frames_digest(so_far, kept), "frames": int(kept.sum())}}
            sim.checkpoint.before_save = before_checkpoint
        told = sim.notes
        try:
            for k, (until, every) in enumerate(plan):
                before = sim.trajectory
                sim.notes = told and k == len(plan) - 1  # one set of notes, at the end, for the whole run
                try:
                    parts.append(sim.run(until=until, record_every=every, progress=progress))
                except (KeyboardInterrupt, SimulationError):
                    if sim.trajectory is not before and sim.trajectory is not None:
                        parts.append(sim.trajectory)  # the frames of the run that stopped (last: where)
                    raise
                if k < len(plan) - 1:
                    sim.continue_notes()
        finally:
            sim.notes = told
            if sim.checkpoint is not None:
                sim.checkpoint.before_save = None
            sim.close()
            if parts:
                trajectory = _join(earlier, parts, start, stride, end, dt)
                if target is not None and written["step"] != sim.step:
                    from ..outputs import write_or_rescue
                    target.parent.mkdir(parents=True, exist_ok=True)
                    where = write_or_rescue(target, lambda tmp: _savez(trajectory, tmp), "trajectory")
                    if where != target:
                        self.rescued["trajectory"] = where
        self.write_outputs(None, out_dir, sim)
        return trajectory

    def _earlier_frames(self, target, sim, stride):
        """The frames of the earlier runs on the grid up to the resume step, from the trajectory file,
        or None (with a line saying why) when it does not hold them all or ends elsewhere."""
        dt, start = self.integrator.dt, sim.step
        recorded = (getattr(sim, "resumed_meta", None) or {}).get("trajectory")  # digest of its frames
        why = None
        try:
            saved = load_trajectory(target) if target.is_file() else None
        except ValueError as err:
            saved, why = None, f"it cannot be read ({err})"
        if saved is None:
            why = why or "there is none"
        else:
            steps = np.rint(saved.time / dt).astype(np.int64)
            keep = _kept(steps, stride, start)
            first = int(steps[0]) if len(steps) else 0
            grid = np.union1d([first], np.arange(-(-first // stride) * stride, start + 1, stride))
            p = self.scene.particles
            if len(saved.ids) != len(p) or not np.array_equal(saved.ids, p.ids):
                why = "it holds other spheres"
            elif not np.array_equal(steps[keep], grid[grid <= start]):
                why = (f"it ends at t = {steps.max() * dt:.6g}, before the checkpoint's t = {start * dt:.6g} (the "
                       f"earlier run was stopped before writing the frames in between)"
                       if len(steps) and steps.max() < grid[grid <= start].max() else
                       "its frames are not on this run's record_every grid")
            elif recorded is not None and frames_digest(saved, keep) != recorded.get("sha256"):
                why = ("its frames up to the checkpoint are not those the checkpoint's run recorded (another run "
                       "wrote it)")
            elif recorded is None and not _holds_state(saved, steps == start, _state_frame(sim)):
                why = (f"its frame at t = {start * dt:.6g} is not the checkpoint's state (another run wrote it)"
                       if (steps == start).any() else f"it has no frame at the checkpoint's t = {start * dt:.6g}")
            else:
                return _frames(saved, keep)
        aside = ""
        if target.is_file():  # not overwritten: what another run wrote may be all there is of it
            k, kept = 1, target.with_name(f"{target.stem}.set-aside{target.suffix}")
            while kept.exists():
                k += 1
                kept = target.with_name(f"{target.stem}.set-aside-{k}{target.suffix}")
            try:
                target.rename(kept)
                aside = f" (the file is kept as {kept})"
            except OSError as err:
                aside = f" (it could not be set aside: {err.strerror or err}; it will be replaced)"
        print(f"{target}: frames before t = {start * dt:.6g} (the resume) are not kept: {why}{aside}; the file will "
              f"hold t = {start * dt:.6g} .. {self.duration:g}", file=sys.stderr)
        return None

    def write_outputs(self, trajectory, out_dir=None, sim=None):
        """Write the trajectory file (unless ``trajectory`` is None) and the animation (the VTK
        series and checkpoints are written while running). Returns the paths written."""
        out, written = self.outputs, []
        if out.get("trajectory") and trajectory is not None:
            from ..outputs import write_or_rescue
            target = self.output_path(out["trajectory"], out_dir)
            target.parent.mkdir(parents=True, exist_ok=True)
            written.append(write_or_rescue(target, lambda tmp: _savez(trajectory, tmp), "trajectory"))
        if out.get("animation") is not None:
            made = self._animate(sim.writers[0].pvd, out_dir)
            written += [made] if made is not None else []
        return written

    def _animate(self, pvd, out_dir):
        """The animation [outputs.animation] asks for, made from the VTK series ``pvd``: its path, or None
        (rendering unavailable: said)."""
        from .. import viz
        a = self.outputs["animation"]
        target = self.output_path(a["path"], out_dir)
        target.parent.mkdir(parents=True, exist_ok=True)
        options = {"color_by": a["color_by"]} if a["color_by"] else {}
        if a["trail"] is not None:
            options["trail"] = a["trail"]
        try:
            viz.animate(pvd, target, max_frames=a["max_frames"], fps=a["fps"], **options)
            return target
        except viz.RenderingUnavailable as err:
            print(f"no animation: {err}")
            return None


def _kept(steps, stride, upto):
    """Mask of the frames (at ``steps``) of a trajectory file that a resume at step ``upto`` keeps:
    those on the record grid up to it, and the first (a file may start at an earlier resume)."""
    keep = (steps <= upto) & (steps % stride == 0)
    if len(steps):
        keep[0] = steps[0] <= upto
    return keep


def _current(sim):
    """[the frames of ``sim``'s run in progress]: the part of a run not yet returned by
    Simulation.run. At its end or on Ctrl-C the run has recorded the state it stopped at
    (``sim.trajectory``); in the middle, only the frames on its record grid so far are taken (the
    kernels are not asked to record the state now: that would maintain the neighbour lists at a
    moment an uninterrupted run does not, and change its last bits)."""
    record, first, local = sim._recording
    dt = sim.integrator.dt
    t = sim.trajectory
    if t is not None and len(t.time) and round(t.time[0] / dt) == first and round(t.time[-1] / dt) == sim.step:
        return [t]
    n = (sim.step - first) // local + 1
    return [sim._trajectory(record, (first + np.arange(n) * local) * dt)]


def _state_frame(sim):
    """The state of ``sim`` now as a one-frame Trajectory, recorded by the kernels as a run records
    its frames (periodic coordinates folded into the box, image counts moved along). Only where the
    next run records this state anyway (right after a resume)."""
    record = sim._allocate(1)
    sim.scene.kernels.record_frame(0, sim.scene.state, record)
    return sim._trajectory(record, np.array([sim.time]))


def _holds_state(saved, at, state):
    """Does the trajectory ``saved`` hold ``state`` (one frame) at its last frame where ``at``?"""
    at = np.flatnonzero(at)
    if not len(at):
        return False
    k = at[-1]
    same = [np.array_equal(saved.position[k], state.position[0]), np.array_equal(saved.velocity[k], state.velocity[0])]
    if saved.image is not None and state.image is not None:
        same.append(np.array_equal(saved.image[k], state.image[0]))
    return all(same)


def frames_digest(trajectory, keep):
    """sha256 (hex) of the frames ``keep`` (mask or indices) of a Trajectory: every per-frame array
    and energy, bit for bit."""
    import hashlib
    t = _frames(trajectory, keep)
    h = hashlib.sha256(str(len(t.time)).encode())
    fields = [(name, getattr(t, name)) for name in ("position", "velocity", "angular_velocity", "dipole", "image",
                                                   "angular_momentum")]
    fields += [(f"energy_{k}", t.energy[k]) for k in sorted(t.energy)]
    for name, a in fields:
        if a is not None:
            a = np.ascontiguousarray(a)
            h.update(f"{name}:{a.dtype}:{a.shape}".encode())
            h.update(a.tobytes())
    return h.hexdigest()


def _frames(trajectory, keep):
    """The frames ``keep`` (a mask or indices) of a Trajectory, as a new Trajectory."""
    from ..trajectory import Trajectory
    t = trajectory

    def pick(a):
        return None if a is None else np.asarray(a)[keep]
    return Trajectory(time=pick(t.time), position=pick(t.position), velocity=pick(t.velocity),
                      angular_velocity=pick(t.angular_velocity), dipole=pick(t.dipole),
                      energy={k: pick(v) for k, v in t.energy.items()}, angular_momentum=pick(t.angular_momentum),
                      radius=t.radius, mass=t.mass, inertia=t.inertia, ids=t.ids, image=pick(t.image), box=t.box)


def _join(earlier, parts, start, stride, end, dt):
    """One Trajectory on the whole run's grid (steps that are multiples of ``stride``, and ``end``):
    ``earlier`` (its frames up to step ``start``, or None) followed by the frames of the
    consecutive runs ``parts`` (from ``start`` on) after ``start`` on the grid. Kept besides: the
    last frame of the last part (where a stopped run stopped) and, without ``earlier``, the first
    (the file then starts at the resume)."""
    from ..trajectory import Trajectory
    pieces = [] if earlier is None else [earlier]
    for k, part in enumerate(parts):
        steps = np.rint(part.time / dt).astype(np.int64)
        keep = ((steps % stride == 0) | (steps == end)) & (steps > start)
        keep[0] = earlier is None and k == 0  # later parts start where the one before ended
        keep[-1] |= k == len(parts) - 1
        pieces.append(_frames(part, keep))
    first = pieces[0]

    def joined(name, get=getattr):
        arrays = [get(p, name) for p in pieces]
        return None if arrays[0] is None else np.concatenate(arrays)
    energy = {key: joined(key, lambda p, k: np.asarray(p.energy[k])) for key in first.energy}
    return Trajectory(energy=energy, radius=first.radius, mass=first.mass, inertia=first.inertia, ids=first.ids,
                      box=first.box, **{name: joined(name) for name in ("time", "position", "velocity",
                                                                        "angular_velocity", "dipole",
                                                                        "angular_momentum", "image")})


def load_trajectory(path):
    """A Trajectory from a .npz written by :func:`save_trajectory` (read without pickle). Raises
    ValueError for a file that is not one."""
    from ..box import Box, Deform, Shear
    from ..trajectory import Trajectory
    try:
        with np.load(path, allow_pickle=False) as z:
            a = {name: z[name] for name in z.files}
    except Exception as err:  # zip or npy damage: one message
        raise ValueError(f"cannot read {path} as .npz: {err}") from None
    need = ("time", "position", "velocity", "angular_momentum", "radius", "mass", "inertia", "ids")
    missing = [name for name in need if name not in a]
    if missing:
        raise ValueError(f"{path} is not a demkit trajectory (no {', '.join(missing)})")
    shear = None
    if "box_shear_rate" in a:  # a sheared box: its rate and axes (flow, gradient)
        shear = Shear(float(a["box_shear_rate"]), *("xyz"[int(k)] for k in a["box_shear_axes"]))
    deform = Deform.recorded(a["box_deform_rates"], a["box_deform_history"]) if "box_deform_rates" in a else None
    box = Box(a["box_size"], a["box_periodic"], shear=shear, deform=deform) if "box_size" in a else None
    return Trajectory(time=a["time"], position=a["position"], velocity=a["velocity"],
                      angular_velocity=a.get("angular_velocity"), dipole=a.get("dipole"),
                      energy={k[len("energy_"):]: v for k, v in a.items() if k.startswith("energy_")},
                      angular_momentum=a["angular_momentum"], radius=a["radius"], mass=a["mass"],
                      inertia=a["inertia"], ids=a["ids"], image=a.get("image"), box=box)


def save_trajectory(trajectory, path):
    """Write a Trajectory's arrays to a .npz (no pickle): time, position, velocity, angular_velocity,
    dipole, image (when present), angular_momentum, radius, mass, inertia, ids and energy_<kind>.
    Written atomically (:func:`demkit.outputs.write_atomically`): ``path`` holds the previous file
    or the new one whole, never a part. Raises OSError when it cannot be written."""
    from ..outputs import write_atomically
    return write_atomically(path, lambda tmp: _savez(trajectory, tmp))


def _savez(trajectory, path):
    arrays = {name: getattr(trajectory, name) for name in ("time", "position", "velocity", "angular_velocity",
                                                           "dipole", "image", "angular_momentum", "radius", "mass",
                                                           "inertia", "ids")}
    arrays.update({f"energy_{k}": v for k, v in trajectory.energy.items()})
    if trajectory.box is not None:
        arrays["box_size"], arrays["box_periodic"] = trajectory.box.size, trajectory.box.periodic
        if getattr(trajectory.box, "shear", None) is not None:
            arrays["box_shear_rate"] = np.array(trajectory.box.shear.rate)
            arrays["box_shear_axes"] = np.array(trajectory.box.shear.axes)
        if getattr(trajectory.box, "deform", None) is not None:
            arrays["box_deform_rates"] = np.array(trajectory.box.deform.rates)
            arrays["box_deform_history"] = np.array(trajectory.box.deform.history)  # (a servo's changes)
    with open(path, "wb") as fh:
        np.savez(fh, **{k: v for k, v in arrays.items() if v is not None})
    return path
