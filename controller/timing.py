"""When the controller FMUs sample and how late their samples take effect.

:class:`Timing` holds ``sensing_delay`` and ``sample_period`` and their checks; the delay
line itself is :class:`controller.delay.Sensor`. Pure Python (shipped inside the controller
FMUs); imports only the project's errors.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property

from ..core.errors import DroneflyError

__all__ = ["DRIFT", "DRIFT_CAP", "MAX_SAMPLES", "TOLERANCE", "SensingError", "Timing",
           "tolerance"]

#: bound of the delay line (samples taken, not yet in effect) of one instance
MAX_SAMPLES = 100_000
#: times closer than TOLERANCE * (communication step) count as equal ...
TOLERANCE = 1e-9
#: ... plus the drift of a master's time t_m = t_(m-1) + h: up to one rounding, 2^-53 |t|,
#: per step, so m = (t - t_start) / h steps give m DRIFT |t| (DRIFT: two roundings) ...
DRIFT = 2.0 ** -52
#: ... at most DRIFT_CAP * (communication step): without a cap the drift term grows as m^2
#: and an instant 1e-4 h off the grid would snap onto it after 6.7e5 steps (the latency
#: seen changing mid-run). Summed steps drift far less than the bound DRIFT m^2 h: over the
#: 1e6 steps the project's masters allow (harness.cosim.records.MAX_STEPS), at most 2.4e-5 h
#: for steps of 0.1, 0.5 and 1 wing beat (exact sums, test_controller_delay; 2.7e-5 h the
#: most of 21 step sizes tried). So 5e-5 h keeps a master that sums its steps on the grid
#: for runs that long and still tells an instant 1e-4 h off the grid from one on it at any
#: run length; 1e-6 h would not (summed steps pass it after 2.2e5 steps for some steps).
DRIFT_CAP = 5e-5
#: steps of the grid on which the warning gives the latency the importer sees
_GRID_STEPS = 2000


def tolerance(t0: float, t: float, h: float) -> float:
    """Times within this of each other [s] count as equal at ``t`` [s] on steps of ``h`` [s]
    from ``t0`` [s]: TOLERANCE h + min(DRIFT |t| (t - t0) / h, DRIFT_CAP h) (0 before the
    first step, h = 0). The drift term reaches TOLERANCE h after about 2100 steps from t0 = 0
    and its cap DRIFT_CAP h after about 4.7e5."""
    if not h > 0.0:
        return 0.0
    return TOLERANCE * h + min(DRIFT * abs(t) * abs(t - t0) / h, DRIFT_CAP * h)

class SensingError(DroneflyError):
    """A sensing delay or sample period is not acceptable, or the integral state overflows."""


@dataclass(frozen=True)
class Timing:
    """When the controller samples and how late its samples take effect.

    Parameters
    ----------
    sensing_delay : float
        Delay from a sample instant to the instant its control takes effect [s], >= 0.
    sample_period : float
        Period of the sample instants t_start + k * sample_period [s]; 0 = sample at every
        communication point.
    delay_required : bool
        The FMU declares no direct feedthrough: ``sensing_delay`` must be > 0.
    """

    sensing_delay: float = 0.0
    sample_period: float = 0.0
    delay_required: bool = False

    @cached_property
    def immediate(self) -> bool:
        """No delay, no sampling: each communication point's input in effect at once."""
        return self.sensing_delay == 0.0 and self.sample_period == 0.0

    def validate(self) -> None:
        """Raise :class:`SensingError` naming the first bad value."""
        for name, value in (("sensing_delay", self.sensing_delay),
                            ("sample_period", self.sample_period)):
            if not (math.isfinite(value) and value >= 0.0):
                raise SensingError(f"{name} = {value!r} s must be finite and >= 0")
        if self.delay_required and not self.sensing_delay > 0.0:
            raise SensingError(f"sensing_delay = {self.sensing_delay!r} s must be > 0 in this "
                               "FMU (it declares no direct feedthrough; the FMU of the same "
                               "name without 'Delayed' takes 0)")

    def too_long(self, h: float) -> str:
        """The refusal of a delay line longer than :data:`MAX_SAMPLES` for a step of ``h`` [s]."""
        return (f"sensing_delay = {self.sensing_delay!r} s with sample_period = "
                f"{self.sample_period!r} s and a communication step of {h!r} s needs a delay "
                f"line of more than {MAX_SAMPLES} samples (memory bound): use a longer "
                "sample_period or communication step")

    def check_step(self, h: float) -> None:
        """Refuse a step of ``h`` [s] that would need more than :data:`MAX_SAMPLES` entries
        (one per step or per sample period within the delay)."""
        if self.sensing_delay > MAX_SAMPLES * max(h, self.sample_period):
            raise SensingError(self.too_long(h))

    def seen_latency(self, h: float, steps: int = _GRID_STEPS) -> tuple[float, float]:
        """The shortest and longest time [s] from a communication point, where the importer
        sets an input, to the first communication point that shows the control of a sample of
        it, on a grid of steps ``h`` [s] from t_start (over the first ``steps`` steps, as far
        as the grid stays within float range; ``inf``: none shown, or beyond float range)."""
        d, period, tol = self.sensing_delay, self.sample_period, TOLERANCE * h  # (no drift)
        seen: list[float] = []
        for m in range(steps):
            t = m * h
            if not math.isfinite(t + h):  # the grid leaves float range
                break
            try:
                ts = t if period <= tol else math.ceil((t - tol) / period) * period
                if ts < t + h - tol:  # the first instant in [t, t + h)
                    seen.append(math.ceil((ts + d - tol) / h) * h - t)
            except (OverflowError, ValueError):  # an instant index beyond float range
                seen.append(math.inf)
        return (min(seen), max(seen)) if seen else (math.inf, math.inf)

    def off_grid_warning(self, what: str, instant: float, t: float, h: float,
                         fmi: str = "FMI") -> str:
        """The warning for ``what`` ("a sample instant", "an effect instant") at ``instant`` [s]
        strictly inside the step [t, t + h) [s]: what the FMU does and what the importer sees;
        ``fmi`` names the FMU's standard ("FMI 2.0", "FMI 3.0")."""
        lo, hi = self.seen_latency(h)
        if not math.isfinite(lo):  # no instant in the steps looked at, or beyond float range
            seen = f"more than {_GRID_STEPS} steps later (or beyond float range)"
        elif not math.isfinite(hi):
            seen = f"{lo / h:.4g} steps ({lo:.6g} s) or more later"
        elif hi - lo <= TOLERANCE * h:
            seen = f"{lo / h:.4g} step(s) ({lo:.6g} s) later"
        else:
            seen = f"{lo / h:.4g} to {hi / h:.4g} steps ({lo:.6g} to {hi:.6g} s) later"
        return (f"sensing_delay = {self.sensing_delay!r} s and sample_period = "
                f"{self.sample_period!r} s on a communication step of {h!r} s: {what} "
                f"(t = {instant!r} s) falls inside the step from {t!r} s. "
                f"Inputs are constant over a communication step ({fmi} co-simulation), so the "
                "FMU samples the input held since the start of the step, and a control that "
                "takes effect inside a step is visible from the next communication point on: at "
                "this step size the importer sees the control of an input set at a "
                f"communication point {seen}, instead of sensing_delay. Values are computed "
                "this way, not refused; make both whole numbers of steps to get them exactly "
                "(warned once per instance)")
