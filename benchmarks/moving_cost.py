"""`python -m benchmarks moving-walls`: the per-step cost of a moving wall and of a rigid body against the
same scene with the wall static (issue 19).

One process, three variants of one scene (a tank of water with a box obstacle in it): the box
static, the box a kinematic paddle (sinusoid), the box a floating rigid body. Each is set up and
compiled first, then they step in turns (A B C A B C ...), STEPS steps at a fixed dt per turn, so
the machine's load hits them alike; the figures are medians over the turns and same-run ratios to
the static variant. What a moving wall adds: the walls' re-sort into the grid and their per-cell
candidate lists every step (`NeighbourSearch._resort_walls`), the wall-velocity pass
(`wall_rate`), the serial reaction scatter (`rigid.wall_forces`); a body also its contacts.
"""

from __future__ import annotations

import statistics
import time

STEPS = 10
DT = 1e-3


def _scene(kind: str, r: float) -> dict:
    box = {"name": "box", "role": "obstacle", "box": {"min": [0.5, 0.2, 0.2], "max": [0.7, 0.4, 0.4]}}
    if kind == "kinematic":
        box["motion"] = {"type": "sinusoid", "axis": [1, 0, 0], "amplitude": 0.05, "period": 1.0}
    elif kind == "body":
        box["density"] = 500.0
    return {
        "simulation": {"particle_radius": r, "end_time": 10.0, "fit_wall_volumes": True},
        "fluid": [{"box": {"min": [0, 0, 0], "max": [1.2, 0.35, 0.6]}}],
        "boundary": [{"name": "tank", "box": {"min": [0, 0, 0], "max": [1.2, 0.8, 0.6]}}, box],
        "render": {"enabled": False},
    }


def moving_cost(r: float = 0.02, repeats: int = 5, threads: int = 2, log=print) -> list[dict]:
    import numba

    from ipsph.simulation import Simulation

    numba.set_num_threads(threads)
    sims = {}
    for kind in ("static", "kinematic", "body"):
        sims[kind] = Simulation.from_scene(_scene(kind, r))
        for _ in range(3):  # compile and warm the caches
            sims[kind].step(DT)
    times: dict[str, list[float]] = {k: [] for k in sims}
    for rep in range(repeats):
        for kind, sim in sims.items():
            t0 = time.perf_counter()
            for _ in range(STEPS):
                sim.step(DT)
            times[kind].append((time.perf_counter() - t0) / STEPS)
        log(f"ipsph bench: moving walls, turn {rep + 1}/{repeats}")
    base = statistics.median(times["static"])
    return [
        {
            "variant": k,
            "fluid": sims[k].n_fluid,
            "walls": sims[k].n_boundary,
            "ms_per_step": 1000 * statistics.median(v),
            "ratio": statistics.median(v) / base,
            "ms_all": [1000 * x for x in v],
        }
        for k, v in times.items()
    ]


def table(rows: list[dict], markdown: bool) -> str:
    head = ("variant", "fluid", "walls", "ms/step (median)", "ratio to static")
    lines = [
        [r["variant"], f"{r['fluid']:,}", f"{r['walls']:,}", f"{r['ms_per_step']:.2f}", f"{r['ratio']:.3f}"]
        for r in rows
    ]
    if markdown:
        out = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
        out += ["| " + " | ".join(x) + " |" for x in lines]
    else:
        out = ["  ".join(f"{h:>16}" for h in head)] + ["  ".join(f"{x:>16}" for x in ln) for ln in lines]
    return "\n".join(out) + "\n(same-run ratios, interleaved turns; a loaded machine inflates all three alike)"
