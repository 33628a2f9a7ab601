"""Tank at rest, per wall model and method: first/second layer pressure against rho0 g depth, the first
layer's height above the floor and the interior slope (means over the frames of the last second), the
per-step peak speed and whether the kinetic energy grows (issue 39's tank rows).

    python scripts/tank_check.py [--models field akinci-volume] [--methods ipsph dfsph] [--r 0.02] [--t 4]
                                 [--seeds N [--first-seed K]] [--where] [--layers]

A settled tank is never quite still, and its trajectory is chaotic: the same commit on another CPU
(another rounding of the same sums) moves one run's p1 and slope by about 2 % and its peak speed by
half. --seeds N runs N trajectories, each started from the lattice moved by a uniform jitter of
JITTER_D d per coordinate (seed k), and prints each and the median [min, max] of every figure.
--layers prints the first layer's particle count once a second: on the frictionless field walls
it grows as particles from above fill vacancies in it, the fastest events of a run.
"""

import argparse
import time

import numpy as np

from ipsph import Simulation
from ipsph.sampling.scene import sample_scene
from ipsph.scene import scene_from_dict

TANK = [0.6, 1.0, 0.6]  # the container box from the origin [m]; the fluid fills it to FILL
FILL = [0.6, 0.6, 0.6]
JITTER_D = 1e-3  # --seeds: the start's jitter per coordinate, in d (far below any figure's resolution)
AVERAGE_S = 1.0  # the layer figures are means over the frames of the last second (the tank is never quite still)


def first_layer(y, d):
    """Which of the heights y are the bottom layer's: within d/2 of the lowest."""
    return y < y.min() + 0.5 * d


def surface_height(y, d, r):
    """The free surface over a set of full columns: the mean height of its top layer + r, the top layer
    being as many particles as the bottom layer holds (one per column; a cube's n^(2/3) is not that
    count when the columns are fewer than the layers, and took in part of the next layer down)."""
    per_layer = int(np.count_nonzero(first_layer(y, d)))
    return np.sort(y)[-per_layer:].mean() + r


def layers(sim, scene, r):
    """(p1/hyd, p2/hyd, y1/d, interior slope - 1) of one state: the first and second layers' mean
    pressure against rho0 g depth below the surface, the first layer's height, the fitted dp/d(depth)."""
    x, p = sim.positions, sim.pressures
    d, h, g, rho0 = 2 * r, sim.support, 9.81, scene.density0
    lo, hi = np.zeros(3), np.array(TANK)
    inner_xz = np.all(x[:, [0, 2]] > lo[[0, 2]] + h, axis=1) & np.all(x[:, [0, 2]] < hi[[0, 2]] - h, axis=1)
    y = x[inner_xz, 1]
    surface = surface_height(y, d, r)
    pi = p[inner_xz]
    ymin = y.min()
    first = first_layer(y, d)
    second = (y >= ymin + 0.5 * d) & (y < ymin + 1.5 * d)
    rel1 = np.mean(pi[first] / (rho0 * g * (surface - y[first])))
    rel2 = np.mean(pi[second] / (rho0 * g * (surface - y[second])))
    deep = inner_xz & (x[:, 1] > ymin + h) & (x[:, 1] < surface - h)
    slope = np.polyfit(surface - x[deep, 1], p[deep], 1)[0] / (rho0 * g) - 1.0
    return rel1, rel2, np.mean(y[first]) / d, slope


def fastest(sim, r):
    """(speed, depth below the surface / d, distance to the nearest side wall / d, |v_y| / |v|) of the
    fastest particle of one state."""
    x, v = sim.positions, sim.velocities
    speed = np.linalg.norm(v, axis=1)
    i = int(np.argmax(speed))
    d = 2 * r
    surface = surface_height(x[:, 1], d, r)
    side = min(x[i, 0], TANK[0] - x[i, 0], x[i, 2], TANK[2] - x[i, 2])
    return speed[i], (surface - x[i, 1]) / d, side / d, abs(v[i, 1]) / max(speed[i], 1e-30)


