"""Checkpoints: the whole state of a run in one plain ``.npz`` file, for an exact restart.

A checkpoint holds every array the compiled time loop reads or carries from one step to the next,
in the kernels' own (possibly re-sorted) order: positions, velocities, spins, dipoles, periodic
image counts, forces and torques of the last evaluation, the integrator's working arrays
(``s.stage``), dissipated work, per-contact and per-sphere history, every neighbour list as it is
(entries, history rows, thread bounds) with its reference positions, the list and sort counters,
and the step count. demkit's stepping draws no random numbers (builders take their own seeds), so
there is no random state to keep. Resuming from it (:meth:`demkit.Simulation.resume`) continues
bit for bit as if the run had never stopped, any number of times.

The file is written atomically (temporary file in the same folder, flush, fsync, rename, fsync of
the folder): at every moment the path holds either the previous checkpoint or the new one, never a
mixture. It is a zip of ``.npy`` arrays with no pickled object (metadata is JSON text stored as
bytes) and is read with ``allow_pickle=False``, so loading one executes nothing.

A checkpoint names the demkit version and a hash of the scene's constant parameters (interactions
and their parameters, radii, masses, inertias, ids, fixed spheres, box, skin, sorting, thread
chunks, integrator); resuming into another scene or with another version is refused before
anything is changed, naming the parameter that differs (it also keeps those parameters in its
metadata: interactions, box, skin, ...; radii, masses and inertias are in its arrays).
"""
from __future__ import annotations

import hashlib
import json
import os
import tempfile
import time
import zipfile
from pathlib import Path

import numpy as np

from . import checks
from . import version
from .outputs import check_writable, sync_folder
from .engine.deform import DEFORM_VALUES, DF_BUILT, DF_START
from .engine.shear import SH_BUILT
from .engine.state import PAIR_LIST_FIELDS
from .interactions.wall_motion import S_FORCE, SERVO_STATE

#: bumped whenever the layout of the file changes
FORMAT = 1
#: state arrays saved by name (kernel order); thread buffers and scratch are not state
SAVED_ARRAYS = ("position", "velocity", "angular_velocity", "dipole", "radius", "mass", "inertia", "tag",
                "image", "force", "torque", "accum", "reference", "counters", "sphere_history", "stage")


class Checkpoint:
    """Where and how often a :class:`demkit.Simulation` saves its state.

    Parameters
    ----------
    path : the checkpoint file (``.npz``; replaced atomically at every save).
    every : simulation time between saves (rounded to whole steps), or None.
    seconds : wall-clock seconds between saves, or None. The state is also saved at the end of
        every run and when a run is interrupted (Ctrl-C); never after a run failed.
    """

    def __init__(self, path, every=None, seconds=None):
        self.path = Path(path)
        self.every = _interval("every", every)
        self.seconds = _interval("seconds", seconds)
        if self.path.exists() and self.path.is_dir():
            raise ValueError(f"checkpoint path {self.path} is a folder: name a file")
        folder = self.path.parent if str(self.path.parent) else Path(".")
        if not folder.is_dir():
            raise ValueError(f"the folder of the checkpoint {self.path} does not exist")
        check_writable(self.path, "checkpoint")  # found now, not at the first save
        self.saves = 0
        #: None, or a callable(simulation) -> dict called before every save (its dict goes into the
        #: metadata): demkit run writes the trajectory so far there, before the checkpoint
        self.before_save = None
        self.last_save = None  # wall-clock time of the last save
        self.saved_step = None  # step count of the last save

    def exists(self):
        """Is there a checkpoint file to resume from?"""
        return self.path.is_file()

    def due(self, now):
        """Has the wall-clock interval passed since the last save (or since ``start``)?"""
        return self.seconds is not None and self.last_save is not None and now - self.last_save >= self.seconds

    def save(self, simulation):
        """Write ``simulation``'s state now (atomically). Returns the path."""
        extra = self.before_save(simulation) if self.before_save is not None else None
        save(simulation, self.path, extra)
        self.saves += 1
        self.saved_step = simulation.step
        self.last_save = time.perf_counter()
        return self.path

    def __repr__(self):
        return f"Checkpoint({str(self.path)!r}, every={self.every!r}, seconds={self.seconds!r})"


def _interval(name, value):
    return None if value is None else checks.positive(f"Checkpoint {name}", value)


