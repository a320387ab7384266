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
(:meth:`~dronefly.models.quasisteady.QuasiSteadyModel.wing_kinematics`: per-wing stroke
amplitude, mean stroke angle, angles of attack). **When a change takes effect**: the controls
are sampled at the start of each wing beat, t+ = k, the rear stroke reversal where the wing is
at rest, and held for that beat. Beat k's stroke runs from the rear reversal the previous beat
reached to the front reversal of the new controls (downstroke), then to their rear reversal
(upstroke), each half a cosine, so the stroke angle and its rate are continuous; the pitch
rotation centred on the reversal at t+ = k is already under way when the controls are sampled
and is finished with the angles it began with, so the new angles of attack begin with the next
rotation: the upstroke angle alpha_u in beat k, the downstroke angle alpha_d from beat k + 1 (no
jump in the pitch angle or rate, so no impulse of the added mass). With the controls held, the
kinematics are exactly those of the quasi-steady model. A host that steps once per wing beat and
one that steps 40 times per wing beat, setting the same controls at the beats' starts, see the
same physics (tests/test_flapping.py): a change between two beat starts waits for the next one.

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
(each :class:`~dronefly.models.quasisteady.Instant` called with the state, the rigid body) alone; a
partial step makes its own. The kept stages are the equations evaluated at those instants, to
round-off (tests/test_flapping.py); the angles and loads at a grid point are its stage's.

numpy is imported (the quasi-steady model needs it); the FMU that ships this package documents it.

The package, one idea a module: :mod:`~dronefly.models.flapping.model` the equations
(:class:`FlappingModel`), :mod:`~dronefly.models.flapping.flight` the model in time for a host
(:class:`Flight`, the FMU's), :mod:`~dronefly.models.flapping.orbit` hover as a periodic orbit and
its Floquet analysis; the Newton shooting it uses is generic, :mod:`dronefly.models.shooting`.
"""

from __future__ import annotations

from ..shooting import shooting
from .flight import Flight
from .model import (STATE_SIZE, STEPS_PER_BEAT, WING_CM_OVER_R, Z_NAMES, FlappingError,
                    FlappingModel, wing_beat_controls)
from .orbit import (AXES, Floquet, PeriodicOrbit, averaged_exponents, averaged_monodromy,
                    block_exponents, monodromy, orbit_start, periodic_orbit)

__all__ = ["AXES", "STATE_SIZE", "STEPS_PER_BEAT", "WING_CM_OVER_R", "FlappingError",
           "FlappingModel", "Flight", "Floquet", "PeriodicOrbit", "Z_NAMES", "averaged_exponents",
           "averaged_monodromy", "block_exponents", "monodromy", "orbit_start", "periodic_orbit",
           "shooting", "wing_beat_controls"]
