"""The cycle averages: the forces sampled over the wing beat element by element
(:func:`sampled_forces`) and their mean through maps of the wing motion made once per
kinematics (:func:`cycle_maps`, :func:`cycle_mean`).

Cycle averages are the mean over ``n_time`` equally spaced samples midway between the
reversals' instants (the periodic midpoint rule); in the added mass's cycle average the time
derivative is moved, by parts over the periodic cycle, onto the wing's own motion (analytic), so
no derivative of the state-dependent flow is sampled.
"""

from __future__ import annotations

from typing import Sequence

import numpy as np

from .elements import BladeElements
from .kinematics import SIDE, cross, pitch, stroke
from .wing import Array, CoefficientSet, Terms, WingGeometry

__all__ = ["cycle_maps", "cycle_mean", "sampled_forces"]


def sampled_forces(motion: dict[str, Array], state: Array, geometry: WingGeometry, terms: Terms,
                   coefficients: CoefficientSet, elements: BladeElements,
                   n_time: int) -> Array:
    """(X+, Y+, Z+, L+, M+, N+) at each sample of the cycle, shape (6, n_time), evaluated
    directly, element by element (the added mass's time derivatives as periodic central
    differences); their mean over the samples is the cycle average. Forces over
    0.5 rho U^2 S_t, moments over 0.5 rho U^2 S_t c.

    ``motion`` is :func:`~dronefly.models.quasisteady.kinematics.sampled_motion` at the
    samples, ``state`` (du+, dv+, dw+, dp+, dq+, dr+). Vectors are handled by components, each
    an array (wing, time, element).
    """
    g = geometry
    k = g.k
    q = motion
    erx, ery, etx, ety = q["erx"], q["ery"], q["etx"], q["ety"]
    cpsi, spsi = q["cpsi"], q["spsi"]
    Px, Py, Pz = q["Px"], q["Py"], q["Pz"]
    u, v, w, p, qq, rr = (float(c) for c in state)
    # chord e_c = cpsi e_t + spsi up, normal n = -spsi e_t + cpsi up (up = -z)
    ecx, ecy, ecz = cpsi * etx, cpsi * ety, -spsi
    nx, ny, nz = -spsi * etx, -spsi * ety, -cpsi
    # velocity: flapping + translation + k Omega x P, then the spanwise part removed
    vf = q["vflap"]
    Vx = vf * etx + u + k * (qq * Pz - rr * Py)
    Vy = vf * ety + v + k * (rr * Px - p * Pz)
    Vz = w + k * (p * Py - qq * Px) + 0.0 * vf
    span = Vx * erx + Vy * ery
    Vx = Vx - span * erx
    Vy = Vy - span * ery
    side = q["side"]
    # the pitch axis a_p = side e_r: psi rotates e_t towards up about it
    omega_p = q["dpsi"] + side * (p * erx + qq * ery)
    speed2 = Vx * Vx + Vy * Vy + Vz * Vz
    Vc = Vx * ecx + Vy * ecy + Vz * ecz
    Vn = Vx * nx + Vy * ny + Vz * nz
    chord = elements.chord
    cw = elements.cw
    Fx = np.zeros_like(Vx)
    Fy = np.zeros_like(Vx)
    Fz = np.zeros_like(Vx)
    if terms.translational:
        alpha = np.arctan2(np.abs(Vn), np.abs(Vc))
        speed = np.sqrt(speed2)
        inv = 1.0 / np.where(speed > 0.0, speed, 1.0)
        sa = np.abs(Vn) * inv  # sin(alpha)
        s_n = -np.sign(Vn)
        # lift along n_opp + sin(alpha) e_v (length cos(alpha)), drag along -e_v
        Lx, Ly, Lz = s_n * nx + sa * Vx * inv, s_n * ny + sa * Vy * inv, \
            s_n * nz + sa * Vz * inv
        norm = np.sqrt(Lx * Lx + Ly * Ly + Lz * Lz)
        norm = np.where(norm > 0.0, norm, 1.0)
        cl = coefficients.lift(alpha) * speed2 * cw / norm
        cd = coefficients.drag(alpha) * speed2 * cw * inv
        Fx = Fx + cl * Lx - cd * Vx
        Fy = Fy + cl * Ly - cd * Vy
        Fz = Fz + cl * Lz - cd * Vz
    if terms.rotational:
        c_rot = np.pi * (0.75 - g.x0_hat)
        # rho Gamma_rot (a_p x V), Gamma_rot = C_rot omega_p c^2: smooth in V
        f = 2.0 * c_rot * k * omega_p * chord * cw * side
        Fx = Fx + f * (ery * Vz)
        Fy = Fy - f * (erx * Vz)
        Fz = Fz + f * (erx * Vy - ery * Vx)
    if terms.added_mass:
        v_mid = Vn - k * (0.5 - g.x0_hat) * chord * omega_p
        m_a = 0.5 * np.pi * k * chord * cw
        half = n_time / 2.0
        if terms.added_mass_form == "impulse":
            ix, iy, iz = m_a * v_mid * nx, m_a * v_mid * ny, m_a * v_mid * nz
            dix = (np.roll(ix, -1, axis=1) - np.roll(ix, 1, axis=1)) * half
            diy = (np.roll(iy, -1, axis=1) - np.roll(iy, 1, axis=1)) * half
            diz = (np.roll(iz, -1, axis=1) - np.roll(iz, 1, axis=1)) * half
            Fx = Fx - dix - (qq * iz - rr * iy)
            Fy = Fy - diy - (rr * ix - p * iz)
            Fz = Fz - diz - (p * iy - qq * ix)
        else:
            dv = (np.roll(v_mid, -1, axis=1) - np.roll(v_mid, 1, axis=1)) * half
            f = m_a * dv
            Fx = Fx - f * nx
            Fy = Fy - f * ny
            Fz = Fz - f * nz
    scale = 1.0 / (2.0 * g.S_wing)
    Mx = Py * Fz - Pz * Fy
    My = Pz * Fx - Px * Fz
    Mz = Px * Fy - Py * Fx
    return np.array([np.sum(c, axis=(0, 2)) for c in (Fx, Fy, Fz, Mx, My, Mz)]) * scale


