"""The quasi-steady model of both wings (:class:`QuasiSteadyModel`): one object that holds the
options (coefficients, terms, grid), the blade elements and the trim, and answers for the
forces, cycle-averaged or instantaneous."""

from __future__ import annotations

from typing import Any, Callable, Mapping, Sequence

import numpy as np

from ...core.errors import DroneflyError
from .cycle import cycle_maps, cycle_mean, sampled_forces
from .elements import blade_elements
from .instantaneous import Instant, instants
from .kinematics import named, sampled_motion, wing_kinematics
from .trim import Trim, solve_trim
from .wing import COEFFICIENT_SETS, CONTROLS, STATES, Array, CoefficientSet, Terms, WingGeometry

__all__ = ["QuasiSteadyModel"]

class QuasiSteadyModel:
    """The forces and moments of both wings, in the paper's non-dimensional form.

    Four ways to the forces, each its own contract (all non-dimensional: the body state
    (du+, dv+, dw+, dp+, dq+, dr+), velocities over U and rates times t_w; the loads
    (X+, Y+, Z+, L+, M+, N+), forces over 0.5 rho U^2 S_t and moments over 0.5 rho U^2 S_t c,
    in the order of :data:`~dronefly.models.quasisteady.FORCES`):

    - the cycle average at one state: :meth:`forces_vector`;
    - the cycle average as a function of the state, the controls held (the wing motion
      mapped once, for the plants' Runge-Kutta stages): :meth:`state_function`;
    - the instantaneous loads at any wing motion: :meth:`forces_at` at one instant, or
      :meth:`instants` for the wing motion's part at many instants, each then called with
      states (the wing-beat-resolved plant);
    - the instantaneous loads sampled over the cycle of this model's kinematics, element by
      element (the independent evaluation the others are checked against):
      :meth:`forces_over_cycle`.

    Parameters
    ----------
    coefficients : str or CoefficientSet
        Translational coefficients (a key of :data:`~dronefly.models.quasisteady.COEFFICIENT_SETS`,
        default ``"dickinson1999"``).
    terms : Terms
        The force terms to add.
    n_span : int
        Blade elements per wing (Gauss-Jacobi nodes of the planform), default 8.
    n_time : int
        Samples per cycle (default 100), even, at t+ = (j + 1/2)/n_time: no sample falls on a stroke
        reversal, where the element velocity vanishes and the force directions are undefined.
    geometry : WingGeometry, optional
        Default: :meth:`WingGeometry.from_flight_data`.
    """

    def __init__(self, coefficients: str | CoefficientSet = "dickinson1999",
                 terms: Terms = Terms(), n_span: int = 8, n_time: int = 100,
                 geometry: WingGeometry | None = None) -> None:
        if isinstance(coefficients, str):
            if coefficients not in COEFFICIENT_SETS:
                raise DroneflyError(f"coefficients {coefficients!r}: expected one of "
                                    f"{', '.join(COEFFICIENT_SETS)}")
            coefficients = COEFFICIENT_SETS[coefficients]
        if n_time < 20 or n_time % 2:
            raise DroneflyError(f"n_time = {n_time!r} must be an even number >= 20")
        if terms.added_mass_form not in ("sane2001", "impulse"):
            raise DroneflyError(f"added_mass_form {terms.added_mass_form!r}: expected sane2001 "
                                "or impulse")
        if n_span < 2:
            raise DroneflyError(f"n_span = {n_span!r} must be >= 2")
        self.coefficients = coefficients
        self.terms = terms
        self.geometry = geometry or WingGeometry.from_flight_data()
        self.n_span, self.n_time = n_span, n_time
        #: the blade elements (:func:`~dronefly.models.quasisteady.elements.blade_elements`)
        self.elements = blade_elements(self.geometry, terms, n_span)
        self._t = (np.arange(n_time) + 0.5) / n_time
        self._trim: Trim | None = None
        self._kin_key: tuple[bytes, ...] | None = None
        self._kin: dict[str, Array] = {}
        self._map_key: tuple[bytes, ...] | None = None
        self._map: dict[str, Array] = {}

    # -- kinematics ---------------------------------------------------------------------
    def wing_kinematics(self, control: Mapping[str, float] | None = None,
                        trim: Trim | None = None) -> dict[str, Array]:
        """Per-wing (left, right) stroke amplitude, mean stroke angle and angles of attack [rad].

        Parameters
        ----------
        control : mapping, optional
            Control increments [rad] by name (:data:`~dronefly.models.quasisteady.CONTROLS`);
            unnamed ones are 0.
        trim : Trim, optional
            The reference angles (default: :meth:`trim`).
        """
        return wing_kinematics(self.geometry, trim or self.trim(), control)

    # -- the cycle average --------------------------------------------------------------
    def _maps(self, Phi: Array, phibar: Array, alpha_d: Array, alpha_u: Array) -> dict[str, Array]:
        """:func:`~dronefly.models.quasisteady.cycle.cycle_maps`, cached for the last
        kinematics."""
        key = (Phi.tobytes(), phibar.tobytes(), alpha_d.tobytes(), alpha_u.tobytes())
        if self._map_key != key:
            self._map = cycle_maps(self._t, Phi, phibar, alpha_d, alpha_u, self.geometry,
                                   self.terms, self.elements)
            self._map_key = key
        return self._map

    def _mean(self, Phi: Array, phibar: Array, alpha_d: Array, alpha_u: Array,
              state: Sequence[float] | Array) -> Array:
        """Cycle-averaged loads for per-wing kinematics (left, right) [rad]."""
        return cycle_mean(self._maps(Phi, phibar, alpha_d, alpha_u), state, self.terms,
                          self.coefficients, self.elements.cw, self.geometry.S_wing,
                          self.n_time)

    def _kinematics_and_state(self, state: Sequence[float] | Array,
                              control: Mapping[str, float] | None,
                              trim: Trim | None) -> tuple[Any, ...]:
        """(Phi, phibar, alpha_d, alpha_u, x) for :meth:`_mean` and
        :meth:`forces_over_cycle`; a state that is not 6 finite numbers is refused naming it."""
        x = np.asarray(state, dtype=float)
        if x.shape != (6,) or not np.all(np.isfinite(x)):
            raise DroneflyError(f"state = {state!r}: expected 6 finite numbers "
                                f"({', '.join(STATES)})")
        kin = self.wing_kinematics(control, trim)
        return kin["Phi"], kin["phibar"], kin["alpha_d"], kin["alpha_u"], x

    def forces_vector(self, state: Sequence[float] | Array | Mapping[str, float] = (0.0,) * 6,
                      control: Mapping[str, float] | None = None,
                      trim: Trim | None = None) -> Array:
        """The cycle-averaged loads of both wings at one body state.

        Parameters
        ----------
        state : sequence of 6 floats, or mapping
            (du+, dv+, dw+, dp+, dq+, dr+) about hover (velocities over U, rates times t_w), or
            the same by name (:data:`~dronefly.models.quasisteady.STATES`; 0 where not named).
        control : mapping, optional
            Control increments [rad] by name (:data:`~dronefly.models.quasisteady.CONTROLS`),
            0 where not named.
        trim : Trim, optional
            The reference (default: the trimmed hover).

        Returns
        -------
        array of 6 floats
            (X+, Y+, Z+, L+, M+, N+) averaged over the wing beat: forces over
            0.5 rho U^2 S_t, moments over 0.5 rho U^2 S_t c (order
            :data:`~dronefly.models.quasisteady.FORCES`).
        """
        if isinstance(state, Mapping):
            state = [float(v) for v in named(state, STATES, "state").values()]
        return self._mean(*self._kinematics_and_state(state, control, trim))

    def state_function(self, controls: Sequence[float] = (0.0,) * 7,
                       trim: Trim | None = None) -> Callable[[Sequence[float]], Array]:
        """The cycle-averaged loads as a function of the body state, the controls held.

        What the 6-DOF plant's quasi-steady aerodynamics call at every Runge-Kutta stage
        (:class:`dronefly.models.rigid_body.Hover6DOF`): the wing motion of ``controls`` is
        mapped once, each call computes only what depends on the state.

        Parameters
        ----------
        controls : sequence of 7 floats
            The control increments [rad] in the order of
            :data:`~dronefly.models.quasisteady.CONTROLS` (lateral, then longitudinal).
        trim : Trim, optional
            The reference (default: the trimmed hover).

        Returns
        -------
        callable
            (du+, dv+, dw+, dp+, dq+, dr+) -> array (X+, Y+, Z+, L+, M+, N+), as
            :meth:`forces_vector` returns (no check of the state: the caller's).
        """
        if len(controls) != len(CONTROLS):
            raise DroneflyError(f"controls = {controls!r}: expected {len(CONTROLS)} values "
                                f"({', '.join(CONTROLS)})")
        kin = self.wing_kinematics(dict(zip(CONTROLS, controls)), trim)
        mp = self._maps(kin["Phi"], kin["phibar"], kin["alpha_d"], kin["alpha_u"])
        terms, coefficients, cw = self.terms, self.coefficients, self.elements.cw
        S_wing, n_time = self.geometry.S_wing, self.n_time
        return lambda state: cycle_mean(mp, state, terms, coefficients, cw, S_wing, n_time)

    # -- the instantaneous loads --------------------------------------------------------
    def instants(self, angles: Sequence[Sequence[float]] | Array) -> list[Instant]:
        """The wing motion's part of the instantaneous loads at one or more instants, each
        then called with body states.

        Everything of :meth:`forces_at` that does not depend on the body state
        (:func:`~dronefly.models.quasisteady.instantaneous.instants`). A host that needs the
        loads at the same wing motion for many states (the Runge-Kutta stages of
        :mod:`dronefly.models.flapping`, the same instants every wing beat) computes this once.

        Parameters
        ----------
        angles : array, shape (6, 2) or (T, 6, 2)
            As :meth:`forces_at`, per wing (columns left, right): phi [rad], dphi/dt+
            [rad per wing beat], d2phi/dt+2 [rad per wing beat squared], psi [rad] and its two
            derivatives; a stack of T instants (computed together).

        Returns
        -------
        list of Instant
            One per instant (one for a single (6, 2)): ``instant(state)`` is the array
            (X+, Y+, Z+, L+, M+, N+) at the body state (du+, dv+, dw+, dp+, dq+, dr+), as
            :meth:`forces_at` returns (no check of the state: the caller's).

        Raises
        ------
        DroneflyError
            The angles' shape is wrong, or the model's added mass is not the impulse form.
        """
        return instants(angles, self.geometry, self.terms, self.coefficients, self.elements)

    def forces_at(self, angles: Sequence[Sequence[float]] | Array,
                  state: Sequence[float] | Array = (0.0,) * 6) -> Array:
        """The instantaneous loads of both wings at one instant.

        ``angles`` holds, per wing (columns left, right), the stroke angle phi, the pitch angle
        psi of the chord from the forward stroke direction (alpha_d in mid-downstroke,
        pi - alpha_u in mid-upstroke) and their first two derivatives in t+: rows (phi, dphi,
        ddphi, psi, dpsi, ddpsi), shape (6, 2) [rad, per wing beat]. Any wing motion, not only
        this model's harmonic kinematics (the wing-beat-resolved plant,
        :mod:`dronefly.models.flapping`, changes the kinematics between wing beats). The terms
        and their scaling are those of :meth:`forces_over_cycle`, evaluated as
        :meth:`forces_vector` evaluates them: each element's velocity (the spanwise part
        removed) is V_c e_c + V_n n, affine in the span, its forces along e_c, n and (the added
        mass's turning normal) e_r. The added mass's time derivative is analytic, from the
        wing's angular accelerations and the body's rates; the body's own acceleration does not
        enter it (the state is the body's, not its rate): that leaves out the added mass of the
        air that the wings carry with the body, m_a / m = 0.24 % of the insect's mass (both
        wings), a correction the cycle average does not have either.

        It is the one :meth:`instants` instant of ``angles`` called with ``state``.

        Returns
        -------
        array of 6 floats
            (X+, Y+, Z+, L+, M+, N+) at that instant: forces over 0.5 rho U^2 S_t, moments over
            0.5 rho U^2 S_t c.

        Raises
        ------
        DroneflyError
            ``angles`` is not (6, 2) or ``state`` not 6 values.
        """
        a = np.asarray(angles, dtype=float)
        x = np.asarray(state, dtype=float)
        if a.shape != (6, 2) or x.shape != (6,):
            raise DroneflyError(f"angles of shape {a.shape} and state of shape {x.shape}: "
                                "expected (6, 2) and (6,)")
        return self.instants(a)[0](x)

    def forces_over_cycle(self, state: Sequence[float] | Array = (0.0,) * 6,
                          control: Mapping[str, float] | None = None,
                          trim: Trim | None = None) -> Array:
        """The instantaneous loads over the cycle, shape (6, n_time).

        At t+ = (j + 1/2)/n_time, element by element; the added mass's time derivatives are
        periodic central differences. Its mean over the samples is the cycle average of
        :meth:`forces_vector` up to their O(1/n_time^2) difference in the added mass's moment
        (round-off elsewhere). Parameters as :meth:`forces_vector` (the state as 6 values).

        Returns
        -------
        array, shape (6, n_time)
            (X+, Y+, Z+, L+, M+, N+) at each sample: forces over 0.5 rho U^2 S_t, moments over
            0.5 rho U^2 S_t c.
        """
        Phi, phibar, alpha_d, alpha_u, x = self._kinematics_and_state(state, control, trim)
        key = (Phi.tobytes(), phibar.tobytes(), alpha_d.tobytes(), alpha_u.tobytes())
        if self._kin_key != key:
            self._kin = sampled_motion(self.geometry, self.elements.r, self._t, Phi, phibar,
                                       alpha_d, alpha_u)
            self._kin_key = key
        return sampled_forces(self._kin, x, self.geometry, self.terms, self.coefficients,
                              self.elements, self.n_time)

    # -- trim ---------------------------------------------------------------------------
    def trim(self, tol: float = 1e-12, max_iter: int = 30) -> Trim:
        """alpha_d, alpha_u and phibar [rad] such that X = 0, Z = -W+ and M = 0 (cached;
        :func:`~dronefly.models.quasisteady.trim.solve_trim`).

        Raises
        ------
        DroneflyError
            No trim with 0 < alpha < 90 deg and |phibar| < 90 deg, or the residual is not below
            max(``tol``, 1e-9) W+ (a model without the lift terms).
        """
        if self._trim is None:
            Phi = self.geometry.Phi_rad

            def mean(alpha_d: float, alpha_u: float, phibar: float) -> Array:
                return self._mean(np.full(2, Phi), np.full(2, phibar), np.full(2, alpha_d),
                                  np.full(2, alpha_u), np.zeros(6))

            self._trim = solve_trim(mean, self.geometry.weight,
                                    f"{self.coefficients.name}, terms {self.terms}", tol, max_iter)
        return self._trim

    def with_options(self, **changes: object) -> "QuasiSteadyModel":
        """A new model with other ``coefficients``, ``terms``, ``n_span``, ``n_time``."""
        opts = {"coefficients": self.coefficients, "terms": self.terms, "n_span": self.n_span,
                "n_time": self.n_time, "geometry": self.geometry, **changes}
        return QuasiSteadyModel(**opts)  # type: ignore[arg-type]
