"""FMU ``DroneFlyFlapping``: the hovering drone fly with its wings flapping, FMI 2.0 / 3.0 CS.

The rigid body of ``DroneFlyHover6DOF`` (the same states, outputs and start parameters, named
alike) driven at every instant of the wing beat by the quasi-steady forces of both wings and
their inertia (:mod:`dronefly.models.flapping`); the seven controls of the linear plants are the
wing kinematics they stand for, taken at the start of each wing beat. The wrapper only maps
variables; the equations live in the model.

The Integer parameter ``forces`` (fixed) chooses what drives the body: 1 (the default) the
instantaneous forces and moments of the flapping wings and their inertia; 2 their cycle
average, with the beat's kinematics (:class:`dronefly.models.flapping.FlappingModel` with
``averaged=True``: the wings' inertia, zero on average, left out), which makes the FMU the
quasi-steady averaged model, ``DroneFlyHover6DOF`` with ``aerodynamics = 2`` and the same body,
sampled at the beats' starts: the comparison of Sect. 2.1's averaging through FMI.

Unlike the other FMUs this one needs numpy in the Python that runs it (the quasi-steady
model is vectorised over the blade elements): importing this module imports it. It needs no
other package (the Gauss-Jacobi nodes of the span are numpy's eigenvalues).
"""

from __future__ import annotations

import math
from functools import lru_cache
from typing import Any

from ...fmi import SlaveBase, Var
from ...models.flapping import (STATE_SIZE, STEPS_PER_BEAT, FlappingError, FlappingModel, Flight)
from ...models.hover6dof import EXTRA_STARTS, OUTPUT_NAMES, STATE_OUTPUTS
from ...models.lateral_interface import N_HZ, U_M_PER_S
from ...models.quasisteady import CONTROLS
from ...models.rigid_body import Hover6DOFError, initial_state, outputs
from ..body_variables import (ATTITUDE_STARTS, VELOCITY_STARTS, control_inputs, rows,
                              start_parameters, state_outputs)

__all__ = ["CONTROL_LIMIT_RAD", "FORCES", "LOAD_OUTPUTS", "MAX_STEP_BEATS", "WING_OUTPUTS",
           "DroneFlyFlapping"]

_STARTS = (*(f"{s}_start" for s in STATE_OUTPUTS), *(e[0] for e in EXTRA_STARTS))
#: the largest control magnitude accepted [rad] (Sect. 3.6 keeps them within 0.4 rad; the
#: blade-element forces are defined for any wing attitude, so nothing else is refused)
CONTROL_LIMIT_RAD = 1.0
#: the longest communication step [wing beats] (a step computes every wing beat it spans)
MAX_STEP_BEATS = 1000.0
#: the values of the parameter ``forces``
FORCES = {1: "instantaneous", 2: "cycle_averaged"}
_FORCES_TEXT = ("forces on the body: 1 = instantaneous (the flapping wings' quasi-steady forces "
                "at every instant of the wing beat, and the wings' inertia), 2 = cycle_averaged "
                "(their average over the wing beat for the beat's controls, as functions of the "
                "state; no wing inertia, zero on average: the averaged model of Sect. 2.1)")
#: (name, unit, display unit, description) of the wing angles
WING_OUTPUTS: tuple[tuple[str, str, str | None, str], ...] = (
    ("stroke_angle_left", "rad", "deg", "left wing's stroke (positional) angle, forward "
                                        "positive, in the stroke plane (the body x-y plane)"),
    ("stroke_angle_right", "rad", "deg", "right wing's stroke angle, forward positive"),
    ("angle_of_attack_left", "rad", "deg", "left wing's geometrical angle of attack: the "
                                           "chord's pitch psi on the downstroke, pi - psi on "
                                           "the upstroke"),
    ("angle_of_attack_right", "rad", "deg", "right wing's geometrical angle of attack"),
)
#: (name, description) of the instantaneous aerodynamic loads (non-dimensional, body axes)
LOAD_OUTPUTS: tuple[tuple[str, str], ...] = tuple(
    (f"{c}_aero", f"instantaneous aerodynamic {what} of both wings (with forces = 2 their "
                  f"cycle average), body {axis} axis, over {scale} (the wings' inertia not "
                  "included)")
    for c, what, axis, scale in (
        ("X", "force", "x", "0.5 rho U^2 S_t"), ("Y", "force", "y", "0.5 rho U^2 S_t"),
        ("Z", "force", "z", "0.5 rho U^2 S_t"), ("L", "moment", "x", "0.5 rho U^2 S_t c"),
        ("M", "moment", "y", "0.5 rho U^2 S_t c"), ("N", "moment", "z", "0.5 rho U^2 S_t c")))


