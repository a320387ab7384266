"""The averaged model itself: the periodic orbit of the wing-beat-resolved model, its
Floquet exponents beside the averaged model's eigenvalues and the paper's.

:mod:`dronefly.models.flapping` is the model, its periodic orbit and Floquet exponents
(:mod:`dronefly.models.flapping.orbit`; ``AXES``, ``averaged_exponents`` and
``averaged_monodromy`` are re-exported here); :mod:`dronefly.harness.flapping.floquet` the
report beside the averaged model's and the paper's eigenvalues,
:mod:`dronefly.harness.flapping.fmi_floquet` the same analysis through FMI (any FMU that can get
and set its state; ``dronefly floquet``). An analysis package (numpy), not shipped in an FMU.
:mod:`dronefly.harness.flapping.closed_loop` flies the paper's controller in the model,
:mod:`dronefly.harness.flapping.master_run` the same as a system of FMUs through the project's
master.
"""

from __future__ import annotations

from ...models.flapping import AXES, averaged_exponents, averaged_monodromy
from .floquet import FloquetReport, convergence, convergence_rows, floquet_report, readme_paragraph
from .closed_loop import ClosedLoopReport, closed_loop_report
from .fmi_floquet import FmiFloquet, FmiPeriodicMap, floquet_analysis, floquet_text, fmi_floquet
from .master_run import MasterReport, master_report, write_flapping_ssp
from .trim import FlappingTrim, flapping_trim

__all__ = ["AXES", "ClosedLoopReport", "FloquetReport", "FmiFloquet", "FmiPeriodicMap", "readme_paragraph",
           "closed_loop_report",
           "averaged_exponents", "averaged_monodromy", "convergence", "convergence_rows",
           "floquet_analysis", "floquet_report", "floquet_text", "fmi_floquet", "MasterReport",
           "master_report", "write_flapping_ssp", "FlappingTrim", "flapping_trim"]
