"""The paper's Table 1: IPSPH, DFSPH and PF on pipelines/*.toml (and SPlisHSPlasH on its stock
scenes), the paper's columns (averages per step). A study of ours, run from a clone:

    python -m benchmarks table1 [--pipelines ...] [--dragon-mesh OBJ] [ipsph bench options]
"""

from __future__ import annotations

from pathlib import Path

from ipsph.bench import report
from ipsph.bench.report import fmt_int, fmt_num, format_table
from ipsph.bench.runs import PEER_METHODS, interleaved
from ipsph.bench.scenes import PIPELINES, pipeline_path, resolve_scene
from ipsph.errors import ConfigError


def bench_table1(args, peer: bool) -> tuple[str, list[dict]]:
    jobs = []
    for stem in args.pipelines or list(PIPELINES):
        path = pipeline_path(stem)
        over = tuple(args.set)
        if stem == "two_dragons" and args.dragon_mesh is not None:
            mesh = Path(args.dragon_mesh).expanduser().resolve()
            if not mesh.is_file():
                raise ConfigError(
                    f"--dragon-mesh {args.dragon_mesh} (resolved {mesh}) is not a file: pass "
                    f"SPlisHSPlasH's data/models/Dragon_50k.obj"
                )
            over = (f"boundary.1.mesh={mesh}", f"boundary.2.mesh={mesh}") + over
        jobs += [("ours", path, m, stem, over) for m in ("ipsph", "dfsph", "pf") if m in args.methods]
        if peer:
            stock = resolve_scene(PIPELINES[stem], args.scene_dir)
            jobs += [("peer", stock, m, f"{stem} / {stock.stem}", ()) for m in PEER_METHODS]
    rows = interleaved(jobs, args)
    groups = report.summarise(rows, args.max_load)
    return table1(groups, args.markdown), rows


TABLE1_HEADERS = [
    "scene (fluid particles)",
    "method",
    "steps",
    "avg divergenceSolve ms",
    "avg solvePDConstraints ms",
    "avg densitySolve ms",
    "avg ms / step",
    "s wall / sim s",
    "density err mean %",
    "worst %",
]


def _table1_row(scene: str, label: str, r: dict) -> list[str]:
    ph = r.get("phases_mean") or {}
    return [
        f"{scene} ({fmt_int(r.get('fluid'))})",
        label,
        fmt_int(r.get("steps")),
        fmt_num(ph.get("divergenceSolve")),
        fmt_num(ph.get("solvePDConstraints")),
        fmt_num(ph.get("densitySolve")),
        fmt_num(r.get("ms_step_mean")),
        fmt_num(r.get("wall_per_sim")),
        fmt_num(r.get("err_mean"), "{:.3f}"),
        fmt_num(r.get("err_worst"), "{:.3f}"),
    ]


def table1(groups, markdown: bool) -> str:
    """The paper's Table 1 columns (averages) per scene and method: the median of the quiet
    runs, then each loaded run (marked, not counted); failed runs become notes."""
    body, notes = [], []
    for (scene, label), g in groups.items():
        if g["median"] is not None:
            body.append(
                _table1_row(
                    scene, label + (f" (median of {len(g['quiet'])})" if len(g["quiet"]) > 1 else ""), g["median"]
                )
            )
        for r in g["loaded"]:
            body.append(_table1_row(scene, f"{label} [loaded, run {r.get('repeat', 0) + 1}]", r))
        for r in g["failed"]:
            notes.append(f"{scene} {label} run {r.get('repeat', 0) + 1} failed: {r['error'].splitlines()[0]}")
    text = format_table(TABLE1_HEADERS, body, markdown)
    if notes:
        text += "\n\n" + "\n".join(("- " if markdown else "") + "note: " + n for n in notes)
    return text
