"""The trimmed hover (:class:`Trim`) and how it is found (:func:`solve_trim`): the angles of
attack and the mean stroke angle at which the cycle-averaged forces hold the weight with no
horizontal force and no pitch moment."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from ...core.errors import DroneflyError
from .wing import FORCES, Array

__all__ = ["Trim", "solve_trim"]


@dataclass(frozen=True)
class Trim:
    """The trimmed hover: angles [rad], the residual of (X, Z + W, M) and the force balance."""

    alpha_d: float
    alpha_u: float
    phibar: float
    residual: float
    forces: dict[str, float] = field(default_factory=dict)

    def to_json(self) -> dict[str, float]:
        """Angles in deg, the residual over the weight, and the forces at trim (``X_plus``...)."""
        return {"alpha_d_deg": math.degrees(self.alpha_d), "alpha_u_deg": math.degrees(self.alpha_u),
                "phibar_deg": math.degrees(self.phibar), "residual_over_weight": self.residual,
                **{f"{k}_plus": v for k, v in self.forces.items()}}


def solve_trim(mean: Callable[[float, float, float], Array], weight: float, what: str,
               tol: float = 1e-12, max_iter: int = 30) -> Trim:
    """alpha_d, alpha_u and phibar [rad] such that X = 0, Z = -W+ and M = 0.

    Newton's method with a central-difference Jacobian, from 30 deg, 30 deg, 0.

    Parameters
    ----------
    mean : callable
        (alpha_d, alpha_u, phibar) [rad], both wings alike, the body at rest ->
        cycle-averaged (X+, Y+, Z+, L+, M+, N+) (non-dimensional, order :data:`FORCES`).
    weight : float
        W+ = m+ g+, non-dimensional as the forces.
    what : str
        The model, as the messages name it.
    tol : float
        The residual, over the weight, below which Newton stops; after ``max_iter`` steps a
        residual below max(tol, 1e-9) is accepted.
    max_iter : int
        Newton steps at most.

    Raises
    ------
    DroneflyError
        The residual does not fall below max(``tol``, 1e-9) W+ or the angles leave
        0 < alpha < 90 deg, |phibar| < 90 deg (a model without the lift terms).
    """
    W = weight
    z = np.array([math.radians(30.0), math.radians(30.0), 0.0])

    def residual(zz: Array) -> Array:
        f = mean(zz[0], zz[1], zz[2])
        return np.array([f[0], f[2] + W, f[4]]) / W

    res = residual(z)
    for _ in range(max_iter):
        if np.max(np.abs(res)) < tol:
            break
        J = np.empty((3, 3))
        h = 1e-6
        for j in range(3):
            dz = np.zeros(3)
            dz[j] = h
            J[:, j] = (residual(z + dz) - residual(z - dz)) / (2 * h)
        try:
            z = z - np.linalg.solve(J, res)
        except np.linalg.LinAlgError:
            raise DroneflyError(f"no trim: the force and pitch moment do not depend on the "
                                f"angles of attack ({what})") from None
        res = residual(z)
        if not np.all(np.isfinite(res)):
            break
    err = float(np.max(np.abs(res)))
    if not (0.0 < z[0] < np.pi / 2 and 0.0 < z[1] < np.pi / 2 and abs(z[2]) < np.pi / 2):
        raise DroneflyError(
            f"no trim with angles of attack in (0, 90) deg and |phibar| < 90 deg: Newton "
            f"ended at alpha_d = {math.degrees(z[0]):.4g} deg, alpha_u = "
            f"{math.degrees(z[1]):.4g} deg, phibar = {math.degrees(z[2]):.4g} deg ({what})")
    if not err < max(tol, 1e-9):
        raise DroneflyError(f"trim did not converge: residual {err:.3g} of the weight ({what})")
    f = mean(z[0], z[1], z[2])
    return Trim(float(z[0]), float(z[1]), float(z[2]), err,
                dict(zip(FORCES, (float(v) for v in f))))
