"""The reproduction table: every printed number of Tables 2-3, Eqs. (12)-(32) and Sect. 3.5.

Each row compares a printed value with the value computed from the plants' model modules:
the lateral one, and the longitudinal one, which recovers its derivatives from the printed
A, B of Sect. 3.5 (with m+ and Iy+) and rebuilds them. ``match`` means
|computed - printed| <= half a unit in the last printed digit. A mismatch gets a
reason ("convention", "rounding", "error in print") and a note. "Rounding" is
decided, never assumed: every printed input (Eq. 12 and Sect. 3.5 to 4 decimals,
m+, Ix+, Iz+, Ixz+ and Table 1 to their printed digits, the Table 2 targets) is
moved by +/- half a unit of its last digit and the effect is summed to first order
(worst case); the reason is "rounding" only if the printed value lies inside.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import Callable

import numpy as np

from ...models import lateral_dynamics, longitudinal_dynamics
from ...models import lateral_interface
from . import printed as pv
from .analysis import (LONGITUDINAL_CONVENTION, ModalConvention, characteristic_affine,
                       coefficient_matching_gains, eigenvector_table, longitudinal_system,
                       modal_decomposition, ordered_eigen)
from .design import analysis_report
from .notes import Notes
from .rows import Row, rounds_to, summary

__all__ = ["Analysis", "Row", "analyze", "lateral_inputs", "longitudinal_inputs",
           "reproduction_table"]

Ctx = dict[str, np.ndarray]
STATES = ("dv+", "dp+", "dr+", "dgamma")


# --- inputs and their rounding -------------------------------------------------------------
def lateral_inputs() -> list[tuple[str, float, float]]:
    """(name, printed value, half unit) of every rounded input of the lateral analysis."""
    out = [(f"A1({i + 1},{j + 1})", pv.EQ12_A1[i][j], 0.5 * 10.0 ** -pv.EQ12_DECIMALS)
           for i in range(4) for j in range(4) if (i, j) not in pv.EQ12_STRUCTURAL]
    out += [(k, lateral_interface.INERTIAS_SECT21[k], 0.5 * 10.0 ** -d) for k, d in pv.SECT21_DECIMALS.items()]
    out += [(k, v, 0.5 * 10.0 ** -pv.TABLE1_DECIMALS) for k, v in lateral_dynamics.CONTROL_DERIVATIVES_TABLE1.items()]
    out += [(f"Table 2 {k}", float(t), pv.half_unit(t)) for k, t in pv.TABLE2.items() if k != "lambda1"]
    return out


def longitudinal_inputs() -> list[tuple[str, float, float]]:
    """(name, printed value, half unit) of every rounded entry of the Sect. 3.5 A and B."""
    return [(f"{m}({i + 1},{j + 1})", float(tab[i][j]), pv.half_unit(tab[i][j], 4))
            for m, tab in (("A", pv.SECT35_A), ("B", pv.SECT35_B)) for i in range(4) for j in range(4)
            if (i, j) not in pv.LONGITUDINAL_STRUCTURAL[m]]


def _lateral_ctx(x: np.ndarray) -> Ctx:
    names = [n for n, _, _ in lateral_inputs()]
    val = dict(zip(names, x))
    A = np.array(pv.EQ12_A1, dtype=float)
    for i in range(4):
        for j in range(4):
            A[i, j] = val.get(f"A1({i + 1},{j + 1})", A[i, j])
    inertias = {k: val[k] for k in pv.SECT21_DECIMALS} | {"g_plus": A[0, 3]}
    params = lateral_dynamics.LateralParameters(**inertias, **lateral_dynamics.derive_stability_derivatives(A, inertias),
                                     **{k: val[k] for k in lateral_dynamics.CONTROL_DERIVATIVES_TABLE1})
    A, B = lateral_dynamics.system_matrices(params)
    re, im, l4 = (val[f"Table 2 {k}"] for k in ("lambda23_re", "lambda23_im", "lambda4"))
    return _ctx(A, B, [0.0, complex(re, im), complex(re, -im), l4])


def _ctx(A: np.ndarray, B: np.ndarray, targets: list[complex] | None,
         conv: ModalConvention | None = None) -> Ctx:
    mf = modal_decomposition(A, B) if conv is None else modal_decomposition(A, B, conv)
    c: Ctx = {"A": A, "B": B, "w": ordered_eigen(A)[0], "Ann": mf.A_nn, "Bn": mf.B_n}
    if targets is not None:
        _, c["mag"], c["ph"] = eigenvector_table(A)
        c["c0"], c["G"] = characteristic_affine(A, B[:, 0])
        c["k"] = coefficient_matching_gains(A, B, targets)
    return c


def _longitudinal_ctx(x: np.ndarray) -> Ctx:
    A, B = longitudinal_system()
    for (name, _, _), v in zip(longitudinal_inputs(), x):
        i, j = int(name[2]) - 1, int(name[4]) - 1
        (A if name[0] == "A" else B)[i, j] = v
    # the longitudinal plant's A and B: derivatives recovered from the printed A, B, g+ = -A(1,4)
    params = longitudinal_dynamics.default_parameters().with_values(g_plus=-A[0, 3],
                                                        **longitudinal_dynamics.derive_derivatives(A, B))
    return _ctx(*longitudinal_dynamics.system_matrices(params), None, LONGITUDINAL_CONVENTION)


def _intervals(ctx_of: Callable[[np.ndarray], Ctx], inputs: list[tuple[str, float, float]],
               getters: list[Callable[[Ctx], float]]) -> list[tuple[float, float]]:
    x0 = np.array([v for _, v, _ in inputs])
    f0 = np.array([g(ctx_of(x0)) for g in getters])
    spread = np.zeros_like(f0)
    for i, (_, _, h) in enumerate(inputs):
        up, dn = ctx_of(x0 + h * np.eye(len(x0))[i]), ctx_of(x0 - h * np.eye(len(x0))[i])
        spread += np.abs([g(up) - g(dn) for g in getters]) / 2.0
    return [(float(a - s), float(a + s)) for a, s in zip(f0, spread)]


# --- the rows -------------------------------------------------------------------------------
def _fmt(v: float, structural: bool) -> str:
    return f"{v:g}" if structural or v == 0.0 else f"{v:.4f}"


def _lateral_specs() -> list[tuple[str, str, str, int | None, Callable[[Ctx], float]]]:
    S: list = []
    for src in ("Eq. (12)", "Eq. (24)"):
        for i in range(4):
            for j in range(4):
                S.append((src, f"A1({i + 1},{j + 1})", _fmt(pv.EQ12_A1[i][j], (i, j) in pv.EQ12_STRUCTURAL),
                          4, lambda c, i=i, j=j: c["A"][i, j]))
    t2 = pv.TABLE2
    S += [("Table 2", "lambda1", t2["lambda1"], None, lambda c: c["w"][0].real),
          ("Table 2", "Re lambda2,3", t2["lambda23_re"], None, lambda c: c["w"][1].real),
          ("Table 2", "Im lambda2,3 (+/-)", t2["lambda23_im"], None, lambda c: c["w"][1].imag),
          ("Table 2", "lambda4", t2["lambda4"], None, lambda c: c["w"][3].real)]
    for s in range(4):
        for m in range(3):
            S.append(("Table 3", f"|{STATES[s]}| mode {m + 1}", pv.TABLE3_MAGNITUDE[s][m], None,
                      lambda c, s=s, m=m: c["mag"][s, m]))
            S.append(("Table 3", f"phase {STATES[s]} mode {m + 1} (deg)", pv.TABLE3_PHASE_DEG[s][m], None,
                      lambda c, s=s, m=m: c["ph"][s, m]))
    S += [("Eq. (19)", f"A_lnn({i + 1},{j + 1})", pv.EQ19_A_LNN[i][j], 4, lambda c, i=i, j=j: c["Ann"][i, j])
          for i in range(4) for j in range(4)]
    S += [("Eq. (20)", f"B_ln({i + 1},{j + 1}) [{lateral_interface.CONTROL_NAMES[j]}]", pv.EQ20_B_LN[i][j], 4,
           lambda c, i=i, j=j: c["Bn"][i, j]) for i in range(4) for j in range(3)]
    S += [("Eq. (24)", f"b({i + 1}) [B1 column of delta_Phi_a]", pv.EQ24_B_COLUMN[i], 4,
           lambda c, i=i: c["B"][i, 0]) for i in range(4)]
    for r, coef in enumerate("bcde"):
        for j, text in enumerate(pv.EQ26[coef]):
            what = "constant" if j == 0 else f"coefficient of k{j}"
            if text is None:
                text, what = pv.EQ26_ABSENT[(coef, j)], what + " (term not printed)"
            S.append((f"Eq. (26{chr(ord('a') + r)})", f"{coef}: {what}", text, None,
                      lambda c, r=r, j=j: c["c0"][r] if j == 0 else c["G"][r, j - 1]))
    S += [("Eq. (27)", f"k{j + 1} (model B1, Table 2 targets)", pv.EQ27_GAINS[j], None,
           lambda c, j=j: c["k"][j]) for j in range(4)]
    return S


def _longitudinal_specs() -> list[tuple[str, str, str, int | None, Callable[[Ctx], float]]]:
    S: list = [("Sect. 3.5", f"{m}({i + 1},{j + 1})" + (f" [{pv.LONGITUDINAL_CONTROLS[j]}]" if m == "B" else ""),
                tab[i][j], pv.SECT35_DECIMALS, lambda c, m=m, i=i, j=j: c[m][i, j])
               for m, tab in (("A", pv.SECT35_A), ("B", pv.SECT35_B)) for i in range(4) for j in range(4)]
    ev = pv.EQ31_EIGENVALUES  # eig(A) ordered: the pair (sigma + i omega first), slow, fast
    S += [("Eq. (31)", "eigenvalue sigma (unstable pair)", ev["sigma"], None, lambda c: c["w"][0].real),
          ("Eq. (31)", "eigenvalue omega (unstable pair, +/-)", ev["omega"], None, lambda c: c["w"][0].imag),
          ("Eq. (31)", "eigenvalue fast subsidence", ev["fast"], None, lambda c: c["w"][3].real),
          ("Eq. (31)", "eigenvalue slow subsidence", ev["slow"], None, lambda c: c["w"][2].real)]
    S += [("Eq. (31)", f"A_nn({i + 1},{j + 1})", pv.EQ31_A_NN[i][j], 4, lambda c, i=i, j=j: c["Ann"][i, j])
         for i in range(4) for j in range(4)]
    S += [("Eq. (32)", f"B_n({i + 1},{j + 1}) [{pv.LONGITUDINAL_CONTROLS[j]}]", pv.EQ32_B_N[i][j], 4,
           lambda c, i=i, j=j: c["Bn"][i, j]) for i in range(4) for j in range(4)]
    return S


def _make(spec, computed: float, interval, note_fn) -> Row:
    src, qty, text, dec, _ = spec
    tol = pv.half_unit(text, dec)
    match = rounds_to(computed, text, tol)
    reason, note = note_fn(src, qty, text, computed, match, interval)
    return Row(src, qty, text, float(computed), tol, bool(match), reason, note, interval)


def reproduction_table() -> list[Row]:
    """All rows, lateral then Eq. (27) with the paper's own inputs, then longitudinal."""
    return list(_build()[0])


