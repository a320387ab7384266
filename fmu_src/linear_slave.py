"""FMI 2.0 CS slave of a linear plant x+' = A x+ + B u: the shared wrapper of both plant FMUs.

A plant FMU (``DroneFlyLateral``, ``DroneFlyLongitudinal``) is this class with its
:class:`~dronefly.models.axes.Axis` (names, units, non-dimensionalisation), its parameter
dataclass and its model (A and B from the parameters). The wrapper only maps FMI
variables; the equations live in each plant's ``model`` module.

Variables: the controls as inputs [rad], the dimensional states as outputs (no direct
feedthrough), the model's parameters and the reference scales ``n`` [Hz] and ``U`` [m/s]
as tunable parameters, ``<state>_start`` as fixed parameters, and A and B as calculated
parameters. The state is kept non-dimensional (x+).
"""

from __future__ import annotations

import math
from operator import mul
from typing import Any, Callable, ClassVar

from ..models.axes import Axis
from ..fmi import SlaveBase, Var
from ..models.linear import ZohModel

__all__ = ["MODELS", "LinearPlantSlave", "plant_variables"]

#: parameter sets whose models (with their step matrices) a plant class keeps
MODELS = 16


def _block(vrs: tuple[int, ...]) -> slice:
    """The value references ``vrs`` as one slice of the value table (they must be consecutive,
    as :func:`plant_variables` lists the controls and the states)."""
    if vrs != tuple(range(vrs[0], vrs[0] + len(vrs))):
        raise ValueError(f"value references {vrs} are not consecutive")
    return slice(vrs[0], vrs[0] + len(vrs))


def plant_variables(axis: Axis, defaults: Any, param_text: Callable[[str], str],
                    matrix_dependencies: Callable[[int, int, bool], tuple[str, ...]],
                    n_hz: float, u_m_per_s: float, matrices: tuple[str, str]) -> tuple[Var, ...]:
    """The variable table of a linear plant FMU.

    Parameters
    ----------
    axis : Axis
        States (outputs) and controls (inputs).
    defaults : dataclass instance
        Default model parameters; every field becomes a tunable parameter (unit 1).
    param_text : callable
        Description of a model parameter from its name.
    matrix_dependencies : callable
        ``(row, col, is_B)`` -> the parameter names that entry of A (or B) depends on.
    n_hz, u_m_per_s : float
        Default reference scales.
    matrices : (str, str)
        What the paper calls A and B, for the descriptions (e.g. ``"A1 of Eq. (9)"``).
    """
    out: list[Var] = []
    unit, disp = axis.control_unit
    for name, text in zip(axis.control_names, axis.control_descriptions):
        out.append(Var(name, "input", "continuous", f"{text} (held over each step)", unit, disp,
                       start=0.0))
    states = tuple(zip(axis.state_names, axis.state_descriptions, axis.state_units))
    for name, text, (unit, disp) in states:
        out.append(Var(name, "output", "continuous", text, unit, disp, initial="calculated",
                       dependencies=(), initial_dependencies=(f"{name}_start",)))
    for name in type(defaults).names():
        out.append(Var(name, "parameter", "tunable", param_text(name), "1",
                       start=getattr(defaults, name)))
    out.append(Var("n", "parameter", "tunable",
                   "wing-beat frequency; reference time t_w = 1/n (Sect. 2.4)", "Hz", start=n_hz))
    out.append(Var("U", "parameter", "tunable",
                   "reference velocity U = 2 Phi n r2 (Sect. 2.4)", "m/s", start=u_m_per_s))
    for name, text, (unit, disp) in states:
        out.append(Var(f"{name}_start", "parameter", "fixed", f"initial {text}", unit, disp,
                       start=0.0))
    ns, nu = len(axis.state_names), len(axis.control_names)
    for M, what, cols, per in (("A", matrices[0], ns, "per wing beat"),
                               ("B", matrices[1], nu, "per wing beat per rad")):
        for i in range(ns):
            for j in range(cols):
                out.append(Var(f"{M}[{i + 1},{j + 1}]", "calculatedParameter", "tunable",
                               f"{what}, row {i + 1} column {j + 1} ({per})", "1",
                               initial="calculated",
                               initial_dependencies=matrix_dependencies(i, j, M == "B")))
    return tuple(out)


