"""The paper's Figure 4: the breaking dam, IPSPH beside PF at the same simulated times.

    python -m benchmarks figure4 OUT [--end-time T]

Runs pipelines/breaking_dam.toml with IPSPH and with PF (same scene, radius, time-step
settings and colour range), then writes OUT/figure4_t<time>.png (IPSPH left, PF right) for a few
common frame times and OUT/plots/ (density error, divergence error and iterations against time,
both runs overlaid). Prints the run-mean density error of both.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np

from ipsph.bench.scenes import pipeline_path

SNAPSHOT_FRACTIONS = (0.25, 0.5, 0.75, 1.0)


def _run(method: str, out: Path, end_time: float, threads: int, extra: list[str]) -> None:
    cmd = [
        sys.executable,
        "-m",
        "ipsph",
        "run",
        str(pipeline_path("breaking_dam")),
        "--method",
        method,
        "-o",
        str(out),
        "--end-time",
        str(end_time),
        "--overwrite",
        "--quiet",
        "--threads",
        str(threads),
        *sum((["--set", s] for s in extra), []),
    ]
    res = subprocess.run(cmd, capture_output=True, text=True)
    if res.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} failed ({res.returncode}): {res.stderr.strip()[-2000:]}")


def _side_by_side(left: Path, right: Path, out: Path, labels=("IPSPH", "PF")) -> Path:
    from PIL import Image, ImageDraw

    a, b = Image.open(left).convert("RGB"), Image.open(right).convert("RGB")
    canvas = Image.new("RGB", (a.width + b.width, max(a.height, b.height)))
    canvas.paste(a, (0, 0))
    canvas.paste(b, (a.width, 0))
    draw = ImageDraw.Draw(canvas)
    for x, text in ((a.width // 2, labels[0]), (a.width + b.width // 2, labels[1])):
        draw.text((x - 20, 8), text, fill=(255, 255, 255))
    canvas.save(out)
    return out


def figure4(out_dir: Path, end_time: float = 2.0, threads: int = 2, extra: list[str] | None = None) -> dict:
    from ipsph.io.provenance import read_run_json
    from ipsph.io.pvd import PvdSeries
    from ipsph.io.stats import read_stats
    from ipsph.post.plots import plot_runs

    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    runs = {m: out_dir / m for m in ("ipsph", "pf")}
    for method, folder in runs.items():
        _run(method, folder, end_time, threads, extra or [])
    series = {m: PvdSeries.load(f / "run.pvd") for m, f in runs.items()}
    times = series["ipsph"].times
    written = []
    for frac in SNAPSHOT_FRACTIONS:
        k = int(round(frac * (len(times) - 1)))
        t = times[k]
        pngs = [runs[m] / "renders" / f"frame_{k:06d}.png" for m in ("ipsph", "pf")]
        if all(p.exists() for p in pngs) and abs(series["pf"].times[k] - t) < 1e-9:
            written.append(_side_by_side(pngs[0], pngs[1], out_dir / f"figure4_t{t:.2f}.png"))
    written += plot_runs([runs["ipsph"], runs["pf"]], out_dir / "plots")
    summary = {}
    for m, folder in runs.items():
        st = read_stats(folder / "stats.csv")
        run = read_run_json(folder / "run.json")
        summary[m] = {
            "density_error_mean_pct": float(np.mean(st["density_error_mean_pct"])),
            "density_error_worst_pct": float(np.max(st["density_error_mean_pct"])),
            "steps": int(run["steps"]),
            "wall_seconds": float(run["wall_seconds"]),
            "fluid_particles": int(run["fluid_particles"]),
        }
    summary["files"] = [str(p) for p in written]
    return summary


def print_summary(summary: dict) -> None:
    print("| method | fluid | steps | wall s | density error mean % | worst step % |")
    print("|---|---:|---:|---:|---:|---:|")
    for m in ("ipsph", "pf"):
        s = summary[m]
        print(
            f"| {m.upper()} | {s['fluid_particles']:,} | {s['steps']} | {s['wall_seconds']:.1f} | "
            f"{s['density_error_mean_pct']:.4f} | {s['density_error_worst_pct']:.4f} |"
        )
    for f in summary["files"]:
        print(f)
