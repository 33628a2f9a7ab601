"""Backends: where the particle arrays live and the per-particle passes run (`base.Backend`).

    be = get_backend("cpu")

Adding one: subclass `base.Backend` in a module of this package, launch the bodies of
`bodies` for every particle, and add it to `BACKENDS` (imported on first use, so a backend's
dependencies load only when it is chosen).
"""

from __future__ import annotations

import importlib

from ..params import BACKEND_NAMES
from .base import Backend, Densities

BACKENDS = {"cpu": "ipsph.backends.cpu:CPUBackend", "cuda": "ipsph.backends.cuda:CUDABackend"}


assert tuple(BACKENDS) == BACKEND_NAMES, "params.BACKEND_NAMES and BACKENDS must list the same backends"


def get_backend(name: str = "cpu", precision: str = "float64", device: int = 0) -> Backend:
    """The backend `name` with real arrays of `precision`, on `device` (CUDA: the GPU's number).
    ConfigError (exit 2) when it cannot run here: the message names what is missing."""
    if name not in BACKENDS:
        raise ValueError(f"unknown backend {name!r}: use one of {', '.join(BACKENDS)}")
    module, cls = BACKENDS[name].split(":")
    return getattr(importlib.import_module(module), cls)(precision=precision, device=device)


__all__ = ["BACKENDS", "Backend", "Densities", "get_backend"]
