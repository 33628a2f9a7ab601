"""PNG files of rendered frames."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np


def save_png(img: np.ndarray, path) -> Path:
    """PNG through `ipsph.post.render.splat.encode_png` (Up filter, zlib level 1: ~2.5x faster than Pillow's
    fastest level here), renamed into place so a viewer never sees half a file; parent folders
    are created. Releases the GIL for most of its time (the filter is nogil, zlib too)."""
    from .splat import encode_png

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    data = encode_png(np.ascontiguousarray(np.asarray(img)[..., :3]))
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    try:
        tmp.write_bytes(data)
        os.replace(tmp, path)
    finally:
        if tmp.exists():
            tmp.unlink()
    return path
