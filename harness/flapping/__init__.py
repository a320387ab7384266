"""The averaged model itself (issue 30): the periodic orbit of the wing-beat-resolved model, its
Floquet exponents beside the averaged model's eigenvalues and the paper's.

:mod:`dronefly.models.flapping` is the model; :mod:`dronefly.harness.flapping.floquet` the
analysis. An analysis package (numpy), not shipped in an FMU.
"""

from __future__ import annotations

from .floquet import (AXES, FloquetReport, answer, averaged_exponents, averaged_monodromy,
                      convergence, convergence_rows, floquet_report)

__all__ = ["AXES", "FloquetReport", "answer", "averaged_exponents", "averaged_monodromy",
           "convergence", "convergence_rows", "floquet_report"]
