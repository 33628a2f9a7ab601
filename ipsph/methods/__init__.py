"""The methods behind one interface: `METHODS[name](scene, state, boundary, search, backend, mf)`.

Each class names itself (`name`, one of `ipsph.params.METHOD_NAMES`) and its timed phases
(`phases`, keys of `ipsph.params.PHASES`); this registry is built from the classes.
"""

from ..config import Method as MethodName
from ..params import PHASES
from .dfsph import DFSPH
from .ipsph import IPSPH
from .pf import PF

METHODS = {MethodName(cls.name): cls for cls in (IPSPH, PF, DFSPH)}

if set(METHODS) != set(MethodName) or any(p not in PHASES for cls in METHODS.values() for p in cls.phases):
    raise ImportError(
        "ipsph.methods: every name in params.METHOD_NAMES needs a class here, and every phase a line in params.PHASES"
    )

__all__ = ["METHODS", "IPSPH", "PF", "DFSPH"]
