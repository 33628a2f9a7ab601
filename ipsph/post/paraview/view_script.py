"""Open the ipsph run in this folder in ParaView, set up as the run's own renders.

    pvpython paraview_view.py                        # ParaView's Python
    xvfb-run -a pvpython paraview_view.py --screenshot view.png --time 0.48
                                                     # headless, X-only builds (Debian's paraview)
    pvpython paraview_view.py --line-csv line.csv --time 1.0   # the SPH line's values as CSV
    pvpython paraview_view.py --line-csv line.csv --every-frame  # ... at every frame (Time column)
    paraview --script=paraview_view.py               # the GUI (or View > Python Shell > Run Script)

What it builds, with this run's values filled in (SETTINGS below):
  - fluid    fluid.pvd as Point Gaussian spheres of the particle radius, coloured by speed
             (velocity Magnitude) over the run's colour range, with the renders' colour map;
  - walls    boundary_surface.vtp as a translucent surface (front faces culled: a cutaway);
  - wall particles (boundary.vtu), hidden;
  - bodies   bodies.pvd, the moving walls and rigid bodies where they are at each frame, as
             surfaces in the walls' colour (when the run has any);
  - surface  surface.pvd, the fluid's surface mesh (a run with --surface), coloured by speed;
             shown when the run rendered surfaces (render.mode = "surface"), else hidden;
  - the camera, background, time annotation and title of `ipsph render`;
  - SPH line, hidden until you show it: an SPH Line Interpolator on the fluid with the settings
    it needs (cubic kernel, Spatial Step = 2r, Density Array `density`, Mass Array `mass`), then
    "SPH line" divides every interpolated array by the Shepard sum, so values near the walls and
    the free surface are not read low. Its line is vertical through the fluid; move it with
    the line widget of "SPH line interpolator". `Shepard Summation` stays on the line: the free
    surface is where it falls through 0.5.

Written by `ipsph run` and `ipsph paraview OUT` (ipsph/post/paraview/); files are found next to this
script, so the folder can be moved. It needs ParaView 5.10 or later and nothing from ipsph.
"""

import argparse
import os
import sys

SETTINGS = {}  # filled in by ipsph.post.paraview.write_view_script

# Divide every interpolated point array by the Shepard sum (ParaView's SPH filters do not expose
# VTK's ShepardNormalization); points no fluid particle reaches keep the null value.
SHEPARD_SCRIPT = """
import numpy as np
from vtkmodules.util.numpy_support import numpy_to_vtk, vtk_to_numpy
inp = self.GetInputDataObject(0, 0)
out = self.GetOutputDataObject(0)
out.ShallowCopy(inp)
pd = out.GetPointData()
s = pd.GetArray("Shepard Summation")
if s is not None:
    s = vtk_to_numpy(s).astype(np.float64)
    ok = s > 0.0
    for i in range(pd.GetNumberOfArrays()):
        a = pd.GetArray(i)
        name = a.GetName() if a is not None else None
        if name in (None, "Shepard Summation", "vtkValidPointMask") or not a.GetDataType() in (10, 11):
            continue
        v = vtk_to_numpy(a).astype(np.float64)
        w = s.reshape((-1,) + (1,) * (v.ndim - 1))
        n = np.where(ok.reshape(w.shape), v / np.where(w > 0.0, w, 1.0), v)
        b = numpy_to_vtk(np.ascontiguousarray(n), deep=1)
        b.SetName(name)
        pd.AddArray(b)
"""


def folder():
    """The run folder: this script's own, else (a GUI shell without __file__) the one it was written in."""
    here = os.path.dirname(os.path.abspath(globals().get("__file__", "") or "."))
    if os.path.isfile(os.path.join(here, SETTINGS["files"]["fluid"])):
        return here
    return SETTINGS["folder"]


def _font(s):
    """The renders' font file where this machine has it (ParaView's own Arial draws '[' like '(')."""
    for f in s.get("font_files") or []:
        if f and os.path.isfile(f):
            return f
    return None


def _rgb_points(lo, hi, colours):
    pts = []
    for i, c in enumerate(colours):
        pts += [lo + (hi - lo) * i / (len(colours) - 1), *c]
    return pts


