"""Printed values of Zhang & Sun that the analysis is compared against.

Every number is stored once, as the text printed in the paper (so that its
rounding, half a unit in the last printed digit, is known), with its source.
``"a×10^-n"`` is written ``"ae-n"``. The lateral system matrix of Eq. (12) lives
in :mod:`dronefly.models.lateral_dynamics` (``A1_EQ12``) and Eq. (24) reprints it verbatim,
so it is imported, not repeated; likewise Sect. 3.5's longitudinal A and B live in
:mod:`dronefly.models.longitudinal_dynamics` (``A_SECT35``, ``B_SECT35``) and are formatted
here as printed (4 decimals; a printed 0 or 1 as such). A number that appears in two equations (e.g.
0.4993 in Eq. 24 and Eq. 26) is two printed numbers and is checked twice.

Layout conventions: matrices are tuples of rows; Table 3 is indexed
``[state][mode]`` with states (dv+, dp+, dr+, dgamma) and modes 1-3 as printed.
"""

from __future__ import annotations

import math
from decimal import Decimal

from ...models.feedback import PAPER_GAINS_EQ27
from ...models.longitudinal_interface import CONTROL_NAMES
from ...models.lateral_dynamics import A1_EQ12
from ...models.longitudinal_dynamics import A_SECT35, B_SECT35

__all__ = [
    "EQ12_A1", "EQ12_DECIMALS", "EQ12_STRUCTURAL", "EQ19_A_LNN", "EQ20_B_LN",
    "EQ24_B_COLUMN", "EQ26", "EQ26_ABSENT", "EQ27_GAINS", "ERRATA",
    "EQ31_A_NN", "EQ31_EIGENVALUES", "EQ32_B_N", "LONGITUDINAL_CONTROLS",
    "LONGITUDINAL_STRUCTURAL", "SECT21_DECIMALS", "SECT35_A", "SECT35_B", "SECT35_DECIMALS", "TABLE1_DECIMALS", "TABLE2", "TABLE3_MAGNITUDE",
    "TABLE3_PHASE_DEG",
    "eq27_targets", "half_unit", "table2_eigenvalues",
]

#: Eq. (12), from the model module (4 decimals as printed).
EQ12_A1 = A1_EQ12
EQ12_DECIMALS = 4
#: Entries of Eq. (12) fixed by the structure of Eq. (10) (exact 0 and 1), 0-based.
EQ12_STRUCTURAL = ((1, 3), (2, 3), (3, 0), (3, 1), (3, 2), (3, 3))

#: Table 2: eigenvalues of A1 (per wing beat).
TABLE2 = {"lambda1": "0.079", "lambda23_re": "-0.089", "lambda23_im": "0.057",
          "lambda4": "-0.510"}

#: Table 3: eigenvector magnitudes, normalised to dgamma = 1 (rows dv+, dp+, dr+, dgamma).
TABLE3_MAGNITUDE = (("0.179", "0.163", "0.033"),
                    ("0.079", "0.106", "0.510"),
                    ("0.018", "0.072", "0.472"),
                    ("1", "1", "1"))
#: Table 3: eigenvector phases in degrees.
TABLE3_PHASE_DEG = (("0", "-144.7", "180"),
                    ("0", "147.5", "180"),
                    ("180", "74.6", "0"),
                    ("0", "0", "0"))

#: Eq. (19): modal system matrix A_lnn.
EQ19_A_LNN = (("0.0786", "0", "0", "0"),
              ("0", "-0.0890", "0.0568", "0"),
              ("0", "-0.0568", "-0.0890", "0"),
              ("0", "0", "0", "-0.5097"))
#: Eq. (20): modal control matrix B_ln (columns dPhi_a, dalpha_1a, dalpha_2a).
EQ20_B_LN = (("-0.5711", "-0.8901", "-0.2809"),
             ("0.1387", "0.1851", "0.7498"),
             ("0.4979", "0.7747", "-0.4859"),
             ("-1.0135", "-1.5056", "-2.1243"))

#: Eq. (24): the dPhi_a column of B1 as printed.
EQ24_B_COLUMN = ("-0.0005", "0.4993", "-0.3296", "0")

#: Eq. (26a)-(26d): (constant, k1, k2, k3, k4) coefficients; None = term not printed.
EQ26 = {
    "b": ("0.609", "5e-4", "-0.4993", "0.3296", None),
    "c": ("4.774e-2", "8.49e-4", "-8.2789e-2", "7.8691e-3", "-0.4993"),
    "d": ("-2.3257e-3", "-7.782e-3", "-7.2081e-4", "4.671e-5", "-8.279e-3"),
    "e": ("4.4567e-4", "-1.2353e-3", None, "-2.5462e-5", "-7.2081e-4"),
}
#: Absent terms are read as a printed 0 at the precision of the last digit of the
#: smallest printed coefficient of the same equation.
EQ26_ABSENT = {("b", 4): "0.0000", ("e", 2): "0.000000000"}

#: Eq. (27): feedback gains k1..k4 of dPhi_a, printed to 4 decimals; the numbers live in
#: the controller's law module (the FMU's default gains), so they are formatted, not repeated.
EQ27_GAINS = tuple(f"{k:.4f}" for k in PAPER_GAINS_EQ27)

#: Sect. 3.5 prints A and B to 4 decimals (0 and 1 bare).
SECT35_DECIMALS = 4


def _as_printed(matrix: tuple[tuple[float, ...], ...]) -> tuple[tuple[str, ...], ...]:
    return tuple(tuple(f"{v:g}" if v in (0.0, 1.0) else f"{v:.{SECT35_DECIMALS}f}" for v in row)
                 for row in matrix)


