"""ipsph: Incompressible Projective SPH (and the PF and DFSPH references) in Numba."""

from ._version import __version__

__all__ = ["__version__", "Simulation", "load_scene", "sweep"]


def __getattr__(name):  # lazy: importing ipsph must stay cheap and side-effect free
    if name == "Simulation":
        from .simulation import Simulation

        return Simulation
    if name == "load_scene":
        from .scene import load_scene

        return load_scene
    if name == "sweep":
        from .sweeps import sweep

        return sweep
    raise AttributeError(name)
