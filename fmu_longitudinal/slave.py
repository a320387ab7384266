"""FMU ``DroneFlyLongitudinal``: the longitudinal plant of Sect. 3.5 as an FMI 2.0 CS slave.

The wrapper (:class:`~dronefly.linear_slave.LinearPlantSlave`, shared with the lateral
plant) maps FMI variables onto :mod:`.model`; all numbers come from there.
Outputs are the disturbance states made dimensional with U and t_w.
"""

from __future__ import annotations

from ..lateral import N_HZ, U_M_PER_S
from ..linear_slave import LinearPlantSlave, plant_variables
from ..longitudinal import LONGITUDINAL
from .model import LongitudinalModel, LongitudinalParameters, default_parameters, \
    parameter_dependencies

__all__ = ["DroneFlyLongitudinal"]

_PARAM_TEXT = {
    "m_plus": "non-dimensional mass m/(0.5 rho U S_t t_w) (Sect. 2.1)",
    "Iy_plus": "non-dimensional pitch inertia, Iy of Sect. 2.4 scaled as the printed Ix+",
    "g_plus": "non-dimensional gravity g t_w/U (Sect. 2.1; -A[1,4] of Sect. 3.5)",
}
_FORCE = {"X": "x-force", "Z": "z-force", "M": "pitch moment"}


def _param_text(name: str) -> str:
    if name in _PARAM_TEXT:
        return _PARAM_TEXT[name]
    force, rest = name[0], name[1:-len("_plus")]
    if rest.startswith("_"):
        return f"control derivative of the {_FORCE[force]} w.r.t. delta{rest} (from B, Sect. 3.5)"
    return f"stability derivative of the {_FORCE[force]} w.r.t. delta {rest}+ (from A, Sect. 3.5)"


class DroneFlyLongitudinal(LinearPlantSlave):
    """Linearized longitudinal motion of the hovering model drone fly (Zhang & Sun, Sect. 3.5)."""

    MODEL_NAME = "DroneFlyLongitudinal"
    MODEL_DESCRIPTION = (
        "Linearized longitudinal dynamics of the hovering model drone fly, A and B of Sect. 3.5 "
        "of Zhang & Sun, 'Stabilization control of a hovering model insect: lateral motion'; "
        "exact zero-order-hold integration")
    VARIABLES = plant_variables(LONGITUDINAL, default_parameters(), _param_text,
                                parameter_dependencies, N_HZ, U_M_PER_S,
                                ("system matrix A of Sect. 3.5", "control matrix B of Sect. 3.5"))
    DEFAULT_EXPERIMENT = (0.0, 60.0 / N_HZ, 0.1 / N_HZ)  # 60 wing beats: open loop oscillates

    AXIS = LONGITUDINAL
    PARAMETERS = LongitudinalParameters
    MODEL = LongitudinalModel
