"""Quasi-steady blade-element aerodynamics of the flapping wings (Sect. 3.6, aerodynamic half).

:mod:`dronefly.models.quasisteady` is the model (kinematics, planform, blade elements, cycle
averages, trim); :mod:`dronefly.harness.aero.beside_paper` its derivatives, eigenvalues and controller beside
the paper's. An analysis package (numpy), not shipped in an FMU.
"""

from __future__ import annotations

from .beside_paper import (DerivativeRow, ParityReport, closed_loop, derivative_table, eigenvalues,
    linearity_scan, parity_report)
from ...models.quasisteady import (COEFFICIENT_SETS, CONTROLS, STATES, CoefficientSet,
    QuasiSteadyModel, Terms, Trim, WingGeometry)

__all__ = ["COEFFICIENT_SETS", "CONTROLS", "STATES", "CoefficientSet", "DerivativeRow",
           "ParityReport", "QuasiSteadyModel", "Terms", "Trim", "WingGeometry", "closed_loop",
           "derivative_table", "eigenvalues", "linearity_scan", "parity_report"]
