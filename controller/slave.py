"""The controller FMUs: u = K x+_s + KI z of Eq. (22) as FMI 2.0 CS slaves, for either axis.

One implementation (:class:`_Feedback`), four interfaces: ``StateFeedback`` and
``StateFeedbackLongitudinal`` (direct feedthrough declared: exact at ``sensing_delay`` = 0, the
default) and their ``...Delayed`` variants (``sensing_delay`` > 0 required, no direct
feedthrough declared). The internal state is the delay line and the integral z
(:class:`.delay.Sensor`); the outputs are recomputed whenever an output is read after a
value was set (feedthrough FMUs) and at the end of every step. All numbers come from
:mod:`dronefly.models.feedback`, the timing from :mod:`.delay`, the variables from
:mod:`.variables`.
"""

from __future__ import annotations

from operator import itemgetter
from typing import Any, ClassVar

from pythonfmu.enums import Fmi2Status

from ..models.axes import Axis
from ..fmi import SlaveBase
from ..models.lateral_interface import LATERAL, N_HZ
from ..models.longitudinal_interface import LONGITUDINAL
from .delay import Sensor, Timing
from ..models.feedback import FeedbackLaw, default_gains, default_longitudinal_gains
from .variables import LAW_PARAMETERS, TIMING, all_gains, all_integral_gains, controller_variables

__all__ = ["LAWS", "StateFeedback", "StateFeedbackDelayed", "StateFeedbackLongitudinal",
           "StateFeedbackLongitudinalDelayed"]

#: parameter sets whose validated laws a controller class keeps for its instances
LAWS = 16


def _block(vrs: tuple[int, ...]) -> slice:
    """The value references ``vrs`` as one slice of the value table (they must be consecutive,
    as :func:`.variables.controller_variables` lists the controls)."""
    if vrs != tuple(range(vrs[0], vrs[0] + len(vrs))):
        raise ValueError(f"value references {vrs} are not consecutive")
    return slice(vrs[0], vrs[0] + len(vrs))


