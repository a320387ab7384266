"""The rightmost roots of the delayed loop by Chebyshev collocation (second method for (a)).

The delay equation X'(t) = A_a X(t) + B_a K_a X(t - tau) is a linear evolution of the
history segment on [-tau, 0]; its infinitesimal generator is discretised by collocation at
the N + 1 Chebyshev extremal points theta_j = tau (cos(j pi / N) - 1) / 2 (Breda, Maset &
Vermiglio, SIAM J. Sci. Comput. 27, 2005, the method of DDE-BIFTOOL's ``eigAppr``): the first
block row is the equation at theta_0 = 0, [A_a, 0, ..., 0, B_a K_a]; the others are the
derivative by the Chebyshev differentiation matrix. Its eigenvalues converge to the
rightmost roots of the quasi-polynomial spectrally fast in N. It shares nothing with
:mod:`.continuous` but the loop's matrices, so it cross-checks the delay margins there.
Rates per wing beat, delays in wing beats.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import brentq

from .loop import NEUTRAL_RATE, FeedbackLoop, LatencyInputError

__all__ = ["chebyshev_differentiation", "collocation_margin", "collocation_roots",
           "dominant_root"]

#: collocation points beyond the first (the lateral loops' rightmost roots converge to
#: about 1e-15 from 12 on)
N_POINTS = 16


def chebyshev_differentiation(N: int) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Points x_j = cos(j pi / N), j = 0..N, and the differentiation matrix D on [-1, 1]
    (Trefethen, *Spectral Methods in MATLAB*, 2000, ``cheb``)."""
    if N < 1:
        raise LatencyInputError(f"N = {N!r} collocation points: need at least 1")
    x = np.cos(np.pi * np.arange(N + 1) / N)
    c = np.ones(N + 1)
    c[0] = c[-1] = 2.0
    c *= (-1.0) ** np.arange(N + 1)
    dX = x[:, None] - x[None, :]
    D = np.outer(c, 1.0 / c) / (dX + np.eye(N + 1))
    D -= np.diag(D.sum(axis=1))
    return x, D


def collocation_roots(loop: FeedbackLoop, tau: float, N: int = N_POINTS) -> NDArray[np.complex128]:
    """Approximate roots of det(s I - A_a - B_a K_a e^(-s tau)), descending real part.

    Parameters
    ----------
    tau : float
        Delay, wing beats (>= 0; 0 gives the eigenvalues of A_a + B_a K_a).
    N : int
        Collocation points beyond theta_0.
    """
    if not (math.isfinite(tau) and tau >= 0.0):
        raise LatencyInputError(f"tau = {tau!r} wing beats must be finite and >= 0")
    Aa, Ba, Ka = loop.augmented()
    if tau == 0.0:
        ev = np.linalg.eigvals(Aa + Ba @ Ka)
    else:
        n = len(Aa)
        _, D = chebyshev_differentiation(N)
        G = np.kron((2.0 / tau) * D, np.eye(n))
        G[:n, :] = 0.0
        G[:n, :n] = Aa
        G[:n, N * n:] = Ba @ Ka
        ev = np.linalg.eigvals(G)
    return ev[np.lexsort((-ev.imag, -ev.real))]


def dominant_root(loop: FeedbackLoop, tau: float, N: int = N_POINTS) -> complex:
    """The rightmost root other than the neutral one (for a neutral loop: the root nearest
    s = 0 is left out)."""
    ev = collocation_roots(loop, tau, N)
    if loop.neutral:
        ev = np.delete(ev, int(np.argmin(np.abs(ev))))
    return complex(ev[0])


def collocation_margin(loop: FeedbackLoop, tau_lo: float, tau_hi: float, N: int = N_POINTS,
                       tol: float = 1e-13) -> float:
    """The delay in [tau_lo, tau_hi] at which the dominant root reaches Re s = 0, by Brent's
    method on its real part: for a neutral loop the dominant root other than the one nearest
    s = 0; for a near-neutral one (not exactly neutral) the rightmost root reaching +1e-3.

    Raises
    ------
    LatencyInputError
        The interval does not bracket a change.
    """
    def excess(tau: float) -> float:
        if loop.neutral and not loop.exactly_neutral:
            return float(collocation_roots(loop, tau, N)[0].real) - NEUTRAL_RATE
        return dominant_root(loop, tau, N).real

    lo, hi = float(tau_lo), float(tau_hi)
    if not excess(lo) < 0.0 < excess(hi):
        raise LatencyInputError(f"[{lo!r}, {hi!r}] wing beats does not bracket the margin")
    return float(brentq(excess, lo, hi, xtol=tol, rtol=1e-15))
