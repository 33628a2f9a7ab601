"""Contacts between a body and the walls it touches (static, kinematic, other bodies): one penalty
spring-damper per pair of walls in touch, set on each body's contact_force and contact_torque
before it integrates (method.md section 9, Contacts)."""

from __future__ import annotations

import numpy as np

from .particles import radius_lists

# Contact when two walls' surfaces are closer than this many d: their particles are then closer than
# the sum of their layers' depths behind the surfaces (Boundary.depth) plus this gap. A dense body
# rests with its surface within the gap of the floor's (the d/4 bound); with the 0.1 d layers
# of an earlier model, a particle distance of d was the same rule for a gap of 0.8 d.
CONTACT_GAP_D = 0.2
CONTACT_STEPS = 4.0  # contact stiffness: omega_c = 1 / (CONTACT_STEPS dt), stable explicit springs
CONTACT_DAMPING = 1.0  # damping ratio of the contact spring (critical: no bounce)
CONTACT_FRICTION = 0.5  # Coulomb friction coefficient capping the contact's viscous tangential damping


def contact_forces(b, bodies: list, d: float, dt: float) -> None:
    """One penalty spring-damper per (body, partner wall) in touch, from the pairs of their
    particles closer than the contact distance d_c,p = depth_a + depth_b + CONTACT_GAP_D d (their
    layers' depths behind the two surfaces plus the gap; partners: static and kinematic walls, other
    bodies). With w_p = d_c,p - r_p > 0 over the pairs, the penetration is delta = max w_p, the
    normal n the w-weighted mean of the pairs' directions and the contact point the w-weighted
    mean of the body's particles; then

        f = mu [omega^2 delta - 2 zeta omega (v_rel . n)]_+ n,   omega = 1 / (CONTACT_STEPS dt)

    mu the effective mass of the contact point along n (`_contact_mass`: both bodies' masses and
    inertias at their lever arms; equal and opposite forces), v_rel the
    relative velocity at the contact point; tangentially a viscous friction -mu 2 zeta omega v_t,
    capped at CONTACT_FRICTION |f|. One contact, not one spring per pair: a spring per
    pair normalised by the pair count is not conservative (the count changes along the
    approach) and bounced a dropped box higher than it fell."""
    gap = CONTACT_GAP_D * d
    om = 1.0 / (CONTACT_STEPS * dt)
    for body in bodies:
        body.contact_force = np.zeros(3)
        body.contact_torque = np.zeros(3)
    by_group = {body.group: body for body in bodies}
    for body in bodies:
        mine = np.flatnonzero(b.groups == body.group)
        other = np.flatnonzero(b.groups != body.group)
        if len(other) == 0:
            continue
        reach = float(b.depth[mine].max() + b.depth[other].max()) + gap
        order, nbr, cnt = radius_lists(np.ascontiguousarray(b.x[mine]), np.ascontiguousarray(b.x[other]), reach)
        if cnt.sum() == 0:
            continue
        rows = np.repeat(np.arange(len(mine)), cnt)
        cols = np.concatenate([nbr[i, : cnt[i]] for i in np.flatnonzero(cnt)])
        p, q = mine[rows], other[order[cols]]
        diff = b.x[p] - b.x[q]
        r = np.linalg.norm(diff, axis=1)
        w = b.depth[p] + b.depth[q] + gap - r  # how far the two surfaces overlap the contact gap
        touch = w > 0.0
        if not touch.any():
            continue
        p, q, diff, r, w = p[touch], q[touch], diff[touch], r[touch], w[touch]
        n_pair = diff / np.maximum(r, 1e-12)[:, None]
        for grp_other in np.unique(b.groups[q]):
            sel = b.groups[q] == grp_other
            partner = by_group.get(int(grp_other))
            if partner is not None and partner.group < body.group:
                continue  # that pair was done from the partner's side
            ws = w[sel]
            n = (ws[:, None] * n_pair[sel]).sum(axis=0)
            if not np.linalg.norm(n) > 0.0:
                continue
            n /= np.linalg.norm(n)
            at = (ws[:, None] * b.x[p[sel]]).sum(axis=0) / ws.sum()
            v_mine = body.v + np.cross(body.w, at - body.c)
            v_other = (
                (ws[:, None] * b.v[q[sel]]).sum(axis=0) / ws.sum()
                if partner is None
                else partner.v + np.cross(partner.w, at - partner.c)
            )
            v_rel = v_mine - v_other
            mu = _contact_mass(body, partner, at, n)
            mag = max(mu * (om * om * ws.max() - 2.0 * CONTACT_DAMPING * om * float(np.dot(v_rel, n))), 0.0)
            f = mag * n  # contacts push, never pull
            v_t = v_rel - float(np.dot(v_rel, n)) * n  # friction: viscous, capped by Coulomb's mu_f f_n
            speed_t = float(np.linalg.norm(v_t))
            if speed_t > 0.0 and mag > 0.0:
                t_hat = v_t / speed_t
                mu_t = _contact_mass(body, partner, at, t_hat)
                f = f - min(CONTACT_FRICTION * mag, mu_t * 2.0 * CONTACT_DAMPING * om * speed_t) * t_hat
            body.contact_force += f
            body.contact_torque += np.cross(at - body.c, f)
            if partner is not None:
                partner.contact_force -= f
                partner.contact_torque -= np.cross(at - partner.c, f)


def _contact_mass(body, partner, at: np.ndarray, n: np.ndarray) -> float:
    """The effective mass of the contact point along n: what the spring and its damping act on. With
    the body's mass alone, a corner's damping rate 2 zeta omega m / m_eff exceeded the explicit limit
    2 / dt and the contact bounced a brick that landed on its edge higher than it came (issue 42)."""
    inv = body.inverse_mass_at(at, n) + (0.0 if partner is None else partner.inverse_mass_at(at, n))
    return 1.0 / inv
