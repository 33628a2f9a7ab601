"""The headless GL stack: EGL before the first render window, and a probe in a subprocess
(a missing GL stack segfaults, so the probe must not run in the caller)."""

from __future__ import annotations

import functools
import os
import signal
import subprocess
import sys

GL_HINT = "install an EGL + Mesa stack (apt-get install -y --no-install-recommends libegl1 libgl1-mesa-dri)"


_PROBE = """
import os
os.environ["VTK_DEFAULT_OPENGL_WINDOW"] = "vtkEGLRenderWindow"
import vtkmodules.vtkRenderingOpenGL2
from vtkmodules.vtkCommonCore import vtkUnsignedCharArray
from vtkmodules.vtkFiltersSources import vtkSphereSource
from vtkmodules.vtkRenderingCore import vtkActor, vtkPolyDataMapper, vtkRenderer, vtkRenderWindow
src = vtkSphereSource()
mapper = vtkPolyDataMapper()
mapper.SetInputConnection(src.GetOutputPort())
actor = vtkActor()
actor.SetMapper(mapper)
ren = vtkRenderer()
ren.AddActor(actor)
win = vtkRenderWindow()
win.SetOffScreenRendering(True)
win.SetMultiSamples(0)
win.SetSize(32, 24)
win.AddRenderer(ren)
win.Render()
buf = vtkUnsignedCharArray()
win.GetPixelData(0, 0, 31, 23, 1, buf, 0)
assert buf.GetNumberOfTuples() == 32 * 24 and max(buf.GetRange(0)) > 0, "blank probe image"
win.Finalize()
print("ok")
"""


def _use_egl() -> None:
    os.environ.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")


@functools.cache
def gl_available(timeout: float = 60.0) -> tuple[bool, str]:
    """Can this machine render offscreen?  (ok, reason); probed once per process, in a subprocess.

    A missing GL stack segfaults VTK instead of raising, so the probe renders a 32x24 frame in a
    child process and reports how it died.
    """
    env = dict(os.environ)
    env.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")
    try:
        proc = subprocess.run([sys.executable, "-c", _PROBE], env=env, capture_output=True, text=True, timeout=timeout)
    except subprocess.TimeoutExpired:
        return False, f"offscreen GL probe did not finish in {timeout:.0f} s; {GL_HINT}"
    except OSError as exc:
        return False, f"cannot start the offscreen GL probe: {exc}"
    if proc.returncode == 0 and proc.stdout.strip().endswith("ok"):
        return True, "offscreen rendering available"
    if proc.returncode < 0:
        try:
            name = signal.Signals(-proc.returncode).name
        except ValueError:
            name = f"signal {-proc.returncode}"
        return False, f"offscreen GL probe crashed ({name}): no usable GL/EGL stack; {GL_HINT}"
    lines = [ln.strip() for ln in (proc.stderr or proc.stdout).splitlines() if ln.strip()]
    last = lines[-1] if lines else f"exit status {proc.returncode}"
    return False, f"offscreen GL probe failed ({last[:200]}); {GL_HINT}"
