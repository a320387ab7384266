"""The hovering model drone fly as a rigid body in six degrees of freedom (not linearised).

The single home of the nonlinear equations; the FMU ``DroneFlyHover6DOF`` and the analysis
import it. The aerodynamics are the paper's: the mean force at equilibrium (balancing the
weight, fixed in the body) plus the linear stability and control derivatives of the lateral
(Eq. 12, Table 1; :mod:`dronefly.plant.model`) and longitudinal (Sect. 3.5;
:mod:`dronefly.plant_longitudinal.model`) models, applied to the body-axis velocity, rate and
control perturbations. That aerodynamic linearity is the paper's assumption and stays. What the
linearisation of Sect. 3.6 drops in the rigid body is restored:

- the transport terms omega x V of the translational equations (dr du, dp dw, ...);
- the gyroscopic terms omega x J omega with the full inertia tensor (dp dq, dq dr, ...);
- the exact projection of gravity on the body axes (sin and cos of the attitude);
- the exact attitude kinematics (a unit quaternion: no gimbal lock at any attitude).

Axes: body axes at the centre of mass, x forward, y right, z down, x and y horizontal at
equilibrium; earth axes north-east-down with the origin at the initial position.
Non-dimensional as the linear models (end of Sect. 2.1): velocities by U, rates by n, time in
wing beats t+ = n t, lengths by U/n. The state (13 values) is

    V+ = (u, v, w)           body-axis velocity / U
    w+ = (p, q, r)           body-axis rates / n
    e  = (e0, e1, e2, e3)    unit quaternion, body -> earth
    P+ = (x, y, z)           earth-axis position n / U

and with J+ = [[Ix+, 0, -Ixz+], [0, Iy+, 0], [-Ixz+, 0, Iz+]] and R = R(e) (body -> earth):

    dV+/dt+ = a_aero(V+, w+, c) - w+ x V+ + g+ (R^T e_z - e_z)
    dw+/dt+ = J+^-1 M_aero(V+, w+, c) - J+^-1 (w+ x J+ w+)
    de/dt+  = e (x) (0, w+) / 2
    dP+/dt+ = R V+

where a_aero = the rows (v, u, w) of the linear models' A and B without their gravity column,
and J+^-1 M_aero = their rows (p, r, q), as those rows are (Eqs. 2-3, 10-11; Sect. 3.5).
Linearised about hover this is exactly the two linear models (tests check the Jacobian).

Integration: Butcher's Runge-Kutta method of order 6 (7 stages) on sub-steps of at most
:data:`MAX_SUBSTEP_WB` wing beats (fewer where the body rotates fast), the quaternion
normalised after each step. Order 6 rather than the classical order 4: at the same cost per
communication step of 0.1 wing beat it is some 300 times more accurate (the classical
method on 0.05 wing beats missed 1e-9 relative at twice the Sect. 3.6 box: 1.8e-8). Sub-steps
of 0.2 wing beat keep 1e-9 relative with a margin of 4 (2.4e-10 at the box corner) at 0.65
times the cost of 0.1.
Pure Python arithmetic: the right-hand side costs about as much as one small numpy call.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable, Sequence

from ..errors import DroneflyError
from ..plant import model as lateral
from ..plant_longitudinal import model as longitudinal

__all__ = ["MAX_SUBSTEP_WB", "MAX_TURN_PER_SUBSTEP_RAD", "Hover6DOF", "Hover6DOFError",
           "STATE_SIZE", "TERMS", "euler_from_quaternion", "gamma_from_quaternion",
           "initial_state", "outputs", "quaternion_from_euler"]

#: largest Runge-Kutta sub-step, wing beats (global error ~3e-11 relative over 15 wing beats
#: from twice the Sect. 3.6 box; tests/test_hover6dof.py)
MAX_SUBSTEP_WB = 0.2
#: largest rotation of the body per sub-step, rad (sub-steps shrink when it rotates faster
#: than 0.5 rad per wing beat, the fastest rate of the linear dynamics)
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
    a = tuple(tuple(float(A[i, j]) for j in range(3)) for i in rows)
    b = tuple(tuple(float(x) for x in B[i]) for i in rows)
    for i in rows[1:]:  # the moment rows: no attitude dependence (structural zeros)
        if A[i, gravity_column] != 0.0:
            raise Hover6DOFError(f"A[{i + 1},{gravity_column + 1}] = {A[i, gravity_column]!r}: "
                                 "a moment that depends on the attitude is not aerodynamic")
    return a, b


def _make_rhs(la: tuple, na: tuple, J: tuple, g: float,
              terms: frozenset) -> Callable[[Sequence[float], Sequence[float], Sequence[float]],
                                            list[float]]:
    """dx/dt+ as a closure over the coefficients (local lookups: the hot loop of a step)."""
    (l00, l01, l02), (l10, l11, l12), (l20, l21, l22) = la
    (n00, n01, n02), (n10, n11, n12), (n20, n21, n22) = na
    Ix, Iy, Iz, Ixz, det = J
    gravity, transport, gyroscopic = ("gravity" in terms, "transport" in terms,
                                      "gyroscopic" in terms)
    asin = math.asin

    def rhs(x: Sequence[float], bl: Sequence[float], bn: Sequence[float]) -> list[float]:
        u, v, w, p, q, r, e0, e1, e2, e3 = x[:10]
        a_v = l00 * v + l01 * p + l02 * r + bl[0]
        a_p = l10 * v + l11 * p + l12 * r + bl[1]
        a_r = l20 * v + l21 * p + l22 * r + bl[2]
        a_u = n00 * u + n01 * w + n02 * q + bn[0]
        a_w = n10 * u + n11 * w + n12 * q + bn[1]
        a_q = n20 * u + n21 * w + n22 * q + bn[2]
        R20 = 2.0 * (e1 * e3 - e0 * e2)
        R21 = 2.0 * (e2 * e3 + e0 * e1)
        R22 = 1.0 - 2.0 * (e1 * e1 + e2 * e2)
        if gravity:  # g (R^T e_z - e_z): the third row of R
            a_u += g * R20
            a_v += g * R21
            a_w += g * (R22 - 1.0)
        else:  # linear in the attitude angles, as in the linear models: g (-theta, gamma, 0)
            a_u -= g * asin(max(-1.0, min(1.0, -R20)))
            a_v += g * asin(max(-1.0, min(1.0, R21)))
        if transport:  # - omega x V
            a_u -= q * w - r * v
            a_v -= r * u - p * w
            a_w -= p * v - q * u
        if gyroscopic:  # - J^-1 (omega x J omega)
            hx, hy, hz = Ix * p - Ixz * r, Iy * q, Iz * r - Ixz * p
            cx, cy, cz = q * hz - r * hy, r * hx - p * hz, p * hy - q * hx
            a_p -= (Iz * cx + Ixz * cz) / det
            a_q -= cy / Iy
            a_r -= (Ixz * cx + Ix * cz) / det
        return [a_u, a_v, a_w, a_p, a_q, a_r,
                0.5 * (-e1 * p - e2 * q - e3 * r), 0.5 * (e0 * p + e2 * r - e3 * q),
                0.5 * (e0 * q - e1 * r + e3 * p), 0.5 * (e0 * r + e1 * q - e2 * p),
                (1.0 - 2.0 * (e2 * e2 + e3 * e3)) * u + 2.0 * (e1 * e2 - e0 * e3) * v
                + 2.0 * (e1 * e3 + e0 * e2) * w,
                2.0 * (e1 * e2 + e0 * e3) * u + (1.0 - 2.0 * (e1 * e1 + e3 * e3)) * v
                + 2.0 * (e2 * e3 - e0 * e1) * w,
                R20 * u + R21 * v + R22 * w]

    return rhs


@dataclass(frozen=True)
class Hover6DOF:
    """The nonlinear model with the lateral and longitudinal parameters of the linear models.

    Parameters
    ----------
    lateral_params : dronefly.plant.model.LateralParameters
    longitudinal_params : dronefly.plant_longitudinal.model.LongitudinalParameters
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
        A, B = lateral.system_matrices(lp)  # validates
        object.__setattr__(self, "_lat", _aero_rows(A, B, (0, 1, 2), 3))
        A, B = longitudinal.system_matrices(np_)
        object.__setattr__(self, "_lon", _aero_rows(A, B, (0, 1, 2), 3))
        det = lp.Ix_plus * lp.Iz_plus - lp.Ixz_plus ** 2
        J = (lp.Ix_plus, np_.Iy_plus, lp.Iz_plus, lp.Ixz_plus, det)
        object.__setattr__(self, "_rhs", _make_rhs(self._lat[0], self._lon[0], J, lp.g_plus,
                                                   frozenset(self.terms)))

    # -- the equations -------------------------------------------------------------------
    def derivative(self, x: Sequence[float], c_lat: Sequence[float],
                   c_lon: Sequence[float]) -> list[float]:
        """dx/dt+ of the 13-value state with the lateral (3) and longitudinal (4) controls."""
        bl = [sum(k * c for k, c in zip(row, c_lat)) for row in self._lat[1]]
        bn = [sum(k * c for k, c in zip(row, c_lon)) for row in self._lon[1]]
        return self._rhs(x, bl, bn)

    # -- stepping ------------------------------------------------------------------------
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
        (_, lb), (_, nb) = self._lat, self._lon
        bl = [sum(k * c for k, c in zip(row, c_lat)) for row in lb]
        bn = [sum(k * c for k, c in zip(row, c_lon)) for row in nb]
        rate = math.sqrt(x[3] * x[3] + x[4] * x[4] + x[5] * x[5])
        hmax = min(MAX_SUBSTEP_WB, MAX_TURN_PER_SUBSTEP_RAD / rate) if rate > 0 else MAX_SUBSTEP_WB
        n = max(1, math.ceil(h_wb / hmax - 1e-9))
        if n > 10_000_000:
            raise Hover6DOFError(f"a step of {h_wb!r} wing beats at a rate of {rate!r} rad per "
                                 f"wing beat needs {n} sub-steps; take shorter steps")
        h = h_wb / n
        h3, h8, h12, h16, h44, h120 = h / 3, h / 8, h / 12, h / 16, h / 44, h / 120
        f = self._rhs
        y = list(x)
        for _ in range(n):  # Butcher (1964): c = 0, 1/3, 2/3, 1/3, 1/2, 1/2, 1
            k1 = f(y, bl, bn)
            k2 = f([a + h3 * b for a, b in zip(y, k1)], bl, bn)
            k3 = f([a + 2.0 * h3 * c for a, c in zip(y, k2)], bl, bn)
            k4 = f([a + h12 * (b - d) + h3 * c for a, b, c, d in zip(y, k1, k2, k3)], bl, bn)
            k5 = f([a + h16 * (18.0 * c - b - 3.0 * d - 6.0 * e)
                    for a, b, c, d, e in zip(y, k1, k2, k3, k4)], bl, bn)
            k6 = f([a + h8 * (9.0 * c - 3.0 * d - 6.0 * e + 4.0 * g)
                    for a, c, d, e, g in zip(y, k2, k3, k4, k5)], bl, bn)
            k7 = f([a + h44 * (9.0 * b - 36.0 * c + 63.0 * d + 72.0 * e - 64.0 * g)
                    for a, b, c, d, e, g in zip(y, k1, k2, k3, k4, k6)], bl, bn)
            y = [a + h120 * (11.0 * (b + k) + 81.0 * (d + e) - 32.0 * (g + j))
                 for a, b, d, e, g, j, k in zip(y, k1, k3, k4, k5, k6, k7)]
        norm = math.sqrt(sum(c * c for c in y[6:10]))
        if not all(math.isfinite(a) for a in y) or not norm > 0.0:
            raise Hover6DOFError(f"the state is not finite after a step of {h_wb!r} wing beats "
                                 f"(from u, v, w, p, q, r = {list(x[:6])!r})")
        y[6:10] = [c / norm for c in y[6:10]]
        return y


