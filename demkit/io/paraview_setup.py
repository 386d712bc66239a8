"""ParaView set-up for a demkit series: spheres to scale, dipole arrows, trails, the box.

Run with ParaView's Python (not demkit's):

    pvpython paraview_setup.py out/particles.pvd              # writes out/particles.pvsm
    paraview --state=out/particles.pvsm                       # open it in the GUI
    xvfb-run -a pvpython paraview_setup.py out/particles.pvd --screenshot frame.png

(``--screenshot`` renders, which Debian's ParaView does through X only: use a display or
``xvfb-run``.) Or, in the ParaView GUI, open the .pvd, select it and run this file from View >
Python Shell > Run Script: it decorates the selected series. Find this file with
``python -m demkit.io --paraview-script``.

Pipeline: PVD reader -> Glyph (Sphere, scaled by ``radius``: ParaView's sphere glyph has radius
0.5, so scale factor 2), coloured by ``id`` (up to 10 particles) or by speed (|velocity|, with a
colour bar whose range follows the frame shown; ``--colour-range run``: the range over the whole
run, which reads every frame); Glyph (Arrow, oriented by ``dipole``, centred on the sphere,
3.4 radii long and thick enough to see among hundreds of spheres) when the series has dipoles;
"Temporal Particles To Pathlines" keyed by ``id`` for trails that grow as the animation plays
(broken where a sphere crosses a periodic side; above 10 spheres only the last
:data:`TRAIL_FRAMES` frames, so that the spheres stay readable); the ``<name>_trails.vtp``
poly-lines (whole paths, coloured by time; hidden at first) when present; the box outline when the
.pvd holds a ``Box`` element, and for a box that deforms the outline of each frame's box
(``<name>_box.pvd``, :mod:`demkit.io.box_outline`) instead. The saved state has a layout holding the
render view and a camera that frames the box (a deforming box's largest lengths), or else every
position of the run.

It says what it does as it goes, a line a step with the seconds since it started (loading ParaView
and the steps that read every frame of a long series take a while).
"""
import argparse
import math
import os
import sys
import time
import xml.etree.ElementTree as ET

START = time.perf_counter()


def say(text):
    """One line of what the script does now, with the seconds since it started (flushed at once)."""
    print(f"[{time.perf_counter() - START:6.1f} s] {text}", flush=True)


if __name__ == "__main__":
    say("loading ParaView (paraview.simple)...")
import paraview.simple as pvs  # noqa: E402

ID_COLOURS_UP_TO = 10  # particles; above this the spheres are coloured by speed
TRAIL_FRAMES = 10  # frames of growing trail kept above ID_COLOURS_UP_TO particles
VIEW_SIZE = [1024, 768]


def read_box(pvd):
    """(size [3], periodic [3] bools) from the .pvd's Box element, or None."""
    try:
        element = ET.parse(pvd).getroot().find("Box")
    except (ET.ParseError, OSError):
        return None
    if element is None:
        return None
    size = [float(x) for x in element.get("size").split()]
    periodic = [x == "1" for x in element.get("periodic").split()]
    return size, periodic


def box_frames(box_file):
    """(reader, smallest lengths [3], largest lengths [3]) of a deforming box's outline series (the
    .pvd ``box_file``: every frame's box [0, L]), or None when there is no such file."""
    if not box_file or not os.path.exists(box_file):
        return None
    outline = pvs.PVDReader(registrationName="box", FileName=box_file)
    sizes = []
    for t in outline.TimestepValues or [0.0]:
        outline.UpdatePipeline(t)
        bounds = outline.GetDataInformation().GetBounds()
        sizes.append([bounds[2 * a + 1] - bounds[2 * a] for a in range(3)])
    return outline, [min(s[a] for s in sizes) for a in range(3)], [max(s[a] for s in sizes) for a in range(3)]


