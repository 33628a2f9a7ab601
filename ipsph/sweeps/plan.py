"""The sweep's output folder: which members a run has left to do (`plan`: fresh, --resume,
--overwrite) and creating or clearing it (`prepare`).
"""

from __future__ import annotations

import shutil
from pathlib import Path

from ..errors import OutputError
from ..io import RUN_JSON, check_writable
from . import member as mem
from . import records
from .spec import Sweep


def _member_entry(sweep: Sweep, m) -> dict:
    return {
        "name": m.name,
        "folder": m.name,
        "parameters": m.params(),
        "varied": dict(m.varied),
        "status": "pending",
        "exit_code": None,
        "reason": None,
        "wall_seconds": None,
        "threads": None,
        "host": None,
        "attempts": 0,
    }


def plan(sweep: Sweep, out: Path, resume: bool, overwrite: bool) -> tuple[list[dict], list[str]]:
    """(records of every member, names of the members to run); raises OutputError (exit 2) on a conflict.

    Creates nothing and deletes nothing (see `prepare`)."""
    if out.exists() and not out.is_dir():
        raise OutputError(f"output folder {out} (resolved {out.resolve()}) is a file; choose another -o")
    fresh = {m.name: _member_entry(sweep, m) for m in sweep.members}
    old = records.read_sweep_json(out) if out.is_dir() else None
    if (out / records.SWEEP_JSON).exists() and old is None and not overwrite:
        raise OutputError(f"{out / records.SWEEP_JSON} cannot be read; pass --overwrite to start the sweep afresh")
    if old is not None and not overwrite:
        old_members = {r["name"]: r for r in old.get("members", [])}
        why = None
        if old.get("scene") != str(sweep.scene):
            why = f"its base scene was {old.get('scene')}, now {sweep.scene}"
        elif set(old_members) != set(fresh):
            gone = sorted(set(old_members) - set(fresh))
            new = sorted(set(fresh) - set(old_members))
            why = "members " + ", ".join([f"{n} removed" for n in gone[:2]] + [f"{n} added" for n in new[:2]])
        else:
            for n, r in fresh.items():
                if old_members[n].get("parameters") != records.to_jsonable(r["parameters"]):
                    why = f"member {n} has other parameters"
                    break
        if why:
            raise OutputError(
                f"{out} holds a different sweep ({why}); pass --overwrite to replace it or choose another -o"
            )
        recs = []
        for n, r in fresh.items():
            o = old_members[n]
            r.update(
                {
                    k: o.get(k)
                    for k in ("status", "exit_code", "reason", "wall_seconds", "threads", "host", "attempts", "resumed")
                }
            )
            recs.append(r)
    else:
        recs = list(fresh.values())
        if not overwrite:
            for r in recs:
                if (out / r["name"] / RUN_JSON).exists():
                    raise OutputError(
                        f"{out / r['name']} holds an earlier run that is not part of a sweep in "
                        f"{out}; pass --overwrite to replace it or choose another -o"
                    )
    if overwrite:
        for r in recs:
            r.update(_member_entry(sweep, next(m for m in sweep.members if m.name == r["name"])))
        return recs, [r["name"] for r in recs]
    todo = []
    for r in recs:
        if mem.folder_state(out / r["name"]) == "completed":
            r["status"] = "completed"
        else:
            if r["status"] in ("completed", "running"):
                r["status"] = "pending"
            todo.append(r["name"])
    if old is not None and todo and len(todo) < len(recs) and not resume:
        raise OutputError(
            f"{out} holds an unfinished sweep ({len(recs) - len(todo)} of {len(recs)} members "
            f"completed); pass --resume to run the other {len(todo)}, or --overwrite to start afresh"
        )
    if (
        old is not None
        and todo
        and len(todo) == len(recs)
        and not resume
        and any(mem.folder_state(out / n) != "empty" for n in todo)
    ):
        raise OutputError(
            f"{out} holds an unfinished sweep (no member completed); pass --resume to continue "
            f"it, or --overwrite to start afresh"
        )
    return recs, todo


def prepare(sweep: Sweep, out: Path, overwrite: bool, recs: list[dict], old: dict | None) -> None:
    """Create OUT (checking it is writable); with --overwrite delete the earlier sweep's member folders."""
    check_writable(out)
    if overwrite:
        names = {r["name"] for r in recs} | {r["name"] for r in (old or {}).get("members", [])}
        for n in names:
            if n and "/" not in n and n not in (".", ".."):
                shutil.rmtree(out / n, ignore_errors=True)
        for f in (records.SWEEP_JSON, records.SUMMARY_CSV):
            (out / f).unlink(missing_ok=True)
