"""The on-disk cache of sampled particles ($IPSPH_CACHE_DIR, else ~/.cache/ipsph): fluid lattices
and wall samples keyed by everything that decides them, written atomically, read only if sane."""

from __future__ import annotations

import hashlib
import os
import tempfile
from pathlib import Path

import numpy as np


def cache_dir() -> Path:
    """$IPSPH_CACHE_DIR, else ~/.cache/ipsph."""
    env = os.environ.get("IPSPH_CACHE_DIR")
    return Path(env).expanduser() if env else Path.home() / ".cache" / "ipsph"


def cache_key(kind: str, spec, radius: float, version: str, mesh_path: Path | None) -> str:
    """sha256 over kind, sampler version, radius, geometry (box corners or mesh bytes), transform, flags."""
    h = hashlib.sha256()

    def put(*items):
        for it in items:
            h.update(repr(it).encode())
            h.update(b"\0")

    t = spec.transform
    put(
        version,
        kind,
        float(radius).hex(),
        spec.shape,
        tuple(float(v).hex() for v in t.translate),
        tuple(float(v).hex() for v in t.scale),
        tuple(float(v).hex() for v in t.rotate_axis),
        float(t.rotate_deg).hex(),
        getattr(spec, "allow_open_mesh", None),
    )
    if spec.shape == "box":
        put(tuple(float(v).hex() for v in spec.box_min), tuple(float(v).hex() for v in spec.box_max))
    else:
        path = mesh_path.expanduser().resolve()
        put(path.suffix.lower())
        try:
            h.update(hashlib.sha256(path.read_bytes()).digest())
        except OSError:
            put("unreadable", str(path))  # the sampler itself raises MeshError
    return h.hexdigest()


def read(path: Path) -> np.ndarray | None:
    try:
        arr = np.load(path, allow_pickle=False)
    except Exception:  # noqa: BLE001 - missing or unreadable: resample
        return None
    if arr.dtype != np.float64 or arr.ndim != 2 or arr.shape[1] != 3 or not np.all(np.isfinite(arr)):
        return None
    return np.ascontiguousarray(arr)


def write(path: Path, arr: np.ndarray) -> None:
    """Best effort: temp file + atomic rename, so a reader never sees a partial file."""
    tmp = None
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=path.stem, suffix=".tmp", dir=path.parent)
        with os.fdopen(fd, "wb") as fh:
            np.save(fh, arr, allow_pickle=False)
        os.replace(tmp, path)
        tmp = None
    except Exception:  # noqa: BLE001 - a cache that cannot be written only costs time
        pass
    finally:
        if tmp is not None:
            try:
                os.unlink(tmp)
            except OSError:
                pass


def cached(key: str, sample) -> np.ndarray:
    """The array stored under `key`, else sample() (stored for next time)."""
    path = cache_dir() / f"{key}.npy"
    hit = read(path)
    if hit is not None:
        return hit
    arr = np.ascontiguousarray(sample(), dtype=np.float64)
    write(path, arr)
    return arr
