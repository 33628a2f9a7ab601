"""Time-step convergence: halving dt shrinks the free-surface error at the integrator's order.

A block thrown upwards with no walls falls freely: no pressure acts (the lattice starts
under-dense and moves rigidly, so every constraint is inactive and D rho/Dt = 0), and its free
surface, the top layer, follows y0 + v0 t - g t^2 / 2. All three methods integrate with the same
semi-implicit Euler step (v += dt g; x += dt v, or PF's inertial target s = x + dt v + dt^2 g,
the same map), whose error at time T is g dt T / 2: first order. The measured order is log2 of
the error ratio at dt and dt/2.
"""

import math

import pytest

from ipsph.scene import scene_from_dict
from ipsph.simulation import Simulation, sample_scene

# runs at several time steps: the full suite only
pytestmark = pytest.mark.slow

G = 9.81
T = 0.24  # s: a whole number of steps at every dt below
V0 = 1.5  # m/s upwards
DTS = (0.008, 0.004, 0.002)
# The truncation error is the only error, so the order is 1 to round-off (1e-9 here); 0.05 still
# tells it from a second-order integrator (2) or from a dt-independent error such as a stray
# force (0).
ORDER_TOL = 0.05


def _surface_error(method: str, dt: float) -> float:
    scene = scene_from_dict(
        {
            "simulation": {"method": method, "particle_radius": 0.025, "end_time": T},
            "time_step": {"dt_min": dt, "dt_max": dt, "dt_initial": dt},
            "fluid": [{"box": {"min": [0, 0, 0], "max": [0.3, 0.3, 0.3]}, "velocity": [0.0, V0, 0.0]}],
        },
        name="thrown-block",
    )
    sim = Simulation(scene, *sample_scene(scene)[:3])
    y0 = sim.positions[:, 1].max()
    sim.run(end_time=T, fps=25)
    assert sim.steps == round(T / dt)
    exact = y0 + V0 * T - 0.5 * G * T * T
    return abs(sim.positions[:, 1].max() - exact)


@pytest.mark.parametrize("method", ["ipsph", "pf", "dfsph"])
def test_free_surface_error_is_first_order_in_dt(method):
    errors = [_surface_error(method, dt) for dt in DTS]
    orders = [math.log2(a / b) for a, b in zip(errors, errors[1:])]
    assert all(abs(p - 1.0) <= ORDER_TOL for p in orders), f"{method}: errors {errors}, orders {orders}"
    # and the error is the semi-implicit Euler's g dt T / 2 (10 % for the top layer's rounding)
    assert errors[-1] == pytest.approx(0.5 * G * DTS[-1] * T, rel=0.1)
