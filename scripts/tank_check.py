"""Tank at rest, per wall model and method: first/second layer pressure against rho0 g depth, the first
layer's height above the floor and the interior slope (means over the frames of the last second), the
per-step peak speed and whether the kinetic energy grows (issue 39's tank rows).

    python scripts/tank_check.py [--models field akinci-volume] [--methods ipsph dfsph] [--r 0.02] [--t 4]
"""

import argparse
import time

import numpy as np

from ipsph import Simulation
from ipsph.sampling.scene import sample_scene
from ipsph.scene import scene_from_dict

AVERAGE_S = 1.0  # the layer figures are means over the frames of the last second (the tank is never quite still)


def layers(sim, scene, r):
    """(p1/hyd, p2/hyd, y1/d, interior slope - 1) of one state: the first and second layers' mean
    pressure against rho0 g depth below the surface, the first layer's height, the fitted dp/d(depth)."""
    x, p = sim.positions, sim.pressures
    d, h, g, rho0 = 2 * r, sim.support, 9.81, scene.density0
    lo, hi = np.zeros(3), np.array([0.6, 1.0, 0.6])
    inner_xz = np.all(x[:, [0, 2]] > lo[[0, 2]] + h, axis=1) & np.all(x[:, [0, 2]] < hi[[0, 2]] - h, axis=1)
    top_layer = np.sort(x[inner_xz, 1])[-int(inner_xz.sum() ** (2 / 3)) :]
    surface = top_layer.mean() + r
    y = x[inner_xz, 1]
    pi = p[inner_xz]
    ymin = y.min()
    first = y < ymin + 0.5 * d
    second = (y >= ymin + 0.5 * d) & (y < ymin + 1.5 * d)
    rel1 = np.mean(pi[first] / (rho0 * g * (surface - y[first])))
    rel2 = np.mean(pi[second] / (rho0 * g * (surface - y[second])))
    deep = inner_xz & (x[:, 1] > ymin + h) & (x[:, 1] < surface - h)
    slope = np.polyfit(surface - x[deep, 1], p[deep], 1)[0] / (rho0 * g) - 1.0
    return rel1, rel2, np.mean(y[first]) / d, slope


def tank(method, model, r, t_end, extra=None):
    sim_keys = {"method": method, "particle_radius": r, "end_time": t_end, "boundary_model": model}
    sim_keys.update(extra or {})
    scene = scene_from_dict(
        {
            "simulation": sim_keys,
            "time_step": {"dt_max": 0.005},
            "fluid": [{"name": "column", "box": {"min": [0, 0, 0], "max": [0.6, 0.6, 0.6]}}],
            "boundary": [{"name": "tank", "role": "container", "box": {"min": [0, 0, 0], "max": [0.6, 1.0, 0.6]}}],
        },
        name=f"tank-{method}-{model}",
    )
    sim = Simulation(scene, *sample_scene(scene)[:3])
    vmax, energy, proj, snaps = [], [], [0], []
    t0 = time.perf_counter()

    def on_step(s):
        vmax.append(s.max_speed)
        energy.append(s.kinetic_energy)
        proj[0] += getattr(s, "wall_projections", 0)

    def on_frame(s, k):
        if s.time >= t_end - AVERAGE_S - 1e-9:
            snaps.append(layers(s, scene, r))

    sim.run(end_time=t_end, fps=10, on_step=on_step, on_frame=on_frame)
    wall = time.perf_counter() - t0
    rel1, rel2, y1, slope = np.mean(snaps, axis=0)
    late = vmax[len(vmax) // 4 :]
    third = max(len(energy) // 3, 1)
    return dict(
        method=method,
        model=model,
        n=sim.n_fluid,
        walls=sim.n_boundary,
        first_p=rel1,
        second_p=rel2,
        first_h_d=y1,
        slope=slope,
        energy=(float(np.mean(energy[third : 2 * third])), float(np.mean(energy[2 * third :]))),
        vmax=max(vmax),
        vmax_late=max(late),
        projections=proj[0],
        settle=sim.settle_report.get("converged"),
        wall_s=wall,
    )


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--models", nargs="+", default=["field", "akinci-volume"])
    ap.add_argument("--methods", nargs="+", default=["ipsph", "dfsph"])
    ap.add_argument("--r", type=float, default=0.02)
    ap.add_argument("--t", type=float, default=4.0)
    a = ap.parse_args()
    print(
        f"method model n walls | p1/hyd p2/hyd | y1/d | slope (means over the last {AVERAGE_S:g} s) | vmax (after t/4) | "
        "KE 2nd third -> last third [J] | proj | settled | wall s"
    )
    for model in a.models:
        for method in a.methods:
            o = tank(method, model, a.r, a.t)
            print(
                f"{o['method']:6s} {o['model']:14s} {o['n']:5d} {o['walls']:6d} | {o['first_p']:.3f} {o['second_p']:.3f} | "
                f"{o['first_h_d']:.3f} | {o['slope']:+.3%} | {o['vmax']:.3f} ({o['vmax_late']:.3f}) | "
                f"{o['energy'][0]:.4f} -> {o['energy'][1]:.4f} | {o['projections']} | {o['settle']} | {o['wall_s']:.0f}",
                flush=True,
            )