@functools.lru_cache(maxsize=1)
def _build() -> tuple[tuple[Row, ...], "Notes"]:
    lat_in, lon_in = lateral_inputs(), longitudinal_inputs()
    lspecs, ospecs = _lateral_specs(), _longitudinal_specs()
    lat = _lateral_ctx(np.array([v for _, v, _ in lat_in]))
    lon = _longitudinal_ctx(np.array([v for _, v, _ in lon_in]))
    li = _intervals(_lateral_ctx, lat_in, [s[4] for s in lspecs])
    oi = _intervals(_longitudinal_ctx, lon_in, [s[4] for s in ospecs])
    notes = Notes(lat, lon)
    rows = [_make(s, s[4](lat), iv, notes) for s, iv in zip(lspecs, li)]
    k_paper = notes.alt["k_paper"]
    rows += [_make(("Eq. (27)", f"k{j + 1} (paper's inputs: Eq. 19 targets, Eq. 24 b)", pv.EQ27_GAINS[j],
                    None, None), k_paper[j], None, notes) for j in range(4)]
    rows += [_make(s, s[4](lon), iv, notes) for s, iv in zip(ospecs, oi)]
    return tuple(rows), notes


# --- output ---------------------------------------------------------------------------------
def _gains(notes: Notes) -> dict:
    a = notes.alt
    return {"eq27_printed": [float(t) for t in pv.EQ27_GAINS],
            "eq27_paper_inputs (Eq. 19 targets, Eq. 24 b)": a["k_paper"].tolist(),
            "eq27_paper_inputs place_poles": a["k_paper_pp"].tolist(),
            "eq27_paper_inputs Ackermann": a["k_paper_ack"].tolist(),
            "eq27_exact (exact eigenvalues, model b)": a["k_exact"].tolist(),
            "eq27_exact (exact eigenvalues, Eq. 24 b)": a["k_exact_b24"].tolist(),
            "eq27_table2_targets (Eq. 24 b)": a["k_t2_b24"].tolist()}


@dataclass(frozen=True)
class Analysis:
    """What ``dronefly analyze`` reports: the reproduction rows, the analysis report (modal
    forms, designs, controllability) and the gains; rendered by :mod:`.report`."""

    rows: tuple[Row, ...]
    report: dict
    gains: dict

    def to_json(self) -> dict:
        """The JSON of ``dronefly analyze --json``; a design for given targets comes first
        (``custom_design``), as the user asked for it."""
        first = {k: v for k, v in self.report.items() if k == "custom_design"}
        return {**first, "reproduction": [r.as_dict() for r in self.rows],
                "summary": summary(self.rows), "gains": self.gains,
                **{k: v for k, v in self.report.items() if k != "custom_design"}}


def analyze(targets: str | None = None, design_input: str = "delta_Phi_a") -> Analysis:
    """Reproduce every printed number and run the analysis (and a design for ``targets``).

    Raises
    ------
    AnalysisInputError
        (a DroneflyError) for a bad input name or bad targets.
    """

    report = analysis_report(targets, design_input)
    rows, notes = _build()
    return Analysis(rows, report, _gains(notes))
