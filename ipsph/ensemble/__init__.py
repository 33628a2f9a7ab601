"""Scene ensembles on Dask distributed: `ipsph sweep` and `ipsph.sweep(...)`.

    spec.py      sweep files (scene, [set], [grid], [zip]) -> members; validation before anything starts
    engine.py    the output folder plan, the LocalCluster / --scheduler client, progress, faults, Ctrl-C
    member.py    the Dask task: one member as an `ipsph run` child process in OUT/<member>/
    _child.py    that child's entry point (dies with its worker, then is exactly `ipsph run`)
    records.py   OUT/sweep.json and OUT/summary.csv
    cli.py       the `ipsph sweep` arguments

Dask distributed is imported only when a sweep runs (`pip install 'ipsph[sweep]'`).
"""

from .engine import SweepOptions, run_sweep, sweep

__all__ = ["sweep", "run_sweep", "SweepOptions"]