class _Feedback(SlaveBase):
    """Full-state feedback with sensing delay, sampling and integral action on one axis;
    subclasses set ``AXIS``, ``VARIABLES`` and, for the delayed variants,
    ``DIRECT_FEEDTHROUGH = False`` (which also requires ``sensing_delay`` > 0)."""

    AXIS: ClassVar[Axis]
    DIRECT_FEEDTHROUGH = True

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        (self._in_vr, self._outputs, self._sat_vr, self._law_vr, self._timing_vr,
         self._inputs) = self._rows_of_class()
        self._law_key: tuple[Any, ...] | None = None
        self._law: FeedbackLaw | None = None
        self._timing: Timing | None = None
        self._sensor = Sensor(len(self._in_vr))
        self._outputs_valid = False  # the last output computation succeeded
        #: the current law's u = K x+ on the value table (FeedbackLaw.on_table) while the
        #: outputs are K x+ of the inputs at once (no delay, sampling, integral); else None
        self._proportional: Any = None

    @classmethod
    def _rows_of_class(cls) -> tuple[Any, ...]:
        """The rows of the value table the law reads and writes, made once per class: the
        inputs, the controls (a slice), ``saturated``, the law's parameters, the timing's, and
        ``r -> the input tuple``."""
        rows = cls.__dict__.get("_ROWS")
        if rows is None:
            vr, axis = cls._class_tables()[0], cls.AXIS
            in_vr = tuple(vr[n] for n in axis.state_names)
            rows = cls._ROWS = (
                in_vr, _block(tuple(vr[n] for n in axis.control_names)), vr["saturated"],
                tuple(vr[n] for n in (*all_gains(axis), *all_integral_gains(axis),
                                      *LAW_PARAMETERS)),
                tuple(vr[n] for n in TIMING), itemgetter(*in_vr))
        return rows

    def _current_law(self) -> FeedbackLaw:
        """The law of the current parameters, validated (rebuilt only when they changed)."""
        r = self._real
        key = tuple(r[i] for i in self._law_vr)
        if self._law is None or key != self._law_key:
            laws = type(self).__dict__.get("_LAWS")
            if laws is None:
                laws = type(self)._LAWS = {}
            law = laws.get(key)  # a law of these parameters another instance made (immutable)
            if law is None:
                m, c = len(self.AXIS.control_names), len(self.AXIS.state_names)
                K = tuple(tuple(float(key[i * c + j]) for j in range(c)) for i in range(m))
                KI = tuple(tuple(float(key[m * c + i * c + j]) for j in range(c))
                           for i in range(m))
                n, U, enabled, u_max = key[2 * m * c:]
                law = FeedbackLaw(K, float(n), float(U), float(u_max), bool(enabled), self.AXIS,
                                  KI)
                law.validate()  # raises naming the bad value; nothing is cached then
                if len(laws) >= LAWS:
                    laws.pop(next(iter(laws)))
                laws[key] = law
            self._law, self._law_key, self._proportional = law, key, None
        return self._law

    def _current_timing(self) -> Timing:
        r = self._real
        d, period = (float(r[i]) for i in self._timing_vr)
        timing = self._timing
        if timing is None or (d, period) != (timing.sensing_delay, timing.sample_period):
            timing = Timing(d, period, delay_required=not self.DIRECT_FEEDTHROUGH)
            timing.validate()  # raises naming the bad value; nothing is cached then
            self._timing, self._proportional = timing, None
        return timing

    def _refresh(self) -> None:
        self._current_law()
        self._current_timing()

    def _outputs_at(self, t: float, law: FeedbackLaw, timing: Timing) -> None:
        """Outputs at the communication point ``t`` [s]; raises before writing any."""
        r = self._real
        x = self._inputs(r)
        sensor = self._sensor
        sensed = (x if timing.immediate and self.DIRECT_FEEDTHROUGH
                  else sensor.sensed(t, x, timing, self.DIRECT_FEEDTHROUGH))
        if law.has_integral:
            z = sensor.integral_in_effect(t, timing, self.DIRECT_FEEDTHROUGH)
            u, saturated = law.evaluate(sensed, z)
        else:  # K x+ on the hot path (the same floats); None: evaluate checks the values, raising
            out = law.evaluate_proportional(sensed)
            u, saturated = law.evaluate(sensed) if out is None else out
        r[self._outputs] = u
        r[self._sat_vr] = saturated

    def _update_if_stale(self) -> None:
        # the hot path of a get after a set: u = K x+ of the inputs now, on the value table
        # (False: a value is not finite, which the general path names)
        proportional = self._proportional
        if proportional is not None and not self._dirty and proportional(self._real):
            self._stale = False
            self._outputs_valid = True
            return
        SlaveBase._update_if_stale(self)

    def _update_outputs(self) -> None:
        proportional = self._proportional
        if proportional is not None and not self._dirty and proportional(self._real):
            self._outputs_valid = True  # (as _update_if_stale, for a caller of this hook)
            return
        self._outputs_valid = False
        # parameters are re-read only after one was set (the base class's dirty flag)
        fresh = self._dirty or self._law is None or self._timing is None
        law = self._current_law() if fresh else self._law
        timing = self._current_timing() if fresh else self._timing
        self._outputs_at(self._time, law, timing)  # type: ignore[arg-type]
        self._outputs_valid = True
        # the law whose outputs are K x+ of the inputs at once (no delay, sampling, integral)
        if timing.immediate and self.DIRECT_FEEDTHROUGH and not law.has_integral:  # type: ignore[union-attr]
            self._proportional = law.on_table(self._in_vr, range(self._outputs.start,  # type: ignore[union-attr]
                                                                  self._outputs.stop),
                                              self._sat_vr)
        else:
            self._proportional = None

    def _initialize(self) -> None:
        warned = self._sensor.off_grid is False
        self._sensor = Sensor(len(self.AXIS.state_names), self._time)
        self._sensor.off_grid = False if warned else None
        self._update_outputs()

    def _warn_off_grid(self, timing: Timing) -> None:
        """Log, once per instance, that an instant fell inside a communication step.

        Runs after the step is committed, so it cannot fail it: if the full warning cannot be
        formed, a plain one is logged instead."""
        try:
            what, instant, t, h = self._sensor.off_grid  # type: ignore[misc]
            self._sensor.off_grid = False
            msg = timing.off_grid_warning(what, instant, t, h, self.FMI_TEXT)
        except BaseException as e:  # (off_grid_warning guards its arithmetic; and if not)
            self._sensor.off_grid = False
            msg = (f"sensing_delay = {timing.sensing_delay!r} s and sample_period = "
                   f"{timing.sample_period!r} s: an instant falls inside a communication step "
                   f"(the latency the importer sees could not be computed: {e!r}); the input "
                   "held over the step is sampled, and a control is visible from the next "
                   "communication point on (warned once per instance)")
        try:
            self._report(msg, Fmi2Status.warning)
        except BaseException:  # pragma: no cover - nothing left to log with; the step is OK
            pass

    def _advance(self, t: float, h: float) -> None:
        # the base class has called _initialize or _refresh after any parameter was set
        sensor = self._sensor
        if (self._proportional is not None and not self._stale and self._outputs_valid
                and not sensor.integrating and not sensor.line):
            # the hot path: the current law is K x+ at once (as below) and the outputs of the
            # inputs, valid at t, hold at t + h as well
            sensor.held, sensor.h, sensor.last_k = self._inputs(self._real), h, None
            return
        law, timing = self._law, self._timing
        if law is None or timing is None:  # pragma: no cover - the base class prevents it
            law, timing = self._current_law(), self._current_timing()
        x = self._inputs(self._real)
        if (timing.immediate and not law.has_integral and not sensor.integrating
                and not sensor.line):  # the sample at t in effect at once: u = K x+ (Eq. 22)
            if self._stale or not self._outputs_valid:  # (else the outputs of x, valid at t,
                before = sensor.held, sensor.h, sensor.last_k  # hold at t + h as well)
                sensor.held, sensor.h, sensor.last_k = x, h, None
                try:  # validates x, naming a bad input
                    self._outputs_at(t + h, law, timing)
                except BaseException:
                    sensor.held, sensor.h, sensor.last_k = before  # a refused step changes
                    raise  # nothing
                self._outputs_valid, self._stale = True, False
            else:
                sensor.held, sensor.h, sensor.last_k = x, h, None
            return
        total = sum(x)
        if total - total != 0.0:  # inf or nan (or an overflowing sum): named if not finite
            law.nondimensional_state(x)
        timing.check_step(h)
        token = sensor.advance(t, h, x, law.scale, law.n, timing, law.has_integral)
        try:
            self._outputs_at(t + h, law, timing)
        except BaseException:
            sensor.undo(token)  # a refused step changes nothing
            raise
        self._outputs_valid, self._stale = True, False
        if sensor.off_grid:  # an instant inside this step, the first in this instance
            self._warn_off_grid(timing)

    def _extra_state(self) -> dict[str, Any]:
        return {"sensor": self._sensor.to_dict()}

    def _restore_extra_state(self, state: dict[str, Any]) -> None:
        warned = self._sensor.off_grid is False  # the warning belongs to the instance
        self._sensor = Sensor.from_dict(state["sensor"], len(self.AXIS.state_names))
        self._sensor.off_grid = False if warned else None


