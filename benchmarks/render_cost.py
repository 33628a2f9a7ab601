"""What renders cost (issue 4).

    python -m benchmarks render-sizes 100000 1000000   # seconds per 1280x720 frame at N particles
    python -m benchmarks render-overhead --repeats 5   # the default scene's `ipsph run`, with and without renders

Per frame: a cubic block of N particles (a lattice at r = 0.01 m with a shear velocity field, so the
colour map is exercised) inside a translucent box, rendered at the default 1280x720 by the
FrameRenderer `ipsph run` uses (the splat engine: particles rasterised over static layers VTK drew
once), split into drawing and PNG encoding; beside it the all-VTK engine (vtkPointGaussianMapper
sprites) on the same frame, for reference.

Overhead: `ipsph run` of the built-in default scene in fresh processes, alternating --no-render and
renders (the render process beside the solver), R times each; medians of wall time and their ratio,
the figure the issue's "renders slow the default run by at most 25 %" is about. A pair during which
other processes kept more than --max-load cores busy is shown as loaded and left out of the medians.
"""

from __future__ import annotations

import statistics
import tempfile
import time
from pathlib import Path

import numpy as np

from . import overhead


def _block(n: int):
    from ipsph.geometry.meshes import box_mesh
    from ipsph.params import spacing

    r = 0.01
    side = max(int(round(n ** (1 / 3))), 1)
    g = (np.arange(side) + 1.0) * spacing(r)
    X, Y, Z = np.meshgrid(g, g, g, indexing="ij")
    pts = np.stack([X.ravel(), Y.ravel(), Z.ravel()], axis=1)
    ext = (side + 1) * spacing(r)
    vel = np.zeros_like(pts)
    vel[:, 0] = 3.0 * pts[:, 1] / ext
    return pts, vel, r, [0.0, ext, 0.0, ext, 0.0, ext], box_mesh((0.0, 0.0, 0.0), (ext, ext, ext))


def render_cost(n: int, frames: int = 3) -> dict:
    """Median seconds per frame at ~n particles: splat engine (draw, PNG) and the all-VTK engine."""
    from ipsph.config import RenderConfig
    from ipsph.post.render import FrameRenderer, gl_available, save_png

    ok, why = gl_available()
    if not ok:
        return {"particles": n, "error": why}
    pts, vel, r, bounds, surface = _block(n)
    row: dict = {"particles": len(pts), "frames": frames}
    with tempfile.TemporaryDirectory() as tmp:
        for engine in ("splat", "vtk"):
            draw, png = [], []
            with FrameRenderer(RenderConfig(view="iso"), bounds, r, (0.0, 3.0), surface, engine=engine) as fr:
                fr.render(pts, vel, Path(tmp) / "warm.png", time=0.0)  # static layers, JIT, GL warm-up
                for k in range(frames):
                    t0 = time.perf_counter()
                    img = fr.image(pts, vel, time=float(k))
                    t1 = time.perf_counter()
                    save_png(img, Path(tmp) / f"f{k}.png")
                    draw.append(t1 - t0)
                    png.append(time.perf_counter() - t1)
            row[engine] = {
                "seconds_per_frame": statistics.median(a + b for a, b in zip(draw, png)),
                "draw_seconds": statistics.median(draw),
                "png_seconds": statistics.median(png),
            }
    row["seconds_per_frame"] = row["splat"]["seconds_per_frame"]
    return row


def table(rows: list[dict], markdown: bool) -> str:
    head = ["particles", "s / frame", "draw s", "PNG s", "all-VTK s / frame", "speed-up"]
    lines = []
    if markdown:
        lines += ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    else:
        lines.append("  ".join(f"{h:>17s}" for h in head))
    for r in rows:
        if r.get("error"):
            cells = [f"{r['particles']:,}", "skipped: " + r["error"]] + [""] * 4
        else:
            s, v = r["splat"], r["vtk"]
            cells = [
                f"{r['particles']:,}",
                f"{s['seconds_per_frame']:.3f}",
                f"{s['draw_seconds']:.3f}",
                f"{s['png_seconds']:.3f}",
                f"{v['seconds_per_frame']:.3f}",
                f"{v['seconds_per_frame'] / s['seconds_per_frame']:.1f}x",
            ]
        lines.append(("| " + " | ".join(cells) + " |") if markdown else "  ".join(f"{c:>17s}" for c in cells))
    return "\n".join(lines)


def _one_run(render: bool, threads: int, tmp: Path, k: int, timeout: float) -> dict:
    out = tmp / f"out-{'render' if render else 'plain'}-{k}"
    row = overhead.default_run(
        [] if render else ["--no-render"],
        out,
        threads,
        timeout,
        lambda r, _: r["pngs"] == r["frames"] if render else True,
    )
    return {"render": render, **row}


def render_overhead(repeats: int, threads: int, max_load: float, timeout: float = 900.0, log=print) -> dict:
    """`ipsph run` (default scene) without and with renders, alternating, `repeats` pairs."""
    return overhead.alternating_pairs(
        lambda on, tmp, k: _one_run(on, threads, tmp, k, timeout),
        "render",
        repeats,
        max_load,
        lambda r: f"renders, {r['pngs']} PNGs",
        log,
    )


def overhead_table(s: dict, markdown: bool) -> str:
    return overhead.table(s, "render", "without renders (--no-render)", "with renders", markdown)
