"""FMU ``DroneFlyHover6DOF``: the hovering drone fly as a nonlinear rigid body, FMI 2.0 CS.

A drop-in for ``DroneFlyLateral`` and ``DroneFlyLongitudinal`` (their states, controls and
parameters, with the same names, units and causalities; see :mod:`dronefly.models.hover6dof`). The
wrapper only maps variables; the equations live in :mod:`dronefly.models.rigid_body`.

The Integer parameter ``aerodynamics`` (fixed) chooses the aerodynamics: 1 (the default) the
paper's linear derivatives, standard library only; 2 the cycle-averaged forces of the
quasi-steady wing model (:class:`dronefly.models.quasisteady.QuasiSteadyModel`, dickinson1999,
all terms, the default grid) as functions of the state. Only the second imports numpy, and
only when it is chosen: :func:`_quasi_steady_model` imports the model in the function, so
that the default FMU loads nothing outside the standard library (tests/test_host_requirements).
"""

from __future__ import annotations

import math
import os
from functools import lru_cache
from typing import Any

from ... import models as _models
from ...fmi import SlaveBase, Var
from ...models.hover6dof import EXTRA_STARTS, OUTPUT_NAMES, STATE_OUTPUTS
from ...models.lateral_interface import LATERAL, N_HZ, U_M_PER_S
from ...models.lateral_interface import parameter_description as lateral_text
from ...models.longitudinal_interface import LONGITUDINAL
from ...models.longitudinal_interface import parameter_description as longitudinal_text
from ...models import lateral_dynamics
from ...models import longitudinal_dynamics
from ...models.rigid_body import STATE_SIZE, Hover6DOF, Hover6DOFError, initial_state, outputs
from ..body_variables import (ATTITUDE_STARTS, VELOCITY_STARTS, control_inputs, rows,
                              start_parameters, state_outputs)

__all__ = ["AERODYNAMICS", "DroneFlyHover6DOF"]

_LAT_PARAMS = lateral_dynamics.LateralParameters.names()
_LON_PARAMS = longitudinal_dynamics.LongitudinalParameters.names()
_STARTS = (*(f"{s}_start" for s in STATE_OUTPUTS), *(e[0] for e in EXTRA_STARTS))
#: the values of the parameter ``aerodynamics``
AERODYNAMICS = {1: "linear", 2: "quasi_steady"}
_AERO_TEXT = ("aerodynamics: 1 = linear (the paper's stability and control derivatives, the "
              "derivative parameters), 2 = quasi_steady (the cycle-averaged forces of a "
              "quasi-steady blade-element model of the wings, dickinson1999, as functions of "
              "the state; the derivative parameters unused; needs numpy)")


def _quasi_steady_model(resources: str | None) -> Any:
    """The trimmed quasi-steady wing model (built once per process, then shared).

    The import is here, not at the top, on purpose: the model needs numpy, and the FMU with
    its default (linear) aerodynamics must import nothing outside the standard library. An
    FMU's package is shared by name by every instance in the process (same sources, same
    name), and the folder it was first imported from may be gone (fmpy removes each
    extraction after its run): the package's ``models`` folder of this instance is added to
    where ``models`` looks for modules first."""
    folder = os.path.join(resources, *_models.__name__.split(".")) if resources else ""
    if folder and os.path.isdir(folder) and folder not in _models.__path__:
        _models.__path__.insert(0, folder)
    return _trimmed_quasi_steady()


@lru_cache(maxsize=1)
def _trimmed_quasi_steady() -> Any:
    from ...models.quasisteady import QuasiSteadyModel  # lazy: numpy only when chosen
    model = QuasiSteadyModel()
    model.trim()
    return model


def _initial_dependencies(name: str) -> tuple[str, ...]:
    """The knowns an output's initial value is computed from (FMI 2.0 InitialUnknowns)."""
    if name in ("delta_gamma", "delta_theta", "theta"):
        return (f"{name if name != 'theta' else 'delta_theta'}_start",)
    if name in ("phi", "psi"):
        return ATTITUDE_STARTS
    if name in STATE_OUTPUTS:
        return (f"{name}_start", "U" if name in ("delta_u", "delta_v", "delta_w") else "n")
    if name in ("x_earth", "y_earth", "z_earth"):
        return (f"{name}_start", "n", "U")
    return (*VELOCITY_STARTS, *ATTITUDE_STARTS, "U")  # the earth-axis velocity


