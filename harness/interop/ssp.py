"""The closed loop as an SSP 1.0 file.

``DroneFlyClosedLoop.ssp``
    SSP 1.0 archive: ``SystemStructure.ssd`` (components ``plant`` and ``controller``, their
    input/output connectors, the connections by name, a default experiment),
    ``resources/DroneFlyLateral.fmu``, ``resources/StateFeedback.fmu`` and the parameter
    values ``resources/plant.ssv`` and ``resources/controller.ssv``, each bound to its component
    (SSP 1.0 ParameterBinding; names are the FMU's variable names). fmpy's ``simulate_ssp``
    does not apply an SSD's bindings itself; it takes one parameter set with hierarchical
    names (``plant.delta_gamma_start``, ``controller.K[1,1]``), so :func:`ssp_parameter_set`
    reads the bound sets with the project's one SSP reader (:meth:`System.from_ssp`) and
    prefixes each name with its component's name. libcosim (``CosimExecution.from_ssp_file``)
    applies component bindings itself and runs the same file; a system-level binding it would
    ignore.

``build/fmi3/DroneFlyClosedLoop.ssp`` is the same system of the FMI 3.0 FMUs (SSD and SSV files
alike: SSP 1.0 binds the FMI 3.0 array ``K`` by its elements ``K[i,j]``, which
``dronefly cosim --system`` resolves). fmpy's ``simulate_ssp`` cannot run it (it instantiates
every FMU as FMI 2.0), so :func:`run_ssp` refuses it; docs/fmi3.md says what Ecos does with it.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Mapping

import numpy as np
from fmpy.ssp.simulation import simulate_ssp
from fmpy.ssp.ssd import Parameter, ParameterSet

from ..builder.closedloop import CLOSED_LOOP, plant_md_scales
from ...models.lateral_interface import STATE_NAMES
from ..cosim.fmu3 import read_view
from ..cosim.master import CoSimError
from ..cosim.system import System, SystemSpecError
from ..cosim.identification import Verdict, unit_start_values, verdict_of

__all__ = ["PLANT_INSTANCE", "ClosedLoopSSP", "run_ssp", "ssp_parameter_set", "ssp_verdict"]

#: the closed loop's plant component (docs: ``plant`` and ``controller``)
PLANT_INSTANCE = "plant"

#: the SSV type of a value as :meth:`System.from_ssp` reads it
_SSV_TYPES = {float: "Real", int: "Integer", bool: "Boolean", str: "String"}


class ClosedLoopSSP:
    """An SSP read once through the project's one SSP reader (:meth:`System.from_ssp`, which
    validates the SSD and the SSV files against the SSP 1.0 schema and removes each binding's
    prefix), with the model description of each component's FMU (FMI 3.0 ones as the
    harness's view). What fmpy's and Ecos' runs of it need is derived from this one read."""

    def __init__(self, ssp: str | Path) -> None:
        self.path = Path(ssp)
        try:
            self.system = System.from_ssp(ssp)
        except SystemSpecError as e:
            raise CoSimError(str(e)) from e
        self.mds = {inst: read_view(path) for inst, path in self.system.fmus.items()}

    def md(self, instance: str) -> Any:
        """The model description of the component ``instance``'s FMU."""
        if instance not in self.mds:
            raise CoSimError(f"the SSP {str(self.path)!r} has no component {instance!r} "
                             f"(components: {', '.join(self.mds)})")
        return self.mds[instance]

    def parameter_set(self) -> ParameterSet:
        """One fmpy ``ParameterSet`` of every component binding, named
        ``<component>.<variable>`` as fmpy's ``simulate_ssp`` expects."""
        merged = ParameterSet(name=CLOSED_LOOP)
        for inst, values in self.system.parameters.items():
            for name, value in values.items():
                merged.parameters.append(Parameter(name=f"{inst}.{name}",
                                                   type=_SSV_TYPES[type(value)], value=value))
        return merged

    def plant(self, instance: str = PLANT_INSTANCE) -> tuple[float, np.ndarray, float]:
        """The plant component's n [Hz], its state scales and the default step (0.1 wing
        beat, s)."""
        n, scale = plant_md_scales(self.md(instance))
        return n, scale, 0.1 / n

    def stop_s(self) -> float:
        """The SSD's DefaultExperiment stop time, s."""
        if self.system.stop_s is None:
            raise CoSimError(f"the SSP {str(self.path)!r} gives no DefaultExperiment stopTime")
        return self.system.stop_s