class LinearPlantSlave(SlaveBase):
    """A linear plant in non-dimensional form with exact zero-order-hold steps.

    Subclasses set ``AXIS``, ``PARAMETERS`` (a frozen dataclass with ``names()``; its
    constructor takes the values in that order), ``MODEL`` (parameters -> :class:`ZohModel`,
    validating them), ``VARIABLES`` (from :func:`plant_variables`) and the FMU's names.
    """

    AXIS: ClassVar[Axis]
    PARAMETERS: ClassVar[Any]
    MODEL: ClassVar[Callable[[Any], ZohModel]]

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        axis = self.AXIS
        self._x = [0.0] * len(axis.state_names)  # x+, non-dimensional
        self._model: Any = None
        self._stepper_model: Any = None
        self._scale = [1.0] * len(axis.state_names)
        self._n = 1.0
        (self._inputs, self._outputs, self._params, self._starts,
         self._matrix) = self._names_of_class()
        #: step size [s] -> the model's fused step for the current model and scales
        self._steppers: dict[float, Any] = {}

    def _refresh(self) -> None:
        params = self.PARAMETERS(*self._values(self._params))
        if self._model is None or self._model.params != params:
            self._model = self._shared_model(params)  # validates
        n, U = self._values(("n", "U"))
        for name, value in (("n", n), ("U", U)):
            if not (math.isfinite(value) and value > 0.0):
                raise ValueError(f"{name} = {value!r} must be finite and > 0")
        scale = list(self.AXIS.scale_vector(U, n))
        if self._steppers and (self._model is not self._stepper_model or scale != self._scale
                               or n != self._n):
            self._steppers.clear()
        self._n, self._scale, self._stepper_model = n, scale, self._model
        self._set_values(self._matrix,
                         [x for M in (self._model.A_rows, self._model.B_rows) for row in M for x in row])

    @classmethod
    def _names_of_class(cls) -> tuple[Any, ...]:
        """Made once per class: the controls' and the states' rows of the value table (slices),
        the parameters' names, the start values' and the calculated matrices'."""
        names = cls.__dict__.get("_NAMES")
        if names is None:
            vr, axis = cls._class_tables()[0], cls.AXIS
            names = cls._NAMES = (
                _block(tuple(vr[n] for n in axis.control_names)),
                _block(tuple(vr[n] for n in axis.state_names)),
                cls.PARAMETERS.names(),
                tuple(f"{s}_start" for s in axis.state_names),
                tuple(v.name for v in cls.VARIABLES if v.causality == "calculatedParameter"))
        return names

    @classmethod
    def _shared_model(cls, params: Any) -> ZohModel:
        """The model of ``params`` (validated by ``MODEL``), shared by the class's instances:
        its (Phi, Gamma) per step size, a matrix exponential each, outlive an instance (a host
        that resets or re-instantiates the FMU computes them once per process). At most
        :data:`MODELS` parameter sets are kept, the oldest dropped first."""
        models = cls.__dict__.get("_MODELS")
        if models is None:
            models = cls._MODELS = {}
        model = models.get(params)
        if model is None:
            model = cls.MODEL(params)  # raises for parameters that are not valid: not kept
            if len(models) >= MODELS:
                models.pop(next(iter(models)))
            models[params] = model
        return model

    def _update_outputs(self) -> None:
        # Before initialization ends, the initial unknowns already follow the start values and
        # parameters (FMI 2.0: fmi2GetReal in initialization mode); afterwards only doStep
        # changes the outputs (no direct feedthrough).
        if self._initialized:
            return
        start = self._values(self._starts)
        self._check_finite(self._starts, start)
        self._set_values(self.AXIS.state_names, start)
        self._refresh()

    def _initialize(self) -> None:
        start = self._values(self._starts)
        self._check_finite(self._starts, start)
        self._set_values(self.AXIS.state_names, start)  # outputs are defined if _refresh fails
        self._refresh()
        self._x = [float(v) / s for v, s in zip(start, self._scale)]

    def _advance(self, t: float, h: float) -> None:
        r = self._real
        stepper = self._steppers.get(h)
        if stepper is None:
            if len(self._steppers) >= 16:  # a bounded cache, as the model's
                self._steppers.clear()
            stepper = self._steppers[h] = self._model.stepper(
                h * self._n, self._scale, range(self._inputs.start, self._inputs.stop),
                range(self._outputs.start, self._outputs.stop)) or False
        if stepper:  # the fused step (None: a value is not finite, checked below)
            x = stepper(self._x, r)
            if x is not None:
                self._x = x
                return
        u = r[self._inputs]
        total = sum(u)
        if total - total != 0.0:  # inf or nan (or an overflowing sum): named if not finite
            self._check_finite(self.AXIS.control_names, u)
        x = self._model.step_list(self._x, u, h * self._n)
        y = list(map(mul, x, self._scale))
        total = sum(y)
        if total - total != 0.0 and not all(map(math.isfinite, y)):
            inputs = ", ".join(f"{n} = {v!r}" for n, v in zip(self.AXIS.control_names, u))
            raise ValueError(f"state overflow: outputs {y!r} after a step of {h!r} s with "
                             f"{inputs} (the linear model is far outside its range)")
        self._x = x
        r[self._outputs] = y

    def _extra_state(self) -> dict[str, Any]:
        return {"x": list(self._x)}

    def _restore_extra_state(self, state: dict[str, Any]) -> None:
        x = [float(v) for v in state["x"]]
        if len(x) != len(self._x):
            raise ValueError(f"the state holds {len(x)} plant states, expected {len(self._x)}")
        self._x = x
