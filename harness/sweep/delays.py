"""The delay axes of ``dronefly sweep`` (``--delays``, ``--sample-periods``): the loop's verdict.

A sweep whose cases set the controller's ``sensing_delay`` or ``sample_period`` (any value
other than 0; see :mod:`dronefly.controller.timing`) gets the columns ``DELAY_COLUMNS`` on
every row. Per configuration (gains, step, delay, sample period, master, ``--set`` values) the
closed loop's verdict is computed once, with the delay states in it:

``stability``, ``stability_rate``
    Model (b) (:func:`dronefly.harness.latency.sampled.sampled_rates`) for the plant FMU's A and
    B (its calculated parameters with the case's values set), the gains and the FMU's timing,
    where the sample instants lie on the communication grid
    (:meth:`dronefly.harness.latency.grid.GridTiming.model_b`); otherwise the exact periodic
    loop on the grid (:func:`dronefly.harness.latency.grid.grid_monodromy`, without
    integral action). ``stable``/``neutral``/``unstable`` with the harness's tolerance of 1e-3
    per wing beat on the dominant rate (per wing beat).
``stability_identified``, ``stability_deviation``
    The cross-check where model (b) applies: four co-simulations of the real FMUs from the unit
    initial states, the augmented state (delay line and integral) rebuilt from the record, the
    transition matrix fitted (:func:`dronefly.harness.latency.identify.identify_delayed`): its
    verdict, and how far its dominant rate is from model (b)'s, per wing beat (the dominant
    rate decides the verdict; the small eigenvalues of a long delay line are ill-conditioned,
    so the fit moves them by more while its residual stays at rounding).

Empty cells: no model (a plant without A[i,j]/B[i,j] or not lateral, integral action off the
grid, more than ``MAX_LAG`` samples of delay) or no identification (its runs failed).
"""

from __future__ import annotations

import math
from collections import defaultdict
from typing import Any, Sequence

import numpy as np

from ...models.feedback import gain_name, integral_gain_name
from ...models.lateral_interface import CONTROL_NAMES, STATE_NAMES, plant_scales
from ..cosim.calculated import plant_matrices
from ..cosim.identification import classify, rates_from_transition, unit_start_values
from ..latency.grid import GridTiming, grid_monodromy, timing_params
from ..latency.identify import identify_delayed
from ..latency.loop import FeedbackLoop, LatencyInputError
from ..latency.sampled import delay_split, sampled_rates
from .cases import Case, SweepInputError
from .results import DELAY_COLUMNS
from .worker import FmuRef, close_all, loop_for

__all__ = ["DELAY_COLUMNS", "MAX_LAG", "delay_results", "delay_summary", "is_delay_sweep",
           "loop_verdict"]

#: Delays of more samples than this get no model (its augmented state grows with them).
MAX_LAG = 100
_TIMING = ("sensing_delay", "sample_period")


def is_delay_sweep(cases: Sequence[Case]) -> bool:
    """Whether any case sets a sensing delay or a sample period."""
    return any(c.delay_wb or c.sample_period_wb for c in cases)


def _plant_model(pair: Any, values: dict[str, Any]) -> tuple[np.ndarray, np.ndarray] | None:
    """A (4x4, per wing beat) and B (4x3) as the plant FMU computes them with ``values`` set."""

    if list(pair.states) != list(STATE_NAMES) or list(pair.controls) != list(CONTROL_NAMES):
        return None
    return plant_matrices(pair.plant, len(STATE_NAMES), len(CONTROL_NAMES), values)


def _integral_gains(pair: Any, values: dict[str, Any]) -> np.ndarray:
    start = {**pair.controller.start_values(), **values}
    return np.array([[float(start.get(integral_gain_name(i, j)) or 0.0) for j in range(4)]
                     for i in range(3)])


def loop_verdict(loop: Any, timing: GridTiming) -> tuple[str, float]:
    """(verdict, dominant rate per wing beat) of a
    :class:`~dronefly.harness.latency.loop.FeedbackLoop` under ``timing``; ("", nan) where no
    model applies (see the module text)."""

    b = timing.model_b()
    if b is not None:
        if delay_split(b[1], b[0])[0] > MAX_LAG:
            return "", math.nan
        rates = sampled_rates(loop, *b)
    else:
        size = 4 * (math.ceil((timing.tau_eff + timing.Ts) / timing.h) + 2)
        if loop.integrated or size ** 3 * (timing.period_steps or 1) > 2e9:
            return "", math.nan  # no integral action on the grid; or a few seconds or more
        grid = grid_monodromy(loop.A, loop.B, loop.K, timing)
        if grid is None:
            return "", math.nan
        rates = rates_from_transition(*grid)
    return classify(rates), float(np.max(rates.real))


def _identify(pair: Any, insts: tuple, case: Case, loop: Any, timing: GridTiming,
              scale: np.ndarray) -> tuple[str, float]:
    """Verdict and dominant rate (its deviation from model (b)'s, per wing beat) identified
    from four co-simulated runs."""

    Ts, tau = timing.model_b()
    d, eps = delay_split(tau, Ts)
    m = int(round(Ts / case.step_wb))
    samples = 2 * (d + 2) + 10
    params = {**dict(case.controller_values), **timing_params(case, scale[1])}
    params |= {gain_name(i, j): float(loop.K[i, j]) for i in range(3) for j in range(4)}
    params |= {integral_gain_name(i, j): float(loop.KI[i, j]) for i in range(3) for j in range(4)
               if loop.KI[i, j] != 0.0}
    runs = []
    for unit in unit_start_values(scale):
        start = {**dict(case.plant_values), **unit}
        r = pair.run(case.step_wb / scale[1], samples * m, master=case.master, plant_start=start,
                     controller_params=params, instances=insts,
                     u_source0=[0.0] * 4 if timing.jacobi else None)
        if not r.complete:
            return "", math.nan
        runs.append(r.signals[::m, :4] / scale)
    try:
        ident = identify_delayed(runs, loop, Ts, tau)
    except LatencyInputError:
        return "", math.nan
    fit, exact = (rates_from_transition(M, Ts) for M in (ident.transition, ident.exact))
    return classify(fit), abs(float(np.max(fit.real)) - float(np.max(exact.real)))