def ssp_parameter_set(ssp: str | Path) -> ParameterSet:
    """:meth:`ClosedLoopSSP.parameter_set` of the SSP at ``ssp``."""
    return ClosedLoopSSP(ssp).parameter_set()


def run_ssp(ssp: str | Path | ClosedLoopSSP, *, step_s: float | None = None,
            stop_s: float | None = None,
            overrides: Mapping[str, float] | None = None) -> np.ndarray:
    """Simulate the SSP with fmpy's ``simulate_ssp`` and the SSP's own parameter values.

    ``ssp``: the file, or a :class:`ClosedLoopSSP` already read. ``overrides`` replace bound
    values by hierarchical name (e.g. ``plant.delta_v_start``). Default step: 0.1 wing beat;
    default stop: the SSD's DefaultExperiment.

    fmpy's SSP master (read from fmpy/ssp/simulation.py, and measured): connectors start at 0;
    in every step each component gets its inputs from the connector values, steps, and its
    outputs are read; then all connections are applied. The row stamped t_j therefore holds
    the values *after* the step, at t_(j+1), and the plant's control over step k is
    u_k = K x_(k-1) for k >= 2, with u_0 = u_1 = 0 (the controller sees 0 in its first step).
    """

    read = ssp if isinstance(ssp, ClosedLoopSSP) else ClosedLoopSSP(ssp)
    fmi3 = [read.system.fmus[inst].name for inst, md in read.mds.items()
            if str(md.fmiVersion).startswith("3")]
    if fmi3:  # fmpy/ssp/simulation.py instantiates every FMU as an FMU2Slave
        raise CoSimError(f"fmpy's simulate_ssp runs FMI 2.0 FMUs only, and {str(read.path)!r} "
                         f"holds FMI 3.0 ones ({', '.join(fmi3)}): run it with dronefly cosim "
                         "--system")
    pset = read.parameter_set()
    for name, value in (overrides or {}).items():
        hits = [p for p in pset.parameters if p.name == name]
        if not hits:
            raise CoSimError(f"the SSP binds no parameter {name!r}")
        for p in hits:
            p.value = repr(float(value))
    step = read.plant()[2] if step_s is None else step_s
    stop = read.stop_s() if stop_s is None else stop_s
    # fmpy steps while time < stop; stop half a step early so that float accumulation of
    # the time cannot add one step
    return simulate_ssp(str(read.path), start_time=0.0, stop_time=stop - 0.5 * step,
                        step_size=step, parameter_set=pset)


def ssp_verdict(ssp: str | Path, n_steps: int = 20) -> Verdict:
    """Identify and classify the loop as fmpy's SSP simulation runs it.

    One run per unit initial state x+_0 = e_i (the SSP's gains). By the master described in
    :func:`run_ssp` the rows hold x_1, x_2, ... and the controller's first input is 0, so each
    run is [0; x_1; x_2; ...] in the delayed (Jacobi) form of ``harness.cosim.identification.identify``.

    Raises
    ------
    CrossCheckError
        The fit's residual exceeds :data:`~dronefly.harness.cosim.identification.FIT_RESIDUAL_TOL`
        (the runs are not the loop identified, e.g. a controller with a sensing delay).
    """
    read = ClosedLoopSSP(ssp)
    n, scale, d_step = read.plant()
    runs = []
    for start in unit_start_values(scale, prefix=f"{PLANT_INSTANCE}."):
        res = run_ssp(read, stop_s=(n_steps + 0.5) * d_step, overrides=start)
        xs = np.column_stack([res[f"{PLANT_INSTANCE}.{s}"] for s in STATE_NAMES]) / scale
        runs.append(np.vstack([np.zeros(len(STATE_NAMES)), xs]))
    return verdict_of(runs, d_step * n, delay=True, where=f"fmpy SSP {ssp}")
