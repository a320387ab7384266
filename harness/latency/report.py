"""The numbers of docs/latency.md: delay margins, the cost of latency, redesigns.

Everything at the drone fly's n = 164 Hz (1 wing beat = 6.098 ms); model (b) samples once
per wing beat (Chang & Wang 2014). Responses start from a unit roll-angle disturbance
x+_0 = (0, 0, 0, 1) with the delay line at the equilibrium (a push the controller senses
only after the delay); the linear loops scale, so peaks are rad per rad of roll.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable

import numpy as np
from scipy.optimize import brentq

from .continuous import DelayMargin, delay_margin
from .designs import DESIGNS, bryson_weights, design, designs
from .loop import FeedbackLoop, LatencyInputError
from .sampled import Response, SampledMargin, excess_rate, response, sampled_margin, sampled_rates
from ..cosim.identification import classify
from ..paper.analysis import lateral_system
from ..paper.design import lqr_gains
from ..paper.rows import markdown_table
from ...models.lateral_interface import CONTROL_NAMES, N_HZ

__all__ = ["COST_DELAYS_MS", "MarginRow", "ROLL", "Redesign", "TARGETS_MS", "cost", "cost_table",
           "margin_rows", "margin_table", "markdown", "ms_to_wb", "redesign_table", "redesigns",
           "wb_to_ms"]

#: Delays of the cost table, ms: none, the roll reflex (Beatus et al. 2015), pitch
#: (Whitehead et al. 2015), visual feedback (20-30 ms).
COST_DELAYS_MS: tuple[float, ...] = (0.0, 5.0, 10.0, 20.0, 30.0)
#: Margins the redesigns aim at, ms (model (b)).
TARGETS_MS: tuple[float, ...] = (5.0, 30.0)
#: The disturbance of the responses: a unit roll angle, x+.
ROLL: tuple[float, ...] = (0.0, 0.0, 0.0, 1.0)


def wb_to_ms(tau: float, n_hz: float = N_HZ) -> float:
    """Wing beats -> ms at ``n_hz`` [Hz]."""
    return 1e3 * tau / n_hz


def ms_to_wb(ms: float, n_hz: float = N_HZ) -> float:
    """ms -> wing beats at ``n_hz`` [Hz]."""
    return ms * 1e-3 * n_hz


@dataclass(frozen=True)
class MarginRow:
    """One design's margins (a) and (b) and its delay-free response."""

    name: str
    loop: FeedbackLoop
    continuous: DelayMargin
    sampled: SampledMargin
    undelayed: Response


def margin_rows() -> list[MarginRow]:
    """Margins of every design of :data:`~.designs.DESIGNS`."""
    return [MarginRow(name, loop, delay_margin(loop), sampled_margin(loop),
                      response(loop, ROLL)) for name, loop in designs().items()]


def cost(loop: FeedbackLoop, delay_ms: float) -> tuple[str, Response | None]:
    """Verdict of model (b) at a delay (ms) and, unless unstable, the roll response."""
    tau = ms_to_wb(delay_ms)
    verdict = classify(sampled_rates(loop, 1.0, tau))
    return verdict, None if verdict == "unstable" else response(loop, ROLL, 1.0, tau)


@dataclass(frozen=True)
class Redesign:
    """A gain factor that gives a margin (b) of ``target_ms``; the roll response without delay
    and at half the target delay."""

    family: str
    target_ms: float
    factor: float
    gains: np.ndarray
    undelayed: Response
    half: Response


def _lqr_weighted(rho: float) -> FeedbackLoop:
    A, B = lateral_system()
    q, r = bryson_weights()
    K = np.zeros((len(CONTROL_NAMES), 4))
    K[0] = lqr_gains(A, B, CONTROL_NAMES[0], q, r * rho)
    return FeedbackLoop(A, B, K, None, f"LQR, R x {rho:g}")


#: (family, loop of the factor, bracket of the factor). Eq. (27) times alpha moves lambda_1
#: to 0.0786 (1 - alpha) and keeps the other eigenvalues (coefficient matching is affine in
#: the targets, and only lambda_1's factor changes), so the stabilising design is Eq. (27)
#: (exact) x 2.27 and no alpha < 1 is stable; the LQR is scaled by alpha, or redesigned with
#: the control weight R times rho.
_FAMILIES: tuple[tuple[str, Callable[[float], FeedbackLoop], tuple[float, float]], ...] = (
    ("Eq. (27) (exact) x alpha", lambda a: design("eq27_exact").scaled(a), (1.0, 30.0)),
    ("LQR gains x alpha", lambda a: design("lqr").scaled(a), (0.12, 1.0)),
    ("LQR with R x rho", _lqr_weighted, (1.0, 1000.0)),
)


