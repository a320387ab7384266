"""Which dropped rigid-body term breaks the linear theory first? The model, term by term.

The closed loops of the comparison sweep, run on the model classes instead of the FMUs: the
linear loop (both linear models, exact zero-order hold) and the nonlinear one
(:class:`dronefly.models.rigid_body.Hover6DOF`), each with the controls computed from the
state at every communication point and held over the step (u_k = K x+_k, the Gauss-Seidel
loop of the co-simulation), from the same initial state. The nonlinear model is run with all
restored terms, and with each of them (transport, gyroscopic, exact gravity) switched off in
turn; what remains with all three off is the nonlinear attitude kinematics. The term whose
removal shrinks the linearisation error most is the one that breaks the linear theory first.

With all terms on, :func:`linearisation_error` is what ``dronefly sweep --compare`` measures
through the FMUs (a test checks they agree).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Sequence

import numpy as np

from ...models.feedback import LONGITUDINAL_GAINS_DESIGN_B, PAPER_GAINS_EQ27
from ...models.linear import discretize_zoh
from ...models import lateral_dynamics as lateral
from ...models import lateral_interface
from ...models.rigid_body import TERMS, Hover6DOF, gamma_from_quaternion
from ...models import longitudinal_dynamics as longitudinal

from ..sweep.cases import CONTROL_BOUND, STATE_BOUNDS_SECT36, direction_vector

__all__ = ["TermErrors", "VARIANTS", "line_profile", "linearisation_error", "term_errors"]

#: the nonlinear variants compared: all terms, each one off, all off (kinematics only)
VARIANTS: dict[str, frozenset] = {
    "all": TERMS,
    **{f"no {t}": TERMS - {t} for t in sorted(TERMS)},
    "kinematics only": frozenset(),
}


def _gains() -> tuple[np.ndarray, np.ndarray]:
    Kl = np.zeros((3, 4))
    Kl[0] = PAPER_GAINS_EQ27
    Kn = np.zeros((4, 4))
    Kn[2] = LONGITUDINAL_GAINS_DESIGN_B
    return Kl, Kn


def linearisation_error(x0_lateral: Sequence[float], *, terms: frozenset = TERMS,
                        step_wb: float = 1.0, stop_wb: float = 100.0) -> np.ndarray:
    """Peak over the run of |x_nonlinear - x_linear| / bound per state.

    Parameters
    ----------
    x0_lateral : 4 floats
        Initial non-dimensional lateral state (dv+, dp+, dr+, dgamma); the longitudinal
        state starts at zero.
    terms : frozenset
        Restored rigid-body terms of the nonlinear model.
    step_wb, stop_wb : float
        Communication step and stop time, wing beats.

    Returns
    -------
    ndarray of 8
        Lateral (dv, dp, dr, dgamma) then longitudinal (du, dw, dq, dtheta) errors, as
        fractions of the Sect. 3.6 bounds.
    """
    return _errors(x0_lateral, terms, step_wb, stop_wb)[0]


def line_profile(direction: Sequence[float], amplitudes: Sequence[float], *,
                 step_wb: float = 1.0, stop_wb: float = 100.0) -> list[tuple[float, ...]]:
    """Along a line of initial states: per amplitude a (box units), from the lateral state a *
    direction * the Sect. 3.6 bounds, ``(a, lateral error, longitudinal error, linear peak)``:
    the largest linearisation errors of :func:`linearisation_error` (fractions of the bounds)
    and the linear loop's peak over the run of max(|x_i| / bound_i, |u| / 0.4 rad), the
    sweep's ``peak`` (below 1: the linear trajectory stays within the bounds)."""
    out = []
    for a in amplitudes:
        x0 = float(a) * np.asarray(direction, float) * np.array(STATE_BOUNDS_SECT36)
        e, _, peak = _errors(x0, TERMS, step_wb, stop_wb)
        out.append((float(a), float(e[:4].max()), float(e[4:].max()), peak))
    return out


