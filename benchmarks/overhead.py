"""What a side process costs the default scene's `ipsph run`: runs without and with it, alternating
in fresh processes (`python -m benchmarks surface-overhead`, `render-overhead`), median of pair ratios."""

from __future__ import annotations

import statistics
import tempfile
from pathlib import Path

TARGET = 0.25  # a side process (renders, surfaces) may slow the default scene's run by at most 25 %


def default_run(args: list[str], out: Path, threads: int, timeout: float, check) -> dict:
    """One `ipsph run` of the default scene into `out`: wall and CPU seconds, frames, PNGs, load;
    `ok` when it exited 0 with frames and `check(result, out)` holds."""
    from ipsph.bench.machine import timed_ipsph_run

    r = timed_ipsph_run(args, out, threads, timeout)
    return {
        "seconds": r["seconds"],
        "cpu_seconds": r["cpu_seconds"],
        "exit_code": r["exit_code"],
        "frames": r["frames"],
        "pngs": r["pngs"],
        "stderr_tail": r["stderr_tail"],
        "ok": r["exit_code"] == 0 and r["frames"] > 0 and check(r, out),
        "others_cores": r["load"].others_busy_mean * r["load"].cpus,
    }


def alternating_pairs(one_run, key: str, repeats: int, max_load: float, describe, log=print) -> dict:
    """`one_run(with_it: bool, tmp: Path, k: int) -> dict` (seconds, cpu_seconds, ok, others_cores),
    once to warm the caches, then `repeats` pairs without / with; `key` names the "with" side."""
    pairs = []
    with tempfile.TemporaryDirectory(prefix=f"ipsph-{key}-overhead-") as tmp:
        one_run(True, Path(tmp), -1)  # warm the Numba and sampling caches
        for k in range(repeats):
            plain, with_it = one_run(False, Path(tmp), k), one_run(True, Path(tmp), k)
            others = max(plain["others_cores"], with_it["others_cores"])
            pairs.append(
                {
                    "plain": plain,
                    key: with_it,
                    "loaded": others > max_load,
                    "ratio": with_it["seconds"] / plain["seconds"],
                }
            )
            log(
                f"{key} overhead pair {k + 1}/{repeats}: {plain['seconds']:.2f} s without, {with_it['seconds']:.2f} s "
                f"with ({describe(with_it)}), x{pairs[-1]['ratio']:.3f}, others {others:.2f} cores"
                f"{' (loaded)' if others > max_load else ''}"
            )
    good = [p for p in pairs if not p["loaded"] and p["plain"]["ok"] and p[key]["ok"]]
    every = [p for p in pairs if p["plain"]["ok"] and p[key]["ok"]]
    med = lambda xs: statistics.median(xs) if xs else float("nan")  # noqa: E731
    return {
        "pairs": pairs,
        "counted": len(good),
        "plain_seconds": med([p["plain"]["seconds"] for p in good]),
        f"{key}_seconds": med([p[key]["seconds"] for p in good]),
        "ratio_median": med([p["ratio"] for p in good]),
        "ratio_median_all": med([p["ratio"] for p in every]),
        "plain_cpu": med([p["plain"]["cpu_seconds"] for p in good]),
        f"{key}_cpu": med([p[key]["cpu_seconds"] for p in good]),
        "ok": all(p["plain"]["ok"] and p[key]["ok"] for p in pairs),
    }


def table(s: dict, key: str, without: str, with_it: str, markdown: bool, target: float = TARGET) -> str:
    """The pair medians and the slow-down against `target` (a fraction)."""
    met = "met" if s["ratio_median"] <= 1 + target else "NOT met"
    rows = [
        (without, f"{s['plain_seconds']:.2f}", f"{s['plain_cpu']:.1f}", ""),
        (
            with_it,
            f"{s[key + '_seconds']:.2f}",
            f"{s[key + '_cpu']:.1f}",
            f"x{s['ratio_median']:.3f} (median of pair ratios; target <= x{1 + target:.2f}: {met})",
        ),
    ]
    head = ("default scene `ipsph run`", "wall s (median)", "CPU s (median)", "slow-down")
    note = f"{s['counted']} of {len(s['pairs'])} pairs counted (the others ran on a loaded machine or failed)"
    if "ratio_median_all" in s:
        note += f"; median ratio over every pair that ran: x{s['ratio_median_all']:.3f}"
    if markdown:
        lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
        lines += ["| " + " | ".join(r) + " |" for r in rows]
    else:
        lines = ["  ".join(f"{h:<30s}" if i == 0 else f"{h:>16s}" for i, h in enumerate(head))]
        lines += ["  ".join(f"{c:<30s}" if i == 0 else f"{c:>16s}" for i, c in enumerate(r)) for r in rows]
    return "\n".join(lines) + "\n\n" + note