def delay_results(cases: Sequence[Case], refs: tuple) -> dict[str, dict[str, Any]]:
    """The ``DELAY_COLUMNS`` values but the case's own two, by case key (empty: no delay axes).

    Raises
    ------
    SweepInputError
        The delay axes with ``--system``, or with ``--set controller.sensing_delay`` /
        ``sample_period`` (one of the two ways, not both), or with a controller that lacks
        the two parameters or does not default them to 0 (``StateFeedbackDelayed``).
    """
    if not is_delay_sweep(cases):
        return {}
    try:
        return _delay_results(cases, refs)
    finally:
        close_all()  # this process's FMUs (a pool's workers open their own; run_here again)


def _delay_results(cases: Sequence[Case], refs: tuple) -> dict[str, dict[str, Any]]:

    if not isinstance(refs[0], FmuRef):
        raise SweepInputError("--delays/--sample-periods need the plant/controller pair, not "
                              "--system (set a system's controller timing with --set "
                              "instance.sensing_delay=S)")
    for c in cases:
        both = sorted(set(_TIMING) & {k for k, _ in c.controller_values})
        if both:
            raise SweepInputError(f"--set controller.{both[0]} and --delays/--sample-periods "
                                  "both set the controller's timing: use one")
    pair, p, c, _ = loop_for(refs, (None, None))
    ctrl = pair.controller
    for name in _TIMING:
        if name not in ctrl.variables:
            raise SweepInputError(f"--delays/--sample-periods: the controller {ctrl.name!r} has "
                                  f"no parameter {name!r}")
        if float(ctrl.start_values().get(name) or 0.0) != 0.0:  # a case of 0 would not set it
            raise SweepInputError(f"--delays/--sample-periods need a controller whose {name} "
                                  f"defaults to 0; {ctrl.name!r} has "
                                  f"{ctrl.start_values()[name]!r} s (use StateFeedback)")
    groups: dict[tuple, dict[str, Any]] = {}
    plants: dict[tuple, Any] = {}
    out = {}
    for case in cases:
        g = (case.K, case.step_wb, case.delay_wb, case.sample_period_wb, case.master,
             case.plant_values, case.controller_values)
        if g not in groups:
            if case.plant_values not in plants:
                plants[case.plant_values] = _plant_model(pair, dict(case.plant_values))
            scale = np.array(plant_scales({**pair.plant.start_values(),
                                           **dict(case.plant_values)}))
            n = scale[1]
            res: dict[str, Any] = {"delay_ms": 1e3 * case.delay_wb / n,
                                   "sample_period_ms": 1e3 * case.sample_period_wb / n,
                                   "stability": "", "stability_rate": math.nan,
                                   "stability_identified": "", "stability_deviation": math.nan}
            timing = GridTiming(case.step_wb, case.delay_wb, case.sample_period_wb,
                            case.master == "jacobi")
            if plants[case.plant_values] is not None:
                A, B = plants[case.plant_values]
                loop = FeedbackLoop(A, B, np.array(case.K),
                                    _integral_gains(pair, dict(case.controller_values)))
                res["stability"], res["stability_rate"] = loop_verdict(loop, timing)
                if res["stability"] and timing.model_b() is not None:
                    res["stability_identified"], res["stability_deviation"] = _identify(
                        pair, (p, c), case, loop, timing, scale)
            groups[g] = res
        out[case.key] = groups[g]
    return out


def delay_summary(rows: Sequence[dict[str, str]]) -> dict[str, Any]:
    """Per gains, step, delay, sample period and scale: the loop's verdicts and the share of
    cases within the bounds; and how many identifications disagree with the model."""
    groups: dict[tuple, list[dict[str, str]]] = defaultdict(list)
    for r in rows:
        groups[(r["gains"], r["step_wb"], r["delay_wb"], r["sample_period_wb"],
                r["scale"])].append(r)
    out = []
    for (gains, h, d, T, s), rs in groups.items():
        r0 = rs[0]
        rate, dev = r0["stability_rate"], r0["stability_deviation"]
        out.append({"gains": gains, "step_wb": float(h), "delay_wb": float(d),
                    "sample_period_wb": float(T), "scale": float(s),
                    "delay_ms": float(r0["delay_ms"]),
                    "sample_period_ms": float(r0["sample_period_ms"]),
                    "stability": r0["stability"] or None,
                    "stability_rate": float(rate) if rate else None,
                    "stability_identified": r0["stability_identified"] or None,
                    "stability_deviation": float(dev) if dev else None,
                    "cases": len(rs),
                    "fraction_within_bounds": sum(r["verdict"] == "within" for r in rs) / len(rs),
                    "peak_u": max((float(r["peak_u"]) for r in rs if r["peak_u"]),
                                  default=None)})
    disagree = sum(1 for g in out if g["stability_identified"]
                   and g["stability_identified"] != g["stability"])
    return {"delay_groups": out, "stability_disagreements": disagree}
