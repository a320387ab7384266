"""Interface of the longitudinal plant (Zhang & Sun, Sect. 3.5): names, units, scales.

State x = (delta_u, delta_w, delta_q, delta_theta): forward and vertical velocity [m/s],
pitch rate [rad/s] and pitch angle [rad] disturbances, made non-dimensional as the
lateral state is (end of Sect. 2.1): x+ = (delta_u/U, delta_w/U, delta_q/n, delta_theta).

Controls, in the order of the columns of the printed B (and of Eq. 30's control vector):
u = (delta_Phi, delta_alpha_1, delta_phibar, delta_alpha_2) [rad]. The text of Sect. 3.5
lists them as delta_Phi, delta_phibar, delta_alpha_1, delta_alpha_2, but Eq. (30) writes
the vector as (delta_Phi, delta_alpha_1, delta_phibar, delta_alpha_2), and the printed
modal control matrix B_n of Eq. (32) equals M^-1 B only with B's columns in that order
(``tests/test_analysis.py``); so that is the order of B's columns and of the FMU's inputs.
The inputs are connected by name, so an importer never depends on the order.

Pure Python (no numpy): the longitudinal FMUs ship this module.
"""

from __future__ import annotations

from .axes import Axis
from .lateral_interface import CONTROL_UNIT, FLIGHT_DATA, INERTIAS_SECT21

__all__ = [
    "parameter_description",
    "CONTROL_DESCRIPTIONS",
    "CONTROL_NAMES",
    "IY_PLUS",
    "LONGITUDINAL",
    "STATE_DESCRIPTIONS",
    "STATE_NAMES",
    "STATE_UNITS",
]

STATE_NAMES: tuple[str, ...] = ("delta_u", "delta_w", "delta_q", "delta_theta")
CONTROL_NAMES: tuple[str, ...] = ("delta_Phi", "delta_alpha_1", "delta_phibar", "delta_alpha_2")

STATE_UNITS: tuple[tuple[str, str | None], ...] = (
    ("m/s", None), ("m/s", None), ("rad/s", "deg/s"), ("rad", "deg"))

STATE_DESCRIPTIONS: tuple[str, ...] = (
    "forward (x-axis) velocity disturbance",
    "vertical (z-axis, positive down) velocity disturbance",
    "pitch rate disturbance (about y)",
    "pitch angle disturbance",
)
CONTROL_DESCRIPTIONS: tuple[str, ...] = (
    "symmetric change of the stroke amplitude of both wings",
    "equal change of the down- and upstroke geometrical angles of attack",
    "change of the mean stroke angle of both wings",
    "differential change of the down- and upstroke geometrical angles of attack",
)

LONGITUDINAL = Axis("longitudinal", STATE_NAMES, CONTROL_NAMES, STATE_UNITS, CONTROL_UNIT,
                    STATE_DESCRIPTIONS, CONTROL_DESCRIPTIONS, ("U", "U", "n", "1"))

#: Non-dimensional pitch inertia Iy+ = Iy Ix+ / Ix. The paper prints Ix+ = 10.00, Iz+ = 12.69
#: and Ixz+ = -8.36 (end of Sect. 2.1) but no Iy+; Sect. 2.4 gives Iy = 1308.5 mg mm^2. The
#: printed inertias are each 1.0014 times Sect. 2.4's values over 0.5 rho U^2 S_t c t_w^2
#: (``reference_scales``; a rounded flight datum behind Ref. [8]), so Iy is put into the
#: paper's own non-dimensionalisation through the printed Ix+: Iy+ = 19.895.
IY_PLUS: float = FLIGHT_DATA["Iy"] / FLIGHT_DATA["Ix"] * INERTIAS_SECT21["Ix_plus"]


_PARAM_TEXT = {
    "m_plus": "non-dimensional mass m/(0.5 rho U S_t t_w) (Sect. 2.1)",
    "Iy_plus": "non-dimensional pitch inertia, Iy of Sect. 2.4 scaled as the printed Ix+",
    "g_plus": "non-dimensional gravity g t_w/U (Sect. 2.1; -A[1,4] of Sect. 3.5)",
}
_FORCE = {"X": "x-force", "Z": "z-force", "M": "pitch moment"}


def parameter_description(name: str) -> str:
    """Description of a longitudinal model parameter (``Iy_plus``, ``Xu_plus``, ...)."""
    if name in _PARAM_TEXT:
        return _PARAM_TEXT[name]
    force, rest = name[0], name[1:-len("_plus")]
    if rest.startswith("_"):
        return f"control derivative of the {_FORCE[force]} w.r.t. delta{rest} (from B, Sect. 3.5)"
    return f"stability derivative of the {_FORCE[force]} w.r.t. delta {rest}+ (from A, Sect. 3.5)"
