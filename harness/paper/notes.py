"""Reason and note of each row of the reproduction table, with the computations they cite."""

from __future__ import annotations

import numpy as np

from . import printed as pv
from .analysis import (ModalConvention, ackermann_gains, characteristic_affine,
    coefficient_matching_gains, modal_decomposition, place_poles_gains)
from .rows import format_bound, format_vector

__all__ = ["LAT_INPUTS", "Notes"]

Ctx = dict[str, np.ndarray]
LAT_INPUTS = "Eq. (12) to 4 decimals, m+, Ix+, Iz+, Ixz+ (Sect. 2.1) and Table 1 to their printed digits"


def _ij(qty: str) -> tuple[int, int]:
    inside = qty[qty.index("(") + 1:qty.index(")")]
    i, j = (int(t) - 1 for t in inside.split(","))
    return i, j


class Notes:
    """Reason and note of each row, with the alternative computations they cite."""

    def __init__(self, lat: Ctx, lon: Ctx) -> None:
        A, B = lat["A"], lat["B"]
        B24 = B.copy()
        B24[:, 0] = [float(t) for t in pv.EQ24_B_COLUMN]
        w = lat["w"]
        e19 = [[float(t) for t in r] for r in pv.EQ19_A_LNN]
        t19 = [0.0, complex(e19[1][1], e19[1][2]), complex(e19[1][1], -e19[1][2]), e19[3][3]]
        t2 = [0.0, complex(float(pv.TABLE2["lambda23_re"]), float(pv.TABLE2["lambda23_im"]))]
        t2 += [t2[1].conjugate(), float(pv.TABLE2["lambda4"])]
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
        erratum = pv.ERRATA.get((src, qty))
        if erratum is not None:  # classified from the errata table, the one home of errors
            note = special[1] if special else f"Error in print ({erratum[2]})."
            return "error in print", " ".join(filter(None, [note, conv]))
        if special and special[0] != "error in print":
            return special[0], " ".join(filter(None, [special[1], conv]))
        return (*self._rounding(src, text, x, iv, conv),)

    def _rounding(self, src: str, text: str, x: float, iv, conv: str) -> tuple[str, str]:
        inputs = {"Eq. (31)": "the Sect. 3.5 A to 4 decimals",
                  "Eq. (32)": "the Sect. 3.5 A and B to 4 decimals"}.get(src, LAT_INPUTS)
        if src == "Eq. (27)":
            inputs += " and the Table 2 targets to 3 decimals"
        lo, hi = iv if iv else (x, x)
        p, tol = float(text), pv.half_unit(text, None if "." in text or src < "Eq. (1" else 4)
        inside = lo <= p + tol and p - tol <= hi
        msg = (f"{'Rounding' if inside else 'Not explained by rounding'}: computed {x:.6g}; moving every "
               f"printed input ({inputs}) by +/- half a unit of its last digit gives [{lo:.6g}, {hi:.6g}] "
               f"(first order, worst case), which {'overlaps' if inside else 'does not overlap'} the "
               f"printed {text}'s own rounding interval [{p - tol:.6g}, {p + tol:.6g}].")
        return ("rounding" if inside else "unexplained"), " ".join(filter(None, [msg, conv]))

    def _convention(self, src: str, qty: str, x: float) -> str:
        a = self.alt
        if src in ("Eq. (12)", "Eq. (24)") and qty.startswith("A1"):
            return ("Round trip: lateral_dynamics.py recovers the stability derivatives from Eq. (12) and the Sect. 2.1 "
                    "inertias and rebuilds A1 by Eq. (10); this checks that inversion, not an independent "
                    "source." + (" Eq. (24) reprints Eq. (12)." if src == "Eq. (24)" else ""))
        if src == "Sect. 3.5":
            return ("Round trip: models/longitudinal_dynamics.py recovers the derivatives from the printed A and "
                    "B with m+ (Sect. 2.1) and Iy+ (Sect. 2.4's Iy scaled as the printed Ix+), g+ = -A(1,4), "
                    "and rebuilds A and B; this checks that inversion, not an independent source.")
        if src == "Eq. (31)" and qty.startswith("eigenvalue"):
            return ("eig(A) of the longitudinal plant, convention-free; Eq. (31) prints the eigenvalues as "
                    "A_nn's diagonal and the pair's off-diagonal.")
        if src == "Table 3":
            parts = []
            if qty == "|dp+| mode 2":
                t2 = complex(float(pv.TABLE2["lambda23_re"]), float(pv.TABLE2["lambda23_im"]))
                e19 = complex(float(pv.EQ19_A_LNN[1][1]), float(pv.EQ19_A_LNN[1][2]))
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
            return f"The term is not printed, i.e. 0; it is exactly 0: {why} (computed magnitude {format_bound(x)}, round-off)."
        if src == "Eq. (27)" and "paper" in qty:
            dev = max(np.abs(a["k_paper_pp"] - a["k_paper"]).max(), np.abs(a["k_paper_ack"] - a["k_paper"]).max())
            return ("The paper's method (coefficient matching, Eqs. 25-26) with the paper's own numbers: "
                    "lambda1 = 0 and lambda2,3, lambda4 'remain the same' read as Eq. (19)'s four-decimal "
                    "values, b from Eq. (24). All four Eqs. (26a)-(26d) are solved; the text's '(i.e. Eqs. "
                    "(26a) and (26b))' is a typo, since four gains need four equations. place_poles and "
                    f"Ackermann agree to {format_bound(dev)} (round-off). Exact gains for the exact eigenvalues of Eq. (12): "
                    f"{format_vector(a['k_exact'], 6)} with lateral_dynamics.py's b, {format_vector(a['k_exact_b24'], 6)} with Eq. (24)'s b.")
        return ""

    def _special(self, src: str, qty: str, text: str, x: float, iv) -> tuple[str, str] | None:
        a, p = self.alt, float(text)
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
                    f"should be one higher. Computed {x:.5g} (lateral_dynamics.py b), {g24:.5g} with Eq. (24)'s b, which matches "
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
                          f"the Table 2 targets {format_vector(a['k_t2_b24'])}; exact gains for the exact eigenvalues "
                          f"(lambda1 -> 0) {format_vector(a['k_exact'], 6)}. The printed gains are reproduced by the "
                          "paper's own inputs (rows 'paper's inputs').")
        if src == "Eq. (31)" and qty in ("A_nn(1,2)", "A_nn(2,1)") and abs(x + p) <= 2e-4:
            kind, msg = self._rounding(src, f"{-p:g}", x, iv, "")
            return "error in print", (
                f"Error in print (sign): no single M reproduces both Eq. (31) and Eq. (32). The convention that "
                f"reproduces Eq. (32) (and Eqs. 19-20) puts +omega at (1,2); Eq. (31) prints the transposed "
                f"block. Computed {x:.5f}; magnitude: {kind}: {msg.split(': ', 1)[1]}")
        return None
