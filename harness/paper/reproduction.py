"""The reproduction table: every printed number of Tables 2-3 and Eqs. (12)-(32).

Each row compares a printed value with the value computed from the model module
(lateral) or from the printed longitudinal A, B of Sect. 3.5. ``match`` means
|computed - printed| <= half a unit in the last printed digit. A mismatch gets a
reason ("convention", "rounding", "error in print") and a note. "Rounding" is
decided, never assumed: every printed input (Eq. 12 and Sect. 3.5 to 4 decimals,
m+, Ix+, Iz+, Ixz+ and Table 1 to their printed digits, the Table 2 targets) is
moved by +/- half a unit of its last digit and the effect is summed to first order
(worst case); the reason is "rounding" only if the printed value lies inside.
"""

from __future__ import annotations

import functools
import json
from dataclasses import dataclass
from typing import Callable, Sequence

import numpy as np

from dronefly.plant import model

from dronefly.harness.paper import values as pv
from dronefly.harness.paper.analysis import (LONGITUDINAL_CONVENTION, ModalConvention, ackermann_gains,
                       characteristic_affine, coefficient_matching_gains, eigenvector_table,
                       longitudinal_system, modal_decomposition, ordered_eigen, place_poles_gains)

__all__ = ["Row", "lateral_inputs", "longitudinal_inputs", "reproduction_table", "run_analyze",
           "summary"]

Ctx = dict[str, np.ndarray]
STATES = ("dv+", "dp+", "dr+", "dgamma")
LAT_INPUTS = "Eq. (12) to 4 decimals, m+, Ix+, Iz+, Ixz+ (Sect. 2.1) and Table 1 to their printed digits"


@dataclass(frozen=True)
class Row:
    """One printed number against its computed value (see the module docstring)."""

    source: str
    quantity: str
    printed: str
    computed: float
    tolerance: float
    match: bool
    reason: str
    note: str
    interval: tuple[float, float] | None = None

    def as_dict(self) -> dict:
        """JSON-ready row: source, quantity, printed, computed, match, note (+ extras)."""
        return {"source": self.source, "quantity": self.quantity, "printed": float(self.printed),
                "printed_text": self.printed, "computed": self.computed, "match": self.match,
                "tolerance": self.tolerance, "reason": self.reason, "note": self.note,
                "input_rounding_interval": list(self.interval) if self.interval else None}


# --- inputs and their rounding -------------------------------------------------------------
def lateral_inputs() -> list[tuple[str, float, float]]:
    """(name, printed value, half unit) of every rounded input of the lateral analysis."""
    out = [(f"A1({i + 1},{j + 1})", pv.EQ12_A1[i][j], 0.5 * 10.0 ** -pv.EQ12_DECIMALS)
           for i in range(4) for j in range(4) if (i, j) not in pv.EQ12_STRUCTURAL]
    out += [(k, model.INERTIAS_SECT21[k], 0.5 * 10.0 ** -d) for k, d in pv.SECT21_DECIMALS.items()]
    out += [(k, v, 0.5 * 10.0 ** -pv.TABLE1_DECIMALS) for k, v in model.CONTROL_DERIVATIVES_TABLE1.items()]
    out += [(f"Table 2 {k}", pv.value(t), pv.half_unit(t)) for k, t in pv.TABLE2.items() if k != "lambda1"]
    return out


