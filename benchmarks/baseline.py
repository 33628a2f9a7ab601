"""This build against another source tree: our methods from both, interleaved (a change's speed A/B).

    git worktree add ../base main
    python -m benchmarks baseline ../base --methods ipsph --repeats 3 --end-time 0.3

The other build's rows sit beside ours, labelled " (baseline)", on the scenes of `ipsph bench`
(--scenes, default its stock dam breaks), and each scene's table ends with this / baseline ratios
to three decimals (same-round pairs and fastest/fastest too): one build against another differs
by a few per cent, so the rounding of a peer comparison would hide it.
"""

from __future__ import annotations

from pathlib import Path

from ipsph.bench import report
from ipsph.bench.runs import interleaved, run_one
from ipsph.bench.scenes import DEFAULT_SCENES, resolve_scene
from ipsph.errors import ConfigError

BASELINE = " (baseline)"  # label suffix of the other build's rows
WORKER = Path("ipsph") / "bench" / "_ours_worker.py"  # what a source tree must hold


def check_tree(tree: Path) -> Path:
    """The resolved source tree, or a one-line ConfigError when it holds no ipsph benchmark worker."""
    resolved = Path(tree).expanduser().resolve()
    if not (resolved / WORKER).is_file():
        raise ConfigError(f"baseline {tree} (resolved {resolved}): not an ipsph source tree (no {WORKER} in it)")
    return resolved


def _run(tree: Path):
    """`run_one`, with the "baseline" jobs run by the other tree's ipsph and labelled as such."""

    def run(kind, scene_file, method, args, label, repeat, work_dir, overrides=()):
        if kind != "baseline":
            return run_one(kind, scene_file, method, args, label, repeat, work_dir, overrides)
        row = run_one(
            "ours", scene_file, method, args, label, repeat, work_dir, overrides, env={"PYTHONPATH": str(tree)}
        )
        row.update(source="baseline", label=row["label"] + BASELINE)
        return row

    return run


def pairs(methods) -> tuple[tuple[str, str], ...]:
    """(this build, the baseline) label pairs of the ratio lines."""
    labels = [report.LABELS[("ours", m)] for m in methods]
    return tuple((label, label + BASELINE) for label in labels)


def bench_baseline(tree: Path, args) -> tuple[str, list[dict]]:
    """Our `args.methods` on the scenes, from this build and from `tree`, interleaved; the tables."""
    tree = check_tree(tree)
    jobs = []
    for name in args.scenes or list(DEFAULT_SCENES):
        f = resolve_scene(name, args.scene_dir)
        for m in args.methods:
            jobs += [(kind, f, m, f.stem, tuple(args.set)) for kind in ("ours", "baseline")]
    rows = interleaved(jobs, args, run=_run(tree))
    groups = report.summarise(rows, args.max_load)
    return report.scene_tables(groups, args.markdown, args.max_load, pairs(args.methods), digits=3), rows
