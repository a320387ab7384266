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

from dataclasses import dataclass

import numpy as np

from dronefly import lateral

__all__ = ["TOL_PER_WINGBEAT", "Identification", "classify", "identify", "rates_from_transition",
           "sort_eigenvalues"]

TOL_PER_WINGBEAT = 1e-3
#: |mu| below this: a pure delay, no continuous rate. Above the noise floor of the fitted
#: delay modes: a Jacobi fit at the 1e-5 wing-beat check step leaves them at 1e-12 to 3e-9
#: (a transition matrix 1 ulp off moves them across 1e-9); a physical mode this small would
#: decay at 16 / step per wing beat.
_DELAY_MODE = 1e-7


def sort_eigenvalues(ev: np.ndarray) -> np.ndarray:
    """As an array, in the order of :func:`dronefly.lateral.sort_eigenvalues`."""
    return np.array(lateral.sort_eigenvalues(np.ravel(ev)), dtype=complex)


def rates_from_transition(F: np.ndarray, step_wb: float) -> np.ndarray:
    """Continuous eigenvalues per wing beat of a one-step transition matrix."""
    mu = np.linalg.eigvals(F)
    mu = mu[np.abs(mu) > _DELAY_MODE]
    return sort_eigenvalues(np.log(mu.astype(complex)) / step_wb)


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
