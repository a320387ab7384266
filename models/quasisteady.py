"""A quasi-steady blade-element model of the two flapping wings of the model drone fly.

Everything is non-dimensional as in Zhang & Sun, Sect. 2.1: lengths in the mean chord c,
velocities in U = 2 Phi n r2, time in the wing-beat period t_w (t+ in [0, 1) is one cycle),
forces over 0.5 rho U^2 S_t and moments over 0.5 rho U^2 S_t c, S_t the area of both wings.

Axes (Sect. 2.1, Fig. 1): body axes at the centre of mass, x forward, y to the right, z down;
at hover x and y are horizontal. The stroke plane is horizontal (Sect. 2.4), so it is the
x-y plane. Moments L, M, N are about x, y, z (right-handed): more lift on the left wing rolls
right (L > 0, as L_Phi_a > 0 in Table 1), more drag backwards on the left wing yaws left
(N < 0, as N_alpha_2a < 0). Gravity enters through the weight W+ = m+ g+ only (trim).

Kinematics (the Sun group's model insects, Sect. 2.4 data), per wing, t+ in [0, 1):

- stroke (positional) angle, forward positive: phi = phibar - (Phi/2) cos(2 pi t+): the
  downstroke (t+ in [0, 0.5], the wing moving forward) then the upstroke;
- the geometrical angle of attack is alpha_d in mid-downstroke and alpha_u in mid-upstroke;
  "Delta t_r is 30 % of the wing-beat cycle" is read as a rotation of duration 0.3 t_w
  centred on each stroke reversal (t+ = 0 and 0.5), so the mid-stroke phases are
  [0.15, 0.35] and [0.65, 0.85]; the pitch angle psi of the chord from the forward stroke
  direction goes alpha_d -> pi - alpha_u -> alpha_d, in each rotation by
  psi = psi0 + dpsi (tau - sin(2 pi tau)/(2 pi)), tau in [0, 1] (angular velocity
  0.5 w0 (1 - cos 2 pi tau), Sun & Tang 2002), about the pitch axis at x0 = c/4 from the
  leading edge.

Planform (Ellington 1984): chord c(r) proportional to a beta distribution
r^(p-1) (1-r)^(q-1) on r = r/R in [0, 1], with r2 = 0.55 R (Sect. 2.4) and r1 from
Ellington's relation r2 = 0.929 r1^0.732 (so r1 = 0.489 R).

Wing roots: 0.33 l_b apart (y = +/-0.165 l_b), the wing-base axis l1 = 0.13 l_b from the
centre of mass; the free body angle chi0 = 52 deg is the body angle at which the centre of
mass hangs straight below the wing-base axis (Ellington 1984), so at the body angle
chi = 42 deg the roots are l1 cos(10 deg) above and l1 sin(10 deg) ahead of it.

Blade elements (Gauss-Jacobi nodes of the planform): the element velocity relative to the
air is the flapping velocity plus the body's translation and rotation (u, v, w) +
Omega x r, the spanwise component removed. Terms (each can be switched off, :class:`Terms`):

- translational: 0.5 rho |V|^2 c dr (CL(alpha) e_L + CD(alpha) e_D), e_D against V,
  e_L normal to V away from the side the flow meets, alpha in [0, pi/2] the angle
  between V and the chord line, CL/CD from a :class:`CoefficientSet`;
- rotational (Sane & Dickinson 2002): the circulation Gamma_rot = C_rot omega_p c^2,
  C_rot = pi (0.75 - x0/c), omega_p the pitch rate (rotation plus the body's rate about the
  wing's span axis), as a Kutta-Joukowski force rho Gamma_rot dr (a_p x V) of magnitude
  rho C_rot omega_p |V| c^2 dr, perpendicular to V, towards the suction side when the rotation
  raises the angle of attack. Sane & Dickinson put this force normal to the wing, which needs
  the sign of V.e_c and so jumps where V crosses the wing normal mid-rotation; the
  Kutta-Joukowski direction is smooth in the state (the derivatives exist) and differs from
  the normal by the angle of attack;
- added mass (per element, the mass m_a = rho (pi/4) c^2 dr of the mid-chord's normal
  velocity V_n), in one of two forms (:class:`Terms`): ``"impulse"`` (the default) is the rate
  of change of the fluid impulse, -d/dt(m_a V_n n) - Omega x (m_a V_n n) in body axes. In an
  ideal fluid the added-mass force is the rate of change of the fluid impulse; for a periodic
  wing motion (no body rates) the impulse is periodic and the force averages to zero over the
  cycle, exactly. ``"sane2001"`` (Sane & Dickinson 2001) is -m_a dV_n/dt n: it drops
  m_a V_n dn/dt, the turning of the wing normal, and so averages to m_a mean(V_n dn/dt), a
  net force of no physical origin (an upward force carrying 31 % of the weight at its trim,
  :func:`dronefly.harness.aero.beside_paper.trim_table`); it is kept for comparison with the literature
  that uses it.

All forces act on the pitch axis of their element; the body's own aerodynamic force is not
modelled (Sun's CFD finds it negligible in hover). Cycle averages are the mean over
``n_time`` equally spaced samples midway between the reversals' instants (the periodic
midpoint rule); in the added mass's cycle average the time derivative is moved, by parts over
the periodic cycle, onto the wing's own motion (analytic), so no derivative of the
state-dependent flow is sampled. The velocities are affine in the state and the span, so
what does not depend on the state is computed once per wing kinematics; the instantaneous
forces (:meth:`QuasiSteadyModel.forces_at`) are split the same way, into
:meth:`QuasiSteadyModel.instants`, the wing motion's part (at any number of instants at once),
and :meth:`QuasiSteadyModel.forces_of`, the state's (the wing-beat-resolved plant keeps the
first for the instants of its grid). The default grid,
8 elements and 100 samples, is the smallest whose derivatives agree with a grid of 32 x 800
to 0.1 % of each input's largest derivative (tests/test_aero.py); the error is the midpoint
rule's O(1/n_time^2) at the kinks of the quasi-steady forces where an element's velocity
passes through zero near a reversal.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Callable, Mapping, NamedTuple, Sequence

import numpy as np
from numpy.typing import NDArray

from ..core.errors import DroneflyError
from .lateral_interface import FLIGHT_DATA, reference_scales

__all__ = [
    "BODY_DATA",
    "COEFFICIENT_SETS",
    "CONTROLS",
    "FORCES",
    "Instant",
    "STATES",
    "CoefficientSet",
    "QuasiSteadyModel",
    "Terms",
    "Trim",
    "WingGeometry",
    "gauss_jacobi",
]

Array = NDArray[np.float64]

#: The body state, as the plant FMUs name it (non-dimensional x+: velocities over U, rates
#: times t_w).
STATES: tuple[str, ...] = ("delta_u", "delta_v", "delta_w", "delta_p", "delta_q", "delta_r")
#: The controls [rad]: lateral (Sect. 2.1) then longitudinal (Sect. 3.5, Eq. 30 order).
CONTROLS: tuple[str, ...] = ("delta_Phi_a", "delta_alpha_1a", "delta_alpha_2a", "delta_Phi",
                             "delta_alpha_1", "delta_phibar", "delta_alpha_2")
#: The cycle-averaged forces and moments, in this order.
FORCES: tuple[str, ...] = ("X", "Y", "Z", "L", "M", "N")

#: Sect. 2.4 data that :data:`dronefly.models.lateral_interface.FLIGHT_DATA` does not hold (lengths in m,
#: angles in deg, the rotation as a fraction of the cycle).
BODY_DATA: dict[str, float] = {
    "l_b": 14.11e-3,  # m, body length
    "root_spacing_over_lb": 0.33,  # distance between the two wing roots
    "l1_over_lb": 0.13,  # wing-base axis to centre of mass
    "chi0_deg": 52.0,  # free body angle
    "chi_deg": 42.0,  # body angle at hover
    "rotation_fraction": 0.30,  # Delta t_r / t_w
    "Re": 781.6,
}


@dataclass(frozen=True)
class CoefficientSet:
    """Translational lift and drag coefficients CL(alpha), CD(alpha) of a wing, with source.

    Parameters
    ----------
    name : str
        Key in :data:`COEFFICIENT_SETS`.
    lift, drag : callable
        alpha [rad] (array) -> coefficient.
    source : str
        Paper, equation, Reynolds number.
    """

    name: str
    lift: Callable[[Array], Array]
    drag: Callable[[Array], Array]
    source: str


_DEG = math.pi / 180.0

#: The coefficient sets, each from its source; none is tuned to the paper's CFD values.
COEFFICIENT_SETS: dict[str, CoefficientSet] = {
    "dickinson1999": CoefficientSet(
        "dickinson1999",
        lambda a: 0.225 + 1.58 * np.sin(2.13 * a - 7.20 * _DEG),
        lambda a: 1.92 - 1.55 * np.cos(2.04 * a - 9.82 * _DEG),
        "Dickinson, Lehmann & Sane 1999, Science 284:1954, fits to the steady-state forces of "
        "a revolving Drosophila model wing (Robofly), Re of order 100-200 (alpha in deg in the "
        "paper's form: 0.225 + 1.58 sin(2.13 alpha - 7.20), 1.92 - 1.55 cos(2.04 alpha - 9.82))"),
    "wang2004": CoefficientSet(
        "wang2004",
        lambda a: 1.2 * np.sin(2.0 * a),
        lambda a: 1.4 - np.cos(2.0 * a),
        "Wang, Birch & Dickinson 2004, J Exp Biol 207:449, Eqs. (14)-(15): two-dimensional "
        "quasi-steady fits, 1.2 sin 2 alpha and 1.4 - cos 2 alpha, Re 75-115"),
}


@dataclass(frozen=True)
class Terms:
    """Which force terms the model adds (each True by default), and the added-mass form.

    Parameters
    ----------
    translational, rotational, added_mass : bool
        Add the translational lift and drag, the rotational force, the added mass.
    added_mass_form : {"impulse", "sane2001"}
        ``"impulse"`` (default): the rate of change of the fluid impulse,
        -d/dt(m_a V_n n) (in body axes, minus Omega x m_a V_n n), the ideal-fluid added-mass
        force; for a periodic wing motion without body rates it averages to zero over the
        cycle (the mean of the derivative of a periodic function). ``"sane2001"`` (Sane &
        Dickinson 2001): -m_a dV_n/dt n, the normal acceleration alone; it drops
        m_a V_n dn/dt, the turning of the wing normal, so its cycle average is not zero (an
        artefact of the form: at its trim it carries 31 % of the weight).
    """

    translational: bool = True
    rotational: bool = True
    added_mass: bool = True
    added_mass_form: str = "impulse"


@dataclass(frozen=True)
class WingGeometry:
    """Non-dimensional geometry and kinematic constants of the model drone fly (Sect. 2.4).

    Lengths are in mean chords c; ``Phi_rad`` the stroke amplitude [rad]; ``k`` =
    c / (U t_w), the factor that turns a rate per wing beat times a length in chords into a
    velocity in U.
    """

    R: float
    r2_hat: float
    r1_hat: float
    p: float
    q: float
    S_wing: float
    Phi_rad: float
    k: float
    hinge: tuple[float, float, float]  # right wing's root (x, y, z), the left mirrored in y
    x0_hat: float = 0.25
    rotation_fraction: float = 0.30
    weight: float = 0.0  # W+ = m+ g+

    @classmethod
    def from_flight_data(cls, data: Mapping[str, float] = FLIGHT_DATA,
                         body: Mapping[str, float] = BODY_DATA) -> "WingGeometry":
        """The geometry from the Sect. 2.4 data (SI units in ``data``, :data:`BODY_DATA`)."""
        c = data["c"]
        r2_hat = data["r2_over_R"]
        r1_hat = (r2_hat / 0.929) ** (1.0 / 0.732)
        common = r1_hat * (1.0 - r1_hat) / (r2_hat**2 - r1_hat**2) - 1.0
        Phi = math.radians(data["Phi_deg"])
        scales = reference_scales(data)
        k = c / (scales["U"] * scales["t_w"])
        lb = body["l_b"]
        l1 = body["l1_over_lb"] * lb
        tilt = math.radians(body["chi0_deg"] - body["chi_deg"])
        hinge = (l1 * math.sin(tilt) / c, 0.5 * body["root_spacing_over_lb"] * lb / c,
                 -l1 * math.cos(tilt) / c)
        return cls(R=data["R"] / c, r2_hat=r2_hat, r1_hat=r1_hat, p=r1_hat * common,
                   q=(1.0 - r1_hat) * common, S_wing=data["S_wing"] / c**2, Phi_rad=Phi, k=k,
                   hinge=hinge, rotation_fraction=body["rotation_fraction"],
                   weight=scales["m_plus"] * scales["g_plus"])


@dataclass(frozen=True)
class Trim:
    """The trimmed hover: angles [rad], the residual of (X, Z + W, M) and the force balance."""

    alpha_d: float
    alpha_u: float
    phibar: float
    residual: float
    forces: dict[str, float] = field(default_factory=dict)

    def to_json(self) -> dict[str, float]:
        """Angles in deg, the residual over the weight, and the forces at trim (``X_plus``...)."""
        return {"alpha_d_deg": math.degrees(self.alpha_d), "alpha_u_deg": math.degrees(self.alpha_u),
                "phibar_deg": math.degrees(self.phibar), "residual_over_weight": self.residual,
                **{f"{k}_plus": v for k, v in self.forces.items()}}


def _cross(a: Array, b: Array) -> Array:
    """Cross product along the last axis of two arrays (..., 3), broadcast: component i is
    a_j b_k - a_k b_j, (i, j, k) the cyclic permutations of (0, 1, 2)."""
    return a[..., _NEXT] * b[..., _AFTER] - a[..., _AFTER] * b[..., _NEXT]


_NEXT, _AFTER = np.array([1, 2, 0]), np.array([2, 0, 1])


#: the lift's sign in (F_n, F_c) of :meth:`QuasiSteadyModel.forces_of`, per (wing, element)
_LIFT_SIDE = np.array([-1.0, 1.0])[:, None, None]
#: the wings' sides (left, right): the left wing mirrors the right in y
_SIDE = np.array([-1.0, 1.0])
_EYE3 = np.eye(3)


class Instant(NamedTuple):
    """The wing motion at one instant as :meth:`QuasiSteadyModel.forces_of` needs it
    (:meth:`QuasiSteadyModel.instants`): non-dimensional maps of x1 = (1, du+, dv+, dw+, dp+,
    dq+, dr+).

    Attributes
    ----------
    rows : array, shape (7, 8 n_span + 8)
        x1 @ rows is every element's V_n, V_c (over U) and rotational factor f, -f (over
        0.5 rho U S_t), ordered (quantity, wing, element), then the added mass's sums: per
        wing those of its impulse m_a v_mid and of r times it, then per wing those of its
        normal force and of r times that.
    loads : array, shape (6, 8 n_span + 20)
        loads @ (every element's F_n, F_c over 0.5 rho U^2 S_t, ordered as in ``rows``; the
        added mass's sums; their products with the body's rates) is (X+, Y+, Z+, L+, M+, N+).
    """

    rows: Array
    loads: Array


def gauss_jacobi(n: int, a: float, b: float) -> tuple[Array, Array]:
    """Nodes and weights of the n-point Gauss-Jacobi rule on [-1, 1], weight
    (1 - x)^a (1 + x)^b (a, b > -1): the eigenvalues of the Jacobi matrix of the orthonormal
    Jacobi polynomials and the squared first components of its eigenvectors (Golub & Welsch
    1969), in numpy alone (no scipy: the 6-DOF FMU's quasi-steady aerodynamics run on this
    module; tests/test_aero.py checks it against ``scipy.special.roots_jacobi``)."""
    k = np.arange(n, dtype=float)
    s = 2.0 * k + a + b
    diag = np.where(k == 0, (b - a) / (a + b + 2.0),
                    (b * b - a * a) / np.where(k == 0, 1.0, s * (s + 2.0)))
    k1, s1 = k[1:], s[1:]
    off = np.sqrt(4.0 * k1 * (k1 + a) * (k1 + b) * (k1 + a + b)
                  / (s1 * s1 * (s1 + 1.0) * (s1 - 1.0)))
    x, v = np.linalg.eigh(np.diag(diag) + np.diag(off, 1) + np.diag(off, -1))
    mu0 = 2.0 ** (a + b + 1.0) * math.gamma(a + 1.0) * math.gamma(b + 1.0) / math.gamma(a + b + 2.0)
    return x, mu0 * v[0] ** 2

def _rotation_profile(t: Array, start: float, duration: float) -> tuple[Array, Array, Array]:
    """tau - sin(2 pi tau)/(2 pi) and its first two derivatives in t, 0/1 outside."""
    tau = np.mod(t - start, 1.0) / duration
    inside = tau < 1.0
    tau_c = np.where(inside, tau, 1.0)
    f = tau_c - np.sin(2 * np.pi * tau_c) / (2 * np.pi)
    df = np.where(inside, (1.0 - np.cos(2 * np.pi * tau_c)) / duration, 0.0)
    ddf = np.where(inside, 2 * np.pi * np.sin(2 * np.pi * tau_c) / duration**2, 0.0)
    return f, df, ddf


class QuasiSteadyModel:
    """Cycle-averaged forces and moments of both wings, in the paper's non-dimensional form.

    Parameters
    ----------
    coefficients : str or CoefficientSet
        Translational coefficients (a key of :data:`COEFFICIENT_SETS`, default
        ``"dickinson1999"``).
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

        g = self.geometry
        # nodes x in [-1, 1] with weight (1-x)^(q-1) (1+x)^(p-1); r_hat = (1+x)/2
        x, w = gauss_jacobi(n_span, g.q - 1.0, g.p - 1.0)
        r_hat = 0.5 * (1.0 + x)
        # chord c(r) = C r^(p-1) (1-r)^(q-1) with the integral of c over the span = S_wing
        beta = math.gamma(g.p) * math.gamma(g.q) / math.gamma(g.p + g.q)
        C = g.S_wing / (g.R * beta)
        # integral of f(r) c(r) dr over [0, R] = sum f(r_i) * cw_i
        self._r = g.R * r_hat
        self._cw = C * g.R * w * 0.5 ** (g.p + g.q - 1.0)
        self._chord = C * r_hat ** (g.p - 1.0) * (1.0 - r_hat) ** (g.q - 1.0)
        self._roots = np.array([[g.hinge[0], -g.hinge[1], g.hinge[2]], list(g.hinge)])
        # the added mass m_a = rho (pi/4) c^2 dr of each element and its mid-chord's lever
        # arm over the pitch rate: sums of m_a r^j, j = 0, 1, 2, and of m_a mid r^j, j = 0, 1
        m_a = (0.5 * math.pi * g.k * self._chord * self._cw if terms.added_mass
               else 0.0 * self._r)
        mid = g.k * (0.5 - g.x0_hat) * self._chord
        self._added_mass_sums = tuple(float(np.sum(m_a * self._r ** j)) for j in range(3)) + \
            tuple(float(np.sum(m_a * mid * self._r ** j)) for j in range(2))
        self._t = (np.arange(n_time) + 0.5) / n_time
        self._trim: Trim | None = None
        self._kin_key: tuple[bytes, ...] | None = None
        self._kin: dict[str, Array] = {}
        self._map_key: tuple[bytes, ...] | None = None
        self._map: dict[str, Array] = {}

    # -- kinematics ---------------------------------------------------------------------
    def _pitch(self, alpha_d: Array, alpha_u: Array) -> tuple[Array, Array, Array]:
        """psi, dpsi/dt+, d2psi/dt+2 for each wing (rows) over the cycle (columns)."""
        t, dr = self._t, self.geometry.rotation_fraction
        ad, au = alpha_d[:, None], alpha_u[:, None]
        up_psi = np.pi - au
        if dr == 0.0:  # an instantaneous flip at the reversals (t+ = 0 and 0.5, between samples)
            psi = np.where(t < 0.5, ad, up_psi)
            return psi, np.zeros_like(psi), np.zeros_like(psi)
        f1, d1, dd1 = _rotation_profile(t, 0.5 - dr / 2, dr)  # end of downstroke
        f2, d2, dd2 = _rotation_profile(t, 1.0 - dr / 2, dr)  # end of upstroke
        in1 = (np.mod(t - (0.5 - dr / 2), 1.0) < dr)
        in2 = (np.mod(t - (1.0 - dr / 2), 1.0) < dr)
        mid_down = (t >= dr / 2) & (t < 0.5 - dr / 2)
        d_a = up_psi - ad
        psi = np.where(mid_down, ad, up_psi)
        psi = np.where(in1, ad + d_a * f1, psi)
        psi = np.where(in2, up_psi - d_a * f2, psi)
        dpsi = np.where(in1, d_a * d1, 0.0) - np.where(in2, d_a * d2, 0.0)
        ddpsi = np.where(in1, d_a * dd1, 0.0) - np.where(in2, d_a * dd2, 0.0)
        return psi, dpsi, ddpsi

    def wing_kinematics(self, control: Mapping[str, float] | None = None,
                        trim: Trim | None = None) -> dict[str, Array]:
        """Per-wing (left, right) stroke amplitude, mean stroke angle and angles of attack [rad].

        Parameters
        ----------
        control : mapping, optional
            Control increments [rad] by name (:data:`CONTROLS`); unnamed ones are 0.
        trim : Trim, optional
            The reference angles (default: :meth:`trim`).
        """
        u = _controls(control)
        tr = trim or self.trim()
        side = np.array([-1.0, 1.0])  # left, right; lateral controls add +d/2 on the left
        Phi = self.geometry.Phi_rad + u["delta_Phi"] - side * u["delta_Phi_a"] / 2
        phibar = tr.phibar + u["delta_phibar"] + 0.0 * side
        ad = (tr.alpha_d + u["delta_alpha_1"] + u["delta_alpha_2"] / 2
              - side * (u["delta_alpha_1a"] + u["delta_alpha_2a"]) / 2)
        au = (tr.alpha_u + u["delta_alpha_1"] - u["delta_alpha_2"] / 2
              - side * (u["delta_alpha_1a"] - u["delta_alpha_2a"]) / 2)
        return {"Phi": Phi, "phibar": phibar, "alpha_d": ad, "alpha_u": au}

    # -- forces -------------------------------------------------------------------------
    def _kinematics(self, Phi: Array, phibar: Array, alpha_d: Array,
                    alpha_u: Array) -> dict[str, Array]:
        """The body-motion-free part of the wing motion, cached for the last kinematics."""
        key = (Phi.tobytes(), phibar.tobytes(), alpha_d.tobytes(), alpha_u.tobytes())
        if self._kin_key == key:
            return self._kin
        g, t = self.geometry, self._t
        side = np.array([-1.0, 1.0])[:, None]
        phi = phibar[:, None] - 0.5 * Phi[:, None] * np.cos(2 * np.pi * t)  # (2, T)
        dphi = np.pi * Phi[:, None] * np.sin(2 * np.pi * t)
        psi, dpsi, _ = self._pitch(alpha_d, alpha_u)
        sphi, cphi = np.sin(phi), np.cos(phi)
        cpsi, spsi = np.cos(psi), np.sin(psi)
        r = self._r[None, None, :]
        kin = {
            # e_r = (sphi, side cphi, 0), e_t = (cphi, -side sphi, 0), up = (0, 0, -1)
            "erx": sphi[..., None], "ery": (side * cphi)[..., None],
            "etx": cphi[..., None], "ety": (-side * sphi)[..., None],
            "cpsi": cpsi[..., None], "spsi": spsi[..., None],
            "dpsi": dpsi[..., None], "side": side[..., None],
            # element positions from the centre of mass, (2, T, S) each
            "Px": g.hinge[0] + sphi[..., None] * r,
            "Py": side[..., None] * g.hinge[1] + (side * cphi)[..., None] * r,
            "Pz": np.full((2, 1, 1), g.hinge[2]),
            "vflap": (g.k * dphi)[..., None] * r,
        }
        self._kin_key, self._kin = key, kin
        return kin

    def _samples(self, Phi: Array, phibar: Array, alpha_d: Array, alpha_u: Array,
                 state: Array) -> Array:
        """(X, Y, Z, L, M, N) at each sample of the cycle, shape (6, n_time), evaluated
        directly, element by element (the added mass's time derivatives as periodic central
        differences); their mean over the samples is the cycle average.

        Vectors are handled by components, each an array (wing, time, element).
        """
        g, terms = self.geometry, self.terms
        k = g.k
        q = self._kinematics(Phi, phibar, alpha_d, alpha_u)
        erx, ery, etx, ety = q["erx"], q["ery"], q["etx"], q["ety"]
        cpsi, spsi = q["cpsi"], q["spsi"]
        Px, Py, Pz = q["Px"], q["Py"], q["Pz"]
        u, v, w, p, qq, rr = (float(c) for c in state)
        # chord e_c = cpsi e_t + spsi up, normal n = -spsi e_t + cpsi up (up = -z)
        ecx, ecy, ecz = cpsi * etx, cpsi * ety, -spsi
        nx, ny, nz = -spsi * etx, -spsi * ety, -cpsi
        # velocity: flapping + translation + k Omega x P, then the spanwise part removed
        vf = q["vflap"]
        Vx = vf * etx + u + k * (qq * Pz - rr * Py)
        Vy = vf * ety + v + k * (rr * Px - p * Pz)
        Vz = w + k * (p * Py - qq * Px) + 0.0 * vf
        span = Vx * erx + Vy * ery
        Vx = Vx - span * erx
        Vy = Vy - span * ery
        side = q["side"]
        # the pitch axis a_p = side e_r: psi rotates e_t towards up about it
        omega_p = q["dpsi"] + side * (p * erx + qq * ery)
        speed2 = Vx * Vx + Vy * Vy + Vz * Vz
        Vc = Vx * ecx + Vy * ecy + Vz * ecz
        Vn = Vx * nx + Vy * ny + Vz * nz
        chord = self._chord
        cw = self._cw
        Fx = np.zeros_like(Vx)
        Fy = np.zeros_like(Vx)
        Fz = np.zeros_like(Vx)
        if terms.translational:
            alpha = np.arctan2(np.abs(Vn), np.abs(Vc))
            speed = np.sqrt(speed2)
            inv = 1.0 / np.where(speed > 0.0, speed, 1.0)
            sa = np.abs(Vn) * inv  # sin(alpha)
            s_n = -np.sign(Vn)
            # lift along n_opp + sin(alpha) e_v (length cos(alpha)), drag along -e_v
            Lx, Ly, Lz = s_n * nx + sa * Vx * inv, s_n * ny + sa * Vy * inv, \
                s_n * nz + sa * Vz * inv
            norm = np.sqrt(Lx * Lx + Ly * Ly + Lz * Lz)
            norm = np.where(norm > 0.0, norm, 1.0)
            cl = self.coefficients.lift(alpha) * speed2 * cw / norm
            cd = self.coefficients.drag(alpha) * speed2 * cw * inv
            Fx = Fx + cl * Lx - cd * Vx
            Fy = Fy + cl * Ly - cd * Vy
            Fz = Fz + cl * Lz - cd * Vz
        if terms.rotational:
            c_rot = np.pi * (0.75 - g.x0_hat)
            # rho Gamma_rot (a_p x V), Gamma_rot = C_rot omega_p c^2: smooth in V
            f = 2.0 * c_rot * k * omega_p * chord * cw * side
            Fx = Fx + f * (ery * Vz)
            Fy = Fy - f * (erx * Vz)
            Fz = Fz + f * (erx * Vy - ery * Vx)
        if terms.added_mass:
            v_mid = Vn - k * (0.5 - g.x0_hat) * chord * omega_p
            m_a = 0.5 * np.pi * k * chord * cw
            half = self.n_time / 2.0
            if terms.added_mass_form == "impulse":
                ix, iy, iz = m_a * v_mid * nx, m_a * v_mid * ny, m_a * v_mid * nz
                dix = (np.roll(ix, -1, axis=1) - np.roll(ix, 1, axis=1)) * half
                diy = (np.roll(iy, -1, axis=1) - np.roll(iy, 1, axis=1)) * half
                diz = (np.roll(iz, -1, axis=1) - np.roll(iz, 1, axis=1)) * half
                Fx = Fx - dix - (qq * iz - rr * iy)
                Fy = Fy - diy - (rr * ix - p * iz)
                Fz = Fz - diz - (p * iy - qq * ix)
            else:
                dv = (np.roll(v_mid, -1, axis=1) - np.roll(v_mid, 1, axis=1)) * half
                f = m_a * dv
                Fx = Fx - f * nx
                Fy = Fy - f * ny
                Fz = Fz - f * nz
        scale = 1.0 / (2.0 * g.S_wing)
        Mx = Py * Fz - Pz * Fy
        My = Pz * Fx - Px * Fz
        Mz = Px * Fy - Py * Fx
        return np.array([np.sum(c, axis=(0, 2)) for c in (Fx, Fy, Fz, Mx, My, Mz)]) * scale

    def _maps(self, Phi: Array, phibar: Array, alpha_d: Array, alpha_u: Array) -> dict[str, Array]:
        """What the cycle average needs of the wing motion, cached for the last kinematics.

        The element at span r of a wing at a sample has the chord direction e_c, the normal n
        and the span direction e_r (orthonormal, e_r x e_c = s n with s = +/-1), its position
        P = H + r e_r from the centre of mass (H the root). Its normal and chordwise velocity
        (the spanwise one is removed, so |V|^2 = V_n^2 + V_c^2) and its pitch rate are affine
        in x1 = (1, state) and in r: ``A @ x1 + r B @ x1``, per wing-sample. Its forces are
        along e_c and n; their six sums (force, moment about the centre of mass) are linear in
        the span sums of the forces and of r times the forces, ``M``; ``am0``, ``am1`` do the
        same for the added mass's mid-chord normal velocity (the derivative in time moved, by
        parts over the periodic cycle, onto the wing's own motion, analytic). Stored for
        :meth:`_mean_of`: ``rows`` (7, 4 T2 S), what x1 turns into V_n, V_c, the rotational
        factor and the added-mass velocity of every element; ``Mt`` and ``amt``, ``M`` and
        the added mass's maps ordered (sample, sum); ``R`` the span sums.
        """
        key = (Phi.tobytes(), phibar.tobytes(), alpha_d.tobytes(), alpha_u.tobytes())
        if self._map_key == key:
            return self._map
        g, t = self.geometry, self._t
        k = g.k
        T2 = 2 * self.n_time
        side = np.array([-1.0, 1.0])[:, None]
        phi = phibar[:, None] - 0.5 * Phi[:, None] * np.cos(2 * np.pi * t)  # (2, T)
        dphi = np.pi * Phi[:, None] * np.sin(2 * np.pi * t)
        psi, dpsi, _ = self._pitch(alpha_d, alpha_u)
        sphi, cphi, spsi, cpsi = np.sin(phi), np.cos(phi), np.sin(psi), np.cos(psi)
        zero, one = np.zeros_like(phi), np.ones_like(phi)

        def vec(x: Array, y: Array, z: Array) -> Array:
            return np.stack(np.broadcast_arrays(x, y, z), axis=-1).reshape(T2, 3)

        e_r = vec(sphi, side * cphi, zero)
        e_t = vec(cphi, -side * sphi, zero)
        up = vec(zero, zero, -one)
        cps, sps, dps, dph = (a.reshape(T2, 1) for a in (cpsi, spsi, dpsi, dphi))
        e_c = cps * e_t + sps * up
        n = -sps * e_t + cps * up
        dn = -dps * e_c + (sps * dph) * e_r  # dn/dt+
        H = vec(g.hinge[0] + zero, side * g.hinge[1] + zero, g.hinge[2] + zero)
        s_or = np.sum(_cross(e_r, e_c) * n, axis=-1)[:, None]  # +/-1
        Hxn, Hxc = _cross(H, n), _cross(H, e_c)
        z1, z3 = np.zeros((T2, 1)), np.zeros((T2, 3))
        # V = k dphi r e_t + (u, v, w) + k Omega x P; V.a = k dphi r e_t.a + a.(u, v, w)
        # + k Omega.(P x a), with P x n = H x n - s r e_c and P x e_c = H x e_c + s r n
        A = np.stack([np.hstack([z1, n, k * Hxn]), np.hstack([z1, e_c, k * Hxc]),
                      np.hstack([dps, z3, side.repeat(self.n_time, 1).reshape(T2, 1) * e_r[:, :2],
                                 z1])])
        B = np.stack([np.hstack([-sps * k * dph, z3, -k * s_or * e_c]),
                      np.hstack([cps * k * dph, z3, k * s_or * n]), np.zeros((T2, 7))])
        # six sums from (sum Fc, sum r Fc, sum Fn, sum r Fn): F = Fc e_c + Fn n, moment
        # P x F = Fc (H x e_c + s r n) + Fn (H x n - s r e_c)
        M = np.stack([np.hstack([e_c, Hxc]), np.hstack([z3, s_or * n]),
                      np.hstack([n, Hxn]), np.hstack([z3, -s_or * e_c])])  # (4, T2, 6)
        etxn = dph * _cross(e_t, n)  # dP/dt+ x n over r
        if self.terms.added_mass_form == "impulse":
            # mean of -dI/dt - Omega x I, I = m_a v n: -Omega x sum(I); its moment, by parts,
            # sum(dP x I) - Omega sum(P.I) + Q Omega, Q_ij = sum(I_i P_j), P.n = H.n
            am0 = np.hstack([n, z3, np.sum(H * n, axis=-1)[:, None],
                             (n[:, :, None] * H[:, None, :]).reshape(T2, 9)])
            am1 = np.hstack([z3, etxn, z1, (n[:, :, None] * e_r[:, None, :]).reshape(T2, 9)])
        else:
            # mean of -m_a dv/dt n, by parts: sum(v m_a dn/dt), moment sum(v m_a d(P x n)/dt)
            am0 = np.hstack([dn, _cross(H, dn)])
            am1 = np.hstack([z3, etxn + _cross(e_r, dn)])
        c_rot = np.pi * (0.75 - g.x0_hat)
        chord, cw, r = self._chord, self._cw, self._r
        rot = (2.0 * c_rot * k * side.repeat(self.n_time, 1).reshape(T2, 1) * s_or) \
            * (chord * cw)[None, :]
        mid, m_a = k * (0.5 - g.x0_hat) * chord, 0.5 * np.pi * k * chord * cw
        # per wing-sample and element, the rows that x1 turns into V_n, V_c, the rotational
        # force factor f = rot omega_p and the added mass's m_a (V_n - mid omega_p): one
        # product per state, x1 @ (7, 4 T2 S) (long rows: a fast product; (4, T2, S, 7) @ x1
        # is the slow layout)
        Vn = A[0][:, None, :] + r[None, :, None] * B[0][:, None, :]
        Vc = A[1][:, None, :] + r[None, :, None] * B[1][:, None, :]
        om = A[2][:, None, :]
        rows = np.stack([Vn, Vc, rot[:, :, None] * om,
                         m_a[None, :, None] * (Vn - mid[None, :, None] * om)])
        self._map = {
            "rows": np.ascontiguousarray(np.moveaxis(rows, -1, 0).reshape(7, -1)),
            "shape": rows.shape[:-1],
            # the sums' maps ordered (sample, sum): the span sums come out (T2, 4) and (T2, 2)
            "Mt": np.ascontiguousarray(M.transpose(1, 0, 2).reshape(T2 * 4, 6)),
            "amt": np.ascontiguousarray(
                np.stack([am0, am1]).transpose(1, 0, 2).reshape(T2 * 2, -1)),
            "R": np.stack([np.ones_like(r), r], axis=1),  # (S, 2): span sums of f and r f
        }
        self._map_key = key
        return self._map

    def _mean(self, Phi: Array, phibar: Array, alpha_d: Array, alpha_u: Array,
              state: Array) -> Array:
        """Cycle-averaged (X, Y, Z, L, M, N) for per-wing kinematics (left, right).

        The forces of :meth:`_samples`, summed through the state-independent maps of
        :meth:`_maps`: the translational and rotational forces in the (e_c, n) frame of each
        element, the added mass integrated by parts over the periodic cycle, which removes the
        O(dt^2) error of the central differences.
        """
        return self._mean_of(self._maps(Phi, phibar, alpha_d, alpha_u), state)

    def _mean_of(self, mp: dict[str, Array], state: Sequence[float] | Array) -> Array:
        """:meth:`_mean` through the maps ``mp`` of the wing motion (the state's part only).

        One product gives every element's V_n, V_c, rotational factor and added-mass velocity
        (:meth:`_maps`, ``rows``); the rest is elementwise, then two products with the maps of
        the sums (the fewest numpy calls: each costs about a microsecond)."""
        terms = self.terms
        x = np.asarray(state, dtype=float)
        x1 = np.empty(7)
        x1[0] = 1.0
        x1[1:] = x
        Vn, Vc, f, v = (x1 @ mp["rows"]).reshape(mp["shape"])  # each (T2, S)
        R = mp["R"]
        if terms.translational:
            speed = np.sqrt(Vn * Vn + Vc * Vc)
            alpha = np.arctan2(np.abs(Vn), np.abs(Vc))
            q = self._cw * speed
            cl = q * self.coefficients.lift(alpha)
            cd = q * self.coefficients.drag(alpha)
            # lift normal to V away from the side the flow meets, drag against V
            Fc = cl * np.copysign(Vn, Vc) - cd * Vc
            Fn = -(cl * np.copysign(Vc, Vn) + cd * Vn)
            if terms.rotational:
                Fc -= f * Vn
                Fn += f * Vc
        elif terms.rotational:
            Fc, Fn = -f * Vn, f * Vc
        else:
            Fc = Fn = np.zeros_like(Vn)
        out = np.hstack([Fc @ R, Fn @ R]).reshape(-1) @ mp["Mt"]
        if terms.added_mass:
            s = (v @ R).reshape(-1) @ mp["amt"]
            if terms.added_mass_form == "impulse":
                p, q_, rr = x[3:]
                J, K, s1, Q = s[:3], s[3:6], s[6], s[7:].reshape(3, 3)
                out[:3] -= (q_ * J[2] - rr * J[1], rr * J[0] - p * J[2], p * J[1] - q_ * J[0])
                out[3:] += K - x[3:] * s1 + Q @ x[3:]
            else:
                out += s
        return out / (2.0 * self.geometry.S_wing * self.n_time)

    def state_function(self, controls: Sequence[float] = (0.0,) * 7,
                       trim: Trim | None = None) -> Callable[[Sequence[float]], Array]:
        """The cycle-averaged forces as a function of the body state, the controls held.

        What the 6-DOF plant's quasi-steady aerodynamics call at every Runge-Kutta stage
        (:class:`dronefly.models.rigid_body.Hover6DOF`): the wing motion of ``controls`` is
        mapped once, each call computes only what depends on the state.

        Parameters
        ----------
        controls : sequence of 7 floats
            The control increments [rad] in the order of :data:`CONTROLS` (lateral, then
            longitudinal).
        trim : Trim, optional
            The reference (default: the trimmed hover).

        Returns
        -------
        callable
            (du+, dv+, dw+, dp+, dq+, dr+) -> array (X+, Y+, Z+, L+, M+, N+), non-dimensional
            as :meth:`forces_vector` (no check of the state: the caller's).
        """
        if len(controls) != len(CONTROLS):
            raise DroneflyError(f"controls = {controls!r}: expected {len(CONTROLS)} values "
                                f"({', '.join(CONTROLS)})")
        kin = self.wing_kinematics(dict(zip(CONTROLS, controls)), trim)
        mp = self._maps(kin["Phi"], kin["phibar"], kin["alpha_d"], kin["alpha_u"])
        mean = self._mean_of
        return lambda state: mean(mp, state)

    def instants(self, angles: Sequence[Sequence[float]] | Array) -> list[Instant]:
        """What :meth:`forces_of` needs of the wings' motion at one or more instants.

        Everything of :meth:`forces_at` that does not depend on the body state: the frames of
        both wings, the linear forms of each element's velocities in the state, and the maps
        from the forces' span sums to the six loads. A host that needs the forces at the same
        wing motion for many states (the Runge-Kutta stages of
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
            One per instant (one for a single (6, 2)).

        Raises
        ------
        DroneflyError
            The angles' shape is wrong, or the model's added mass is not the impulse form.
        """
        a = np.asarray(angles, dtype=float)
        if a.ndim == 2:
            a = a[None]
        if a.ndim != 3 or a.shape[1:] != (6, 2):
            raise DroneflyError(f"angles of shape {np.shape(angles)}: expected (6, 2) or "
                                "(T, 6, 2)")
        g, terms, k = self.geometry, self.terms, self.geometry.k
        if terms.added_mass and terms.added_mass_form != "impulse":
            raise DroneflyError("forces_at has the impulse form of the added mass only")
        T = len(a)
        phi, dphi, ddphi, psi, dpsi, ddpsi = (a[:, j, :] for j in range(6))  # each (T, wing)
        side = _SIDE
        sphi, cphi, spsi, cpsi = np.sin(phi), np.cos(phi), np.sin(psi), np.cos(psi)
        zero = np.zeros_like(phi)
        # e_r = (sphi, s cphi, 0), e_t = (cphi, -s sphi, 0), e_c = cpsi e_t + spsi up,
        # n = -spsi e_t + cpsi up (up = -z); e_r x e_c = s_or n, e_r x n = -s_or e_c. Vectors
        # are (T, wing, 3), H the roots (wing, 3)
        etx, ety = cphi, -side * sphi
        er = np.stack([sphi, side * cphi, zero], axis=-1)
        et = np.stack([etx, ety, zero], axis=-1)
        ec = np.stack([cpsi * etx, cpsi * ety, -spsi], axis=-1)
        nn = np.stack([-spsi * etx, -spsi * ety, -cpsi], axis=-1)
        H = self._roots
        s_or = np.sum(_cross(er, ec) * nn, axis=-1)
        so = s_or[..., None]
        Hx = _cross(H, np.stack([nn, ec, er]))  # H x n, H x e_c, H x e_r
        # linear forms in x1 = (1, u, v, w, p, q, r), (T, wing, form, 7). The element at span r
        # has V_n = an + r bn, V_c = ac + r bc: V.a = V_b.a + k Omega.(H x a)
        # + r (k dphi e_t.a + k Omega.(e_r x a)); V.e_r = vr0 (the same along the span); the
        # pitch rate about a_p = s e_r (rotation plus the body's rate) om_p and its derivative
        # d_om; d(V.n)/dt+ = r (-k ddphi spsi + k dphi Omega.(e_t x n)) - dpsi V_c
        # + spsi dphi V_r, r dbn the first term
        L = np.zeros((T, 2, 8, 7))
        an, bn, ac, bc, vr0, om_p, d_om, dbn = (L[:, :, i] for i in range(8))
        an[..., 1:4], an[..., 4:] = nn, k * Hx[0]
        bn[..., 0], bn[..., 4:] = -k * dphi * spsi, -k * so * ec
        ac[..., 1:4], ac[..., 4:] = ec, k * Hx[1]
        bc[..., 0], bc[..., 4:] = k * dphi * cpsi, k * so * nn
        vr0[..., 1:4], vr0[..., 4:] = er, k * Hx[2]
        om_p[..., 0], om_p[..., 4:6] = dpsi, side[:, None] * er[..., :2]
        d_om[..., 0], d_om[..., 4:6] = ddpsi, (side * dphi)[..., None] * et[..., :2]
        dbn[..., 0], dbn[..., 4:] = -k * ddphi * spsi, (k * dphi)[..., None] * _cross(et, nn)
        r, chord, cw = self._r, self._chord, self._cw
        # per element: V_n, V_c and the rotational force factor f (as f and -f):
        # rho Gamma_rot (a_p x V) = f (V_c n - V_n e_c), f = rho C_rot omega_p c^2 s s_or
        c_rot = 2.0 * math.pi * (0.75 - g.x0_hat) * k if terms.rotational else 0.0
        f = (c_rot * side * s_or)[..., None, None] * (chord * cw) * om_p[..., None]
        rows = np.empty((T, 7, 4, 2, len(r)))  # (T, x1, quantity, wing, element)
        rows[:, :, 0] = (an[..., None] + bn[..., None] * r).transpose(0, 2, 1, 3)
        rows[:, :, 1] = (ac[..., None] + bc[..., None] * r).transpose(0, 2, 1, 3)
        rows[:, :, 2] = f.transpose(0, 2, 1, 3)
        rows[:, :, 3] = -rows[:, :, 2]
        # the added mass, I = m_a v_mid n per element, v_mid = V_n - mid omega_p: its span
        # sums are linear in x1: S0 = sum m_a v_mid, S1 = sum r m_a v_mid, and those of its
        # normal force -m_a dv_mid/dt+ and of r times it (D0, D1), dv_mid/dt+ = r dbn
        # - dpsi V_c + spsi dphi V_r - mid d(omega_p)/dt+
        M0, M1, M2, Mm0, Mm1 = self._added_mass_sums
        dps, spd = dpsi[..., None], (spsi * dphi)[..., None]
        am = np.empty((T, 2, 2, 2, 7))  # (T, (S, D), wing, (sum, r sum), x1)
        am[:, 0, :, 0] = an * M0 + bn * M1 - om_p * Mm0
        am[:, 0, :, 1] = an * M1 + bn * M2 - om_p * Mm1
        am[:, 1, :, 0] = -(dbn * M1 - dps * (ac * M0 + bc * M1) + spd * vr0 * M0 - d_om * Mm0)
        am[:, 1, :, 1] = -(dbn * M2 - dps * (ac * M1 + bc * M2) + spd * vr0 * M1 - d_om * Mm1)
        # the six loads of each sum, (T, wing, 6): a force F at the element (P = H + r e_r)
        # adds (F, H x F) and r e_r x F, with r e_r x (Fc e_c + Fn n) = s_or r (Fc n - Fn e_c);
        # the added mass: F_c += dpsi S0, F_r = -spsi dphi S0, and -Omega x sum(I):
        # F -= S0 Omega x n, M -= S0 H x (Omega x n) + S1 e_r x (Omega x n)
        z3 = np.zeros_like(nn)
        c_fn, c_fc, c_fr = np.concatenate([np.stack([nn, ec, er]), Hx], axis=-1)
        c_rfn, c_rfc = np.concatenate([z3, -so * ec], axis=-1), np.concatenate([z3, so * nn], -1)
        G = np.empty((T, 6, 28))

        def put(i: int, c: Array) -> None:  # the columns i (left), i + 2 (right)
            G[:, :, i:i + 3:2] = np.swapaxes(c, 1, 2)

        put(0, c_fn), put(1, c_rfn), put(4, c_fc), put(5, c_rfc)  # sums of (F_n, F_c)
        put(8, dps * c_fc - spd * c_fr), put(9, dps * c_rfc), put(12, c_fn), put(13, c_rfn)
        oxn = _cross(_EYE3[:, None, None, :], nn)  # e_j x n, (j, T, wing, 3)
        P = np.empty((T, 6, 2, 2, 3))  # (T, load, wing, (S0, S1), omega_j)
        P[:, :, :, 0] = -np.concatenate([oxn, _cross(H, oxn)], axis=-1).transpose(1, 3, 2, 0)
        P[:, :, :, 1] = -np.concatenate([np.zeros_like(oxn), _cross(er, oxn)],
                                        axis=-1).transpose(1, 3, 2, 0)
        G[:, :, 16:] = P.reshape(T, 6, 12)
        G /= 2.0 * g.S_wing
        # the span sums of (F_n, F_c) folded in: the loads of each element's forces
        sums = G[:, :, :8].reshape(T, 6, 2, 2, 2)
        G = np.concatenate([(sums[..., :1] + sums[..., 1:] * r).reshape(T, 6, -1),
                            G[:, :, 8:]], axis=-1)
        # one product with x1 for the elements and the added mass's sums
        rows = np.concatenate([rows.reshape(T, 7, -1),
                               am.reshape(T, 8, 7).transpose(0, 2, 1)], axis=-1)
        return [Instant(rows[i], G[i]) for i in range(T)]

    def forces_of(self, instant: Instant, state: Sequence[float] | Array) -> Array:
        """The instantaneous forces and moments of both wings at an :meth:`instants` instant.

        The state's part of :meth:`forces_at`: one product gives every element's V_n, V_c and
        rotational factor and the added mass's span sums, the translational forces are
        elementwise, then one product gives the six loads of every element's forces, the added
        mass's sums and their products with the rates (the fewest numpy calls: each costs about
        a microsecond).

        Parameters
        ----------
        instant : Instant
            The wing motion (:meth:`instants`).
        state : array of 6 floats
            (du+, dv+, dw+, dp+, dq+, dr+), non-dimensional as :meth:`forces_at`'s (no check:
            the caller's; :meth:`forces_at` checks it).

        Returns
        -------
        array
            (X+, Y+, Z+, L+, M+, N+): forces over 0.5 rho U^2 S_t, moments over
            0.5 rho U^2 S_t c.
        """
        rows, out = instant
        x1 = np.empty(7)
        x1[0] = 1.0
        x1[1:] = state
        e = x1 @ rows
        a = e[-8:]  # (S0, S1) of each wing, then the added mass's normal force sums
        E = e[:-8].reshape(4, 2, -1)  # (V_n, V_c, f, -f) of (wing, element)
        V = E[:2]
        if self.terms.translational:
            aV = np.abs(V)
            speed = np.hypot(V[0], V[1])
            alpha = np.arctan2(aV[0], aV[1])
            q = self._cw * speed
            cl = q * self.coefficients.lift(alpha)
            cd = q * self.coefficients.drag(alpha)
            # lift normal to V away from the side the flow meets, drag against V:
            # F_n = -cl copysign(|V_c|, V_n) - cd V_n, F_c = cl copysign(|V_n|, V_c) - cd V_c
            F = cl * (np.copysign(aV[::-1], V) * _LIFT_SIDE) - cd * V
            F += E[2:] * V[::-1]  # F_n += f V_c, F_c -= f V_n
        else:
            F = E[2:] * V[::-1]
        return out @ np.concatenate([F.reshape(-1), a, (a[:4, None] * x1[4:]).reshape(-1)])

    def forces_at(self, angles: Sequence[Sequence[float]] | Array,
                  state: Sequence[float] | Array = (0.0,) * 6) -> Array:
        """The instantaneous (X+, Y+, Z+, L+, M+, N+) of both wings at one instant.

        ``angles`` holds, per wing (columns left, right), the stroke angle phi, the pitch angle
        psi of the chord from the forward stroke direction (alpha_d in mid-downstroke,
        pi - alpha_u in mid-upstroke) and their first two derivatives in t+: rows (phi, dphi,
        ddphi, psi, dpsi, ddpsi), shape (6, 2). Any wing motion, not only this model's
        harmonic kinematics (the wing-beat-resolved plant, :mod:`dronefly.models.flapping`,
        changes the kinematics between wing beats). The terms and their scaling are those of
        :meth:`forces_over_cycle`, evaluated as :meth:`forces_vector` evaluates them: each
        element's velocity (the spanwise part removed) is V_c e_c + V_n n, affine in the span,
        its forces along e_c, n and (the added mass's turning normal) e_r. The added mass's
        time derivative is analytic, from the wing's angular accelerations and the body's
        rates; the body's own acceleration does not enter it (the state is the body's, not its
        rate): that leaves out the added mass of the air that the wings carry with the body,
        m_a / m = 0.24 % of the insect's mass (both wings), a correction the cycle average does
        not have either.

        It is :meth:`forces_of` at the one :meth:`instants` instant of ``angles``: the part
        that depends on the wing motion alone, then the state's.
        """
        a = np.asarray(angles, dtype=float)
        x = np.asarray(state, dtype=float)
        if a.shape != (6, 2) or x.shape != (6,):
            raise DroneflyError(f"angles of shape {a.shape} and state of shape {x.shape}: "
                                "expected (6, 2) and (6,)")
        return self.forces_of(self.instants(a)[0], x)

    def forces_over_cycle(self, state: Sequence[float] | Array = (0.0,) * 6,
                          control: Mapping[str, float] | None = None,
                          trim: Trim | None = None) -> Array:
        """The instantaneous (X+, Y+, Z+, L+, M+, N+) over the cycle, shape (6, n_time).

        At t+ = (j + 1/2)/n_time, element by element; the added mass's time derivatives are
        periodic central differences. Its mean over the samples is the cycle average of
        :meth:`forces_vector` up to their O(1/n_time^2) difference in the added mass's moment
        (round-off elsewhere). Parameters as :meth:`forces_vector`.
        """
        return self._samples(*self._kinematics_and_state(state, control, trim))

    def _kinematics_and_state(self, state: Sequence[float] | Array,
                              control: Mapping[str, float] | None,
                              trim: Trim | None) -> tuple[Any, ...]:
        """(Phi, phibar, alpha_d, alpha_u, x) for :meth:`_mean` and :meth:`_samples`; a state
        that is not 6 finite numbers is refused naming it."""
        x = np.asarray(state, dtype=float)
        if x.shape != (6,) or not np.all(np.isfinite(x)):
            raise DroneflyError(f"state = {state!r}: expected 6 finite numbers "
                                f"({', '.join(STATES)})")
        kin = self.wing_kinematics(control, trim)
        return kin["Phi"], kin["phibar"], kin["alpha_d"], kin["alpha_u"], x

    def forces_vector(self, state: Sequence[float] | Array = (0.0,) * 6,
                      control: Mapping[str, float] | None = None,
                      trim: Trim | None = None) -> Array:
        """Cycle-averaged (X+, Y+, Z+, L+, M+, N+) as an array (order :data:`FORCES`).

        Parameters
        ----------
        state : sequence of 6 floats
            (du+, dv+, dw+, dp+, dq+, dr+), non-dimensional, about hover.
        control : mapping, optional
            Control increments [rad] by name.
        trim : Trim, optional
            The reference (default: the trimmed hover).
        """
        return self._mean(*self._kinematics_and_state(state, control, trim))

    def forces(self, state: Mapping[str, float] | None = None,
               control: Mapping[str, float] | None = None,
               trim: Trim | None = None) -> dict[str, float]:
        """Cycle-averaged forces and moments by name ``X`` ... ``N`` (non-dimensional).

        Parameters
        ----------
        state : mapping, optional
            Non-dimensional state by FMU name (:data:`STATES`), 0 if not named.
        control : mapping, optional
            Control increments [rad] by name (:data:`CONTROLS`), 0 if not named.
        """
        x = [float(v) for v in _named(state, STATES, "state").values()]
        return dict(zip(FORCES, (float(v) for v in self.forces_vector(x, control, trim))))

    # -- trim ---------------------------------------------------------------------------
    def trim(self, tol: float = 1e-12, max_iter: int = 30) -> Trim:
        """alpha_d, alpha_u and phibar such that X = 0, Z = -W+ and M = 0 (cached).

        Newton's method with a central-difference Jacobian, from 30 deg, 30 deg, 0. Raises
        :class:`DroneflyError` if the residual does not fall below ``tol`` W+ or the angles
        leave 0 < alpha < 90 deg, |phibar| < 90 deg (a model without the lift terms).
        """
        if self._trim is not None:
            return self._trim
        W = self.geometry.weight
        z = np.array([math.radians(30.0), math.radians(30.0), 0.0])

        def residual(zz: Array) -> Array:
            f = self._mean(np.full(2, self.geometry.Phi_rad), np.full(2, zz[2]),
                           np.full(2, zz[0]), np.full(2, zz[1]), np.zeros(6))
            return np.array([f[0], f[2] + W, f[4]]) / W

        res = residual(z)
        for _ in range(max_iter):
            if np.max(np.abs(res)) < tol:
                break
            J = np.empty((3, 3))
            h = 1e-6
            for j in range(3):
                dz = np.zeros(3)
                dz[j] = h
                J[:, j] = (residual(z + dz) - residual(z - dz)) / (2 * h)
            try:
                z = z - np.linalg.solve(J, res)
            except np.linalg.LinAlgError:
                raise DroneflyError(f"no trim: the force and pitch moment do not depend on the "
                                    f"angles of attack ({self.coefficients.name}, terms "
                                    f"{self.terms})") from None
            res = residual(z)
            if not np.all(np.isfinite(res)):
                break
        err = float(np.max(np.abs(res)))
        if not (0.0 < z[0] < np.pi / 2 and 0.0 < z[1] < np.pi / 2 and abs(z[2]) < np.pi / 2):
            raise DroneflyError(
                f"no trim with angles of attack in (0, 90) deg and |phibar| < 90 deg: Newton "
                f"ended at alpha_d = {math.degrees(z[0]):.4g} deg, alpha_u = "
                f"{math.degrees(z[1]):.4g} deg, phibar = {math.degrees(z[2]):.4g} deg "
                f"({self.coefficients.name}, terms {self.terms})")
        if not err < max(tol, 1e-9):
            raise DroneflyError(f"trim did not converge: residual {err:.3g} of the weight "
                                f"({self.coefficients.name}, terms {self.terms})")
        f = self._mean(np.full(2, self.geometry.Phi_rad), np.full(2, z[2]), np.full(2, z[0]),
                       np.full(2, z[1]), np.zeros(6))
        self._trim = Trim(float(z[0]), float(z[1]), float(z[2]), err,
                          dict(zip(FORCES, (float(v) for v in f))))
        return self._trim

    def with_options(self, **changes: object) -> "QuasiSteadyModel":
        """A new model with other ``coefficients``, ``terms``, ``n_span``, ``n_time``."""
        opts = {"coefficients": self.coefficients, "terms": self.terms, "n_span": self.n_span,
                "n_time": self.n_time, "geometry": self.geometry, **changes}
        return QuasiSteadyModel(**opts)  # type: ignore[arg-type]


def _named(values: Mapping[str, float] | None, names: Sequence[str], what: str) -> dict[str, float]:
    out = {n: 0.0 for n in names}
    for key, value in (values or {}).items():
        if key not in out:
            raise DroneflyError(f"{what} {key!r}: expected one of {', '.join(names)}")
        v = float(value)
        if not math.isfinite(v):
            raise DroneflyError(f"{what} {key} = {value!r} is not finite")
        out[key] = v
    return out


def _controls(control: Mapping[str, float] | None) -> dict[str, float]:
    return _named(control, CONTROLS, "control")