def decorate(reader, view, trails_file=None, box=None, colour_range="frame", box_file=None):
    """Add the demkit glyphs, arrows, trails and box to ``view`` (``box_file``: a deforming box's outline
    series, drawn instead of the fixed outline); returns the sources made.
    ``colour_range``: 'frame' (the speed colours span the frame shown) or 'run' (the whole run)."""
    say("reading the series' frame list and its first frame...")
    reader.UpdatePipelineInformation()
    times = list(reader.TimestepValues) or [0.0]
    reader.UpdatePipeline(times[0])
    arrays = reader.PointData.keys()
    count = reader.GetDataInformation().GetNumberOfPoints()
    say(f"{len(times)} frames (t = {times[0]:g} to {times[-1]:g}), {count} spheres; fields: {', '.join(arrays)}")
    say("sphere glyphs to scale...")
    spheres = pvs.Glyph(registrationName="spheres", Input=reader, GlyphType="Sphere")
    spheres.ScaleArray = ["POINTS", "radius"]
    spheres.ScaleFactor = 2.0
    spheres.GlyphMode = "All Points"
    spheres.GlyphType.ThetaResolution = 24
    spheres.GlyphType.PhiResolution = 24
    shown = pvs.Show(spheres, view)
    if count > ID_COLOURS_UP_TO and "velocity" in arrays:
        pvs.ColorBy(shown, ("POINTS", "velocity", "Magnitude"))
        lut = pvs.GetColorTransferFunction("velocity")
        if colour_range == "run":
            say(f"colouring by speed: its range over the whole run reads all {len(times)} frames...")
            shown.RescaleTransferFunctionToDataRangeOverTime()
            lut.AutomaticRescaleRangeMode = "Never"
        else:
            say("colouring by speed: the range follows the frame shown...")
            lut.AutomaticRescaleRangeMode = "Clamp and update every timestep"
            shown.RescaleTransferFunctionToDataRange(False, True)
        shown.SetScalarBarVisibility(view, True)
    else:
        pvs.ColorBy(shown, ("POINTS", "id"))
    made = {"spheres": spheres}
    if "dipole" in arrays:
        say("dipole arrows...")
        arrows = pvs.Glyph(registrationName="dipoles", Input=reader, GlyphType="Arrow")
        arrows.OrientationArray = ["POINTS", "dipole"]
        arrows.ScaleArray = ["POINTS", "radius"]
        arrows.ScaleFactor = 3.4  # 3.4 radii: 0.7 radius out of the sphere at each end
        arrows.GlyphType.TipLength = 0.25
        arrows.GlyphType.TipRadius = 0.15  # of the length: thick enough to read among hundreds
        arrows.GlyphType.ShaftRadius = 0.07
        arrows.GlyphMode = "All Points"
        arrows.GlyphTransform.Translate = [-0.5, 0.0, 0.0]  # centre the unit arrow on the sphere
        arrows_shown = pvs.Show(arrows, view)
        arrows_shown.ColorArrayName = ["POINTS", ""]
        arrows_shown.DiffuseColor = [0.12, 0.12, 0.12]
        made["dipoles"] = arrows
    say("growing trails (Temporal Particles To Pathlines)...")
    paths = pvs.TemporalParticlesToPathlines(registrationName="growing trails", Input=reader)
    paths.IdChannelArray = "id"
    paths.MaskPoints = 1
    paths.MaxTrackLength = TRAIL_FRAMES if count > ID_COLOURS_UP_TO else 100000
    # a step longer than half a periodic side is a jump across the box: the track breaks there (a
    # deforming box: half its smallest side over the run)
    deforming = box_frames(box_file) if box else None
    sides = deforming[1] if deforming else (box[0] if box else None)
    paths.MaxStepDistance = [s / 2 if p else 1e30 for s, p in zip(sides, box[1])] if box else [1e30] * 3
    paths_shown = pvs.Show(paths, view)
    pvs.ColorBy(paths_shown, ("POINTS", "id"))
    made["growing trails"] = paths
    if trails_file and os.path.exists(trails_file):
        say(f"whole-path trails from {trails_file} (hidden at first)...")
        whole = pvs.XMLPolyDataReader(registrationName="trails", FileName=[trails_file])
        whole_shown = pvs.Show(whole, view)
        pvs.ColorBy(whole_shown, ("POINTS", "time"))
        pvs.Hide(whole, view)  # whole paths: tick the eye in the Pipeline Browser to show them
        made["trails"] = whole
    if deforming:
        outline, smallest, largest = deforming
        say(f"box outline at every frame (the box deforms: from {smallest[0]:g} x {smallest[1]:g} x {smallest[2]:g} "
            f"to {largest[0]:g} x {largest[1]:g} x {largest[2]:g} at most)...")
        outline_shown = pvs.Show(outline, view)
        outline_shown.ColorArrayName = ["POINTS", ""]
        outline_shown.AmbientColor = outline_shown.DiffuseColor = [0.85, 0.85, 0.85]
        made["box"] = outline
        box = (largest, box[1])  # the camera frames the largest box
    elif box:
        size = box[0]
        say(f"box outline {size[0]:g} x {size[1]:g} x {size[2]:g}...")
        outline = pvs.Box(registrationName="box", XLength=size[0], YLength=size[1], ZLength=size[2],
                          Center=[s / 2 for s in size])
        outline_shown = pvs.Show(outline, view)
        outline_shown.SetRepresentationType("Outline")
        outline_shown.AmbientColor = outline_shown.DiffuseColor = [0.85, 0.85, 0.85]
        made["box"] = outline
    pvs.Hide(reader, view)
    say("camera: framing " + ("the box" if box else "every position of the run (first and last frames"
                              + (", trails)" if "trails" in made else ")")) + "...")
    frame_camera(view, reader, times, made.get("trails"), box)
    return made


