"""Offscreen renders: camera fit, colour map, and (with GL) pixels, determinism and videos.

GL is probed in a subprocess (a missing GL stack segfaults); render tests skip with its reason.
"""

from __future__ import annotations

import math
from dataclasses import asdict
from pathlib import Path

import numpy as np
import pytest

from ipsph.config import RenderConfig
from ipsph.errors import ConfigError, OutputError
from ipsph.io import frame_file
from ipsph.io.provenance import write_run_json
from ipsph.io.pvd import PvdSeries
from ipsph.io.stats import STATS_COLUMNS, StatsWriter
from ipsph.io.vtu import write_particles, write_surface
from ipsph.post.render import (
    VIEWS,
    camera_for_view,
    default_speed_range,
    gl_available,
    make_video,
    render_output,
    speed_colormap,
)

SMALL = RenderConfig(width=320, height=180)


def make_output_folder(out: Path, n_frames: int = 3, r: float = 0.02) -> Path:
    """A synthetic, solver-free output folder: a column of fluid sliding right in a box."""
    import pyvista as pv

    (out / "frames").mkdir(parents=True, exist_ok=True)
    bounds = [0.0, 1.0, 0.0, 0.5, 0.0, 0.3]
    box = pv.Box(bounds=bounds).triangulate()
    write_surface(out / "boundary_surface.vtp", box)
    write_particles(
        out / "boundary.vtu", box.points, {"volume": np.full(box.n_points, 1e-5), "id": np.arange(box.n_points)}, 0.0
    )
    d = 2 * r
    g = np.stack(
        np.meshgrid(np.arange(r, 0.3, d), np.arange(r, 0.3, d), np.arange(r, 0.3 - r, d), indexing="ij"), -1
    ).reshape(-1, 3)
    series = PvdSeries(out / "run.pvd", "boundary.vtu")
    with StatsWriter(out / "stats.csv", STATS_COLUMNS) as stats:
        for k in range(n_frames):
            t = 0.1 * k
            v = np.c_[g[:, 0] * 4 * t + 0.1 * k, -g[:, 1] * t, np.zeros(len(g))]
            write_particles(out / frame_file(k), g + [0.2 * t, 0, 0], {"velocity": v, "id": np.arange(len(g))}, t)
            series.add(t, frame_file(k))
            stats.write({"step": k + 1, "time": t, "max_speed": float(np.linalg.norm(v, axis=1).max())})
    write_run_json(
        out / "run.json",
        {
            "scene": {"name": "synthetic", "output": {"fps": 10.0}},
            "method": "ipsph",
            "status": "completed",
            "completed": True,
            "particle_radius": r,
            "fluid_particles": len(g),
            "domain_bounds": bounds,
            "frames": n_frames,
            "render": {**asdict(SMALL), "speed_range": [0.0, 2.0]},
        },
    )
    return out


# --- no GL needed -------------------------------------------------------------------------------


def test_gl_probe_gives_a_reason():
    ok, reason = gl_available()
    assert isinstance(ok, bool) and reason and "\n" not in reason


def test_default_speed_range_is_free_fall_from_fluid_top():
    lo, hi = default_speed_range(0.0, (0.0, -9.81, 0.0), fluid_top=2.0, domain_bottom=0.0)
    assert lo == 0.0 and hi == pytest.approx(math.sqrt(2 * 9.81 * 2.0))
    assert default_speed_range(3.0, 9.81, 0.0, 0.0)[1] == pytest.approx(3.0)
    assert default_speed_range(0.0, 0.0, 1.0, 0.0) == (0.0, 1.0)  # degenerate: documented fallback


def test_colormap_runs_dark_blue_to_white_with_rising_lightness():
    cmap = speed_colormap()
    rgb = cmap(np.linspace(0, 1, 64))[:, :3]
    lum = rgb @ [0.2126, 0.7152, 0.0722]
    assert np.all(np.diff(lum) > 0)
    assert np.allclose(rgb[-1], 1.0) and rgb[0, 2] > rgb[0, 0]  # ends white, starts blue


def test_render_lut_is_the_plot_colormap():
    """The renders' lookup table (built without matplotlib) is the colormap the plots and docs use."""
    from ipsph.post.render import speed_lut_rgb

    lut = speed_lut_rgb()
    assert lut.shape == (256, 3)
    np.testing.assert_allclose(lut, speed_colormap()(np.linspace(0.0, 1.0, 256))[:, :3], atol=1.0 / 255)


