"""The equations of the wing-beat-resolved model (:class:`FlappingModel`): the wing kinematics
of each beat from its controls, the stages of the Runge-Kutta grid, the rigid body under the
wings' instantaneous loads and their inertia (the package's text,
:mod:`dronefly.models.flapping`, states them)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable, Mapping, Sequence

import numpy as np

from ...core.errors import DroneflyError
from ..lateral_interface import FLIGHT_DATA, reference_scales
from ..quasisteady import CONTROLS, QuasiSteadyModel
from ..rigid_body import euler_from_quaternion, quaternion_from_euler

__all__ = ["STATE_SIZE", "STEPS_PER_BEAT", "WING_CM_OVER_R", "FlappingError", "FlappingModel",
           "Z_NAMES", "wing_beat_controls"]

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
        state there, :meth:`dronefly.models.flapping.Flight.state_at`): its loads are those of
        the integration's stage there."""
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
        """dx/dtau of the rigid body (the equations of :mod:`dronefly.models.flapping`) under
        the loads ``F`` (the six, non-dimensional as :meth:`loads`'), in Python floats (13
        values: numpy's per-call cost would be most of it)."""
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
