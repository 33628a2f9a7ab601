"""The package version, in a module of its own so that any module can read it without importing
the `ipsph` package facade (which lazily reaches the top layers: Simulation, load_scene, sweep)."""

__version__ = "0.1.0"
