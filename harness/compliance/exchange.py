"""Check family: the Model Exchange interface of an FMU that has one besides Co-Simulation.

``model-exchange``, ``check(ctx) -> detail`` for FMI 2.0 and 3.0 alike:

* the event iteration of initialization terminates: after fmi2ExitInitializationMode,
  fmi2NewDiscreteStates (FMI 3.0: fmi3UpdateDiscreteStates) stops asking for another iteration
  within :data:`MAX_EVENT_ITERATIONS` (FMI 2.0 3.2.3, FMI 3.0 chapter 3: the event iteration
  must converge);
* the calling sequence of Model Exchange's state machine runs to the stop time under FMPy's
  Model Exchange simulation (its CVODE solver and event handling: state and time events,
  terminateSimulation), with finite outputs (non-finite: a warning).

Not yet through Model Exchange: start values, dependencies, reset, FMU state, two instances;
an FMU with Model Exchange only is not checked (docs/compliance.md).
"""

from __future__ import annotations

import numpy as np
import fmpy
from fmpy.fmi2 import FMU2Model
from fmpy.fmi3 import FMU3Model

from .driver import Context
from .rules import CheckSkipped, require

__all__ = ["MAX_EVENT_ITERATIONS", "check_model_exchange"]

#: event iterations at one time instant after which the iteration is taken not to terminate
MAX_EVENT_ITERATIONS = 1000


def _event_iterations(ctx: Context) -> int:
    """Iterations of the event update after initialization until no new one is needed (or the
    FMU asks to terminate); ``MAX_EVENT_ITERATIONS + 1``: it never ended."""
    md = ctx.fmu.model_description3 or ctx.fmu.model_description
    ident = md.modelExchange.modelIdentifier
    if ctx.fmu.fmi_version == 2:
        model = FMU2Model(guid=md.guid, unzipDirectory=ctx.fmu._unzipdir, modelIdentifier=ident,
                          instanceName="me-check")
        instantiate, update = "fmi2Instantiate(fmi2ModelExchange)", "fmi2NewDiscreteStates"

        def initialize() -> None:
            model.setupExperiment(startTime=ctx.start, stopTime=ctx.stop)
            model.enterInitializationMode()

        next_event = model.newDiscreteStates
    else:
        model = FMU3Model(guid=md.instantiationToken, unzipDirectory=ctx.fmu._unzipdir,
                          modelIdentifier=ident, instanceName="me-check")
        instantiate, update = "fmi3InstantiateModelExchange()", "fmi3UpdateDiscreteStates"

        def initialize() -> None:
            model.enterInitializationMode(startTime=ctx.start, stopTime=ctx.stop)

        next_event = model.updateDiscreteStates
    ctx.event(call=instantiate)
    model.instantiate()
    try:
        initialize()
        model.exitInitializationMode()
        for k in range(1, MAX_EVENT_ITERATIONS + 1):
            ctx.event(call=f"{update}() (iteration {k})")
            needed, terminate = next_event()[:2]
            if not needed or terminate:
                model.terminate()
                return k
        return MAX_EVENT_ITERATIONS + 1
    finally:
        model.freeInstance()
        model.freeLibrary()


def check_model_exchange(ctx: Context) -> str:
    md = ctx.fmu.model_description3 or ctx.fmu.model_description
    if md.modelExchange is None:
        raise CheckSkipped("no Model Exchange interface")
    iterations = _event_iterations(ctx)
    require(iterations <= MAX_EVENT_ITERATIONS,
            f"the event iteration of initialization did not terminate in "
            f"{MAX_EVENT_ITERATIONS} iterations")
    outputs = [v.name for v in ctx.outputs if v.kind == "Real"]
    ctx.event(call=f"fmpy.simulate_fmu(fmi_type='ModelExchange', solver='CVode', "
                   f"stop_time={ctx.stop!r})")
    result = fmpy.simulate_fmu(str(ctx.fmu._unzipdir), fmi_type="ModelExchange", solver="CVode",
                               start_time=ctx.start, stop_time=ctx.stop,
                               # at most 100 rows: the run is checked, not recorded
                               output_interval=max(ctx.step, (ctx.stop - ctx.start) / 100),
                               output=outputs or None,
                               model_description=ctx.fmu.model_description3
                               or ctx.fmu.model_description, validate=False)
    names = [n for n in result.dtype.names[1:] if n in outputs]
    bad = [n for n in names if not np.isfinite(np.asarray(result[n], float)).all()]
    if bad:
        ctx.warnings.append(f"non-finite outputs through Model Exchange: {', '.join(bad[:5])}")
    end = float(result["time"][-1])
    return (f"event iteration at initialization: {iterations} iteration(s); FMPy's Model "
            f"Exchange simulation (CVODE) to t = {end:.6g} s, {len(result)} rows, "
            f"{len(names)} output(s)")
