"""Neutral-stability check identified from co-simulated trajectories.

The closed loop sampled at the communication step is linear: z_(k+1) = F z_k,
with z = x+ (Gauss-Seidel) or z = (x+_k, x+_(k-1)) (Jacobi: the controller
holds the previous point's state). Runs of the real FMUs from the unit initial
states give pairs (z_k, z_(k+1)); F is their least-squares fit (each pair
scaled to unit |z_k|, so growing and decaying runs weigh alike), and the
continuous rates per wing beat are lambda = log(mu) / h+ for the eigenvalues
mu of F. Delay modes with |mu| ~ 0 have no continuous rate and are dropped.

Verdict, with tolerance ``TOL_PER_WINGBEAT`` = 1e-3 on the dominant real part
(under 1.3 % of the open-loop divergence rate 0.0786):
``unstable`` if max Re lambda > tol, ``neutral`` if |max Re lambda| <= tol,
``stable`` otherwise.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from ...models import lateral_interface
from ...models.lateral_interface import sort_eigenvalues
from ...models.linear import discretize_zoh
from ...core.errors import CrossCheckError

__all__ = ["FIT_RESIDUAL_TOL", "RATE_TOL_PER_WINGBEAT", "TOL_PER_WINGBEAT", "TRAJECTORY_TOL",
           "Identification", "Verdict", "checked", "classify", "cross_check_failures", "identify",
           "rates_from_transition", "relative_deviation", "sampled_closed_loop",
           "unit_start_values",
           "verdict_of"]

TOL_PER_WINGBEAT = 1e-3
#: Largest fit residual max |z_(k+1) - F z_k| / |z_k| of a loop that is the linear map
#: identified. The records are doubles of an exactly linear loop, so the residual is rounding
#: (1e-15 measured for the project's FMUs); an unmodelled state or a nonlinearity leaves far
#: more (3e-5 for the paper's gains saturating at u_max = 1e-3 rad, O(1) for a delay the map
#: has no state for). 1e-9 keeps four orders of margin on either side.
FIT_RESIDUAL_TOL = 1e-9
#: Largest |identified - exact| dominant rate per wing beat (the rate that decides the
#: verdict). A simple, separated eigenvalue moves by about its condition number (< 1e3 here)
#: times the residual, so a loop that passes the residual check agrees to 1e-12 or better; 1e-6
#: is the tolerance of the ``--system`` cross-check against eig(A + B K).
RATE_TOL_PER_WINGBEAT = 1e-6
#: Largest deviation of the co-simulated states from the exact sampled-data solution, relative
#: to each state's peak. Both sides accumulate one rounding per step in a loop whose transition
#: has norm near 1 (1e-13 measured over 300 steps); a loop other than the one modelled
#: deviates by O(1).
TRAJECTORY_TOL = 1e-8
#: |mu| below this: a pure delay, no continuous rate. Above the noise floor of the fitted
#: delay modes: a Jacobi fit at the 1e-5 wing-beat check step leaves them at 1e-12 to 3e-9
#: (a transition matrix 1 ulp off moves them across 1e-9); a physical mode this small would
#: decay at 16 / step per wing beat.
_DELAY_MODE = 1e-7


def rates_from_transition(F: np.ndarray, step_wb: float) -> np.ndarray:
    """Continuous eigenvalues per wing beat of a one-step transition matrix."""
    mu = np.linalg.eigvals(F)
    mu = mu[np.abs(mu) > _DELAY_MODE]
    return np.array(sort_eigenvalues(np.log(mu.astype(complex)) / step_wb), dtype=complex)


def classify(rates: np.ndarray, tol: float = TOL_PER_WINGBEAT) -> str:
    dominant = float(np.max(np.real(rates)))
    if dominant > tol:
        return "unstable"
    if dominant >= -tol:
        return "neutral"
    return "stable"


@dataclass(frozen=True)
class Identification:
    """Result of :func:`identify`."""

    transition: np.ndarray  # F
    eigenvalues: np.ndarray  # per wing beat, sorted
    dominant_growth_rate: float  # max Re, per wing beat
    verdict: str
    fit_residual: float  # max |z_(k+1) - F z_k| / |z_k| over all pairs


def identify(runs: list[np.ndarray], step_wb: float, delay: bool) -> Identification:
    """Fit F from state trajectories (each (N, 4), non-dimensional) and classify.

    Parameters
    ----------
    runs : list of ndarray
        Non-dimensional state trajectories x+_k of the loop; for ``delay`` the
        first row of each run is x+_(-1), the state the controller was fed
        before the first step.
    step_wb : float
        Communication step in wing beats.
    delay : bool
        Jacobi ordering (z stacks the current and the previous state).
    """
    z0, z1 = [], []
    for x in runs:
        z = np.hstack([x[1:], x[:-1]]) if delay else x
        z0.append(z[:-1])
        z1.append(z[1:])
    Z0, Z1 = np.vstack(z0), np.vstack(z1)
    w = 1.0 / np.maximum(np.linalg.norm(Z0, axis=1), 1e-300)
    A, B = Z0 * w[:, None], Z1 * w[:, None]
    Ft, *_ = np.linalg.lstsq(A, B, rcond=None)
    F = Ft.T
    resid = float(np.max(np.linalg.norm(B - A @ Ft, axis=1)))
    rates = rates_from_transition(F, step_wb)
    return Identification(F, rates, float(np.max(rates.real)), classify(rates), resid)


@dataclass(frozen=True)
class Verdict:
    """How an importer ran the closed loop: the identification and the runs it used."""

    identification: Identification
    runs: list[np.ndarray]  # non-dimensional state trajectories, one per unit initial state
    step_wb: float  # the communication step of the runs, in wing beats

    @property
    def verdict(self) -> str:
        """``unstable``, ``neutral`` or ``stable`` (:func:`classify`)."""
        return self.identification.verdict


def sampled_closed_loop(A: np.ndarray, B: np.ndarray, K: np.ndarray, step_wb: float,
                        jacobi: bool) -> np.ndarray:
    """The exact transition of the sampled-data loop over one step (zero-order hold,
    u_k = K x_k): Phi + Gamma K on x (Gauss-Seidel), or on z = (x_k, x_(k-1)) with the control
    of the previous point (Jacobi: [[Phi, Gamma K], [I, 0]])."""
    Phi, Gamma = discretize_zoh(A, B, step_wb)
    if not jacobi:
        return Phi + Gamma @ K
    n = len(A)
    return np.block([[Phi, Gamma @ K], [np.eye(n), np.zeros((n, n))]])


def unit_start_values(scale: np.ndarray, prefix: str = "",
                      states: Sequence[str] = lateral_interface.STATE_NAMES) -> list[dict[str, float]]:
    """The start values of the runs an identification needs: one per unit initial state
    x+_0 = e_i, dimensional (times ``scale``, e.g. [U, n, n, 1] for the lateral ``states``),
    named ``<prefix><state>_start``."""
    return [{f"{prefix}{s}_start": float(v) for s, v in zip(states, e * scale)}
            for e in np.eye(len(states))]


def verdict_of(runs: list[np.ndarray], step_wb: float, *, delay: bool, where: str) -> Verdict:
    """:func:`identify` the runs and :func:`checked` the fit (``where`` names the runner).

    Raises
    ------
    CrossCheckError
        The fit's residual exceeds :data:`FIT_RESIDUAL_TOL`.
    """
    return Verdict(checked(identify(runs, step_wb, delay), where), runs, step_wb)


def checked(ident: Identification, where: str) -> Identification:
    """``ident`` if its fit residual is within :data:`FIT_RESIDUAL_TOL`.

    Raises
    ------
    CrossCheckError
        The runs are not the linear loop of ``len(ident.transition)`` states that was fitted
        (``where`` names the importer), so its verdict is not theirs.
    """
    if not ident.fit_residual <= FIT_RESIDUAL_TOL:
        raise CrossCheckError(
            f"{where}: the identification's fit residual {ident.fit_residual:.1e} > "
            f"{FIT_RESIDUAL_TOL:g}: the runs are not the linear {len(ident.transition)}-state "
            f"loop identified, so its verdict {ident.verdict!r} is not theirs")
    return ident


def cross_check_failures(ident_rate: float, exact_rate: float, resid: float, err: float,
                         ident_verdict: str, exact_verdict: str, exact: str) -> list[str]:
    """The failed cross-checks of one run, one sentence each (empty: all passed).

    Parameters
    ----------
    ident_rate, exact_rate : float
        Dominant rate identified from the runs and that of the exact loop ``exact`` (named
        in the sentences), per wing beat.
    resid : float
        The identification's fit residual (:data:`FIT_RESIDUAL_TOL`).
    err : float
        The run's deviation from the exact solution, relative to each state's peak
        (:data:`TRAJECTORY_TOL`).
    ident_verdict, exact_verdict : str
        The two verdicts.
    """
    out = []
    if not resid <= FIT_RESIDUAL_TOL:
        out.append(f"the identification's fit residual {resid:.1e} > {FIT_RESIDUAL_TOL:g}: "
                   "the runs are not the linear loop identified")
    if not abs(ident_rate - exact_rate) <= RATE_TOL_PER_WINGBEAT:
        out.append(f"the identified dominant rate {ident_rate:+.6g} per wing beat deviates from "
                   f"{exact_rate:+.6g} of {exact} by {abs(ident_rate - exact_rate):.1e} > "
                   f"{RATE_TOL_PER_WINGBEAT:g}")
    if ident_verdict != exact_verdict:
        out.append(f"the identified verdict {ident_verdict!r} is not {exact_verdict!r} of {exact}")
    if not err <= TRAJECTORY_TOL:
        out.append(f"the co-simulated states deviate from the exact sampled-data solution by "
                   f"{err:.1e} of their peak > {TRAJECTORY_TOL:g}")
    return out


def relative_deviation(xs: np.ndarray, ref: np.ndarray) -> float:
    """max |xs - ref| relative to each state's peak |ref| (nan: nothing to compare)."""
    if not len(xs):
        return math.nan
    peak = np.maximum(np.abs(ref).max(axis=0), 1e-300)
    return float(np.max(np.abs(xs - ref) / peak))
