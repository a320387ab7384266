"""The quasi-steady model beside the paper: derivatives, eigenvalues, controller, linearity.

Derivatives are central differences of the cycle-averaged forces about the trimmed hover
(:meth:`QuasiSteadyModel.trim`), named as the plant FMUs name them (``Yv_plus``,
``L_Phi_a_plus``, ``Mq_plus``, ...), each beside the value the project recovers from the
paper (Eq. 12 and Table 1 through :mod:`dronefly.models.lateral_dynamics`, Sect. 3.5's A and B through
:mod:`dronefly.models.longitudinal_dynamics`). Eigenvalues are per wing beat, with the paper's
inertias (Sect. 2.1 and ``IY_PLUS``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Sequence

import numpy as np
from numpy.typing import NDArray

from ...core.text import complex_text
from ...models import (lateral_dynamics,
                       longitudinal_dynamics)
from ...models.feedback import PAPER_GAINS_EQ27
from ...models.lateral_interface import STATE_BOUNDS_SECT36, sort_eigenvalues
from ..paper.analysis import ackermann_gains
from ...models.quasisteady import (COEFFICIENT_SETS, CONTROLS, FORCES, STATES, QuasiSteadyModel,
                                   Terms, Trim)

__all__ = [
    "CONTROL_BOX_RAD",
    "DerivativeRow",
    "LATERAL_PAIRS",
    "LATERAL_PARAMETERS",
    "LINEARITY_BLOCKS",
    "LONGITUDINAL_PARAMETERS",
    "ParityReport",
    "STATE_BOX",
    "TRIM_VARIANTS",
    "readme_paragraph",
    "closed_loop",
    "derivative_table",
    "derivative_parameters",
    "derivatives",
    "eigenvalues",
    "linearity_scan",
    "linearity_summary",
    "matrices_with_derivatives",
    "pair_scan",
    "parity_report",
    "term_contributions",
    "trim_table",
]

Array = NDArray[np.float64]

#: Sect. 3.6: the controls stay within +/-0.4 rad; the states within STATE_BOUNDS_SECT36.
CONTROL_BOX_RAD: float = 0.4
#: Sect. 3.6: |dv+|, |dp+|, |dr+| <= 0.15 (and the same box for du+, dw+, dq+ here).
STATE_BOX: float = STATE_BOUNDS_SECT36[0]

#: (parameter, force, input) of the lateral derivatives, Eq. (9)'s names.
LATERAL_PARAMETERS: tuple[tuple[str, str, str], ...] = (
    *((f"{F}{s}_plus", F, f"delta_{s}") for s in "vpr" for F in "YLN"),
    *((f"{F}_{c}_plus", F, f"delta_{c}") for c in ("Phi_a", "alpha_1a", "alpha_2a") for F in "YLN"),
)
#: (parameter, force, input) of the longitudinal derivatives, Sect. 3.5's names.
LONGITUDINAL_PARAMETERS: tuple[tuple[str, str, str], ...] = (
    *((f"{F}{s}_plus", F, f"delta_{s}") for s in "uwq" for F in "XZM"),
    *((f"{F}_{c}_plus", F, f"delta_{c}") for c in ("Phi", "alpha_1", "phibar", "alpha_2")
      for F in "XZM"),
)


def _paper_values() -> dict[str, float]:
    out = dict(lateral_dynamics.default_parameters().__dict__)
    out.update(longitudinal_dynamics.default_parameters().__dict__)
    return out


def _perturbed(model: QuasiSteadyModel, name: str, value: float,
               trim: Trim | None = None) -> Array:
    if name in STATES:
        x = np.zeros(6)
        x[STATES.index(name)] = value
        return model.forces_vector(x, trim=trim)
    return model.forces_vector(np.zeros(6), {name: value}, trim=trim)


def derivatives(model: QuasiSteadyModel, step: float = 1e-3,
                inputs: Sequence[str] = STATES + CONTROLS,
                trim: Trim | None = None) -> dict[str, Array]:
    """Central differences d(X, Y, Z, L, M, N)/d(input) at the trimmed hover.

    Parameters
    ----------
    model : QuasiSteadyModel
    step : float
        The step, in the input's unit (x+ for states, rad for controls).
    inputs : sequence of str
        Names from :data:`STATES` and :data:`CONTROLS`.
    trim : Trim, optional
        The reference (default: the model's own trimmed hover).

    Returns
    -------
    dict
        input name -> array of the six derivatives (order :data:`FORCES`).
    """
    return {name: (_perturbed(model, name, step, trim) - _perturbed(model, name, -step, trim))
            / (2 * step) for name in inputs}


#: The model's terms one at a time, for :func:`term_contributions`.
_SINGLE_TERMS = {"translational": dict(rotational=False, added_mass=False),
                 "rotational": dict(translational=False, added_mass=False),
                 "added_mass": dict(translational=False, rotational=False)}


def term_contributions(model: QuasiSteadyModel, step: float = 1e-3) -> dict[str, dict[str, float]]:
    """Each derivative split into the parts of the translational, rotational and added-mass
    terms, at the model's trimmed hover (the forces are sums of the terms, so the parts add
    up to the derivative exactly, up to round-off).

    Returns
    -------
    dict
        parameter name (``Lp_plus``, ...) -> {term: part}; a switched-off term gives 0.
    """
    trim = model.trim()
    out: dict[str, dict[str, float]] = {p: {} for p, _, _ in (*LATERAL_PARAMETERS,
                                                               *LONGITUDINAL_PARAMETERS)}
    for term, off in _SINGLE_TERMS.items():
        on = getattr(model.terms, term)
        single = model.with_options(terms=replace(model.terms, **off))
        d = derivatives(single, step, trim=trim) if on else None
        for p, F, inp in (*LATERAL_PARAMETERS, *LONGITUDINAL_PARAMETERS):
            out[p][term] = float(d[inp][FORCES.index(F)]) if d is not None else 0.0
    return out


@dataclass(frozen=True)
class DerivativeRow:
    """One derivative: quasi-steady, paper, their ratio and whether the signs agree."""

    parameter: str
    quasi_steady: float
    paper: float

    @property
    def ratio(self) -> float:
        return self.quasi_steady / self.paper if self.paper != 0.0 else math.nan

    @property
    def same_sign(self) -> bool:
        return (self.quasi_steady > 0) == (self.paper > 0)

    @property
    def sign(self) -> str:
        """``"same"``, ``"opposite"``, ``"zero"`` (the model's value rounds to 0 at four
        decimals: its sign is round-off) or ``"-"`` (the paper's value is 0)."""
        if self.paper == 0.0:
            return "-"
        if _f4(self.quasi_steady) == "0.0000":
            return "zero"
        return "same" if self.same_sign else "opposite"


def derivative_table(model: QuasiSteadyModel, step: float = 1e-3) -> list[DerivativeRow]:
    """Every lateral and longitudinal derivative of the paper, quasi-steady beside paper."""
    d = derivatives(model, step)
    paper = _paper_values()
    return [DerivativeRow(p, float(d[inp][FORCES.index(F)]), float(paper[p]))
            for p, F, inp in (*LATERAL_PARAMETERS, *LONGITUDINAL_PARAMETERS)]


def derivative_parameters(values: dict[str, float]) -> tuple[lateral_dynamics.LateralParameters,
                                                          longitudinal_dynamics.LongitudinalParameters]:
    """The paper's lateral and longitudinal parameters with the derivatives of ``values``
    in place of the paper's (mass, inertias and gravity stay the paper's)."""
    lat = dict(lateral_dynamics.default_parameters().__dict__)
    lat.update({p: values[p] for p, _, _ in LATERAL_PARAMETERS if p in values})
    lon = dict(longitudinal_dynamics.default_parameters().__dict__)
    lon.update({p: values[p] for p, _, _ in LONGITUDINAL_PARAMETERS if p in values})
    return (lateral_dynamics.LateralParameters(**lat),
            longitudinal_dynamics.LongitudinalParameters(**lon))


def matrices_with_derivatives(values: dict[str, float]) -> tuple[tuple[Array, Array],
                                                                  tuple[Array, Array]]:
    """Lateral (A1, B1) and longitudinal (A, B) of :func:`derivative_parameters`, by the one
    home of the equations, ``system_matrices`` of :mod:`dronefly.models.lateral_dynamics` and
    :mod:`dronefly.models.longitudinal_dynamics`."""
    lat, lon = derivative_parameters(values)
    return lateral_dynamics.system_matrices(lat), longitudinal_dynamics.system_matrices(lon)


def eigenvalues(values: dict[str, float]) -> dict[str, list[complex]]:
    """Lateral and longitudinal eigenvalues per wing beat of the derivatives ``values``
    (with the paper's m+, g+, Ix+, Iz+, Ixz+, Iy+), in the project's order."""
    (A1, _), (A, _) = matrices_with_derivatives(values)
    return {"lateral": sort_eigenvalues(np.linalg.eigvals(A1)),
            "longitudinal": sort_eigenvalues(np.linalg.eigvals(A))}


def closed_loop(values: dict[str, float]) -> dict[str, object]:
    """Eq. (27) on the quasi-steady plant, and the paper's method re-applied to it.

    Returns
    -------
    dict
        ``qs_A_qs_B`` and ``paper_A_qs_B``: closed-loop eigenvalues with the Eq. (27) gains on
        dPhi_a; ``matched_gains``: coefficient matching (Ackermann, as Eqs. 25-26) moving every
        quasi-steady eigenvalue with a positive real part onto the imaginary axis and keeping
        the others; ``matched_eigenvalues`` its closed loop.
    """
    (A1q, B1q), _ = matrices_with_derivatives(values)
    A1p, _ = lateral_dynamics.system_matrices(lateral_dynamics.default_parameters())
    k = np.asarray(PAPER_GAINS_EQ27)
    b = B1q[:, 0]
    open_q = sort_eigenvalues(np.linalg.eigvals(A1q))
    targets = [complex(0.0, z.imag) if z.real > 0 else z for z in open_q]
    gains = ackermann_gains(A1q, b, targets)
    return {
        "qs_A_qs_B": sort_eigenvalues(np.linalg.eigvals(A1q + np.outer(b, k))),
        "paper_A_qs_B": sort_eigenvalues(np.linalg.eigvals(A1p + np.outer(b, k))),
        "targets": targets,
        "matched_gains": [float(g) for g in gains],
        "matched_eigenvalues": sort_eigenvalues(np.linalg.eigvals(A1q + np.outer(b, gains))),
    }


@dataclass(frozen=True)
class ParityReport:
    """Everything ``dronefly aero`` prints: trim, derivative rows, eigenvalues, controller."""

    coefficients: str
    terms: dict[str, object]
    trim: dict[str, float]
    rows: list[DerivativeRow]
    eigenvalues: dict[str, dict[str, list[complex]]]
    controller: dict[str, object]
    split: dict[str, dict[str, float]]

    def to_json(self) -> dict[str, object]:
        def cx(values: Sequence[complex]) -> list[list[float]]:
            return [[float(complex(z).real), float(complex(z).imag)] for z in values]

        ctrl = {k: (cx(v) if k != "matched_gains" else v) for k, v in self.controller.items()}
        return {
            "coefficients": self.coefficients,
            "coefficient_source": COEFFICIENT_SETS[self.coefficients].source
            if self.coefficients in COEFFICIENT_SETS else None,
            "terms": self.terms,
            "trim": self.trim,
            "derivatives": {r.parameter: {"quasi_steady": r.quasi_steady, "paper": r.paper,
                                          "terms": self.split[r.parameter]}
                            for r in self.rows},
            "eigenvalues": {axis: {k: cx(v) for k, v in d.items()}
                            for axis, d in self.eigenvalues.items()},
            "controller": ctrl,
        }

    def table(self) -> str:
        lines = [f"quasi-steady model ({self.coefficients}; terms: "
                 + ", ".join(k for k, v in self.terms.items() if v is True) + ")",
                 f"trim: alpha_d {self.trim['alpha_d_deg']:.3f} deg, alpha_u "
                 f"{self.trim['alpha_u_deg']:.3f} deg, phibar {self.trim['phibar_deg']:.3f} deg, "
                 f"residual {_residual(self.trim['residual_over_weight'])} of the weight", "",
                 f"{'parameter':<16} {'quasi-steady':>12} {'paper':>8} {'ratio':>6} "
                 f"{'sign':<8} {'transl.':>8} {'rotat.':>8} {'added m.':>8}"]
        for r in self.rows:
            ratio = "-" if math.isnan(r.ratio) else f"{r.ratio:.2f}"
            sign = r.sign
            if sign == "zero":
                ratio = "0"
            part = self.split[r.parameter]
            lines.append(f"{r.parameter:<16} {_f4(r.quasi_steady):>12} {_f4(r.paper):>8} "
                         f"{ratio:>6} {sign:<8} {_f4(part['translational']):>8} "
                         f"{_f4(part['rotational']):>8} {_f4(part['added_mass']):>8}")
        lines.append("")
        for axis, d in self.eigenvalues.items():
            for who, values in d.items():
                lines.append(f"{axis} eigenvalues per wing beat, {who}: "
                             + ", ".join(complex_text(z) for z in values))
        c = self.controller
        lines.append("Eq. (27) on the quasi-steady A and B: " + ", ".join(complex_text(z) for z in c["qs_A_qs_B"]))
        lines.append("Eq. (27) on the paper's A, quasi-steady B: "
                     + ", ".join(complex_text(z) for z in c["paper_A_qs_B"]))
        lines.append("coefficient matching on the quasi-steady model: k = "
                     + ", ".join(f"{g:.4f}" for g in c["matched_gains"]))
        return "\n".join(lines)


def _residual(value: float) -> str:
    """The trim residual over the weight: below the trim's tolerance 1e-12 it is round-off,
    printed as the bound (its digits differ between machines)."""
    return "< 1e-12" if value < 1e-12 else f"{value:.1e}"


def _f4(value: float) -> str:
    """Four decimals; a value that rounds to zero prints 0.0000 whatever its sign (round-off)."""
    return f"{value:.4f}" if abs(value) >= 5e-5 else "0.0000"


def parity_report(model: QuasiSteadyModel, step: float = 1e-3) -> ParityReport:
    """Trim, derivative table, eigenvalues and the paper's controller on ``model``."""
    trim = model.trim()
    rows = derivative_table(model, step)
    qs = {r.parameter: r.quasi_steady for r in rows}
    paper = _paper_values()
    t = model.terms
    return ParityReport(
        coefficients=model.coefficients.name,
        terms={"translational": t.translational, "rotational": t.rotational,
               "added_mass": t.added_mass, "added_mass_form": t.added_mass_form},
        trim=trim.to_json(), rows=rows,
        eigenvalues={axis: {"quasi_steady": eigenvalues(qs)[axis],
                            "paper": eigenvalues(paper)[axis]}
                     for axis in ("lateral", "longitudinal")},
        controller=closed_loop(qs), split=term_contributions(model, step))


def linearity_scan(model: QuasiSteadyModel, inputs: Sequence[str], outputs: Sequence[str],
                   extent: float = 2.0, points: int = 13) -> dict[str, object]:
    """The error of the tangent at hover, per input, out to ``extent`` times the box.

    Each input (a state, box +/-0.15; a control, box +/-0.4 rad) is swept alone over
    ``points`` values in +/- extent * box; the error of the linear model F0 + D s is given in
    per cent of the output's scale, the largest range that any of ``inputs`` gives it inside
    the box. The 10 % extent is where the error first reaches 10 %, linearly interpolated on
    the samples (None if not within the sweep).

    Returns
    -------
    dict
        ``scale`` (output -> range in the box), ``inputs`` (input -> ``values`` and, per
        output, ``forces``, ``error_pct``, ``max_error_box_pct``, ``max_error_pct`` and
        ``ten_pct_extent`` [input's unit, the smaller of the two sides]).
    """
    f0 = model.forces_vector()
    d = derivatives(model, 1e-3, inputs)
    sweeps: dict[str, dict[str, object]] = {}
    box_ranges: dict[str, dict[str, float]] = {}
    for name in inputs:
        box = STATE_BOX if name in STATES else CONTROL_BOX_RAD
        s = np.linspace(-extent * box, extent * box, points)
        F = np.array([_perturbed(model, name, v) for v in s])
        lin = f0 + np.outer(s, d[name])
        inside = np.abs(s) <= box + 1e-12
        sweeps[name] = {"values": s, "F": F, "err": np.abs(F - lin), "inside": inside}
        box_ranges[name] = {o: float(np.ptp(F[inside, FORCES.index(o)])) for o in outputs}
    scale = {o: max(box_ranges[n][o] for n in inputs) for o in outputs}
    out: dict[str, object] = {"scale": scale, "inputs": {}}
    for name, sw in sweeps.items():
        s, err, inside = sw["values"], sw["err"], sw["inside"]
        per: dict[str, object] = {"values": [float(v) for v in s]}
        for o in outputs:
            i = FORCES.index(o)
            pct = 100.0 * err[:, i] / scale[o] if scale[o] > 0 else np.zeros(len(s))
            per[o] = {"forces": [float(v) for v in sw["F"][:, i]],
                      "error_pct": [float(v) for v in pct],
                      "max_error_box_pct": float(pct[inside].max()),
                      "max_error_pct": float(pct.max()),
                      "ten_pct_extent": _first_crossing(s, pct, 10.0)}
        out["inputs"][name] = per  # type: ignore[index]
    return out


def _first_crossing(s: Array, pct: Array, level: float) -> float | None:
    """The smallest |s| at which ``pct`` reaches ``level``, interpolated (None if never)."""
    mid = len(s) // 2
    best: float | None = None
    for direction in (1, -1):
        idx = range(mid, len(s)) if direction == 1 else range(mid, -1, -1)
        prev = None
        for i in idx:
            if pct[i] >= level:
                if prev is None:
                    x = abs(float(s[i]))
                else:
                    a, b = pct[prev], pct[i]
                    x = abs(float(s[prev] + (s[i] - s[prev]) * (level - a) / (b - a)))
                best = x if best is None else min(best, x)
                break
            prev = i
    return best


#: The sweeps of :func:`linearity_summary`: (inputs, outputs) per block.
LINEARITY_BLOCKS: tuple[tuple[tuple[str, ...], str], ...] = (
    (("delta_v", "delta_p", "delta_r"), "YLN"),
    (("delta_Phi_a", "delta_alpha_1a", "delta_alpha_2a"), "YLN"),
    (("delta_u", "delta_w", "delta_q"), "XZM"),
    (("delta_Phi", "delta_alpha_1", "delta_phibar", "delta_alpha_2"), "XZM"),
)


def linearity_summary(model: QuasiSteadyModel) -> str:
    """The largest error of the tangent at hover, in per cent of each output's scale, inside
    the box and out to twice it, and where it reaches 10 % (:func:`linearity_scan`)."""
    lines = [f"{'input':<15} {'output':<6} {'in box %':>9} {'at 2x %':>8} {'10 % at':>8}"]
    for inputs, outputs in LINEARITY_BLOCKS:
        r = linearity_scan(model, inputs, tuple(outputs))
        for name in inputs:
            for o in outputs:
                e = r["inputs"][name][o]  # type: ignore[index]
                at = "-" if e["ten_pct_extent"] is None else f"{e['ten_pct_extent']:.2f}"
                lines.append(f"{name:<15} {o:<6} {e['max_error_box_pct']:>9.2f} "
                             f"{e['max_error_pct']:>8.2f} {at:>8}")
    return "\n".join(lines)


#: The pairs of the lateral box swept by :func:`pair_scan`.
LATERAL_PAIRS: tuple[tuple[str, str], ...] = (("delta_v", "delta_p"), ("delta_v", "delta_r"),
                                               ("delta_p", "delta_r"))


def pair_scan(model: QuasiSteadyModel, pair: tuple[str, str], outputs: str = "YLN",
              extent: float = 2.0, points: int = 13) -> dict[str, object]:
    """The error of the tangent at hover over a pair of states, out to ``extent`` times the
    box, in per cent of each output's scale (as :func:`linearity_scan`, over the three lateral
    states).

    Returns
    -------
    dict
        ``values`` (the grid of each axis), per output ``error_pct`` (points x points, first
        index the first state), ``max_error_box_pct``, ``max_error_pct`` and
        ``ten_pct_radius``: the smallest max-norm radius, in units of the box (0.15), of a
        grid point whose error reaches 10 % (None if none does).
    """
    a, b = pair
    states = ("delta_v", "delta_p", "delta_r")
    scale = linearity_scan(model, states, tuple(outputs), extent=1.0, points=7)["scale"]
    f0 = model.forces_vector()
    d = derivatives(model, 1e-3, pair)
    s = np.linspace(-extent * STATE_BOX, extent * STATE_BOX, points)
    err = np.zeros((points, points, 6))
    for i, va in enumerate(s):
        for j, vb in enumerate(s):
            x = np.zeros(6)
            x[STATES.index(a)], x[STATES.index(b)] = va, vb
            err[i, j] = np.abs(model.forces_vector(x) - f0 - va * d[a] - vb * d[b])
    radius = np.maximum(np.abs(s)[:, None], np.abs(s)[None, :]) / STATE_BOX
    out: dict[str, object] = {"values": [float(v) for v in s]}
    for o in outputs:
        k = FORCES.index(o)
        pct = 100.0 * err[:, :, k] / scale[o]  # type: ignore[index]
        hit = radius[pct >= 10.0]
        out[o] = {"error_pct": pct.tolist(),
                  "max_error_box_pct": float(pct[radius <= 1.0 + 1e-12].max()),
                  "max_error_pct": float(pct.max()),
                  "ten_pct_radius": float(hit.min()) if hit.size else None}
    return out


#: The model variants of :func:`trim_table`: (coefficients, terms label, Terms keywords).
TRIM_VARIANTS: tuple[tuple[str, str, dict[str, object]], ...] = (
    ("dickinson1999", "all, added mass impulse", {"added_mass_form": "impulse"}),
    ("dickinson1999", "all, added mass sane2001", {"added_mass_form": "sane2001"}),
    ("dickinson1999", "translational only", {"rotational": False, "added_mass": False}),
    ("wang2004", "all, added mass impulse", {"added_mass_form": "impulse"}),
    ("wang2004", "all, added mass sane2001", {"added_mass_form": "sane2001"}),
    ("wang2004", "translational only", {"rotational": False, "added_mass": False}),
)


def trim_table() -> str:
    """The trimmed angles of every variant of :data:`TRIM_VARIANTS` [deg], and the share of
    the weight that each term carries at that trim [%]."""

    lines = [f"{'coefficients':<14} {'terms':<26} {'alpha_d':>8} {'alpha_u':>8} {'phibar':>7} "
             f"{'transl. %':>9} {'rotat. %':>8} {'added m. %':>10}"]
    for name, label, kw in TRIM_VARIANTS:
        m = QuasiSteadyModel(name, Terms(**kw))  # type: ignore[arg-type]
        tr = m.trim()
        W = m.geometry.weight
        share = []
        for term, off in _SINGLE_TERMS.items():
            if not getattr(m.terms, term):
                share.append(0.0)
                continue
            single = m.with_options(terms=replace(m.terms, **off))
            share.append(-100.0 * single.forces_vector(trim=tr)[2] / W)
        lines.append(f"{name:<14} {label:<26} {math.degrees(tr.alpha_d):>8.2f} "
                     f"{math.degrees(tr.alpha_u):>8.2f} {math.degrees(tr.phibar):>7.2f} "
                     f"{share[0]:>9.1f} {share[1]:>8.1f} {share[2]:>10.1f}")
    return "\n".join(lines)


def readme_paragraph(report: ParityReport, model: QuasiSteadyModel) -> str:
    """The answer to Sect. 3.6's aerodynamic half in three lines (README, docs)."""
    lat = {r.parameter: r for r in report.rows[:18]}
    stab = [lat[p] for p, _, _ in LATERAL_PARAMETERS[:9] if lat[p].paper != 0.0]
    ctrl = [lat[p] for p, _, _ in LATERAL_PARAMETERS[9:]]
    main = [lat[p] for p in ("L_Phi_a_plus", "L_alpha_1a_plus", "N_alpha_2a_plus")]
    ev_q = report.eigenvalues["lateral"]["quasi_steady"][0].real
    ev_p = report.eigenvalues["lateral"]["paper"][0].real
    worst_state = _worst(model, ("delta_v", "delta_p", "delta_r"), 6.0, 49)
    worst_ctrl = _worst(model, ("delta_Phi_a", "delta_alpha_1a", "delta_alpha_2a"), 3.0, 37)
    box = linearity_scan(model, ("delta_v", "delta_p", "delta_r", ), tuple("YLN"), 1.0, 7)
    box_c = linearity_scan(model, ("delta_Phi_a", "delta_alpha_1a", "delta_alpha_2a"),
                           tuple("YLN"), 1.0, 7)
    in_box = max(e[o]["max_error_box_pct"] for r in (box, box_c)  # type: ignore[index]
                 for e in r["inputs"].values() for o in "YLN")  # type: ignore[union-attr]
    closed = report.controller["qs_A_qs_B"][0].real  # type: ignore[index]
    return "\n".join([
        f"A quasi-steady blade-element model ({report.coefficients}) trims at alpha_d = "
        f"{report.trim['alpha_d_deg']:.1f} deg, alpha_u = {report.trim['alpha_u_deg']:.1f} deg and "
        f"gets the sign of {sum(r.sign == 'same' for r in stab)} of the {len(stab)} nonzero "
        f"lateral stability derivatives and {sum(r.sign == 'same' for r in ctrl)} of the 9 "
        f"control derivatives of the paper's CFD ({sum(r.sign == 'zero' for r in ctrl)} are zero "
        f"in the model), the three main control derivatives at "
        f"{min(r.ratio for r in main):.2f}-{max(r.ratio for r in main):.2f} times the CFD values; "
        f"the lateral instability is {ev_q:.4f} per wing beat against {ev_p:.4f}.",
        f"Within the Sect. 3.6 box the cycle-averaged Y, L, N are linear to {in_box:.1f} % of "
        f"their range; the first to leave 10 % are {worst_ctrl[0]} (at {worst_ctrl[1]:.2f} rad, "
        f"{worst_ctrl[1] / CONTROL_BOX_RAD:.1f} times the box) and {worst_state[0]} (at "
        f"{worst_state[1]:.2f}, {worst_state[1] / STATE_BOX:.1f} times the box): the box holds "
        f"for the aerodynamics.",
        f"The Eq. (27) gains leave the quasi-steady loop unstable ({closed:+.4f} per wing beat): "
        f"its neutrality rests on the CFD derivatives; coefficient matching on the quasi-steady "
        f"A and B gives k = " + ", ".join(f"{g:.3f}" for g in report.controller["matched_gains"])
        + ".",  # type: ignore[union-attr]
    ])


def _worst(model: QuasiSteadyModel, inputs: tuple[str, ...], extent: float,
           points: int) -> tuple[str, float]:
    """The input whose error first reaches 10 % for any of Y, L, N, and where."""
    r = linearity_scan(model, inputs, tuple("YLN"), extent, points)
    best = ("none", math.inf)
    for name, per in r["inputs"].items():  # type: ignore[union-attr]
        for o in "YLN":
            at = per[o]["ten_pct_extent"]
            if at is not None and at < best[1]:
                best = (name, at)
    return best