def _assert_framed(bounds, pos, focal, up, w=1280, h=720):
    """Every corner of `bounds` projects inside the frame region: in the image, off the colour bar
    (right of FRAME_RIGHT) and off the time label and title (beyond FRAME_V)."""
    from ipsph.post.render import FRAME_LEFT, FRAME_RIGHT, FRAME_V

    pos, focal, up = map(np.asarray, (pos, focal, up))
    fwd = (focal - pos) / np.linalg.norm(focal - pos)
    right = np.cross(fwd, up)
    tan_v = math.tan(math.radians(15))
    b = np.reshape(bounds, (3, 2))
    for c in np.array([[x, y, z] for x in b[0] for y in b[1] for z in b[2]]):
        rel = c - pos
        depth = rel @ fwd
        assert depth > 0
        assert abs(rel @ up) / depth <= FRAME_V * tan_v + 1e-9  # inside vertically
        u = (rel @ right) / depth / (tan_v * w / h)  # -1 .. 1 across
        assert FRAME_LEFT - 1e-9 <= u <= FRAME_RIGHT + 1e-9  # not under the bar


@pytest.mark.parametrize("view", list(VIEWS))
def test_camera_frames_every_corner(view):
    bounds = (-1.0, 3.0, 0.0, 1.0, -0.5, 0.5)
    _assert_framed(bounds, *camera_for_view(bounds, view, width=1280, height=720))


def test_an_imported_camera_frames_the_whole_domain():
    """SPlisHSPlasH's DoubleDamBreak camera (at (0, 2, 5) looking at the origin) is too close for
    the tank: the view keeps its direction and steps back until nothing is cropped or under the bar."""
    bounds = (-1.55, 1.55, -0.05, 3.05, -1.55, 1.55)  # that scene's domain at t = 0
    pos, focal, up = camera_for_view(bounds, camera_position=(0, 2, 5), focal_point=(0, 0, 0))
    _assert_framed(bounds, pos, focal, up)
    d = np.subtract(pos, focal)
    np.testing.assert_allclose(d / np.linalg.norm(d), np.array([0, 2, 5]) / math.sqrt(29), atol=1e-12)
    assert np.linalg.norm(d) > math.sqrt(29)


def test_camera_explicit_and_bad_view():
    # far enough to see the unit box: the user's camera is kept as given
    pos, focal, up = camera_for_view((0, 1, 0, 1, 0, 1), camera_position=(5, 5, 5), focal_point=(0.5, 0.5, 0.5))
    np.testing.assert_allclose(pos, (5, 5, 5), atol=1e-12)
    np.testing.assert_allclose(focal, (0.5, 0.5, 0.5), atol=1e-12)
    assert up == pytest.approx((0, 1, 0), abs=0.5)  # y stays up (orthogonalised against the view)
    _, _, up = camera_for_view((0, 1, 0, 1, 0, 1), camera_position=(0, 5, 0), focal_point=(0, 0, 0))
    np.testing.assert_allclose(np.abs(up), (0, 0, 1), atol=1e-12)  # looking straight down: y cannot be up
    with pytest.raises(ConfigError, match="front"):
        camera_for_view((0, 1, 0, 1, 0, 1), "diagonal")


@pytest.mark.parametrize("shape", [(1, 1), (7, 13), (180, 320)])
def test_png_encoder_round_trips_exactly(shape):
    """ipsph.post.render.splat.encode_png (Up filter + zlib, hand-rolled for speed) is a valid PNG that Pillow
    decodes to the very same pixels: random noise and a smooth gradient with flat rows."""
    import io

    from PIL import Image

    from ipsph.post.render.splat import encode_png

    h, w = shape
    rng = np.random.default_rng(1)
    noise = rng.integers(0, 256, (h, w, 3), dtype=np.uint8)
    ramp = np.broadcast_to(np.linspace(0, 255, h, dtype=np.uint8)[:, None, None], (h, w, 3))
    for img in (noise, ramp):
        back = np.asarray(Image.open(io.BytesIO(encode_png(img))))
        assert back.shape == (h, w, 3)
        np.testing.assert_array_equal(back, img)
    with pytest.raises(ValueError, match="h, w, 3"):
        encode_png(np.zeros((4, 4), np.uint8))


