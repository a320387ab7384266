"""Sensing delay, sampling and the integral state of the controller FMUs.

The controller samples the measured state at its sample instants

    t_k = t_start + k * sample_period       (sample_period = 0: every communication point)

and the control computed from the sample at t_k takes effect at t_k + sensing_delay, held
(zero-order hold) until the next one takes effect. Before the first sample takes effect the
sensed state is the equilibrium x = 0 (the insect hovered before t_start). The output at a
communication point t is the control of the latest sample with t_k + sensing_delay <= t
(times compared to 1e-9 of the communication step plus the drift of a master that adds up its
steps, capped: :func:`.timing.tolerance`).

FMI co-simulation holds the inputs over a communication step (``canInterpolateInputs`` is
false): a sample instant inside [t, t + h) sees the input set at t (exact for what the importer
supplied), and an effect inside a step is visible from the next communication point on. None is
refused; :attr:`Sensor.off_grid` records the first such instant, for the FMU's warning. All
instants of one step see the same input: one line entry per step, its instants counting one by
one for the integral term as they take effect (:meth:`Sensor.integral_in_effect`).

:class:`Sensor` holds the delay line, the sample in effect and the integral state
z = integral of x+_s dt+ (t+ = t n) of the sensed non-dimensional state x+_s, exact for the
held signal: z(t) = z(t_b) + x+_s (t - t_b) n since the last change t_b of the held sample.
The control, computed when a sample takes effect and held until the next one does, is
u = K x+_s + KI z(t_e), t_e the instant the held sample took effect (every sample instant
counts, also one whose value repeats). z integrates while integral action is on (any integral
gain non-zero), from z = 0 at t_start if the gains are set before the run starts.

Pure Python (shipped inside the controller FMUs); imports only :mod:`.timing`.
"""

from __future__ import annotations

import math
import operator
from collections import deque
from dataclasses import dataclass, fields
from typing import Any, Sequence, Tuple

from .timing import DRIFT, DRIFT_CAP, MAX_SAMPLES, TOLERANCE, SensingError, Timing

__all__ = ["MAX_SAMPLES", "TOLERANCE", "Sensor", "SensingError", "Timing", "Undo"]

State = Tuple[float, ...]  # (typing.Tuple: Python 3.8 hosts)


@dataclass
class Undo:
    """What :meth:`Sensor.undo` restores after a :meth:`Sensor.advance`.

    Attributes
    ----------
    saved : tuple
        The sensor's fields before the step, in the order of ``dataclasses.fields(Sensor)``
        (``line`` is the sensor's own deque, its content restored from the two below).
    length : int
        The length of the delay line before the step.
    popped : list of tuple
        The entries the step took from the front of the line, oldest first.
    """

    saved: tuple[Any, ...]
    length: int
    popped: list[tuple[Any, ...]]
    __slots__ = tuple(__annotations__)  # the fields above (slots=True needs Python 3.10)


