"""Linearized longitudinal dynamics of the hovering model drone fly (Zhang & Sun, Sect. 3.5).

The single home of the longitudinal equations and of Sect. 3.5's printed A and B.
Names, units and scales live in :mod:`dronefly.models.longitudinal_interface`.

State x+ = (du+, dw+, dq+, dtheta) = (du/U, dw/U, dq t_w, dtheta), control
u = (dPhi, dalpha_1, dphibar, dalpha_2) [rad] in the order of B's columns (Eq. 30; see
:mod:`dronefly.models.longitudinal_interface`), time t+ = t/t_w in wing beats. The equations of the
averaged model linearised about hover (body x-axis horizontal, no equilibrium
velocity; the form of Refs. [7, 16, 17]):

    du+'     = (Xu du+ + Xw dw+ + Xq dq+ + sum_c X_c u_c) / m+ - g+ dtheta
    dw+'     = (Zu du+ + Zw dw+ + Zq dq+ + sum_c Z_c u_c) / m+
    dq+'     = (Mu du+ + Mw dw+ + Mq dq+ + sum_c M_c u_c) / Iy+
    dtheta'  = dq+

A (4x4) and B (4x4) are these coefficients. The paper prints A and B but not the
derivatives; they are recovered by inverting the equations with the printed m+ and g+
(end of Sect. 2.1) and Iy+ (:data:`dronefly.models.longitudinal_interface.IY_PLUS`): X = m+ A[0, :],
Z = m+ A[1, :], M = Iy+ A[2, :]. The printed A[0, 3] = -0.0158 is -g+, as the
equations require; A[1, 3] = 0 because gravity has no component along z for a small
pitch from a horizontal x-axis.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Sequence

from .lateral_interface import INERTIAS_SECT21
from .linear import ModelParameterError, PlantParameters, Rows, ZohModel, as_arrays, finite_rows
from .longitudinal_interface import CONTROL_NAMES, IY_PLUS

__all__ = [
    "A_SECT35",
    "B_SECT35",
    "LongitudinalModel",
    "LongitudinalParameters",
    "default_parameters",
    "derive_derivatives",
    "parameter_dependencies",
    "system_matrices",
    "system_rows",
]

if TYPE_CHECKING:
    import numpy as np
    from numpy.typing import NDArray

    Array = NDArray[np.float64]

#: Sect. 3.5: the longitudinal system matrix A as printed (per wing beat; from Ref. [17]).
A_SECT35: tuple[tuple[float, ...], ...] = (
    (-0.0134, 0.0011, -0.0025, -0.0158),
    (-0.0006, -0.0122, -0.0003, 0.0),
    (0.0895, -0.0062, -0.0098, 0.0),
    (0.0, 0.0, 1.0, 0.0),
)
#: Sect. 3.5: the longitudinal control matrix B as printed (per wing beat per rad), columns
#: (dPhi, dalpha_1, dphibar, dalpha_2).
B_SECT35: tuple[tuple[float, ...], ...] = (
    (0.0, 0.0009, -0.0022, -0.0321),
    (-0.0180, -0.0266, 0.0, -0.0001),
    (0.0011, 0.0013, -0.1556, 0.0247),
    (0.0, 0.0, 0.0, 0.0),
)

_FORCES = ("X", "Z", "M")
_STATES = ("u", "w", "q")
#: control suffixes in B's column order
_CONTROLS = tuple(c[len("delta_"):] for c in CONTROL_NAMES)
#: parameter names of A[i, j] (stability) and B[i, j] (control), i over X, Z, M; formed once
#: (names built per call would fill the interpreter's attribute cache with copies)
_A_NAMES = tuple(tuple(f"{F}{s}_plus" for s in _STATES) for F in _FORCES)
_B_NAMES = tuple(tuple(f"{F}_{c}_plus" for c in _CONTROLS) for F in _FORCES)


@dataclass(frozen=True)
class LongitudinalParameters(PlantParameters):
    """Non-dimensional parameters of the longitudinal equations (all unit 1)."""

    m_plus: float
    Iy_plus: float
    g_plus: float
    Xu_plus: float
    Xw_plus: float
    Xq_plus: float
    Zu_plus: float
    Zw_plus: float
    Zq_plus: float
    Mu_plus: float
    Mw_plus: float
    Mq_plus: float
    X_Phi_plus: float
    Z_Phi_plus: float
    M_Phi_plus: float
    X_alpha_1_plus: float
    Z_alpha_1_plus: float
    M_alpha_1_plus: float
    X_phibar_plus: float
    Z_phibar_plus: float
    M_phibar_plus: float
    X_alpha_2_plus: float
    Z_alpha_2_plus: float
    M_alpha_2_plus: float

    def check_physical(self) -> None:
        """Raise :class:`ModelParameterError` for finite values that are not physical."""
        for name in ("m_plus", "Iy_plus"):
            if getattr(self, name) <= 0.0:
                raise ModelParameterError(f"{name} = {getattr(self, name)!r} must be > 0")


def derive_derivatives(A: Sequence[Sequence[float]] = A_SECT35,
                       B: Sequence[Sequence[float]] = B_SECT35, m_plus: float =
                       INERTIAS_SECT21["m_plus"], Iy_plus: float = IY_PLUS) -> dict[str, float]:
    """Invert the equations: the stability and control derivatives behind A and B.

    Returns
    -------
    dict
        ``Xu_plus`` ... ``Mq_plus`` and ``X_Phi_plus`` ... ``M_alpha_2_plus``
        (non-dimensional).
    """
    scale = (m_plus, m_plus, Iy_plus)
    out: dict[str, float] = {}
    for i in range(len(_FORCES)):
        for j, name in enumerate(_A_NAMES[i]):
            out[name] = float(scale[i] * A[i][j])
    for j in range(len(_CONTROLS)):
        for i in range(len(_FORCES)):
            out[_B_NAMES[i][j]] = float(scale[i] * B[i][j])
    return out


def default_parameters() -> LongitudinalParameters:
    """The paper's model: m+, g+ of Sect. 2.1, Iy+ from Sect. 2.4, derivatives from Sect. 3.5."""
    return LongitudinalParameters(m_plus=INERTIAS_SECT21["m_plus"], Iy_plus=IY_PLUS,
                                  g_plus=INERTIAS_SECT21["g_plus"], **derive_derivatives())


