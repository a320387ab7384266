"""The model in time for a host (:class:`Flight`): the state kept on the Runge-Kutta grid, the
controls latched at the beats' starts, any instant reached by a partial step; the whole state a
snapshot of plain values (the ``DroneFlyFlapping`` FMU's state)."""

from __future__ import annotations

import math
from typing import Mapping, Sequence

import numpy as np

from .model import STATE_SIZE, FlappingError, FlappingModel, wing_beat_controls

__all__ = ["Flight"]


class Flight:
    """The model in time: the state on the Runge-Kutta grid, the controls latched at the beats'
    starts, any instant reached by a partial step that the flight does not keep.

    Time is t+ in wing beats from the start; beat k is [k, k + 1). ``set_controls`` may be
    called at any time: the values are taken when the flight enters the next beat (see
    :mod:`dronefly.models.flapping`). The whole state is :meth:`snapshot` (plain Python values;
    the FMU's state).
    """

    def __init__(self, model: FlappingModel, x0: Sequence[float],
                 controls: Sequence[float] | Mapping[str, float] | None = None) -> None:
        self.model = model
        y = np.array(x0, dtype=float)
        if y.shape != (STATE_SIZE,) or not np.all(np.isfinite(y)):
            raise FlappingError(f"initial state {list(np.ravel(x0))!r}: expected {STATE_SIZE} "
                                "finite values")
        c = wing_beat_controls(controls)
        self.grid = 0  # grid index of y: t+ = grid / N
        self.y = y
        self.pending = c
        self.c_prev = c  # before the first beat the insect flapped with the initial controls
        self.c_now = c
        self.latched = -1  # the beat whose controls c_now are

    @property
    def N(self) -> int:
        return self.model.steps_per_beat

    def set_controls(self, controls: Sequence[float] | Mapping[str, float] | None) -> None:
        """The controls for the next beat that starts (taken at its start)."""
        self.pending = wing_beat_controls(controls)

    def _latch(self, beat: int) -> None:
        if self.latched < beat:
            if self.latched >= 0:
                self.c_prev = self.c_now
            self.c_now = self.pending
            self.latched = beat

    def _tolerance(self) -> float:
        return 1e-9 / self.N

    def advance_to(self, t: float) -> np.ndarray:
        """Integrate the kept state to the last grid point at or before ``t`` (wing beats) and
        return the state at ``t`` (a partial step from there if ``t`` is off the grid)."""
        N = self.N
        if not t >= self.grid / N - self._tolerance():
            raise FlappingError(f"time {t!r} wing beats is before the flight's state "
                                f"({self.grid / N!r})")
        m = self.model
        while (self.grid + 1) / N <= t + self._tolerance():
            k, j = divmod(self.grid, N)
            self._latch(k)
            self.y = m._advance(self.y, j / N, (j + 1) / N, self.c_prev, self.c_now)
            self.grid += 1
        return self.state_at(t)

    def state_at(self, t: float) -> np.ndarray:
        """The state at ``t`` between the kept grid point and the next (not kept)."""
        N = self.N
        dt = t - self.grid / N
        if abs(dt) <= self._tolerance():
            return self.y.copy()
        if not 0.0 < dt < 1.0 / N + self._tolerance():
            raise FlappingError(f"time {t!r} is not within one grid step after the state")
        k, j = divmod(self.grid, N)
        self._latch(k)
        return self.model.advance(self.y, j / N, min(1.0, j / N + dt), self.c_prev, self.c_now)

    def phase(self, t: float) -> tuple[float, tuple[float, ...], tuple[float, ...]]:
        """(phase in the beat, its previous and current controls) at ``t`` (at or after the
        kept state, within a step): at the start of a beat not yet entered, the end of the
        last one (its angles are the same: the controls act from the beat's first instant
        on)."""
        k = int(math.floor(t + self._tolerance()))
        if k > self.latched:
            return (0.0 if self.latched < 0 else 1.0), self.c_prev, self.c_now
        return max(0.0, min(1.0, t - k)), self.c_prev, self.c_now

    def snapshot(self) -> dict:
        """Everything the flight's future depends on (plain values)."""
        return {"grid": self.grid, "y": [float(v) for v in self.y], "pending": self.pending,
                "c_prev": self.c_prev, "c_now": self.c_now, "latched": self.latched}

    def restore(self, snap: Mapping) -> None:
        """Return to a :meth:`snapshot`."""
        self.grid = int(snap["grid"])
        self.y = np.array(snap["y"], dtype=float)
        self.pending = wing_beat_controls(snap["pending"])
        self.c_prev = wing_beat_controls(snap["c_prev"])
        self.c_now = wing_beat_controls(snap["c_now"])
        self.latched = int(snap["latched"])
