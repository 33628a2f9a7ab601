"""plots/gauges.png: every gauge's series against time, one panel per gauge and unit (Agg backend)."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from .log import read_gauges

_HEADER = re.compile(r"^(?P<name>.*?)\s*\[(?P<unit>[^\]]*)\]\s*$")


def _panels(headers: list[str]) -> dict[tuple[str, str], list[str]]:
    """(gauge, unit) -> the headers of its columns, in file order (time left out)."""
    out: dict[tuple[str, str], list[str]] = {}
    for h in headers[1:]:
        m = _HEADER.match(h)
        name, unit = (m["name"], m["unit"]) if m else (h, "")
        out.setdefault((name.split(".", 1)[0], unit), []).append(h)
    return out


def plot_gauges(csv_path, png_path, *, under=None, dpi: int = 110, title: str | None = None) -> Path:
    """Plot gauges.csv (or the CSV `ipsph gauge` writes) into `png_path`; returns the path. `under`:
    another gauges CSV (the run's, under `ipsph gauge`'s) whose columns of the same name are drawn
    beneath, thin and grey, so the frames' samples show against every step's."""
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    data = read_gauges(csv_path, units=True)
    below = read_gauges(under, units=True) if under is not None and Path(under).is_file() else {}
    headers = list(data)
    t = data[headers[0]]
    panels = _panels(headers)
    n = max(len(panels), 1)
    height = min(2.2 * n + 0.8, 24)
    fig, axes = plt.subplots(n, 1, figsize=(9, height), sharex=True, squeeze=False)
    # fixed margins in inches (constrained_layout took 1/3 of the plot's time on 19 panels)
    fig.subplots_adjust(left=1.2 / 9, right=1 - 0.15 / 9, top=1 - 0.35 / height, bottom=0.5 / height, hspace=0.12)
    for ax, ((gauge, unit), cols) in zip(axes[:, 0], panels.items()):
        for h in cols:
            y = data[h]
            ok = np.isfinite(y)
            label = _HEADER.match(h)["name"].split(".", 1)[-1] if _HEADER.match(h) else h
            if h in below:
                yb, tb = below[h], below[headers[0]]
                fine = np.isfinite(yb)
                ax.plot(tb[fine], yb[fine], lw=0.7, color="0.6", label=f"{label}, every step", zorder=1)
                label += ", at the frames"
            ax.plot(t[ok], y[ok], lw=1.0, marker="." if ok.sum() < 60 or below else None, ms=4, label=label)
        ax.set_ylabel(f"{gauge} [{unit}]" if unit else gauge, fontsize=8)
        ax.grid(True, alpha=0.3)
        if len(cols) > 1 or below:
            ax.legend(fontsize=7, loc="upper right", ncols=min(len(cols), 3))
    axes[-1, 0].set_xlabel("time [s]")
    axes[0, 0].set_title(title or f"Gauges: {Path(csv_path).name}")
    png_path = Path(png_path)
    png_path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(png_path, dpi=dpi)
    plt.close(fig)
    return png_path
