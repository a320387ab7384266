"""The instantaneous forces of both wings at any wing motion, split into the wing motion's part
(:func:`instants`, at any number of instants at once) and the state's (:class:`Instant`, called
with the body state).

Each element's velocity (the spanwise part removed) is V_c e_c + V_n n, affine in the body state
and in the span; its forces are along e_c, n and (the added mass's turning normal) e_r. So
everything but the elementwise translational coefficients is a product with maps that depend on
the wing motion alone: x1 @ rows gives every element's V_n, V_c and rotational factor and the
added mass's span sums, x1 = (1, du+, dv+, dw+, dp+, dq+, dr+); loads @ (the elements' forces,
the added mass's sums, their products with the body's rates) gives the six loads.
"""

from __future__ import annotations

import math
from typing import NamedTuple, Sequence

import numpy as np

from ...core.errors import DroneflyError
from .elements import BladeElements
from .kinematics import SIDE, cross
from .wing import Array, CoefficientSet, Terms, WingGeometry

__all__ = ["Instant", "instants"]

# -- x1 = (1, du+, dv+, dw+, dp+, dq+, dr+): the state with the affine forms' constant first
_X1 = 7
_ONE = 0  # the constant
_VELOCITY = slice(1, 4)  # du+, dv+, dw+
_RATES = slice(4, 7)  # dp+, dq+, dr+
_RATES_PQ = slice(4, 6)  # dp+, dq+ (e_r, the pitch axis, has no z component)
_XY = slice(0, 2)  # the x and y components of a vector
# -- the linear forms in x1 of each wing at each instant (:func:`instants`)
_FORMS = 8  # an, bn, ac, bc, vr0, om_p, d_om, dbn
# -- per element, x1 @ rows gives, in this order, V_n, V_c, the rotational factor f and -f
_V_N, _V_C, _ROT, _MINUS_ROT = range(4)
_QUANTITIES = 4
# -- the elements' forces along n and e_c (the order of (V_n, V_c))
_F_N, _F_C = 0, 1
# -- the added mass's span sums: of the impulse (S) and of its normal force (D), each per wing
# the sum and the sum of r times it; the impulse's four first
_IMPULSE, _NORMAL = 0, 1
_SUM, _R_SUM = 0, 1
_ADDED_MASS_SUMS = 8  # (S, D) x wing x (sum, r sum)
_IMPULSE_SUMS = slice(0, 4)  # S of each wing, (sum, r sum)
#: the lift's sign in (F_n, F_c), per (wing, element)
_LIFT_SIDE = np.array([-1.0, 1.0])[:, None, None]
_EYE3 = np.eye(3)


