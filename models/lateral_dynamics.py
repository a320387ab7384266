"""Linearized lateral dynamics of the hovering model drone fly (Zhang & Sun).

This module is the single home of the model's equations and of its printed
coefficients (Eq. 12, Sect. 2.1, Table 1). The plant FMU and the analysis
import it; names, units and reference scales (Sect. 2.4) live in
:mod:`dronefly.models.lateral_interface`, which the controller shares without this module.

Non-dimensionalisation (end of Sect. 2.1): reference length c (mean chord),
velocity U = 2 Phi n r2, time t_w = 1/n. The state is
x+ = (dv+, dp+, dr+, dgamma) = (dv/U, dp t_w, dr t_w, dgamma) and the control is
c1 = (dPhi_a, dalpha_1a, dalpha_2a) in rad. Time t+ = t / t_w (wing beats).

The stability derivatives are not printed in the paper. They are recovered from
the printed system matrix, Eq. (12), and the printed inertias by inverting
Eq. (10): rows 2 and 3 of A1 are M^-1 [L; N] with M = [[Ix, -Ixz], [-Ixz, Iz]]
(Eqs. 2-3), so [L; N] = M [A1 row 2; A1 row 3]; row 1 is Y/m. With these values
Eq. (10) gives back Eq. (12) exactly, up to floating-point rounding.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Mapping

from .lateral_interface import INERTIAS_SECT21
from .linear import ModelParameterError, PlantParameters, Rows, ZohModel, as_arrays, finite_rows

__all__ = [
    "A1_EQ12",
    "CONTROL_DERIVATIVES_TABLE1",
    "LateralModel",
    "LateralParameters",
    "default_parameters",
    "derive_stability_derivatives",
    "system_matrices",
    "system_rows",
]

if TYPE_CHECKING:
    import numpy as np
    from numpy.typing import NDArray

    Array = NDArray[np.float64]

#: Eq. (12): the system matrix A1 as printed (non-dimensional, per wing beat).
A1_EQ12: tuple[tuple[float, ...], ...] = (
    (-0.0094, -0.0011, 0.0, 0.0158),
    (0.1741, -0.2496, 0.2930, 0.0),
    (-0.1117, 0.1551, -0.3500, 0.0),
    (0.0, 1.0, 0.0, 0.0),
)

#: Table 1: non-dimensional lateral control derivatives (per rad).
CONTROL_DERIVATIVES_TABLE1: dict[str, float] = {
    "Y_Phi_a_plus": -0.049,
    "L_Phi_a_plus": 2.236,
    "N_Phi_a_plus": -0.007,
    "Y_alpha_1a_plus": 0.511,
    "L_alpha_1a_plus": 3.456,
    "N_alpha_1a_plus": 0.121,
    "Y_alpha_2a_plus": 0.066,
    "L_alpha_2a_plus": 0.014,
    "N_alpha_2a_plus": -4.922,
}


def derive_stability_derivatives(
    A1: Any = A1_EQ12,
    inertias: Mapping[str, float] = INERTIAS_SECT21,
) -> dict[str, float]:
    """Invert Eq. (10): the nine stability derivatives behind a system matrix.

    Parameters
    ----------
    A1 : (4, 4) array_like
        Non-dimensional system matrix (default: Eq. 12 as printed).
    inertias : mapping
        ``m_plus``, ``Ix_plus``, ``Iz_plus``, ``Ixz_plus`` (non-dimensional).

    Returns
    -------
    dict
        ``Yv_plus`` ... ``Nr_plus`` (non-dimensional).
    """
    a = _rows_of(A1)
    m, Ix, Iz, Ixz = (inertias[k] for k in ("m_plus", "Ix_plus", "Iz_plus", "Ixz_plus"))
    out: dict[str, float] = {}
    for j, s in enumerate("vpr"):  # [L; N] = [[Ix, -Ixz], [-Ixz, Iz]] [A1 row 2; A1 row 3]
        out[f"Y{s}_plus"] = float(m * a[0][j])
        out[f"L{s}_plus"] = float(Ix * a[1][j] + -Ixz * a[2][j])
        out[f"N{s}_plus"] = float(-Ixz * a[1][j] + Iz * a[2][j])
    return out


def _rows_of(M: Any) -> Rows:
    """A matrix (rows of numbers, or a 2-D array) as a tuple of rows of floats."""
    return tuple(tuple(float(x) for x in row) for row in M)


@dataclass(frozen=True)
class LateralParameters(PlantParameters):
    """Non-dimensional parameters of Eq. (9) (all unit 1)."""

    m_plus: float
    Ix_plus: float
    Iz_plus: float
    Ixz_plus: float
    g_plus: float
    Yv_plus: float
    Yp_plus: float
    Yr_plus: float
    Lv_plus: float
    Lp_plus: float
    Lr_plus: float
    Nv_plus: float
    Np_plus: float
    Nr_plus: float
    Y_Phi_a_plus: float
    L_Phi_a_plus: float
    N_Phi_a_plus: float
    Y_alpha_1a_plus: float
    L_alpha_1a_plus: float
    N_alpha_1a_plus: float
    Y_alpha_2a_plus: float
    L_alpha_2a_plus: float
    N_alpha_2a_plus: float

    def check_physical(self) -> None:
        """Raise :class:`ModelParameterError` for finite values that are not physical."""
        if self.m_plus <= 0.0:
            raise ModelParameterError(f"m_plus = {self.m_plus!r} must be > 0")
        if self.Ix_plus <= 0.0 or self.Iz_plus <= 0.0:
            raise ModelParameterError(
                f"Ix_plus = {self.Ix_plus!r}, Iz_plus = {self.Iz_plus!r} must be > 0"
            )
        det = self.Ix_plus * self.Iz_plus - self.Ixz_plus * self.Ixz_plus
        if not math.isfinite(det):
            raise ModelParameterError(
                f"Ix_plus*Iz_plus - Ixz_plus^2 = {det!r} is not finite (Ix_plus = "
                f"{self.Ix_plus!r}, Iz_plus = {self.Iz_plus!r}, Ixz_plus = {self.Ixz_plus!r})")
        if det <= 0.0:
            raise ModelParameterError(
                f"Ix_plus*Iz_plus = {self.Ix_plus * self.Iz_plus!r} must exceed "
                f"Ixz_plus^2 = {self.Ixz_plus * self.Ixz_plus!r} (Ixz_plus = {self.Ixz_plus!r})"
            )


def default_parameters() -> LateralParameters:
    """The paper's model: Sect. 2.1 inertias, Eq. (12) derivatives, Table 1."""
    return LateralParameters(
        **INERTIAS_SECT21,
        **derive_stability_derivatives(),
        **CONTROL_DERIVATIVES_TABLE1,
    )


