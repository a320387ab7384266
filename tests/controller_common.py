"""Constants and helpers shared by the controller tests (law, slave class, real FMU)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from dronefly.harness.paper import printed as pv
from dronefly.models import feedback as L
from dronefly.models import lateral_interface

ROOT = Path(__file__).resolve().parents[1]
STATES = list(lateral_interface.STATE_NAMES)
CONTROLS = list(lateral_interface.CONTROL_NAMES)
GAINS = [L.gain_name(i, j) for i in range(3) for j in range(4)]
H = 0.1 / lateral_interface.N_HZ  # communication step: 0.1 wing beat

#: Printed closed-loop eigenvalues (Sect. 3.4: lambda1 = 0, the others as in Table 2).
EIG_EQ27 = pv.eq27_targets()
#: Eq. (24): the delta_Phi_a column of B1 as printed.
B1_COL1_EQ24 = tuple(float(t) for t in pv.EQ24_B_COLUMN)


def dimensional(xp: np.ndarray, n: float = lateral_interface.N_HZ, U: float = lateral_interface.U_M_PER_S) -> list[float]:
    return [float(v) for v in lateral_interface.to_dimensional(np.asarray(xp, dtype=float), U, n)]


def expected_controls(K: np.ndarray, x: list[float], n: float = lateral_interface.N_HZ, U: float = lateral_interface.U_M_PER_S,
              u_max: float | None = None) -> tuple[np.ndarray, bool]:
    u = np.asarray(K, dtype=float) @ lateral_interface.to_nondimensional(np.array(x), U, n)
    if u_max is None:
        return u, False
    return np.clip(u, -u_max, u_max), bool(np.any(np.abs(u) > u_max))


def random_gains(seed: int = 3) -> np.ndarray:
    return np.random.default_rng(seed).uniform(-2.0, 2.0, (3, 4))