@dataclass(init=False, eq=False)
class Sensor:
    """The delay line and the integral state of one controller instance.

    Parameters
    ----------
    size : int
        Number of state components.
    t0 : float
        Start time [s], origin of the sample instants.

    Attributes
    ----------
    t0 : float
        Start time [s], origin of the sample instants.
    line : deque of tuple
        Samples taken and not yet in effect, oldest first: (instant [s], dimensional state),
        or (first instant, state, last instant, period) [s] for several in one step.
    held : tuple
        The state of the sample in effect (zeros: the equilibrium).
    z0, t_base : tuple, float
        The integral state (non-dimensional) at ``t_base`` [s], the last change of ``held``.
    x_plus, scale, n : tuple, tuple, float
        x+ of ``held`` (x = x+ * scale) and the wing-beat frequency [Hz] of t+ since t_base.
    integrating : bool
        Whether z integrates (integral action on) since t_base.
    last_k, last_period : int or None, float
        Index of the last sample instant taken on the grid of ``last_period`` [s].
    h, drift : float
        The last communication step [s] (0 before the first) and its tolerance's drift term.
    t_effect : float
        The instant [s] the sample in effect took effect (``t0`` before the first).
    current : tuple or None
        The line entry in effect (None: the equilibrium, or a sample without delay; its
        instants after the first take effect one by one).
    off_grid : tuple or None or False
        None until a sample or effect instant falls strictly inside a communication step, then
        (what, instant [s], step start [s], step [s]) until reported; False once reported.
    """

    t0: float
    line: deque[tuple[Any, ...]]
    held: State
    z0: State
    t_base: float
    x_plus: State
    scale: State
    n: float
    integrating: bool
    last_k: int | None
    last_period: float
    h: float
    drift: float
    t_effect: float
    current: tuple[Any, ...] | None
    off_grid: tuple[str, float, float, float] | None | bool
    __slots__ = tuple(__annotations__)  # the fields above (slots=True needs Python 3.10)

    def __init__(self, size: int, t0: float = 0.0) -> None:
        zero = (0.0,) * size
        self.t0 = float(t0)
        self.line = deque()
        self.held, self.z0, self.x_plus = zero, zero, zero
        self.t_base = self.t0
        self.scale = ()
        self.n = 0.0
        self.integrating = False
        self.last_k, self.last_period = None, 0.0
        self.h, self.drift = 0.0, 0.0
        self.t_effect = self.t0
        self.current = None
        self.off_grid = None

    def integral(self, t: float) -> State:
        """z(t) [non-dimensional] for t >= t_base (exact for the held sample)."""
        if t == self.t_base or not self.integrating:
            return self.z0
        dt = (t - self.t_base) * self.n
        return tuple(a + b * dt for a, b in zip(self.z0, self.x_plus))

    def _switch(self, t: float, x: State, scale: State, n: float) -> None:
        """From ``t`` [s] on, ``x`` is in effect with the scales ``scale``, ``n``."""
        if not self.integrating:
            self.held = x
            return
        z = self.integral(t)
        for j, v in enumerate(z):
            if not math.isfinite(v):
                raise SensingError(f"the integral state z{j + 1} = {v!r} (of x+{j + 1}) "
                                   f"overflows at t = {t!r} s: the sensed state is far outside "
                                   "the linear range")
        self.z0, self.t_base, self.held, self.scale, self.n = z, t, x, scale, n
        self.x_plus = tuple(v / s for v, s in zip(x, scale))

    def _instant(self, t: float, h: float, end: float, tol: float, period: float,
                 x: State) -> float | None:
        """The first sample instant in [t, end = t + h) [s] not taken yet (None: none, or
        taken here: several instants in the step, appended as (first, ``x``, last, period))."""
        if period <= tol:  # every communication point (or finer than the step resolves)
            self.last_k = None
            return t
        try:
            k_end = math.ceil((end - tol - self.t0) / period)  # instants k < k_end: before end
            if self.last_k is None or self.last_period != period:
                k = math.ceil((t - tol - self.t0) / period)
            else:  # the next one on the grid, unless it lies before this step (by more than
                # the tolerance of the previous step, which decided that it was not in it)
                wide = max(tol, TOLERANCE * self.h + self.drift)
                k = max(self.last_k + 1, math.ceil((t - wide - self.t0) / period))
            if k_end - k != 1:
                if k >= k_end:
                    return None
                ts = self.t0 + k * period  # several instants: the second is inside the step
                self.last_k, self.last_period = k_end - 1, period
                if self.off_grid is None:
                    self.off_grid = ("a sample instant", ts if ts > t + tol else ts + period, t,
                                     h)
                if len(self.line) >= MAX_SAMPLES:  # refused by the caller
                    return ts
                self.line.append((ts, x, self.t0 + (k_end - 1) * period, period))
                return None
            ts = self.t0 + k * period
        except (OverflowError, ValueError):  # an instant index beyond float range
            self.last_k = None
            return t
        self.last_k, self.last_period = k, period
        if ts > t + tol and self.off_grid is None:  # the one instant inside the step
            self.off_grid = ("a sample instant", ts, t, h)
        return ts

    def advance(self, t: float, h: float, x: State, scale: State, n: float,
                timing: Timing, integrate: bool) -> Undo:
        """One communication step [t, t + h) [s] with the input ``x`` (dimensional) held.

        Takes the sample (if an instant falls in the step) and puts into effect every sample
        due by t + h; z integrates over the step if ``integrate`` (integral action on). On an
        exception nothing is changed.

        Returns
        -------
        Undo
            The token for :meth:`undo`.

        Raises
        ------
        SensingError
            The delay line would exceed :data:`MAX_SAMPLES`, or the integral overflows.
        """
        line = self.line
        popped: list[tuple[Any, ...]] = []
        token = Undo(_fields_of(self), len(line), popped)
        try:
            # tolerance(t0, t, h) inline: t >= t0 (the base class checks h > 0)
            drift = min(DRIFT * (t if t > 0.0 else -t) * (t - self.t0) / h, DRIFT_CAP * h)
            tol, end = TOLERANCE * h + drift, t + h
            if integrate != self.integrating:  # integral action switched on or off at t
                if self.integrating:
                    self._switch(t, self.held, scale, n)  # z up to t, held from then on
                self.integrating, self.t_base = integrate, t
                if integrate:
                    self._switch(t, self.held, scale, n)  # x+ of the sample in effect
            elif integrate and (scale != self.scale or n != self.n):  # new scales from t on
                self._switch(t, self.held, scale, n)
            d, period = timing.sensing_delay, timing.sample_period
            if not line and d <= tol and period <= tol:  # the sample at t takes effect at t
                if x != self.held:
                    self._switch(t, x, scale, n)
                self.last_k, self.h, self.drift, self.t_effect, self.current = (None, h, drift,
                                                                                t, None)
                return token
            ts = self._instant(t, h, end, tol, period, x)
            if ts is not None:  # also a repeated value: its instant updates the control
                if len(line) >= MAX_SAMPLES:
                    raise SensingError(timing.too_long(h))
                line.append((ts, x))
            while line:
                entry = line[0]
                e = entry[0] + d
                if e > end + tol:
                    break
                if e < t + tol:
                    e = t
                elif e > end - tol:
                    e = end
                elif self.off_grid is None:  # an effect strictly inside the step
                    self.off_grid = ("an effect instant", e, t, h)
                popped.append(line.popleft())
                if entry[1] != self.held:  # a repeated value leaves z's base as it is
                    self._switch(e, entry[1], scale, n)
                self.t_effect, self.current = e, entry
            self.h, self.drift = h, drift
        except BaseException:
            self.undo(token)
            raise
        return token

    def undo(self, token: Undo) -> None:
        """Return to the state before the :meth:`advance` that gave ``token``."""
        for name, value in zip(_FIELD_NAMES, token.saved):
            setattr(self, name, value)
        line = self.line
        line.extendleft(reversed(token.popped))
        while len(line) > token.length:
            line.pop()

    def is_instant(self, t: float, period: float) -> bool:
        """Whether the communication point ``t`` [s] is a sample instant."""
        if period <= (tol := TOLERANCE * self.h + self.drift):  # (the last step's)
            return True
        try:
            k = round((t - self.t0) / period)
            return abs(self.t0 + k * period - t) <= tol
        except (OverflowError, ValueError):
            return True

    def sensed(self, t: float, x_live: State, timing: Timing, feedthrough: bool) -> State:
        """The sensed state at the communication point ``t`` [s]: the live input if the delay is
        0, ``t`` a sample instant and ``feedthrough`` declared, else the sample in effect."""
        if (feedthrough and timing.sensing_delay <= TOLERANCE * self.h + self.drift
                and self.is_instant(t, timing.sample_period)):
            return x_live
        return self.held

    def integral_in_effect(self, t: float, timing: Timing, feedthrough: bool) -> State:
        """z for the control at the communication point ``t`` [s]: z(t) if the sample at ``t`` is
        in effect at once (see :meth:`sensed`), else z when the sample in effect took effect."""
        if (feedthrough and timing.sensing_delay <= TOLERANCE * self.h + self.drift
                and self.is_instant(t, timing.sample_period)):
            return self.integral(t)
        te, c = self.t_effect, self.current
        if c is not None and len(c) > 2:  # several instants: the latest in effect by t
            first, _, last, period = c
            d, tol = timing.sensing_delay, TOLERANCE * self.h + self.drift
            j = min(round((last - first) / period), math.floor((t + tol - d - first) / period))
            e = first + j * period + d
            te = max(te, t if e > t - tol else e)
        return self.integral(max(te, self.t_base))

    # -- FMU state ------------------------------------------------------------------------
    def to_dict(self) -> dict[str, Any]:
        """Everything, JSON-ready (floats exact)."""
        return {"t0": self.t0, "line": [[e[0], list(e[1]), *e[2:]] for e in self.line],
                "held": list(self.held), "z0": list(self.z0), "t_base": self.t_base,
                "x_plus": list(self.x_plus), "scale": list(self.scale), "n": self.n,
                "integrating": self.integrating, "last_k": self.last_k,
                "last_period": self.last_period, "h": self.h, "drift": self.drift,
                "t_effect": self.t_effect,
                "current": None if self.current is None else
                [self.current[0], list(self.current[1]), *self.current[2:]]}

    @classmethod
    def from_dict(cls, d: dict[str, Any], size: int) -> "Sensor":
        """The sensor of :meth:`to_dict`'s output; ``ValueError`` if it does not fit ``size``."""
        def vec(v: Sequence[Any], n: int | None = size) -> State:
            out = tuple(float(a) for a in v)
            if n is not None and len(out) != n:
                raise ValueError(f"the sensor state holds {len(out)} values, expected {n}")
            return out

        def entry(e: Sequence[Any]) -> tuple[Any, ...]:  # (ts, x) or (ts, x, last, period)
            if len(e) not in (2, 4):
                raise ValueError(f"a delay-line entry holds {len(e)} items, expected 2 or 4")
            return (float(e[0]), vec(e[1]), *(float(v) for v in e[2:]))

        s = cls(size, float(d["t0"]))
        if len(d["line"]) > MAX_SAMPLES:
            raise ValueError(f"the delay line holds {len(d['line'])} samples, more than "
                             f"{MAX_SAMPLES}")
        s.line.extend(entry(e) for e in d["line"])
        s.held, s.z0, s.x_plus = vec(d["held"]), vec(d["z0"]), vec(d["x_plus"])
        s.scale = vec(d["scale"], None)
        s.t_base, s.n, s.h, s.drift = (float(d[k]) for k in ("t_base", "n", "h", "drift"))
        s.integrating = bool(d["integrating"])
        s.last_k = None if d["last_k"] is None else int(d["last_k"])
        s.last_period = float(d["last_period"])
        s.t_effect = float(d["t_effect"])
        s.current = None if d["current"] is None else entry(d["current"])
        return s


_FIELD_NAMES = tuple(f.name for f in fields(Sensor))
_fields_of = operator.attrgetter(*_FIELD_NAMES)  # a sensor's fields, as a tuple (fast: per step)