def cycle_maps(t: Array, Phi: Array, phibar: Array, alpha_d: Array, alpha_u: Array,
               geometry: WingGeometry, terms: Terms, elements: BladeElements) -> dict[str, Array]:
    """What the cycle average needs of the wing motion (per-wing kinematics [rad], the samples
    ``t`` of the cycle), for :func:`cycle_mean`.

    The element at span r of a wing at a sample has the chord direction e_c, the normal n
    and the span direction e_r (orthonormal, e_r x e_c = s n with s = +/-1), its position
    P = H + r e_r from the centre of mass (H the root). Its normal and chordwise velocity
    (the spanwise one is removed, so |V|^2 = V_n^2 + V_c^2) and its pitch rate are affine
    in x1 = (1, state) and in r: ``A @ x1 + r B @ x1``, per wing-sample. Its forces are
    along e_c and n; their six sums (force, moment about the centre of mass) are linear in
    the span sums of the forces and of r times the forces, ``M``; ``am0``, ``am1`` do the
    same for the added mass's mid-chord normal velocity (the derivative in time moved, by
    parts over the periodic cycle, onto the wing's own motion, analytic). Returned: ``rows``
    (7, 4 T2 S), what x1 turns into V_n, V_c, the rotational factor and the added-mass
    velocity of every element; ``Mt`` and ``amt``, ``M`` and the added mass's maps ordered
    (sample, sum); ``R`` the span sums.
    """
    g = geometry
    k = g.k
    n_time = len(t)
    T2 = 2 * n_time
    side = SIDE[:, None]
    phi, dphi = stroke(t, Phi, phibar)  # (2, T)
    psi, dpsi, _ = pitch(t, g.rotation_fraction, alpha_d, alpha_u)
    sphi, cphi, spsi, cpsi = np.sin(phi), np.cos(phi), np.sin(psi), np.cos(psi)
    zero, one = np.zeros_like(phi), np.ones_like(phi)

    def vec(x: Array, y: Array, z: Array) -> Array:
        return np.stack(np.broadcast_arrays(x, y, z), axis=-1).reshape(T2, 3)

    e_r = vec(sphi, side * cphi, zero)
    e_t = vec(cphi, -side * sphi, zero)
    up = vec(zero, zero, -one)
    cps, sps, dps, dph = (a.reshape(T2, 1) for a in (cpsi, spsi, dpsi, dphi))
    e_c = cps * e_t + sps * up
    n = -sps * e_t + cps * up
    dn = -dps * e_c + (sps * dph) * e_r  # dn/dt+
    H = vec(g.hinge[0] + zero, side * g.hinge[1] + zero, g.hinge[2] + zero)
    s_or = np.sum(cross(e_r, e_c) * n, axis=-1)[:, None]  # +/-1
    Hxn, Hxc = cross(H, n), cross(H, e_c)
    z1, z3 = np.zeros((T2, 1)), np.zeros((T2, 3))
    # V = k dphi r e_t + (u, v, w) + k Omega x P; V.a = k dphi r e_t.a + a.(u, v, w)
    # + k Omega.(P x a), with P x n = H x n - s r e_c and P x e_c = H x e_c + s r n
    A = np.stack([np.hstack([z1, n, k * Hxn]), np.hstack([z1, e_c, k * Hxc]),
                  np.hstack([dps, z3, side.repeat(n_time, 1).reshape(T2, 1) * e_r[:, :2],
                             z1])])
    B = np.stack([np.hstack([-sps * k * dph, z3, -k * s_or * e_c]),
                  np.hstack([cps * k * dph, z3, k * s_or * n]), np.zeros((T2, 7))])
    # six sums from (sum Fc, sum r Fc, sum Fn, sum r Fn): F = Fc e_c + Fn n, moment
    # P x F = Fc (H x e_c + s r n) + Fn (H x n - s r e_c)
    M = np.stack([np.hstack([e_c, Hxc]), np.hstack([z3, s_or * n]),
                  np.hstack([n, Hxn]), np.hstack([z3, -s_or * e_c])])  # (4, T2, 6)
    etxn = dph * cross(e_t, n)  # dP/dt+ x n over r
    if terms.added_mass_form == "impulse":
        # mean of -dI/dt - Omega x I, I = m_a v n: -Omega x sum(I); its moment, by parts,
        # sum(dP x I) - Omega sum(P.I) + Q Omega, Q_ij = sum(I_i P_j), P.n = H.n
        am0 = np.hstack([n, z3, np.sum(H * n, axis=-1)[:, None],
                         (n[:, :, None] * H[:, None, :]).reshape(T2, 9)])
        am1 = np.hstack([z3, etxn, z1, (n[:, :, None] * e_r[:, None, :]).reshape(T2, 9)])
    else:
        # mean of -m_a dv/dt n, by parts: sum(v m_a dn/dt), moment sum(v m_a d(P x n)/dt)
        am0 = np.hstack([dn, cross(H, dn)])
        am1 = np.hstack([z3, etxn + cross(e_r, dn)])
    c_rot = np.pi * (0.75 - g.x0_hat)
    chord, cw, r = elements.chord, elements.cw, elements.r
    rot = (2.0 * c_rot * k * side.repeat(n_time, 1).reshape(T2, 1) * s_or) \
        * (chord * cw)[None, :]
    mid, m_a = k * (0.5 - g.x0_hat) * chord, 0.5 * np.pi * k * chord * cw
    # per wing-sample and element, the rows that x1 turns into V_n, V_c, the rotational
    # force factor f = rot omega_p and the added mass's m_a (V_n - mid omega_p): one
    # product per state, x1 @ (7, 4 T2 S) (long rows: a fast product; (4, T2, S, 7) @ x1
    # is the slow layout)
    Vn = A[0][:, None, :] + r[None, :, None] * B[0][:, None, :]
    Vc = A[1][:, None, :] + r[None, :, None] * B[1][:, None, :]
    om = A[2][:, None, :]
    rows = np.stack([Vn, Vc, rot[:, :, None] * om,
                     m_a[None, :, None] * (Vn - mid[None, :, None] * om)])
    return {
        "rows": np.ascontiguousarray(np.moveaxis(rows, -1, 0).reshape(7, -1)),
        "shape": rows.shape[:-1],
        # the sums' maps ordered (sample, sum): the span sums come out (T2, 4) and (T2, 2)
        "Mt": np.ascontiguousarray(M.transpose(1, 0, 2).reshape(T2 * 4, 6)),
        "amt": np.ascontiguousarray(
            np.stack([am0, am1]).transpose(1, 0, 2).reshape(T2 * 2, -1)),
        "R": np.stack([np.ones_like(r), r], axis=1),  # (S, 2): span sums of f and r f
    }