def build(s=None, where=None, text_scale=1.0):
    """Load the run and set up the view (text sizes times `text_scale`); returns {name: proxy}."""
    from paraview import simple as pv

    s = s or SETTINGS
    where = where or folder()
    pv._DisableFirstRenderCameraReset()  # as ParaView's own state files do: keep the camera set below
    files = s["files"]
    view = pv.GetActiveViewOrCreate("RenderView")
    view.OrientationAxesVisibility = 0
    try:  # ParaView 5.11 and later
        view.UseColorPaletteForBackground = 0
        view.BackgroundColorMode = "Gradient"
    except Exception:  # 5.10
        view.UseGradientBackground = 1
    view.Background = s["background"][0]
    view.Background2 = s["background"][1]
    out = {"view": view}

    fluid = pv.PVDReader(registrationName="fluid", FileName=os.path.join(where, files["fluid"]))
    out["fluid"] = fluid
    disp = pv.Show(fluid, view)
    disp.SetRepresentationType("Point Gaussian")
    disp.GaussianRadius = s["particle_radius"]
    disp.ScaleByArray = 0
    disp.ShaderPreset = "Sphere"
    disp.Specular = 0.0
    pv.ColorBy(disp, ("POINTS", "velocity", "Magnitude"))
    lut = pv.GetColorTransferFunction("velocity")
    lo, hi = s["speed_range"]
    lut.AutomaticRescaleRangeMode = "Never"
    lut.RGBPoints = _rgb_points(lo, hi, s["speed_colours"])
    lut.ColorSpace = "RGB"
    lut.VectorMode = "Magnitude"
    pv.GetOpacityTransferFunction("velocity").RescaleTransferFunction(lo, hi)
    lut.RescaleTransferFunction(lo, hi)
    bar = pv.GetScalarBar(lut, view)
    bar.Title = s["speed_title"]
    bar.ComponentTitle = ""
    bar.AutomaticLabelFormat = 0
    bar.RangeLabelFormat = bar.LabelFormat = "%.2f"
    k = float(text_scale)
    bar.TitleFontSize, bar.LabelFontSize = round(20 * k), round(16 * k)
    bar.TitleColor = bar.LabelColor = [1.0, 1.0, 1.0]
    font = _font(s)
    if font:
        bar.TitleFontFamily = bar.LabelFontFamily = "File"
        bar.TitleFontFile = bar.LabelFontFile = font
    bar.ScalarBarThickness = round(24 * k)
    bar.WindowLocation = "Any Location"
    bar.Orientation = "Vertical"
    bar.Position = s["scalar_bar"]["position"]
    bar.ScalarBarLength = s["scalar_bar"]["length"]
    disp.SetScalarBarVisibility(view, True)

    if files.get("walls"):
        walls = pv.XMLPolyDataReader(registrationName="walls", FileName=[os.path.join(where, files["walls"])])
        wd = pv.Show(walls, view)
        wd.SetRepresentationType("Surface")
        wd.ColorArrayName = ["POINTS", ""]  # a solid colour
        wd.AmbientColor = wd.DiffuseColor = s["wall_colour"]
        wd.Opacity = s["wall_opacity"]
        wd.Specular = 0.0
        wd.BackfaceRepresentation = "Cull Frontface"  # the near walls are left out, as in the renders
        edges = pv.FeatureEdges(registrationName="wall edges", Input=walls)  # outline and creases, as rendered
        edges.FeatureAngle = 40.0
        edges.ManifoldEdges = 0
        ed = pv.Show(edges, view)
        ed.ColorArrayName = ["POINTS", ""]
        ed.AmbientColor = ed.DiffuseColor = s["wall_colour"]
        ed.Opacity = s["edge_opacity"]
        out["walls"], out["wall edges"] = walls, edges
    if files.get("wall_particles"):
        wp = pv.XMLUnstructuredGridReader(
            registrationName="wall particles", FileName=[os.path.join(where, files["wall_particles"])]
        )
        pv.Hide(wp, view)
        out["wall particles"] = wp

    if files.get("bodies"):  # moving walls and rigid bodies: a surface per frame
        bodies = pv.PVDReader(registrationName="bodies", FileName=os.path.join(where, files["bodies"]))
        bd = pv.Show(bodies, view)
        bd.SetRepresentationType("Surface")
        bd.ColorArrayName = ["POINTS", ""]
        bd.AmbientColor = bd.DiffuseColor = s["wall_colour"]
        bd.Specular = 0.0
        out["bodies"] = bodies
    if files.get("surface"):  # the fluid's surface mesh per frame (--surface)
        surface = pv.PVDReader(registrationName="surface", FileName=os.path.join(where, files["surface"]))
        sd = pv.Show(surface, view)
        sd.SetRepresentationType("Surface")
        pv.ColorBy(sd, ("POINTS", "velocity", "Magnitude"))  # the fluid's colour map (lut above)
        if not s.get("surface_visible"):
            pv.Hide(surface, view)
        else:
            pv.Hide(fluid, view)
        out["surface"] = surface

    ann = pv.AnnotateTimeFilter(registrationName="time", Input=fluid)
    ann.Format = "t = {time:.3f} s"
    ad = pv.Show(ann, view)
    ad.WindowLocation = "Upper Left Corner"
    ad.FontSize = round(28 * k)
    ad.Color = [1.0, 1.0, 1.0]
    if font:
        ad.FontFamily, ad.FontFile = "File", font
    out["time"] = ann
    if s.get("title"):
        title = pv.Text(registrationName="title", Text=s["title"])
        td = pv.Show(title, view)
        td.WindowLocation = "Lower Left Corner"
        td.FontSize = round(20 * k)
        td.Color = s["title_colour"]
        if font:
            td.FontFamily, td.FontFile = "File", font
        out["title"] = title

    sph_s = s["sph"]
    interp = pv.SPHLineInterpolator(registrationName="SPH line interpolator", Input=fluid, Source="Line")
    interp.Source.Point1 = sph_s["point1"]
    interp.Source.Point2 = sph_s["point2"]
    interp.Source.Resolution = sph_s["resolution"]
    interp.Kernel = "SPHCubicKernel"
    interp.Kernel.Dimension = 3
    interp.Kernel.SpatialStep = sph_s["spatial_step"]  # VTK's cubic reaches 2 spatial steps = H = 4r
    interp.DensityArray = sph_s["density_array"]
    interp.MassArray = sph_s["mass_array"]
    interp.ComputeShepardSum = 1
    interp.NullPointsStrategy = "Null Value"
    interp.NullValue = 0.0
    line = pv.ProgrammableFilter(registrationName="SPH line", Input=interp)
    line.Script = SHEPARD_SCRIPT
    line.CopyArrays = 1
    out["SPH line interpolator"], out["SPH line"] = interp, line
    pv.Hide(interp, view)
    pv.Hide(line, view)

    cam = s["camera"]
    view.CameraPosition = cam["position"]
    view.CameraFocalPoint = cam["focal_point"]
    view.CameraViewUp = cam["view_up"]
    view.CameraViewAngle = cam["view_angle"]
    view.CameraParallelProjection = 0
    pv.SetActiveSource(fluid)
    return out


