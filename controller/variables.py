"""The variable table of the controller FMUs, for either axis, with or without feedthrough.

Inputs (the measured state), outputs (the controls, ``saturated``), the gains ``K[i,j]`` and
``KI[i,j]``, ``n``, ``U``, the limit, ``sensing_delay`` and ``sample_period``; and the
ModelStructure each output declares. Shipped inside the controller FMUs.
"""

from __future__ import annotations

from typing import Callable

from ..models.axes import Axis
from ..fmi import Var
from ..models.lateral_interface import N_HZ, U_M_PER_S
from ..models.feedback import U_MAX_LINEAR_RANGE, Gains, gain_name, integral_gain_name

__all__ = ["LAW_PARAMETERS", "TIMING", "all_gains", "all_integral_gains", "controller_variables"]

#: the parameters of the law besides the gains, in the order the slave reads them
LAW_PARAMETERS = ("n", "U", "limit_enabled", "u_max")
#: when the controller samples and how late its samples take effect [s]
TIMING = ("sensing_delay", "sample_period")

_TIMING_TEXT = (
    "the control computed from the state sampled at t_k takes effect at t_k + sensing_delay "
    "and is held until the next one does; before the first, the equilibrium (x = 0). Outputs "
    "change only at communication points: an effect inside a communication step is seen at "
    "the next one, so a delay that is not a whole number of steps is seen longer (logged "
    "once as a warning)")


def _row(axis: Axis, i: int, name: Callable[[int, int], str] = gain_name) -> tuple[str, ...]:
    """The names of row ``i`` (0-based) of K (or, with ``name``, of KI)."""
    return tuple(name(i, j) for j in range(len(axis.state_names)))


def all_gains(axis: Axis) -> tuple[str, ...]:
    """``K[1,1]`` ... row by row."""
    return tuple(g for i in range(len(axis.control_names)) for g in _row(axis, i))


def all_integral_gains(axis: Axis) -> tuple[str, ...]:
    """``KI[1,1]`` ... row by row."""
    return tuple(g for i in range(len(axis.control_names))
                 for g in _row(axis, i, integral_gain_name))


def _timing(delayed: bool) -> list[Var]:
    if delayed:
        delay = Var("sensing_delay", "parameter", "tunable",
                    f"sensing latency, > 0 (default one wing beat, 1/n); {_TIMING_TEXT}", "s",
                    "ms", start=1.0 / N_HZ)
    else:
        delay = Var("sensing_delay", "parameter", "tunable",
                    f"sensing latency, >= 0 (default 0: none); {_TIMING_TEXT}", "s", "ms",
                    start=0.0)
    period = Var("sample_period", "parameter", "tunable",
                 "period of the controller's sample instants t_k = t_start + k sample_period; "
                 "0 (default): sample at every communication point. Inputs are constant over "
                 "a communication step (co-simulation), so an instant inside a step samples the "
                 "input set at its start (logged once as a warning when a period that is not "
                 "a whole number of steps puts one there)", "s", "ms", start=0.0)
    return [delay, period]


def controller_variables(axis: Axis, K: Gains, sources: tuple[str, ...],
                         delayed: bool = False) -> tuple[Var, ...]:
    """The variables of one controller FMU.

    Parameters
    ----------
    axis : Axis
        Names, units and non-dimensionalisation of the state and controls.
    K : nested tuple
        Default gains (controls x states); ``sources[i]`` says where row i comes from.
    delayed : bool
        The variant without direct feedthrough (``sensing_delay`` > 0 required): the outputs
        depend on no input, at initialization on nothing (they are 0: the equilibrium).
        Otherwise the outputs declare the inputs conservatively (feedthrough at delay 0).
        At initialization (t = t_start, a sample instant; z = 0) the outputs depend on the
        inputs, the gains K of their row, n, U, the limit and sensing_delay (> 0: u = 0), not
        on KI or sample_period.
    """
    states = axis.state_names
    limit = LAW_PARAMETERS
    out: list[Var] = []
    for name, text, nondim, (unit, disp) in zip(states, axis.state_descriptions,
                                                axis.nondimensional, axis.state_units):
        out.append(Var(name, "input", "continuous", f"measured {text}; {nondim}", unit, disp,
                       start=0.0))
    if delayed:
        how = ("no direct feedthrough: the outputs depend on inputs sampled at least "
               "sensing_delay > 0 earlier")
        deps: tuple[str, ...] = ()
    else:
        how = ("direct feedthrough declared conservatively: exact when sensing_delay = 0, "
               "none when it is > 0 (a tunable parameter cannot change the ModelStructure)")
        deps = states
    for i, (name, text) in enumerate(zip(axis.control_names, axis.control_descriptions)):
        init = () if delayed else (*states, *_row(axis, i), *limit, "sensing_delay")
        out.append(Var(name, "output", "continuous",
                       f"{text}: row {i + 1} of u = K x+_s + KI z (x+_s the sensed state, z its "
                       f"integral over t+ = t n), limited to +/-u_max if limit_enabled; {how}",
                       *axis.control_unit, initial="calculated", dependencies=deps,
                       initial_dependencies=init))
    init = () if delayed else (*states, *all_gains(axis), *limit, "sensing_delay")
    out.append(Var("saturated", "output", "discrete",
                   "true while any control output is limited to +/-u_max", None,
                   initial="calculated", type="Boolean", dependencies=deps,
                   initial_dependencies=init))
    for i, row in enumerate(K):
        for j, k in enumerate(row):
            out.append(Var(gain_name(i, j), "parameter", "tunable",
                           f"gain of {axis.control_names[i]} [rad] on x+{j + 1} ({states[j]}, "
                           f"non-dimensional); {sources[i]}", "1", start=k))
    out.append(Var("n", "parameter", "tunable",
                   "wing-beat frequency; reference time t_w = 1/n (Sect. 2.4)", "Hz", start=N_HZ))
    out.append(Var("U", "parameter", "tunable",
                   "reference velocity U = 2 Phi n r2 (Sect. 2.4)", "m/s", start=U_M_PER_S))
    out.append(Var("limit_enabled", "parameter", "tunable",
                   "limit every control to [-u_max, u_max] (default false: no limit)", None,
                   start=False, type="Boolean"))
    out.append(Var("u_max", "parameter", "tunable",
                   "actuator limit, used if limit_enabled; the linear range of the control "
                   "derivatives ends at 0.4 rad (Sect. 3.1)", "rad", "deg",
                   start=U_MAX_LINEAR_RANGE))
    # appended after the proportional law's variables, whose value references are therefore
    # those of a controller without integral gains and timing parameters
    for i, control in enumerate(axis.control_names):
        for j, state in enumerate(states):
            out.append(Var(integral_gain_name(i, j), "parameter", "tunable",
                           f"integral gain of {control} [rad] on z{j + 1}, the integral of "
                           f"x+{j + 1} ({state}) over t+ = t n from t_start; default 0",
                           "1", start=0.0))
    out.extend(_timing(delayed))
    return tuple(out)
