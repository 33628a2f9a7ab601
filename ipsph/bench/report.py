"""Benchmark results -> rows -> medians of quiet runs -> text or Markdown tables.

Every run (ours or SPlisHSPlasH) is first flattened by :func:`normalise` into one row with the same
keys, so the tables never care where a number came from. A run is *loaded* when other processes
used more than ``max_load`` cores on average while it ran (``others_busy_mean * cpus``, from
:class:`ipsph.bench.machine.LoadSampler`; our own worker's threads are not counted, so this is
"mean load > threads + max_load" without the 1-minute lag of the load average). Loaded runs are
printed, marked, and left out of the medians.

The tables of one mode sit beside it: `scaling.py` (--scaling), `first_frame.py` (--first-frame).
"""

from __future__ import annotations

import math
from collections import OrderedDict

from ..params import PHASES

__all__ = [
    "LABELS",
    "normalise",
    "is_loaded",
    "summarise",
    "format_table",
    "fmt_num",
    "fmt_int",
    "scene_tables",
    "ratio_lines",
    "PEER_PAIRS",
    "PHASE_SHORT",
]

LABELS = {
    ("ours", "ipsph"): "IPSPH",
    ("ours", "pf"): "PF",
    ("ours", "dfsph"): "DFSPH",
    ("peer", "dfsph"): "SPH-DFSPH",
    ("peer", "pf"): "SPH-PF",
}
# the ratio lines under a scene's table: (ours, theirs) by label, where both ran
PEER_PAIRS = (("IPSPH", "SPH-DFSPH"), ("IPSPH", "SPH-PF"))
# per-phase column: our timer name -> short label, in print order
PHASE_SHORT = OrderedDict((p, short) for p, (short, _) in PHASES.items())
NUMERIC = (
    "fluid",
    "boundary",
    "steps",
    "ms_step",
    "ms_step_mean",
    "wall_per_sim",
    "wall_seconds",
    "err_mean",
    "err_worst",
    "err_max",
    "rss_mb",
    "others_cores",
    "loadavg",
    "first_step_s",
    "setup_s",
    "iters_mean",
    "us_particle_step",
    "bytes_rss",
    "bytes_solver",
    "bytes_pair_cache",
)


def _f(x) -> float:
    try:
        return float(x)
    except (TypeError, ValueError):
        return math.nan