def frame_camera(view, reader, times, trails=None, box=None):
    """Point the camera at the box, or at every position of the run (the trails file, or the
    first and last frames): a plane view when the spheres lie in a plane, else isometric."""
    rmax = reader.PointData["radius"].GetRange()[1]
    spans = []
    for t in (times[0], times[-1]):
        reader.UpdatePipeline(t)
        spans.append(reader.GetDataInformation().GetBounds())
    if trails is not None:
        trails.UpdatePipeline()
        spans.append(trails.GetDataInformation().GetBounds())
    lo = [min(b[2 * a] for b in spans) for a in range(3)]
    hi = [max(b[2 * a + 1] for b in spans) for a in range(3)]
    extent = [h - l for l, h in zip(lo, hi)]
    if box:
        lo, hi = [0.0] * 3, list(box[0])
    else:
        pad = 1.4 * rmax
        lo, hi = [x - pad for x in lo], [x + pad for x in hi]
    centre = [(l + h) / 2 for l, h in zip(lo, hi)]
    flat = min(range(3), key=lambda a: extent[a])
    if extent[flat] <= 0.5 * rmax:  # face-on, parallel projection
        up = 2 if flat != 2 else 1
        across = 3 - flat - up
        half = max((hi[up] - lo[up]) / 2, (hi[across] - lo[across]) / 2 * VIEW_SIZE[1] / VIEW_SIZE[0])
        eye = list(centre)
        eye[flat] += (-1.0 if flat == 1 else 1.0) * 4 * max(hi[a] - lo[a] for a in range(3))
        view.CameraParallelProjection = 1
        view.CameraParallelScale = 1.1 * half
        view.CameraViewUp = [1.0 if a == up else 0.0 for a in range(3)]
    else:  # isometric, perspective: the bounds' enclosing sphere fills the view
        radius = 0.5 * math.sqrt(sum((h - l) ** 2 for l, h in zip(lo, hi)))
        distance = radius / math.sin(math.radians(view.CameraViewAngle / 2))
        eye = [c + distance / math.sqrt(3) for c in centre]
        view.CameraParallelProjection = 0
        view.CameraViewUp = [0.0, 0.0, 1.0]
    view.CameraPosition = eye
    view.CameraFocalPoint = centre
    view.CenterOfRotation = centre


