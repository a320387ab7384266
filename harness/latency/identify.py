"""The delayed loop's eigenvalues identified from co-simulated runs (model (b) cross-check).

A co-simulation of the plant FMU with the controller FMU (``sensing_delay`` = d Ts,
``sample_period`` = Ts, communication step Ts, Gauss-Seidel) records x_k at t_k = k Ts. The
delay line inside the controller holds past samples the importer cannot read, but they are
past samples of the recorded x, so the augmented state of :mod:`.sampled`,

    X_k = [x_k; x_(k-1); ...; x_(k-d); z_k],   z_k = Ts C (x_0 + ... + x_(k-1)),

is rebuilt from the record (x = 0 before t = 0, the controller's delay line starting at the
equilibrium). Runs from the unit initial states x+_0 = e_j give pairs (X_k, X_(k+1)), and
X_(k+1) = M X_k is fitted by least squares (each pair scaled to unit |X_k|, as
:func:`dronefly.harness.cosim.identification.identify` does). The non-zero eigenvalues of M are
the loop's; they are compared with those of the exact M of :func:`.sampled.sampled_matrix`.
The zero eigenvalues are pure delay (Jordan chains, so the fit moves them by about the
square root of the fit's rounding) and are reported apart.
"""

from __future__ import annotations

import contextlib
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Sequence

import numpy as np
from numpy.typing import NDArray

from ...models.feedback import gain_name, integral_gain_name
from ...models.lateral_interface import plant_scales
from ..cosim.fmu import FMU
from ..cosim.master import Loop
from ..cosim.identification import unit_start_values
from .loop import FeedbackLoop, LatencyInputError
from .sampled import delay_split, sampled_matrix

__all__ = ["DelayedIdentification", "augmented_trajectory", "cosimulate_runs",
           "identify_delayed"]

#: |mu| below which an eigenvalue of M counts as a delay mode
DELAY_MODE = 1e-3


def augmented_trajectory(x: NDArray[np.float64], loop: FeedbackLoop, Ts: float,
                         tau: float) -> NDArray[np.float64]:
    """X_k (rows) rebuilt from a recorded x+ trajectory (rows x_0 .. x_N), see the module text."""
    d, eps = delay_split(tau, Ts)
    D = d + (1 if eps > 0.0 else 0)
    x = np.asarray(x, float)
    N, n = x.shape
    if n != loop.n:
        raise LatencyInputError(f"the trajectory has {n} states, the loop {loop.n}")
    padded = np.vstack([np.zeros((D, n)), x])
    blocks = [padded[D - i:D - i + N] for i in range(D + 1)]
    z = Ts * np.vstack([np.zeros((1, n)), np.cumsum(x, axis=0)[:-1]]) @ loop.C.T
    return np.hstack([*blocks, z])


@dataclass(frozen=True)
class DelayedIdentification:
    """The fitted transition matrix and its comparison with the exact one.

    Attributes
    ----------
    transition : ndarray
        Fitted M.
    exact : ndarray
        M of :func:`.sampled.sampled_matrix`.
    eigenvalues, exact_eigenvalues : ndarray
        Non-zero eigenvalues (|mu| > 1e-3) of each, matched pairwise (same order).
    max_deviation : float
        max |mu_fit - mu_exact| over the matched non-zero eigenvalues.
    delay_mode_max : float
        Largest |mu| of the fitted delay modes (exactly 0 in the exact M).
    fit_residual : float
        max |X_(k+1) - M X_k| / |X_k| over the pairs.
    """

    transition: NDArray[np.float64]
    exact: NDArray[np.float64]
    eigenvalues: NDArray[np.complex128]
    exact_eigenvalues: NDArray[np.complex128]
    max_deviation: float
    delay_mode_max: float
    fit_residual: float

    def rates(self, Ts: float) -> NDArray[np.complex128]:
        """log(mu) / Ts of the fitted non-zero eigenvalues, per wing beat."""
        return np.log(self.eigenvalues.astype(complex)) / Ts


