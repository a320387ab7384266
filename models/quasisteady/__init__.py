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
state-dependent flow is sampled. The velocities are affine in the state and the span, so what
does not depend on the state is computed once per wing kinematics; the instantaneous forces
(:meth:`QuasiSteadyModel.forces_at`) are split the same way, into
:meth:`QuasiSteadyModel.instants`, the wing motion's part (at any number of instants at once),
and the call of each :class:`Instant` with a state, the state's (the wing-beat-resolved plant
keeps the first for the instants of its grid). The default grid, 8 elements and 100 samples, is
the smallest whose derivatives agree with a grid of 32 x 800 to 0.1 % of each input's largest
derivative (tests/test_aero.py); the error is the midpoint rule's O(1/n_time^2) at the kinks of
the quasi-steady forces where an element's velocity passes through zero near a reversal.

The package, one idea a module:

- :mod:`~dronefly.models.quasisteady.wing`: the names of the state, controls and loads, the
  body data, the geometry, the coefficient sets and the force terms;
- :mod:`~dronefly.models.quasisteady.elements`: the blade elements (Gauss-Jacobi nodes of the
  planform);
- :mod:`~dronefly.models.quasisteady.kinematics`: the wings' stroke and pitch from the controls
  and the trim;
- :mod:`~dronefly.models.quasisteady.instantaneous`: the instantaneous loads at any wing motion;
- :mod:`~dronefly.models.quasisteady.cycle`: the loads sampled over the cycle and their average;
- :mod:`~dronefly.models.quasisteady.trim`: the trimmed hover;
- :mod:`~dronefly.models.quasisteady.model`: :class:`QuasiSteadyModel`, which holds the options
  and the caches and answers for the forces.
"""

from __future__ import annotations

from .elements import gauss_jacobi
from .instantaneous import Instant
from .model import QuasiSteadyModel
from .trim import Trim
from .wing import (BODY_DATA, COEFFICIENT_SETS, CONTROLS, FORCES, STATES, CoefficientSet, Terms,
                   WingGeometry)

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
