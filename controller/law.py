"""State feedback u = K x+ of Sect. 3.4 (Eq. 22), generalised to all three lateral controls.

This module is the single home of the controller's numbers: the gains of
Eq. (27) are defined here and nowhere else. The reference scales (n, U) and
the variable names come from :mod:`dronefly.lateral`, the interface the plant
shares, so that the controller and the plant agree on the
non-dimensionalisation of Sect. 2.1:

    x+ = (delta_v / U, delta_p t_w, delta_r t_w, delta_gamma),  t_w = 1/n
    u  = (delta_Phi_a, delta_alpha_1a, delta_alpha_2a) = K x+   [rad]

K is 3x4 and non-dimensional (rad per unit of x+). Eq. (22) is its first row.
An optional actuator limit clips each control to [-u_max, u_max].
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property
from typing import Sequence

from ..errors import DroneflyError
from ..lateral import (CONTROL_NAMES, N_HZ, STATE_NAMES, U_M_PER_S, scale_vector,
                       to_nondimensional)

__all__ = [
    "CONTROL_NAMES",
    "FeedbackLaw",
    "Gains",
    "LawParameterError",
    "PAPER_GAINS_EQ27",
    "STATE_NAMES",
    "U_MAX_LINEAR_RANGE",
    "default_gains",
    "gain_name",
]

Gains = tuple[tuple[float, float, float, float], ...]

#: Eq. (27): delta_Phi_a = k1 dv+ + k2 dp+ + k3 dr+ + k4 dgamma, making the lateral
#: motion neutrally stable (closed-loop eigenvalues 0, -0.089 +/- 0.057i, -0.510).
PAPER_GAINS_EQ27: tuple[float, float, float, float] = (-0.3192, -0.2879, -0.1969, -0.0643)

#: Sect. 3.1 (Fig. 2): forces and moments vary linearly with each control for |control| <= 0.4 rad.
U_MAX_LINEAR_RANGE: float = 0.4


class LawParameterError(DroneflyError):
    """A gain, reference scale, limit or state value is not acceptable."""


def gain_name(i: int, j: int) -> str:
    """FMI name of the gain in row ``i``, column ``j`` (0-based): ``K[i+1,j+1]``."""
    return f"K[{i + 1},{j + 1}]"


def default_gains() -> Gains:
    """3x4 gains: Eq. (27) in the first row (delta_Phi_a), zeros elsewhere."""
    return (PAPER_GAINS_EQ27, (0.0, 0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 0.0))


@dataclass(frozen=True)
class FeedbackLaw:
    """u = K x+, optionally clipped to [-u_max, u_max]; x+ formed from the dimensional state.

    Parameters
    ----------
    K : 3x4 nested tuple
        Non-dimensional gains, rows = controls, columns = x+ components.
    n : float
        Wing-beat frequency [Hz]; t_w = 1/n.
    U : float
        Reference velocity [m/s].
    u_max : float
        Symmetric limit of every control [rad], used only if ``limit_enabled``
        (validated either way: it must be finite and > 0).
    limit_enabled : bool
        Whether the controls are limited (default: no limit).
    """

    K: Gains
    n: float = N_HZ
    U: float = U_M_PER_S
    u_max: float = U_MAX_LINEAR_RANGE
    limit_enabled: bool = False

    def validate(self) -> None:
        """Raise :class:`LawParameterError` naming the first bad value."""
        if len(self.K) != len(CONTROL_NAMES) or any(len(row) != len(STATE_NAMES) for row in self.K):
            raise LawParameterError(f"K must be {len(CONTROL_NAMES)}x{len(STATE_NAMES)}")
        for i, row in enumerate(self.K):
            for j, k in enumerate(row):
                if not math.isfinite(k):
                    raise LawParameterError(f"{gain_name(i, j)} = {k!r} is not finite")
        for name, value in (("n", self.n), ("U", self.U), ("u_max", self.u_max)):
            if not (math.isfinite(value) and value > 0.0):
                raise LawParameterError(f"{name} = {value!r} must be finite and > 0")

    def nondimensional_state(self, x: Sequence[float]) -> tuple[float, float, float, float]:
        """(dv [m/s], dp [rad/s], dr [rad/s], dgamma [rad]) -> x+; non-finite values are refused."""
        for name, value in zip(STATE_NAMES, x):
            if not math.isfinite(value):
                raise LawParameterError(f"{name} = {value!r} is not finite")
        return to_nondimensional(x, self.U, self.n)  # type: ignore[return-value]

    @cached_property
    def _rows(self) -> tuple[tuple[float, float, float, float], ...]:
        """K with the non-dimensionalisation folded in: u_i = sum_j Kd[i][j] x_j (x dimensional)."""
        scale = scale_vector(self.U, self.n)
        return tuple(tuple(k / s for k, s in zip(row, scale)) for row in self.K)  # type: ignore

    def evaluate(self, x: Sequence[float]) -> tuple[tuple[float, float, float], bool]:
        """Controls [rad] for a dimensional state, and whether any of them is limited.

        Each control is clipped on its own; ``saturated`` is true exactly when
        at least one unclipped value lies outside [-u_max, u_max].

        Raises
        ------
        LawParameterError
            A state value is not finite, or K x+ overflows.
        """
        x0, x1, x2, x3 = x
        if not (math.isfinite(x0) and math.isfinite(x1) and math.isfinite(x2)
                and math.isfinite(x3)):
            self.nondimensional_state(x)  # raises, naming the value
        # runs once per FMI get after a set: unrolled, no per-element Python loop
        u = [k0 * x0 + k1 * x1 + k2 * x2 + k3 * x3 for k0, k1, k2, k3 in self._rows]
        if not (math.isfinite(u[0]) and math.isfinite(u[1]) and math.isfinite(u[2])):
            for name, value in zip(CONTROL_NAMES, u):
                if not math.isfinite(value):
                    raise LawParameterError(f"{name} = {value!r} is not finite (K x+ overflows)")
        saturated = False
        if self.limit_enabled:
            lim = self.u_max
            for i, value in enumerate(u):
                if value > lim:
                    u[i], saturated = lim, True
                elif value < -lim:
                    u[i], saturated = -lim, True
        return (u[0], u[1], u[2]), saturated
