"""Gauges: time series of pressure, velocity, density, water level, wall forces and flow at chosen
places, during a run (gauges.csv) and on a finished run's frames (`ipsph gauge`); docs/gauges.md.

    sampler.Gauges   the [[gauge]] tables as columns, and their values for one state of the fluid
    kernels          the numerics (numba), reading the fluid at the precision frames store it
    walls            a force gauge's wall particles, in one order for a run and its frames
    log, recorder    gauges.csv and its reader; GaugeLog, a Simulation's gauges (file or memory)
    replay, plot     `ipsph gauge` on a finished run's frames; plots/gauges.png

    from ipsph.gauges import GaugeLog, read_gauges
"""

from .log import read_gauges
from .recorder import GaugeLog
from .sampler import Gauges

__all__ = ["GaugeLog", "Gauges", "read_gauges"]