def main(argv=None):
    parser = argparse.ArgumentParser(description="Set up ParaView for a demkit .pvd series.")
    parser.add_argument("pvd", help="the series' .pvd collection")
    parser.add_argument("--state", help="ParaView state file to write (default: next to the .pvd)")
    parser.add_argument("--screenshot", help="also save a picture of the last frame (renders: needs "
                                             "a display or xvfb-run)")
    parser.add_argument("--colour-range", choices=("frame", "run"), default="frame",
                        help="speed colours over the frame shown (default) or the whole run")
    args = parser.parse_args(argv)
    pvd = os.path.abspath(args.pvd)
    if not os.path.exists(pvd):
        parser.error(f"no such file: {pvd}")
    say(f"opening {pvd}")
    reader = pvs.PVDReader(registrationName=os.path.basename(pvd), FileName=pvd)
    view = pvs.CreateView("RenderView")
    layout = pvs.CreateLayout("demkit")
    pvs.AssignViewToLayout(view=view, layout=layout, hint=0)  # else the GUI opens with no view
    pvs.SetActiveView(view)
    view.ViewSize = VIEW_SIZE
    pvs.GetAnimationScene().PlayMode = "Snap To TimeSteps"  # play the frames as written
    box = read_box(pvd)
    made = decorate(reader, view, pvd[:-4] + "_trails.vtp", box, args.colour_range, pvd[:-4] + "_box.pvd")
    state = os.path.abspath(args.state or pvd[:-4] + ".pvsm")
    say(f"writing the state file {state}...")
    pvs.SaveState(state)
    print(f"set up {', '.join(made)} for {pvd}")
    print(f"state written to {state}: open it with  paraview --state={state}")
    if args.screenshot:
        times = reader.TimestepValues
        last = times[-1] if times else 0.0
        view.ViewTime = last
        spheres = pvs.GetDisplayProperties(made["spheres"], view)
        if args.colour_range == "frame" and spheres.ColorArrayName[1] == "velocity":
            # "update every timestep" acts when the animation plays, not on a time set here: the
            # colours of the picture span the speeds of the frame drawn
            made["spheres"].UpdatePipeline(last)
            spheres.RescaleTransferFunctionToDataRange(False, True)
            values = pvs.GetColorTransferFunction("velocity").RGBPoints[0::4]
            say(f"speed colours span the frame drawn: {values[0]:.3g} .. {values[-1]:.3g}")
        # the growing trails only grow while the animation plays: show the whole paths instead
        # (unwrapped, so not in a periodic box, where they leave it)
        pvs.Hide(made["growing trails"], view)
        if "trails" in made and not (box and any(box[1])):
            pvs.Show(made["trails"], view)
        say(f"rendering the last frame (t = {last:g}) to {args.screenshot}...")
        pvs.SaveScreenshot(os.path.abspath(args.screenshot), view, ImageResolution=VIEW_SIZE)
        print(f"picture written to {args.screenshot}")
    # release the render window while the X connection is still open: without this, pvpython
    # under xvfb-run exits with GLXBadContext and status 1 after writing the picture
    pvs.Delete(view)
    pvs.RemoveLayout(layout)
    say("done")
    return 0


def in_gui():
    """Run from ParaView's Python shell: decorate the selected .pvd series."""
    source = pvs.GetActiveSource()
    if source is None:
        raise RuntimeError("select a demkit .pvd series in the Pipeline Browser first")
    name = getattr(source, "FileName", None)
    is_pvd = isinstance(name, str) and name.endswith(".pvd")
    decorate(source, pvs.GetActiveViewOrCreate("RenderView"), name[:-4] + "_trails.vtp" if is_pvd else None,
             read_box(name) if is_pvd else None, box_file=name[:-4] + "_box.pvd" if is_pvd else None)
    pvs.GetAnimationScene().UpdateAnimationUsingDataTimeSteps()
    pvs.Render()


if __name__ == "__main__":
    if any(arg.endswith(".pvd") or arg in ("-h", "--help") for arg in sys.argv[1:]):
        sys.exit(main())
    in_gui()
