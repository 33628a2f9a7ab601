"""OUT/sweep.json and OUT/summary.csv: what the sweep is and how far it got, rewritten atomically.

OUT/sweep.json     the resolved sweep (sweep file, base scene, [set], [grid], [zip]) and per
                   member: name, folder, parameters, status (pending | running | completed |
                   failed | interrupted), exit code, reason, wall time, threads, host, attempts
OUT/summary.csv    one row per member, columns SUMMARY_COLUMNS then one per varied key,
                   from the member's run.json and stats.csv
OUT/<member>/      everything `ipsph run` writes, plus sweep-member.log (its stderr, per attempt)
"""

from __future__ import annotations

import csv
import io
import json
import math
import time
from pathlib import Path

import numpy as np

from ..io import PLOTS_DIR, RUN_JSON, STATS_CSV, atomic_path
from ..io.provenance import to_jsonable, versions

SWEEP_JSON = "sweep.json"
SUMMARY_CSV = "summary.csv"
FORMAT = 1

# (column, what it is): the one place summary.csv's columns are declared (docs/sweeps.md lists them)
SUMMARY_COLUMNS = (
    ("member", "member folder name"),
    ("status", "completed, failed, interrupted or pending"),
    ("exit_code", "exit code of the member's `ipsph run`"),
    ("method", "simulation.method"),
    ("particle_radius", "simulation.particle_radius [m]"),
    ("fluid_particles", "fluid particles"),
    ("boundary_particles", "boundary particles"),
    ("steps", "time steps taken"),
    ("sim_time", "simulated time reached [s]"),
    ("wall_seconds", "wall time of the simulation loop [s] (run.json; after a resume: the continuation's)"),
    ("wall_per_sim_second", "wall seconds per simulated second"),
    ("density_error_mean_pct", "mean over steps of the mean density error [%]"),
    ("density_error_worst_pct", "largest per-particle density error of any step [%]"),
    ("pd_passes_mean", "mean PF/IPSPH constraint passes per step"),
    ("divergence_iterations_mean", "mean divergence-solve iterations per step"),
    ("density_iterations_mean", "mean DFSPH density-solve iterations per step"),
    ("threads", "Numba threads the member ran with"),
    ("attempts", "times the member was started (more than 1: rerun after a worker died or --resume)"),
)


def write_sweep_json(out: Path, sweep_info: dict, records: list[dict]) -> None:
    data = {
        "format": FORMAT,
        **sweep_info,
        "updated": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
        "counts": counts(records),
        "members": records,
        "versions": versions(),
    }
    text = json.dumps(to_jsonable(data), indent=2, allow_nan=False) + "\n"
    with atomic_path(out / SWEEP_JSON, "sweep record") as tmp:
        tmp.write_text(text)


def read_sweep_json(out: Path) -> dict | None:
    try:
        return json.loads((out / SWEEP_JSON).read_text())
    except (OSError, ValueError):
        return None


def counts(records: list[dict]) -> dict:
    c = {"members": len(records)}
    for r in records:
        c[r["status"]] = c.get(r["status"], 0) + 1
    return c


def _mean(a) -> float:
    a = np.asarray(a, dtype=float)
    return float(np.nanmean(a)) if a.size and np.any(np.isfinite(a)) else math.nan


def member_row(out: Path, rec: dict) -> dict:
    """The summary row of one member, from its record and its folder."""
    from ..io.stats import read_stats

    folder = out / rec["name"]
    row = {
        "member": rec["name"],
        "status": rec["status"],
        "exit_code": rec.get("exit_code"),
        "threads": rec.get("threads"),
        "attempts": rec.get("attempts"),
    }
    try:
        info = json.loads((folder / RUN_JSON).read_text())
    except (OSError, ValueError):
        info = {}
    row.update(
        method=info.get("method"),
        particle_radius=info.get("particle_radius"),
        fluid_particles=info.get("fluid_particles"),
        boundary_particles=info.get("boundary_particles"),
        steps=info.get("steps"),
        sim_time=info.get("sim_time"),
        wall_seconds=info.get("wall_seconds"),
    )
    if row["wall_seconds"] and row["sim_time"]:
        row["wall_per_sim_second"] = row["wall_seconds"] / row["sim_time"]
    try:
        s = read_stats(folder / STATS_CSV)
    except Exception:  # no stats yet (failed before the first step)
        s = {}
    if len(s.get("step", ())):
        row["density_error_mean_pct"] = _mean(s["density_error_mean_pct"])
        worst = np.asarray(s["density_error_max_pct"], dtype=float)
        row["density_error_worst_pct"] = float(np.nanmax(worst)) if np.any(np.isfinite(worst)) else math.nan
        for col in ("pd_passes", "divergence_iterations", "density_iterations"):
            row[f"{col}_mean"] = _mean(s[col])
    return row


def write_summary_csv(out: Path, records: list[dict], varied_keys: list[str], params: dict[str, dict]) -> None:
    """Rewrite OUT/summary.csv: SUMMARY_COLUMNS then the varied keys (their values per member)."""
    cols = [c for c, _ in SUMMARY_COLUMNS] + list(varied_keys)
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=cols, extrasaction="ignore", lineterminator="\n")
    w.writeheader()
    for rec in records:
        row = member_row(out, rec)
        row.update(
            {
                k: json.dumps(v) if isinstance(v, (list, tuple)) else v
                for k, v in params.get(rec["name"], {}).items()
                if k in varied_keys
            }
        )
        w.writerow({k: _cell(row.get(k)) for k in cols})
    with atomic_path(out / SUMMARY_CSV, "sweep summary") as tmp:
        tmp.write_text(buf.getvalue())


def _cell(v):
    if v is None:
        return ""
    if isinstance(v, float):
        return "" if not math.isfinite(v) else f"{v:.6g}"
    return v


def plot_folders(dirs: list[Path], output: Path | None) -> tuple[list[Path], Path | None]:
    """`ipsph plot` arguments with each sweep folder replaced by its members that have stats.csv
    (in sweep order); the plots of a lone sweep folder go to OUT/plots."""
    from ..errors import OutputError

    expanded, target = [], output
    for d in map(Path, dirs):
        info = read_sweep_json(d) if (d / SWEEP_JSON).is_file() else None
        if info is None:
            expanded.append(d)
            continue
        members = [d / r["name"] for r in info.get("members", []) if (d / r["name"] / STATS_CSV).is_file()]
        if not members:
            raise OutputError(f"sweep folder {d} (resolved {d.resolve()}) has no member with {STATS_CSV} yet")
        expanded += members
        if target is None and len(dirs) == 1:
            target = d / PLOTS_DIR
    return expanded, target


def summary_columns_markdown() -> str:
    """The summary.csv column table of docs/sweeps.md (generated: `python -m ipsph.sweeps`)."""
    rows = [f"| `{c}` | {doc} |" for c, doc in SUMMARY_COLUMNS]
    rows.append("| *one per varied key* | its value for the member (`simulation.method`, ...), lists as JSON |")
    return "| column | meaning |\n|---|---|\n" + "\n".join(rows) + "\n"