def _errors(x0_lateral: Sequence[float], terms: frozenset = TERMS, step_wb: float = 1.0,
            stop_wb: float = 100.0,
            longitudinal_control: bool = True) -> tuple[np.ndarray, float, float]:
    """(the errors of :func:`linearisation_error`, the largest sink z_earth [m], the linear
    loop's peak of :func:`line_profile`); ``longitudinal_control`` False: the longitudinal
    controller's gains zero (the lateral controller alone)."""
    lp, np_ = lateral.default_parameters(), longitudinal.default_parameters()
    model = Hover6DOF(lp, np_, terms)
    Kl, Kn = _gains()
    if not longitudinal_control:
        Kn = np.zeros_like(Kn)
    A1, B1 = lateral.system_matrices(lp)
    A2, B2 = longitudinal.system_matrices(np_)
    P1, G1 = discretize_zoh(A1, B1, step_wb)
    P2, G2 = discretize_zoh(A2, B2, step_wb)
    F1, F2 = P1 + G1 @ Kl, P2 + G2 @ Kn
    g0 = float(x0_lateral[3])
    x = [0.0, float(x0_lateral[0]), 0.0, float(x0_lateral[1]), 0.0, float(x0_lateral[2]),
         float(np.cos(g0 / 2)), float(np.sin(g0 / 2)), 0.0, 0.0, 0.0, 0.0, 0.0]
    lat, lon = np.array(x0_lateral, float), np.zeros(4)
    bounds = np.array(STATE_BOUNDS_SECT36 * 2)
    worst, sink, peak = np.zeros(8), 0.0, 0.0
    n_steps = int(round(stop_wb / step_wb))
    for k in range(n_steps + 1):  # every communication point, the last one included
        sink = max(sink, x[12])
        nl_lat = np.array([x[1], x[3], x[5], gamma_from_quaternion(x[6:10])])
        theta = float(np.arcsin(np.clip(-2.0 * (x[7] * x[9] - x[6] * x[8]), -1.0, 1.0)))
        nl_lon = np.array([x[0], x[2], x[4], theta])
        worst = np.maximum(worst, np.abs(np.concatenate([nl_lat - lat, nl_lon - lon])) / bounds)
        peak = max(peak, float(np.max(np.abs(lat) / bounds[:4])),
                   float(np.max(np.abs(Kl @ lat))) / CONTROL_BOUND)
        if k < n_steps:
            x = model.step(x, (Kl @ nl_lat).tolist(), (Kn @ nl_lon).tolist(), step_wb)
            lat, lon = F1 @ lat, F2 @ lon
    return worst, sink * lateral_interface.U_M_PER_S / lateral_interface.N_HZ, peak


@dataclass(frozen=True)
class TermErrors:
    """The largest lateral (and longitudinal) linearisation error per variant."""

    direction: str
    amplitude: float
    lateral: dict[str, float]
    longitudinal: dict[str, float]

    altitude_lost_m: dict[str, float]

    @property
    def contributions(self) -> dict[str, float]:
        """Lateral error each part accounts for: the kinematics (all terms off), and each
        restored term (the error with all terms minus the error without it; negative where
        it cancels part of the others)."""
        out = {"kinematics": self.lateral["kinematics only"]}
        out.update({v[len("no "):]: self.lateral["all"] - self.lateral[v]
                    for v in self.lateral if v.startswith("no ")})
        return out

    @property
    def first(self) -> str:
        """The part with the largest contribution to the lateral error."""
        c = self.contributions
        return max(c, key=lambda k: c[k])


def term_errors(direction: str, amplitude: float = 1.0, **kw: Any) -> TermErrors:
    """:func:`linearisation_error` of every variant of :data:`VARIANTS` for one initial state:
    ``amplitude`` (box units) along ``direction`` (``+dr``, ``-mode1``, ...); ``kw``:
    ``step_wb``, ``stop_wb`` (wing beats) and ``longitudinal_control`` (False: the lateral
    controller alone)."""
    x0 = amplitude * direction_vector(direction) * np.array(STATE_BOUNDS_SECT36)
    lat, lon, alt = {}, {}, {}
    for name, terms in VARIANTS.items():
        e, z, _ = _errors(x0, terms, **kw)
        lat[name], lon[name], alt[name] = float(e[:4].max()), float(e[4:].max()), z
    return TermErrors(direction, amplitude, lat, lon, alt)
