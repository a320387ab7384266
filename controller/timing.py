"""When the controller FMUs sample and how late their samples take effect (issue 14).

:class:`Timing` holds ``sensing_delay`` and ``sample_period`` and their checks; the delay
line itself is :class:`controller.delay.Sensor`. Pure Python (shipped inside the controller
FMUs); imports only the project's errors.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property

from ..errors import DroneflyError

__all__ = ["DRIFT", "MAX_SAMPLES", "TOLERANCE", "SensingError", "Timing", "tolerance"]

#: bound of the delay line (samples taken, not yet in effect) of one instance
MAX_SAMPLES = 100_000
#: times closer than TOLERANCE * (communication step) count as equal ...
TOLERANCE = 1e-9
#: ... plus the drift of a master's time t_m = t_(m-1) + h: up to one rounding, 2^-53 |t|,
#: per step, so m = (t - t_start) / h steps give m DRIFT |t| (DRIFT: two roundings)
DRIFT = 2.0 ** -52


def tolerance(t0: float, t: float, h: float) -> float:
    """Times within this of each other [s] count as equal at ``t`` [s] on steps of ``h`` [s]
    from ``t0`` [s]: TOLERANCE h + DRIFT |t| (t - t0) / h (0 before the first step, h = 0).
    The drift term reaches TOLERANCE h after about 2100 steps from t0 = 0 and h/2 after 5e7."""
    if not h > 0.0:
        return 0.0
    return TOLERANCE * h + DRIFT * abs(t) * abs(t - t0) / h

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

    def seen_latency(self, h: float, steps: int = 2000) -> tuple[float, float]:
        """The shortest and longest time [s] from a communication point, where the importer
        sets an input, to the first communication point that shows the control of a sample of
        it, on a grid of steps ``h`` [s] from t_start (over the first ``steps`` steps)."""
        d, period, tol = self.sensing_delay, self.sample_period, TOLERANCE * h  # (no drift)
        seen: list[float] = []
        for m in range(steps):
            t = m * h
            ts = t if period <= tol else math.ceil((t - tol) / period) * period
            if ts < t + h - tol:  # the first instant in [t, t + h)
                seen.append(math.ceil((ts + d - tol) / h) * h - t)
        return (min(seen), max(seen)) if seen else (math.inf, math.inf)

    def off_grid_warning(self, what: str, instant: float, t: float, h: float) -> str:
        """The warning for ``what`` ("a sample instant", "an effect instant") at ``instant`` [s]
        strictly inside the step [t, t + h) [s]: what the FMU does and what the importer sees."""
        lo, hi = self.seen_latency(h)
        seen = (f"{lo / h:.4g} step(s) ({lo:.6g} s)" if hi - lo <= TOLERANCE * h else
                f"{lo / h:.4g} to {hi / h:.4g} steps ({lo:.6g} to {hi:.6g} s)")
        return (f"sensing_delay = {self.sensing_delay!r} s and sample_period = "
                f"{self.sample_period!r} s on a communication step of {h!r} s: {what} "
                f"(t = {instant!r} s) falls inside the step from {t!r} s. "
                "Inputs are constant over a communication step (FMI 2.0), so the FMU samples the "
                "input held since the start of the step, and a control that takes effect inside "
                "a step is visible from the next communication point on: at this step size the "
                f"importer sees the control of an input set at a communication point {seen} "
                "later, instead of sensing_delay. Values are computed this way, not refused; "
                "make both whole numbers of steps to get them exactly (warned once per "
                "instance)")
