"""Per-frame render cost at a given particle count (issue 4): `ipsph bench --render-sizes 100000 1000000`.

A cubic block of N particles (a lattice at r = 0.01 m with a shear velocity field, so the colour
map is exercised) inside a translucent box, rendered at the default 1280x720 with the same
FrameRenderer `ipsph run` uses; the median over a few frames of draw + PNG encode, and each part.
"""
from __future__ import annotations

import statistics
import tempfile
import time
from pathlib import Path

import numpy as np


def render_cost(n: int, frames: int = 3) -> dict:
    from ..meshes import box_mesh
    from ..model import RenderConfig
    from ..render import FrameRenderer, _save_png, gl_available
    ok, why = gl_available()
    if not ok:
        return {"particles": n, "error": why}
    r = 0.01
    side = max(int(round(n ** (1 / 3))), 1)
    g = (np.arange(side) + 1.0) * 2 * r
    X, Y, Z = np.meshgrid(g, g, g, indexing="ij")
    pts = np.stack([X.ravel(), Y.ravel(), Z.ravel()], axis=1)
    ext = (side + 1) * 2 * r
    vel = np.zeros_like(pts)
    vel[:, 0] = 3.0 * pts[:, 1] / ext
    bounds = [0.0, ext, 0.0, ext, 0.0, ext]
    surface = box_mesh((0.0, 0.0, 0.0), (ext, ext, ext))
    draw, png = [], []
    with tempfile.TemporaryDirectory() as tmp, \
            FrameRenderer(RenderConfig(view="iso"), bounds, r, (0.0, 3.0), surface) as fr:
        fr.render(pts, vel, Path(tmp) / "warm.png")
        for k in range(frames):
            t0 = time.perf_counter()
            fr._set_particles(pts, np.linalg.norm(vel, axis=1))
            fr.plotter.render()
            img = fr.plotter.screenshot(return_img=True)
            t1 = time.perf_counter()
            _save_png(img, Path(tmp) / f"f{k}.png")
            t2 = time.perf_counter()
            draw.append(t1 - t0)
            png.append(t2 - t1)
    total = [a + b for a, b in zip(draw, png)]
    return {"particles": len(pts), "frames": frames, "seconds_per_frame": statistics.median(total),
            "draw_seconds": statistics.median(draw), "png_seconds": statistics.median(png)}


def table(rows: list[dict], markdown: bool) -> str:
    head = ["particles", "s / frame (median)", "draw + screenshot s", "PNG encode s"]
    lines = []
    if markdown:
        lines += ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    else:
        lines.append("  ".join(f"{h:>20s}" for h in head))
    for r in rows:
        if r.get("error"):
            cells = [f"{r['particles']:,}", "skipped: " + r["error"], "", ""]
        else:
            cells = [f"{r['particles']:,}", f"{r['seconds_per_frame']:.2f}", f"{r['draw_seconds']:.2f}",
                     f"{r['png_seconds']:.2f}"]
        lines.append(("| " + " | ".join(cells) + " |") if markdown else "  ".join(f"{c:>20s}" for c in cells))
    return "\n".join(lines)