# ---- what identifies a scene --------------------------------------------------------------------
def scene_hash(scene, integrator):
    """sha256 of everything constant that the stepping depends on (not the state)."""
    from .interactions import induction
    h = hashlib.sha256()
    p = scene.particles

    def add(label, value):
        h.update(label.encode())
        if isinstance(value, np.ndarray):
            h.update(str(value.dtype).encode() + str(value.shape).encode())
            h.update(memoryview(np.ascontiguousarray(value)).cast("B"))
        else:
            h.update(repr(value).encode())

    add("n", len(p))
    for inter in scene.interactions + scene.effects:
        add("interaction", type(inter).__module__ + "." + type(inter).__qualname__)
    params = scene.params.copy()
    params[scene.time_step_slots] = 0.0  # set by each run from the integrator
    if scene.induction_slot is not None:  # the induced-moment solver's key (a number of this process), its counts
        params[scene.induction_slot:scene.induction_slot + induction.STATISTICS] = 0.0
    # servo-controlled walls: their target, speed limit, gain and target points (set by each run from the
    # servo, which may change between runs: a stress's target is not in a new scene's block until its
    # first run), their state (saved with the state) and time step
    for e, state in scene.servo_slots():  # (from the target to the end of the block: the points)
        params[state.start - (SERVO_STATE - S_FORCE):scene.geometry_slots[e] + np.size(scene.effects[e].block)] = 0.0
    if getattr(scene, "shear_slot", None) is not None:  # the offset the lists were built at: state, saved with it
        params[scene.shear_slot + SH_BUILT] = 0.0
    if getattr(scene, "deform_slot", None) is not None:  # ... and the box lengths they were built in
        params[scene.deform_slot + DF_BUILT:scene.deform_slot + DF_BUILT + 3] = 0.0
        if scene.box.deform.servo is not None:  # (a servo's rates, and the lengths and time they started from)
            params[scene.deform_slot:scene.deform_slot + DF_BUILT] = params[scene.deform_slot + DF_START] = 0.0
    add("params", params)
    for name in ("radius", "mass", "inertia", "ids"):
        add(name, np.asarray(getattr(p, name)))
    add("fixed", np.asarray(p.fixed) if p.fixed is not None else None)
    add("box", (scene.box.size.tolist(), list(scene.box.periodic)) if scene.box is not None else None)
    if scene.box is not None and scene.box.shear is not None:
        add("shear", repr(scene.box.shear))
    if scene.box is not None and getattr(scene.box, "deform", None) is not None:
        add("deform", repr(scene.box.deform))
    add("skin", scene.skin)
    add("sort_every", scene.sort_every)
    add("chunks", scene.chunks)
    add("parallel", scene.parallel)
    add("groups", [(g.kind, g.reach, g.parallel, [k for k, _ in g.members]) for g in scene.plan.groups])
    add("fields", [name for name in SAVED_ARRAYS if scene.arrays[name].size])
    add("integrator", repr(integrator))
    add("version", version.__version__)
    return h.hexdigest()


# ---- writing ------------------------------------------------------------------------------------
def state_arrays(scene):
    """Every array a checkpoint holds, by name (the scene's own arrays, not copies: written out or
    compared, never changed)."""
    arrays = {f"state.{name}": scene.arrays[name] for name in SAVED_ARRAYS}
    for e, state in scene.servo_slots():
        arrays[f"servo{e}.state"] = scene.params[state]
    if getattr(scene, "shear_slot", None) is not None:
        arrays["shear.built"] = scene.params[scene.shear_slot + SH_BUILT:scene.shear_slot + SH_BUILT + 1]
    if getattr(scene, "deform_slot", None) is not None:  # the box now, its block, a servo's history
        arrays["deform.box"] = scene.arrays["box"]
        arrays["deform.block"] = scene.params[scene.deform_slot:scene.deform_slot + DEFORM_VALUES]
        arrays["deform.history"] = scene.box.deform.history
    for g in range(len(scene.plan.groups)):
        pl = scene._list(g)
        arrays[f"list{g}.reach"] = np.array([pl.reach])
        for name in PAIR_LIST_FIELDS[1:]:
            arrays[f"list{g}.{name}"] = getattr(pl, name)
    return arrays


def constants(scene):
    """The scene's constant parameters that a checkpoint names when they differ (JSON-ready)."""
    box = scene.box
    return {"interactions": [repr(inter) for inter in scene.interactions + scene.effects],
            "box size": box.size.tolist() if box is not None else None,
            "box periodic": [bool(b) for b in box.periodic] if box is not None else None,
            "skin": scene.skin, "sort_every": scene.sort_every, "parallel": bool(scene.parallel),
            "chunks": scene.chunks, "ids": hashlib.sha256(np.ascontiguousarray(scene.particles.ids)).hexdigest(),
            "fixed": None if scene.particles.fixed is None else
            [int(i) for i in np.asarray(scene.particles.ids)[np.asarray(scene.particles.fixed, dtype=bool)][:1000]]}


