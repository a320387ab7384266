"""Check family: the Model Exchange interface of an FMU (``dronefly check``).

``model-exchange``, ``check(ctx) -> detail`` for FMI 2.0 and 3.0 alike, the family's first:

* the event iteration of initialization terminates: after fmi2ExitInitializationMode,
  fmi2NewDiscreteStates (FMI 3.0: fmi3UpdateDiscreteStates) stops asking for another iteration
  within :data:`MAX_EVENT_ITERATIONS` (FMI 2.0 3.2.3, FMI 3.0 chapter 3: the event iteration
  must converge);
* the calling sequence of Model Exchange's state machine runs to the stop time under FMPy's
  Model Exchange simulation (its CVODE solver and event handling: state and time events,
  terminateSimulation), with finite outputs (non-finite: a warning).

The runtime checks run through Model Exchange too (``me:call-sequence``, ``me:start-values``,
``me:dependencies``, ``me:reset``, ``me:two-instances``, ``me:state``): the functions of
:mod:`.runtime`, their instances driven by :class:`..cosim.exchange.MEStepper`. They are not
run when this check fails.
"""

from __future__ import annotations

import numpy as np
import fmpy

from ..cosim.exchange import MAX_EVENT_ITERATIONS, EventIterationError
from .driver import Context, initialize
from .rules import CheckFailed, CheckSkipped

__all__ = ["MAX_EVENT_ITERATIONS", "check_model_exchange"]


def _event_iterations(ctx: Context) -> int:
    """Iterations of the event update after initialization until no new one is needed (or the
    FMU asks to terminate), through the Model Exchange instance's own loop."""
    with ctx.instantiate("me-check") as inst:
        try:
            initialize(ctx, inst)
        except EventIterationError:
            raise CheckFailed(f"the event iteration of initialization did not terminate in "
                              f"{MAX_EVENT_ITERATIONS} iterations") from None
        ctx.event(call=f"{ctx.fmi}Terminate()")
        inst.slave.terminate()
        return inst.slave.iterations


def check_model_exchange(ctx: Context) -> str:
    md = ctx.fmu.model_description3 or ctx.fmu.model_description
    if md.modelExchange is None:
        raise CheckSkipped("no Model Exchange interface")
    iterations = _event_iterations(ctx)
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
