"""`ipsph bench`'s interleaved runs: ours beside SPlisHSPlasH's, one worker process per run,
`repeats` rounds of every (scene, method) so machine noise spreads over all alike; and the default
mode, the stock scenes compared. `run_one` and `interleaved` are public: the studies in the
repository's benchmarks/ build on them (Table 1, another build against this one).
"""

from __future__ import annotations

import sys
import tempfile
import time
from pathlib import Path

from ..errors import ConfigError
from ..params import METHOD_NAMES
from . import report
from .scenes import DEFAULT_SCENES, resolve_scene

OUR_METHODS = METHOD_NAMES
PEER_METHODS = ("dfsph", "pf")


def log(msg: str) -> None:
    print(msg, file=sys.stderr, flush=True)


def use_peer(flag: bool | None) -> tuple[bool, str]:
    from .peer import peer_available

    if flag is False:
        return False, "SPlisHSPlasH: off (--no-peer)"
    ok, why = peer_available()
    if flag and not ok:
        raise ConfigError(f"--peer: {why}")
    return ok, (f"SPlisHSPlasH: {why}" if ok else f"SPlisHSPlasH: skipped ({why})")


def run_one(
    kind: str,
    scene_file: Path,
    method: str,
    args,
    label_scene: str,
    repeat: int,
    work_dir: Path,
    overrides=(),
    end_time: float | None = None,
    env: dict[str, str] | None = None,
) -> dict:
    """Run one simulation, `kind` "ours" or "peer" (SPlisHSPlasH); failures become a row with `error`.
    `env`: what our worker's environment changes (e.g. PYTHONPATH, to run another build)."""
    t = args.end_time if end_time is None else end_time
    t0 = time.perf_counter()
    try:
        if kind == "ours":
            from .ours import run_ours

            res = run_ours(scene_file, method, t, args.threads, overrides, timeout=args.timeout, env=env)
        else:
            from .peer import run_peer

            res = run_peer(scene_file, method, t, args.threads, timeout=args.timeout, work_dir=work_dir)
        row = report.normalise(res, kind, method, label_scene, repeat)
        row["raw"] = res
    except (RuntimeError, ConfigError, OSError) as exc:
        row = {
            "scene": label_scene,
            "source": kind,
            "method": method,
            "repeat": repeat,
            "label": report.LABELS[(kind, method)],
            "error": str(exc),
        }
    row["elapsed_s"] = time.perf_counter() - t0
    return row


def _progress(i: int, n: int, row: dict, max_load: float) -> None:
    head = f"[{i}/{n}] {row['scene']} {row['label']} run {row['repeat'] + 1}: "
    if row.get("error"):
        log(head + "FAILED: " + row["error"].splitlines()[0])
        return
    flag = " LOADED" if report.is_loaded(row, max_load) else ""
    log(
        head + f"{row['elapsed_s']:.1f} s, {row['ms_step']:.2f} ms/step, {row['wall_per_sim']:.2f} s/sim s, "
        f"others {row['others_cores']:.2f} cores{flag}"
    )


def interleaved(jobs: list[tuple], args, run=run_one) -> list[dict]:
    """jobs: (kind, scene_file, method, label_scene, overrides), run `repeats` times interleaved, each
    by `run` (called as `run_one` is)."""
    rows = []
    n = len(jobs) * args.repeats
    with tempfile.TemporaryDirectory(prefix="ipsph-bench-") as tmp:
        for rep in range(args.repeats):
            for kind, scene_file, method, label, overrides in jobs:
                row = run(kind, scene_file, method, args, label, rep, Path(tmp), overrides)
                rows.append(row)
                _progress(len(rows), n, row, args.max_load)
    return rows


def bench_scenes(args, peer: bool) -> tuple[str, list[dict]]:
    names = args.scenes or list(DEFAULT_SCENES)
    files = [(resolve_scene(s, args.scene_dir), s) for s in names]
    jobs = []
    for f, given in files:
        label = f.stem
        jobs += [("ours", f, m, label, tuple(args.set)) for m in args.methods]
        if peer:
            if f.suffix.lower() == ".json":
                jobs += [("peer", f, m, label, ()) for m in PEER_METHODS]
            else:
                log(f"ipsph bench: note: {given} is not a SPlisHSPlasH scene; SPlisHSPlasH skips it")
    rows = interleaved(jobs, args)
    groups = report.summarise(rows, args.max_load)
    return report.scene_tables(groups, args.markdown, args.max_load), rows
