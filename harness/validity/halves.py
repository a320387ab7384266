"""Both halves of Sect. 3.6: the error of the linear theory from the rigid body, from the
aerodynamics, and from both together.

Sect. 3.6 rests the linear theory on two assumptions: a linearised rigid body and
aerodynamic forces linear in the state. Each half is measured here by the closed loops of the
comparison sweep, run on the model classes as in :mod:`.terms` (the controls computed from the
state at every communication point and held over the step, from the same initial state), each
nonlinear loop against the linear loop of its own tangent at hover:

``rigid_body``
    :class:`~dronefly.models.rigid_body.Hover6DOF` with the paper's linear aerodynamics
    against the two linear plants of the paper (:func:`.terms.linearisation_error`, what
    ``dronefly sweep --compare nonlinear`` measures through the FMUs).
``aerodynamics``
    the *linear* rigid body (the linear models' kinematics and gravity: dgamma/dt = p,
    dtheta/dt = q, g+ (-theta, gamma, 0)) driven by the cycle-averaged forces of the
    quasi-steady wing model as functions of the state (:class:`LinearRigidBody`), against the
    linear plants of the quasi-steady derivatives.
``both``
    :class:`~dronefly.models.rigid_body.Hover6DOF` with the quasi-steady forces (the FMU's
    ``aerodynamics = 2``) against the same linear plants.
``rigid_body_qs``
    the rigid-body half on the quasi-steady plant: :class:`~dronefly.models.rigid_body.Hover6DOF`
    with the *linear* aerodynamics of the quasi-steady derivatives against the same linear
    plants, so that the three measurements on the quasi-steady plant (this one,
    ``aerodynamics`` and ``both``) share plant and controller, and ``both`` can be read
    against the sum of its halves.

Why the quasi-steady halves have a reference of their own: the model's derivatives are not
the paper's CFD ones (docs/aerodynamics.md), and against the paper's plants its error would
be that difference, not the nonlinearity. The linear reference of the quasi-steady plant is
the tangent of its forces at hover: the central-difference derivatives of
:func:`dronefly.harness.aero.beside_paper.derivatives` in the linear models' A and B (the paper's
m+, g+ and inertias). Nor can the quasi-steady loops keep the paper's gains: Eq. (27) leaves
the quasi-steady lateral loop unstable (+0.0741 per wing beat) and the longitudinal design
(b) the longitudinal one (+0.248). They get the paper's method re-applied to the
quasi-steady plant: laterally coefficient matching on dPhi_a moving the unstable eigenvalue
to 0 and keeping the others (:func:`dronefly.harness.aero.beside_paper.closed_loop`, as Eq. (27)
does on the CFD plant), longitudinally the gains on dphibar that give the quasi-steady plant
the closed-loop eigenvalues of the paper's design (b) (Ackermann). So each half is a
comparable measurement: a neutral lateral loop and a stable longitudinal one, in both the
paper's and the quasi-steady pair.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache
from typing import Any, Callable, Sequence

import numpy as np

from ...models import lateral_dynamics
from ...models import longitudinal_dynamics
from ...models.feedback import LONGITUDINAL_GAINS_DESIGN_B
from ...models.linear import discretize_zoh
from ...models.quasisteady import FORCES, QuasiSteadyModel
from ...models.rigid_body import Hover6DOF, gamma_from_quaternion, quasi_steady_rates
from ..aero.beside_paper import (LATERAL_PARAMETERS, LONGITUDINAL_PARAMETERS, closed_loop,
                            derivative_parameters, derivatives, matrices_with_derivatives)
from ..paper.analysis import ackermann_gains
from ..sweep.cases import STATE_BOUNDS_SECT36, direction_vector
from .terms import linearisation_error

__all__ = ["HALF_LABELS", "HALVES", "LinearRigidBody", "QuasiSteadyLoops", "format_halves",
           "format_halves_table", "half_errors", "halves_summary", "halves_table",
           "quasi_steady_loops"]

#: the three measurements, in the order they are reported
HALVES: tuple[str, ...] = ("rigid_body", "aerodynamics", "both", "rigid_body_qs")
#: largest sub-step of :class:`LinearRigidBody` (classical Runge-Kutta), wing beats
_RK4_SUBSTEP_WB = 0.25


class LinearRigidBody:
    """The linear models' rigid body driven by aerodynamic forces that are functions of the
    state: only the aerodynamics are nonlinear.

    State (8 values) as the linear plants: (dv+, dp+, dr+, dgamma, du+, dw+, dq+, dtheta);
    dx/dt+ = (a_v + g+ dgamma, a_p, a_r, dp+, a_u - g+ dtheta, a_w, a_q, dq+), the
    accelerations a of :func:`dronefly.models.rigid_body.quasi_steady_rates` (the forces less
    those at hover, over m+ and through J+^-1). With a force model linear in the state this is
    exactly the linear models (a test checks it against their zero-order hold). Integrated by
    the classical Runge-Kutta method on sub-steps of at most 0.25 wing beat.

    Parameters
    ----------
    aerodynamics : QuasiSteadyModel
        Or any :class:`~dronefly.models.rigid_body.CycleAveragedForces`.
    lateral_params, longitudinal_params : the paper's by default (m+, g+ and the inertias)
    """

    def __init__(self, aerodynamics: Any, lateral_params: Any = None,
                 longitudinal_params: Any = None) -> None:
        lp = lateral_params or lateral_dynamics.default_parameters()
        np_ = longitudinal_params or longitudinal_dynamics.default_parameters()
        self.aerodynamics = aerodynamics
        self.g = lp.g_plus
        self._F0 = [float(v) for v in aerodynamics.state_function((0.0,) * 7)((0.0,) * 6)]
        self._inertia = (lp.m_plus, lp.Ix_plus, np_.Iy_plus, lp.Iz_plus, lp.Ixz_plus)

    def _derivative(self, acc: Callable[..., tuple], x: np.ndarray) -> np.ndarray:
        v, p, r, gamma, u, w, q, theta = x
        a_v, a_p, a_r, a_u, a_w, a_q = acc(u, v, w, p, q, r)
        return np.array([a_v + self.g * gamma, a_p, a_r, p, a_u - self.g * theta, a_w, a_q, q])

    def step(self, x: Sequence[float], c_lat: Sequence[float], c_lon: Sequence[float],
             h_wb: float) -> np.ndarray:
        """The state after ``h_wb`` wing beats with the controls held."""
        acc = quasi_steady_rates(self.aerodynamics.state_function((*c_lat, *c_lon)), self._F0,
                                 *self._inertia)
        n = max(1, math.ceil(h_wb / _RK4_SUBSTEP_WB - 1e-9))
        h = h_wb / n
        y = np.asarray(x, dtype=float)
        for _ in range(n):
            k1 = self._derivative(acc, y)
            k2 = self._derivative(acc, y + 0.5 * h * k1)
            k3 = self._derivative(acc, y + 0.5 * h * k2)
            k4 = self._derivative(acc, y + h * k3)
            y = y + (h / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
        return y


@dataclass(frozen=True)
class QuasiSteadyLoops:
    """What the quasi-steady halves need: the plants, their tangent, the gains.

    ``tangent``: lateral (A1, B1) and longitudinal (A, B) of the quasi-steady derivatives;
    ``Kl`` (3 x 4) and ``Kn`` (4 x 4): the gains (u = K x+) of the module's text;
    ``six_dof`` the 6-DOF plant and ``linear_body`` the linear rigid body, both with the
    quasi-steady forces; ``six_dof_tangent`` the 6-DOF plant with the linear aerodynamics of
    the quasi-steady derivatives.
    """

    model: QuasiSteadyModel
    tangent: tuple
    Kl: np.ndarray
    Kn: np.ndarray
    six_dof: Hover6DOF
    linear_body: LinearRigidBody
    six_dof_tangent: Hover6DOF


@lru_cache(maxsize=4)
def quasi_steady_loops(model: QuasiSteadyModel | None = None) -> QuasiSteadyLoops:
    """The quasi-steady plants, their tangent at hover and the gains (cached per model;
    default: ``QuasiSteadyModel()``, the 6-DOF FMU's ``aerodynamics = 2``)."""
    qs = model if model is not None else QuasiSteadyModel()
    d = derivatives(qs)
    values = {p: float(d[i][FORCES.index(F)])
              for p, F, i in (*LATERAL_PARAMETERS, *LONGITUDINAL_PARAMETERS)}
    (A1, B1), (A2, B2) = tangent = matrices_with_derivatives(values)
    Kl = np.zeros((3, 4))
    Kl[0] = closed_loop(values)["matched_gains"]
    Ap, Bp = longitudinal_dynamics.system_matrices(longitudinal_dynamics.default_parameters())
    targets = np.linalg.eigvals(Ap + np.outer(Bp[:, 2], LONGITUDINAL_GAINS_DESIGN_B))
    Kn = np.zeros((4, 4))
    Kn[2] = ackermann_gains(A2, B2[:, 2], targets)
    lp, np_ = lateral_dynamics.default_parameters(), longitudinal_dynamics.default_parameters()
    lpq, npq = derivative_parameters(values)
    return QuasiSteadyLoops(qs, tangent, Kl, Kn, Hover6DOF(lp, np_, aerodynamics=qs),
                            LinearRigidBody(qs, lp, np_), Hover6DOF(lpq, npq))


def _quasi_steady_errors(x0_lateral: Sequence[float], loops: QuasiSteadyLoops, plant: Any,
                         step_wb: float, stop_wb: float) -> np.ndarray:
    """Peak over the run of |x_nonlinear - x_linear| / bound per state (8 values), the
    nonlinear ``plant`` one of ``loops``' (a :class:`Hover6DOF`: the 13-value state, or the
    :class:`LinearRigidBody`: the 8 states of the linear plants)."""
    six_dof = isinstance(plant, Hover6DOF)
    (A1, B1), (A2, B2) = loops.tangent
    Kl, Kn = loops.Kl, loops.Kn
    P1, G1 = discretize_zoh(A1, B1, step_wb)
    P2, G2 = discretize_zoh(A2, B2, step_wb)
    F1, F2 = P1 + G1 @ Kl, P2 + G2 @ Kn
    lat, lon = np.array(x0_lateral, float), np.zeros(4)
    if six_dof:
        g0 = float(x0_lateral[3])
        x: Any = [0.0, lat[0], 0.0, lat[1], 0.0, lat[2], math.cos(g0 / 2), math.sin(g0 / 2),
                  0.0, 0.0, 0.0, 0.0, 0.0]
    else:
        x = np.concatenate([lat, lon])
    bounds = np.array(STATE_BOUNDS_SECT36 * 2)
    worst = np.zeros(8)
    n_steps = int(round(stop_wb / step_wb))
    for k in range(n_steps + 1):  # every communication point, the last one included
        if six_dof:
            theta = math.asin(max(-1.0, min(1.0, -2.0 * (x[7] * x[9] - x[6] * x[8]))))
            nl_lat = np.array([x[1], x[3], x[5], gamma_from_quaternion(x[6:10])])
            nl_lon = np.array([x[0], x[2], x[4], theta])
        else:
            nl_lat, nl_lon = x[:4], x[4:]
        worst = np.maximum(worst, np.abs(np.concatenate([nl_lat - lat, nl_lon - lon])) / bounds)
        if k < n_steps:
            x = plant.step(x, (Kl @ nl_lat).tolist(), (Kn @ nl_lon).tolist(), step_wb)
            lat, lon = F1 @ lat, F2 @ lon
    return worst


def half_errors(x0_lateral: Sequence[float], *, step_wb: float = 1.0, stop_wb: float = 100.0,
                model: QuasiSteadyModel | None = None) -> dict[str, np.ndarray]:
    """The linearisation error of each half (:data:`HALVES`) from one initial state.

    Parameters
    ----------
    x0_lateral : 4 floats
        Initial non-dimensional lateral state (dv+, dp+, dr+, dgamma); the longitudinal state
        starts at zero.
    step_wb, stop_wb : float
        Communication step and stop time, wing beats.
    model : QuasiSteadyModel, optional
        The wing model of the quasi-steady halves (default ``QuasiSteadyModel()``).

    Returns
    -------
    dict
        half -> ndarray of 8: lateral (dv, dp, dr, dgamma) then longitudinal (du, dw, dq,
        dtheta) peak errors, as fractions of the Sect. 3.6 bounds.
    """
    loops = quasi_steady_loops(model)
    return {"rigid_body": linearisation_error(x0_lateral, step_wb=step_wb, stop_wb=stop_wb),
            **{half: _quasi_steady_errors(x0_lateral, loops, plant, step_wb, stop_wb)
               for half, plant in (("aerodynamics", loops.linear_body), ("both", loops.six_dof),
                                   ("rigid_body_qs", loops.six_dof_tangent))}}


def halves_table(directions: Sequence[str], amplitudes: Sequence[float] = (1.0,), *,
                 step_wb: float = 1.0, stop_wb: float = 100.0,
                 model: QuasiSteadyModel | None = None) -> list[dict[str, Any]]:
    """Per direction (``+dv``, ``-mode1``, ...) and amplitude (box units): the largest
    lateral and longitudinal error of each half, ``{"direction", "amplitude",
    "<half>_lateral", "<half>_longitudinal", ...}`` (fractions of the bounds)."""
    rows = []
    for d in directions:
        for a in amplitudes:
            e = half_errors(float(a) * direction_vector(d) * np.array(STATE_BOUNDS_SECT36),
                            step_wb=step_wb, stop_wb=stop_wb, model=model)
            row: dict[str, Any] = {"direction": d, "amplitude": float(a)}
            for half in HALVES:
                row[f"{half}_lateral"] = float(e[half][:4].max())
                row[f"{half}_longitudinal"] = float(e[half][4:].max())
            rows.append(row)
    return rows


#: the halves' names in tables and terminal lines
HALF_LABELS: dict[str, str] = {
    "rigid_body": "rigid body (paper's plant)", "aerodynamics": "aerodynamics (QS plant)",
    "both": "both (QS plant)", "rigid_body_qs": "rigid body (QS plant)"}


def _pct(x: float) -> str:
    return f"{100 * x:.1f} %" if x >= 0.005 else f"{100 * x:.2f} %"


def format_halves_table(rows: Sequence[dict[str, Any]]) -> str:
    """The Markdown table of :func:`halves_table` rows (docs/validity.md): per direction the
    largest lateral / longitudinal error of each half, in per cent of the bounds."""
    head = "| direction | " + " | ".join(HALF_LABELS[h] for h in HALVES) + " |"
    lines = [head, "|---|" + "---|" * len(HALVES)]
    for r in rows:
        name = r["direction"].lstrip("+")
        amp = "" if r["amplitude"] == 1.0 else f" x {r['amplitude']:g}"
        cells = [f"{_pct(r[f'{h}_lateral'])} / {_pct(r[f'{h}_longitudinal'])}" for h in HALVES]
        lines.append(f"| {name}{amp} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def halves_summary(rows: Sequence[dict[str, str]],
                   model: QuasiSteadyModel | None = None) -> list[dict[str, Any]]:
    """The halves over the direction cases of a comparison sweep (``sweep.csv`` rows): per
    direction, for each half, the lateral and longitudinal errors at the box edge (amplitude
    1, if swept) and the largest amplitude up to which the lateral error stays within 10 %,
    each case from its own initial state, step and stop."""
    dirs: dict[str, list[dict[str, str]]] = {}
    for r in rows:
        if r.get("family") == "direction" and not r.get("error"):
            dirs.setdefault(r["label"], []).append(r)
    out = []
    for label, rs in dirs.items():
        rs = sorted(rs, key=lambda r: float(r["amplitude"]))
        errs = [half_errors([float(r[f"x0_{a}"]) for a in ("dv", "dp", "dr", "dgamma")],
                            step_wb=float(r["step_wb"]), stop_wb=float(r["stop_wb"]),
                            model=model) for r in rs]
        entry: dict[str, Any] = {"direction": label}
        for half in HALVES:
            best = None
            for r, e in zip(rs, errs):
                if e[half][:4].max() > 0.10:
                    break
                best = float(r["amplitude"])
            entry[f"{half}_largest_amplitude_within_10pct"] = best
            for r, e in zip(rs, errs):
                if math.isclose(float(r["amplitude"]), 1.0):
                    entry[f"{half}_err_lateral_at_box_edge"] = float(e[half][:4].max())
                    entry[f"{half}_err_longitudinal_at_box_edge"] = float(e[half][4:].max())
        out.append(entry)
    return out


def format_halves(entries: Sequence[dict[str, Any]]) -> list[str]:
    """Terminal lines of :func:`halves_summary`."""
    lines = ["halves of Sect. 3.6 (lateral / longitudinal error at the box edge; lateral within "
             "10 % up to, box units):"] if entries else []
    for d in entries:
        parts = []
        for half in HALVES:
            w = d[f"{half}_largest_amplitude_within_10pct"]
            edge = (f"{_pct(d[f'{half}_err_lateral_at_box_edge'])} / "
                    f"{_pct(d[f'{half}_err_longitudinal_at_box_edge'])}, "
                    if f"{half}_err_lateral_at_box_edge" in d else "")
            parts.append(f"{half} {edge}{'-' if w is None else format(w, 'g')}")
        lines.append(f"  {d['direction']:<8} " + "; ".join(parts))
    return lines
