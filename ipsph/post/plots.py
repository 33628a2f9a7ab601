"""Matplotlib plots of one or several runs' stats.csv (Agg backend, no display needed).

errors_iterations.png: density error (mean, max) [%], divergence error [%] and solver iterations
against simulated time, three stacked panels, runs overlaid. timings.png: median ms per step
phase per run, grouped bars. Legend: run folder name + method (from run.json).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import OutputError
from ..io import PLOTS_DIR, RUN_JSON, STATS_CSV
from ..params import PHASES as _PHASES

__all__ = ["plot_runs", "PHASES"]

# stats.csv timing columns -> bar labels (the paper's phase names, ipsph.params.PHASES)
PHASES = {**{f"ms_{p}": p for p in _PHASES}, "ms_step": "whole step"}


def _label(out: Path) -> str:
    from ..io.provenance import read_run_json

    method = None
    if (out / RUN_JSON).is_file():
        try:
            method = read_run_json(out / RUN_JSON).get("method")
        except OutputError:
            method = None
    name = out.resolve().name
    return f"{name} ({method})" if method else name


def _column(stats: dict, name: str) -> np.ndarray:
    n = len(stats.get("step", ()))
    return stats.get(name, np.full(n, np.nan))


def plot_runs(out_dirs, output_dir: Path | None = None, *, dpi: int = 110) -> list[Path]:
    """Plot the runs in `out_dirs`; write PNGs to `output_dir` (default: first folder's plots/)."""
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    from ..io.stats import read_stats

    dirs = [Path(d) for d in ([out_dirs] if isinstance(out_dirs, (str, Path)) else out_dirs)]
    if not dirs:
        raise OutputError("plot_runs needs at least one output folder")
    runs = []
    for d in dirs:
        if not (d / STATS_CSV).is_file():
            raise OutputError(f"{d} (resolved {d.resolve()}) has no {STATS_CSV}; give a folder written by `ipsph run`")
        runs.append((_label(d), read_stats(d / STATS_CSV)))
    target = Path(output_dir) if output_dir is not None else dirs[0] / PLOTS_DIR
    target.mkdir(parents=True, exist_ok=True)
    colours = plt.get_cmap("tab10").colors
    written = []

    fig, axes = plt.subplots(3, 1, figsize=(9, 8.5), sharex=True, constrained_layout=True)
    for k, (label, s) in enumerate(runs):
        c = colours[k % len(colours)]
        t = _column(s, "time")
        axes[0].plot(t, _column(s, "density_error_mean_pct"), color=c, lw=1.3, label=f"{label}: mean")
        axes[0].plot(t, _column(s, "density_error_max_pct"), color=c, lw=0.9, ls="--", label=f"{label}: max")
        axes[1].plot(t, _column(s, "divergence_error_pct"), color=c, lw=1.3, label=label)
        for col, ls, what in (
            ("pd_passes", "-", "PD passes"),
            ("divergence_iterations", "--", "divergence it."),
            ("density_iterations", ":", "density it."),
        ):
            y = _column(s, col)
            if np.any(np.nan_to_num(y) > 0):
                axes[2].step(t, y, where="post", color=c, ls=ls, lw=1.1, label=f"{label}: {what}")
    axes[0].set_ylabel("density error [%]")
    axes[1].set_ylabel("divergence error [%]")
    axes[2].set_ylabel("iterations per step")
    axes[2].set_xlabel("time [s]")
    axes[0].set_title("Density error, divergence error and solver iterations")
    for ax in axes:
        ax.grid(True, alpha=0.3)
        if ax.get_legend_handles_labels()[0]:
            ax.legend(fontsize=8, loc="upper right")
    p = target / "errors_iterations.png"
    fig.savefig(p, dpi=dpi)
    plt.close(fig)
    written.append(p)

    # only the phases some run's method has (older stats.csv files hold 0 ms for the others)
    phases = [ph for ph in PHASES if any(np.any(np.nan_to_num(_column(s, ph)) > 0) for _, s in runs)]
    fig, ax = plt.subplots(figsize=(9, 4.5), constrained_layout=True)
    width = 0.8 / len(runs)
    x = np.arange(len(phases))
    for k, (label, s) in enumerate(runs):
        med = [float(np.nanmedian(_column(s, ph))) if np.any(np.isfinite(_column(s, ph))) else 0.0 for ph in phases]
        bars = ax.bar(x + (k - (len(runs) - 1) / 2) * width, med, width, label=label, color=colours[k % len(colours)])
        ax.bar_label(bars, fmt="%.1f", fontsize=7, padding=1)
    ax.set_xticks(x, [PHASES[ph] for ph in phases], rotation=15)
    ax.set_ylabel("median time per step [ms]")
    ax.set_title("Time per step by phase")
    ax.grid(True, axis="y", alpha=0.3)
    ax.legend(fontsize=8)
    p = target / "timings.png"
    fig.savefig(p, dpi=dpi)
    plt.close(fig)
    written.append(p)
    return written