_LATERAL_SOURCES = ("Eq. (27)", "default 0", "default 0")
_LONGITUDINAL_SOURCES = ("default 0", "default 0", "design (b): mirror the unstable pair",
                         "default 0")
_PAPER = "Zhang & Sun, 'Stabilization control of a hovering model insect: lateral motion'"
_TIMING_TEXT = ("sensing_delay and sample_period (zero-order hold of the delayed samples); "
                "integral gains KI (default 0)")
_FEEDTHROUGH = ("direct feedthrough declared conservatively (exact at sensing_delay = 0, the "
                "default; the ModelStructure cannot follow a tunable parameter)")
_NO_FEEDTHROUGH = ("sensing_delay > 0 required (default one wing beat), so no direct "
                   "feedthrough: the outputs depend on no input at the same instant")


class StateFeedback(_Feedback):
    """Full-state feedback u = K x+_s + KI z of the lateral motion (Zhang & Sun, Eq. 22)."""

    MODEL_NAME = "StateFeedback"
    AXIS = LATERAL
    MODEL_DESCRIPTION = (
        f"State feedback u = K x+ (Eq. 22 generalised to the three lateral controls) of {_PAPER}; "
        f"default K: Eq. (27) on delta_Phi_a; {_TIMING_TEXT}; {_FEEDTHROUGH}")
    VARIABLES = controller_variables(LATERAL, default_gains(), _LATERAL_SOURCES)
    DEFAULT_EXPERIMENT = (0.0, 30.0 / N_HZ, 0.1 / N_HZ)


