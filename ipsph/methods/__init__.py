"""The three methods behind one interface: `METHODS[name](scene, state, boundary, search)`."""
from ..model import Method as MethodName
from .dfsph import DFSPH
from .ipsph import IPSPH
from .pf import PF

METHODS = {MethodName.IPSPH: IPSPH, MethodName.PF: PF, MethodName.DFSPH: DFSPH}

__all__ = ["METHODS", "IPSPH", "PF", "DFSPH"]
