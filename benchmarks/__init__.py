"""Studies of our own, run from a clone (not installed with the package): `python -m benchmarks`.

    table1.py       the paper's Table 1 on pipelines/*.toml (and SPlisHSPlasH on its stock scenes)
    figure4.py      the paper's Figure 4: the breaking dam, IPSPH beside PF, and their density errors
    render_cost.py  what renders cost: seconds per frame at N particles, and the default run with / without
    sweep_bench.py  `ipsph sweep` on a 2-worker LocalCluster against the same runs one after another
    moving_cost.py  per-step cost of a kinematic wall and of a rigid body against the same scene, static

They build on `ipsph.bench` (the workers, the load sampling, the tables) and take the same
options as `ipsph bench` (--repeats, --threads, --end-time, --max-load, --markdown, --json, ...).
"""