class Instant(NamedTuple):
    """The wing motion at one instant (:func:`instants`), called with a body state: the
    instantaneous loads of both wings.

    Attributes
    ----------
    rows : array, shape (7, 8 n_span + 8)
        x1 @ rows, x1 = (1, du+, dv+, dw+, dp+, dq+, dr+), is every element's V_n, V_c (over U)
        and rotational factor f, -f (over 0.5 rho U S_t), ordered (quantity, wing, element),
        then the added mass's sums: per wing those of its impulse m_a v_mid and of r times it,
        then per wing those of its normal force and of r times that.
    loads : array, shape (6, 8 n_span + 20)
        loads @ (every element's F_n, F_c over 0.5 rho U^2 S_t, ordered as in ``rows``; the
        added mass's sums; their products with the body's rates) is (X+, Y+, Z+, L+, M+, N+).
    cw : array, shape (n_span,)
        The elements' quadrature weights [c^2]
        (:class:`~dronefly.models.quasisteady.elements.BladeElements`).
    coefficients : CoefficientSet or None
        The translational coefficients; None without the translational term.
    """

    rows: Array
    loads: Array
    cw: Array
    coefficients: CoefficientSet | None

    def __call__(self, state: Sequence[float] | Array) -> Array:
        """The instantaneous loads of both wings at this instant.

        One product gives every element's V_n, V_c and rotational factor and the added mass's
        span sums, the translational forces are elementwise, then one product gives the six
        loads of every element's forces, the added mass's sums and their products with the
        rates (the fewest numpy calls: each costs about a microsecond).

        Parameters
        ----------
        state : array of 6 floats
            (du+, dv+, dw+, dp+, dq+, dr+): velocities over U, rates times t_w (no check: the
            caller's; :meth:`~dronefly.models.quasisteady.QuasiSteadyModel.forces_at` checks it).

        Returns
        -------
        array
            (X+, Y+, Z+, L+, M+, N+): forces over 0.5 rho U^2 S_t, moments over
            0.5 rho U^2 S_t c.
        """
        rows, out, cw, coefficients = self
        x1 = np.empty(_X1)
        x1[_ONE] = 1.0
        x1[_ONE + 1:] = state
        e = x1 @ rows
        a = e[-_ADDED_MASS_SUMS:]  # (S0, S1) of each wing, then the normal force's sums
        # (V_n, V_c, f, -f) of (wing, element)
        E = e[:-_ADDED_MASS_SUMS].reshape(_QUANTITIES, 2, -1)
        V = E[_V_N:_V_C + 1]
        rotational = E[_ROT:] * V[::-1]  # (f V_c, -f V_n)
        if coefficients is not None:
            aV = np.abs(V)
            speed = np.hypot(V[_V_N], V[_V_C])
            alpha = np.arctan2(aV[_V_N], aV[_V_C])
            q = cw * speed
            cl = q * coefficients.lift(alpha)
            cd = q * coefficients.drag(alpha)
            # lift normal to V away from the side the flow meets, drag against V:
            # F_n = -cl copysign(|V_c|, V_n) - cd V_n, F_c = cl copysign(|V_n|, V_c) - cd V_c
            F = cl * (np.copysign(aV[::-1], V) * _LIFT_SIDE) - cd * V
            F += rotational  # F_n += f V_c, F_c -= f V_n
        else:
            F = rotational
        return out @ np.concatenate([F.reshape(-1), a,
                                     (a[_IMPULSE_SUMS, None] * x1[_RATES]).reshape(-1)])