def test_render_output_refuses_a_non_output_folder(tmp_path):
    with pytest.raises(OutputError, match="run.pvd"):
        render_output(tmp_path)


# --- GL -----------------------------------------------------------------------------------------


def _png(path):
    import imageio.v2 as imageio

    return imageio.imread(path)[..., :3].astype(np.int32)


def test_frame_renders_and_is_not_uniform(gl, tmp_path):
    from ipsph.post.render import FrameRenderer

    rng = np.random.default_rng(0)
    pts = rng.random((2000, 3))
    with FrameRenderer(SMALL, (0, 1, 0, 1, 0, 1), 0.01, (0.0, 1.0), None) as fr:
        out = fr.render(pts, rng.random((2000, 3)), tmp_path / "sub" / "a.png", time=0.5)
    img = _png(out)
    assert img.shape == (180, 320, 3)
    assert img.std() > 10  # background gradient + particles + text, not a blank frame


def test_faster_particles_are_lighter(gl, tmp_path):
    """A row of particles along x, speed rising with x, seen from the front: the pixel at each
    particle's projected centre gets lighter with speed (the splat centre faces the viewer, so its
    shading is the same for all; only the colour map changes)."""
    from vtkmodules.vtkRenderingCore import vtkCoordinate

    from ipsph.post.render import FrameRenderer

    x = np.linspace(0.05, 0.95, 12)
    pts = np.c_[x, np.full_like(x, 0.5), np.zeros_like(x)]
    vel = np.c_[2.0 * x, np.zeros_like(x), np.zeros_like(x)]
    cfg = RenderConfig(width=640, height=360, view="front")
    with FrameRenderer(cfg, (0, 1, 0.45, 0.55, -0.05, 0.05), 0.02, (0.0, 2.0), None) as fr:
        png = fr.render(pts, vel, tmp_path / "row.png")
        coord = vtkCoordinate()
        coord.SetCoordinateSystemToWorld()
        centres = []
        for p in pts:
            coord.SetValue(*p)
            centres.append(coord.GetComputedDisplayValue(fr.renderer))
    img = _png(png)
    lum = np.array([img[cfg.height - 1 - cy, cx] @ [0.2126, 0.7152, 0.0722] for cx, cy in centres])
    # 3 levels of 8-bit slack for rasterisation at the exact centre pixel
    assert np.all(np.diff(lum) > -3), lum
    assert lum[-1] - lum[0] > 120, lum  # dark blue vs white


def test_same_frame_twice_gives_identical_pixels(gl, tmp_path):
    import pyvista as pv

    from ipsph.post.render import FrameRenderer

    rng = np.random.default_rng(3)
    pts, vel = rng.random((3000, 3)), rng.random((3000, 3))
    surface = pv.Box(bounds=(0, 1, 0, 1, 0, 1)).triangulate()
    with FrameRenderer(SMALL, (0, 1, 0, 1, 0, 1), 0.01, (0, 1.5), surface) as fr:
        a = _png(fr.render(pts, vel, tmp_path / "a.png", time=0.1))
        fr.render(rng.random((500, 3)), rng.random((500, 3)), tmp_path / "other.png")  # different N between
        b = _png(fr.render(pts, vel, tmp_path / "b.png", time=0.1))
    np.testing.assert_array_equal(a, b)


def test_render_output_writes_pngs_and_videos(gl, tmp_path):
    import imageio.v2 as imageio

    out = make_output_folder(tmp_path / "out", n_frames=3)
    written = render_output(out, video="mp4")
    pngs = sorted((out / "renders").glob("frame_*.png"))
    assert [p.name for p in pngs] == ["frame_000000.png", "frame_000001.png", "frame_000002.png"]
    assert written[:3] == pngs and written[-1] == out / "video.mp4"
    assert _png(pngs[0]).shape == (180, 320, 3)  # size from run.json's render settings
    with imageio.get_reader(out / "video.mp4") as rd:
        assert rd.count_frames() == 3

    gif = make_video(pngs, out / "video.gif", fps=10)
    frames = imageio.mimread(gif)
    assert len(frames) == 3 and frames[0].shape[:2] == (180, 320)

    # overrides and a frame subset: iso view, only the last frame
    written = render_output(
        out, frames=slice(-1, None), config_overrides={"view": "iso", "width": 161, "height": 91}, video="mp4"
    )
    assert _png(written[0]).shape == (91, 161, 3)
    with imageio.get_reader(out / "video.mp4") as rd:  # odd size padded to even for yuv420p
        assert rd.count_frames() == 1
    with pytest.raises(ConfigError, match="width"):
        render_output(out, config_overrides={"widht": 10})


