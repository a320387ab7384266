"""FMU ``DroneFlyLateral``: the lateral plant of Eq. (9) as an FMI 2.0 CS slave.

The wrapper maps FMI variables onto :mod:`.model`; all numbers come from there.
Outputs are the paper's disturbance states made dimensional with U and t_w.
"""

from __future__ import annotations

import math
from typing import Any

from ..fmi import SlaveBase, Var
from ..lateral import (CONTROL_DESCRIPTIONS, CONTROL_NAMES, CONTROL_UNIT, N_HZ, STATE_DESCRIPTIONS,
                       STATE_NAMES, STATE_UNITS, U_M_PER_S)
from .model import LateralModel, LateralParameters, default_parameters

__all__ = ["DroneFlyLateral"]

_PARAM_TEXT = {
    "m_plus": "non-dimensional mass m/(0.5 rho U S_t t_w)",
    "Ix_plus": "non-dimensional roll inertia",
    "Iz_plus": "non-dimensional yaw inertia",
    "Ixz_plus": "non-dimensional product of inertia",
    "g_plus": "non-dimensional gravity g t_w/U",
}


def _param_text(name: str) -> str:
    if name in _PARAM_TEXT:
        return _PARAM_TEXT[name]
    force, rest = name[0], name[1:-len("_plus")]
    what = {"Y": "side force", "L": "roll moment", "N": "yaw moment"}[force]
    if rest.startswith("_"):
        return f"control derivative of {what} w.r.t. delta{rest} (Table 1)"
    return f"stability derivative of {what} w.r.t. delta {rest}+ (from Eq. 12)"


def _matrix_dependencies(row: int, col: int, controls: bool) -> tuple[str, ...]:
    """Knowns that A1[row, col] (or B1) depends on, by Eqs. (10)-(11)."""
    if row == 3:
        return ()
    if controls:
        suffix = "_" + ("Phi_a", "alpha_1a", "alpha_2a")[col] + "_plus"
    elif col == 3:
        return ("g_plus",) if row == 0 else ()
    else:
        suffix = "vpr"[col] + "_plus"
    if row == 0:
        return ("m_plus", "Y" + suffix)
    return ("Ix_plus", "Iz_plus", "Ixz_plus", "L" + suffix, "N" + suffix)


def _variables() -> tuple[Var, ...]:
    defaults = default_parameters()
    out: list[Var] = []
    for name, text in zip(CONTROL_NAMES, CONTROL_DESCRIPTIONS):
        out.append(Var(name, "input", "continuous", f"{text} (held over each step)",
                       *CONTROL_UNIT, start=0.0))
    for name, text, (unit, disp) in zip(STATE_NAMES, STATE_DESCRIPTIONS, STATE_UNITS):
        out.append(Var(name, "output", "continuous", text, unit, disp, initial="calculated",
                       dependencies=(), initial_dependencies=(f"{name}_start",)))
    for name in LateralParameters.names():
        out.append(Var(name, "parameter", "tunable", _param_text(name), "1",
                       start=getattr(defaults, name)))
    out.append(Var("n", "parameter", "tunable",
                   "wing-beat frequency; reference time t_w = 1/n (Sect. 2.4)", "Hz", start=N_HZ))
    out.append(Var("U", "parameter", "tunable",
                   "reference velocity U = 2 Phi n r2 (Sect. 2.4)", "m/s", start=U_M_PER_S))
    for name, text, (unit, disp) in zip(STATE_NAMES, STATE_DESCRIPTIONS, STATE_UNITS):
        out.append(Var(f"{name}_start", "parameter", "fixed", f"initial {text}", unit, disp,
                       start=0.0))
    for M, what, cols, per in (("A", "system matrix A1", len(STATE_NAMES), "per wing beat"),
                               ("B", "control matrix B1", len(CONTROL_NAMES),
                                "per wing beat per rad")):
        for i in range(len(STATE_NAMES)):
            for j in range(cols):
                out.append(Var(f"{M}[{i + 1},{j + 1}]", "calculatedParameter", "tunable",
                               f"{what} of Eq. (9), row {i + 1} column {j + 1} ({per})", "1",
                               initial="calculated",
                               initial_dependencies=_matrix_dependencies(i, j, M == "B")))
    return tuple(out)


