"""Interface of the six-degree-of-freedom plant ``DroneFlyHover6DOF``: names, units, texts.

A drop-in for both linear plants: the lateral states and controls of :mod:`dronefly.models.lateral_interface`
and the longitudinal ones of :mod:`dronefly.models.longitudinal_interface`, with the same names, units and
causalities, plus the attitude as Euler angles and the motion in earth axes (north-east-down,
origin at the initial position).

The initial attitude is given by three angles: ``delta_theta_start`` (pitch theta, the angle
of the body x-axis above the horizontal), ``delta_gamma_start`` (gamma, the angle of the body
y-axis below the horizontal, the linear lateral plant's state) and ``psi_start`` (heading).
They are the Euler angles (psi, theta, phi) with sin(phi) = sin(gamma) / cos(theta); with
theta = 0, phi = gamma, so a linear plant's initial state means the same here.

Pure Python (no numpy).
"""

from __future__ import annotations

from .lateral_interface import LATERAL
from .longitudinal_interface import LONGITUDINAL

__all__ = ["EARTH_OUTPUTS", "EULER_OUTPUTS", "EXTRA_STARTS", "OUTPUT_NAMES", "STATE_OUTPUTS"]

#: the eight disturbance states, lateral then longitudinal (names as in the linear plants)
STATE_OUTPUTS: tuple[str, ...] = (*LATERAL.state_names, *LONGITUDINAL.state_names)

#: (name, unit, display unit, description)
EULER_OUTPUTS: tuple[tuple[str, str, str | None, str], ...] = (
    ("phi", "rad", "deg", "roll angle (Euler angles yaw-pitch-roll, body to earth)"),
    ("theta", "rad", "deg", "pitch angle (Euler angles yaw-pitch-roll; equals delta_theta)"),
    ("psi", "rad", "deg", "heading (Euler angles yaw-pitch-roll), from north"),
)
EARTH_OUTPUTS: tuple[tuple[str, str, str | None, str], ...] = (
    ("x_earth", "m", "mm", "position north of the initial position (earth axes)"),
    ("y_earth", "m", "mm", "position east of the initial position (earth axes)"),
    ("z_earth", "m", "mm", "position below the initial position (earth axes, positive down: "
                           "the altitude lost)"),
    ("vx_earth", "m/s", None, "velocity north (earth axes)"),
    ("vy_earth", "m/s", None, "velocity east (earth axes)"),
    ("vz_earth", "m/s", None, "velocity down (earth axes; positive = sinking)"),
)
#: every output, in the order of :func:`dronefly.models.rigid_body.outputs`
OUTPUT_NAMES: tuple[str, ...] = (*STATE_OUTPUTS, *(o[0] for o in EULER_OUTPUTS),
                                 *(o[0] for o in EARTH_OUTPUTS))
#: start parameters beyond the eight ``<state>_start``: (name, unit, display unit, text)
EXTRA_STARTS: tuple[tuple[str, str, str | None, str], ...] = (
    ("psi_start", "rad", "deg", "initial heading"),
    ("x_earth_start", "m", "mm", "initial position north"),
    ("y_earth_start", "m", "mm", "initial position east"),
    ("z_earth_start", "m", "mm", "initial position down"),
)