class StateFeedbackDelayed(_Feedback):  # not a subclass of StateFeedback: pythonfmu's
    # findClass leaks memory per MRO entry on every instantiation
    """:class:`StateFeedback` with a sensing delay > 0 and no direct feedthrough."""

    MODEL_NAME = "StateFeedbackDelayed"
    AXIS = LATERAL
    DIRECT_FEEDTHROUGH = False
    MODEL_DESCRIPTION = (
        f"State feedback u = K x+ (Eq. 22 generalised to the three lateral controls) of {_PAPER}, "
        f"sensed late; default K: Eq. (27) on delta_Phi_a; {_TIMING_TEXT}; {_NO_FEEDTHROUGH}")
    VARIABLES = controller_variables(LATERAL, default_gains(), _LATERAL_SOURCES, delayed=True)
    DEFAULT_EXPERIMENT = StateFeedback.DEFAULT_EXPERIMENT


class StateFeedbackLongitudinal(_Feedback):
    """Full-state feedback u = K x+_s + KI z of the longitudinal motion (Sect. 3.5), same law."""

    MODEL_NAME = "StateFeedbackLongitudinal"
    AXIS = LONGITUDINAL
    MODEL_DESCRIPTION = (
        f"State feedback u = K x+ on the four longitudinal controls of Sect. 3.5 of {_PAPER}; "
        "default K: delta_phibar moves the unstable oscillatory pair to its mirror image "
        "-0.0481 +/- 0.0976i per wing beat by coefficient matching (Eqs. 25-26), the other "
        f"eigenvalues kept; {_TIMING_TEXT}; {_FEEDTHROUGH}")
    VARIABLES = controller_variables(LONGITUDINAL, default_longitudinal_gains(),
                                     _LONGITUDINAL_SOURCES)
    DEFAULT_EXPERIMENT = (0.0, 60.0 / N_HZ, 0.1 / N_HZ)


class StateFeedbackLongitudinalDelayed(_Feedback):
    """:class:`StateFeedbackLongitudinal` with a sensing delay > 0 and no direct feedthrough."""

    MODEL_NAME = "StateFeedbackLongitudinalDelayed"
    AXIS = LONGITUDINAL
    DIRECT_FEEDTHROUGH = False
    MODEL_DESCRIPTION = (
        f"State feedback u = K x+ on the four longitudinal controls of Sect. 3.5 of {_PAPER}, "
        "sensed late; default K: design (b) (the unstable pair mirrored) on delta_phibar; "
        f"{_TIMING_TEXT}; {_NO_FEEDTHROUGH}")
    VARIABLES = controller_variables(LONGITUDINAL, default_longitudinal_gains(),
                                     _LONGITUDINAL_SOURCES, delayed=True)
    DEFAULT_EXPERIMENT = StateFeedbackLongitudinal.DEFAULT_EXPERIMENT