@lru_cache(maxsize=2)
def _shared_model(forces: int = 1) -> FlappingModel:
    """One model per value of ``forces`` for every instance of the process (it keeps no
    flight state; building the first trims the quasi-steady model, some 0.1 s; the averaged
    one shares its aerodynamics)."""
    if forces == 1:
        return FlappingModel(steps_per_beat=STEPS_PER_BEAT)
    return FlappingModel(_shared_model(1).qs, STEPS_PER_BEAT, averaged=True)


def _initial_dependencies(name: str) -> tuple[str, ...]:
    """The knowns an output's initial value is computed from (FMI 2.0 InitialUnknowns)."""
    if name in ("delta_gamma", "delta_theta", "theta"):
        return (f"{name if name != 'theta' else 'delta_theta'}_start",)
    if name in ("phi", "psi"):
        return ATTITUDE_STARTS
    if name in STATE_OUTPUTS:
        return (f"{name}_start",)
    if name in ("x_earth", "y_earth", "z_earth"):
        return (f"{name}_start",)
    if name in ("vx_earth", "vy_earth", "vz_earth"):
        return (*VELOCITY_STARTS, *ATTITUDE_STARTS)
    if name.startswith("stroke_angle"):  # at the rear reversal: phibar - Phi/2
        return ("delta_Phi_a", "delta_Phi", "delta_phibar")
    if name.startswith("angle_of_attack"):  # mid-rotation: (alpha_d + pi - alpha_u)/2
        return ("delta_alpha_2a", "delta_alpha_2")
    # the loads at the start: with forces = 2 (the cycle average of the beat's kinematics)
    # every control changes every load under a change of 1 rad, as the dependencies check of
    # ``dronefly check`` sets it (the couplings of the lateral and longitudinal controls are of
    # second order, but not zero); the model description holds for either value of forces,
    # so the union of the two modes is declared (with forces = 1, at the rear reversal, the
    # wing at rest and mid-rotation, fewer show: a declared dependency that does not show is
    # allowed, a warning of the check; an undeclared one would not be)
    return (*CONTROLS, "forces", *VELOCITY_STARTS, "delta_p_start", "delta_q_start",
            "delta_r_start")


def _variables() -> tuple[Var, ...]:
    out = [*control_inputs("); the wing kinematics it stands for, taken at the start of each "
                           "wing beat"), *state_outputs(_initial_dependencies)]
    for name, u, du, text in WING_OUTPUTS:
        out.append(Var(name, "output", "continuous", text, u, du, initial="calculated",
                       dependencies=(), initial_dependencies=_initial_dependencies(name)))
    for name, text in LOAD_OUTPUTS:
        out.append(Var(name, "output", "continuous", text, "1", initial="calculated",
                       dependencies=(), initial_dependencies=_initial_dependencies(name)))
    out.append(Var("forces", "parameter", "fixed", _FORCES_TEXT, None, start=1,
                   type="Integer"))
    out.append(Var("n", "parameter", "fixed",
                   "wing-beat frequency; reference time t_w = 1/n (Sect. 2.4; the "
                   "aerodynamics are computed for this value, which cannot be changed)", "Hz",
                   start=N_HZ))
    out.append(Var("U", "parameter", "fixed", "reference velocity U = 2 Phi n r2 (Sect. 2.4; "
                   "fixed with n)", "m/s", start=U_M_PER_S))
    return (*out, *start_parameters())


