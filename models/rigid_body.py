"""The hovering model drone fly as a rigid body in six degrees of freedom (not linearised).

The single home of the nonlinear equations; the FMU ``DroneFlyHover6DOF`` and the analysis
import it. The aerodynamics are the paper's, the mean force at equilibrium (balancing the
weight, fixed in the body) plus the linear derivatives of the lateral (Eq. 12, Table 1;
:mod:`dronefly.models.lateral_dynamics`) and longitudinal (Sect. 3.5; :mod:`dronefly.fmu_src.longitudinal.
model`) models: that linearity is the paper's assumption and stays. What the linearisation of
Sect. 3.6 drops in the rigid body is restored: the transport terms omega x V (dr du, dp dw,
...), the gyroscopic terms omega x J omega with the full inertia tensor (dp dq, dq dr, ...),
the exact projection of gravity and the exact attitude kinematics (a unit quaternion: no
gimbal lock at any attitude).

Axes (body axes at the centre of mass, x forward, y right, z down; earth axes north-east-down),
the non-dimensional 13-value state (V+ = (u, v, w), omega+ = (p, q, r), the unit quaternion e
body -> earth, the earth-axis position P+) and the equations: fmu_src/hover6dof/README.md,
"Equations"; in code they are the right-hand side of :func:`_equations`, line by line, with
a_aero = the rows (v, u, w) of the linear models' A and B without their gravity column and
J+^-1 M_aero = their rows (p, r, q). Linearised about hover this is exactly the two linear
models (tests check the Jacobian).

Integration: Butcher's Runge-Kutta method of order 6 (7 stages, :func:`_equations`) on
sub-steps of at most :data:`MAX_SUBSTEP_WB` wing beats (shorter where the body turns fast); the
quaternion is normalised after each step. Accuracy (within 1e-9 of ``solve_ivp``) and cost:
the README and docs/benchmarks.md.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from operator import mul
from typing import Sequence

from ..core.errors import DroneflyError
from . import lateral_dynamics as lateral
from . import longitudinal_dynamics as longitudinal

__all__ = ["MAX_SUBSTEP_WB", "MAX_TURN_PER_SUBSTEP_RAD", "Hover6DOF", "Hover6DOFError",
           "STATE_SIZE", "TERMS", "euler_from_quaternion", "gamma_from_quaternion",
           "initial_state", "outputs", "quaternion_from_euler"]

#: largest Runge-Kutta sub-step, wing beats (the accuracy this gives: tests/test_hover6dof.py)
MAX_SUBSTEP_WB = 0.2
#: largest turn per sub-step, rad (shorter sub-steps above 0.5 rad per wing beat, the fastest
#: rate of the linear dynamics)
MAX_TURN_PER_SUBSTEP_RAD = 0.05
#: number of state values
STATE_SIZE = 13
#: the restored rigid-body terms; a model without some of them shows what each one does
TERMS = frozenset({"transport", "gyroscopic", "gravity"})


class Hover6DOFError(DroneflyError):
    """A bad value for the six-degree-of-freedom model (the message names it)."""


def quaternion_from_euler(phi: float, theta: float, psi: float) -> tuple[float, ...]:
    """Unit quaternion (body -> earth) of the Euler angles (yaw psi, pitch theta, roll phi), rad."""
    cr, sr = math.cos(phi / 2), math.sin(phi / 2)
    cp, sp = math.cos(theta / 2), math.sin(theta / 2)
    cy, sy = math.cos(psi / 2), math.sin(psi / 2)
    return (cy * cp * cr + sy * sp * sr, cy * cp * sr - sy * sp * cr,
            cy * sp * cr + sy * cp * sr, sy * cp * cr - cy * sp * sr)


def euler_from_quaternion(e: Sequence[float]) -> tuple[float, float, float]:
    """(phi, theta, psi) [rad] of a unit quaternion; theta in [-pi/2, pi/2]."""
    e0, e1, e2, e3 = e
    s = max(-1.0, min(1.0, -2.0 * (e1 * e3 - e0 * e2)))
    return (math.atan2(2.0 * (e2 * e3 + e0 * e1), 1.0 - 2.0 * (e1 * e1 + e2 * e2)), math.asin(s),
            math.atan2(2.0 * (e1 * e2 + e0 * e3), 1.0 - 2.0 * (e2 * e2 + e3 * e3)))


def gamma_from_quaternion(e: Sequence[float]) -> float:
    """The paper's gamma: the angle between the body y-axis and the horizontal, rad
    (positive with the right wing down; equal to the roll angle phi when theta = 0)."""
    e0, e1, e2, e3 = e
    return math.asin(max(-1.0, min(1.0, 2.0 * (e2 * e3 + e0 * e1))))


def _aero_rows(A: object, B: object, rows: Sequence[int], gravity_column: int) -> tuple:
    """Rows of A (without the attitude column, which holds only gravity) and B, as floats."""
    a = tuple(tuple(float(A[i][j]) for j in range(3)) for i in rows)
    b = tuple(tuple(float(x) for x in B[i]) for i in rows)
    for i in rows[1:]:  # the moment rows: no attitude dependence (structural zeros)
        if A[i][gravity_column] != 0.0:
            raise Hover6DOFError(f"A[{i + 1},{gravity_column + 1}] = {A[i][gravity_column]!r}: "
                                 "a moment that depends on the attitude is not aerodynamic")
    return a, b


def _gyroscopic(Ix: float, Iy: float, Iz: float, Ixz: float) -> tuple[float, ...]:
    """G0 .. G5 of J^-1 (omega x J omega) = (G0 qr + G1 pq, G2 pr + G3 (p^2 - r^2), G4 qr +
    G5 pq), J = [[Ix, 0, -Ixz], [0, Iy, 0], [-Ixz, 0, Iz]]."""
    det = Ix * Iz - Ixz ** 2
    return ((Iz * (Iz - Iy) + Ixz * Ixz) / det, Ixz * (Iy - Ix - Iz) / det, (Ix - Iz) / Iy,
            Ixz / Iy, Ixz * (Iz - Iy + Ix) / det, (Ix * (Iy - Ix) - Ixz * Ixz) / det)


def _equations(la: tuple, na: tuple, G: tuple, g: float, terms: frozenset) -> tuple:
    """The right-hand side and the Runge-Kutta sub-steps of the model's equations.

    Parameters
    ----------
    la, na : 3 rows of 3 floats
        The lateral rows (v, p, r) and the longitudinal rows (u, w, q) of the linear models' A,
        each on the columns (v, p, r) and (u, w, q) (:func:`_aero_rows`).
    G : 6 floats
        The gyroscopic coefficients (:func:`_gyroscopic`).
    g : float
        g+, the non-dimensional gravity.
    terms : frozenset of str
        The restored rigid-body terms (:data:`TERMS`).

    Returns
    -------
    rhs : callable
        ``rhs(x, bl, bn, positions=True)``: dx/dt+ of the first 10 state values ``x`` (u .. e3)
        with the control forces ``bl`` (B_lat c_lat, rows v, p, r) and ``bn`` (B_lon c_lon,
        rows u, w, q); the 13 derivatives, or the first 10 if not ``positions``.
    substeps : callable
        ``substeps(y, n, h, bl, bn)``: the 13-value state after ``n`` sub-steps of ``h`` from
        ``y`` (Butcher's order 6), the quaternion not normalised.
    """
    (l00, l01, l02), (l10, l11, l12), (l20, l21, l22) = la
    (n00, n01, n02), (n10, n11, n12), (n20, n21, n22) = na
    G0, G1, G2, G3, G4, G5 = G
    gravity, transport, gyroscopic = (name in terms for name in
                                      ("gravity", "transport", "gyroscopic"))
    asin = math.asin

    def rhs(x: Sequence[float], bl: Sequence[float], bn: Sequence[float],
            positions: bool = True) -> list[float]:
        u, v, w, p, q, r, e0, e1, e2, e3 = x
        # the aerodynamic accelerations: the linear models' rows (v, p, r) and (u, w, q)
        a_v = l00 * v + l01 * p + l02 * r + bl[0]
        a_p = l10 * v + l11 * p + l12 * r + bl[1]
        a_r = l20 * v + l21 * p + l22 * r + bl[2]
        a_u = n00 * u + n01 * w + n02 * q + bn[0]
        a_w = n10 * u + n11 * w + n12 * q + bn[1]
        a_q = n20 * u + n21 * w + n22 * q + bn[2]
        # the bottom row of R (body -> earth), R^T e_z; t = 2 e and s_ij = 2 e_i e_j are exact
        # doublings, so 2 (e1 e3 - e0 e2) = s13 - s02 exactly
        t0, t1, t2 = e0 + e0, e1 + e1, e2 + e2
        s13, s02, s23, s01, s11, s22 = t1 * e3, t0 * e2, t2 * e3, t0 * e1, t1 * e1, t2 * e2
        R20, R21, R22 = s13 - s02, s23 + s01, 1.0 - (s11 + s22)
        if gravity:  # g (R^T e_z - e_z): the weight less the mean force balancing it at hover
            a_u, a_v, a_w = a_u + g * R20, a_v + g * R21, a_w + g * (R22 - 1.0)
        else:  # the linear projection g (-theta, gamma, 0)
            a_u -= g * asin(max(-1.0, min(1.0, -R20)))
            a_v += g * asin(max(-1.0, min(1.0, R21)))
        if transport:  # - omega x V
            a_u, a_v, a_w = a_u - (q * w - r * v), a_v - (r * u - p * w), a_w - (p * v - q * u)
        if gyroscopic:  # - J^-1 (omega x J omega)
            pq, qr = p * q, q * r
            a_p -= G0 * qr + G1 * pq
            a_q -= G2 * (p * r) + G3 * (p * p - r * r)
            a_r -= G4 * qr + G5 * pq
        dx = [a_u, a_v, a_w, a_p, a_q, a_r,  # then e' = e (0, omega) / 2
              0.5 * (-e1 * p - e2 * q - e3 * r),
              0.5 * (e0 * p + e2 * r - e3 * q),
              0.5 * (e0 * q - e1 * r + e3 * p),
              0.5 * (e0 * r + e1 * q - e2 * p)]
        if positions:  # P' = R V
            s33, s12, s03 = (e3 + e3) * e3, t1 * e2, t0 * e3
            dx += [(1.0 - (s22 + s33)) * u + (s12 - s03) * v + (s13 + s02) * w,
                   (s12 + s03) * u + (1.0 - (s11 + s33)) * v + (s23 - s01) * w,
                   R20 * u + R21 * v + R22 * w]
        return dx

    def substeps(y: Sequence[float], n: int, h: float, bl: Sequence[float],
                 bn: Sequence[float]) -> list[float]:
        # Butcher's (1964) order 6, c = 0, 1/3, 2/3, 1/3, 1/2, 1/2, 1. A stage reads only the
        # first 10 values of its input (the positions never enter the right-hand side), so the
        # inputs are built from those: zip stops at the shortest list, y10. K2 enters no
        # position, so its positions are not computed.
        h3, h8, h12, h16, h44, h120 = h / 3, h / 8, h / 12, h / 16, h / 44, h / 120
        h23 = 2.0 * h3
        y = list(y)
        for _ in range(n):
            y10 = y[:10]
            k1 = rhs(y10, bl, bn)
            k2 = rhs([a + h3 * b1 for a, b1 in zip(y10, k1)], bl, bn, positions=False)
            k3 = rhs([a + h23 * b2 for a, b2 in zip(y10, k2)], bl, bn)
            k4 = rhs([a + h12 * (b1 - b3) + h3 * b2 for a, b1, b2, b3 in zip(y10, k1, k2, k3)],
                     bl, bn)
            k5 = rhs([a + h16 * (18.0 * b2 - b1 - 3.0 * b3 - 6.0 * b4)
                      for a, b1, b2, b3, b4 in zip(y10, k1, k2, k3, k4)], bl, bn)
            k6 = rhs([a + h8 * (9.0 * b2 - 3.0 * b3 - 6.0 * b4 + 4.0 * b5)
                      for a, b2, b3, b4, b5 in zip(y10, k2, k3, k4, k5)], bl, bn)
            k7 = rhs([a + h44 * (9.0 * b1 - 36.0 * b2 + 63.0 * b3 + 72.0 * b4 - 64.0 * b6)
                      for a, b1, b2, b3, b4, b6 in zip(y10, k1, k2, k3, k4, k6)], bl, bn)
            y = [a + h120 * (11.0 * (b1 + b7) + 81.0 * (b3 + b4) - 32.0 * (b5 + b6))
                 for a, b1, b3, b4, b5, b6, b7 in zip(y, k1, k3, k4, k5, k6, k7)]
        return y

    return rhs, substeps


@dataclass(frozen=True)
class Hover6DOF:
    """The nonlinear model with the lateral and longitudinal parameters of the linear models.

    Parameters
    ----------
    lateral_params : dronefly.models.lateral_dynamics.LateralParameters
    longitudinal_params : dronefly.models.longitudinal_dynamics.LongitudinalParameters
        Must agree on ``m_plus`` and ``g_plus``.
    terms : frozenset of str
        Restored rigid-body terms (default all of :data:`TERMS`); without ``gravity`` the
        gravity projection is the linear one, g+ (-theta, gamma, 0).
    """

    lateral_params: lateral.LateralParameters
    longitudinal_params: longitudinal.LongitudinalParameters
    terms: frozenset = TERMS

    def __post_init__(self) -> None:
        lp, np_ = self.lateral_params, self.longitudinal_params
        for name in ("m_plus", "g_plus"):
            if getattr(lp, name) != getattr(np_, name):
                raise Hover6DOFError(f"{name} = {getattr(lp, name)!r} (lateral) and "
                                     f"{getattr(np_, name)!r} (longitudinal) must agree")
        unknown = set(self.terms) - TERMS
        if unknown:
            raise Hover6DOFError(f"terms {sorted(unknown)!r}: choose from {sorted(TERMS)}")
        for name, axis, params in (("_lat", lateral, lp), ("_lon", longitudinal, np_)):
            object.__setattr__(self, name, _aero_rows(*axis.system_rows(params), (0, 1, 2), 3))
        G = _gyroscopic(lp.Ix_plus, np_.Iy_plus, lp.Iz_plus, lp.Ixz_plus)
        for name, f in zip(("_rhs", "_substeps"), _equations(
                self._lat[0], self._lon[0], G, lp.g_plus, frozenset(self.terms))):
            object.__setattr__(self, name, f)

    def derivative(self, x: Sequence[float], c_lat: Sequence[float],
                   c_lon: Sequence[float]) -> list[float]:
        """dx/dt+ of the 13-value state with the lateral (3) and longitudinal (4) controls."""
        bl = [sum(k * c for k, c in zip(row, c_lat)) for row in self._lat[1]]
        bn = [sum(k * c for k, c in zip(row, c_lon)) for row in self._lon[1]]
        return self._rhs(x[:10], bl, bn)

    def step(self, x: Sequence[float], c_lat: Sequence[float], c_lon: Sequence[float],
             h_wb: float) -> list[float]:
        """The state after ``h_wb`` wing beats with the controls held (order-6 sub-steps).

        Raises
        ------
        Hover6DOFError
            A non-finite state or step (the message names it); ``x`` is not changed.
        """
        if not (math.isfinite(h_wb) and h_wb > 0.0):
            raise Hover6DOFError(f"step = {h_wb!r} wing beats must be finite and > 0")
        bl = [sum(map(mul, row, c_lat)) for row in self._lat[1]]
        bn = [sum(map(mul, row, c_lon)) for row in self._lon[1]]
        rate = math.sqrt(x[3] * x[3] + x[4] * x[4] + x[5] * x[5])
        hmax = min(MAX_SUBSTEP_WB, MAX_TURN_PER_SUBSTEP_RAD / rate) if rate > 0 else MAX_SUBSTEP_WB
        n = max(1, math.ceil(h_wb / hmax - 1e-9))
        if n > 10_000_000:
            raise Hover6DOFError(f"a step of {h_wb!r} wing beats at a rate of {rate!r} rad per "
                                 f"wing beat needs {n} sub-steps; take shorter steps")
        h = h_wb / n
        y = self._substeps(x, n, h, bl, bn)  # Butcher's order 6 (see _equations)
        norm = math.sqrt(sum(c * c for c in y[6:10]))  # finiteness on the sum: faster
        if not (math.isfinite(sum(y)) or all(math.isfinite(a) for a in y)) or not norm > 0.0:
            raise Hover6DOFError(f"the state is not finite after a step of {h_wb!r} wing beats "
                                 f"(from u, v, w, p, q, r = {list(x[:6])!r})")
        y[6:10] = [c / norm for c in y[6:10]]
        return y


def initial_state(starts: dict[str, float], U: float, n: float) -> list[float]:
    """The non-dimensional state from the FMU's ``*_start`` values (SI) and U [m/s], n [Hz].

    The attitude: pitch ``delta_theta_start``, heading ``psi_start`` and the roll phi with
    sin(phi) = sin(delta_gamma_start) / cos(delta_theta_start) (see
    :mod:`dronefly.models.hover6dof`).

    Raises
    ------
    Hover6DOFError
        No attitude has the given gamma and theta.
    """
    theta, gamma = starts["delta_theta_start"], starts["delta_gamma_start"]
    sg, ct = math.sin(gamma), math.cos(theta)
    if abs(sg) > abs(ct) + 1e-15:
        raise Hover6DOFError(
            f"delta_gamma_start = {gamma!r} rad and delta_theta_start = {theta!r} rad: no "
            "attitude has both (|sin gamma| must not exceed cos theta)")
    phi = 0.0 if sg == 0.0 else math.asin(max(-1.0, min(1.0, sg / ct)))
    e = quaternion_from_euler(phi, theta, starts["psi_start"])
    k = n / U
    return [starts["delta_u_start"] / U, starts["delta_v_start"] / U, starts["delta_w_start"] / U,
            starts["delta_p_start"] / n, starts["delta_q_start"] / n, starts["delta_r_start"] / n,
            *e, starts["x_earth_start"] * k, starts["y_earth_start"] * k,
            starts["z_earth_start"] * k]


def outputs(x: Sequence[float], U: float, n: float) -> list[float]:
    """The FMU's outputs (SI) in the order of :data:`dronefly.models.hover6dof.OUTPUT_NAMES`."""
    u, v, w, p, q, r = x[:6]
    e0, e1, e2, e3 = e = x[6:10]
    phi, theta, psi = euler_from_quaternion(e)
    R = ((1.0 - 2.0 * (e2 * e2 + e3 * e3), 2.0 * (e1 * e2 - e0 * e3), 2.0 * (e1 * e3 + e0 * e2)),
         (2.0 * (e1 * e2 + e0 * e3), 1.0 - 2.0 * (e1 * e1 + e3 * e3), 2.0 * (e2 * e3 - e0 * e1)),
         (2.0 * (e1 * e3 - e0 * e2), 2.0 * (e2 * e3 + e0 * e1), 1.0 - 2.0 * (e1 * e1 + e2 * e2)))
    L = U / n
    return [v * U, p * n, r * n, gamma_from_quaternion(e), u * U, w * U, q * n, theta,
            phi, theta, psi, x[10] * L, x[11] * L, x[12] * L,
            *((row[0] * u + row[1] * v + row[2] * w) * U for row in R)]
