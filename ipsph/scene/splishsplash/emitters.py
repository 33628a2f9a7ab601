"""SPlisHSPlasH `Emitters` and the fluid block's emitter box -> [[emitter]] tables and [domain].

SPlisHSPlasH (doc/file_format.md, Emitter.cpp): `width` and `height` count particles (the
layer is width x height lattice points of spacing 2r; a circle (type 1) keeps those of a
width x width square within 0.5 * width * 2r of its centre); the emitter's rotation (rotationAxis,
rotationAngle in radians) maps x to the emission direction, y to the height axis and z to the
width axis; `velocity` is the speed along it; emitStartTime / emitEndTime bound the emission
(end default REAL_MAX: until the run ends). `emitterReuseParticles` with emitterBoxMin/Max
recycles the particles that leave that box: ipsph removes them ([domain]) and emits fresh ones
with new ids. `maxEmitterParticles` is not needed (ipsph plans the capacity from the rates).
"""

from __future__ import annotations

import math

import numpy as np

from ...params import spacing

_KEYS = (
    "width",
    "height",
    "translation",
    "rotationAxis",
    "rotationAngle",
    "velocity",
    "emitStartTime",
    "emitEndTime",
    "type",
    "id",
)
MATERIAL_KEYS = ("maxEmitterParticles", "emitterReuseParticles", "emitterBoxMin", "emitterBoxMax")
_REAL_MAX = 1e30  # emitEndTime at or above this: SPlisHSPlasH's "never" (REAL_MAX)


def _rotation(axis, angle: float) -> np.ndarray:
    """Rodrigues: the rotation by `angle` (radians) about `axis`."""
    a = np.asarray(axis, dtype=np.float64)
    n = np.linalg.norm(a)
    if n == 0.0 or angle == 0.0:
        return np.eye(3)
    k = a / n
    kx = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + math.sin(angle) * kx + (1.0 - math.cos(angle)) * kx @ kx


def emitter(imp, i: int, e: dict, radius: float) -> dict:
    """One [[emitter]] table from SPlisHSPlasH's Emitters[i] (`imp`: the importer's checks)."""
    label = f"Emitters[{i}]"
    d = spacing(radius)
    kind = imp.int_(e.get("type", 0), f"{label}.type")
    if kind not in (0, 1):
        raise imp.fail(f"{label}.type", f"{kind} is not an emitter type (0: box, 1: circle)")
    width = imp.int_(e.get("width", 5), f"{label}.width")
    height = imp.int_(e.get("height", 5), f"{label}.height")
    for key, n in (("width", width), ("height", height)):
        if n < 1 and (key == "width" or kind == 0):
            raise imp.fail(f"{label}.{key}", f"{n}: an emitter needs at least 1 particle across")
    rot = _rotation(
        imp.vec3(e.get("rotationAxis", [0, 0, 1]), f"{label}.rotationAxis"),
        imp.num(e.get("rotationAngle", 0.0), f"{label}.rotationAngle"),
    )
    entry = {
        "name": f"emitter{i}",
        "shape": "box" if kind == 0 else "circle",
        "position": imp.vec3(e.get("translation", [0, 0, 0]), f"{label}.translation"),
        "direction": [float(c) for c in rot[:, 0]],
        "velocity": imp.num(e.get("velocity", 1.0), f"{label}.velocity"),
        "start_time": imp.num(e.get("emitStartTime", 0.0), f"{label}.emitStartTime"),
    }
    if kind == 0:
        entry.update(width=width * d, height=height * d, height_axis=[float(c) for c in rot[:, 1]])
    else:
        entry["radius"] = 0.5 * width * d
    if "emitEndTime" in e:
        end = imp.num(e["emitEndTime"], f"{label}.emitEndTime")
        if end < _REAL_MAX:
            entry["end_time"] = end
    for key, value in e.items():
        if key not in _KEYS:
            imp.ignore("Emitters", key, value, index=i)
    return entry


def domain(imp, materials: list[tuple[str, dict]]) -> dict | None:
    """[domain] from a material's emitterReuseParticles + emitterBoxMin/Max (None without)."""
    for label, mat in materials:
        if "emitterReuseParticles" in mat and imp.bool_(mat["emitterReuseParticles"], f"{label}.emitterReuseParticles"):
            lo = imp.vec3(mat.get("emitterBoxMin", [-1, -1, -1]), f"{label}.emitterBoxMin")
            hi = imp.vec3(mat.get("emitterBoxMax", [1, 1, 1]), f"{label}.emitterBoxMax")
            return {"min": lo, "max": hi}
    return None
