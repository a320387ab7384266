"""The controller's sensing delay and sampling on a sweep case's communication grid.

The controller FMU (``controller/README.md``) samples its inputs at t_k = k T (T =
``sample_period``; T = 0: at every communication point) and the control of the sample at t_k
appears at the first communication point t_j with t_k + tau <= t_j (times within 1e-9 of the
step count as equal), held until the next one appears. A sample sees the input set at the last
communication point at or before t_k. On the grid t_j = j h of a case the plant therefore sees

    u_j = K x_g(j),   g(j) = the grid point sampled by the latest sample in effect at t_j,

and u_j = 0 before the first sample takes effect (the delay line starts at the equilibrium).
With the Jacobi master the controller's output at t_j is read before x_j is set, so a sample
at t_j with no delay gives K x_(j-1) there (x_0 at j = 0, the master's default) and K x_j from
the next point on. The lag j - g(j) is periodic in j (period p steps once T / h is rational),
so the loop on the grid is linear and periodic: its monodromy over p steps in the state
Y_j = [x_j; x_(j-1); ...; x_(j-L)] gives its eigenvalues exactly (:func:`grid_monodromy`).

Where the sample instants lie on the grid (T = 0, or T a whole number of steps), this is model
(b) of :mod:`dronefly.harness.latency.sampled` with the sample period T (or h) and the
effective delay ceil(tau / h) h, the first grid point at or after t_k + tau
(:meth:`GridTiming.model_b`); with Jacobi and no effective delay only for T = h (then the delay is
one step). All times in wing beats.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ...models.linear import discretize_zoh

__all__ = ["MAX_PERIOD_STEPS", "TOL", "GridTiming", "grid_monodromy", "grid_simulate",
           "timing_params"]

#: Times closer than this fraction of the step count as equal (the controller FMU's rule).
TOL = 1e-9
#: Periods of the lag pattern longer than this many steps get no grid model.
MAX_PERIOD_STEPS = 1000


def timing_params(case: Any, n_hz: float) -> dict[str, float]:
    """``sensing_delay`` and ``sample_period`` [s] of a case (wing beats / ``n_hz`` [Hz]); empty
    when both are 0, so that a case without them sets no timing parameter at all."""
    if not (case.delay_wb or case.sample_period_wb):
        return {}
    return {"sensing_delay": case.delay_wb / n_hz, "sample_period": case.sample_period_wb / n_hz}


@dataclass(frozen=True)
class GridTiming:
    """Communication step ``h``, sensing delay ``tau``, sample period ``T`` (0: every step),
    all in wing beats, and the master's ordering (``jacobi``)."""

    h: float
    tau: float
    T: float
    jacobi: bool = False

    @property
    def Ts(self) -> float:
        """The sample period in effect, wing beats: T, or the step when T = 0."""
        return self.T if self.T > 0.0 else self.h

    @cached_property
    def tau_eff(self) -> float:
        """The delay rounded up to the grid, wing beats (the first point at or after t_k + tau)."""
        return math.ceil(self.tau / self.h - TOL) * self.h

    def model_b(self) -> tuple[float, float] | None:
        """(Ts, delay) of model (b) when it is this loop (sample instants on the grid), else None."""
        m = self.Ts / self.h
        if abs(m - round(m)) > TOL * max(1.0, m) or round(m) < 1:
            return None
        if self.jacobi and self.tau_eff == 0.0:
            return (self.h, self.h) if round(m) == 1 else None
        return self.Ts, self.tau_eff

    def lag(self, j: int) -> int | None:
        """j - g(j): how many steps back the control in effect at t_j sampled (None: none yet)."""
        h, tol = self.h, TOL * self.h
        t = j * h - self.tau
        if t < -tol:
            return None
        if self.T > 0.0:
            tk = math.floor((t + tol) / self.T) * self.T
        else:
            tk = math.floor((t + tol) / h) * h
        g = math.floor((tk + tol) / h)
        if self.jacobi and g == j and self.tau <= tol:
            g = j - 1
        return j - g

    @cached_property
    def period_steps(self) -> int | None:
        """p: lag(j + p) = lag(j) for every j past the start (None: T / h not a ratio of
        integers up to ``MAX_PERIOD_STEPS``)."""
        if self.T == 0.0:
            return 1
        for q in range(1, MAX_PERIOD_STEPS + 1):
            r = q * self.T / self.h
            if abs(r - round(r)) <= TOL * max(1.0, r) and round(r) >= 1:
                return int(round(r)) if round(r) <= MAX_PERIOD_STEPS else None
        return None

    def start(self) -> int:
        """A point from which on every lag is defined and periodic (a multiple of p)."""
        p = self.period_steps or 1
        return p * math.ceil((self.tau + self.Ts + 2.0 * self.h) / (p * self.h))


def grid_monodromy(A: NDArray, B: NDArray, K: NDArray,
                   timing: GridTiming) -> tuple[NDArray[np.float64], float] | None:
    """The loop's transition over one period of the lag pattern, and that period [wing beats].

    Parameters
    ----------
    A, B : ndarray
        Plant per wing beat (x+' = A x+ + B u, u in rad).
    K : ndarray
        Gains, rad per unit of x+ (no integral action: the grid model has none).
    timing : GridTiming

    Returns
    -------
    (M, P) with Y_(j+p) = M Y_j and P = p h wing beats, or None when ``timing`` has no period
    (its eigenvalues mu give the rates log(mu) / P per wing beat).
    """
    p = timing.period_steps
    if p is None:
        return None
    n = len(A)
    Phi, Gam = discretize_zoh(np.asarray(A, float), np.asarray(B, float), timing.h)
    GK = Gam @ np.asarray(K, float)
    j0 = timing.start()
    lags = [timing.lag(j) for j in range(j0, j0 + p)]
    L = max(lags)
    N = n * (L + 1)
    M = np.eye(N)
    for lag in lags:
        T = np.zeros((N, N))
        T[:n, :n] = Phi
        T[:n, lag * n:(lag + 1) * n] += GK
        T[n:, :-n] = np.eye(N - n)
        M = T @ M
    return M, p * timing.h


def grid_simulate(A: NDArray, B: NDArray, K: NDArray, timing: GridTiming, x0: NDArray,
                  n_steps: int) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """States and controls at the communication points, simulated from the timing alone.

    Parameters
    ----------
    A, B, K : ndarray
        Plant per wing beat and gains (rad per unit of x+).
    timing : GridTiming
    x0 : (r, n) ndarray
        Initial states x+, one row per run (all simulated at once).
    n_steps : int
        Communication steps.

    Returns
    -------
    x : (n_steps + 1, r, n) ndarray
        x+ at t_j = j h.
    u : (n_steps + 1, r, m) ndarray
        Controls in effect over [t_j, t_(j+1)), rad.
    """
    Phi, Gam = discretize_zoh(np.asarray(A, float), np.asarray(B, float), timing.h)
    K = np.asarray(K, float)
    x0 = np.atleast_2d(np.asarray(x0, float))
    x = np.empty((n_steps + 1, *x0.shape))
    u = np.zeros((n_steps + 1, len(x0), len(K)))
    x[0] = x0
    for j in range(n_steps + 1):
        lag = timing.lag(j)
        if lag is not None:
            u[j] = x[max(j - lag, 0)] @ K.T
        if j < n_steps:
            x[j + 1] = x[j] @ Phi.T + u[j] @ Gam.T
    return x, u
