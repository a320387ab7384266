"""The numbers of docs/latency.md's sweep over sensing delay x sample period.

``docs/latency_map.png`` is the ``map_delay_period.png`` of :data:`MAP_COMMAND`: the paper's
gains (Eq. 27) and the stabilising design, communication step half a wing beat, the delays
:data:`MAP_DELAYS_WB` x the sample periods :data:`MAP_PERIODS_WB`, from the ten box directions
at four amplitudes each (40 disturbances per cell), 200 wing beats each. :func:`table`
recomputes the doc's table from the timing alone (:func:`..latency.grid.grid_simulate`, which
reproduces the FMUs' trajectories to rounding; tests) and model (b) (the margins,
:func:`dronefly.harness.latency.sampled.sampled_margin`), so the test that compares the doc
with it costs a second, not the sweep's minute.

The other tables of docs/latency.md (margins of every design, the cost of latency, the
redesigns) are :mod:`dronefly.harness.latency.report`'s. Kept apart on purpose: this table
needs the sweep's cases (:mod:`.cases`, a floor above ``harness.latency``, which latency may
not import), and the one number both tables show, margin (b) at one sample per wing beat,
has one home, :func:`dronefly.harness.latency.sampled.sampled_margin`, which both call; the
wing beat to ms conversion is the report's :func:`~dronefly.harness.latency.report.wb_to_ms`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ...models.lateral_interface import N_HZ
from ..cosim.identification import classify
from ..latency.grid import GridTiming, grid_simulate
from ..latency.loop import FeedbackLoop
from ..latency.report import wb_to_ms
from ..latency.sampled import SampledMargin, sampled_margin, sampled_rates
from ..paper.analysis import lateral_system
from ..paper.gains import gain_matrix
from ..paper.rows import markdown_table
from .cases import CONTROL_BOUND, STATE_BOUNDS_SECT36, SweepSpec

__all__ = ["Cell", "MAP_COMMAND", "MAP_DELAYS_WB", "MAP_PERIODS_WB", "MAP_STEP_WB",
           "TABLE_DELAYS_WB", "cell", "cells", "map_spec", "margins", "table"]

MAP_STEP_WB = 0.5
MAP_DELAYS_WB: tuple[float, ...] = (0, 1, 2, 3, 4, 5, 6, 8, 10, 12)
MAP_PERIODS_WB: tuple[float, ...] = (0, 1, 2, 3, 4)
MAP_STOP_WB = 200.0
#: Delays of the table: none, the roll reflex (5 ms -> 1 wb on the half-wing-beat grid), pitch
#: (10 ms -> 2 wb), vision (30 ms -> 5 wb).
TABLE_DELAYS_WB: tuple[float, ...] = (0, 1, 2, 5)
_GAINS = ("paper", "stabilising")
_RECOVERY_HORIZON_WB = 400.0


def _csv(values: tuple[float, ...]) -> str:
    return ",".join(f"{v:g}" for v in values)


MAP_COMMAND = (f"dronefly sweep --gains {','.join(_GAINS)} --disturbances directions "
               f"--amplitudes 4 --steps {MAP_STEP_WB:g} --delays {_csv(MAP_DELAYS_WB)} "
               f"--sample-periods {_csv(MAP_PERIODS_WB)} --stop {MAP_STOP_WB:g}")


def map_spec() -> SweepSpec:
    """The :class:`SweepSpec` of :data:`MAP_COMMAND`."""
    return SweepSpec(disturbances=("directions",), amplitudes=4, gains=_GAINS,
                     steps_wb=(MAP_STEP_WB,), stop_wb=MAP_STOP_WB,
                     delays_wb=tuple(map(float, MAP_DELAYS_WB)),
                     sample_periods_wb=tuple(map(float, MAP_PERIODS_WB)))


@dataclass(frozen=True)
class Cell:
    """One (gains, delay, sample period) of the map.

    Attributes
    ----------
    verdict : str
        Model (b) at the FMU's timing (stable, neutral, unstable).
    share : float
        Fraction of the 40 disturbances that stay within the Sect. 3.6 bounds.
    peak_control : float
        Largest |u| over them, rad.
    recovery : float
        Wing beats until a roll at its bound (0.22 rad) stays within 5 % of its initial
        box-normalised deviation (``inf``: not within 400 wing beats).
    settles : float
        That deviation after 400 wing beats, a fraction of the initial one.
    """

    verdict: str
    share: float
    peak_control: float
    recovery: float
    settles: float


def cell(K: np.ndarray, delay: float, period: float) -> Cell:
    """The map's cell of gains ``K`` at ``delay`` and ``period`` (wing beats; see the module)."""

    A, B = lateral_system()
    timing = GridTiming(MAP_STEP_WB, delay, period)
    verdict = classify(sampled_rates(FeedbackLoop(A, B, K), *timing.model_b()))
    box = np.asarray(STATE_BOUNDS_SECT36)
    x0 = np.array([x for *_, x in map_spec().initial_states()])
    x, u = grid_simulate(A, B, K, timing, x0, int(round(MAP_STOP_WB / MAP_STEP_WB)))
    r = np.maximum(np.max(np.abs(x) / box, axis=(0, 2)), np.max(np.abs(u), axis=(0, 2)) / CONTROL_BOUND)
    share = float(np.mean(r <= 1.0 + 1e-9))
    roll = np.array([0.0, 0.0, 0.0, box[3]])
    steps = int(round(_RECOVERY_HORIZON_WB / MAP_STEP_WB))
    xr, _ = grid_simulate(A, B, K, timing, roll[None, :], steps)
    dev = np.max(np.abs(xr[:, 0]) / box, axis=1)  # the roll starts at its bound: dev(0) = 1
    above = np.flatnonzero(dev > 0.05)
    recovery = (math.inf if len(above) and above[-1] == steps
                else float((above[-1] + 1) * MAP_STEP_WB) if len(above) else 0.0)
    return Cell(verdict, share, float(np.max(np.abs(u))), recovery, float(dev[-1]))