def save(simulation, path, extra=None):
    """Write the checkpoint of ``simulation`` to ``path`` atomically (see the module docstring);
    ``extra``: more metadata (a dict)."""
    path = Path(path)
    scene = simulation.scene
    meta = {"format": FORMAT, "demkit": version.__version__, "scene": scene_hash(scene, simulation.integrator),
            "integrator": repr(simulation.integrator), "step": int(simulation.step),
            "time": float(simulation.time), "particles": len(scene.particles),
            "groups": len(scene.plan.groups), "energy_origin": simulation.energy_origin,
            "forces_valid": bool(simulation.forces_valid), "constants": constants(scene),
            "notes": simulation.notes_so_far(), **(extra or {})}
    arrays = state_arrays(scene)
    arrays["meta"] = np.frombuffer(json.dumps(meta).encode(), dtype=np.uint8)
    folder = path.parent if str(path.parent) else Path(".")
    fd, tmp = tempfile.mkstemp(dir=folder, prefix=path.name + ".", suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as fh:
            np.savez(fh, **arrays)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        raise
    sync_folder(folder)  # the rename itself survives a power cut once the folder is synced
    return path


# ---- reading ------------------------------------------------------------------------------------
def load(path):
    """(meta dict, arrays dict) of a checkpoint file. Raises ValueError for a missing, truncated,
    corrupted or foreign file, or one holding pickled objects (nothing in it is executed)."""
    path = Path(path)
    if not path.is_file():
        raise ValueError(f"no checkpoint file at {path}")
    try:
        with np.load(path, allow_pickle=False) as data:
            arrays = {name: data[name] for name in data.files}
    except ValueError as err:
        if "pickle" in str(err):
            raise ValueError(f"checkpoint {path} holds pickled objects; demkit checkpoints never do, and "
                             f"it is not loaded (loading pickles can execute code)") from None
        raise ValueError(f"checkpoint {path} is not a readable demkit checkpoint: {err}") from None
    except (zipfile.BadZipFile, OSError, EOFError, KeyError) as err:
        raise ValueError(f"checkpoint {path} is truncated or corrupted ({type(err).__name__}: {err}); "
                         f"it is not used") from None
    if "meta" not in arrays or arrays["meta"].dtype != np.uint8:
        raise ValueError(f"{path} is not a demkit checkpoint (no metadata)")
    try:
        meta = json.loads(arrays.pop("meta").tobytes().decode())
    except (UnicodeDecodeError, json.JSONDecodeError) as err:
        raise ValueError(f"checkpoint {path} has corrupted metadata: {err}") from None
    if not isinstance(meta, dict) or meta.get("format") != FORMAT:
        raise ValueError(f"checkpoint {path} has format {meta.get('format') if isinstance(meta, dict) else '?'}; "
                         f"this demkit reads format {FORMAT}")
    return meta, arrays


def check_compatible(meta, arrays, simulation, path):
    """Raise ValueError unless the checkpoint fits ``simulation``'s scene, integrator and version."""
    scene = simulation.scene
    if meta.get("demkit") != version.__version__:
        raise ValueError(f"checkpoint {path} was written by demkit {meta.get('demkit')}, this is demkit "
                         f"{version.__version__}: an exact restart needs the same version")
    if meta.get("particles") != len(scene.particles):
        raise ValueError(f"checkpoint {path} holds {meta.get('particles')} particles, the scene has "
                         f"{len(scene.particles)}: it belongs to another scene")
    if meta.get("integrator") != repr(simulation.integrator):
        raise ValueError(f"checkpoint {path} was written with {meta.get('integrator')}, this simulation "
                         f"uses {simulation.integrator!r}: an exact restart needs the same integrator")
    if meta.get("scene") != scene_hash(scene, simulation.integrator):
        what = difference(meta, arrays, scene)
        raise ValueError(f"checkpoint {path} belongs to another scene: "
                         + (f"{what}" if what else "its parameters (interactions, radii, masses, box, skin, thread "
                                                    "chunks, ...) differ from this scene's"))
    expected = state_arrays(scene)
    for name, value in expected.items():
        if name not in arrays:
            raise ValueError(f"checkpoint {path} lacks {name!r}: not a checkpoint of this scene")
        got = arrays[name]
        if got.dtype != value.dtype or (not name.endswith(("partner", "history")) and got.shape != value.shape):
            raise ValueError(f"checkpoint {path}: {name} has {got.dtype} {got.shape}, the scene expects "
                             f"{value.dtype} {value.shape}")
    for name in arrays:
        if name not in expected:
            raise ValueError(f"checkpoint {path} holds an unexpected array {name!r}")
    step = meta.get("step")
    if not isinstance(step, int) or step < 0:
        raise ValueError(f"checkpoint {path} has an invalid step count {step!r}")


def _arguments(text):
    """{name: value text} of a repr like ``Name(a=1, b=Other(c=2))`` (top-level keywords only)."""
    inner = text[text.find("(") + 1:text.rfind(")")] if "(" in text else ""
    out, depth, part = {}, 0, ""
    for ch in inner + ",":
        if ch == "," and depth == 0:
            name, sep, value = part.partition("=")
            out[name.strip() if sep else f"#{len(out)}"] = value.strip() if sep else name.strip()
            part = ""
            continue
        depth += (ch in "([{") - (ch in ")]}")
        part += ch
    return out


def difference(meta, arrays, scene):
    """The first constant parameter in which the checkpoint and ``scene`` differ, as one phrase
    ("radius of sphere id 3: checkpoint 0.5, scene 0.6"), or None when none is found."""
    saved = meta.get("constants")
    now = constants(scene)
    if isinstance(saved, dict):
        old, new = saved.get("interactions", []), now["interactions"]
        if len(old) != len(new):
            return f"{len(old)} interactions in the checkpoint ({', '.join(old)}), {len(new)} in the scene"
        for k, (a, b) in enumerate(zip(old, new)):
            if a == b:
                continue
            name_a, name_b = a.split("(")[0], b.split("(")[0]
            if name_a != name_b:
                return f"interaction {k}: checkpoint {name_a}, scene {name_b}"
            args_a, args_b = _arguments(a), _arguments(b)
            for key in list(args_a) + [k2 for k2 in args_b if k2 not in args_a]:
                if args_a.get(key) != args_b.get(key):
                    label = "" if key.startswith("#") else f" {key}"
                    return f"interaction {k} {name_a}{label}: checkpoint {args_a.get(key)}, scene {args_b.get(key)}"
            return f"interaction {k}: checkpoint {a}, scene {b}"
    tag_old, tag_new = arrays.get("state.tag"), scene.arrays["tag"]
    for name in ("radius", "mass", "inertia"):
        got = arrays.get(f"state.{name}")
        if got is None or tag_old is None or got.shape != scene.arrays[name].shape:
            continue
        old = np.empty_like(got)
        old[tag_old] = got
        new = np.empty_like(got)
        new[tag_new] = scene.arrays[name]
        bad = np.flatnonzero(~((old == new) | (np.isnan(old) & np.isnan(new))))
        if len(bad):
            i = int(bad[0])
            more = f" (and {len(bad) - 1} more spheres)" if len(bad) > 1 else ""
            return (f"{name} of sphere id {scene.particles.ids[i]}: checkpoint {float(old[i])!r}, "
                    f"scene {float(new[i])!r}{more}"
                    + (" (an infinite mass or inertia is a fixed sphere)" if np.isinf([old[i], new[i]]).any() else ""))
    if isinstance(saved, dict):
        for key in ("box size", "box periodic", "skin", "sort_every", "parallel", "chunks", "fixed"):
            if saved.get(key) != now[key]:
                return f"{key}: checkpoint {saved.get(key)}, scene {now[key]}"
        if saved.get("ids") != now["ids"]:
            return "the sphere ids differ"
    return None


def restore(scene, arrays):
    """Put the checkpoint's arrays into ``scene`` (already checked by :func:`check_compatible`)."""
    for name in SAVED_ARRAYS:
        scene.arrays[name][...] = arrays[f"state.{name}"]
    for e, state in scene.servo_slots():
        scene.params[state] = arrays[f"servo{e}.state"]
    if getattr(scene, "shear_slot", None) is not None:
        scene.params[scene.shear_slot + SH_BUILT] = arrays["shear.built"][0]
    if getattr(scene, "deform_slot", None) is not None:
        scene.arrays["box"][...] = arrays["deform.box"]
        scene.params[scene.deform_slot:scene.deform_slot + DEFORM_VALUES] = arrays["deform.block"]
        scene.box.deform.history = np.array(arrays["deform.history"]).reshape(-1, 7)
    lists = []
    for g in range(len(scene.plan.groups)):
        fields = [float(arrays[f"list{g}.reach"][0])] + [np.array(arrays[f"list{g}.{name}"])
                                                        for name in PAIR_LIST_FIELDS[1:]]
        lists.append(scene._pair_list(fields))
    scene.arrays["lists"] = scene.padded(lists)
    scene.state = scene._state_object()
    scene.pull()
