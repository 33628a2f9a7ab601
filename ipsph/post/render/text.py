"""Text in renders: the font, the speed scalar bar, and labels drawn into a finished image."""

from __future__ import annotations

import functools
import os

import numpy as np

from .style import SCALAR_BAR_LENGTH, SCALAR_BAR_POSITION, SPEED_TITLE


@functools.cache
def _font_file() -> str | None:
    """DejaVu Sans as matplotlib ships it, found without importing matplotlib (~0.3 s)."""
    import importlib.util

    spec = importlib.util.find_spec("matplotlib")
    for folder in (spec.submodule_search_locations or []) if spec else []:
        path = os.path.join(folder, "mpl-data", "fonts", "ttf", "DejaVuSans.ttf")
        if os.path.isfile(path):
            return path
    return None


def _set_font(prop) -> None:
    """DejaVu Sans from matplotlib's data (VTK's embedded font draws '[' like '(')."""
    font = _font_file()
    if font:
        prop.SetFontFamily(4)  # VTK_FONT_FILE
        prop.SetFontFile(font)
    else:
        prop.SetFontFamilyToArial()


def _scalar_bar(lut, scale: float = 1.0):
    """Vertical bar on the right, white text, title "speed [m/s]", five labels."""
    from vtkmodules.vtkRenderingAnnotation import vtkScalarBarActor

    bar = vtkScalarBarActor()
    bar.SetLookupTable(lut)
    bar.SetTitle(SPEED_TITLE)
    bar.SetNumberOfLabels(5)
    bar.SetLabelFormat("%.2f")
    bar.SetMaximumNumberOfColors(256)
    bar.SetOrientationToVertical()
    bar.SetTextPositionToSucceedScalarBar()  # labels right of the bar, never over it
    bar.GetPositionCoordinate().SetCoordinateSystemToNormalizedViewport()
    bar.GetPositionCoordinate().SetValue(*SCALAR_BAR_POSITION)
    bar.SetWidth(0.09)
    bar.SetHeight(SCALAR_BAR_LENGTH)
    bar.SetBarRatio(0.3)
    bar.SetVerticalTitleSeparation(round(14 * scale))
    bar.SetTextPad(round(6 * scale))
    bar.UnconstrainedFontSizeOn()
    for prop, size in ((bar.GetTitleTextProperty(), 20), (bar.GetLabelTextProperty(), 16)):
        prop.SetColor(1.0, 1.0, 1.0)
        prop.SetFontSize(max(round(size * scale), 6))
        _set_font(prop)
        prop.ShadowOff()
        prop.BoldOff()
        prop.ItalicOff()
    return bar


def _draw_text(img: np.ndarray, text: str, prop, position: tuple[int, int]) -> None:
    """Alpha-blend `text`, rasterised by VTK's FreeType text renderer with the text property of
    the label actor (same font, size and colour), into `img` with its bottom-left at `position`
    (display pixels, y up), as a vtkTextActor at that position would draw it."""
    import vtkmodules.vtkRenderingFreeType  # noqa: F401 - registers the FreeType text renderer
    from vtkmodules.util.numpy_support import vtk_to_numpy
    from vtkmodules.vtkCommonDataModel import vtkImageData
    from vtkmodules.vtkRenderingCore import vtkTextRenderer

    tr = vtkTextRenderer()
    data = vtkImageData()
    dims = [0, 0]
    if not tr.RenderString(prop, text, data, dims, 72):
        return
    nx, ny, _ = data.GetDimensions()
    rgba = vtk_to_numpy(data.GetPointData().GetScalars()).reshape(ny, nx, -1)[::-1].astype(np.float32)
    h, w = img.shape[:2]
    x0, top = position[0], h - position[1] - ny  # rows of the text image, top down
    ys, xs = slice(max(top, 0), min(top + ny, h)), slice(max(x0, 0), min(x0 + nx, w))
    patch = rgba[ys.start - top : ys.stop - top, xs.start - x0 : xs.stop - x0]
    a = patch[..., 3:4] / 255.0
    dst = img[ys, xs].astype(np.float32)
    img[ys, xs] = np.clip(patch[..., :3] * a + dst * (1.0 - a) + 0.5, 0, 255).astype(np.uint8)
