"""FMU ``DroneFlyLongitudinal``: the longitudinal plant of Sect. 3.5 as an FMI 2.0 CS slave.

The wrapper (:class:`~dronefly.fmu_src.linear_slave.LinearPlantSlave`, shared with the lateral
plant) maps FMI variables onto :mod:`dronefly.models.longitudinal_dynamics`; all numbers come
from there.
Outputs are the disturbance states made dimensional with U and t_w.
"""

from __future__ import annotations

from ...models.lateral_interface import N_HZ, U_M_PER_S
from ..linear_slave import LinearPlantSlave, plant_variables
from ...models.longitudinal_interface import LONGITUDINAL, parameter_description
from ...models.longitudinal_dynamics import (LongitudinalModel, LongitudinalParameters,
    default_parameters, parameter_dependencies)

__all__ = ["DroneFlyLongitudinal"]


class DroneFlyLongitudinal(LinearPlantSlave):
    """Linearized longitudinal motion of the hovering model drone fly (Zhang & Sun, Sect. 3.5)."""

    MODEL_NAME = "DroneFlyLongitudinal"
    MODEL_DESCRIPTION = (
        "Linearized longitudinal dynamics of the hovering model drone fly, A and B of Sect. 3.5 "
        "of Zhang & Sun, 'Stabilization control of a hovering model insect: lateral motion'; "
        "exact zero-order-hold integration")
    VARIABLES = plant_variables(LONGITUDINAL, default_parameters(), parameter_description,
                                parameter_dependencies, N_HZ, U_M_PER_S,
                                ("system matrix A of Sect. 3.5", "control matrix B of Sect. 3.5"))
    DEFAULT_EXPERIMENT = (0.0, 60.0 / N_HZ, 0.1 / N_HZ)  # 60 wing beats: open loop oscillates

    AXIS = LONGITUDINAL
    PARAMETERS = LongitudinalParameters
    MODEL = LongitudinalModel
