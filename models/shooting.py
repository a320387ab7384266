"""A periodic orbit by shooting: Newton's chord method on a period map (:func:`shooting`), for
any map of a state vector over one period (the wing-beat map of :mod:`dronefly.models.flapping`,
an FMU's through FMI in :mod:`dronefly.harness.flapping.fmi_floquet`)."""

from __future__ import annotations

from typing import Callable

import numpy as np

from ..core.errors import DroneflyError

__all__ = ["ShootingError", "shooting"]


class ShootingError(DroneflyError):
    """Newton's method found no periodic orbit (the message gives the residuals)."""


def shooting(period_map: Callable[[np.ndarray], np.ndarray], x0: np.ndarray,
             monodromy: np.ndarray, tol: float, max_iter: int,
             scales: np.ndarray | None = None) -> tuple[np.ndarray, list[float]]:
    """A periodic orbit by shooting: Newton's chord method on ``period_map(x) - x`` from ``x0``,
    the Jacobian ``monodromy - I`` kept for every step (the map is nearly linear over the
    orbit's offset), until the largest residual (over ``scales``, if given) is below ``tol``.

    Returns
    -------
    x, residuals : array, list of float
        The state at the orbit's start and the residual of each iteration (in the units of the
        state, or over ``scales``).

    Raises
    ------
    ShootingError
        The residual is not below ``tol`` after ``max_iter`` steps.
    """
    x = np.asarray(x0, dtype=float)
    J = np.asarray(monodromy, dtype=float) - np.eye(len(x))
    residuals: list[float] = []
    for _ in range(max_iter):
        r = period_map(x) - x
        residuals.append(float(np.max(np.abs(r if scales is None else r / scales))))
        if residuals[-1] < tol:
            return x, residuals
        x = x - np.linalg.solve(J, r)
    raise ShootingError(f"no periodic orbit: the residual is {residuals[-1]:.3g} after "
                        f"{max_iter} steps ({residuals!r})")