#: (Y, L, N) derivative names per column of A1 (v, p, r) and of B1 (the three controls)
_STABILITY = tuple(tuple(f"{F}{s}_plus" for F in "YLN") for s in "vpr")
_CONTROL = tuple(tuple(f"{F}_{c}_plus" for F in "YLN") for c in ("Phi_a", "alpha_1a", "alpha_2a"))


def system_rows(p: LateralParameters) -> tuple[Rows, Rows]:
    """A1 and B1 of Eq. (9) by Eqs. (10)-(11), as tuples of rows (plain Python).

    Returns
    -------
    A1 : 4 rows of 4 floats
        Non-dimensional system matrix, per wing beat.
    B1 : 4 rows of 3 floats
        Non-dimensional control matrix, per wing beat per rad.

    Raises
    ------
    ModelParameterError
        A parameter is not valid, or an entry overflows.
    """
    p.validate()
    det = p.Ix_plus * p.Iz_plus - p.Ixz_plus**2

    def _rows(Y: float, L: float, N: float) -> tuple[float, float, float]:
        return (
            Y / p.m_plus,
            (p.Iz_plus * L + p.Ixz_plus * N) / det,
            (p.Ixz_plus * L + p.Ix_plus * N) / det,
        )

    A = [[0.0] * 4 for _ in range(4)]
    for j, names in enumerate(_STABILITY):
        for i, x in enumerate(_rows(*(getattr(p, n) for n in names))):
            A[i][j] = x
    A[0][3] = p.g_plus
    A[3][1] = 1.0
    B = [[0.0] * 3 for _ in range(4)]
    for j, names in enumerate(_CONTROL):
        for i, x in enumerate(_rows(*(getattr(p, n) for n in names))):
            B[i][j] = x
    return finite_rows(A, B, ModelParameterError, f"Eqs. (10)-(11) (m_plus = {p.m_plus!r}, "
                       f"Ix_plus = {p.Ix_plus!r}, Iz_plus = {p.Iz_plus!r}, Ixz_plus = "
                       f"{p.Ixz_plus!r}, or a derivative)")


def system_matrices(p: LateralParameters) -> "tuple[Array, Array]":
    """A1 (4 x 4, per wing beat) and B1 (4 x 3, per wing beat per rad) of :func:`system_rows`
    as numpy arrays, for the analyses (imports numpy)."""
    return as_arrays(*system_rows(p))


class LateralModel(ZohModel):
    """Eq. (9) with exact stepping for piecewise-constant controls (time in wing beats).

    Parameters
    ----------
    params : LateralParameters
        Validated on construction (raises :class:`ModelParameterError`).
    """

    A_NAME = "A1"
    B_NAME = "B1"

    def __init__(self, params: LateralParameters) -> None:
        self.params = params
        super().__init__(*system_rows(params))
