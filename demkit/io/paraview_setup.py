"""ParaView set-up for a demkit series: spheres to scale, dipole arrows, trails.

Run with ParaView's Python (not demkit's):

    pvpython paraview_setup.py out/particles.pvd              # writes out/particles.pvsm
    paraview --state=out/particles.pvsm                       # open it in the GUI
    pvpython paraview_setup.py out/particles.pvd --screenshot frame.png   (needs a display)

or, in the ParaView GUI, open the .pvd, select it and run this file from View > Python Shell >
Run Script: it decorates the selected series. Find this file with
``python -m demkit.io --paraview-script``.

Pipeline: PVD reader -> Glyph (Sphere, scaled by ``radius``: ParaView's sphere glyph has radius
0.5, so scale factor 2), coloured by ``id``; Glyph (Arrow, oriented by ``dipole``, centred on the
sphere, 2.7 radii long) when the series has dipoles; "Temporal Particles To Pathlines" keyed by
``id`` for trails that grow as the animation plays; the ``<name>_trails.vtp`` poly-lines (whole
paths, coloured by time) when present.
"""
import argparse
import os
import sys

import paraview.simple as pvs


def decorate(reader, view, trails_file=None):
    """Add the demkit glyphs, arrows and trails for ``reader`` to ``view``; returns the sources."""
    reader.UpdatePipelineInformation()
    arrays = reader.PointData.keys()
    spheres = pvs.Glyph(registrationName="spheres", Input=reader, GlyphType="Sphere")
    spheres.ScaleArray = ["POINTS", "radius"]
    spheres.ScaleFactor = 2.0
    spheres.GlyphMode = "All Points"
    spheres.GlyphType.ThetaResolution = 24
    spheres.GlyphType.PhiResolution = 24
    shown = pvs.Show(spheres, view)
    pvs.ColorBy(shown, ("POINTS", "id"))
    made = {"spheres": spheres}
    if "dipole" in arrays:
        arrows = pvs.Glyph(registrationName="dipoles", Input=reader, GlyphType="Arrow")
        arrows.OrientationArray = ["POINTS", "dipole"]
        arrows.ScaleArray = ["POINTS", "radius"]
        arrows.ScaleFactor = 2.7
        arrows.GlyphMode = "All Points"
        arrows.GlyphTransform.Translate = [-0.5, 0.0, 0.0]  # centre the unit arrow on the sphere
        arrows_shown = pvs.Show(arrows, view)
        arrows_shown.ColorArrayName = ["POINTS", ""]
        arrows_shown.DiffuseColor = [0.12, 0.12, 0.12]
        made["dipoles"] = arrows
    paths = pvs.TemporalParticlesToPathlines(registrationName="growing trails", Input=reader)
    paths.IdChannelArray = "id"
    paths.MaskPoints = 1
    paths.MaxTrackLength = 100000
    paths.MaxStepDistance = [1e30, 1e30, 1e30]
    paths_shown = pvs.Show(paths, view)
    pvs.ColorBy(paths_shown, ("POINTS", "id"))
    made["growing trails"] = paths
    if trails_file and os.path.exists(trails_file):
        whole = pvs.XMLPolyDataReader(registrationName="trails", FileName=[trails_file])
        whole_shown = pvs.Show(whole, view)
        pvs.ColorBy(whole_shown, ("POINTS", "time"))
        pvs.Hide(whole, view)  # whole paths: tick the eye in the Pipeline Browser to show them
        made["trails"] = whole
    pvs.Hide(reader, view)
    view.ViewSize = [1024, 768]
    view.ResetCamera()
    return made


def main(argv=None):
    parser = argparse.ArgumentParser(description="Set up ParaView for a demkit .pvd series.")
    parser.add_argument("pvd", help="the series' .pvd collection")
    parser.add_argument("--state", help="ParaView state file to write (default: next to the .pvd)")
    parser.add_argument("--screenshot", help="also save a picture of the last frame (needs a display)")
    args = parser.parse_args(argv)
    pvd = os.path.abspath(args.pvd)
    if not os.path.exists(pvd):
        parser.error(f"no such file: {pvd}")
    reader = pvs.PVDReader(registrationName=os.path.basename(pvd), FileName=pvd)
    view = pvs.CreateView("RenderView")
    pvs.GetAnimationScene().PlayMode = "Snap To TimeSteps"  # play the frames as written
    trails = pvd[:-4] + "_trails.vtp"
    made = decorate(reader, view, trails)
    state = os.path.abspath(args.state or pvd[:-4] + ".pvsm")
    pvs.SaveState(state)
    print(f"set up {', '.join(made)} for {pvd}")
    print(f"state written to {state}: open it with  paraview --state={state}")
    if args.screenshot:
        times = reader.TimestepValues
        view.ViewTime = times[-1] if times else 0.0
        # the growing trails only grow while the animation plays: show the whole paths instead
        pvs.Hide(made["growing trails"], view)
        if "trails" in made:
            pvs.Show(made["trails"], view)
        pvs.SaveScreenshot(os.path.abspath(args.screenshot), view, ImageResolution=[1024, 768])
        print(f"picture written to {args.screenshot}")
    return 0


def in_gui():
    """Run from ParaView's Python shell: decorate the selected .pvd series."""
    source = pvs.GetActiveSource()
    if source is None:
        raise RuntimeError("select a demkit .pvd series in the Pipeline Browser first")
    name = getattr(source, "FileName", None)
    trails = name[:-4] + "_trails.vtp" if isinstance(name, str) and name.endswith(".pvd") else None
    decorate(source, pvs.GetActiveViewOrCreate("RenderView"), trails)
    pvs.Render()


if __name__ == "__main__":
    if any(arg.endswith(".pvd") or arg in ("-h", "--help") for arg in sys.argv[1:]):
        sys.exit(main())
    in_gui()
