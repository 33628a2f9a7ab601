"""What ten every-step gauges cost the default dam break (`python -m benchmarks gauge-overhead`):
`ipsph run --no-render` of the default scene without and with them, alternating in fresh processes,
median of pair ratios (benchmarks.overhead)."""

from __future__ import annotations

import json
import statistics
from pathlib import Path

from . import overhead

TARGET = 0.03  # issue 42: ten gauges sampled after every step may slow the default run by at most 3 %

# four point gauges (in the column, at the floor ahead of it, at the far wall), three level gauges,
# two flow rectangles across the tank and the tank's force: every kind, each sampled after every step
_POINTS = {
    "column_low": (0.3, 0.1, 0.3),
    "column_mid": (0.3, 0.4, 0.3),
    "floor": (1.0, 0.05, 0.3),
    "far_wall": (1.5, 0.1, 0.3),
}
_LEVELS = {"level_column": 0.3, "level_middle": 1.0, "level_far": 1.5}  # x of each line, z = 0.3, y 0 to 1.2
_FLOWS = {"flow_a": 0.8, "flow_b": 1.2}  # x of each section across the tank
_vec = lambda v: "[" + ", ".join(f"{c:g}" for c in v) + "]"  # noqa: E731
TEN_GAUGES = "".join(
    [f'\n[[gauge]]\nname = "{n}"\nkind = "point"\nposition = {_vec(p)}\n' for n, p in _POINTS.items()]
    + [
        f'\n[[gauge]]\nname = "{n}"\nkind = "level"\nposition = [{x:g}, 0, 0.3]\ntop = 1.2\n'
        for n, x in _LEVELS.items()
    ]
    + [
        f'\n[[gauge]]\nname = "{n}"\nkind = "flow"\nmin = [{x:g}, 0, 0]\nmax = [{x:g}, 1.2, 0.6]\n'
        for n, x in _FLOWS.items()
    ]
    + ['\n[[gauge]]\nname = "tank"\nkind = "force"\nwall = "tank"\n']
)


def gauge_scene(folder: Path, gauges: bool) -> Path:
    """The default scene, with TEN_GAUGES appended when `gauges`, written into `folder`."""
    from ipsph.scene import default_scene_path

    path = Path(folder) / ("gauges.toml" if gauges else "plain.toml")
    path.write_text(default_scene_path().read_text() + (TEN_GAUGES if gauges else ""))
    return path


def _one_run(gauges: bool, threads: int, tmp: Path, k: int, timeout: float) -> dict:
    out = tmp / f"out-{'gauges' if gauges else 'plain'}-{k}"
    scene = gauge_scene(tmp, gauges)
    row = overhead.default_run(
        [str(scene), "--no-render"],
        out,
        threads,
        timeout,
        lambda r, o: (o / "gauges.csv").is_file() if gauges else True,
    )
    info = out / "run.json"  # the stepping alone (sampling included; setup and the end's plot not)
    split = json.loads(info.read_text()).get("time_split_seconds", {}) if info.is_file() else {}
    return {"gauges": gauges, **row, "stepping_seconds": split.get("stepping", float("nan"))}


def gauge_overhead(repeats: int, threads: int, max_load: float, timeout: float = 900.0, log=print) -> dict:
    """`ipsph run` (default scene, --no-render) without and with ten every-step gauges, alternating;
    also the median ratio of the stepping alone (run.json's time split: setup, placement check and
    the end's plots/gauges.png left out)."""
    s = overhead.alternating_pairs(
        lambda on, tmp, k: _one_run(on, threads, tmp, k, timeout),
        "gauges",
        repeats,
        max_load,
        lambda r: f"ten every-step gauges, stepping {r['stepping_seconds']:.2f} s",
        log,
    )
    good = [p for p in s["pairs"] if not p["loaded"] and p["plain"]["ok"] and p["gauges"]["ok"]]
    ratios = [p["gauges"]["stepping_seconds"] / p["plain"]["stepping_seconds"] for p in good]
    s["stepping_ratio_median"] = statistics.median(ratios) if ratios else float("nan")
    s["plain_stepping"] = statistics.median([p["plain"]["stepping_seconds"] for p in good]) if good else float("nan")
    return s


def overhead_table(s: dict, markdown: bool) -> str:
    text = overhead.table(s, "gauges", "without gauges", "with ten every-step gauges", markdown, target=TARGET)
    met = "met" if s["stepping_ratio_median"] <= 1 + TARGET else "NOT met"
    return text + (
        f"; the stepping alone (sampling included, {s['plain_stepping']:.2f} s without gauges): "
        f"x{s['stepping_ratio_median']:.3f} (median of pair ratios; target <= x{1 + TARGET:.2f}: {met})"
    )
