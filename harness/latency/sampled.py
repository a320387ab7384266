"""Sampling with a sensing delay (model (b)): the exact augmented discrete-time loop.

The controller samples x at t_k = k Ts; the control computed from the sample at t_k,
u_k = K x_k + KI z_k, takes effect at t_k + tau and is held until the next one takes
effect. z_k = Ts C (x_0 + ... + x_(k-1)) is the exact integral of the sensed (held,
delayed) state up to the instant u_k takes effect. Before t = 0 the delay line holds the
equilibrium (x = 0, z = 0, so u = 0 until the first sample takes effect).

With tau = d Ts + eps (0 <= eps < Ts), over [t_k, t_(k+1)) the control is u_(k-d-1) until
t_k + eps and u_(k-d) after, so the plant, integrated exactly (zero-order hold by the
matrix exponential of the augmented matrix, :func:`dronefly.models.linear.discretize_zoh`), gives

    x_(k+1) = Phi x_k + Gamma(Ts - eps) u_(k-d) + e^(A (Ts - eps)) Gamma(eps) u_(k-d-1),

Phi = e^(A Ts), Gamma(h) = int_0^h e^(A s) ds B (the modified-z transform; eps = 0 drops the
last term). The state X_k = [x_k; x_(k-1); ...; x_(k-D); z_k], D = d (eps = 0) or d + 1,
evolves as X_(k+1) = M X_k. Its non-zero eigenvalues mu are the loop's, z = e^(s Ts); the
zero ones are pure delay. A neutral loop keeps mu = 1 exactly for every delay (the steady
state (A + B K) x = 0 does not depend on it). Times in wing beats (Ts = 1: once per wing
beat).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..cosim.identification import classify, rates_from_transition
from .loop import NEUTRAL_RATE, FeedbackLoop, LatencyInputError
from ...models.linear import discretize_zoh
from ...models.lateral_interface import STATE_BOUNDS_SECT36

__all__ = ["Response", "SampledMargin", "delay_split", "excess_rate", "response",
           "sampled_margin", "sampled_matrix", "sampled_rates", "verdict_map"]

Array = NDArray[np.float64]


def delay_split(tau: float, Ts: float) -> tuple[int, float]:
    """(d, eps) with tau = d Ts + eps, 0 <= eps < Ts (a ratio within 1e-9 of a whole number
    counts as whole)."""
    for name, v in (("tau", tau), ("Ts", Ts)):
        if not math.isfinite(v) or v < 0.0 or (name == "Ts" and v == 0.0):
            raise LatencyInputError(f"{name} = {v!r} wing beats must be finite and "
                                    + (">= 0" if name == "tau" else "> 0"))
    r = tau / Ts
    if abs(r - round(r)) <= 1e-9 * max(1.0, r):
        return int(round(r)), 0.0
    d = math.floor(r)
    return int(d), tau - d * Ts


@lru_cache(maxsize=256)
def _zoh(A: bytes, B: bytes, n: int, h: float) -> tuple[Array, Array]:
    """:func:`discretize_zoh` of (A, B) given as bytes (cached: scans repeat the same steps)."""
    a = np.frombuffer(A).reshape(n, n)
    return discretize_zoh(a, np.frombuffer(B).reshape(n, -1), h)


def _discretize(loop: FeedbackLoop, h: float) -> tuple[Array, Array]:
    return _zoh(loop.A.tobytes(), loop.B.tobytes(), loop.n, float(h))


def _u_rows(loop: FeedbackLoop, j: int, D: int, Ts: float) -> Array:
    """R_j with u_(k-j) = R_j X_k (see the module text)."""
    n, q = loop.n, len(loop.integrated)
    R = np.zeros((loop.m, n * (D + 1) + q))
    R[:, j * n:(j + 1) * n] += loop.K
    if q:
        KIc = loop.KI @ loop.C.T
        for i in range(1, j + 1):
            R[:, i * n:(i + 1) * n] -= Ts * KIc @ loop.C
        R[:, n * (D + 1):] = KIc
    return R


def sampled_matrix(loop: FeedbackLoop, Ts: float = 1.0, tau: float = 0.0) -> Array:
    """M with X_(k+1) = M X_k for sample period ``Ts`` and delay ``tau`` (wing beats)."""
    d, eps = delay_split(tau, Ts)
    D = d + (1 if eps > 0.0 else 0)
    n, q = loop.n, len(loop.integrated)
    N = n * (D + 1) + q
    M = np.zeros((N, N))
    if eps > 0.0:
        # one matrix exponential per eps: [Phi, Gamma](Ts - eps) = [Phi, Gamma](Ts) after
        # the inverse of [Phi, Gamma](eps)
        Pt, Gt = _discretize(loop, Ts)
        Pe, Ge = _discretize(loop, eps)
        Phi = np.linalg.solve(Pe.T, Pt.T).T  # e^(A (Ts - eps))
        Gb = Gt - Phi @ Ge
        M[:n] += Gb @ _u_rows(loop, d, D, Ts) + Phi @ Ge @ _u_rows(loop, d + 1, D, Ts)
        Phi = Pt
    else:
        Phi, Gb = _discretize(loop, Ts)
        M[:n] += Gb @ _u_rows(loop, d, D, Ts)
    M[:n, :n] += Phi
    for i in range(1, D + 1):
        M[i * n:(i + 1) * n, (i - 1) * n:i * n] = np.eye(n)
    if q:
        M[n * (D + 1):, :n] = Ts * loop.C
        M[n * (D + 1):, n * (D + 1):] = np.eye(q)
    return M


def sampled_rates(loop: FeedbackLoop, Ts: float = 1.0, tau: float = 0.0) -> NDArray[np.complex128]:
    """The loop's continuous rates log(mu) / Ts per wing beat (delay modes mu = 0 dropped)."""
    return rates_from_transition(sampled_matrix(loop, Ts, tau), Ts)


