"""The variables that the rigid-body plants share: ``DroneFlyHover6DOF`` and
``DroneFlyFlapping`` (the controls of both linear plants as inputs, the body's states and
attitude outputs, their start parameters), named, described and with units as in
:mod:`dronefly.models.hover6dof`.
"""

from __future__ import annotations

from typing import Callable

from ..fmi import Var
from ..models.hover6dof import EARTH_OUTPUTS, EULER_OUTPUTS, EXTRA_STARTS, OUTPUT_NAMES
from ..models.lateral_interface import LATERAL
from ..models.longitudinal_interface import LONGITUDINAL

__all__ = ["AXES", "ATTITUDE_STARTS", "VELOCITY_STARTS", "control_inputs", "rows",
           "start_parameters", "state_outputs"]

#: the two axes whose controls are the inputs and whose states are the outputs
AXES = (LATERAL, LONGITUDINAL)
#: the start parameters of the attitude and of the body-axis velocity
ATTITUDE_STARTS = ("delta_gamma_start", "delta_theta_start", "psi_start")
VELOCITY_STARTS = ("delta_u_start", "delta_v_start", "delta_w_start")


def rows(vrs: tuple[int, ...]) -> slice:
    """Consecutive value references ``vrs`` as one slice of the value table (the plants read
    their controls and write their outputs as slices).

    Raises
    ------
    ValueError
        The value references are not consecutive (a change of the variable tables' order).
    """
    if vrs != tuple(range(vrs[0], vrs[0] + len(vrs))):
        raise ValueError(f"value references {vrs} are not consecutive")
    return slice(vrs[0], vrs[0] + len(vrs))


def _states() -> list[tuple[str, str, tuple[str, str]]]:
    return [(n, d, u) for a in AXES
            for n, d, u in zip(a.state_names, a.state_descriptions, a.state_units)]


def control_inputs(when: str) -> list[Var]:
    """The seven controls of both linear plants as inputs [rad]; ``when`` (the text after the
    axis in each description) says when a control takes effect."""
    unit, disp = LATERAL.control_unit
    return [Var(name, "input", "continuous", f"{text} ({axis.name}{when}", unit, disp, start=0.0)
            for axis in AXES for name, text in zip(axis.control_names, axis.control_descriptions)]


def state_outputs(initial_dependencies: Callable[[str], tuple[str, ...]]) -> list[Var]:
    """The outputs of :data:`dronefly.models.hover6dof.OUTPUT_NAMES` (states, Euler angles,
    earth-axis position and velocity), each depending on no input, with the knowns its initial
    value is computed from (FMI 2.0 InitialUnknowns)."""
    extra = [(n, d, (u, du)) for n, u, du, d in (*EULER_OUTPUTS, *EARTH_OUTPUTS)]
    table = {n: (d, u) for n, d, u in (*_states(), *extra)}
    out = []
    for name in OUTPUT_NAMES:
        text, (u, du) = table[name]
        out.append(Var(name, "output", "continuous", text, u, du, initial="calculated",
                       dependencies=(), initial_dependencies=initial_dependencies(name)))
    return out


def start_parameters() -> list[Var]:
    """The fixed ``*_start`` parameter of every state and of the extra attitude and position
    starts (:data:`dronefly.models.hover6dof.EXTRA_STARTS`), all 0 by default."""
    out = [Var(f"{name}_start", "parameter", "fixed", f"initial {text}", u, du, start=0.0)
           for name, text, (u, du) in _states()]
    out += [Var(name, "parameter", "fixed", text, u, du, start=0.0)
            for name, u, du, text in EXTRA_STARTS]
    return out