def redesigns(targets_ms: tuple[float, ...] = TARGETS_MS) -> list[Redesign]:
    """For each family of :data:`_FAMILIES` and target: the factor at which the margin (b)
    equals the target, and the roll responses without delay and at half the target delay.

    The factor solves excess_rate(loop(factor), 1, target) = 0 (a root on the unit circle at
    the target delay) by Brent's method over the bracket (``nan`` if the bracket holds no
    change); :func:`~.sampled.sampled_margin` then confirms that the target is the *first*
    delay at which the verdict is lost.

    Raises
    ------
    LatencyInputError
        The root found is not the design's margin.
    """
    out = []
    for family, make, (lo, hi) in _FAMILIES:
        for target in targets_ms:
            tau = ms_to_wb(target)

            def excess(p: float) -> float:
                return excess_rate(make(p), 1.0, tau)[0]

            if excess(lo) * excess(hi) > 0.0:
                nan = Response(math.nan, math.nan, math.nan)
                out.append(Redesign(family, target, math.nan, np.full(4, math.nan), nan, nan))
                continue
            p = brentq(excess, lo, hi, xtol=1e-12, rtol=1e-10)
            loop = make(p)
            margin = sampled_margin(loop, tau_limit=tau + 1.0).tau
            if abs(margin - tau) > 1e-6:
                raise LatencyInputError(f"{family}: factor {p:.6g} loses the verdict at "
                                        f"{margin!r} wing beats, before {tau!r}")
            out.append(Redesign(family, target, float(p), loop.K[0].copy(),
                                response(loop, ROLL), response(loop, ROLL, 1.0, tau / 2)))
    return out


# --- markdown ---------------------------------------------------------------------------------
def _f(x: float, digits: int = 4) -> str:
    return "inf" if math.isinf(x) else f"{x:.{digits}f}"


def _rec(r: Response) -> str:
    if math.isinf(r.recovery):
        return f"never (settles at {100 * r.final_offset:.0f} %)"
    return f"{r.recovery:.0f} wb ({wb_to_ms(r.recovery):.0f} ms)"


_HOW = {"hopf": "pair at +/- i {w} /wb", "origin": "real root through s = 0",
        "tolerance": "small root reaches +1e-3 /wb", "none": "-"}


def margin_table(rows: list[MarginRow]) -> list[str]:
    def cells(r: MarginRow) -> list[str]:
        k = ", ".join(f"{v:.4f}" for v in r.loop.K[0])
        ki = f"{r.loop.KI[0, 3]:.4f}" if r.loop.integrated else "-"
        w = r.continuous.crossing.omega if r.continuous.crossing else 0.0
        how = _HOW[r.continuous.kind].format(w=f"{w:.4f}")
        return [r.loop.name, k, ki, _f(r.continuous.tau, 3), _f(r.continuous.ms(N_HZ), 1), how,
                str(r.sampled.whole), _f(r.sampled.tau, 3), _f(r.sampled.ms(N_HZ), 1)]

    return markdown_table(["design", "k (dv+, dp+, dr+, dgamma)", "kI", "(a) wb", "(a) ms",
                           "(a) lost by", "(b) whole wb", "(b) wb", "(b) ms"], map(cells, rows))


def cost_table() -> list[str]:
    def cells(loop: FeedbackLoop) -> list[str]:
        out = [loop.name]
        for d in COST_DELAYS_MS:
            verdict, r = cost(loop, d)
            out.append("unstable" if r is None else
                       f"{verdict}: {r.peak_control:.3f} rad, {_rec(r)}")
        return out

    head = [f"{d:g} ms ({ms_to_wb(d):.2f} wb)" for d in COST_DELAYS_MS]
    return markdown_table(["design", *head], (cells(design(name)) for name in DESIGNS))


def redesign_table(rows: list[Redesign]) -> list[str]:
    def cells(r: Redesign) -> list[str]:
        if math.isnan(r.factor):
            return [r.family, f"{r.target_ms:g} ms", "not in the bracket", "-", "-", "-"]
        return [r.family, f"{r.target_ms:g} ms", f"{r.factor:.4g}",
                ", ".join(f"{v:.3f}" for v in r.gains),
                f"{r.undelayed.peak_control:.3f} rad, {_rec(r.undelayed)}",
                f"{r.half.peak_control:.3f} rad, {_rec(r.half)}"]

    return markdown_table(["family", "margin (b)", "factor", "k (dv+, dp+, dr+, dgamma)",
                           "no delay: peak, recovery", "half that delay: peak, recovery"],
                          map(cells, rows))


def markdown() -> dict[str, str]:
    """The three tables of docs/latency.md, by name (``margins``, ``costs``, ``redesigns``)."""
    return {"margins": "\n".join(margin_table(margin_rows())),
            "costs": "\n".join(cost_table()),
            "redesigns": "\n".join(redesign_table(redesigns()))}