def test_render_output_on_a_running_folder(gl, tmp_path):
    """A run still going: the .pvd lists the frames so far; stats.csv has a torn last line."""
    out = make_output_folder(tmp_path / "out", n_frames=2)
    with open(out / "stats.csv", "a") as f:
        f.write("3,0.2")
    (out / "run.json").unlink()  # written late by some runners: fall back to the data
    written = render_output(out)
    assert len(written) == 2 and all(p.stat().st_size > 0 for p in written)


def test_splat_engine_matches_the_all_vtk_render(gl, tmp_path):
    """The splat engine (particles rasterised over layers VTK drew once) against the reference, the
    same frame drawn wholly by VTK (vtkPointGaussianMapper impostors): a container, an obstacle
    box with particles inside, behind and in front of it, and particles outside the frame.

    Tolerances: sprite rims differ by the two rasterisers' pixel-coverage rules (one pixel ring per
    sprite) and VTK's light kit scales the shade by ~2 %; so the mean absolute difference must stay
    under 4 of 255 and under 3 % of pixels may differ by more than 40 per channel on average. A
    splat engine that dropped the wall tint, the depth order or the overlays breaks these bounds
    (each of those alone moves > 3 % of pixels here)."""
    import pyvista as pv

    from ipsph.post.render import FrameRenderer

    rng = np.random.default_rng(7)
    pts = rng.uniform((-0.1, 0.0, -0.1), (1.1, 1.0, 1.1), (2500, 3))
    vel = rng.normal(0.0, 0.8, (2500, 3))
    walls = (
        pv.Box(bounds=(0, 1, 0, 1, 0, 1)).triangulate() + pv.Box(bounds=(0.3, 0.7, 0.2, 0.6, 0.3, 0.7)).triangulate()
    )
    cfg = RenderConfig(width=480, height=270, view="iso")
    imgs = {}
    for engine in ("splat", "vtk"):
        with FrameRenderer(cfg, (0, 1, 0, 1, 0, 1), 0.015, (0.0, 2.0), walls, title="t", engine=engine) as fr:
            imgs[engine] = _png(fr.render(pts, vel, tmp_path / f"{engine}.png", time=0.25))
    diff = np.abs(imgs["splat"] - imgs["vtk"])
    assert diff.mean() < 4.0, diff.mean()
    assert (diff.mean(axis=2) > 40).mean() < 0.03, (diff.mean(axis=2) > 40).mean()


@pytest.mark.slow
def test_run_without_gl_warns_once_and_keeps_the_simulation(tmp_path):
    """No usable GL (libglvnd pointed at no EGL vendor): the render process crashes, the run goes
    on, writes its frames, and says why in one warning line; no PNG appears."""
    import os
    import subprocess
    import sys

    env = dict(os.environ, __EGL_VENDOR_LIBRARY_FILENAMES=str(tmp_path / "no-such-vendor.json"))
    probe = subprocess.run(
        [sys.executable, "-c", "from ipsph.post.render import gl_available; print(gl_available()[0])"],
        env=env,
        capture_output=True,
        text=True,
        timeout=120,
    )
    if probe.stdout.strip() != "False":
        pytest.skip("this machine's GL does not go through libglvnd's EGL vendor files; cannot take GL away")
    out = tmp_path / "out"
    res = subprocess.run(
        [
            sys.executable,
            "-m",
            "ipsph",
            "run",
            "-o",
            str(out),
            "--end-time",
            "0.08",
            "--set",
            "simulation.particle_radius=0.04",
        ],
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert res.returncode == 0, res.stderr
    # one line about the renders (the solver may add its own: at r = 0.04 the full-mass column's
    # corners pop at t = 0 and a solve can stop at its cap, docs/method.md section 1)
    warnings = [ln for ln in res.stderr.splitlines() if ln.startswith("ipsph: warning") and "render" in ln]
    assert len(warnings) == 1 and "renders skipped" in warnings[0] and "GL" in warnings[0], res.stderr
    assert len(list((out / "frames").glob("fluid_*.vtu"))) == 3
    assert not list(out.glob("renders/*.png"))
