"""A linear plant closed by a (proportional-integral) state feedback, in non-dimensional time.

The plant is x' = A x + B u with time in wing beats (t+ = t n) and x = x+ non-dimensional
(Sect. 2.1); the law is

    u = K x_s + KI z,   z' = C x_s,   z(0) = 0,

where x_s is the state the controller senses (x itself without latency; delayed and held
with it, see :mod:`.continuous` and :mod:`.sampled`) and C selects the states whose
integral the law uses (the columns of KI with a non-zero entry). Keeping only those
integrals keeps spurious integrator roots at s = 0 out of every spectrum.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from functools import cached_property

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ...core.errors import DroneflyError

__all__ = ["FeedbackLoop", "LatencyInputError", "NEUTRAL_RATE"]

Array = NDArray[np.float64]

#: |s| per wing beat below which a closed-loop eigenvalue of the delay-free loop is the
#: neutral one (the verdict's tolerance, :data:`dronefly.harness.cosim.identification.TOL_PER_WINGBEAT`).
NEUTRAL_RATE = 1e-3


class LatencyInputError(DroneflyError):
    """Bad input to the latency analysis (the message names the value)."""


def _matrix(value: ArrayLike, shape: tuple[int, int], name: str) -> Array:
    m = np.array(value, dtype=float)
    if m.ndim == 1 and shape[0] == 1:
        m = m[None, :]
    if m.shape != shape:
        raise LatencyInputError(f"{name} has shape {m.shape}, expected {shape}")
    if not np.all(np.isfinite(m)):
        raise LatencyInputError(f"{name} has a non-finite entry")
    return m


@dataclass(frozen=True)
class FeedbackLoop:
    """Plant (A, B) with the law u = K x_s + KI z (see the module text).

    Parameters
    ----------
    A : (n, n) array_like
        System matrix, per wing beat.
    B : (n, m) array_like
        Control matrix, per wing beat per rad.
    K : (m, n) array_like
        Proportional gains, rad per unit of x+ (a 1-D row is taken as the only input's).
    KI : (m, n) array_like, optional
        Integral gains, rad per unit of the integral of x+ over t+ (wing beats).
    name : str
        Label for tables.
    """

    A: Array
    B: Array
    K: Array
    KI: Array | None = None
    name: str = ""
    integrated: tuple[int, ...] = field(init=False)

    def __post_init__(self) -> None:
        A = np.array(self.A, dtype=float)
        if A.ndim != 2 or A.shape[0] != A.shape[1] or not np.all(np.isfinite(A)):
            raise LatencyInputError(f"A must be a finite square matrix, got shape {A.shape}")
        n = len(A)
        B = np.array(self.B, dtype=float).reshape(n, -1)
        if not np.all(np.isfinite(B)):
            raise LatencyInputError("B has a non-finite entry")
        m = B.shape[1]
        K = _matrix(self.K, (m, n), "K")
        KI = np.zeros((m, n)) if self.KI is None else _matrix(self.KI, (m, n), "KI")
        object.__setattr__(self, "A", A)
        object.__setattr__(self, "B", B)
        object.__setattr__(self, "K", K)
        object.__setattr__(self, "KI", KI)
        object.__setattr__(self, "integrated",
                           tuple(int(j) for j in np.flatnonzero(np.any(KI != 0.0, axis=0))))

    # --- sizes and the augmented (state + integral) form ------------------------------------
    @property
    def n(self) -> int:
        """Plant states."""
        return len(self.A)

    @property
    def m(self) -> int:
        """Plant inputs."""
        return self.B.shape[1]

    @property
    def C(self) -> Array:
        """(q, n) selection of the integrated states (q = ``len(self.integrated)``)."""
        return np.eye(self.n)[list(self.integrated)]

    def augmented(self) -> tuple[Array, Array, Array]:
        """(A_a, B_a, K_a) with X = [x; integral of C x], A_a = [[A, 0], [C, 0]], B_a = [B; 0],
        K_a = [K, KI C^T]: the loop is X' = A_a X + B_a u, u = K_a X_s.

        The integral of the *sensed* state equals the integral of x delayed, so one delay
        acting on all of X_s describes the law exactly.
        """
        n, q = self.n, len(self.integrated)
        Aa = np.zeros((n + q, n + q))
        Aa[:n, :n] = self.A
        Aa[n:, :n] = self.C
        Ba = np.vstack([self.B, np.zeros((q, self.m))])
        Ka = np.hstack([self.K, self.KI @ self.C.T])
        return Aa, Ba, Ka

    def closed_loop(self) -> Array:
        """A_a + B_a K_a: the delay-free continuous closed loop."""
        Aa, Ba, Ka = self.augmented()
        return Aa + Ba @ Ka

    def eigenvalues(self) -> NDArray[np.complex128]:
        """Eigenvalues of the delay-free loop, per wing beat, descending real part."""
        ev = np.linalg.eigvals(self.closed_loop())
        return ev[np.lexsort((-ev.imag, -ev.real))]

    @cached_property
    def neutral(self) -> bool:
        """Whether the delay-free loop has an eigenvalue with |s| <= :data:`NEUTRAL_RATE`."""
        return bool(np.min(np.abs(self.eigenvalues())) <= NEUTRAL_RATE)

    @cached_property
    def exactly_neutral(self) -> bool:
        """Whether A_a + B_a K_a is singular to rounding (an eigenvalue s = 0 for every delay:
        det(-A_a - B_a K_a e^0) does not depend on the delay)."""
        s = np.linalg.svd(self.closed_loop(), compute_uv=False)
        return bool(s[-1] <= 1e-12 * s[0])

    def scaled(self, alpha: float) -> "FeedbackLoop":
        """The same loop with every gain (K and KI) times ``alpha``."""
        return replace(self, K=alpha * self.K, KI=alpha * self.KI,
                       name=f"{self.name} x {alpha:g}" if self.name else "")

    def control(self, x: ArrayLike, z: ArrayLike | None = None) -> Array:
        """u = K x + KI C^T z for a sensed state x and integrals z (q of them)."""
        u = self.K @ np.asarray(x, float)
        if self.integrated:
            u = u + self.KI @ self.C.T @ np.asarray(z, float)
        return u