def system_rows(p: LongitudinalParameters) -> tuple[Rows, Rows]:
    """A (4x4, per wing beat) and B (4x4, per wing beat per rad) from the parameters, as
    tuples of rows (plain Python).

    Raises
    ------
    ModelParameterError
        A parameter is not valid, or an entry overflows.
    """
    p.validate()
    scale = (p.m_plus, p.m_plus, p.Iy_plus)
    A = [[0.0] * 4 for _ in range(4)]
    B = [[0.0] * len(_CONTROLS) for _ in range(4)]
    for i in range(len(_FORCES)):
        for j, name in enumerate(_A_NAMES[i]):
            A[i][j] = getattr(p, name) / scale[i]
        for j, name in enumerate(_B_NAMES[i]):
            B[i][j] = getattr(p, name) / scale[i]
    A[0][3] = -p.g_plus
    A[3][2] = 1.0
    return finite_rows(A, B, ModelParameterError, f"(m_plus = {p.m_plus!r}, Iy_plus = "
                       f"{p.Iy_plus!r}, or a derivative)")


def system_matrices(p: LongitudinalParameters) -> "tuple[Array, Array]":
    """A and B of :func:`system_rows` as numpy arrays, for the analyses (imports numpy)."""
    return as_arrays(*system_rows(p))


class LongitudinalModel(ZohModel):
    """The longitudinal equations with exact stepping for piecewise-constant controls.

    Parameters
    ----------
    params : LongitudinalParameters
        Validated on construction (raises :class:`ModelParameterError`).
    """

    def __init__(self, params: LongitudinalParameters) -> None:
        self.params = params
        super().__init__(*system_rows(params))


def parameter_dependencies(row: int, col: int, controls: bool) -> tuple[str, ...]:
    """Parameters that A[row, col] (or B) depends on, 0-based."""
    if row == 3:
        return ()
    if not controls and col == 3:
        return ("g_plus",) if row == 0 else ()
    scale = "Iy_plus" if row == 2 else "m_plus"
    return (scale, (_B_NAMES if controls else _A_NAMES)[row][col])