#: Sect. 3.5: longitudinal system matrix A (state du+, dw+, dq+, dtheta; Ref. [17]), as printed.
SECT35_A = _as_printed(A_SECT35)
#: Sect. 3.5: longitudinal control matrix B (columns in the order of Eq. 30), as printed.
SECT35_B = _as_printed(B_SECT35)
#: Eq. (30) control vector order; the text lists dPhi, dphi_bar, dalpha1, dalpha2,
#: but B_n's rows (slow subsidence ~ B row 2) show that B uses Eq. (30)'s order. The names
#: live in the plant's interface (:mod:`dronefly.models.longitudinal_interface`).
LONGITUDINAL_CONTROLS = CONTROL_NAMES
#: Structural entries of the longitudinal A (dtheta' = dq; no theta in w, q rows)
#: and B (no control in the dtheta row), 0-based; all other entries are rounded.
LONGITUDINAL_STRUCTURAL = {"A": ((1, 3), (2, 3), (3, 0), (3, 1), (3, 2), (3, 3)),
                           "B": ((3, 0), (3, 1), (3, 2), (3, 3))}

#: Eq. (31): longitudinal modal system matrix A_nn.
EQ31_A_NN = (("0.0481", "-0.0977", "0", "0"),
             ("0.0977", "0.0481", "0", "0"),
             ("0", "0", "-0.1195", "0"),
             ("0", "0", "0", "-0.0123"))
#: The longitudinal eigenvalues as Eq. (31) prints them (its diagonal and the pair's omega):
#: sigma +/- i omega (unstable oscillatory mode), fast and slow subsidence.
EQ31_EIGENVALUES = {"sigma": EQ31_A_NN[0][0], "omega": EQ31_A_NN[1][0], "fast": EQ31_A_NN[2][2],
                    "slow": EQ31_A_NN[3][3]}
#: Eq. (32): longitudinal modal control matrix B_n.
EQ32_B_N = (("0.0004", "-0.0008", "-0.2201", "0.0742"),
            ("0.0055", "0.0092", "-0.4312", "0.0012"),
            ("0.0005", "0.0034", "0.4413", "-0.1488"),
            ("-0.0181", "-0.0267", "-0.0011", "0"))


#: Errors in the print, once: (source, quantity of the reproduction row) -> what was
#: printed, the corrected value and why. ``dronefly analyze`` classifies a mismatch as
#: "error in print" exactly for these rows; tests/test_analysis.py recomputes each correction.
ERRATA: dict[tuple[str, str], tuple[str, str, str]] = {
    ("Eq. (26c)", "d: coefficient of k4"): (
        EQ26["d"][4], "-8.279e-2",
        "exponent: the k4 coefficient of d equals the k2 coefficient of c (dgamma' = dp+), "
        "printed -8.2789e-2 in Eq. (26b)"),
    ("Eq. (26d)", "e: constant"): (
        EQ26["e"][0], "-4.4567e-4",
        "sign: e = det(A1) = lambda1 lambda2 lambda3 lambda4 < 0, exactly one eigenvalue "
        "(lambda1 = 0.0786) being positive"),
    ("Eq. (31)", "A_nn(1,2)"): (
        EQ31_A_NN[0][1], "0.0977",
        "sign: the modal transformation that reproduces Eq. (32) gives +omega here"),
    ("Eq. (31)", "A_nn(2,1)"): (
        EQ31_A_NN[1][0], "-0.0977",
        "sign: the same transformation gives -omega here"),
}


def table2_eigenvalues() -> tuple[complex, ...]:
    """Table 2 as numbers: lambda1, lambda2,3 = re +/- i im, lambda4 (per wing beat)."""
    re_, im = float(TABLE2["lambda23_re"]), float(TABLE2["lambda23_im"])
    return (complex(float(TABLE2["lambda1"])), complex(re_, im), complex(re_, -im),
            complex(float(TABLE2["lambda4"])))


def eq27_targets() -> tuple[complex, ...]:
    """The closed-loop eigenvalues Eq. (27) aims at: Table 2 with lambda1 moved to 0."""
    return (0j, *table2_eigenvalues()[1:])


def half_unit(text: str, decimals: int | None = None) -> float:
    """Half a unit in the last printed digit of ``text``.

    Parameters
    ----------
    text : str
        Printed number: ``"0.1234"`` -> 5e-5, ``"1.23e-4"`` -> 5e-7.
    decimals : int, optional
        For a bare integer (``"0"``, ``"1"``) inside a matrix printed to ``decimals``
        places, the entry is read as ``0.0000``, ``1.0000`` (the paper prints its
        structural entries, which are exact, without the decimals of the others).

    Returns
    -------
    float
        The rounding half-width, in the unit of the printed value.
    """
    if decimals is not None and "." not in text and "e" not in text.lower():
        return 0.5 * 10.0 ** (-decimals)
    exponent = Decimal(text).as_tuple().exponent
    assert isinstance(exponent, int)
    return 0.5 * math.pow(10.0, exponent)


#: Printed decimals of the Sect. 2.1 values held (as floats) in ``model.INERTIAS_SECT21``
#: and of Table 1 (``model.CONTROL_DERIVATIVES_TABLE1``, all printed to 3 decimals).
SECT21_DECIMALS = {"m_plus": 1, "Ix_plus": 2, "Iz_plus": 2, "Ixz_plus": 2}
TABLE1_DECIMALS = 3
