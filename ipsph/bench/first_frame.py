"""`ipsph bench --first-frame`: seconds from `ipsph run` to its first frame, with a cold and a
warm Numba cache; and its table.
"""

from __future__ import annotations

import json
import math
import os
import statistics
import tempfile
from pathlib import Path

from ..io import RUN_JSON
from .report import _f, fmt_num, format_table
from .runs import log

FIRST_FRAME_TARGET_S = {"cold": 25.0, "warm": 3.0}  # on 2 cores


def first_frame(threads: int, timeout: float = 900.0, repeats: int = 1) -> list[dict]:
    """Time to first frame: seconds for `ipsph run` (default scene, first frame at t = 0.04 s, no renders) to finish,
    with NUMBA_CACHE_DIR pointed at a fresh folder (cold: everything compiles) and then again (warm);
    `repeats` such pairs, each cold run with its own empty cache."""
    from .machine import timed_ipsph_run

    rows = []
    with tempfile.TemporaryDirectory(prefix="ipsph-first-frame-") as tmp:
        for k in range(repeats):
            env = dict(os.environ, NUMBA_CACHE_DIR=str(Path(tmp) / f"numba-cache-{k}"))
            for cache in ("cold", "warm"):
                out = Path(tmp) / f"out-{cache}-{k}"
                r = timed_ipsph_run(["--end-time", "0.04", "--no-render"], out, threads, timeout, env)
                try:  # run.json splits the time: setup (sampling, output folder), compile, the time loop
                    run_info = json.loads((out / RUN_JSON).read_text())
                except (OSError, json.JSONDecodeError):
                    run_info = {}
                secs, code, frames, load = r["seconds"], r["exit_code"], r["frames"], r["load"]
                split = run_info.get("time_split_seconds") or {}
                rows.append(
                    {
                        "cache": cache,
                        "repeat": k,
                        "seconds": secs,
                        "ok": code == 0 and frames >= 2,
                        "exit_code": code,
                        "frames": frames,
                        "setup_seconds": run_info.get("setup_seconds"),
                        "loop_seconds": run_info.get("wall_seconds"),
                        "split": split,
                        "load": load.as_dict(),
                        "others_cores": load.others_busy_mean * load.cpus,
                        "stderr_tail": r["stderr_tail"],
                        "command": r["command"],
                    }
                )
                log(
                    f"first frame ({cache} cache, run {k + 1}/{repeats}): {secs:.1f} s, exit {code}, {frames} frames, "
                    f"compile {split.get('compile', math.nan):.1f} s, others {rows[-1]['others_cores']:.2f} cores"
                )
    return rows


def first_frame_table(rows: list[dict], markdown: bool, target: dict | float = 5.0) -> str:
    """Seconds from `ipsph run` starting to its first frame written, split by the run's own run.json
    (its clock starts at the process's creation): launching and exiting the process, setup without
    compiling, Numba compiling, stepping; each run and the medians."""
    targets = target if isinstance(target, dict) else {"warm": float(target)}

    def cells(r):
        secs = _f(r.get("seconds"))
        sp = r.get("split") or {}
        total, setup, comp, step = (_f(sp.get(k)) for k in ("total", "setup", "compile", "stepping"))
        start = secs - total if not math.isnan(total) else math.nan
        return [secs, start, setup, comp, step]

    body = []
    for cache in ("cold", "warm"):
        group = [r for r in rows if r.get("cache") == cache]
        for r in group:
            body.append(
                [f"{cache} (run {r.get('repeat', 0) + 1})"]
                + [fmt_num(v) for v in cells(r)]
                + ["yes" if r.get("ok") else f"no (exit {r.get('exit_code')})", fmt_num(r.get("others_cores")), ""]
            )
        ok = [r for r in group if r.get("ok")]
        if ok:
            med = [statistics.median(c) for c in zip(*(cells(r) for r in ok))]
            goal = targets.get(cache)
            verdict = "" if goal is None else ("meets" if med[0] <= goal else "misses") + f" {goal:g} s"
            body.append(
                [f"**{cache}: median of {len(ok)}**" if markdown else f"{cache}: median of {len(ok)}"]
                + [fmt_num(v) for v in med]
                + ["", fmt_num(statistics.median(_f(r.get("others_cores")) for r in ok)), verdict]
            )
    return format_table(
        [
            "numba cache",
            "seconds to first frame",
            "process launch + exit",
            "setup (imports, scene, sampling; no compiling)",
            "Numba compiling",
            "stepping",
            "ok",
            "load (others' cores)",
            "target",
        ],
        body,
        markdown,
    )
