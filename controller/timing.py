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

__all__ = ["MAX_SAMPLES", "TOLERANCE", "SensingError", "Timing"]

#: bound of the delay line (samples taken, not yet in effect) of one instance
MAX_SAMPLES = 100_000
#: times closer than TOLERANCE * (communication step) count as equal
TOLERANCE = 1e-9

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
