"""Delay margin of a loop with a continuous pure sensing delay (model (a)).

The controller senses x_s(t) = x(t - tau) (x = 0 before t = 0), so with the augmented state
X of :class:`~.loop.FeedbackLoop` the loop is the delay differential equation

    X'(t) = A_a X(t) + B_a K_a X(t - tau),

with the characteristic quasi-polynomial g(s, tau) = det(s I - A_a - B_a K_a e^(-s tau)).
Time and rates are in wing beats (t+ = t n); ``tau`` too (1 wing beat = 1/n s, 6.1 ms at
n = 164 Hz).

**Crossings at s = i omega, omega > 0.** With G(s) = K_a (s I - A_a)^-1 B_a (m x m),
g = det(s I - A_a) det(I - e^(-s tau) G(s)), so a root is on the imaginary axis exactly when
an eigenvalue mu of G(i omega) has |mu| = 1, at the delays tau = (arg mu + 2 pi j) / omega.
|mu(i omega)| - 1 is scanned on a logarithmic grid and its zeros refined by Brent's method
to the last bit; beyond the grid a bound on |G| excludes crossings.

**s = 0.** g(0, tau) = det(-A_a - B_a K_a) does not depend on tau: a loop with a neutral
eigenvalue s = 0 keeps it for every delay, and a loop without one never gets one. What
the delay changes is the slope: with right and left null vectors v, w of A_a + B_a K_a,
dg/ds(0, tau) is proportional to w^T v + tau w^T B_a K_a v, which vanishes at
tau_0 = w^T v / (w^T A_a v) (as B_a K_a v = -A_a v). There a second real root reaches
s = 0, making it a double root, and passes into the right half-plane.

**Near-neutral loops** (the printed Eq. 27 leaves +7.6e-5 per wing beat): their small real
root moves with tau and the verdict is lost when it reaches the tolerance sigma = 1e-3:
a real root s = sigma needs a real eigenvalue mu(sigma) > 0 of G(sigma), at
tau = ln(mu) / sigma.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import brentq

from .loop import NEUTRAL_RATE, FeedbackLoop, LatencyInputError

__all__ = ["Crossing", "DelayMargin", "crossings", "delay_margin", "loop_gain",
           "origin_crossing_delay", "quasi_polynomial_residual", "real_root_delay"]

#: omega grid of the scan, per wing beat (the lateral loops cross between 0.04 and 2)
_W_MIN, _W_MAX, _W_POINTS = 1e-6, 1e3, 6000


@dataclass(frozen=True)
class Crossing:
    """A root of g on the line Re s = 0 at a delay.

    Attributes
    ----------
    omega : float
        Crossing frequency, rad per wing beat (0 for a real root).
    tau : float
        Smallest delay with that root, wing beats.
    mu : complex
        The eigenvalue of G(i omega) of modulus 1 (or the real one of G(sigma)).
    residual : float
        Smallest singular value of s I - A_a - B_a K_a e^(-s tau) at the root, relative to
        the norms of its terms: the independent check that g(s, tau) = 0.
    """

    omega: float
    tau: float
    mu: complex
    residual: float


@dataclass(frozen=True)
class DelayMargin:
    """The largest delay for which the loop keeps its verdict (model (a)).

    Attributes
    ----------
    tau : float
        Delay margin, wing beats (``inf`` if no delay destabilises the loop).
    kind : str
        ``"hopf"`` (a complex pair crosses at +/- i omega), ``"origin"`` (a second real root
        reaches the neutral s = 0), ``"tolerance"`` (the small real root of a near-neutral
        loop reaches +1e-3 per wing beat) or ``"none"``.
    crossing : Crossing or None
        The crossing that sets the margin.
    """

    tau: float
    kind: str
    crossing: Crossing | None

    def ms(self, n_hz: float) -> float:
        """The margin in milliseconds at a wing-beat frequency ``n_hz`` [Hz]."""
        return 1e3 * self.tau / n_hz


def loop_gain(loop: FeedbackLoop, s: complex) -> NDArray[np.complex128]:
    """G(s) = K_a (s I - A_a)^-1 B_a, the m x m loop gain of u = K_a X (no delay)."""
    Aa, Ba, Ka = loop.augmented()
    return Ka @ np.linalg.solve(s * np.eye(len(Aa)) - Aa, Ba)


def quasi_polynomial_residual(loop: FeedbackLoop, s: complex, tau: float) -> float:
    """sigma_min(s I - A_a - B_a K_a e^(-s tau)) / (|s| + |A_a| + |B_a K_a|) (2-norms)."""
    Aa, Ba, Ka = loop.augmented()
    BK = Ba @ Ka
    M = s * np.eye(len(Aa)) - Aa - BK * np.exp(-s * tau)
    scale = abs(s) + np.linalg.norm(Aa, 2) + np.linalg.norm(BK, 2)
    return float(np.linalg.svd(M, compute_uv=False)[-1] / scale)


def _excess(loop: FeedbackLoop, w: float) -> float:
    """prod_j (|mu_j(i w)| - 1): changes sign where one |mu_j| crosses 1."""
    mu = np.linalg.eigvals(loop_gain(loop, 1j * w))
    return float(np.prod(np.abs(mu) - 1.0))


def _excess_grid(loop: FeedbackLoop, grid: NDArray[np.float64]) -> NDArray[np.float64]:
    """:func:`_excess` on a grid, by batched solves."""
    Aa, Ba, Ka = loop.augmented()
    S = 1j * grid[:, None, None] * np.eye(len(Aa)) - Aa
    G = Ka @ np.linalg.solve(S, np.broadcast_to(Ba, (len(grid), *Ba.shape)))
    return np.prod(np.abs(np.linalg.eigvals(G)) - 1.0, axis=1)


def crossings(loop: FeedbackLoop) -> list[Crossing]:
    """Every omega > 0 with an eigenvalue |mu(i omega)| = 1, with its smallest delay.

    Returns
    -------
    list of Crossing
        Sorted by delay.
    """
    Aa, Ba, Ka = loop.augmented()
    bound = np.linalg.norm(Ka, 2) * np.linalg.norm(Ba, 2)
    w_max = max(_W_MAX, 2.0 * (np.linalg.norm(Aa, 2) + bound))  # beyond: |G| < 1
    grid = np.geomspace(_W_MIN, w_max, _W_POINTS)
    h = _excess_grid(loop, grid)
    out = []
    for i in np.flatnonzero(np.sign(h[:-1]) * np.sign(h[1:]) < 0):
        w = brentq(lambda x: _excess(loop, x), grid[i], grid[i + 1], xtol=1e-300, rtol=1e-15,
                   maxiter=200)
        mu = np.linalg.eigvals(loop_gain(loop, 1j * w))
        mu = complex(mu[np.argmin(np.abs(np.abs(mu) - 1.0))])
        tau = (math.atan2(mu.imag, mu.real) % (2 * math.pi)) / w
        out.append(Crossing(float(w), float(tau), mu,
                            quasi_polynomial_residual(loop, 1j * w, tau)))
    return sorted(out, key=lambda c: c.tau)


def origin_crossing_delay(loop: FeedbackLoop) -> float:
    """tau_0 = w^T v / (w^T A_a v) of an exactly neutral loop (module text), wing beats.

    ``inf`` if tau_0 <= 0 (the real root then never reaches s = 0 from the left) or the
    loop is not exactly neutral.
    """
    if not loop.exactly_neutral:
        return math.inf
    Aa, _, _ = loop.augmented()
    U, _, Vt = np.linalg.svd(loop.closed_loop())
    v, w = Vt[-1], U[:, -1]
    tau = float((w @ v) / (w @ Aa @ v))
    return tau if tau > 0.0 else math.inf


def real_root_delay(loop: FeedbackLoop, sigma: float = NEUTRAL_RATE) -> Crossing | None:
    """The smallest delay at which g has the real root s = ``sigma`` > 0 (module text)."""
    mu = np.linalg.eigvals(loop_gain(loop, sigma))
    taus = [math.log(z.real) / sigma for z in mu
            if abs(z.imag) <= 1e-12 * abs(z) and z.real > 0.0 and math.log(z.real) >= 0.0]
    if not taus:
        return None
    tau = min(taus)
    z = complex(math.exp(sigma * tau))
    return Crossing(0.0, tau, z, quasi_polynomial_residual(loop, sigma, tau))


def delay_margin(loop: FeedbackLoop) -> DelayMargin:
    """Delay margin of model (a): the smallest delay at which the loop loses its verdict.

    A stable loop loses it when a root reaches Re s = 0 (only complex pairs can: s = 0 is a
    root for no delay). A neutral loop keeps its neutral root; it loses the verdict when
    another root reaches Re s = 0 (a pair, or a real root at s = 0 itself), or, if its
    neutral root is not exactly 0, when that root passes the tolerance 1e-3 per wing beat.
    The delay-free loop must not be unstable.

    Raises
    ------
    LatencyInputError
        The delay-free loop has an eigenvalue with real part above the tolerance.
    """
    if float(np.max(loop.eigenvalues().real)) > NEUTRAL_RATE:
        raise LatencyInputError(f"loop {loop.name!r} is unstable without delay: no margin")
    found = [(c.tau, "hopf", c) for c in crossings(loop)]
    if loop.exactly_neutral:
        tau0 = origin_crossing_delay(loop)
        if math.isfinite(tau0):
            found.append((tau0, "origin", Crossing(0.0, tau0, 1.0 + 0j,
                                                   quasi_polynomial_residual(loop, 0.0, tau0))))
    elif loop.neutral:
        c = real_root_delay(loop)
        if c is not None:
            found.append((c.tau, "tolerance", c))
    if not found:
        return DelayMargin(math.inf, "none", None)
    tau, kind, c = min(found, key=lambda f: f[0])
    return DelayMargin(tau, kind, c)
