"""Open-loop simulation of the plant FMU with fmpy, checked against the exact solution."""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import fmpy
import numpy as np

from ..builder.build import ensure_fmu
from ...core.errors import DroneflyError
from ...core.files import write_csv_atomic
from ...core.interrupt import checkpoint
from ...core.interrupt import pending as interrupt_pending
from ...core.text import status_name
from ...models.lateral_interface import N_HZ, STATE_NAMES, STATE_UNITS, scale_vector
from ...models.lateral_dynamics import LateralModel, default_parameters
from ..cosim.master import step_count

__all__ = ["PlantRun", "exact_open_loop", "simulate_plant"]


@dataclass(frozen=True)
class PlantRun:
    """Result of :func:`simulate_plant`."""

    time: np.ndarray  # s
    states: np.ndarray  # (N, 4) dimensional outputs
    max_rel_error: float  # against the exact solution, relative to max |x|
    csv: Path
    complete: bool = True  # False: the FMU refused a step before the stop time
    requested_stop_wb: float | None = None  # when the stop is not a whole number of steps
    built: Path | None = None  # the FMU, if this run built it (missing or out of date)
    #: what the FMU logged with a status of fmi2Discard or worse (why it refused a step)
    messages: tuple[str, ...] = ()

    def summary(self) -> str:
        wb = self.time[-1] * N_HZ
        final = ", ".join(f"{n} = {v:.6g} {unit}"
                          for n, v, (unit, _) in zip(STATE_NAMES, self.states[-1], STATE_UNITS))
        text = (f"DroneFlyLateral open loop, {len(self.time) - 1} steps to {wb:.6g} wing beats "
                f"({self.time[-1]:.6g} s): {final}\nmax relative deviation from the exact "
                f"solution: {self.max_rel_error:.2e}\nresult: {self.csv}")
        if self.requested_stop_wb is not None:
            text += (f"\nnote: stop {wb:.6g} wing beats = {len(self.time) - 1} whole steps; the "
                     f"requested {self.requested_stop_wb:g} is not a whole number of steps")
        if self.built is not None:
            text += f"\nbuilt {self.built} (missing or out of date with the sources)"
        if not self.complete:
            why = "; ".join(self.messages) or "it logged no message"
            text += (f"\nINCOMPLETE: the FMU refused the step after {wb:.6g} wing beats: {why}; "
                     "the CSV holds what was computed")
        return text


def exact_open_loop(x0_dim: np.ndarray, t: np.ndarray, u: np.ndarray | None = None) -> np.ndarray:
    """Exact solution of Eq. (9) for a constant control at times ``t`` [s].

    Independent of the FMU's matrix-exponential stepping: uses the eigen-
    decomposition A1 = V diag(lam) V^-1, x(t) = e^(A t) x0 + A^-1 (e^(A t) - I) B u
    (A1 has no zero eigenvalue).
    """
    model = LateralModel(default_parameters())
    A, B = model.A, model.B
    lam, V = np.linalg.eig(A)
    Vinv = np.linalg.inv(V)
    scale = np.array(scale_vector())
    x0 = np.asarray(x0_dim, dtype=float) / scale
    u = np.zeros(3) if u is None else np.asarray(u, dtype=float)
    a0 = Vinv @ x0
    b = Vinv @ (B @ u)
    tp = np.asarray(t, dtype=float)[:, None] * N_HZ
    e = np.exp(lam[None, :] * tp)
    modal = e * a0[None, :] + (e - 1.0) / lam[None, :] * b[None, :]
    return np.real(modal @ V.T) * scale


def simulate_plant(stop_wingbeats: float = 30.0, step_wingbeats: float = 0.1, gamma0: float = 0.1,
                   out_dir: str | Path = "build") -> PlantRun:
    """Build the plant FMU if needed, simulate it with fmpy and write a CSV.

    Parameters
    ----------
    stop_wingbeats, step_wingbeats : float
        Stop time and communication step in wing beats (t_w = 1/n).
    gamma0 : float
        Initial roll angle [rad].

    Raises
    ------
    KeyboardInterrupt
        A deferred Ctrl-C (:mod:`dronefly.core.interrupt`): the run stops after the step it is
        in, and no CSV is written.
    """


    if not math.isfinite(gamma0):
        raise DroneflyError(f"gamma0 = {gamma0!r} rad is not finite")
    n_steps = step_count(stop_wingbeats, step_wingbeats)
    requested = stop_wingbeats
    stop_wingbeats = n_steps * step_wingbeats
    out = Path(out_dir)
    fmu, fresh = ensure_fmu("DroneFlyLateral", out)  # built only if missing or out of date
    messages: list[str] = []

    def logger(env: object, instance: bytes, status: int, category: bytes,
               message: bytes) -> None:
        if status >= 2:  # fmi2Discard, fmi2Error, fmi2Fatal: why a step was refused
            messages.append(f"{status_name(status)}: {message.decode('utf-8', 'replace')}")

    # the FMU sends its log only with debug logging on; the logger keeps what refuses a step
    res = fmpy.simulate_fmu(str(fmu), stop_time=stop_wingbeats / N_HZ,
                            output_interval=step_wingbeats / N_HZ,
                            start_values={"delta_gamma_start": gamma0},
                            output=list(STATE_NAMES), debug_logging=True, logger=logger,
                            # Ctrl-C: stop after this step (fmpy frees the instance)
                            step_finished=lambda time, recorder: not interrupt_pending())
    checkpoint()  # interrupted: no CSV, as if the run had not been asked for
    t = np.asarray(res["time"], dtype=float)
    x = np.column_stack([res[n] for n in STATE_NAMES])
    complete = len(t) == n_steps + 1
    with np.errstate(over="ignore", invalid="ignore"):
        ref = exact_open_loop(np.array([0.0, 0.0, 0.0, gamma0]), t)
        ok = np.isfinite(ref).all(axis=1)
        err = float(np.max(np.abs(x[ok] - ref[ok])) / max(np.max(np.abs(ref[ok])), 1e-300))
    csv = out / "DroneFlyLateral_open_loop.csv"
    write_csv_atomic(csv, ["time", *STATE_NAMES], np.column_stack([t, x]).tolist())
    return PlantRun(t, x, err, csv, complete,
                    None if math.isclose(stop_wingbeats, requested, rel_tol=1e-9) else requested,
                    fmu if fresh else None, tuple(messages))