def cycle_mean(mp: dict[str, Array], state: Sequence[float] | Array, terms: Terms,
               coefficients: CoefficientSet, cw: Array, S_wing: float, n_time: int) -> Array:
    """Cycle-averaged (X+, Y+, Z+, L+, M+, N+) (forces over 0.5 rho U^2 S_t, moments over
    0.5 rho U^2 S_t c) at the body state ``state`` (du+, dv+, dw+, dp+, dq+, dr+) through the
    maps ``mp`` of the wing motion (:func:`cycle_maps`): the state's part only.

    The forces of :func:`sampled_forces`, summed through the state-independent maps: the
    translational and rotational forces in the (e_c, n) frame of each element, the added
    mass integrated by parts over the periodic cycle, which removes the O(dt^2) error of the
    central differences. One product gives every element's V_n, V_c, rotational factor and
    added-mass velocity (``rows``); the rest is elementwise, then two products with the maps of
    the sums (the fewest numpy calls: each costs about a microsecond)."""
    x = np.asarray(state, dtype=float)
    x1 = np.empty(7)
    x1[0] = 1.0
    x1[1:] = x
    Vn, Vc, f, v = (x1 @ mp["rows"]).reshape(mp["shape"])  # each (T2, S)
    R = mp["R"]
    if terms.translational:
        speed = np.sqrt(Vn * Vn + Vc * Vc)
        alpha = np.arctan2(np.abs(Vn), np.abs(Vc))
        q = cw * speed
        cl = q * coefficients.lift(alpha)
        cd = q * coefficients.drag(alpha)
        # lift normal to V away from the side the flow meets, drag against V
        Fc = cl * np.copysign(Vn, Vc) - cd * Vc
        Fn = -(cl * np.copysign(Vc, Vn) + cd * Vn)
        if terms.rotational:
            Fc -= f * Vn
            Fn += f * Vc
    elif terms.rotational:
        Fc, Fn = -f * Vn, f * Vc
    else:
        Fc = Fn = np.zeros_like(Vn)
    out = np.hstack([Fc @ R, Fn @ R]).reshape(-1) @ mp["Mt"]
    if terms.added_mass:
        s = (v @ R).reshape(-1) @ mp["amt"]
        if terms.added_mass_form == "impulse":
            p, q_, rr = x[3:]
            J, K, s1, Q = s[:3], s[3:6], s[6], s[7:].reshape(3, 3)
            out[:3] -= (q_ * J[2] - rr * J[1], rr * J[0] - p * J[2], p * J[1] - q_ * J[0])
            out[3:] += K - x[3:] * s1 + Q @ x[3:]
        else:
            out += s
    return out / (2.0 * S_wing * n_time)
