"""FMU ``StateFeedback``: the state feedback u = K x+ of Eq. (22) as an FMI 2.0 CS slave.

A block without internal state and with direct feedthrough: the outputs are
recomputed from the current inputs and parameters whenever an output is read
after a value was set (no doStep needed). All numbers come from :mod:`.law`.
"""

from __future__ import annotations

from typing import Any

from typing import ClassVar

from ..axes import Axis
from ..fmi import SlaveBase, Var
from ..lateral import LATERAL, N_HZ, U_M_PER_S
from ..longitudinal import LONGITUDINAL
from .law import (U_MAX_LINEAR_RANGE, FeedbackLaw, Gains, default_gains,
                  default_longitudinal_gains, gain_name)

__all__ = ["StateFeedback", "StateFeedbackLongitudinal"]

_LIMIT = ("limit_enabled", "u_max")


def _gains_of_row(axis: Axis, i: int) -> tuple[str, ...]:
    return tuple(gain_name(i, j) for j in range(len(axis.state_names)))


def _all_gains(axis: Axis) -> tuple[str, ...]:
    return tuple(g for i in range(len(axis.control_names)) for g in _gains_of_row(axis, i))


def _variables(axis: Axis, K: Gains, sources: tuple[str, ...]) -> tuple[Var, ...]:
    """Inputs (the measured state), outputs (the controls, ``saturated``), gains ``K[i,j]``
    with their defaults ``K`` (``sources[i]`` says where row i comes from), n, U, the limit."""
    states = axis.state_names
    out: list[Var] = []
    for name, text, nondim, (unit, disp) in zip(states, axis.state_descriptions,
                                                axis.nondimensional, axis.state_units):
        out.append(Var(name, "input", "continuous", f"measured {text}; {nondim}", unit, disp,
                       start=0.0))
    for i, (name, text) in enumerate(zip(axis.control_names, axis.control_descriptions)):
        out.append(Var(name, "output", "continuous",
                       f"{text}: row {i + 1} of u = K x+, limited to +/-u_max if limit_enabled",
                       *axis.control_unit, initial="calculated", dependencies=states,
                       initial_dependencies=(*states, *_gains_of_row(axis, i), "n", "U",
                                             *_LIMIT)))
    out.append(Var("saturated", "output", "discrete",
                   "true while any control output is limited to +/-u_max", None,
                   initial="calculated", type="Boolean", dependencies=states,
                   initial_dependencies=(*states, *_all_gains(axis), "n", "U", *_LIMIT)))
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
    return tuple(out)


class _Feedback(SlaveBase):
    """Full-state feedback u = K x+ on one axis; subclasses set ``AXIS`` and ``VARIABLES``."""

    AXIS: ClassVar[Axis]
    DIRECT_FEEDTHROUGH = True

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        vr, axis = self._vr, self.AXIS
        self._in_vr = tuple(vr[n] for n in axis.state_names)
        self._out_vr = tuple(vr[n] for n in axis.control_names)
        self._gains = _all_gains(axis)
        self._sat_vr = vr["saturated"]
        self._law_vr = tuple(vr[n] for n in (*self._gains, "n", "U", *_LIMIT))
        self._law_key: tuple[Any, ...] | None = None
        self._law: FeedbackLaw | None = None
        self._outputs_valid = False  # the last _update_outputs succeeded

    def _current_law(self) -> FeedbackLaw:
        """The law of the current parameters, validated (rebuilt only when they changed)."""
        r = self._real
        key = tuple(r[i] for i in self._law_vr)
        if self._law is None or key != self._law_key:
            m, c = len(self.AXIS.control_names), len(self.AXIS.state_names)
            K = tuple(tuple(float(key[i * c + j]) for j in range(c)) for i in range(m))
            n, U, enabled, u_max = key[m * c:]
            law = FeedbackLaw(K, float(n), float(U), float(u_max), bool(enabled), self.AXIS)
            law.validate()  # raises naming the bad value; nothing is cached then
            self._law, self._law_key = law, key
        return self._law

    def _refresh(self) -> None:
        self._current_law()

    def _update_outputs(self) -> None:
        self._outputs_valid = False
        r = self._real
        # parameters are re-read only after one was set (the base class's dirty flag)
        law = self._current_law() if self._dirty or self._law is None else self._law
        u, saturated = law.evaluate([r[i] for i in self._in_vr])
        for i, v in zip(self._out_vr, u):
            r[i] = v
        r[self._sat_vr] = saturated
        self._outputs_valid = True

    def _initialize(self) -> None:
        self._update_outputs()

    def _advance(self, t: float, h: float) -> None:
        # No state to integrate. The step is refused while an input or parameter is bad;
        # outputs already computed for the current inputs are not computed again.
        if self._stale or not self._outputs_valid:
            self._update_outputs()
            self._stale = False


class StateFeedback(_Feedback):
    """Full-state feedback u = K x+ of the lateral motion (Zhang & Sun, Eq. 22)."""

    MODEL_NAME = "StateFeedback"
    AXIS = LATERAL
    MODEL_DESCRIPTION = (
        "State feedback u = K x+ (Eq. 22 generalised to the three lateral controls) of "
        "Zhang & Sun, 'Stabilization control of a hovering model insect: lateral motion'; "
        "default K: Eq. (27) on delta_Phi_a; direct feedthrough, no internal state")
    VARIABLES = _variables(LATERAL, default_gains(), ("Eq. (27)", "default 0", "default 0"))
    DEFAULT_EXPERIMENT = (0.0, 30.0 / N_HZ, 0.1 / N_HZ)


class StateFeedbackLongitudinal(_Feedback):
    """Full-state feedback u = K x+ of the longitudinal motion (Sect. 3.5), same law."""

    MODEL_NAME = "StateFeedbackLongitudinal"
    AXIS = LONGITUDINAL
    MODEL_DESCRIPTION = (
        "State feedback u = K x+ on the four longitudinal controls of Sect. 3.5 of Zhang & Sun, "
        "'Stabilization control of a hovering model insect: lateral motion'; default K: "
        "delta_phibar moves the unstable oscillatory pair to its mirror image -0.0481 +/- "
        "0.0976i per wing beat by coefficient matching (Eqs. 25-26), the other eigenvalues "
        "kept; direct feedthrough, no internal state")
    VARIABLES = _variables(LONGITUDINAL, default_longitudinal_gains(),
                           ("default 0", "default 0", "design (b): mirror the unstable pair",
                            "default 0"))
    DEFAULT_EXPERIMENT = (0.0, 60.0 / N_HZ, 0.1 / N_HZ)