def identify_delayed(runs: Sequence[NDArray[np.float64]], loop: FeedbackLoop, Ts: float,
                     tau: float) -> DelayedIdentification:
    """Fit M from recorded x+ runs (each (N+1, n), from t = 0) and compare with the exact M."""
    X0, X1 = [], []
    for x in runs:
        X = augmented_trajectory(x, loop, Ts, tau)
        X0.append(X[:-1])
        X1.append(X[1:])
    Z0, Z1 = np.vstack(X0), np.vstack(X1)
    w = 1.0 / np.maximum(np.linalg.norm(Z0, axis=1), 1e-300)
    P, Q = Z0 * w[:, None], Z1 * w[:, None]
    if np.linalg.matrix_rank(P) < P.shape[1]:
        raise LatencyInputError(f"the runs span {np.linalg.matrix_rank(P)} of the "
                                f"{P.shape[1]} augmented states: run longer or from more states")
    Mt, *_ = np.linalg.lstsq(P, Q, rcond=None)
    M = Mt.T
    resid = float(np.max(np.linalg.norm(Q - P @ Mt, axis=1)))
    exact = sampled_matrix(loop, Ts, tau)
    fit_ev, ex_ev = np.linalg.eigvals(M), np.linalg.eigvals(exact)
    ex_nz = ex_ev[np.abs(ex_ev) > DELAY_MODE]
    free = list(fit_ev)
    matched = []
    for mu in ex_nz:
        j = int(np.argmin([abs(f - mu) for f in free]))
        matched.append(free.pop(j))
    matched_arr = np.array(matched, dtype=complex)
    dev = float(np.max(np.abs(matched_arr - ex_nz))) if len(ex_nz) else 0.0
    rest = float(np.max(np.abs(free))) if free else 0.0
    return DelayedIdentification(M, exact, matched_arr, ex_nz.astype(complex), dev, rest, resid)


def cosimulate_runs(plant: Any, controller: Any, loop: FeedbackLoop, Ts: float, tau: float,
                    n_steps: int, substeps: int = 1) -> list[NDArray[np.float64]]:
    """Runs of the plant and controller FMUs from each unit initial state x+_0 = e_j.

    Parameters
    ----------
    plant, controller : FMU or path
        The lateral plant and the controller (:class:`dronefly.harness.cosim.fmu.FMU`, or
        ``.fmu`` files, extracted here).
    loop : FeedbackLoop
        Gains ``K[i,j]``, ``KI[i,j]`` set on the controller.
    Ts, tau : float
        ``sample_period`` = Ts / n and ``sensing_delay`` = tau / n [s] of the controller
        (Ts, tau in wing beats).
    n_steps : int
        Sample periods per run.
    substeps : int
        Communication steps per sample period (Gauss-Seidel, step Ts / substeps). The
        controller FMU's control becomes visible at the first communication point at or
        after its instant t_k + tau, so a fractional delay needs those instants on the grid
        (tau a whole number of steps). The control, integral term included, is computed when
        its sample takes effect and held until the next one does (u = K x_s + KI z(t_e)), as
        model (b) has it, so any ``substeps`` that puts the instants on the grid describes
        the same discrete loop.

    Returns
    -------
    list of ndarray
        x+ at t_k = k Ts, k = 0..n_steps, one (n_steps + 1, n) array per run.

    Raises
    ------
    LatencyInputError
        A run stopped early or diverged (the message says which).
    """

    with contextlib.ExitStack() as stack:
        p = plant if isinstance(plant, FMU) else stack.enter_context(FMU(Path(plant)))
        c = controller if isinstance(controller, FMU) else stack.enter_context(FMU(Path(controller)))
        return _runs(p, c, loop, Ts, tau, n_steps, substeps)


def _runs(p: Any, c: Any, loop: FeedbackLoop, Ts: float, tau: float, n_steps: int,
          substeps: int) -> list[NDArray[np.float64]]:
    pair = Loop(p, c)
    scale = np.array(plant_scales(p.start_values()))
    n_hz = float(p.start_values()["n"])
    params = {gain_name(i, j): float(loop.K[i, j]) for i in range(loop.m) for j in range(loop.n)}
    params |= {integral_gain_name(i, j): float(loop.KI[i, j])
               for i in range(loop.m) for j in range(loop.n)}
    params |= {"sample_period": Ts / n_hz, "sensing_delay": tau / n_hz}
    runs = []
    with p.instantiate() as pi, c.instantiate() as ci:
        for j, start in enumerate(unit_start_values(scale, states=pair.states)):
            r = pair.run(Ts / substeps / n_hz, n_steps * substeps, plant_start=start,
                         controller_params=params, instances=(pi, ci))
            if r.failure is not None or len(r.signals) != n_steps * substeps + 1:
                raise LatencyInputError(f"identification run from e_{j + 1} failed: {r.failure}")
            runs.append(r.signals[::substeps, :loop.n] / scale)
    if not math.isfinite(float(np.max(np.abs(np.vstack(runs))))):
        raise LatencyInputError("an identification run diverged to a non-finite state")
    return runs
