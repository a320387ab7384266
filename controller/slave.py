"""FMU ``StateFeedback``: the state feedback u = K x+ of Eq. (22) as an FMI 2.0 CS slave.

A block without internal state and with direct feedthrough: the outputs are
recomputed from the current inputs and parameters whenever an output is read
after a value was set (no doStep needed). All numbers come from :mod:`.law`.
"""

from __future__ import annotations

from typing import Any

from ..fmi import SlaveBase, Var
from ..lateral import (CONTROL_DESCRIPTIONS, CONTROL_NAMES, CONTROL_UNIT, N_HZ, NONDIMENSIONAL,
                       STATE_DESCRIPTIONS, STATE_NAMES, STATE_UNITS, U_M_PER_S)
from .law import U_MAX_LINEAR_RANGE, FeedbackLaw, default_gains, gain_name

__all__ = ["StateFeedback"]

_LIMIT = ("limit_enabled", "u_max")


def _gains_of_row(i: int) -> tuple[str, ...]:
    return tuple(gain_name(i, j) for j in range(len(STATE_NAMES)))


def _variables() -> tuple[Var, ...]:
    K = default_gains()
    all_gains = tuple(g for i in range(len(CONTROL_NAMES)) for g in _gains_of_row(i))
    out: list[Var] = []
    for name, text, nondim, (unit, disp) in zip(STATE_NAMES, STATE_DESCRIPTIONS, NONDIMENSIONAL,
                                                STATE_UNITS):
        out.append(Var(name, "input", "continuous", f"measured {text}; {nondim}", unit, disp,
                       start=0.0))
    for i, (name, text) in enumerate(zip(CONTROL_NAMES, CONTROL_DESCRIPTIONS)):
        out.append(Var(name, "output", "continuous",
                       f"{text}: row {i + 1} of u = K x+, limited to +/-u_max if limit_enabled",
                       *CONTROL_UNIT, initial="calculated", dependencies=STATE_NAMES,
                       initial_dependencies=(*STATE_NAMES, *_gains_of_row(i), "n", "U", *_LIMIT)))
    out.append(Var("saturated", "output", "discrete",
                   "true while any control output is limited to +/-u_max", None,
                   initial="calculated", type="Boolean", dependencies=STATE_NAMES,
                   initial_dependencies=(*STATE_NAMES, *all_gains, "n", "U", *_LIMIT)))
    for i, row in enumerate(K):
        for j, k in enumerate(row):
            source = "Eq. (27)" if i == 0 else "default 0"
            out.append(Var(gain_name(i, j), "parameter", "tunable",
                           f"gain of {CONTROL_NAMES[i]} [rad] on x+{j + 1} ({STATE_NAMES[j]}, "
                           f"non-dimensional); {source}", "1", start=k))
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


class StateFeedback(SlaveBase):
    """Full-state feedback u = K x+ for the hovering model drone fly (Zhang & Sun)."""

    MODEL_NAME = "StateFeedback"
    DIRECT_FEEDTHROUGH = True
    MODEL_DESCRIPTION = (
        "State feedback u = K x+ (Eq. 22 generalised to the three lateral controls) of "
        "Zhang & Sun, 'Stabilization control of a hovering model insect: lateral motion'; "
        "default K: Eq. (27) on delta_Phi_a; direct feedthrough, no internal state")
    VARIABLES = _variables()
    DEFAULT_EXPERIMENT = (0.0, 30.0 / N_HZ, 0.1 / N_HZ)

    _GAINS = tuple(g for i in range(len(CONTROL_NAMES)) for g in _gains_of_row(i))

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        vr = self._vr
        self._in_vr = tuple(vr[n] for n in STATE_NAMES)
        self._out_vr = tuple(vr[n] for n in CONTROL_NAMES)
        self._sat_vr = vr["saturated"]
        self._law_vr = tuple(vr[n] for n in (*self._GAINS, "n", "U", *_LIMIT))
        self._law_key: tuple[Any, ...] | None = None
        self._law: FeedbackLaw | None = None
        self._outputs_valid = False  # the last _update_outputs succeeded

    def _current_law(self) -> FeedbackLaw:
        """The law of the current parameters, validated (rebuilt only when they changed)."""
        r = self._real
        key = tuple(r[i] for i in self._law_vr)
        if self._law is None or key != self._law_key:
            m, c = len(CONTROL_NAMES), len(STATE_NAMES)
            K = tuple(tuple(float(key[i * c + j]) for j in range(c)) for i in range(m))
            n, U, enabled, u_max = key[m * c:]
            law = FeedbackLaw(K, float(n), float(U), float(u_max), bool(enabled))
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
        i0, i1, i2, i3 = self._in_vr
        u, saturated = law.evaluate((r[i0], r[i1], r[i2], r[i3]))
        o = self._out_vr
        r[o[0]], r[o[1]], r[o[2]] = u
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
