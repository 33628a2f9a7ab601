"""Studies of our own, run from a clone (not installed with the package): `python -m benchmarks`.

    table1.py       the paper's Table 1 on pipelines/*.toml (and SPlisHSPlasH on its stock scenes)
    figure4.py      the paper's Figure 4: the breaking dam, IPSPH beside PF, and their density errors
    render_cost.py  what renders cost: seconds per frame at N particles, and the default run with / without
    surface_cost.py what surfaces cost: seconds per reconstruction at N particles, and the run with / without
    overhead.py     the A/B both overheads use: the default run without and with a side process, alternating
    sweep_bench.py  `ipsph sweep` on a 2-worker LocalCluster against the same runs one after another
    moving_cost.py  per-step cost of a kinematic wall and of a rigid body against the same scene, static
    baseline.py     this build against another source tree, interleaved (a change's speed A/B)

They build on `ipsph.bench`'s public helpers (the workers, the load sampling, the tables) and
take the same options as `ipsph bench` (--repeats, --threads, --end-time, --max-load, --markdown, --json, ...).
"""
