"""Backends: where the particle arrays live and the per-particle passes run (`base.Backend`).

    be = get_backend("cpu")

Adding one: subclass `base.Backend` in a module of this package, launch the bodies of
`bodies` for every particle, and add it to `BACKENDS` (imported on first use, so a backend's
dependencies load only when it is chosen).
"""
from __future__ import annotations

import importlib

from .base import Backend, Densities

BACKENDS = {"cpu": "ipsph.backends.cpu:CPUBackend"}


def get_backend(name: str = "cpu") -> Backend:
    if name not in BACKENDS:
        raise ValueError(f"unknown backend {name!r}: use one of {', '.join(BACKENDS)}")
    module, cls = BACKENDS[name].split(":")
    return getattr(importlib.import_module(module), cls)()


__all__ = ["BACKENDS", "Backend", "Densities", "get_backend"]