def tank(method, model, r, t_end, extra=None, where=False, seed=None):
    sim_keys = {"method": method, "particle_radius": r, "end_time": t_end, "boundary_model": model}
    sim_keys.update(extra or {})
    scene = scene_from_dict(
        {
            "simulation": sim_keys,
            "time_step": {"dt_max": 0.005},
            "fluid": [{"name": "column", "box": {"min": [0, 0, 0], "max": FILL}}],
            "boundary": [{"name": "tank", "role": "container", "box": {"min": [0, 0, 0], "max": TANK}}],
        },
        name=f"tank-{method}-{model}",
    )
    x0, v0, xb = sample_scene(scene)[:3]
    if seed is not None:
        x0 = x0 + np.random.default_rng(seed).uniform(-JITTER_D, JITTER_D, x0.shape) * 2 * r
    sim = Simulation(scene, x0, v0, xb)
    vmax, energy, proj, snaps, places, floor_layer = [], [], [0], [], [], []
    t0 = time.perf_counter()

    def on_step(s):
        vmax.append(s.max_speed)
        energy.append(s.kinetic_energy)
        proj[0] += getattr(s, "wall_projections", 0)
        if where and s.time >= t_end / 4:
            places.append((s.time, *fastest(sim, r)))

    def on_frame(s, k):
        if abs(s.time - round(s.time)) < 1e-6:  # the first layer's count once a second
            floor_layer.append(int(np.count_nonzero(first_layer(sim.positions[:, 1], 2 * r))))
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
        places=np.array(places).reshape(-1, 5),
        floor_layer=floor_layer,
    )


def print_where(places):
    """Where the fastest particle of each step after t/4 was, and the five fastest events."""
    t, speed, depth, side, vertical = places.T
    print(
        f"  fastest after t/4: {np.mean(depth < 2):.0%} of steps within 2 d of the surface, "
        f"{np.mean(side < 1.5):.0%} within 1.5 d of a side wall, {np.mean(vertical > 0.7):.0%} moving vertically; "
        f"per-step peak median {np.median(speed):.3f}, q0.9 {np.quantile(speed, 0.9):.3f} m/s"
    )
    for k in np.argsort(speed)[-5:][::-1]:
        print(
            f"    t {t[k]:.3f} s  {speed[k]:.3f} m/s  depth {depth[k]:.2f} d  side {side[k]:.2f} d  |vy|/|v| {vertical[k]:.2f}"
        )


def print_spread(runs):
    """The median [min, max] over the seeds of every figure of a row."""

    def f(key, fmt, i=None):
        v = np.array([o[key] if i is None else o[key][i] for o in runs])
        return f"{np.median(v):{fmt}} [{v.min():{fmt}}, {v.max():{fmt}}]"

    print(
        f"  median [range] of {len(runs)}: p1 {f('first_p', '.3f')}  p2 {f('second_p', '.3f')}  y1 {f('first_h_d', '.3f')} d  "
        f"slope {f('slope', '+.2%')}  vmax after t/4 {f('vmax_late', '.3f')}  KE last third {f('energy', '.4f', 1)}  "
        f"KE falling in {sum(o['energy'][1] <= o['energy'][0] for o in runs)} of {len(runs)}",
        flush=True,
    )


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--models", nargs="+", default=["field", "akinci-volume"])
    ap.add_argument("--methods", nargs="+", default=["ipsph", "dfsph"])
    ap.add_argument("--r", type=float, default=0.02)
    ap.add_argument("--t", type=float, default=4.0)
    ap.add_argument("--where", action="store_true", help="where the fastest particle of each step is")
    ap.add_argument("--layers", action="store_true", help="the first layer's particle count once a second")
    ap.add_argument("--seeds", type=int, default=0, help="N jittered trajectories per row, and their median [range]")
    ap.add_argument("--first-seed", type=int, default=0, help="--seeds counts from this seed (rerun one: --seeds 1)")
    a = ap.parse_args()
    print(
        f"method model n walls | p1/hyd p2/hyd | y1/d | slope (means over the last {AVERAGE_S:g} s) | vmax (after t/4) | "
        "KE 2nd third -> last third [J] | proj | settled | wall s"
    )
    for model in a.models:
        for method in a.methods:
            runs = []
            for seed in range(a.first_seed, a.first_seed + a.seeds) if a.seeds else [None]:
                o = tank(method, model, a.r, a.t, where=a.where, seed=seed)
                runs.append(o)
                print(
                    f"{o['method']:6s} {o['model']:14s} {o['n']:5d} {o['walls']:6d} | {o['first_p']:.3f} {o['second_p']:.3f} | "
                    f"{o['first_h_d']:.3f} | {o['slope']:+.3%} | {o['vmax']:.3f} ({o['vmax_late']:.3f}) | "
                    f"{o['energy'][0]:.4f} -> {o['energy'][1]:.4f} | {o['projections']} | {o['settle']} | {o['wall_s']:.0f}"
                    + (f" | seed {seed}" if seed is not None else ""),
                    flush=True,
                )
                if a.where:
                    print_where(o["places"])
                if a.layers:
                    print(f"  first layer at t = 0, 1, 2, ... s: {o['floor_layer']} particles", flush=True)
            if len(runs) > 1:
                print_spread(runs)
