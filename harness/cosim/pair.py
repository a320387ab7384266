"""What a plant/controller pair connected by name is made of: its states, controls, gains and
the scales that make its state non-dimensional, read from the two model descriptions.

``cosim`` and ``sweep`` identify any such pair, not only the lateral one: the states are the
plant's Real outputs that have a ``<state>_start`` parameter (how a run sets the initial
state), each made non-dimensional by the reference scale its unit calls for (m/s: U, rad/s:
n, rad or 1: none; Sect. 2.1); the controls are the plant's inputs; the gains are the
controller's ``K[i,j]`` (row i: the i-th control, column j: the j-th state, as x+). A pair that
lacks one of these cannot be identified and is refused with the reason
(:class:`PairError`) before anything runs.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Mapping

import numpy as np

from .master import CoSimError

__all__ = ["STATE_SCALES", "PairError", "PairLayout", "pair_layout"]


class PairError(CoSimError):
    """A plant/controller pair whose loop cannot be identified (names what is missing)."""


#: The reference scale of a state by its SI unit: x+ = x / U (m/s), x / n (rad/s), x (rad, 1).
STATE_SCALES: dict[str, str] = {"m/s": "U", "rad/s": "n", "rad": "1", "1": "1"}


def _unit(v: Any) -> str:
    unit = getattr(v, "unit", None)
    if unit is None and getattr(v, "declaredType", None) is not None:
        unit = v.declaredType.unit
    return unit or "1"


@dataclass(frozen=True)
class PairLayout:
    """The states, controls and gains of a plant/controller pair.

    Attributes
    ----------
    states : tuple of str
        The plant's state outputs (each with a ``<state>_start`` parameter), in its order:
        the columns of A and of K.
    controls : tuple of str
        The plant's inputs, in its order: the columns of B and the rows of K.
    scales : tuple of str
        Per state, ``"U"``, ``"n"`` or ``"1"``: x+_i = x_i / scale_i.
    units : tuple of str
        Per state, its SI unit.
    """

    states: tuple[str, ...]
    controls: tuple[str, ...]
    scales: tuple[str, ...]
    units: tuple[str, ...]

    @property
    def shape(self) -> tuple[int, int]:
        """(controls, states): the shape of K."""
        return len(self.controls), len(self.states)

    def gain_names(self, stem: str = "K") -> list[list[str]]:
        """``stem[i,j]`` (1-based) for every control i and state j."""
        return [[f"{stem}[{i + 1},{j + 1}]" for j in range(len(self.states))]
                for i in range(len(self.controls))]

    def scale_vector(self, plant_values: Mapping[str, Any],
                     scales: tuple[str, ...] | None = None) -> np.ndarray:
        """x = x+ * scale: per state its U [m/s], n [Hz] or 1, from the plant's values
        (``scales``: these instead of the states', e.g. ``("n",)`` for the wing-beat
        frequency that makes times non-dimensional).

        Raises
        ------
        PairError
            A scale the states need that the plant has not, or one not finite and > 0.
        """
        scales = self.scales if scales is None else scales
        table = {"1": 1.0}
        for key in sorted(set(scales) - {"1"}):
            value = plant_values.get(key)
            try:
                value = float(value)  # type: ignore[arg-type]
            except (TypeError, ValueError):
                raise PairError(f"the plant has no parameter {key!r}: its states in "
                                f"{'m/s' if key == 'U' else 'rad/s'} are read as x+ over its "
                                f"{key} ({'m/s' if key == 'U' else 'Hz'})") from None
            if not (np.isfinite(value) and value > 0.0):
                raise PairError(f"plant.{key} = {value!r} must be finite and > 0")
            table[key] = value
        return np.array([table[s] for s in scales])

    def default_x0(self) -> np.ndarray:
        """The initial state x+ when none is given: 0.1 rad in the first angle (unit rad;
        for the lateral plant delta_gamma, a 0.1 rad roll), else 0.1 in the first state."""
        x = np.zeros(len(self.states))
        x[self.units.index("rad") if "rad" in self.units else 0] = 0.1
        return x


def pair_layout(plant: Any, controller: Any) -> PairLayout:
    """The :class:`PairLayout` of a plant and a controller FMU
    (:class:`~dronefly.harness.cosim.fmu.FMU`) connected by name.

    Raises
    ------
    PairError
        The plant has no state output with a ``<state>_start`` parameter or no input; a
        controller input that is not such a state; the controller's inputs not the plant's
        states in order, or its controls not the plant's inputs in order; a gain ``K[i,j]`` the controller has not; a state whose unit has no
        reference scale.
    """
    pv = plant.variables
    where = f"plant {str(plant.path)!r}"
    outputs = [v.name for v in plant.model_description.modelVariables
               if v.causality == "output" and v.type == "Real"]
    states = tuple(n for n in outputs if f"{n}_start" in pv
                   and pv[f"{n}_start"].causality == "parameter")
    if not states:
        raise PairError(f"cannot identify the loop: the {where} has no Real output x with a "
                        "parameter x_start (how cosim sets its initial state)")
    controls = tuple(plant.names("input"))
    if not controls:
        raise PairError(f"cannot identify the loop: the {where} has no input")
    sensed = controller.names("input")
    extra = [n for n in sensed if n not in states]
    if extra:
        raise PairError(f"cannot identify the loop: controller input {extra[0]!r} is a plant "
                        f"output without a parameter {extra[0]}_start, not a state of the "
                        f"plant ({', '.join(states)})")
    if list(sensed) != list(states):
        raise PairError(f"cannot identify the loop: the controller's inputs "
                        f"({', '.join(sensed)}) are not the plant's states in its order "
                        f"({', '.join(states)}), the columns of its K")
    driving = [n for n in controller.names("output") if n in controls]
    if driving != list(controls):
        raise PairError(f"cannot identify the loop: the controller's outputs "
                        f"({', '.join(driving)}) are not in the order of the plant's inputs "
                        f"({', '.join(controls)}), the rows of its K")
    units = tuple(_unit(pv[s]) for s in states)
    bad = [(s, u) for s, u in zip(states, units) if u not in STATE_SCALES]
    if bad:
        raise PairError(f"cannot identify the loop: plant state {bad[0][0]!r} is in "
                        f"{bad[0][1]!r}; the harness reads states in "
                        f"{', '.join(STATE_SCALES)} as x+ (Sect. 2.1)")
    layout = PairLayout(states, controls, tuple(STATE_SCALES[u] for u in units), units)
    missing = [n for row in layout.gain_names() for n in row if n not in controller.variables]
    if missing:
        raise PairError(f"cannot identify the loop: the controller {str(controller.path)!r} "
                        f"has no gain {missing[0]!r} ({layout.shape[0]} controls x "
                        f"{layout.shape[1]} states: {', '.join(controls)} on "
                        f"{', '.join(states)})")
    return layout
