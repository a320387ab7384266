"""The wing-beat-resolved model: the rigid body driven by the flapping wings' instantaneous forces.

Zhang & Sun (Sect. 2.1) replace the flapping wings by their cycle-averaged forces. This model
does not: the rigid body of ``DroneFlyHover6DOF`` (same 13-value non-dimensional state, same
axes: body axes at the centre of mass, x forward, y right, z down; earth axes north-east-down)
is driven at every instant of the wing beat by the forces and moments of both wings from the
quasi-steady blade-element model, :meth:`dronefly.models.quasisteady.QuasiSteadyModel.forces_at`
(one implementation, imported). Everything is non-dimensional as there: velocities over U,
rates times t_w, time t+ in wing beats, forces over 0.5 rho U^2 S_t, lengths in mean chords c
(the position P+ in U t_w, as the 6-DOF plant's).

Equations (x = (V+, omega+, e, P+), R(e) body -> earth):

- m+ dV+/dt+ = F_aero+(t+, V+, omega+) + F_wing+ + m+ g+ R^T e_z - m+ omega+ x V+
- J+ domega+/dt+ = M_aero+ + M_wing+ - omega+ x J+ omega+
- de/dt+ = e * (0, omega+) / 2, dP+/dt+ = R V+

with m+, J+ (the full tensor, Ixz+) and g+ from the Sect. 2.4 flight data
(:func:`dronefly.models.lateral_interface.reference_scales`), the same data whose weight the
quasi-steady trim balances (so the trimmed wing motion holds the insect up on average).

Wing inertia: each wing (m_w = 0.56 mg, 0.6 % of the insect) is a point mass at 0.35 R along
its span axis from the root, moving relative to the body with the prescribed stroke; the body
feels the reaction -m_w (a_rel + 2 omega x v_rel) at that point (a_rel, v_rel its acceleration
and velocity relative to the body, the Coriolis term with the body's rate). It is included,
and it is not negligible within the wing beat: the two wings' forward-backward inertial forces
add (together up to 4.2 times the weight), and they dominate the body's fore-aft oscillation
(docs/averaging.md gives the orbit with and without them). Their cycle average is zero, so they
do not change the averaged model. Left out: the centripetal term omega x (omega x r_w) (second
order in the body's rate), the change within the beat of the wings' share of the inertia
tensor (each wing's m_w r^2 about the centre of mass is about 1 % of Iy; the paper's J+ holds
the mean), the shift of the insect's centre of mass in the gravity moment (40 micrometres peak:
the body's fore-aft oscillation on the periodic orbit is its mirror image), and the wing's
rotational inertia about its own span.

Controls (the seven of the linear plants, in the order of
:data:`dronefly.models.quasisteady.CONTROLS`) are the wing kinematics they stand for
(:meth:`QuasiSteadyModel.wing_kinematics`: per-wing stroke amplitude, mean stroke angle, angles
of attack). **When a change takes effect**: the controls are sampled at the start of each wing
beat, t+ = k, the rear stroke reversal where the wing is at rest, and held for that beat.
Beat k's stroke runs from the rear reversal the previous beat reached to the front reversal of
the new controls (downstroke), then to their rear reversal (upstroke), each half a cosine, so
the stroke angle and its rate are continuous; the pitch rotation centred on the reversal at
t+ = k is already under way when the controls are sampled and is finished with the angles it
began with, so the new angles of attack begin with the next rotation: the upstroke angle
alpha_u in beat k, the downstroke angle alpha_d from beat k + 1 (no jump in the pitch angle or
rate, so no impulse of the added mass). With the controls held, the kinematics are exactly
those of the quasi-steady model. A host that steps once per wing beat and one that steps 40
times per wing beat, setting the same controls at the beats' starts, see the same physics
(tests/test_flapping.py): a change between two beat starts waits for the next one.

Integration: the classical Runge-Kutta method on a fixed grid of :data:`STEPS_PER_BEAT` steps
per wing beat anchored at the beats' starts (so the stroke reversals, t+ = k and k + 1/2, and
the rotations' ends are grid points, where the forces have kinks), independent of any
communication step: a communication point between two grid points is reached by a partial step
from the last grid point that the state does not keep. The accuracy against
``scipy.integrate.solve_ivp`` (rtol 1e-10), tests/test_flapping.py: 8e-7 over a beat from hover
(order 4); from a disturbed state with new controls 7.5e-6, of first order in the step where an
element's normal velocity crosses zero off the grid (the lift coefficient's value at zero
incidence, 0.027 in Dickinson's fit, turns the normal force over: a jump in time).

What the equations need of the wing motion at an instant (the angles, the quasi-steady model's
:meth:`~dronefly.models.quasisteady.QuasiSteadyModel.instants`, the wing inertia as an affine
map of the state) does not depend on the state: for the grid's steps it is made once per pair
of controls (the 2N + 2 distinct stage instants of a beat, all together) and kept, so a beat
with its controls held costs the 4N evaluations of the state's part
(:meth:`~dronefly.models.quasisteady.QuasiSteadyModel.forces_of`, the rigid body) alone; a
partial step makes its own. The kept stages are the equations evaluated at those instants, to
round-off (tests/test_flapping.py); the angles and loads at a grid point are its stage's.

numpy is imported (the quasi-steady model needs it); the FMU that ships this module documents it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable, Mapping, Sequence

import numpy as np

from ..core.errors import DroneflyError
from .lateral_interface import FLIGHT_DATA, reference_scales
from .quasisteady import CONTROLS, QuasiSteadyModel
from .rigid_body import euler_from_quaternion, quaternion_from_euler

__all__ = ["STATE_SIZE", "STEPS_PER_BEAT", "WING_CM_OVER_R", "FlappingError", "FlappingModel",
           "Flight", "Floquet", "PeriodicOrbit", "Z_NAMES", "orbit_start", "shooting", "wing_beat_controls"]

#: number of state values (as the 6-DOF plant: u, v, w, p, q, r, e0..e3, x, y, z)
STATE_SIZE = 13
#: Runge-Kutta steps per wing beat (a multiple of 20 puts t+ = 0.15, 0.35, ... on the grid)
STEPS_PER_BEAT = 40
#: the wing's centre of mass along its span, from the root, over R
WING_CM_OVER_R = 0.35
#: the reduced coordinates of the wing-beat map (position and heading are neutral)
Z_NAMES: tuple[str, ...] = ("u", "v", "w", "p", "q", "r", "phi", "theta")


#: the centres of the pitch's five phases in a beat: the rotation about the reversal at its
#: start, held, the rotation about the front reversal, held, the rotation about the next
#: beat's start (a held phase has no centre: 0)
_PITCH_CENTRES = np.array([0.0, 0.0, 0.5, 0.0, 1.0])
#: the grids of stages kept (:meth:`FlappingModel._grid`, some 0.7 MB each), the least recently
#: used dropped: one model serves every FMU instance of a process, so each instance whose
#: controls are held keeps one (16 instances at their own controls before a grid is made again;
#: a closed loop, whose controls change every beat, makes one per beat whatever the size)
_TABLES = 16


class FlappingError(DroneflyError):
    """A bad value for the flapping model (the message names it)."""


def shooting(period_map: Callable[[np.ndarray], np.ndarray], x0: np.ndarray,
             monodromy: np.ndarray, tol: float, max_iter: int,
             scales: np.ndarray | None = None) -> tuple[np.ndarray, list[float]]:
    """A periodic orbit by shooting: Newton's chord method on ``period_map(x) - x`` from ``x0``,
    the Jacobian ``monodromy - I`` kept for every step (the map is nearly linear over the
    orbit's offset), until the largest residual (over ``scales``, if given) is below ``tol``.

    Returns
    -------
    x, residuals : array, list of float
        The state at the orbit's start and the residual of each iteration.

    Raises
    ------
    FlappingError
        The residual is not below ``tol`` after ``max_iter`` steps.
    """
    x = np.asarray(x0, dtype=float)
    J = np.asarray(monodromy, dtype=float) - np.eye(len(x))
    residuals: list[float] = []
    for _ in range(max_iter):
        r = period_map(x) - x
        residuals.append(float(np.max(np.abs(r if scales is None else r / scales))))
        if residuals[-1] < tol:
            return x, residuals
        x = x - np.linalg.solve(J, r)
    raise FlappingError(f"no periodic orbit: the residual is {residuals[-1]:.3g} after "
                        f"{max_iter} steps ({residuals!r})")


def wing_beat_controls(control: Mapping[str, float] | Sequence[float] | None) -> tuple[float, ...]:
    """The seven controls [rad] in :data:`CONTROLS` order from a mapping or a sequence."""
    if control is None:
        return (0.0,) * len(CONTROLS)
    if isinstance(control, Mapping):
        unknown = set(control) - set(CONTROLS)
        if unknown:
            raise FlappingError(f"controls {sorted(unknown)!r}: expected {', '.join(CONTROLS)}")
        values = tuple(float(control.get(n, 0.0)) for n in CONTROLS)
    else:
        values = tuple(float(c) for c in control)
        if len(values) != len(CONTROLS):
            raise FlappingError(f"{len(values)} controls: expected {len(CONTROLS)} "
                                f"({', '.join(CONTROLS)})")
    for name, v in zip(CONTROLS, values):
        if not math.isfinite(v):
            raise FlappingError(f"control {name} = {v!r} is not finite")
    return values


@dataclass(frozen=True)
class _Beat:
    """One wing beat's kinematic constants, per wing (left, right), from the controls held in
    the previous beat and in this one."""

    down: tuple[np.ndarray, np.ndarray]  # stroke: phi = a + b (1 - cos 2 pi t)/2, downstroke
    up: tuple[np.ndarray, np.ndarray]  # the same, upstroke
    # the pitch in each of its five phases (:data:`_PITCH_CENTRES`): from p0 by dp, (5, wing)
    # each: the rotation from the old upstroke's angle to the old downstroke's, held, to the
    # new upstroke's, held, to the new downstroke's
    pitch: tuple[np.ndarray, np.ndarray]


#: one instant of the equations (:meth:`FlappingModel._stages`): the aerodynamic loads as a
#: function of the body's six velocities and rates, the wing inertia's loads without the
#: body's rates (6,) and their linear part in the state (6, 13), the angles (6, 2)
_Stage = tuple[Callable[[np.ndarray], np.ndarray], np.ndarray, np.ndarray, np.ndarray]


class FlappingModel:
    """The flapping drone fly: one wing beat at a time, or any part of one.

    Parameters
    ----------
    qs : QuasiSteadyModel, optional
        The aerodynamics (default: ``QuasiSteadyModel()``); its trim is the hover kinematics.
    steps_per_beat : int
        Runge-Kutta steps per wing beat, a positive multiple of 20.
    wing_inertia : bool
        Add the wings' inertial reaction (default True).
    averaged : bool
        Replace the instantaneous forces by their cycle average
        (:meth:`QuasiSteadyModel.forces_vector`, the kinematics of the beat's controls) and
        leave out the wing inertia (zero on average): the averaged model, for comparison.
    data : mapping
        Flight data (default :data:`dronefly.models.lateral_interface.FLIGHT_DATA`).
    frequency_factor : float
        The averaging experiment (default 1, the insect): the wing beat is ``frequency_factor``
        times faster while the forces at each phase stay what they are, so their cycle average,
        the averaged model, is unchanged; the "beat" of every method is then one of these
        shorter periods (:attr:`period` wing beats of the insect). As the factor grows, the
        Floquet exponents per wing beat tend to the averaged model's eigenvalues.
    """

    def __init__(self, qs: QuasiSteadyModel | None = None, steps_per_beat: int = STEPS_PER_BEAT,
                 wing_inertia: bool = True, averaged: bool = False,
                 data: Mapping[str, float] = FLIGHT_DATA,
                 frequency_factor: float = 1.0) -> None:
        if not (math.isfinite(frequency_factor) and frequency_factor >= 1.0):
            raise FlappingError(f"frequency_factor = {frequency_factor!r} must be >= 1")
        #: the period of the forcing, in wing beats of the insect (1 / frequency_factor)
        self.period = 1.0 / frequency_factor
        if not (isinstance(steps_per_beat, int) and steps_per_beat > 0
                and steps_per_beat % 20 == 0):
            raise FlappingError(f"steps_per_beat = {steps_per_beat!r} must be a positive "
                                "multiple of 20")
        self.qs = qs or QuasiSteadyModel()
        self.trim = self.qs.trim()
        self.steps_per_beat = steps_per_beat
        self.wing_inertia = bool(wing_inertia) and not averaged
        self.averaged = bool(averaged)
        s = reference_scales(data)
        self.U, self.n = s["U"], s["n"]
        self.m = s["m_plus"]
        self.g = s["g_plus"]
        Ix, Iy, Iz, Ixz = s["Ix_plus"], s["Iy_plus"], s["Iz_plus"], s["Ixz_plus"]
        self.J = np.array([[Ix, 0.0, -Ixz], [0.0, Iy, 0.0], [-Ixz, 0.0, Iz]])
        self.J_inv = np.linalg.inv(self.J)
        geo = self.qs.geometry
        q_force = 0.5 * data["rho"] * s["U"] * 2.0 * data["S_wing"] * s["t_w"]
        #: one wing's mass, non-dimensional as m+
        self.m_wing = data["m_wing"] / q_force
        self.r_wing = WING_CM_OVER_R * geo.R
        self._hinge = np.array([[geo.hinge[0], -geo.hinge[1], geo.hinge[2]],
                                [geo.hinge[0], geo.hinge[1], geo.hinge[2]]])
        D = geo.rotation_fraction
        if not 0.0 < D < 0.5:
            raise FlappingError(f"rotation fraction {D!r} must be in (0, 0.5)")
        self._D = D
        #: the ends of the pitch's phases but the last (:data:`_PITCH_CENTRES`)
        self._pitch_ends = np.array([0.5 * D, 0.5 - 0.5 * D, 0.5 + 0.5 * D, 1.0 - 0.5 * D])
        self._beats: dict[tuple, _Beat] = {}
        self._tables: dict[tuple, list] = {}

    # -- kinematics -----------------------------------------------------------------------
    def _beat(self, c_prev: tuple[float, ...], c_now: tuple[float, ...]) -> _Beat:
        key = (c_prev, c_now)
        beat = self._beats.get(key)
        if beat is None:
            names = dict(zip(CONTROLS, c_prev)), dict(zip(CONTROLS, c_now))
            old, new = (self.qs.wing_kinematics(c, self.trim) for c in names)
            rear_old = old["phibar"] - 0.5 * old["Phi"]
            rear, front = new["phibar"] - 0.5 * new["Phi"], new["phibar"] + 0.5 * new["Phi"]
            old_up, old_down = math.pi - old["alpha_u"], old["alpha_d"]
            up, down = math.pi - new["alpha_u"], new["alpha_d"]
            zero = 0.0 * up
            beat = _Beat((rear_old, front - rear_old), (rear, front - rear),
                         (np.array([old_up, old_down, old_down, up, up]),
                          np.array([old_down - old_up, zero, up - old_down, zero, down - up])))
            if len(self._beats) > 64:
                self._beats.clear()
            self._beats[key] = beat
        return beat

    def angles(self, tau: float, c_prev: Sequence[float], c_now: Sequence[float]) -> np.ndarray:
        """(phi, dphi, ddphi, psi, dpsi, ddpsi) of both wings (columns left, right) at the
        phase ``tau`` in [0, 1] of a wing beat whose controls are ``c_now`` after ``c_prev``
        (derivatives in t+); at a grid point (:meth:`loads`) those of its stage."""
        cp, cn = wing_beat_controls(c_prev), wing_beat_controls(c_now)
        beat = self._beat(cp, cn)
        stage = self._grid_stage(tau, beat, cp, cn)
        return self._angles(tau, beat) if stage is None else stage[3].copy()

    def _angles(self, tau: float, beat: _Beat, mid: float | None = None) -> np.ndarray:
        """:meth:`angles` at one phase (on the half-stroke of ``mid``, as :meth:`_angles_of`)."""
        return self._angles_of([tau], [tau if mid is None else mid], beat)[0]

    def _angles_of(self, taus: Sequence[float], mids: Sequence[float],
                   beat: _Beat) -> np.ndarray:
        """:meth:`angles` at the phases ``taus``, (T, 6, 2), each on the half-stroke of the
        Runge-Kutta step whose midpoint is the one of ``mids`` (the stroke's acceleration jumps
        at the front reversal when the controls change: a step needs the branch of its own
        interval at its ends; the phase's own away from the reversals)."""
        tau = np.asarray(taus, dtype=float)[:, None]  # (T, 1), the wings along the columns
        down = (np.asarray(mids, dtype=float) <= 0.5)[:, None]
        a = np.where(down, beat.down[0], beat.up[0])
        b = np.where(down, beat.down[1], beat.up[1])
        w = 2.0 * np.pi * tau
        cw, sw = np.cos(w), np.sin(w)
        D = self._D
        # the pitch: rotations of length D centred on the reversals tau = 0, 0.5, 1 (from the
        # angle p0 by dp), held between them
        phase = np.searchsorted(self._pitch_ends, tau[:, 0], side="right")
        p0, dp = beat.pitch[0][phase], beat.pitch[1][phase]
        s = ((tau - _PITCH_CENTRES[phase][:, None]) + 0.5 * D) / D
        ws = 2.0 * np.pi * s
        psi = p0 + dp * (s - np.sin(ws) / (2.0 * np.pi))
        dpsi = dp * (1.0 - np.cos(ws)) / D
        ddpsi = dp * (2.0 * np.pi * np.sin(ws) / (D * D))
        return np.stack([a + b * (0.5 - 0.5 * cw), b * (np.pi * sw),
                         b * (2.0 * np.pi ** 2 * cw), psi, dpsi, ddpsi], axis=1)

    # -- equations ------------------------------------------------------------------------
    def loads(self, tau: float, x: Sequence[float], c_prev: Sequence[float],
              c_now: Sequence[float]) -> tuple[np.ndarray, np.ndarray]:
        """(aerodynamic (X+, Y+, Z+, L+, M+, N+), wing inertial (the same six)) at phase
        ``tau`` of a beat, body state ``x`` (at least its six velocities and rates).

        A phase within 1e-9 of a step of a grid point is that grid point (as the flight's
        state there, :meth:`Flight.state_at`): its loads are those of the integration's
        stage there."""
        cp, cn = wing_beat_controls(c_prev), wing_beat_controls(c_now)
        beat, v = self._beat(cp, cn), np.asarray(x[:6], dtype=float)
        stage = self._grid_stage(tau, beat, cp, cn)
        if stage is None:
            return self._loads(tau, v, beat, cn)
        aero, c0, W, _ = stage
        return aero(v), c0 + W[:, :6] @ v

    def _loads(self, tau: float, v: np.ndarray, beat: _Beat, c_now: tuple[float, ...],
               mid: float | None = None) -> tuple[np.ndarray, np.ndarray]:
        aero, c0, W, _ = self._stages([(tau, mid)], beat, c_now)[0]
        return aero(v), c0 + W[:, :6] @ v

    def _grid_stage(self, tau: float, beat: _Beat, cp: tuple[float, ...],
                    cn: tuple[float, ...]) -> _Stage | None:
        """The kept stage (:meth:`_grid`) at a phase within 1e-9 of a step of a grid point,
        else None: the start of the step that begins there if the phase is after the point,
        else the end of the one that ends there, so that at the front reversal the half-stroke
        is the phase's own (:meth:`angles`: the downstroke up to 0.5 included)."""
        N = self.steps_per_beat
        j = round(tau * N)
        if not (0 <= j <= N and abs(tau * N - j) <= 1e-9):
            return None
        table = self._grid((cp, cn), beat, cn)
        return table[j][0] if j == 0 or (j < N and tau > j / N) else table[j - 1][2]

    def _stages(self, times: Sequence[tuple[float, float | None]], beat: _Beat,
                c_now: tuple[float, ...]) -> list[_Stage]:
        """What the equations need of the wing motion at each (phase, step midpoint) of
        ``times`` (the midpoint chooses the half-stroke, :meth:`_angles`), all computed
        together: (the aerodynamic loads as a function of the body's six velocities and
        rates, the wing inertia's loads without the body's rates, their linear part in the
        13-value state, the angles (:meth:`angles`)), the loads non-dimensional as
        :meth:`loads`'."""
        ang = self._angles_of([t for t, _ in times],
                              [t if mid is None else mid for t, mid in times], beat)
        if self.averaged:  # the cycle average of the beat's controls, no wing inertia
            aero = self.qs.state_function(c_now, self.trim)
            return [(aero, np.zeros(6), np.zeros((6, STATE_SIZE)), a) for a in ang]
        c0, W = self._inertia(ang)
        return [(inst, c0[i], W[i], ang[i]) for i, inst in enumerate(self.qs.instants(ang))]

    def _inertia(self, ang: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The wings' inertial reaction at the instants of ``ang`` (T, 6, 2) (:meth:`angles`):
        its loads without the body's rates (T, 6) and their linear part in the state
        (T, 6, 13) (the Coriolis term), non-dimensional as :meth:`loads`'; zero without
        ``wing_inertia``."""
        T = len(ang)
        c0, W = np.zeros((T, 6)), np.zeros((T, 6, STATE_SIZE))
        if not self.wing_inertia:
            return c0, W
        phi, dphi, ddphi = ang[:, 0], ang[:, 1], ang[:, 2]  # (T, wing)
        s = np.array([-1.0, 1.0])
        sp, cp = np.sin(phi), np.cos(phi)
        # per wing: e_r = (sin phi, s cos phi, 0), e_t = (cos phi, -s sin phi, 0)
        erx, ery, etx, ety = sp, s * cp, cp, -s * sp
        kw = -self.m_wing * self.qs.geometry.k  # the reaction, over 0.5 rho U^2 S_t
        rw = self.r_wing
        hx, hy, hz = self._hinge[1]
        vx, vy = rw * dphi * etx, rw * dphi * ety  # velocity relative to the body
        at, ar = rw * ddphi, rw * dphi * dphi
        zero = np.zeros_like(phi)
        pos = np.stack([hx + rw * erx, s * hy + rw * ery, hz + zero], axis=-1)
        # -m_w (a_rel + 2 omega x v_rel) (v_rel has no z component): the part without the
        # rates, then the factors of p, q, r
        forces = np.stack([np.stack([kw * (at * etx - ar * erx), kw * (at * ety - ar * ery),
                                     zero], axis=-1),
                           np.stack([zero, zero, 2.0 * kw * vy], axis=-1),
                           np.stack([zero, zero, -2.0 * kw * vx], axis=-1),
                           np.stack([-2.0 * kw * vy, 2.0 * kw * vx, zero], axis=-1)])
        six = np.concatenate([forces, np.cross(pos, forces)], axis=-1).sum(axis=2)  # (4, T, 6)
        c0[:] = six[0]
        W[:, :, 3:6] = six[1:].transpose(1, 2, 0)
        return c0, W

    def _grid(self, key: tuple, beat: _Beat, c_now: tuple[float, ...]) -> list:
        """The :meth:`_stages` of every Runge-Kutta step of the beat's grid, per step (start,
        middle, end), made once per pair of controls (the same every beat they are held)."""
        table = self._tables.pop(key, None)
        if table is not None:
            self._tables[key] = table  # the most recently used last
        else:
            N = self.steps_per_beat
            times: list[tuple[float, float]] = []
            index: dict[tuple[float, bool], int] = {}  # an instant shared by two steps once

            def instant(tau: float, mid: float) -> int:
                which = (tau, mid <= 0.5)  # the phase and the half-stroke
                if which not in index:
                    index[which] = len(times)
                    times.append((tau, mid))
                return index[which]

            steps = []
            for j in range(N):
                t = j / N
                h = (j + 1) / N - t
                mid = t + 0.5 * h
                steps.append([instant(tau, mid) for tau in (t, mid, t + h)])
            stages = self._stages(times, beat, c_now)
            table = [[stages[i] for i in step] for step in steps]
            if len(self._tables) >= _TABLES:
                self._tables.pop(next(iter(self._tables)))
            self._tables[key] = table
        return table

    def _rhs(self, tau: float, y: np.ndarray, beat: _Beat, c_now: tuple[float, ...],
             mid: float | None = None) -> np.ndarray:
        aero, wing = self._loads(tau, y[:6], beat, c_now, mid)
        return self._body(y, aero + wing)

    def _at(self, stage: _Stage, y: np.ndarray) -> np.ndarray:
        """dx/dtau at one of :meth:`_stages`'s instants."""
        aero, c0, W, _ = stage
        return self._body(y, aero(y[:6]) + (c0 + W @ y))

    def _body(self, y: np.ndarray, F: np.ndarray) -> np.ndarray:
        """dx/dtau of the rigid body (the module's equations) under the loads ``F`` (the six,
        non-dimensional as :meth:`loads`'), in Python floats (13 values: numpy's per-call
        cost would be most of it)."""
        u, v, w, p, q, r, e0, e1, e2, e3 = y.tolist()[:10]
        X, Y, Z, L, M, N = F.tolist()
        R20, R21, R22 = 2.0 * (e1 * e3 - e0 * e2), 2.0 * (e2 * e3 + e0 * e1), \
            1.0 - 2.0 * (e1 * e1 + e2 * e2)
        m, g = self.m, self.g
        (J00, J01, J02), (J10, J11, J12), (J20, J21, J22) = self.J.tolist()
        Jx, Jy, Jz = J00 * p + J01 * q + J02 * r, J10 * p + J11 * q + J12 * r, \
            J20 * p + J21 * q + J22 * r
        gx, gy, gz = L - (q * Jz - r * Jy), M - (r * Jx - p * Jz), N - (p * Jy - q * Jx)
        (I00, I01, I02), (I10, I11, I12), (I20, I21, I22) = self.J_inv.tolist()
        return self.period * np.array([
            X / m + g * R20 - (q * w - r * v), Y / m + g * R21 - (r * u - p * w),
            Z / m + g * R22 - (p * v - q * u), I00 * gx + I01 * gy + I02 * gz,
            I10 * gx + I11 * gy + I12 * gz, I20 * gx + I21 * gy + I22 * gz,
            0.5 * (-e1 * p - e2 * q - e3 * r), 0.5 * (e0 * p + e2 * r - e3 * q),
            0.5 * (e0 * q - e1 * r + e3 * p), 0.5 * (e0 * r + e1 * q - e2 * p),
            (1.0 - 2.0 * (e2 * e2 + e3 * e3)) * u + 2.0 * (e1 * e2 - e0 * e3) * v
            + 2.0 * (e1 * e3 + e0 * e2) * w,
            2.0 * (e1 * e2 + e0 * e3) * u + (1.0 - 2.0 * (e1 * e1 + e3 * e3)) * v
            + 2.0 * (e2 * e3 - e0 * e1) * w,
            R20 * u + R21 * v + R22 * w])

    def derivative(self, tau: float, x: Sequence[float], c_prev: Sequence[float] | None = None,
                   c_now: Sequence[float] | None = None) -> np.ndarray:
        """dx/dtau (tau the phase of the beat; dx/dt+ times :attr:`period`) of the 13-value
        state at phase ``tau`` of a beat (controls as :meth:`angles`; default: the trimmed
        hover)."""
        cp, cn = wing_beat_controls(c_prev), wing_beat_controls(c_now)
        return self._rhs(tau, np.asarray(x, dtype=float), self._beat(cp, cn), cn)

    def advance(self, x: Sequence[float], tau0: float, tau1: float,
                c_prev: Sequence[float] | None = None,
                c_now: Sequence[float] | None = None) -> np.ndarray:
        """The state at phase ``tau1`` of a beat from the state at ``tau0`` (0 <= tau0 <= tau1
        <= 1): Runge-Kutta steps on the beat's grid, a partial step at either end off it.

        Raises
        ------
        FlappingError
            The state is not finite after the step.
        """
        if not (0.0 <= tau0 <= tau1 <= 1.0):
            raise FlappingError(f"phases {tau0!r} -> {tau1!r} must satisfy 0 <= tau0 <= tau1 <= 1")
        cp, cn = wing_beat_controls(c_prev), wing_beat_controls(c_now)
        y = np.array(x, dtype=float)
        if y.shape != (STATE_SIZE,):
            raise FlappingError(f"state of {y.size} values: expected {STATE_SIZE}")
        return self._advance(y, tau0, tau1, cp, cn)

    def _advance(self, y: np.ndarray, tau0: float, tau1: float, cp: tuple[float, ...],
                 cn: tuple[float, ...]) -> np.ndarray:
        """:meth:`advance` of a 13-value state array (not changed) with checked phases and
        controls (:func:`wing_beat_controls`'s tuples)."""
        beat = self._beat(cp, cn)
        N = self.steps_per_beat
        x = y
        # grid points strictly inside (tau0, tau1), with a tolerance for round-off
        j0 = math.floor(tau0 * N + 1e-9) + 1
        j1 = math.ceil(tau1 * N - 1e-9) - 1
        cuts = [tau0, *(j / N for j in range(j0, j1 + 1)), tau1]
        for a, b in zip(cuts[:-1], cuts[1:]):
            if b - a > 1e-12:
                j = round(a * N)
                if a == j / N and b == (j + 1) / N:  # a step of the grid: its stages are kept
                    stages = self._grid((cp, cn), beat, cn)[j]
                else:  # a partial step
                    h = b - a
                    mid = a + 0.5 * h
                    stages = self._stages([(a, mid), (mid, mid), (a + h, mid)], beat, cn)
                y = self._rk4(y, b - a, stages)
        if not np.all(np.isfinite(y)):
            raise FlappingError(f"the state is not finite after phases {tau0!r} -> {tau1!r} "
                                f"(from u, v, w, p, q, r = {x[:6].tolist()!r})")
        if y is x:
            y = y.copy()
        y[6:10] /= math.sqrt(float(y[6:10] @ y[6:10]))
        return y

    def _rk4(self, y: np.ndarray, h: float, stages: Sequence[tuple]) -> np.ndarray:
        """One step of the classical Runge-Kutta method of length ``h``, ``stages`` the
        :meth:`_stages` at its start, middle and end."""
        start, middle, end = stages
        at = self._at
        k1 = at(start, y)
        k2 = at(middle, y + (0.5 * h) * k1)
        k3 = at(middle, y + (0.5 * h) * k2)
        k4 = at(end, y + h * k3)
        return y + (h / 6.0) * (k1 + 2.0 * (k2 + k3) + k4)

    def beat(self, x: Sequence[float], c_prev: Sequence[float] | None = None,
             c_now: Sequence[float] | None = None) -> np.ndarray:
        """The wing-beat map: the state at the start of the next beat."""
        return self.advance(x, 0.0, 1.0, c_prev, c_now)

    # -- reduced coordinates (the periodic orbit and the Floquet analysis) ----------------
    @staticmethod
    def state_from_z(z: Sequence[float], psi: float = 0.0) -> np.ndarray:
        """The 13-value state of the reduced coordinates :data:`Z_NAMES` (heading ``psi``,
        position 0)."""
        return np.array([*z[:6], *quaternion_from_euler(z[6], z[7], psi), 0.0, 0.0, 0.0])

    @staticmethod
    def z_from_state(x: Sequence[float]) -> np.ndarray:
        """The reduced coordinates (:data:`Z_NAMES`) of a 13-value state."""
        phi, theta, _ = euler_from_quaternion(x[6:10])
        return np.array([*x[:6], phi, theta])

    def z_map(self, z: Sequence[float], control: Sequence[float] | None = None) -> np.ndarray:
        """One wing beat with the controls held, in reduced coordinates."""
        return self.z_from_state(self.beat(self.state_from_z(z), control, control))

    def periodic_orbit(self, control: Sequence[float] | None = None, tol: float = 1e-12,
                       max_iter: int = 30, step: float = 1e-6, samples: int | None = None,
                       jacobian: np.ndarray | None = None) -> "PeriodicOrbit":
        """Hover as a periodic orbit: Newton's method on the state at the start of a beat
        (shooting with the wing-beat map), from the trimmed hover's state 0, to a residual
        below ``tol``.

        The Jacobian is kept for every step (the chord method: the wing-beat map is nearly
        linear over the orbit's offset): ``jacobian``, an approximation of the monodromy
        matrix (the averaged model's serves), or by default the central-difference one at the
        start.

        Raises
        ------
        FlappingError
            The residual is not below ``tol`` after ``max_iter`` steps.
        """
        z = np.zeros(len(Z_NAMES))
        M = self.monodromy(z, control, step) if jacobian is None else np.asarray(jacobian)
        z, history = shooting(lambda x: self.z_map(x, control), z, M, tol, max_iter)
        return PeriodicOrbit(self, z, control, history, samples or 200)

    def monodromy(self, z: Sequence[float], control: Sequence[float] | None = None,
                  step: float = 1e-6) -> np.ndarray:
        """d(z after one beat)/d(z at its start), central differences of the wing-beat map."""
        z = np.asarray(z, dtype=float)
        cols = []
        for j in range(len(z)):
            dz = np.zeros(len(z))
            dz[j] = step
            cols.append((self.z_map(z + dz, control) - self.z_map(z - dz, control)) / (2 * step))
        return np.column_stack(cols)


def orbit_start(model: FlappingModel | None = None) -> np.ndarray:
    """The start of the flapping insect's periodic orbit at the averaged trim's kinematics
    (:meth:`FlappingModel.periodic_orbit`, the averaged twin's monodromy as the Newton
    Jacobian): the reduced state (u+, v+, w+, p+, q+, r+, phi, theta) at a beat's start.

    ``model`` defaults to ``FlappingModel()``, the model of the ``DroneFlyFlapping`` FMU.
    """
    model = model or FlappingModel()
    twin = FlappingModel(model.qs, model.steps_per_beat, averaged=True)
    return model.periodic_orbit(jacobian=twin.monodromy(np.zeros(8))).z0


class Flight:
    """The model in time: the state on the Runge-Kutta grid, the controls latched at the beats'
    starts, any instant reached by a partial step that the flight does not keep.

    Time is t+ in wing beats from the start; beat k is [k, k + 1). ``set_controls`` may be
    called at any time: the values are taken when the flight enters the next beat (see the
    module's text). The whole state is :meth:`snapshot` (plain Python values; the FMU's
    state).
    """

    def __init__(self, model: FlappingModel, x0: Sequence[float],
                 controls: Sequence[float] | Mapping[str, float] | None = None) -> None:
        self.model = model
        y = np.array(x0, dtype=float)
        if y.shape != (STATE_SIZE,) or not np.all(np.isfinite(y)):
            raise FlappingError(f"initial state {list(np.ravel(x0))!r}: expected {STATE_SIZE} "
                                "finite values")
        c = wing_beat_controls(controls)
        self.grid = 0  # grid index of y: t+ = grid / N
        self.y = y
        self.pending = c
        self.c_prev = c  # before the first beat the insect flapped with the initial controls
        self.c_now = c
        self.latched = -1  # the beat whose controls c_now are

    @property
    def N(self) -> int:
        return self.model.steps_per_beat

    def set_controls(self, controls: Sequence[float] | Mapping[str, float] | None) -> None:
        """The controls for the next beat that starts (taken at its start)."""
        self.pending = wing_beat_controls(controls)

    def _latch(self, beat: int) -> None:
        if self.latched < beat:
            if self.latched >= 0:
                self.c_prev = self.c_now
            self.c_now = self.pending
            self.latched = beat

    def _tolerance(self) -> float:
        return 1e-9 / self.N

    def advance_to(self, t: float) -> np.ndarray:
        """Integrate the kept state to the last grid point at or before ``t`` (wing beats) and
        return the state at ``t`` (a partial step from there if ``t`` is off the grid)."""
        N = self.N
        if not t >= self.grid / N - self._tolerance():
            raise FlappingError(f"time {t!r} wing beats is before the flight's state "
                                f"({self.grid / N!r})")
        m = self.model
        while (self.grid + 1) / N <= t + self._tolerance():
            k, j = divmod(self.grid, N)
            self._latch(k)
            self.y = m._advance(self.y, j / N, (j + 1) / N, self.c_prev, self.c_now)
            self.grid += 1
        return self.state_at(t)

    def state_at(self, t: float) -> np.ndarray:
        """The state at ``t`` between the kept grid point and the next (not kept)."""
        N = self.N
        dt = t - self.grid / N
        if abs(dt) <= self._tolerance():
            return self.y.copy()
        if not 0.0 < dt < 1.0 / N + self._tolerance():
            raise FlappingError(f"time {t!r} is not within one grid step after the state")
        k, j = divmod(self.grid, N)
        self._latch(k)
        return self.model.advance(self.y, j / N, min(1.0, j / N + dt), self.c_prev, self.c_now)

    def phase(self, t: float) -> tuple[float, tuple[float, ...], tuple[float, ...]]:
        """(phase in the beat, its previous and current controls) at ``t`` (at or after the
        kept state, within a step): at the start of a beat not yet entered, the end of the
        last one (its angles are the same: the controls act from the beat's first instant
        on)."""
        k = int(math.floor(t + self._tolerance()))
        if k > self.latched:
            return (0.0 if self.latched < 0 else 1.0), self.c_prev, self.c_now
        return max(0.0, min(1.0, t - k)), self.c_prev, self.c_now

    def snapshot(self) -> dict:
        """Everything the flight's future depends on (plain values)."""
        return {"grid": self.grid, "y": [float(v) for v in self.y], "pending": self.pending,
                "c_prev": self.c_prev, "c_now": self.c_now, "latched": self.latched}

    def restore(self, snap: Mapping) -> None:
        """Return to a :meth:`snapshot`."""
        self.grid = int(snap["grid"])
        self.y = np.array(snap["y"], dtype=float)
        self.pending = wing_beat_controls(snap["pending"])
        self.c_prev = wing_beat_controls(snap["c_prev"])
        self.c_now = wing_beat_controls(snap["c_now"])
        self.latched = int(snap["latched"])


@dataclass
class PeriodicOrbit:
    """The periodic orbit: its start (reduced coordinates), the Newton residuals, and the
    body's motion within the beat."""

    model: FlappingModel
    z0: np.ndarray
    control: Sequence[float] | None
    residuals: list
    samples: int

    def trajectory(self) -> np.ndarray:
        """The 13-value state at ``samples`` + 1 equally spaced phases of one beat."""
        flight = Flight(self.model, self.model.state_from_z(self.z0), self.control)
        return np.array([flight.advance_to(j / self.samples) for j in range(self.samples + 1)])

    def oscillation(self) -> dict[str, float]:
        """Peak-to-peak excursions within the beat: the position (micrometres, the mean drift
        over the beat removed) and the attitude (deg), and the mean drift velocity [mm/s]."""
        X = self.trajectory()
        m = self.model
        L_um = m.U / m.n * 1e6  # U t_w in micrometres
        tau = np.linspace(0.0, 1.0, len(X))
        out: dict[str, float] = {}
        for i, name in zip((10, 11, 12), ("x", "y", "z")):
            drift = X[-1, i] - X[0, i]
            pos = X[:, i] - X[0, i] - drift * tau
            out[f"{name}_pp_um"] = float((pos.max() - pos.min()) * L_um)
            out[f"{name}_drift_mm_per_s"] = float(drift / m.period * m.U * 1e3)
        eul = np.array([euler_from_quaternion(x[6:10]) for x in X])
        for i, name in enumerate(("phi", "theta", "psi")):
            out[f"{name}_pp_deg"] = float(np.degrees(eul[:, i].max() - eul[:, i].min()))
        out["theta_mean_deg"] = float(np.degrees(eul[:-1, 1].mean()))
        return out


@dataclass
class Floquet:
    """Floquet multipliers of the periodic orbit and the exponents log(mu) per wing beat,
    beside the averaged model's eigenvalues in the same coordinates."""

    monodromy: np.ndarray
    multipliers: np.ndarray
    exponents: np.ndarray

    @classmethod
    def of(cls, model: FlappingModel, orbit: PeriodicOrbit, step: float = 1e-6) -> "Floquet":
        M = model.monodromy(orbit.z0, orbit.control, step)
        mu = np.linalg.eigvals(M)
        lam = np.log(mu.astype(complex)) / model.period  # per wing beat of the insect
        order = sorted(range(len(lam)), key=lambda i: (-lam[i].real, -lam[i].imag))
        return cls(M, mu[order], lam[order])