def show_time(proxies, t=None):
    """Go to the frame nearest `t` (s), or the first frame; returns its time."""
    from paraview import simple as pv

    times = list(proxies["fluid"].TimestepValues or [0.0])
    if not isinstance(times, list):
        times = [times]
    target = times[0] if t is None else min(times, key=lambda x: abs(x - t))
    scene = pv.GetAnimationScene()
    scene.UpdateAnimationUsingDataTimeSteps()
    scene.AnimationTime = target
    proxies["view"].ViewTime = target
    return target


def main(argv=None):
    from paraview import simple as pv

    p = argparse.ArgumentParser(description="Open this ipsph run in ParaView with the run's settings.")
    p.add_argument("--time", type=float, help="simulated time to show (nearest frame; default: the first)")
    p.add_argument("--screenshot", metavar="PNG", help="render the view to PNG and exit (headless)")
    p.add_argument("--size", type=int, nargs=2, metavar=("W", "H"), help="screenshot size (default: the renders')")
    p.add_argument("--line-csv", metavar="CSV", help="write the SPH line's (Shepard-normalised) values as CSV")
    p.add_argument(
        "--every-frame", action="store_true", help="with --line-csv: every frame into the one CSV, with a Time column"
    )
    p.add_argument("--show-line", action="store_true", help="show the SPH line in the view")
    args, _ = p.parse_known_args(argv if argv is not None else [])
    size = list(args.size or SETTINGS["image_size"])
    proxies = build(text_scale=size[1] / SETTINGS["image_size"][1] if args.screenshot else 1.0)
    t = show_time(proxies, args.time)
    if args.show_line:
        pv.Show(proxies["SPH line"], proxies["view"])
    if args.line_csv:
        if args.every_frame:
            pv.SaveData(args.line_csv, proxy=proxies["SPH line"], Precision=9, WriteTimeSteps=1, AddTime=1)
            print(f"paraview_view: SPH line at every frame -> {args.line_csv}")
        else:
            pv.SaveData(args.line_csv, proxy=proxies["SPH line"], Precision=9)
            print(f"paraview_view: SPH line at t = {t:.4g} s -> {args.line_csv}")
    if args.screenshot:
        proxies["view"].ViewSize = size  # text sizes are pixels of this size
        pv.SaveScreenshot(args.screenshot, proxies["view"], ImageResolution=size, FontScaling="Do not scale fonts")
        print(f"paraview_view: t = {t:.4g} s -> {args.screenshot}")
    elif not args.line_csv:
        pv.Render(proxies["view"])
    return proxies


if __name__ == "__main__":  # pvpython paraview_view.py [options]
    main(sys.argv[1:])
elif __name__ != "ipsph.post.paraview.view_script":  # the GUI's Python shell, --script, Load State
    main()
