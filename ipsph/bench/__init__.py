"""Benchmark support: the SPlisHSPlasH peer runner (``peer``) and machine-load bookkeeping (``machine``).

Nothing here is imported by the solver; pySPlisHSPlasH is only ever imported inside the peer's worker
subprocess (``_peer_worker``), and only when it is installed.
"""
