"""What a mesh reader hands over, checked before any VTK filter touches it: finite vertices, and
faces that name only vertices the file has (a bad index crashes the filters or reads garbage). For
an OBJ file the offending line is named."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from ipsph.errors import MeshError


def _blocks(data):
    import pyvista as pv

    if isinstance(data, pv.MultiBlock):
        for block in data:
            if block is not None:
                yield from _blocks(block)
    else:
        yield data


def _connectivity(block):
    """(kind, offsets, connectivity) of each explicit cell array of a PolyData or UnstructuredGrid."""
    from vtkmodules.util.numpy_support import vtk_to_numpy

    getters = ("GetVerts", "GetLines", "GetPolys", "GetStrips") if hasattr(block, "GetPolys") else ("GetCells",)
    for name in getters:
        cells = getattr(block, name, lambda: None)()
        if cells is None or not hasattr(cells, "GetConnectivityArray") or cells.GetNumberOfCells() == 0:
            continue
        kind = {"GetVerts": "vertex", "GetLines": "line", "GetPolys": "face", "GetStrips": "strip"}.get(name, "cell")
        yield kind, vtk_to_numpy(cells.GetOffsetsArray()), vtk_to_numpy(cells.GetConnectivityArray())


def check_read(data, where: str, path: Path | None = None) -> None:
    """Refuse what a reader hands over but no filter can use (MeshError, one line naming the file):
    a vertex that is not a finite number, or a face naming a vertex the file does not have. For an
    OBJ file the line is named."""
    for block in _blocks(data):
        if block.n_points:
            pts = np.asarray(block.points, dtype=np.float64)
            bad = np.flatnonzero(~np.isfinite(pts).all(axis=1))
            if len(bad):
                i = int(bad[0])
                at = _obj_line(path, "v", i) if path is not None else None
                first = at or f"point {i} = ({', '.join(f'{float(c):.6g}' for c in pts[i])})"
                many = "1 vertex has" if len(bad) == 1 else f"{len(bad)} vertices have"
                raise MeshError(
                    f"mesh {where}: {many} a coordinate that is not a finite number (NaN or inf), "
                    f"the first {first}; fix the file"
                )
        for kind, offsets, conn in _connectivity(block):
            wrong = np.flatnonzero((conn < 0) | (conn >= block.n_points))
            if len(wrong):
                at = _obj_line(path, "f") if path is not None else None
                if at is None:
                    c = int(np.searchsorted(offsets, wrong[0], side="right") - 1)
                    at = f"{kind} {c} names point {int(conn[wrong[0]])}, but the mesh has {block.n_points} points"
                raise MeshError(f"mesh {where}: {at}; fix the file: its faces may name only the vertices it lists")


def _obj_line(path: Path | None, what: str, index: int = 0) -> str | None:
    """Where an OBJ file goes wrong: what = "v": the line of its `index`-th vertex (0-based) when
    that has a coordinate that is not finite; "f": the first face (or line, point) naming a vertex
    the file does not have. None when the file is no OBJ or says nothing of the kind."""
    if path is None or Path(path).suffix.lower() != ".obj":
        return None
    try:
        lines = Path(path).read_text(encoding="utf-8", errors="replace").splitlines()
    except OSError:
        return None
    n_v = sum(1 for ln in lines if ln.split(maxsplit=1)[:1] == ["v"])
    seen = 0
    for no, ln in enumerate(lines, 1):
        tok = ln.split()
        if not tok:
            continue
        shown = ln.strip() if len(ln.strip()) <= 60 else ln.strip()[:57] + "..."
        if tok[0] == "v":
            if what == "v" and seen == index:
                try:
                    finite = all(math.isfinite(float(c)) for c in tok[1:4])
                except ValueError:
                    finite = False
                return None if finite else f"on line {no} ({shown!r})"
            seen += 1
        elif what == "f" and tok[0] in ("f", "l", "p"):
            for t in tok[1:]:
                try:
                    k = int(t.split("/")[0])
                except ValueError:
                    return f"line {no} ({shown!r}) names vertex {t.split('/')[0]!r}, which is not a number"
                idx = k if k > 0 else seen + k + 1  # negative: counted back from the last vertex so far
                if k == 0 or not 1 <= idx <= n_v:
                    why = "OBJ counts vertices from 1" if k == 0 else f"the file has {n_v} vertices (v lines)"
                    return f"line {no} ({shown!r}) names vertex {k}, but {why}"
    return None
