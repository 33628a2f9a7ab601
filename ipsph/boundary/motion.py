"""Prescribed wall motion (kinematic walls): a wall's pose at time t, its particles' positions and
velocities (docs/method.md section 9).

A pose is a rotation R about a pivot c and a translation T: x(t) = R(t) (X - c) + c + T(t), X the
wall particle as the scene placed it. Every motion is an offset from that placement, so the pose
at t = 0 is the identity:

    constant    T = v t,  R = rot(omega, |omega| t)
    sinusoid    s(t) = sin(2 pi t / P + phase) - sin(phase);  T = A s(t) a,  R = rot(a, theta_A s(t))
    keyframes   T: Catmull-Rom cubic Hermite through the keys (zero tangents at the first and last
                key, so the wall starts and stops smoothly); R: slerp between the keys' rotations;
                held before the first and after the last key; then made relative to the pose at 0.

Velocities are the time derivative of x(t) by a central difference (step VELOCITY_DT), accurate
to O(VELOCITY_DT^2) for every motion type with one code path.

Quaternions are (w, x, y, z) arrays (shared with the rigid bodies, ipsph.boundary.rigid).
"""

from __future__ import annotations

import math

import numpy as np

from ..config import MotionSpec

VELOCITY_DT = 1e-6  # s, the central difference of the wall velocities


# -- quaternions (w, x, y, z) --------------------------------------------------------------------
def quat_axis_angle(axis, angle_rad: float) -> np.ndarray:
    a = np.asarray(axis, dtype=np.float64)
    n = float(np.linalg.norm(a))
    if n == 0.0 or angle_rad == 0.0:
        return np.array([1.0, 0.0, 0.0, 0.0])
    s = math.sin(0.5 * angle_rad) / n
    return np.array([math.cos(0.5 * angle_rad), a[0] * s, a[1] * s, a[2] * s])


def quat_mul(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    w1, x1, y1, z1 = p
    w2, x2, y2, z2 = q
    return np.array(
        [
            w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2,
            w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
            w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2,
            w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2,
        ]
    )


def quat_conj(q: np.ndarray) -> np.ndarray:
    return np.array([q[0], -q[1], -q[2], -q[3]])


def quat_matrix(q: np.ndarray) -> np.ndarray:
    w, x, y, z = q / np.linalg.norm(q)
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    )


def slerp(p: np.ndarray, q: np.ndarray, u: float) -> np.ndarray:
    d = float(np.dot(p, q))
    if d < 0.0:  # the short way round
        q, d = -q, -d
    if d > 0.9995:
        r = p + u * (q - p)
        return r / np.linalg.norm(r)
    th = math.acos(min(d, 1.0))
    return (math.sin((1 - u) * th) * p + math.sin(u * th) * q) / math.sin(th)


# -- motions -------------------------------------------------------------------------------------
class Motion:
    """The pose of one kinematic wall over time (`pose(t)` -> (R, T), identity at t = 0)."""

    def __init__(self, spec: MotionSpec, pivot):
        self.spec = spec
        self.pivot = np.asarray(pivot, dtype=np.float64)
        self._r0, self._t0 = self._absolute(0.0)

    def _absolute(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        m = self.spec
        if m.type == "constant":
            w = np.radians(np.asarray(m.angular_velocity, dtype=np.float64))
            return quat_matrix(quat_axis_angle(w, float(np.linalg.norm(w)) * t)), np.asarray(m.velocity) * t
        if m.type == "sinusoid":
            ph = math.radians(m.phase_deg)
            s = math.sin(2.0 * math.pi * t / m.period + ph) - math.sin(ph)
            a = np.asarray(m.axis, dtype=np.float64)
            a = a / np.linalg.norm(a)
            return quat_matrix(quat_axis_angle(a, math.radians(m.angle_amplitude) * s)), m.amplitude * s * a
        if m.type == "keyframes":
            return self._keyframe_pose(t)
        return np.eye(3), np.zeros(3)

    def _keyframe_pose(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        keys = self.spec.keyframes
        times = [k.time for k in keys]
        if t <= times[0]:
            k = keys[0]
            return quat_matrix(quat_axis_angle(k.rotate_axis, math.radians(k.rotate_deg))), np.asarray(k.translate)
        if t >= times[-1]:
            k = keys[-1]
            return quat_matrix(quat_axis_angle(k.rotate_axis, math.radians(k.rotate_deg))), np.asarray(k.translate)
        i = int(np.searchsorted(times, t, side="right")) - 1
        t0, t1 = times[i], times[i + 1]
        h = t1 - t0
        u = (t - t0) / h
        p = [np.asarray(k.translate, dtype=np.float64) for k in keys]

        def tangent(j):  # Catmull-Rom (finite-difference) tangents, zero at the ends
            if j == 0 or j == len(keys) - 1:
                return np.zeros(3)
            return (p[j + 1] - p[j - 1]) / (times[j + 1] - times[j - 1])

        h00, h10 = 2 * u**3 - 3 * u**2 + 1, u**3 - 2 * u**2 + u
        h01, h11 = -2 * u**3 + 3 * u**2, u**3 - u**2
        tr = h00 * p[i] + h10 * h * tangent(i) + h01 * p[i + 1] + h11 * h * tangent(i + 1)
        qa = quat_axis_angle(keys[i].rotate_axis, math.radians(keys[i].rotate_deg))
        qb = quat_axis_angle(keys[i + 1].rotate_axis, math.radians(keys[i + 1].rotate_deg))
        return quat_matrix(slerp(qa, qb, u)), tr

    def pose(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """(R, T) with x(t) = R (X - pivot) + pivot + T, relative to the placement (identity at 0)."""
        r, tr = self._absolute(t)
        rel = r @ self._r0.T
        return rel, tr - rel @ self._t0

    def positions(self, x0: np.ndarray, t: float) -> np.ndarray:
        r, tr = self.pose(t)
        return (x0 - self.pivot) @ r.T + self.pivot + tr

    def velocities(self, x0: np.ndarray, t: float) -> np.ndarray:
        h = VELOCITY_DT
        return (self.positions(x0, t + h) - self.positions(x0, t - h)) / (2.0 * h)