def excess_rate(loop: FeedbackLoop, Ts: float, tau: float) -> tuple[float, complex]:
    """The largest rate log|mu| / Ts (per wing beat) that counts against the verdict, > 0 when
    it is lost, and its eigenvalue mu: over every eigenvalue of a stable loop; for a neutral
    one over all but the eigenvalue nearest mu = 1, which (if the loop is not exactly
    neutral) counts by its excess over the tolerance 1e-3 per wing beat."""
    mu = np.linalg.eigvals(sampled_matrix(loop, Ts, tau))
    if loop.neutral:
        i = int(np.argmin(np.abs(mu - 1.0)))
        near, mu = mu[i], np.delete(mu, i)
        if not loop.exactly_neutral and math.log(abs(near)) / Ts > NEUTRAL_RATE:
            return math.log(abs(near)) / Ts - NEUTRAL_RATE, complex(near)
    j = int(np.argmax(np.abs(mu)))
    return math.log(max(abs(mu[j]), 1e-300)) / Ts, complex(mu[j])


def _adj_trace(loop: FeedbackLoop, Ts: float, tau: float) -> float:
    """trace adj(I - M) = prod (1 - mu_j) over the eigenvalues but the neutral mu = 1 (M of an
    exactly neutral loop): changes sign where a real mu passes through 1."""
    X = np.eye(len(M := sampled_matrix(loop, Ts, tau))) - M
    U, s, Vt = np.linalg.svd(X)
    return float(np.linalg.det(U @ Vt) * np.prod(s[:-1]) * (Vt[-1] @ U[:, -1]))


@dataclass(frozen=True)
class SampledMargin:
    """Delay margin of model (b) at a sample period.

    Attributes
    ----------
    Ts : float
        Sample period, wing beats.
    whole : int
        Largest d such that the delays 0, Ts, ..., d Ts all keep the verdict (-1: not even 0).
    tau : float
        Smallest delay (fractional) at which the verdict is lost, wing beats (``inf``:
        none up to the scanned limit).
    mu : complex
        The eigenvalue that crosses there (|mu| = 1, or e^(1e-3 Ts) for the small root of
        a near-neutral loop).
    """

    Ts: float
    whole: int
    tau: float
    mu: complex

    def ms(self, n_hz: float) -> float:
        """The fractional margin in ms at ``n_hz`` [Hz]."""
        return 1e3 * self.tau / n_hz


def sampled_margin(loop: FeedbackLoop, Ts: float = 1.0, tau_limit: float = 40.0,
                   per_sample: int = 8) -> SampledMargin:
    """Margins of model (b): whole samples, and the fractional delay by Brent's method on the
    dominant rate (on trace adj(I - M) where a real mu reaches the neutral mu = 1).

    Parameters
    ----------
    Ts : float
        Sample period, wing beats.
    tau_limit : float
        Largest delay scanned, wing beats.
    per_sample : int
        Scan points per sample period.
    """
    whole = -1
    while whole * Ts < tau_limit and excess_rate(loop, Ts, (whole + 1) * Ts)[0] <= 0.0:
        whole += 1
    grid = np.linspace(0.0, tau_limit, int(math.ceil(tau_limit / Ts * per_sample)) + 1)
    from scipy.optimize import brentq  # 0.2 s to import: for margins, not for a loop's matrix

    prev = excess_rate(loop, Ts, 0.0)[0]
    if prev > 0.0:
        return SampledMargin(Ts, whole, 0.0, excess_rate(loop, Ts, 0.0)[1])
    for a, b in zip(grid[:-1], grid[1:]):
        h, mu = excess_rate(loop, Ts, b)
        if h <= 0.0:
            continue
        if loop.exactly_neutral and abs(mu - 1.0) < 1e-2 \
                and _adj_trace(loop, Ts, a) * _adj_trace(loop, Ts, b) < 0:
            tau = brentq(lambda t: _adj_trace(loop, Ts, t), a, b, xtol=1e-14, rtol=1e-15)
        else:
            tau = brentq(lambda t: excess_rate(loop, Ts, t)[0], a, b, xtol=1e-14, rtol=1e-15)
        return SampledMargin(Ts, whole, float(tau), excess_rate(loop, Ts, tau)[1])
    return SampledMargin(Ts, whole, math.inf, 0j)