def longitudinal_inputs() -> list[tuple[str, float, float]]:
    """(name, printed value, half unit) of every rounded entry of the Sect. 3.5 A and B."""
    return [(f"{m}({i + 1},{j + 1})", pv.value(tab[i][j]), pv.half_unit(tab[i][j], 4))
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
    params = model.LateralParameters(**inertias, **model.derive_stability_derivatives(A, inertias),
                                     **{k: val[k] for k in model.CONTROL_DERIVATIVES_TABLE1})
    A, B = model.system_matrices(params)
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
    return _ctx(A, B, None, LONGITUDINAL_CONVENTION)


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
    S += [("Eq. (20)", f"B_ln({i + 1},{j + 1}) [{model.CONTROL_NAMES[j]}]", pv.EQ20_B_LN[i][j], 4,
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
    S = [("Eq. (31)", f"A_nn({i + 1},{j + 1})", pv.EQ31_A_NN[i][j], 4, lambda c, i=i, j=j: c["Ann"][i, j])
         for i in range(4) for j in range(4)]
    S += [("Eq. (32)", f"B_n({i + 1},{j + 1}) [{pv.LONGITUDINAL_CONTROLS[j]}]", pv.EQ32_B_N[i][j], 4,
           lambda c, i=i, j=j: c["Bn"][i, j]) for i in range(4) for j in range(4)]
    return S


def _make(spec, computed: float, interval, note_fn) -> Row:
    src, qty, text, dec, _ = spec
    tol = pv.half_unit(text, dec)
    match = abs(computed - pv.value(text)) <= tol + 1e-12
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


def summary(rows: Sequence[Row]) -> dict:
    """Counts of rows, matches and mismatches by reason."""
    bad = [r for r in rows if not r.match]
    reasons: dict[str, int] = {}
    for r in bad:
        reasons[r.reason] = reasons.get(r.reason, 0) + 1
    return {"rows": len(rows), "matches": len(rows) - len(bad), "mismatches": len(bad),
            "mismatches_by_reason": reasons}


# --- notes ----------------------------------------------------------------------------------
def _v(x: np.ndarray, d: int = 4) -> str:
    return "(" + ", ".join(f"{v:.{d}f}" for v in np.ravel(x)) + ")"


def _ij(qty: str) -> tuple[int, int]:
    inside = qty[qty.index("(") + 1:qty.index(")")]
    i, j = (int(t) - 1 for t in inside.split(","))
    return i, j


class Notes:
    """Reason and note of each row, with the alternative computations they cite."""

    def __init__(self, lat: Ctx, lon: Ctx) -> None:
        A, B = lat["A"], lat["B"]
        B24 = B.copy()
        B24[:, 0] = [pv.value(t) for t in pv.EQ24_B_COLUMN]
        w = lat["w"]
        e19 = [[pv.value(t) for t in r] for r in pv.EQ19_A_LNN]
        t19 = [0.0, complex(e19[1][1], e19[1][2]), complex(e19[1][1], -e19[1][2]), e19[3][3]]
        t2 = [0.0, complex(pv.value(pv.TABLE2["lambda23_re"]), pv.value(pv.TABLE2["lambda23_im"]))]
        t2 += [t2[1].conjugate(), pv.value(pv.TABLE2["lambda4"])]
        exact = [0.0, w[1], w[2], w[3]]
        self.alt = {
            "Bn_last": modal_decomposition(A, B, ModalConvention((0, 1, 2, 3), norm="last")).B_n,
            "Bn_b24": modal_decomposition(A, B24).B_n, "G24": characteristic_affine(A, B24[:, 0])[1],
            "k_paper": coefficient_matching_gains(A, B24, t19),
            "k_paper_pp": place_poles_gains(A, B24, t19), "k_paper_ack": ackermann_gains(A, B24, t19),
            "k_exact": coefficient_matching_gains(A, B, exact),
            "k_exact_b24": coefficient_matching_gains(A, B24, exact),
            "k_t2_b24": coefficient_matching_gains(A, B24, t2), "w": w, "lon_w": lon["w"]}

    def __call__(self, src: str, qty: str, text: str, x: float, match: bool,
                 iv: tuple[float, float] | None) -> tuple[str, str]:
        conv, special = self._convention(src, qty, x), None
        if not match:
            special = self._special(src, qty, text, x, iv)
        if match:
            return "", conv
        if special:
            return special[0], " ".join(filter(None, [special[1], conv]))
        return (*self._rounding(src, text, x, iv, conv),)

    def _rounding(self, src: str, text: str, x: float, iv, conv: str) -> tuple[str, str]:
        inputs = {"Eq. (31)": "the Sect. 3.5 A to 4 decimals",
                  "Eq. (32)": "the Sect. 3.5 A and B to 4 decimals"}.get(src, LAT_INPUTS)
        if src == "Eq. (27)":
            inputs += " and the Table 2 targets to 3 decimals"
        lo, hi = iv if iv else (x, x)
        p, tol = pv.value(text), pv.half_unit(text, None if "." in text or src < "Eq. (1" else 4)
        inside = lo <= p + tol and p - tol <= hi
        msg = (f"{'Rounding' if inside else 'Not explained by rounding'}: computed {x:.6g}; moving every "
               f"printed input ({inputs}) by +/- half a unit of its last digit gives [{lo:.6g}, {hi:.6g}] "
               f"(first order, worst case), which {'overlaps' if inside else 'does not overlap'} the "
               f"printed {text}'s own rounding interval [{p - tol:.6g}, {p + tol:.6g}].")
        return ("rounding" if inside else "unexplained"), " ".join(filter(None, [msg, conv]))

    def _convention(self, src: str, qty: str, x: float) -> str:
        a = self.alt
        if src in ("Eq. (12)", "Eq. (24)") and qty.startswith("A1"):
            return ("Round trip: model.py recovers the stability derivatives from Eq. (12) and the Sect. 2.1 "
                    "inertias and rebuilds A1 by Eq. (10); this checks that inversion, not an independent "
                    "source." + (" Eq. (24) reprints Eq. (12)." if src == "Eq. (24)" else ""))
        if src == "Table 3":
            parts = []
            if qty == "|dp+| mode 2":
                t2 = complex(pv.value(pv.TABLE2["lambda23_re"]), pv.value(pv.TABLE2["lambda23_im"]))
                e19 = complex(pv.value(pv.EQ19_A_LNN[1][1]), pv.value(pv.EQ19_A_LNN[1][2]))
                parts.append(f"|dp+| = |lambda2| exactly (dgamma' = dp+ with dgamma = 1); Table 2's lambda2 "
                             f"gives {abs(t2):.5f} and Eq. (19)'s {abs(e19):.5f}, both consistent with the "
                             "print, while Eq. (12)'s exact |lambda2| is just below the rounding boundary.")
            if "mode 2" in qty:
                parts.append("Mode 2 is the eigenvector of lambda2 = sigma + i omega (omega > 0); that of "
                             "lambda3 is its conjugate (opposite phases).")
            if "phase" in qty and abs(abs(x) - 180.0) < 1e-6:
                parts.append("Phases are wrapped to (-180, 180]; -180 and 180 deg are the same phase.")
            return " ".join(parts)
        if src == "Eq. (19)" and qty in ("A_lnn(2,3)", "A_lnn(3,2)"):
            return ("Convention: eta2 + i eta3 is the eigenvector of sigma + i omega with omega > 0, which puts "
                    "+omega at (2,3) as printed.")
        if src == "Eq. (20)":
            i, j = _ij(qty)
            return ("Convention that reproduces Eq. (20): M1 = [eta1, 2 eta2, 2 eta3, eta4] (factor 2 as in "
                    "Eq. 14) with every eigenvector of unit 2-norm (LAPACK geev / MATLAB eig; the complex one "
                    "rotated so that its largest component, dgamma, is real and positive; eta2 + i eta3 belongs "
                    "to sigma + i omega, omega > 0), eta1 signed with dgamma < 0 and eta4 with dgamma > 0. "
                    f"Table 3's scaling (dgamma = 1) would give {a['Bn_last'][i, j]:.4f} instead.")
        if src == "Eq. (32)":
            return ("Convention as for Eq. (20): unit 2-norm, the pair rotated so that dtheta is real, "
                    "eta2 + i eta3 for sigma + i omega; modes in Eq. (31)'s order (pair, fast subsidence, "
                    "slow subsidence), real eigenvectors with their largest component positive; columns in "
                    "Eq. (30)'s order (dPhi, dalpha1, dphibar, dalpha2).")
        if src.startswith("Eq. (26") and "not printed" in qty:
            why = ("b = -trace(A1') has k4 coefficient -b(4) = 0" if qty[0] == "b" else
                   "e = det(A1') expanded along its last row (0, 1, 0, 0) is a minor without column 2, "
                   "so k2 drops out")
            return f"The term is not printed, i.e. 0; it is exactly 0: {why} (computed {x:.1e}, round-off)."
        if src == "Eq. (27)" and "paper" in qty:
            dev = max(np.abs(a["k_paper_pp"] - a["k_paper"]).max(), np.abs(a["k_paper_ack"] - a["k_paper"]).max())
            return ("The paper's method (coefficient matching, Eqs. 25-26) with the paper's own numbers: "
                    "lambda1 = 0 and lambda2,3, lambda4 'remain the same' read as Eq. (19)'s four-decimal "
                    "values, b from Eq. (24). All four Eqs. (26a)-(26d) are solved; the text's '(i.e. Eqs. "
                    "(26a) and (26b))' is a typo, since four gains need four equations. place_poles and "
                    f"Ackermann agree to {dev:.1e}. Exact gains for the exact eigenvalues of Eq. (12): "
                    f"{_v(a['k_exact'], 6)} with model.py's b, {_v(a['k_exact_b24'], 6)} with Eq. (24)'s b.")
        return ""

    def _special(self, src: str, qty: str, text: str, x: float, iv) -> tuple[str, str] | None:
        a, p = self.alt, pv.value(text)
        tol = pv.half_unit(text, 4 if src.startswith("Eq. (3") else None)
        if src.startswith("Eq. (26") and qty.endswith("constant") and abs(x + p) <= tol:
            return ("error in print", f"Error in print (sign): e = det(A1) = lambda1 lambda2 lambda3 lambda4 "
                    f"is negative because exactly one eigenvalue (lambda1 = {a['w'][0].real:.4f}) is "
                    f"positive; computed {x:.5g}, the printed magnitude with the opposite sign.")
        if src.startswith("Eq. (26") and abs(x - 10 * p) <= 10 * tol + abs(x) * 2e-3:
            r, j = "bcde".index(qty[0]), int(qty[-1])
            g24 = a["G24"][r, j - 1]
            return ("error in print", f"Error in print (exponent): the k4 coefficient of d equals the k2 "
                    f"coefficient of c (dgamma' = dp+), printed {pv.EQ26['c'][2]} in (26b); the exponent "
                    f"should be one higher. Computed {x:.5g} (model.py b), {g24:.5g} with Eq. (24)'s b, which matches "
                    f"{10 * p:.4g} after the correction; the remaining difference is b's rounding (Eq. 24 rows).")
        if src.startswith("Eq. (26") and not qty.endswith("constant"):
            r, j = "bcde".index(qty[0]), int(qty.split("k")[-1][0])
            g24 = a["G24"][r, j - 1]
            if abs(g24 - p) <= tol + 1e-12:
                kind, msg = self._rounding(src, text, x, iv, "")
                return kind, (f"Inherited from b: with Eq. (24)'s printed b instead of Table 1's the "
                              f"coefficient is {g24:.6g}, which matches. {msg}")
        if src == "Eq. (20)" and qty.endswith("[delta_Phi_a]"):
            i, _ = _ij(qty)
            b24 = a["Bn_b24"][i, 0]
            kind, msg = self._rounding(src, text, x, iv, "")
            same = "which matches" if abs(b24 - p) <= tol + 1e-12 else "still not a match"
            return kind, f"{msg} With Eq. (24)'s printed b instead of Table 1's: {b24:.5f}, {same}."
        if src == "Eq. (27)":
            kind, msg = self._rounding(src, text, x, iv, "")
            return kind, (f"{msg} The gains are very sensitive to b and to the targets: with Eq. (24)'s b and "
                          f"the Table 2 targets {_v(a['k_t2_b24'])}; exact gains for the exact eigenvalues "
                          f"(lambda1 -> 0) {_v(a['k_exact'], 6)}. The printed gains are reproduced by the "
                          "paper's own inputs (rows 'paper's inputs').")
        if src == "Eq. (31)" and qty in ("A_nn(1,2)", "A_nn(2,1)") and abs(x + p) <= 2e-4:
            kind, msg = self._rounding(src, f"{-p:g}", x, iv, "")
            return "error in print", (
                f"Error in print (sign): no single M reproduces both Eq. (31) and Eq. (32). The convention that "
                f"reproduces Eq. (32) (and Eqs. 19-20) puts +omega at (1,2); Eq. (31) prints the transposed "
                f"block. Computed {x:.5f}; magnitude: {kind}: {msg.split(': ', 1)[1]}")
        return None


# --- output ---------------------------------------------------------------------------------
def _gains(notes: Notes) -> dict:
    a = notes.alt
    return {"eq27_printed": [pv.value(t) for t in pv.EQ27_GAINS],
            "eq27_paper_inputs (Eq. 19 targets, Eq. 24 b)": a["k_paper"].tolist(),
            "eq27_paper_inputs place_poles": a["k_paper_pp"].tolist(),
            "eq27_paper_inputs Ackermann": a["k_paper_ack"].tolist(),
            "eq27_exact (exact eigenvalues, model b)": a["k_exact"].tolist(),
            "eq27_exact (exact eigenvalues, Eq. 24 b)": a["k_exact_b24"].tolist(),
            "eq27_table2_targets (Eq. 24 b)": a["k_t2_b24"].tolist()}


def run_analyze(as_json: bool = False, markdown: bool = False, targets: str | None = None,
                design_input: str = "delta_Phi_a") -> str:
    """What ``dronefly analyze`` prints: text (default), Markdown or JSON.

    Raises
    ------
    AnalysisInputError
        (a ValueError) for a bad input name or bad targets, before any output.
    """
    from dronefly.harness.paper.design import analysis_report

    report = analysis_report(targets, design_input)
    rows, notes = _build()
    gains = _gains(notes)
    if as_json:
        return json.dumps({"reproduction": [r.as_dict() for r in rows], "summary": summary(rows),
                           "gains": gains, **report}, indent=1) + "\n"
    from dronefly.harness.paper.report import render_markdown, render_text

    return (render_markdown if markdown else render_text)(rows, report, gains)
