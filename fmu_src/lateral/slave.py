"""FMU ``DroneFlyLateral``: the lateral plant of Eq. (9) as an FMI 2.0 CS slave.

The wrapper (:class:`~dronefly.fmu_src.linear_slave.LinearPlantSlave`, shared with the longitudinal
plant) maps FMI variables onto :mod:`dronefly.models.lateral_dynamics`; all numbers come from
there.
Outputs are the paper's disturbance states made dimensional with U and t_w.
"""

from __future__ import annotations

from ...models.lateral_interface import LATERAL, N_HZ, U_M_PER_S, parameter_description
from ..linear_slave import LinearPlantSlave, plant_variables
from ...models.lateral_dynamics import LateralModel, LateralParameters, default_parameters

__all__ = ["DroneFlyLateral"]

def _matrix_dependencies(row: int, col: int, controls: bool) -> tuple[str, ...]:
    """Knowns that A1[row, col] (or B1) depends on, by Eqs. (10)-(11)."""
    if row == 3:
        return ()
    if controls:
        suffix = "_" + ("Phi_a", "alpha_1a", "alpha_2a")[col] + "_plus"
    elif col == 3:
        return ("g_plus",) if row == 0 else ()
    else:
        suffix = "vpr"[col] + "_plus"
    if row == 0:
        return ("m_plus", "Y" + suffix)
    return ("Ix_plus", "Iz_plus", "Ixz_plus", "L" + suffix, "N" + suffix)


class DroneFlyLateral(LinearPlantSlave):
    """Linearized lateral motion of the hovering model drone fly (Zhang & Sun)."""

    MODEL_NAME = "DroneFlyLateral"
    MODEL_DESCRIPTION = (
        "Linearized lateral dynamics of the hovering model drone fly, Eq. (9) of "
        "Zhang & Sun, 'Stabilization control of a hovering model insect: lateral motion'; "
        "exact zero-order-hold integration")
    VARIABLES = plant_variables(LATERAL, default_parameters(), parameter_description, _matrix_dependencies,
                                N_HZ, U_M_PER_S, ("system matrix A1 of Eq. (9)",
                                                  "control matrix B1 of Eq. (9)"))
    DEFAULT_EXPERIMENT = (0.0, 30.0 / N_HZ, 0.1 / N_HZ)  # 30 wing beats: open loop diverges

    AXIS = LATERAL
    PARAMETERS = LateralParameters
    MODEL = LateralModel