class DroneFlyFlapping(SlaveBase):
    """The hovering model drone fly with its wings flapping (wing-beat-resolved)."""

    MODEL_NAME = "DroneFlyFlapping"
    MODEL_DESCRIPTION = (
        "Hovering model drone fly resolved within the wing beat: the rigid body of "
        "DroneFlyHover6DOF driven at every instant by the quasi-steady blade-element forces of "
        "both flapping wings and by the wings' inertia (no cycle averaging); the controls of "
        "the linear plants are the wing kinematics, taken at the start of each wing beat "
        "(parameter forces = 2: the forces' cycle average instead, the averaged model). "
        "Needs numpy in the Python that runs it")
    VARIABLES = _variables()
    DEFAULT_EXPERIMENT = (0.0, 2.0 / N_HZ, 0.1 / N_HZ)

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        vr = self._vr
        self._controls = CONTROLS
        self._inputs = rows(tuple(vr[n] for n in self._controls))
        self._outputs = rows(tuple(vr[n] for n in (
            *OUTPUT_NAMES, *(w[0] for w in WING_OUTPUTS), *(w[0] for w in LOAD_OUTPUTS))))
        self._model = _shared_model()
        self._flight: Flight | None = None
        self._t0 = 0.0
        self._U, self._n = U_M_PER_S, N_HZ

    def _refresh(self) -> None:
        forces = self._value("forces")
        if forces not in FORCES:
            raise ValueError(f"forces = {forces!r}: expected 1 (instantaneous) or 2 "
                             "(cycle_averaged)")
        self._model = _shared_model(forces)
        for name, value, fixed in (("n", self._value("n"), N_HZ),
                                   ("U", self._value("U"), U_M_PER_S)):
            if value != fixed:
                raise ValueError(f"{name} = {value!r}: this FMU's aerodynamics are computed for "
                                 f"the Sect. 2.4 flight data ({name} = {fixed!r})")

    def _controls_now(self) -> tuple[float, ...]:
        c = self._real[self._inputs]
        self._check_finite(self._controls, c)
        for name, value in zip(self._controls, c):
            if abs(value) > CONTROL_LIMIT_RAD:
                raise ValueError(f"{name} = {value!r} rad is outside +/-{CONTROL_LIMIT_RAD} rad")
        return tuple(float(v) for v in c)

    def _start_state(self) -> list[float]:
        starts = self._values(_STARTS)
        self._check_finite(_STARTS, starts)
        self._refresh()
        try:
            return initial_state(dict(zip(_STARTS, starts)), self._U, self._n)
        except Hover6DOFError as e:
            raise ValueError(str(e)) from e

    def _write(self, t_plus: float, x: Any) -> None:
        flight = self._flight
        tau, cp, cn = flight.phase(t_plus)
        ang = self._model.angles(tau, cp, cn)
        aero, _ = self._model.loads(tau, x, cp, cn)
        down = tau <= 0.5
        alpha = [float(a) if down else math.pi - float(a) for a in ang[3]]
        values = [*outputs(list(x), self._U, self._n), float(ang[0][0]), float(ang[0][1]),
                  *alpha, *(float(v) for v in aero)]
        total = sum(values)
        if total - total != 0.0:  # an output not finite (the loads of a huge state)
            starts = {n: v for n, v in zip(_STARTS, self._values(_STARTS)) if v != 0.0}
            raise ValueError(f"overflow: outputs not finite at t+ = {t_plus!r} wing beats "
                             f"(u, v, w, p, q, r = {[float(v) for v in x[:6]]!r}; nonzero start "
                             f"values {starts!r})")
        self._real[self._outputs] = values

    def _update_outputs(self) -> None:
        if not self._initialized:  # initial unknowns follow the starts until initialized
            self._start_flight()

    def _start_flight(self) -> None:
        x = self._start_state()
        flight = Flight(self._model, x, self._controls_now())
        previous, self._flight = self._flight, flight
        try:
            self._write(0.0, flight.y)
        except ValueError:
            self._flight = previous
            raise

    def _initialize(self) -> None:
        self._t0 = self._time
        self._start_flight()

    def _advance(self, t: float, h: float) -> None:
        if h * self._n > MAX_STEP_BEATS:
            raise ValueError(f"a step of {h!r} s is {h * self._n:.6g} wing beats, more than "
                             f"{MAX_STEP_BEATS:g}: take shorter steps")
        c = self._controls_now()
        flight = self._flight
        t_plus = (t + h - self._t0) * self._n
        flight.set_controls(c)
        before = flight.snapshot()
        try:
            x = flight.advance_to(t_plus)
            self._write(t_plus, x)
        except FlappingError as e:
            flight.restore(before)
            raise ValueError(f"state overflow: {e}") from e
        except ValueError:
            flight.restore(before)
            raise

    def _extra_state(self) -> dict[str, Any]:
        return {"t0": self._t0, "flight": self._flight.snapshot() if self._flight else None}

    def _restore_extra_state(self, state: dict[str, Any]) -> None:
        snap = state["flight"]
        if snap is not None:
            y = [float(v) for v in snap["y"]]
            if len(y) != STATE_SIZE or not all(math.isfinite(v) for v in y):
                raise ValueError(f"the state must hold {STATE_SIZE} finite values, got {y!r}")
            self._refresh()  # the model of the restored value of forces
            if self._flight is None or self._flight.model is not self._model:
                self._flight = Flight(self._model, y)
            self._flight.restore(snap)
        self._t0 = float(state["t0"])