def instants(angles: Sequence[Sequence[float]] | Array, geometry: WingGeometry, terms: Terms,
             coefficients: CoefficientSet, elements: BladeElements) -> list[Instant]:
    """The wing motion's part of the instantaneous loads at one or more instants.

    Everything that does not depend on the body state: the frames of both wings, the linear
    forms of each element's velocities in the state, and the maps from the forces' span sums
    to the six loads.

    Parameters
    ----------
    angles : array, shape (6, 2) or (T, 6, 2)
        Per wing (columns left, right): phi [rad], dphi/dt+ [rad per wing beat], d2phi/dt+2
        [rad per wing beat squared], psi [rad] and its two derivatives; a stack of T instants
        (computed together).
    geometry, terms, coefficients, elements
        The model's (:class:`~dronefly.models.quasisteady.QuasiSteadyModel`).

    Returns
    -------
    list of Instant
        One per instant (one for a single (6, 2)), each a function of the body state.

    Raises
    ------
    DroneflyError
        The angles' shape is wrong, or the model's added mass is not the impulse form.
    """
    a = np.asarray(angles, dtype=float)
    if a.ndim == 2:
        a = a[None]
    if a.ndim != 3 or a.shape[1:] != (6, 2):
        raise DroneflyError(f"angles of shape {np.shape(angles)}: expected (6, 2) or "
                            "(T, 6, 2)")
    g, k = geometry, geometry.k
    if terms.added_mass and terms.added_mass_form != "impulse":
        raise DroneflyError("forces_at has the impulse form of the added mass only")
    T = len(a)
    phi, dphi, ddphi, psi, dpsi, ddpsi = (a[:, j, :] for j in range(6))  # each (T, wing)
    side = SIDE
    sphi, cphi, spsi, cpsi = np.sin(phi), np.cos(phi), np.sin(psi), np.cos(psi)
    zero = np.zeros_like(phi)
    # e_r = (sphi, s cphi, 0), e_t = (cphi, -s sphi, 0), e_c = cpsi e_t + spsi up,
    # n = -spsi e_t + cpsi up (up = -z); e_r x e_c = s_or n, e_r x n = -s_or e_c. Vectors
    # are (T, wing, 3), H the roots (wing, 3)
    etx, ety = cphi, -side * sphi
    er = np.stack([sphi, side * cphi, zero], axis=-1)
    et = np.stack([etx, ety, zero], axis=-1)
    ec = np.stack([cpsi * etx, cpsi * ety, -spsi], axis=-1)
    nn = np.stack([-spsi * etx, -spsi * ety, -cpsi], axis=-1)
    H = elements.roots
    s_or = np.sum(cross(er, ec) * nn, axis=-1)
    so = s_or[..., None]
    Hx = cross(H, np.stack([nn, ec, er]))  # H x n, H x e_c, H x e_r
    # linear forms in x1 = (1, u, v, w, p, q, r), (T, wing, form, 7). The element at span r
    # has V_n = an + r bn, V_c = ac + r bc: V.a = V_b.a + k Omega.(H x a)
    # + r (k dphi e_t.a + k Omega.(e_r x a)); V.e_r = vr0 (the same along the span); the
    # pitch rate about a_p = s e_r (rotation plus the body's rate) om_p and its derivative
    # d_om; d(V.n)/dt+ = r (-k ddphi spsi + k dphi Omega.(e_t x n)) - dpsi V_c
    # + spsi dphi V_r, r dbn the first term
    L = np.zeros((T, 2, _FORMS, _X1))
    an, bn, ac, bc, vr0, om_p, d_om, dbn = (L[:, :, i] for i in range(_FORMS))
    an[..., _VELOCITY], an[..., _RATES] = nn, k * Hx[0]
    bn[..., _ONE], bn[..., _RATES] = -k * dphi * spsi, -k * so * ec
    ac[..., _VELOCITY], ac[..., _RATES] = ec, k * Hx[1]
    bc[..., _ONE], bc[..., _RATES] = k * dphi * cpsi, k * so * nn
    vr0[..., _VELOCITY], vr0[..., _RATES] = er, k * Hx[2]
    om_p[..., _ONE], om_p[..., _RATES_PQ] = dpsi, side[:, None] * er[..., _XY]
    d_om[..., _ONE], d_om[..., _RATES_PQ] = ddpsi, (side * dphi)[..., None] * et[..., _XY]
    dbn[..., _ONE], dbn[..., _RATES] = -k * ddphi * spsi, (k * dphi)[..., None] * cross(et, nn)
    r, chord, cw = elements.r, elements.chord, elements.cw
    # per element: V_n, V_c and the rotational force factor f (as f and -f):
    # rho Gamma_rot (a_p x V) = f (V_c n - V_n e_c), f = rho C_rot omega_p c^2 s s_or
    c_rot = 2.0 * math.pi * (0.75 - g.x0_hat) * k if terms.rotational else 0.0
    f = (c_rot * side * s_or)[..., None, None] * (chord * cw) * om_p[..., None]
    rows = np.empty((T, _X1, _QUANTITIES, 2, len(r)))  # (T, x1, quantity, wing, element)
    rows[:, :, _V_N] = (an[..., None] + bn[..., None] * r).transpose(0, 2, 1, 3)
    rows[:, :, _V_C] = (ac[..., None] + bc[..., None] * r).transpose(0, 2, 1, 3)
    rows[:, :, _ROT] = f.transpose(0, 2, 1, 3)
    rows[:, :, _MINUS_ROT] = -rows[:, :, _ROT]
    # the added mass, I = m_a v_mid n per element, v_mid = V_n - mid omega_p: its span
    # sums are linear in x1: S0 = sum m_a v_mid, S1 = sum r m_a v_mid, and those of its
    # normal force -m_a dv_mid/dt+ and of r times it (D0, D1), dv_mid/dt+ = r dbn
    # - dpsi V_c + spsi dphi V_r - mid d(omega_p)/dt+
    M0, M1, M2, Mm0, Mm1 = elements.added_mass_sums
    dps, spd = dpsi[..., None], (spsi * dphi)[..., None]
    am = np.empty((T, 2, 2, 2, _X1))  # (T, (S, D), wing, (sum, r sum), x1)
    am[:, _IMPULSE, :, _SUM] = an * M0 + bn * M1 - om_p * Mm0
    am[:, _IMPULSE, :, _R_SUM] = an * M1 + bn * M2 - om_p * Mm1
    am[:, _NORMAL, :, _SUM] = -(dbn * M1 - dps * (ac * M0 + bc * M1) + spd * vr0 * M0
                                - d_om * Mm0)
    am[:, _NORMAL, :, _R_SUM] = -(dbn * M2 - dps * (ac * M1 + bc * M2) + spd * vr0 * M1
                                  - d_om * Mm1)
    # the six loads of each sum, (T, wing, 6): a force F at the element (P = H + r e_r)
    # adds (F, H x F) and r e_r x F, with r e_r x (Fc e_c + Fn n) = s_or r (Fc n - Fn e_c);
    # the added mass: F_c += dpsi S0, F_r = -spsi dphi S0, and -Omega x sum(I):
    # F -= S0 Omega x n, M -= S0 H x (Omega x n) + S1 e_r x (Omega x n)
    z3 = np.zeros_like(nn)
    c_fn, c_fc, c_fr = np.concatenate([np.stack([nn, ec, er]), Hx], axis=-1)
    c_rfn, c_rfc = np.concatenate([z3, -so * ec], axis=-1), np.concatenate([z3, so * nn], -1)

    def per_load(c: Array) -> Array:  # (T, wing, 6) -> (T, 6, wing)
        return np.swapaxes(c, 1, 2)

    # the loads of the span sums of the elements' forces, (T, load, (F_n, F_c), wing,
    # (sum, r sum)); of the added mass's sums, (T, load, (S, D), wing, (sum, r sum)); of the
    # impulse's sums times the rates, (T, load, wing, (S0, S1), omega_j)
    G_el = np.empty((T, 6, 2, 2, 2))
    G_el[:, :, _F_N, :, _SUM], G_el[:, :, _F_N, :, _R_SUM] = per_load(c_fn), per_load(c_rfn)
    G_el[:, :, _F_C, :, _SUM], G_el[:, :, _F_C, :, _R_SUM] = per_load(c_fc), per_load(c_rfc)
    G_am = np.empty((T, 6, 2, 2, 2))
    G_am[:, :, _IMPULSE, :, _SUM] = per_load(dps * c_fc - spd * c_fr)
    G_am[:, :, _IMPULSE, :, _R_SUM] = per_load(dps * c_rfc)
    G_am[:, :, _NORMAL, :, _SUM], G_am[:, :, _NORMAL, :, _R_SUM] = per_load(c_fn), per_load(c_rfn)
    oxn = cross(_EYE3[:, None, None, :], nn)  # e_j x n, (j, T, wing, 3)
    G_om = np.empty((T, 6, 2, 2, 3))
    G_om[:, :, :, _SUM] = -np.concatenate([oxn, cross(H, oxn)], axis=-1).transpose(1, 3, 2, 0)
    G_om[:, :, :, _R_SUM] = -np.concatenate([np.zeros_like(oxn), cross(er, oxn)],
                                            axis=-1).transpose(1, 3, 2, 0)
    scale = 2.0 * g.S_wing
    G_el /= scale
    G_am /= scale
    G_om /= scale
    # the span sums of (F_n, F_c) folded in: the loads of each element's forces
    G = np.concatenate([(G_el[..., _SUM, None] + G_el[..., _R_SUM, None] * r).reshape(T, 6, -1),
                        G_am.reshape(T, 6, _ADDED_MASS_SUMS), G_om.reshape(T, 6, -1)], axis=-1)
    # one product with x1 for the elements and the added mass's sums
    rows = np.concatenate([rows.reshape(T, _X1, -1),
                           am.reshape(T, _ADDED_MASS_SUMS, _X1).transpose(0, 2, 1)], axis=-1)
    lift = coefficients if terms.translational else None
    return [Instant(rows[i], G[i], cw, lift) for i in range(T)]
