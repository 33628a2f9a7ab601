"""Scene ensembles on Dask distributed: `ipsph sweep` and `ipsph.sweep(...)`.

    spec.py      sweep files (scene, [set], [grid], [zip]) -> members; validation before anything starts
    engine.py    the sweep: the --scheduler client or a LocalCluster, submitting, progress, faults, Ctrl-C
    plan.py      the output folder: what is left to do (--resume, --overwrite), creating or clearing it
    cluster.py   the local layout, the LocalCluster on 127.0.0.1, the check that workers share OUT
    member.py    the Dask task: one member as an `ipsph run` child process in OUT/<member>/
    (the member's child dies with its worker: ipsph/sweeps/lifeline.py)
    records.py   OUT/sweep.json and OUT/summary.csv
    cli.py       the `ipsph sweep` arguments

Dask distributed is imported only when a sweep runs (`pip install 'ipsph[sweep]'`).
"""

from .engine import SweepOptions, run_sweep, sweep

__all__ = ["sweep", "run_sweep", "SweepOptions"]
