"""Fluid entering and leaving the scene: emitters ([[emitter]]), sinks ([[sink]]) and the domain box.

Emitters follow SPlisHSPlasH's `Emitters`: a box (width x height) or circular nozzle at
`position` emits one layer of particles on the lattice of spacing d = 2r across its outlet
every d / v seconds, from start_time until end_time, moving along `direction` at speed v.
Layer k is due at t_k = start_time + k d / v; it is placed after the first step that ends at or
after t_k, at (t - t_k) v ahead of the outlet (where it would be had it left on time), but never
closer than d to the fluid already in front of the nozzle (the previous layer): a layer that
has no room (the fluid in front was pushed back) waits for the next step, and is counted as
late. So the emitted mass by time T is the number of due layers times the layer's mass,
rho0 (2r)^3 per particle: rate x time to within one layer. Like SPlisHSPlasH's emitter, fluid
in the nozzle's guide region (from d/2 behind the outlet to one support radius H in front of it,
across the nozzle plus d/2) leaves every step at the emitter's velocity, so the layers leave the
nozzle at the requested speed whatever the pressure in front of it.

Sinks (axis-aligned outflow boxes) remove the fluid inside them after every step, and the
domain box removes the fluid outside it. Removal is a compaction of every per-particle array
(`ParticleState.keep`); ids are never reused: new particles take ids above every id ever used.

Capacity: everything a run can hold is planned before it starts (`capacity`): the initial
fluid plus every layer every emitter can emit by simulation.end_time, checked against
--max-particles by the preflight. The methods allocate their scratch at that capacity and work
on views of the active count n (`Method.resize`); a scene without emitters has capacity n and
runs exactly as before.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .boundary.containers import container_boxes
from .config import EmitterSpec, Scene
from .errors import ConfigError
from .params import BYTES_PER_PARTICLE, spacing


def _unit(v) -> np.ndarray:
    a = np.asarray(v, dtype=np.float64)
    return a / np.linalg.norm(a)


@dataclass(frozen=True)
class Nozzle:
    """One emitter resolved at a particle radius: its frame, the layer's lattice and its schedule."""

    spec: EmitterSpec
    origin: np.ndarray  # (3,) outlet centre
    axis: np.ndarray  # (3,) unit emission direction e
    across: np.ndarray  # (2, 3) the outlet's width and height directions (unit, perpendicular to e)
    offsets: np.ndarray  # (k, 2) the layer's lattice points in (width, height) coordinates [m]
    half: np.ndarray  # (2,) box: half extents of the guide's cross-section; circle: (R, R)
    interval: float  # d / v: seconds between layers
    start: float
    end: float  # last time a layer may be due
    layers: int  # layers due by `end`

    @property
    def per_layer(self) -> int:
        return len(self.offsets)

    @property
    def velocity(self) -> np.ndarray:
        return self.spec.velocity * self.axis

    def due(self, t: float) -> int:
        """Layers due by time t (t_k <= t), at most `layers`."""
        if t < self.start - 1e-12 * max(1.0, self.start):
            return 0
        return min(self.layers, int(math.floor((min(t, self.end) - self.start) / self.interval + 1e-9)) + 1)

    def layer_points(self, ahead: float) -> np.ndarray:
        """The layer's positions `ahead` metres in front of the outlet."""
        return (
            self.origin
            + ahead * self.axis
            + self.offsets[:, :1] * self.across[0]
            + self.offsets[:, 1:] * self.across[1]
        )

    def local(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(along-axis coordinate s, lateral coordinates (n, 2)) of points relative to the outlet."""
        rel = x - self.origin
        return rel @ self.axis, rel @ self.across.T

    def in_section(self, lateral: np.ndarray, margin: float) -> np.ndarray:
        """Points whose lateral coordinates lie within the nozzle's cross-section plus `margin`."""
        if self.spec.shape == "circle":
            return np.einsum("ij,ij->i", lateral, lateral) <= (self.half[0] + margin) ** 2
        return np.all(np.abs(lateral) <= self.half + margin, axis=1)


def nozzle(spec: EmitterSpec, r: float, end_time: float) -> Nozzle:
    d = spacing(r)
    e = _unit(spec.direction)
    if spec.shape == "box":
        hint = np.asarray(
            spec.height_axis
            if spec.height_axis is not None
            else ((0.0, 0.0, 1.0) if abs(e[1]) > 0.9 else (0.0, 1.0, 0.0)),
            dtype=np.float64,
        )
        h = _unit(hint - np.dot(hint, e) * e)
        w = np.cross(e, h)  # SPlisHSPlasH's rotation columns: direction, height, width
        nw, nh = (max(1, int(math.floor(x / d + 0.5))) for x in (spec.width, spec.height))
        gw, gh = np.meshgrid((np.arange(nw) - 0.5 * (nw - 1)) * d, (np.arange(nh) - 0.5 * (nh - 1)) * d, indexing="ij")
        offsets = np.column_stack([gw.ravel(), gh.ravel()])
        half = np.array([0.5 * nw * d, 0.5 * nh * d])
    else:
        hint = np.array((0.0, 0.0, 1.0) if abs(e[1]) > 0.9 else (0.0, 1.0, 0.0))
        h = _unit(hint - np.dot(hint, e) * e)
        w = np.cross(e, h)
        m = max(1, int(math.floor(2.0 * spec.radius / d + 0.5)))
        c = (np.arange(m) - 0.5 * (m - 1)) * d
        gw, gh = np.meshgrid(c, c, indexing="ij")
        offsets = np.column_stack([gw.ravel(), gh.ravel()])
        offsets = offsets[np.einsum("ij,ij->i", offsets, offsets) <= spec.radius**2 * (1 + 1e-12)]
        half = np.array([spec.radius, spec.radius])
    interval = d / spec.velocity
    end = min(spec.end_time if spec.end_time is not None else end_time, end_time)
    layers = int(math.floor((end - spec.start_time) / interval + 1e-9)) + 1
    return Nozzle(
        spec,
        np.asarray(spec.position, dtype=np.float64),
        e,
        np.stack([w, h]),
        offsets,
        half,
        interval,
        float(spec.start_time),
        float(end),
        layers,
    )


def nozzles(scene: Scene) -> list[Nozzle]:
    return [nozzle(e, scene.particle_radius, scene.end_time) for e in scene.emitters]


def planned_emission(scene: Scene) -> int:
    """Every particle the scene's emitters can emit by simulation.end_time."""
    return sum(n.layers * n.per_layer for n in nozzles(scene))


def check_capacity(scene: Scene, n_fluid: int, limit: int) -> int:
    """The planned capacity (initial fluid + emission); ConfigError naming the emitter over `limit`."""
    total = n_fluid
    for i, n in enumerate(nozzles(scene)):
        total += n.layers * n.per_layer
        if total > limit:
            raise ConfigError(
                f"emitter[{i}] '{n.spec.name}' would emit {n.layers * n.per_layer:,} particles ({n.per_layer} per "
                f"layer, {n.layers} layers from t = {n.start:g} to {n.end:g} s): with the rest the run needs "
                f"{total:,} particles ({total * BYTES_PER_PARTICLE / 2**30:.1f} GiB), over the limit of {limit:,} "
                f"(--max-particles); shorten emitter[{i}].end_time, lower its velocity or size, or add a sink"
            )
    return total


def extent_points(scene: Scene) -> np.ndarray:
    """Points the scene's extent must cover besides fluid and walls: nozzles, domain corners."""
    pts = [np.asarray(e.position, dtype=np.float64) for e in scene.emitters]
    if scene.domain.min is not None:
        pts += [np.asarray(scene.domain.min, dtype=np.float64), np.asarray(scene.domain.max, dtype=np.float64)]
    return np.array(pts).reshape(-1, 3)


def resumed_capacity(scene: Scene, n_now: int, flow_state: dict | None) -> int:
    """The capacity of a run resumed with `flow_state` (a checkpoint's): the particles it holds
    plus what the emitters still emit by this scene's end_time (--resume may give a later one)."""
    done = (flow_state or {}).get("emitted_layers") or [0] * len(scene.emitters)
    return n_now + sum(max(0, n.layers - k) * n.per_layer for n, k in zip(nozzles(scene), done))


def check_resumed_capacity(scene: Scene, n_now: int, flow_state: dict | None, limit: int) -> int:
    """ConfigError when a resumed run would exceed `limit` (--max-particles) by its end_time."""
    total = resumed_capacity(scene, n_now, flow_state)
    if total > limit:
        raise ConfigError(
            f"--resume: the run holds {n_now:,} particles and its emitters would add "
            f"{total - n_now:,} more by simulation.end_time = {scene.end_time:g} s: {total:,} in all, "
            f"over the limit of {limit:,} (--max-particles); resume with an earlier --end-time"
        )
    return total


def wall_notes(scene: Scene, boundary_x: np.ndarray) -> list[str]:
    """One line per nozzle whose first two layers would come closer than 2r to a wall particle
    (the layer would start inside the wall's support and be pushed off violently)."""
    from .geometry.points import nearest_distance

    notes = []
    d = scene.spacing
    for i, nz in enumerate(nozzles(scene)):
        pts = np.concatenate([nz.layer_points(0.0), nz.layer_points(d)])
        near = float(nearest_distance(pts, boundary_x, d).min()) if len(boundary_x) else math.inf
        if near < d:
            notes.append(
                f"emitter[{i}] '{nz.spec.name}': its first layers come within {near:.3g} m of a wall "
                f"(closer than 2r = {d:g} m): move the nozzle away from the wall or make it smaller"
            )
    return notes


def check_placement(scene: Scene) -> None:
    """Each nozzle's outlet inside a container's bounds or the domain box (ConfigError naming the key)."""
    if not scene.emitters:
        return
    boxes = container_boxes(scene.boundaries)
    dom = scene.domain
    if dom.min is not None:
        boxes.append((np.asarray(dom.min), np.asarray(dom.max)))
    for i, e in enumerate(scene.emitters):
        p = np.asarray(e.position)
        if not any(np.all(p >= lo) and np.all(p <= hi) for lo, hi in boxes):
            where = (
                "no container and no [domain] box"
                if not boxes
                else "outside every container's bounds" + (" and the [domain] box" if dom.min is not None else "")
            )
            raise ConfigError(
                f"emitter[{i}].position: [{', '.join(f'{c:g}' for c in p)}] of emitter "
                f"'{e.name}' is {where}; move it inside a [[boundary]] container or give a "
                f"[domain] box around it"
            )


class Flow:
    """The run-time side: emits due layers, keeps nozzles' guide regions at their velocity,
    removes the fluid in sinks and outside the domain. One call per step (`after_step`)."""

    def __init__(self, scene: Scene, first_id: int):
        check_placement(scene)
        self.scene = scene
        self.nozzles = nozzles(scene)
        self.d = scene.spacing
        self.h = scene.support
        self.mass = scene.fluid_mass
        self.sinks = [(np.asarray(s.box_min), np.asarray(s.box_max)) for s in scene.sinks]
        dom = scene.domain
        self.domain = None if dom.min is None else (np.asarray(dom.min), np.asarray(dom.max))
        self.emitted_layers = [0] * len(self.nozzles)
        self.late_layers = 0  # layers placed at least one step after they were due
        self.next_id = int(first_id)
        self.emitted = 0
        self.removed = 0

    @property
    def planned(self) -> int:
        return sum(n.layers * n.per_layer for n in self.nozzles)

    def remaining(self) -> int:
        """Particles still to be emitted."""
        return sum((n.layers - k) * n.per_layer for n, k in zip(self.nozzles, self.emitted_layers))

    def after_step(self, st, be, t: float) -> tuple[int, int]:
        """Remove, guide, emit at the end of a step at time t, on the state `st` of backend `be`;
        returns (emitted, removed) this step. The caller resizes the method when either is not 0."""
        removed = self._remove(st, be)
        x = be.to_host(st.x)
        v = np.array(be.to_host(st.v)) if self.nozzles else None
        guided = self._guide(t, x, v) if self.nozzles else False
        new_x, new_v = self._emit(t, x)
        if guided:
            st.v = be.asarray(v)
        if len(new_x):
            k = len(new_x)
            if st.n + k > st.capacity:  # the plan covers every layer: a bug, not bad input
                raise RuntimeError(f"emission beyond the planned capacity {st.capacity}")
            ids = np.arange(self.next_id, self.next_id + k, dtype=np.int64)
            st.append({"x": new_x, "v": new_v, "m": np.full(k, self.mass), "id": ids})
            self.next_id += k
            self.emitted += k
        return len(new_x), removed

    def _remove(self, st, be) -> int:
        if not self.sinks and self.domain is None or st.n == 0:
            return 0
        x = be.to_host(st.x)
        out = np.zeros(len(x), dtype=bool)
        for lo, hi in self.sinks:
            out |= np.all((x >= lo) & (x <= hi), axis=1)
        if self.domain is not None:
            out |= ~np.all((x >= self.domain[0]) & (x <= self.domain[1]), axis=1)
        k = int(out.sum())
        if k:
            st.keep(np.flatnonzero(~out))
            self.removed += k
        return k

    def _guide(self, t: float, x: np.ndarray, v: np.ndarray) -> bool:
        """Fluid in a nozzle's guide region moves at the emitter's velocity (as SPlisHSPlasH's)."""
        hit = False
        for nz in self.nozzles:
            if not (nz.start <= t <= nz.end + nz.interval):
                continue
            s, lat = nz.local(x)
            sel = (s >= -0.5 * self.d) & (s < self.h) & nz.in_section(lat, 0.5 * self.d)
            if sel.any():
                v[sel] = nz.velocity
                hit = True
        return hit

    def _emit(self, t: float, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        xs, vs = [np.zeros((0, 3))], [np.zeros((0, 3))]
        for j, nz in enumerate(self.nozzles):
            due = nz.due(t)
            if due <= self.emitted_layers[j]:
                continue
            # the fluid in front of the outlet, across the nozzle: the previous layers
            s, lat = nz.local(x)
            near = (s >= -0.5 * self.d) & nz.in_section(lat, 0.5 * self.d)
            room = float(s[near].min()) if near.any() else math.inf
            for k in range(self.emitted_layers[j], due):
                scheduled = (t - (nz.start + k * nz.interval)) * nz.spec.velocity
                ahead = min(scheduled, room - self.d)
                if ahead < -1e-9 * self.d:
                    break  # no room yet: the next step tries again
                ahead = max(ahead, 0.0)
                self.late_layers += ahead < scheduled - 1e-6 * self.d
                xs.append(nz.layer_points(ahead))
                vs.append(np.tile(nz.velocity, (nz.per_layer, 1)))
                room = ahead
                self.emitted_layers[j] = k + 1
        return np.concatenate(xs), np.concatenate(vs)

    # -- saved state ------------------------------------------------------------------------
    def state_dict(self) -> dict:
        return {
            "emitted_layers": list(self.emitted_layers),
            "next_id": self.next_id,
            "emitted": self.emitted,
            "removed": self.removed,
            "late_layers": self.late_layers,
        }

    def load_state_dict(self, d: dict) -> None:
        if len(d["emitted_layers"]) != len(self.nozzles):
            raise ValueError(f"the checkpoint has {len(d['emitted_layers'])} emitters, the scene {len(self.nozzles)}")
        self.emitted_layers = [int(k) for k in d["emitted_layers"]]
        self.next_id, self.emitted = int(d["next_id"]), int(d["emitted"])
        self.removed, self.late_layers = int(d["removed"]), int(d["late_layers"])

    def summary(self) -> dict:
        """run.json's `flow`: totals of the run so far."""
        return {
            "emitted": self.emitted,
            "removed": self.removed,
            "late_layers": self.late_layers,
            "next_id": self.next_id,
            "emitters": [
                {
                    "name": n.spec.name,
                    "layers": k,
                    "per_layer": n.per_layer,
                    "planned_layers": n.layers,
                    "mass_rate_kg_s": self.mass * n.per_layer / n.interval,
                }
                for n, k in zip(self.nozzles, self.emitted_layers)
            ],
        }