def _nanmedian(xs) -> float:
    s = sorted(x for x in (_f(v) for v in xs) if not math.isnan(x))
    n = len(s)
    if not n:
        return math.nan
    return s[n // 2] if n % 2 else 0.5 * (s[n // 2 - 1] + s[n // 2])


def normalise(result: dict, source: str, method: str, scene: str, repeat: int = 0) -> dict:
    """Flatten one worker result (``source`` 'ours' or 'peer') into a row with common keys."""
    load = result.get("load") or {}
    others = _f(load.get("others_busy_mean")) * _f(load.get("cpus"))
    row = {
        "scene": scene,
        "source": source,
        "method": method,
        "label": LABELS.get((source, method), method),
        "repeat": repeat,
        "fluid": result.get("fluid_particles"),
        "boundary": result.get("boundary_particles"),
        "steps": result.get("steps"),
        "wall_per_sim": _f(result.get("wall_seconds_per_sim_second")),
        "wall_seconds": _f(result.get("wall_seconds")),
        "err_mean": _f(result.get("density_error_mean_pct")),
        "err_worst": _f(result.get("density_error_worst_pct")),
        "err_max": _f(result.get("density_error_max_pct")),
        "rss_mb": _f(result.get("peak_rss_mb")),
        "others_cores": others,
        "loadavg": _f(load.get("loadavg_mean")),
        "threads": result.get("threads"),
    }
    if source == "ours":
        row.update(
            ms_step=_f(result.get("ms_per_step_median")),
            ms_step_mean=_f(result.get("ms_per_step_mean")),
            phases=dict(result.get("phases_ms") or {}),
            phases_mean=dict(result.get("phases_ms_mean") or {}),
            first_step_s=_f(result.get("first_step_seconds")),
            setup_s=_f(result.get("setup_seconds")),
            us_particle_step=_f(result.get("us_per_particle_step")),
            bytes_rss=_f(result.get("bytes_per_particle_rss")),
            bytes_solver=_f(result.get("bytes_per_particle_solver")),
            bytes_pair_cache=_f(result.get("bytes_per_particle_pair_cache")),
            backend=result.get("backend", "cpu"),
            precision=result.get("precision", "float64"),
            ns_particle_step=_f(result.get("ns_per_particle_step")),
            bytes_device_used=_f(result.get("device_bytes_per_particle_used")),
            iters_mean=_f(result.get("pd_passes_mean") if method != "dfsph" else result.get("density_iterations_mean")),
            div_iters_mean=_f(result.get("divergence_iterations_mean")) if method != "pf" else math.nan,
        )
    else:
        # SPlisHSPlasH's Timing gives averages only; they stand in for both median and mean phases
        pressure = "densitySolve" if method == "dfsph" else "solvePDConstraints"
        ph = {
            "neighbourSearch": result.get("neighborhood_search_ms"),
            pressure: result.get("pressure_solve_ms"),
            "divergenceSolve": result.get("divergence_solve_ms"),
            "step": result.get("step_ms"),
        }
        ph = {k: _f(v) for k, v in ph.items() if v is not None}
        row.update(
            ms_step=_f(result.get("ms_per_step")),
            ms_step_mean=_f(result.get("ms_per_step_mean")),
            phases=ph,
            phases_mean=dict(ph),
            first_step_s=math.nan,
            setup_s=_f(result.get("init_seconds")),
            iters_mean=_f(result.get("iterations_mean")),
            div_iters_mean=_f(result.get("divergence_iterations_mean")) if method == "dfsph" else math.nan,
        )
        if row["fluid"]:
            row["us_particle_step"] = 1e3 * row["ms_step"] / row["fluid"]
    return row


def is_loaded(row: dict, max_load: float) -> bool:
    """True when other processes used more than `max_load` cores on average during the run."""
    return _f(row.get("others_cores")) > max_load


def _median_row(rows: list[dict]) -> dict:
    out = dict(rows[0])
    for k in NUMERIC:
        if any(k in r for r in rows):
            out[k] = _nanmedian(r.get(k) for r in rows)
    for k in ("phases", "phases_mean"):
        keys = sorted({p for r in rows for p in (r.get(k) or {})})
        out[k] = {p: _nanmedian((r.get(k) or {}).get(p) for r in rows) for p in keys}
    out["runs"] = len(rows)
    return out


def summarise(rows: list[dict], max_load: float) -> "OrderedDict[tuple[str, str], dict]":
    """Group rows by (scene, label), in first-seen order: {"median": row | None, "quiet": [...], "loaded": [...]}."""
    groups: OrderedDict = OrderedDict()
    for r in rows:
        g = groups.setdefault((r["scene"], r["label"]), {"quiet": [], "loaded": [], "failed": []})
        if r.get("error"):
            g["failed"].append(r)
        elif is_loaded(r, max_load):
            g["loaded"].append(r)
        else:
            g["quiet"].append(r)
    for g in groups.values():
        g["median"] = _median_row(g["quiet"]) if g["quiet"] else None
        ok = g["quiet"] + g["loaded"]
        g["median_all"] = _median_row(ok) if ok else None
    return groups


# -- formatting ------------------------------------------------------------------------------------
def fmt_num(x, fmt: str = "{:.2f}") -> str:
    """A table cell: the number in `fmt`, or a dash for a missing one."""
    x = _f(x)
    return "—" if math.isnan(x) else fmt.format(x)


def fmt_int(x) -> str:
    """A table cell: the count with thousands separators, or a dash for a missing one."""
    x = _f(x)
    return "—" if math.isnan(x) else f"{int(round(x)):,}"


def format_table(headers: list[str], rows: list[list[str]], markdown: bool) -> str:
    """A Markdown pipe table, or a plain aligned text table."""
    if markdown:
        lines = ["| " + " | ".join(headers) + " |", "|" + "|".join("---" for _ in headers) + "|"]
        lines += ["| " + " | ".join(str(c) for c in r) + " |" for r in rows]
        return "\n".join(lines)
    cols = [headers] + [[str(c) for c in r] for r in rows]
    widths = [max(len(r[i]) for r in cols) for i in range(len(headers))]
    fmt = lambda r: "  ".join(c.rjust(w) if i else c.ljust(w) for i, (c, w) in enumerate(zip(r, widths)))  # noqa
    return "\n".join([fmt(headers), "  ".join("-" * w for w in widths)] + [fmt(r) for r in cols[1:]])


def _phases(row: dict) -> str:
    ph = row.get("phases") or {}
    parts = [f"{short} {ph[k]:.2f}" for k, short in PHASE_SHORT.items() if k in ph and not math.isnan(_f(ph[k]))]
    return ", ".join(parts) or "—"


SCENE_HEADERS = [
    "method",
    "fluid",
    "boundary",
    "steps",
    "ms/step (median)",
    "per-phase ms",
    "s wall / sim s",
    "density err mean %",
    "worst %",
    "peak RSS MB",
    "load (others' cores, loadavg)",
]


def _scene_row(label: str, r: dict) -> list[str]:
    return [
        label,
        fmt_int(r.get("fluid")),
        fmt_int(r.get("boundary")),
        fmt_int(r.get("steps")),
        fmt_num(r.get("ms_step")),
        _phases(r),
        fmt_num(r.get("wall_per_sim")),
        fmt_num(r.get("err_mean"), "{:.3f}"),
        fmt_num(r.get("err_worst"), "{:.3f}"),
        fmt_num(r.get("rss_mb"), "{:.0f}"),
        f"{fmt_num(r.get('others_cores'))}, {fmt_num(r.get('loadavg'), '{:.1f}')}",
    ]


def scene_tables(groups, markdown: bool, max_load: float, pairs=PEER_PAIRS, digits: int = 2) -> str:
    """One table per scene: the median of the quiet runs per method, then each loaded/failed run,
    and the ratio lines of `pairs` (`ratio_lines`)."""
    out = []
    scenes = list(OrderedDict.fromkeys(s for s, _ in groups))
    for scene in scenes:
        rows, notes, no_quiet = [], [], []
        for (s, label), g in groups.items():
            if s != scene:
                continue
            n_all = len(g["quiet"]) + len(g["loaded"]) + len(g["failed"])
            if g["median"] is not None:
                name = label + (f" (median of {len(g['quiet'])})" if len(g["quiet"]) > 1 else "")
                rows.append(_scene_row(name, g["median"]))
            else:
                no_quiet.append(f"{label} ({n_all} run{'s' if n_all != 1 else ''})")
            for r in g["loaded"]:
                rows.append(_scene_row(f"{label} [loaded, run {r['repeat'] + 1}]", r))
            for r in g["failed"]:
                notes.append(f"{label} run {r['repeat'] + 1} failed: {r['error'].splitlines()[0]}")
        if no_quiet:
            notes.insert(0, "no quiet run, so no median, for " + ", ".join(no_quiet) + ": all loaded or failed")
        title = f"### {scene}" if markdown else f"== {scene} =="
        block = [title, "", format_table(SCENE_HEADERS, rows, markdown)] if rows else [title]
        ratio = ratio_lines(groups, scene, pairs, digits)
        if ratio:
            block += [""] + [("- " if markdown else "") + line for line in ratio]
        if notes:
            block += [""] + [("- " if markdown else "") + "note: " + n for n in notes]
        out.append("\n".join(block))
    legend = (
        f"Medians over quiet runs; a run is 'loaded' when other processes used more than {max_load:g} "
        f"cores on average (it is shown, not counted). per-phase: {', '.join(f'{s} = {k}' for k, s in PHASE_SHORT.items())}; "
        f"ours: medians per step, SPlisHSPlasH: its Timing averages."
    )
    return "\n\n".join(out + [legend])


def ratio_lines(groups, scene: str, pairs=PEER_PAIRS, digits: int = 2) -> list[str]:
    """'IPSPH / SPH-DFSPH: wall per simulated second x, ms per step y' for each (ours, theirs) label
    pair of `pairs` that ran on `scene`, to `digits` decimals.

    From the medians of quiet runs; when either side has none, from the medians of all runs
    (loaded included), and the line says so.
    """
    here = {label: g for (s, label), g in groups.items() if s == scene}
    lines = []
    for mine, other in pairs:
        if mine not in here or other not in here:
            continue
        ours, p, note = here[mine]["median"], here[other]["median"], ""
        if ours is None or p is None:
            ours, p, note = here[mine]["median_all"], here[other]["median_all"], " (from LOADED runs)"
        if ours is None or p is None:
            continue
        a, b = _f(ours.get("wall_per_sim")), _f(p.get("wall_per_sim"))
        c, d = _f(ours.get("ms_step")), _f(p.get("ms_step"))
        q = digits
        if b > 0 and d > 0 and not math.isnan(a):
            lines.append(
                f"{mine} / {other.strip()}: wall per simulated second {a / b:.{q}f}x, ms per step "
                f"{c / d:.{q}f}x{note}"
                + _round_ratios(here[mine]["quiet"], here[other]["quiet"], q)
                + _error_verdict(ours, p)
            )
    return lines


def _error_verdict(ours: dict, peer: dict) -> str:
    """'; density error mean 0.031 % vs 0.046 % (within), worst ... (ABOVE)': whether the faster run
    is also as tight as the one it is compared with, so a looser run cannot pass as a win."""
    parts = []
    for key, name in (("err_mean", "mean"), ("err_worst", "worst")):
        a, b = _f(ours.get(key)), _f(peer.get(key))
        if math.isnan(a) or math.isnan(b):
            continue
        parts.append(f"{name} {a:.3f} % vs {b:.3f} % ({'within' if a <= b else 'ABOVE'})")
    return "; density error " + ", ".join(parts) if parts else ""


def _round_ratios(ours: list[dict], peer: list[dict], q: int = 2) -> str:
    """'; same round 0.88 1.11 1.21, fastest/fastest 1.17x' (wall per simulated second), from quiet runs.

    Runs of one repeat ran minutes apart at most, so their ratio sees less of the machine's drift
    than the ratio of medians; the fastest runs are the least disturbed ones.
    """
    a = {r["repeat"]: _f(r.get("wall_per_sim")) for r in ours}
    b = {r["repeat"]: _f(r.get("wall_per_sim")) for r in peer}
    pairs = [a[k] / b[k] for k in sorted(a) if k in b and b[k] > 0 and not math.isnan(a[k])]
    if len(pairs) < 2:
        return ""
    fastest = min(a.values()) / min(b.values())
    return f"; same round {' '.join(f'{x:.{q}f}' for x in pairs)}, fastest/fastest {fastest:.{q}f}x"