def _text(c: Cell) -> str:
    rec = (f"{c.recovery:.0f} wb" if math.isfinite(c.recovery)
           else f"never ({100 * c.settles:.0f} % left)")
    return f"{c.verdict}: {100 * c.share:.0f} %, {c.peak_control:.2f} rad, {rec}"


def margins() -> dict[tuple[str, float], SampledMargin]:
    """Margin (b) per gain set and sample period of the map (0: the step)."""

    A, B = lateral_system()
    return {(g, T): sampled_margin(FeedbackLoop(A, B, gain_matrix(g)), T or MAP_STEP_WB,
                                   tau_limit=16.0)
            for g in _GAINS for T in MAP_PERIODS_WB}


def cells(delays: tuple[float, ...] = TABLE_DELAYS_WB) -> dict[tuple[str, float, float], Cell]:
    """:func:`cell` per gain set, sample period and delay (of ``delays``)."""
    return {(g, T, d): cell(gain_matrix(g), float(d), float(T))
            for g in _GAINS for T in MAP_PERIODS_WB for d in delays}


def table(m: dict | None = None, c: dict | None = None) -> list[str]:
    """The doc's table: per gains and sample period, margin (b) and the cells at
    :data:`TABLE_DELAYS_WB` (verdict; share within the bounds; peak control; roll recovery).
    ``m``, ``c``: :func:`margins` and :func:`cells`, if computed already."""
    m, c = m or margins(), c or cells()
    rows = []
    for g in _GAINS:
        for T in MAP_PERIODS_WB:
            period = (f"{T:g} wb ({wb_to_ms(T):.1f} ms)" if T
                      else f"every step ({MAP_STEP_WB:g} wb)")
            rows.append([g, period, f"{m[(g, T)].tau:.2f} wb ({m[(g, T)].ms(N_HZ):.1f} ms)",
                         *(_text(c[(g, T, d)]) for d in TABLE_DELAYS_WB)])
    head = [f"{d:g} wb ({wb_to_ms(d):.1f} ms)" for d in TABLE_DELAYS_WB]
    return markdown_table(["gains", "sample period", "margin (b)", *head], rows)