def initial_state(starts: dict[str, float], U: float, n: float) -> list[float]:
    """The non-dimensional state from the FMU's ``*_start`` values (SI) and U [m/s], n [Hz].

    The attitude: pitch ``delta_theta_start``, heading ``psi_start`` and the roll phi with
    sin(phi) = sin(delta_gamma_start) / cos(delta_theta_start) (see
    :mod:`dronefly.hover6dof`).

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
    """The FMU's outputs (SI) in the order of :data:`dronefly.hover6dof.OUTPUT_NAMES`."""
    u, v, w, p, q, r = x[:6]
    e = x[6:10]
    e0, e1, e2, e3 = e
    phi, theta, psi = euler_from_quaternion(e)
    R = ((1.0 - 2.0 * (e2 * e2 + e3 * e3), 2.0 * (e1 * e2 - e0 * e3), 2.0 * (e1 * e3 + e0 * e2)),
         (2.0 * (e1 * e2 + e0 * e3), 1.0 - 2.0 * (e1 * e1 + e3 * e3), 2.0 * (e2 * e3 - e0 * e1)),
         (2.0 * (e1 * e3 - e0 * e2), 2.0 * (e2 * e3 + e0 * e1), 1.0 - 2.0 * (e1 * e1 + e2 * e2)))
    L = U / n
    return [v * U, p * n, r * n, gamma_from_quaternion(e), u * U, w * U, q * n, theta,
            phi, theta, psi, x[10] * L, x[11] * L, x[12] * L,
            *((row[0] * u + row[1] * v + row[2] * w) * U for row in R)]