def _variables() -> tuple[Var, ...]:
    out = [*control_inputs("; held over each step)"), *state_outputs(_initial_dependencies)]
    defaults = (lateral_dynamics.default_parameters(), longitudinal_dynamics.default_parameters())
    for names, params, describe in ((_LAT_PARAMS, defaults[0], lateral_text),
                                    (_LON_PARAMS, defaults[1], longitudinal_text)):
        for name in names:
            if any(v.name == name for v in out):
                continue  # m_plus and g_plus: one parameter for both axes
            out.append(Var(name, "parameter", "tunable", describe(name), "1",
                           start=getattr(params, name)))
    out.append(Var("aerodynamics", "parameter", "fixed", _AERO_TEXT, None, start=1,
                   type="Integer"))
    out.append(Var("n", "parameter", "tunable",
                   "wing-beat frequency; reference time t_w = 1/n (Sect. 2.4)", "Hz", start=N_HZ))
    out.append(Var("U", "parameter", "tunable", "reference velocity U = 2 Phi n r2 (Sect. 2.4)",
                   "m/s", start=U_M_PER_S))
    return (*out, *start_parameters())


class DroneFlyHover6DOF(SlaveBase):
    """The hovering model drone fly as a rigid body in six degrees of freedom."""

    MODEL_NAME = "DroneFlyHover6DOF"
    MODEL_DESCRIPTION = (
        "Hovering model drone fly as a nonlinear rigid body in six degrees of freedom (Newton-"
        "Euler, full inertia tensor, exact gravity projection, quaternion attitude) with the "
        "linear aerodynamic derivatives of Zhang & Sun (Eq. 12, Table 1, Sect. 3.5), as the "
        "paper assumes, or (parameter aerodynamics = 2, needs numpy) the cycle-averaged "
        "forces of a quasi-steady blade-element model of the wings as functions of the "
        "state; a drop-in for DroneFlyLateral and DroneFlyLongitudinal")
    VARIABLES = _variables()
    DEFAULT_EXPERIMENT = (0.0, 30.0 / N_HZ, 0.1 / N_HZ)

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        vr = self._vr
        self._controls = (*LATERAL.control_names, *LONGITUDINAL.control_names)
        # the controls' and the outputs' rows of the value table, as slices
        self._inputs = rows(tuple(vr[n] for n in self._controls))
        self._outputs = rows(tuple(vr[n] for n in OUTPUT_NAMES))
        self._x = initial_state(dict.fromkeys(_STARTS, 0.0), U_M_PER_S, N_HZ)
        self._model: Hover6DOF | None = None
        self._U, self._n = U_M_PER_S, N_HZ

    def _refresh(self) -> None:
        lp = lateral_dynamics.LateralParameters(*self._values(_LAT_PARAMS))
        np_ = longitudinal_dynamics.LongitudinalParameters(*self._values(_LON_PARAMS))
        aero = self._value("aerodynamics")
        if aero not in AERODYNAMICS:
            raise ValueError(f"aerodynamics = {aero!r}: expected 1 (linear) or 2 (quasi_steady)")
        if self._model is None or (self._model.lateral_params, self._model.longitudinal_params,
                                   self._model.aerodynamics is None) != (lp, np_, aero == 1):
            lp.validate()
            np_.validate()
            self._model = Hover6DOF(lp, np_, aerodynamics=None if aero == 1
                                    else _quasi_steady_model(self.resources))
        n, U = self._values(("n", "U"))
        for name, value in (("n", n), ("U", U)):
            if not (math.isfinite(value) and value > 0.0):
                raise ValueError(f"{name} = {value!r} must be finite and > 0")
        self._n, self._U = n, U

    def _start_state(self) -> list[float]:
        starts = self._values(_STARTS)
        self._check_finite(_STARTS, starts)
        self._refresh()
        return initial_state(dict(zip(_STARTS, starts)), self._U, self._n)

    def _write(self, x: list[float]) -> None:
        self._real[self._outputs] = outputs(x, self._U, self._n)

    def _update_outputs(self) -> None:
        if not self._initialized:  # initial unknowns follow the starts until initialized
            self._write(self._start_state())

    def _initialize(self) -> None:
        self._x = self._start_state()
        self._write(self._x)

    def _advance(self, t: float, h: float) -> None:
        c = self._real[self._inputs]
        total = sum(c)
        if total - total != 0.0:  # inf or nan (or an overflowing sum): named if not finite
            self._check_finite(self._controls, c)
        c_lat, c_lon = c[:3], c[3:]
        try:
            x = self._model.step(self._x, c_lat, c_lon, h * self._n)  # type: ignore[union-attr]
        except Hover6DOFError as e:  # name the inputs: the likely cause
            inputs = ", ".join(f"{n} = {v!r}" for n, v in zip(self._controls, (*c_lat, *c_lon)))
            raise ValueError(f"state overflow: {e}, with {inputs}") from e
        self._x = x
        self._write(x)

    def _extra_state(self) -> dict[str, Any]:
        return {"x": list(self._x)}

    def _restore_extra_state(self, state: dict[str, Any]) -> None:
        x = [float(v) for v in state["x"]]
        if len(x) != STATE_SIZE or not all(math.isfinite(v) for v in x):
            raise ValueError(f"the state must hold {STATE_SIZE} finite values, got {x!r}")
        self._x = x
