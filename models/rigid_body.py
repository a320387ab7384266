"""The hovering model drone fly as a rigid body in six degrees of freedom (not linearised).

The single home of the nonlinear equations; the FMU ``DroneFlyHover6DOF`` and the analysis
import it. The aerodynamics are, by default, the paper's: the mean force at equilibrium
(balancing the weight, fixed in the body) plus the linear derivatives of the lateral (Eq. 12,
Table 1; :mod:`dronefly.models.lateral_dynamics`) and longitudinal (Sect. 3.5;
:mod:`dronefly.models.longitudinal_dynamics`) models, the paper's assumption. With
``aerodynamics`` a model of the wings (:class:`CycleAveragedForces`, the quasi-steady
:class:`dronefly.models.quasisteady.QuasiSteadyModel`) the derivative terms are replaced by its
cycle-averaged forces as functions of the state, less their value at the trimmed hover (the
force that balances the weight, as in the linear case): both halves of Sect. 3.6 together.
This module imports no numpy; the quasi-steady model does, and only whoever chooses it.
What the linearisation of Sect. 3.6 drops in the rigid body is restored: the transport
terms omega x V (dr du, dp dw, ...), the gyroscopic terms omega x J omega with the full inertia tensor (dp dq, dq dr, ...),
the exact projection of gravity and the exact attitude kinematics (a unit quaternion: no
gimbal lock at any attitude).

Axes (body axes at the centre of mass, x forward, y right, z down; earth axes north-east-down),
the non-dimensional 13-value state (V+ = (u, v, w), omega+ = (p, q, r), the unit quaternion e
body -> earth, the earth-axis position P+) and the equations: fmu_src/hover6dof/README.md,
"Equations"; in code they are :data:`_RHS`, line by line, with a_aero = the rows (v, u, w) of
the linear models' A and B without their gravity column and J+^-1 M_aero = their rows (p, r, q).
Linearised about hover this is exactly the two linear models (tests check the Jacobian).

Integration: Butcher's Runge-Kutta method of order 6 (7 stages, :data:`_STAGES`) on sub-steps
of at most :data:`MAX_SUBSTEP_WB` wing beats (shorter where the body turns fast), compiled with
the right-hand side into straight-line Python (:func:`_make_functions`); the quaternion is
normalised after each step. Accuracy (within 1e-9 of ``solve_ivp``) and cost: the README and
docs/benchmarks.md.

Two ways of writing fast straight-line code, kept on purpose: exec of generated source is
the package's one exception, :func:`_make_functions` (seven Runge-Kutta stages of 13 states
with the terms chosen per instance: written out by hand that is hundreds of lines per choice of
terms); everything else is plain code, written out by hand where it must be fast (the linear
plants' steps of :mod:`dronefly.models.linear`, the control law's one row). Plain Python
functions for these equations cost more per step and take the 6-DOF/pair cost ratio through
FMI over its target of 5 (docs/benchmarks.md, "Generated code", says how to measure it); no
other code has a measured need for exec, which an FMU reviewer must read as generated text.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from functools import lru_cache
from typing import Any, Callable, Protocol, Sequence

from ..core.errors import DroneflyError
from . import lateral_dynamics
from . import longitudinal_dynamics

__all__ = ["CycleAveragedForces", "MAX_SUBSTEP_QS_WB", "MAX_SUBSTEP_WB",
           "MAX_TURN_PER_SUBSTEP_QS_RAD", "MAX_TURN_PER_SUBSTEP_RAD", "Hover6DOF",
           "Hover6DOFError", "quasi_steady_rates",
           "STATE_SIZE", "TERMS", "euler_from_quaternion", "gamma_from_quaternion",
           "initial_state", "outputs", "quaternion_from_euler"]

#: largest Runge-Kutta sub-step, wing beats (the accuracy this gives: tests/test_hover6dof.py)
MAX_SUBSTEP_WB = 0.2
#: largest Runge-Kutta sub-step with the quasi-steady aerodynamics, wing beats: each stage
#: costs a cycle-averaged force evaluation; the accuracy (within 1e-5 of the disturbance of
#: sub-steps of 0.02 wing beat): tests/test_hover6dof_aero.py
MAX_SUBSTEP_QS_WB = 0.5
#: largest turn per sub-step with the quasi-steady aerodynamics, rad: the forces' kinks (an
#: element's velocity through zero) bound the accuracy first (tests/test_hover6dof_aero.py)
MAX_TURN_PER_SUBSTEP_QS_RAD = 0.1
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


#: dx/dt+ of (u, v, w, p, q, r, e0, e1, e2, e3) as statements assigning a_u .. a_r, d6 .. d12;
#: lines tagged [term] are kept with that term, [-term] without it, [position] where dP+/dt+ is
#: needed, [linear] / [quasi_steady] with that aerodynamics (t = 2 e, s_ij = 2 e_i e_j: exact
#: doublings, 2 (e1 e3 - e0 e2) = s13 - s02 exactly)
_RHS = """\
a_v = l00 * v + l01 * p + l02 * r + bl0  [linear] the paper's derivatives
a_p = l10 * v + l11 * p + l12 * r + bl1  [linear]
a_r = l20 * v + l21 * p + l22 * r + bl2  [linear]
a_u = n00 * u + n01 * w + n02 * q + bn0  [linear]
a_w = n10 * u + n11 * w + n12 * q + bn1  [linear]
a_q = n20 * u + n21 * w + n22 * q + bn2  [linear]
a_v, a_p, a_r, a_u, a_w, a_q = acc(u, v, w, p, q, r)  [quasi_steady] see quasi_steady_rates
t0, t1, t2 = e0 + e0, e1 + e1, e2 + e2
s13, s02, s23, s01, s11, s22 = t1 * e3, t0 * e2, t2 * e3, t0 * e1, t1 * e1, t2 * e2
R20, R21, R22 = s13 - s02, s23 + s01, 1.0 - (s11 + s22)
a_u, a_v, a_w = a_u + g * R20, a_v + g * R21, a_w + g * (R22 - 1.0)  [gravity] g (R^T e_z - e_z)
a_u -= g * asin(max(-1.0, min(1.0, -R20)))  [-gravity] linear: g (-theta, gamma, 0)
a_v += g * asin(max(-1.0, min(1.0, R21)))  [-gravity]
a_u, a_v, a_w = a_u - (q * w - r * v), a_v - (r * u - p * w), a_w - (p * v - q * u)  [transport]
pq, qr = p * q, q * r  [gyroscopic] - J^-1 (omega x J omega), see _gyroscopic
a_p -= G0 * qr + G1 * pq  [gyroscopic]
a_q -= G2 * (p * r) + G3 * (p * p - r * r)  [gyroscopic]
a_r -= G4 * qr + G5 * pq  [gyroscopic]
d6 = 0.5 * (-e1 * p - e2 * q - e3 * r)
d7 = 0.5 * (e0 * p + e2 * r - e3 * q)
d8 = 0.5 * (e0 * q - e1 * r + e3 * p)
d9 = 0.5 * (e0 * r + e1 * q - e2 * p)
s33, s12, s03 = (e3 + e3) * e3, t1 * e2, t0 * e3  [position]
d10 = (1.0 - (s22 + s33)) * u + (s12 - s03) * v + (s13 + s02) * w  [position] R V
d11 = (s12 + s03) * u + (1.0 - (s11 + s33)) * v + (s23 - s01) * w  [position]
d12 = R20 * u + R21 * v + R22 * w  [position]
"""
_STATE = ("u", "v", "w", "p", "q", "r", "e0", "e1", "e2", "e3")
_OUT = re.compile(r"\b(?:a_([uvwpqr])|d(\d+))\b")
#: Butcher's (1964) order 6, c = 0, 1/3, 2/3, 1/3, 1/2, 1/2, 1: each stage's input (y the start
#: of the sub-step, K<s> the derivative of stage s), then the sub-step's result
_STAGES = ("y", "y + h3 * K1", "y + h23 * K2", "y + h12 * (K1 - K3) + h3 * K2",
           "y + h16 * (18.0 * K2 - K1 - 3.0 * K3 - 6.0 * K4)",
           "y + h8 * (9.0 * K2 - 3.0 * K3 - 6.0 * K4 + 4.0 * K5)",
           "y + h44 * (9.0 * K1 - 36.0 * K2 + 63.0 * K3 + 72.0 * K4 - 64.0 * K6)")
_RESULT = "y + h120 * (11.0 * (K1 + K7) + 81.0 * (K3 + K4) - 32.0 * (K5 + K6))"


def _rhs_source(terms: frozenset, out: str, indent: str, positions: bool = True) -> list[str]:
    """The statements of :data:`_RHS` for ``terms``, writing derivative j to ``out.format(j)``
    (the positions' only if ``positions``)."""
    lines = []
    for line in _RHS.splitlines():
        code, _, tag = line.partition("  [")
        term = tag.split("]")[0]
        if (positions if term == "position" else not term or (
                term.lstrip("-") in terms) != term.startswith("-")):
            lines.append(indent + _OUT.sub(lambda m: out.format(
                "uvwpqr".index(m[1]) if m[1] else m[2]), code))
    return lines


def _gyroscopic(Ix: float, Iy: float, Iz: float, Ixz: float) -> tuple[float, ...]:
    """G0 .. G5 of J^-1 (omega x J omega) = (G0 qr + G1 pq, G2 pr + G3 (p^2 - r^2), G4 qr +
    G5 pq), J = [[Ix, 0, -Ixz], [0, Iy, 0], [-Ixz, 0, Iz]]."""
    det = Ix * Iz - Ixz ** 2
    return ((Iz * (Iz - Iy) + Ixz * Ixz) / det, Ixz * (Iy - Ix - Iz) / det, (Ix - Iz) / Iy,
            Ixz / Iy, Ixz * (Iz - Iy + Ix) / det, (Ix * (Iy - Ix) - Ixz * Ixz) / det)


def _value(formula: str, j: int) -> str:
    """``formula`` (of :data:`_STAGES`) for state value j: y -> y<j>, K<s> -> k<s>_<j>."""
    return re.sub(r"K(\d)", rf"k\g<1>_{j}", formula.replace("y", f"y{j}"))


@lru_cache(maxsize=16)  # a bounded cache: instances with equal parameters share one compile
def _make_functions(la: tuple, na: tuple, G: tuple, g: float, terms: frozenset,
                    quasi_steady: bool = False) -> tuple:
    """``(rhs(x, bl, bn) -> dx/dt+, substeps(y, n, h, bl, bn) -> y after n sub-steps of h)``
    compiled from :data:`_RHS` and :data:`_STAGES` into straight-line arithmetic on locals: no
    lists and no calls inside a sub-step (with the linear aerodynamics), nothing computed that
    the result does not use. The coefficients are closure variables (exact floats, never
    printed as text); the source is built from the constant text of this module only. With
    ``quasi_steady`` the aerodynamic lines are one call per stage, ``acc(u, v, w, p, q, r)``
    (:func:`quasi_steady_rates`), and the functions are ``rhs(x, acc)`` and
    ``substeps(y, n, h, acc)``."""
    names = [f"{a}{i}{j}" for a in "ln" for i in range(3) for j in range(3)]
    values = [c for rows in (la, na) for row in rows for c in row]
    head = [] if quasi_steady else ["        bl0, bl1, bl2 = bl", "        bn0, bn1, bn2 = bn"]
    args = "acc" if quasi_steady else "bl, bn"
    terms = terms | {"quasi_steady" if quasi_steady else "linear"}
    src = [f"def bind({', '.join(names)}, G0, G1, G2, G3, G4, G5, g, asin):",
           f"    def rhs(x, {args}):", *head, f"        {', '.join(_STATE)} = x[:10]",
           *_rhs_source(terms, "x{}", "        "),
           f"        return [{', '.join(f'x{j}' for j in range(13))}]",
           f"    def substeps(y, n, h, {args}):", *head,
           "        h3, h8, h12, h16, h44, h120 = h / 3, h / 8, h / 12, h / 16, h / 44, h / 120",
           "        h23 = 2.0 * h3",
           f"        {', '.join(f'y{j}' for j in range(13))}, = y", "        for _ in range(n):"]
    for s, stage in enumerate(_STAGES, start=1):  # the positions (10-12) never enter the rhs
        src += [f"            {name} = {_value(stage, j)}" for j, name in enumerate(_STATE)]
        src += _rhs_source(terms, f"k{s}_{{}}", " " * 12, positions=s != 2)  # K2: not in _RESULT
    src += [f"            y{j} = {_value(_RESULT, j)}" for j in range(13)]
    src += [f"        return [{', '.join(f'y{j}' for j in range(13))}]", "    return rhs, substeps"]
    namespace: dict[str, Callable[..., tuple]] = {}
    exec(compile("\n".join(src) + "\n", "<dronefly.fmu_src.hover6dof equations>", "exec"), namespace)
    return namespace["bind"](*values, *G, g, math.asin)


class CycleAveragedForces(Protocol):
    """Aerodynamics as functions of the state: what :class:`Hover6DOF` needs of a model of
    the flapping wings (:class:`dronefly.models.quasisteady.QuasiSteadyModel` is one)."""

    def state_function(self, controls: Sequence[float]) -> Callable[[Sequence[float]], Any]:
        """For the 7 controls [rad] held (lateral ``delta_Phi_a``, ``delta_alpha_1a``,
        ``delta_alpha_2a``, then longitudinal ``delta_Phi``, ``delta_alpha_1``,
        ``delta_phibar``, ``delta_alpha_2``): (du+, dv+, dw+, dp+, dq+, dr+) -> the cycle-averaged
        (X+, Y+, Z+, L+, M+, N+), forces over 0.5 rho U^2 S_t, moments over 0.5 rho U^2 S_t c,
        body axes (a sequence, or an array with ``tolist``)."""


def quasi_steady_rates(f: Callable[[Sequence[float]], Any], F0: Sequence[float], m: float,
                        Ix: float, Iy: float, Iz: float, Ixz: float) -> Callable[..., tuple]:
    """``acc(u, v, w, p, q, r)`` of the [quasi_steady] line of :data:`_RHS`: (a_v, a_p, a_r,
    a_u, a_w, a_q), the force F = f(state) - F0 over m+ and J+^-1 times the moment, F0 the
    forces at the trimmed hover (which balance the weight: the gravity lines of :data:`_RHS`
    hold the rest, as with the linear aerodynamics)."""
    X0, Y0, Z0, L0, M0, N0 = F0
    det = Ix * Iz - Ixz * Ixz
    im, iy, a, b, c = 1.0 / m, 1.0 / Iy, Iz / det, Ixz / det, Ix / det

    def acc(u: float, v: float, w: float, p: float, q: float, r: float) -> tuple:
        X, Y, Z, L, M, N = _as_list(f((u, v, w, p, q, r)))
        dL, dN = L - L0, N - N0
        return ((Y - Y0) * im, a * dL + b * dN, b * dL + c * dN, (X - X0) * im,
                (Z - Z0) * im, (M - M0) * iy)

    return acc


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
    aerodynamics : CycleAveragedForces, optional
        None (the default): the paper's linear derivatives of the two parameter sets.
        Otherwise the cycle-averaged forces of that model as functions of the state
        (:class:`dronefly.models.quasisteady.QuasiSteadyModel`), less their value at hover
        with no control (the trim force, which balances the weight), in place of the
        derivative terms; the parameters then give only m+, g+ and the inertias, and the
        sub-steps are at most :data:`MAX_SUBSTEP_QS_WB` and turn at most
        :data:`MAX_TURN_PER_SUBSTEP_QS_RAD`.
    """

    lateral_params: lateral_dynamics.LateralParameters
    longitudinal_params: longitudinal_dynamics.LongitudinalParameters
    terms: frozenset = TERMS
    aerodynamics: CycleAveragedForces | None = None

    def __post_init__(self) -> None:
        lp, np_ = self.lateral_params, self.longitudinal_params
        for name in ("m_plus", "g_plus"):
            if getattr(lp, name) != getattr(np_, name):
                raise Hover6DOFError(f"{name} = {getattr(lp, name)!r} (lateral) and "
                                     f"{getattr(np_, name)!r} (longitudinal) must agree")
        unknown = set(self.terms) - TERMS
        if unknown:
            raise Hover6DOFError(f"terms {sorted(unknown)!r}: choose from {sorted(TERMS)}")
        for name, axis, params in (("_lat", lateral_dynamics, lp), ("_lon", longitudinal_dynamics, np_)):
            object.__setattr__(self, name, _aero_rows(*axis.system_rows(params), (0, 1, 2), 3))
        G = _gyroscopic(lp.Ix_plus, np_.Iy_plus, lp.Iz_plus, lp.Ixz_plus)
        qs = self.aerodynamics is not None
        for name, f in zip(("_rhs", "_substeps"), _make_functions(
                self._lat[0], self._lon[0], G, lp.g_plus, frozenset(self.terms), qs)):
            object.__setattr__(self, name, f)
        if qs:  # the forces at hover with no control: the trim, which balances the weight
            F0 = [float(v) for v in _as_list(self.aerodynamics.state_function(  # type: ignore
                (0.0,) * 7)((0.0,) * 6))]
            if len(F0) != 6 or not all(math.isfinite(v) for v in F0):
                raise Hover6DOFError(f"the aerodynamics at hover give {F0!r}: expected 6 "
                                     "finite forces and moments")
            object.__setattr__(self, "_F0", tuple(F0))
            object.__setattr__(self, "_inertia", (lp.m_plus, lp.Ix_plus, np_.Iy_plus,
                                                  lp.Iz_plus, lp.Ixz_plus))

    def _acc(self, c_lat: Sequence[float], c_lon: Sequence[float]) -> Callable[..., tuple]:
        """The quasi-steady aerodynamics' ``acc`` for the controls held over a step."""
        f = self.aerodynamics.state_function((*c_lat, *c_lon))  # type: ignore[union-attr]
        return quasi_steady_rates(f, self._F0, *self._inertia)  # type: ignore[attr-defined]

    def derivative(self, x: Sequence[float], c_lat: Sequence[float],
                   c_lon: Sequence[float]) -> list[float]:
        """dx/dt+ of the 13-value state with the lateral (3) and longitudinal (4) controls."""
        if self.aerodynamics is not None:
            return self._rhs(x, self._acc(c_lat, c_lon))
        bl = [_dot(row, c_lat) for row in self._lat[1]]
        bn = [_dot(row, c_lon) for row in self._lon[1]]
        return self._rhs(x, bl, bn)

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
        qs = self.aerodynamics is not None
        if qs:
            args: tuple = (self._acc(c_lat, c_lon),)
        else:
            args = ([_dot(row, c_lat) for row in self._lat[1]],
                    [_dot(row, c_lon) for row in self._lon[1]])
        rate = math.sqrt(x[3] * x[3] + x[4] * x[4] + x[5] * x[5])
        top, turn = ((MAX_SUBSTEP_QS_WB, MAX_TURN_PER_SUBSTEP_QS_RAD) if qs
                     else (MAX_SUBSTEP_WB, MAX_TURN_PER_SUBSTEP_RAD))
        hmax = min(top, turn / rate) if rate > 0 else top
        n = max(1, math.ceil(h_wb / hmax - 1e-9))
        if n > 10_000_000:
            raise Hover6DOFError(f"a step of {h_wb!r} wing beats at a rate of {rate!r} rad per "
                                 f"wing beat needs {n} sub-steps; take shorter steps")
        h = h_wb / n
        try:
            y = self._substeps(x, n, h, *args)  # Butcher's order 6 (see _STAGES)
        except (OverflowError, ValueError, FloatingPointError) as e:  # the aerodynamics' own
            raise Hover6DOFError(f"the aerodynamics failed in a step of {h_wb!r} wing beats "
                                 f"(from u, v, w, p, q, r = {list(x[:6])!r}): {e}") from e
        e0, e1, e2, e3 = y[6:10]
        norm = math.sqrt(e0 * e0 + e1 * e1 + e2 * e2 + e3 * e3)  # finiteness on the sum: faster
        if not (math.isfinite(sum(y)) or all(math.isfinite(a) for a in y)) or not norm > 0.0:
            raise Hover6DOFError(f"the state is not finite after a step of {h_wb!r} wing beats "
                                 f"(from u, v, w, p, q, r = {list(x[:6])!r})")
        y[6:10] = [c / norm for c in y[6:10]]
        return y


def _dot(row: Sequence[float], c: Sequence[float]) -> float:
    """The sum of ``row[i] * c[i]``, left to right: the same float on every Python (``sum`` of
    floats is compensated from Python 3.12 on) and in the native FMU (fmu_src/hover6dof/model.c)."""
    s = 0.0
    for k, x in zip(row, c):
        s += k * x
    return s


def _as_list(values: Any) -> list:
    """A sequence of forces as a list (an array by its ``tolist``)."""
    return values.tolist() if hasattr(values, "tolist") else list(values)


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
