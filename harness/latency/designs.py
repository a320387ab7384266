"""The lateral designs whose latency tolerance is compared (all on delta_Phi_a alone).

- ``eq27``: Eq. (27) as printed (the controller FMU's default); closed loop neutral within
  rounding (lambda_1 = +7.6e-5 per wing beat).
- ``eq27_exact``: the paper's coefficient matching (Eqs. 25-26) with lambda_1 = 0 exactly and
  the other eigenvalues of A kept: what Eq. (27) rounds.
- ``stabilising``: the same method with lambda_1 moved to -0.1 (the harness's named gain set
  ``stabilising``, :func:`dronefly.harness.paper.gains.gain_matrix`).
- ``lqr``: LQR (``scipy.linalg.solve_continuous_are``) with Bryson's rule: Q = diag(1 / x_max^2)
  from the Sect. 3.6 bounds (0.15, 0.15, 0.15, 0.22) and R = 1 / 0.4^2 from the control limit.
- ``pi``: proportional-integral on the roll angle, u = k x+ + kI * integral of dgamma dt+
  (Beatus et al. 2015 find flies' roll reflex PI). The augmented loop (x+, z) has five
  eigenvalues; coefficient matching keeps Eq. (27)'s three non-zero ones (-0.0889 +/-
  0.0568i, -0.5098) and puts the two that Eq. (27) would leave at s = 0 (its neutral root
  and the integrator's) at a double root -a. a = :data:`PI_DOUBLE_ROOT`: the largest
  multiple of 0.01 per wing beat whose delay margin sampled once per wing beat (model (b))
  covers the 30 ms of visual feedback (a larger a is faster but tolerates less delay; see
  :func:`pi_loop` and tests/test_latency.py).

Gains are rad per unit of x+ (and per unit of the integral, in wing beats).
"""

from __future__ import annotations

import numpy as np

from ...models.feedback import PAPER_GAINS_EQ27, U_MAX_LINEAR_RANGE
from ..paper.gains import STABILISING_LAMBDA1, gain_matrix
from .loop import FeedbackLoop, LatencyInputError
from ..paper.analysis import coefficient_matching_gains, lateral_system, ordered_eigen
from ..paper.design import lqr_gains
from ...models.lateral_interface import CONTROL_NAMES, STATE_BOUNDS_SECT36

__all__ = ["DESIGNS", "PI_DOUBLE_ROOT", "bryson_weights", "design", "designs", "pi_loop"]

#: The design names, in table order.
DESIGNS: tuple[str, ...] = ("eq27", "eq27_exact", "stabilising", "lqr", "pi")
#: Double root -a of the PI design, per wing beat (see the module text).
PI_DOUBLE_ROOT = 0.07

_LABELS = {"eq27": "Eq. (27) as printed", "eq27_exact": "Eq. (27), lambda1 = 0 exactly",
           "stabilising": f"stabilising (lambda1 -> {STABILISING_LAMBDA1:g})",
           "lqr": "LQR, Bryson's rule", "pi": "PI on roll angle"}


def _single_input(k: np.ndarray) -> np.ndarray:
    K = np.zeros((len(CONTROL_NAMES), 4))
    K[0] = k
    return K


def bryson_weights() -> tuple[np.ndarray, float]:
    """Q diagonal (1 / x_max^2, Sect. 3.6 bounds) and r = 1 / u_max^2 (u_max = 0.4 rad)."""
    return 1.0 / np.asarray(STATE_BOUNDS_SECT36) ** 2, 1.0 / U_MAX_LINEAR_RANGE ** 2


def pi_loop(a: float = PI_DOUBLE_ROOT) -> FeedbackLoop:
    """The PI design with the double root -``a`` (per wing beat, > 0), see the module text."""
    if not (np.isfinite(a) and a > 0.0):
        raise LatencyInputError(f"a = {a!r} per wing beat must be finite and > 0")
    A, B = lateral_system()
    w, _ = ordered_eigen(A)
    Aa = np.zeros((5, 5))
    Aa[:4, :4] = A
    Aa[4, 3] = 1.0  # z' = dgamma
    ba = np.append(B[:, 0], 0.0)
    ka = coefficient_matching_gains(Aa, ba, [-a, -a, *w[1:]])
    KI = np.zeros((len(CONTROL_NAMES), 4))
    KI[0, 3] = ka[4]
    return FeedbackLoop(A, B, _single_input(ka[:4]), KI, _LABELS["pi"])


def design(name: str) -> FeedbackLoop:
    """One of :data:`DESIGNS` as a :class:`~.loop.FeedbackLoop`."""
    A, B = lateral_system()
    if name == "eq27":
        K = _single_input(np.array(PAPER_GAINS_EQ27))
    elif name == "eq27_exact":
        w, _ = ordered_eigen(A)
        K = _single_input(coefficient_matching_gains(A, B, [0.0, *w[1:]], CONTROL_NAMES[0]))
    elif name == "stabilising":
        K = gain_matrix("stabilising")
    elif name == "lqr":
        q, r = bryson_weights()
        K = _single_input(lqr_gains(A, B, CONTROL_NAMES[0], q, r))
    elif name == "pi":
        return pi_loop()
    else:
        raise LatencyInputError(f"unknown design {name!r}; choose from {', '.join(DESIGNS)}")
    return FeedbackLoop(A, B, K, None, _LABELS[name])


def designs() -> dict[str, FeedbackLoop]:
    """Every design of :data:`DESIGNS`, by name."""
    return {name: design(name) for name in DESIGNS}