@dataclass(frozen=True)
class Response:
    """Response of the sampled loop to an initial state x0 (delay line at equilibrium).

    Attributes
    ----------
    peak_control : float
        max |u_k| over the inputs and the horizon, rad (every computed control takes effect).
    recovery : float
        Wing beats until the box-normalised deviation max_i |x_i| / bound_i (Sect. 3.6 bounds)
        stays within 5 % of its initial value (on the sample grid); ``inf`` if it never does.
    final_offset : float
        The deviation the loop settles at, as a fraction of the initial one (0 for a stable
        loop; the neutral mode's share for a neutral one).
    """

    peak_control: float
    recovery: float
    final_offset: float


def _deviation(x: Array) -> Array:
    return np.max(np.abs(x) / np.asarray(STATE_BOUNDS_SECT36), axis=-1)


def response(loop: FeedbackLoop, x0: ArrayLike, Ts: float = 1.0, tau: float = 0.0,
             horizon: float = 400.0, within: float = 0.05) -> Response:
    """Peak control, recovery time and final offset from x(0) = ``x0`` (x+), see
    :class:`Response`; ``horizon`` in wing beats."""
    M = sampled_matrix(loop, Ts, tau)
    d, eps = delay_split(tau, Ts)
    D = d + (1 if eps > 0.0 else 0)
    R0 = _u_rows(loop, 0, D, Ts)
    X = np.zeros(len(M))
    X[:loop.n] = np.asarray(x0, float)
    steps = int(math.ceil(horizon / Ts))
    xs, peak = np.empty((steps + 1, loop.n)), 0.0
    for k in range(steps + 1):
        xs[k] = X[:loop.n]
        peak = max(peak, float(np.max(np.abs(R0 @ X))))
        X = M @ X
    dev = _deviation(xs) / _deviation(xs[0])
    final = 0.0
    if loop.neutral:
        # The limit is the spectral projection on the neutral mode, v u^H x0 / (u^H v) with
        # its right and left eigenvectors: well-conditioned for the simple, isolated mu ~ 1.
        # (A whole inverse eigenvector basis is not: the delay line's mu = 0 is defective,
        # and inv(V) then differs in its third digit between BLAS kernels.)
        from scipy.linalg import eig  # 0.3 s to import: for a neutral loop's limit only

        w, vl, vr = eig(M, left=True, right=True)
        i = int(np.argmin(np.abs(w - 1.0)))
        v, u = vr[:, i], vl[:, i]
        X0 = np.zeros(len(M))
        X0[:loop.n] = np.asarray(x0, float)
        limit = np.real(v * (u.conj() @ X0) / (u.conj() @ v))
        final = float(_deviation(limit[:loop.n]) / _deviation(xs[0]))
    above = np.flatnonzero(dev > within)
    if final > within or (len(above) and above[-1] == steps):
        return Response(peak, math.inf, final)
    return Response(peak, float((above[-1] + 1) * Ts) if len(above) else 0.0, final)


def verdict_map(loop: FeedbackLoop, delays: ArrayLike, periods: ArrayLike) -> tuple[NDArray, Array]:
    """Verdicts and dominant rates (per wing beat) of model (b) over delay x sample period.

    Parameters
    ----------
    delays, periods : array_like
        Delays and sample periods, wing beats.

    Returns
    -------
    verdicts : (len(delays), len(periods)) ndarray of str
        ``stable``, ``neutral`` or ``unstable`` (tolerance 1e-3 per wing beat).
    dominant : (len(delays), len(periods)) ndarray
        Largest real part of the rates.
    """
    delays, periods = np.atleast_1d(delays), np.atleast_1d(periods)
    verdicts = np.empty((len(delays), len(periods)), dtype=object)
    dominant = np.empty((len(delays), len(periods)))
    for i, tau in enumerate(delays):
        for j, Ts in enumerate(periods):
            rates = sampled_rates(loop, float(Ts), float(tau))
            verdicts[i, j] = classify(rates)
            dominant[i, j] = float(np.max(rates.real))
    return verdicts, dominant