class DroneFlyLateral(SlaveBase):
    """Linearized lateral motion of the hovering model drone fly (Zhang & Sun)."""

    MODEL_NAME = "DroneFlyLateral"
    MODEL_DESCRIPTION = (
        "Linearized lateral dynamics of the hovering model drone fly, Eq. (9) of "
        "Zhang & Sun, 'Stabilization control of a hovering model insect: lateral motion'; "
        "exact zero-order-hold integration")
    VARIABLES = _variables()
    DEFAULT_EXPERIMENT = (0.0, 30.0 / N_HZ, 0.1 / N_HZ)  # 30 wing beats: open loop diverges

    _PARAMS = LateralParameters.names()
    _STARTS = tuple(f"{s}_start" for s in STATE_NAMES)
    _MATRIX = tuple(v.name for v in VARIABLES if v.causality == "calculatedParameter")

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self._x = [0.0, 0.0, 0.0, 0.0]  # x+, non-dimensional
        self._model: LateralModel | None = None
        self._n = N_HZ
        self._U = U_M_PER_S
        vr = self._vr
        self._in_vr = tuple(vr[n] for n in CONTROL_NAMES)
        self._out_vr = tuple(vr[n] for n in STATE_NAMES)

    def _refresh(self) -> None:
        values = self._values(self._PARAMS)
        params = LateralParameters(*values)
        if self._model is None or self._model.params != params:
            self._model = LateralModel(params)  # validates
        n, U = self._values(("n", "U"))
        for name, value in (("n", n), ("U", U)):
            if not (math.isfinite(value) and value > 0.0):
                raise ValueError(f"{name} = {value!r} must be finite and > 0")
        self._n, self._U = n, U
        self._set_values(self._MATRIX,
                         [*self._model.A.ravel().tolist(), *self._model.B.ravel().tolist()])

    def _update_outputs(self) -> None:
        # Before initialization ends, the initial unknowns already follow the start values and
        # parameters (FMI 2.0: fmi2GetReal in initialization mode); afterwards only doStep
        # changes the outputs (no direct feedthrough).
        if self._initialized:
            return
        start = self._values(self._STARTS)
        self._check_finite(self._STARTS, start)
        self._set_values(STATE_NAMES, start)
        self._refresh()

    def _initialize(self) -> None:
        start = self._values(self._STARTS)
        self._check_finite(self._STARTS, start)
        self._set_values(STATE_NAMES, start)  # outputs are defined even if _refresh fails
        self._refresh()
        n, U = self._n, self._U
        self._x = [start[0] / U, start[1] / n, start[2] / n, float(start[3])]

    def _advance(self, t: float, h: float) -> None:
        r = self._real
        u = [r[i] for i in self._in_vr]
        if not (math.isfinite(u[0]) and math.isfinite(u[1]) and math.isfinite(u[2])):
            self._check_finite(CONTROL_NAMES, u)
        x = self._model.step_list(self._x, u, h * self._n)  # type: ignore[union-attr]
        n = self._n
        y = (x[0] * self._U, x[1] * n, x[2] * n, x[3])
        if not (math.isfinite(y[0]) and math.isfinite(y[1]) and math.isfinite(y[2])
                and math.isfinite(y[3])):
            inputs = ", ".join(f"{n} = {v!r}" for n, v in zip(CONTROL_NAMES, u))
            raise ValueError(f"state overflow: outputs {y!r} after a step of {h!r} s with "
                             f"{inputs} (the linear model is far outside its range)")
        self._x = x
        for i, v in zip(self._out_vr, y):
            r[i] = v

    def _extra_state(self) -> dict[str, Any]:
        return {"x": list(self._x)}

    def _restore_extra_state(self, state: dict[str, Any]) -> None:
        x = [float(v) for v in state["x"]]
        if len(x) != len(STATE_NAMES):
            raise ValueError(f"the state holds {len(x)} plant states, expected {len(STATE_NAMES)}")
        self._x = x
