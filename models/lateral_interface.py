"""Interface of the lateral plant: names, units, descriptions and reference scales.

The one home of what the plant FMU, the controller FMU, the controller law and
the harness must agree on to talk to each other (Zhang & Sun, Sect. 2.1 and 2.4):

- the state x = (delta_v, delta_p, delta_r, delta_gamma) and the control
  u = (delta_Phi_a, delta_alpha_1a, delta_alpha_2a), with SI units, display
  units and descriptions;
- the reference scales n (wing-beat frequency, t_w = 1/n) and U = 2 Phi n r2,
  computed from the Sect. 2.4 flight data;
- the non-dimensional state x+ = (delta_v/U, delta_p t_w, delta_r t_w,
  delta_gamma) = x / [U, n, n, 1], and the conversion both ways;
- the ordering of eigenvalues used in every table and verdict.

Pure Python (no numpy): both FMUs ship this module, and the controller FMU
needs nothing else of the plant.
"""

from __future__ import annotations

import math
from typing import Iterable, Mapping, Sequence

from .axes import Axis
from ..core.errors import DroneflyError

__all__ = [
    "parameter_description",
    "CONTROL_DESCRIPTIONS",
    "CONTROL_NAMES",
    "CONTROL_UNIT",
    "FLIGHT_DATA",
    "INERTIAS_SECT21",
    "LATERAL",
    "N_HZ",
    "NONDIMENSIONAL",
    "STATE_DESCRIPTIONS",
    "STATE_BOUNDS_SECT36",
    "STATE_NAMES",
    "STATE_UNITS",
    "U_M_PER_S",
    "eigen_order",
    "plant_scales",
    "reference_scales",
    "scale_vector",
    "sort_eigenvalues",
    "to_dimensional",
    "to_nondimensional",
]

STATE_NAMES: tuple[str, ...] = ("delta_v", "delta_p", "delta_r", "delta_gamma")
CONTROL_NAMES: tuple[str, ...] = ("delta_Phi_a", "delta_alpha_1a", "delta_alpha_2a")

#: (SI unit, display unit or None) of each state, in STATE_NAMES order.
STATE_UNITS: tuple[tuple[str, str | None], ...] = (
    ("m/s", None), ("rad/s", "deg/s"), ("rad/s", "deg/s"), ("rad", "deg"))
#: (SI unit, display unit) of every control.
CONTROL_UNIT: tuple[str, str] = ("rad", "deg")

STATE_DESCRIPTIONS: tuple[str, ...] = (
    "lateral (y-axis) velocity disturbance",
    "roll rate disturbance (about x)",
    "yaw rate disturbance (about z)",
    "roll angle disturbance (y-axis to horizontal)",
)
CONTROL_DESCRIPTIONS: tuple[str, ...] = (
    "anti-symmetric stroke-amplitude change (left minus right)",
    "anti-symmetric change of both angles of attack (left minus right)",
    "anti-symmetric differential change of down/upstroke angles of attack",
)

#: The lateral axis: state, controls, units and non-dimensionalisation in one object.
LATERAL = Axis("lateral", STATE_NAMES, CONTROL_NAMES, STATE_UNITS, CONTROL_UNIT,
               STATE_DESCRIPTIONS, CONTROL_DESCRIPTIONS, ("U", "n", "n", "1"))
#: How each component of x+ is formed from the dimensional state ("x+1 = delta_v/U", ...).
NONDIMENSIONAL: tuple[str, ...] = LATERAL.nondimensional

#: Sect. 3.6: the linear analysis holds while |dv+|, |dp+|, |dr+| <= 0.15 and |dgamma| <= 0.22 rad
#: (x+, non-dimensional; the controls stay within +/-0.4 rad).
STATE_BOUNDS_SECT36: tuple[float, float, float, float] = (0.15, 0.15, 0.15, 0.22)

#: Sect. 2.4: flight data of the model drone fly, SI units.
FLIGHT_DATA: dict[str, float] = {
    "m_body": 87.76e-6,  # kg
    "m_wing": 0.56e-6,  # kg, one wing
    "R": 11.2e-3,  # m, wing length
    "c": 2.98e-3,  # m, mean chord
    "r2_over_R": 0.55,
    "S_wing": 33.34e-6,  # m^2, one wing
    "Ix": 657.7e-12,  # kg m^2 (657.7 mg mm^2)
    "Iy": 1308.5e-12,
    "Iz": 834.6e-12,
    "Ixz": -550.0e-12,
    "Phi_deg": 107.1,  # stroke amplitude
    "n": 164.0,  # Hz
    "rho": 1.25,  # kg/m^3
    "g": 9.81,  # m/s^2
}


#: End of Sect. 2.1: non-dimensional mass, inertias and gravity (from Ref. [8]).
INERTIAS_SECT21: dict[str, float] = {
    "m_plus": 92.7,
    "Ix_plus": 10.00,
    "Iz_plus": 12.69,
    "Ixz_plus": -8.36,
    "g_plus": 0.0158,
}


def reference_scales(data: Mapping[str, float] = FLIGHT_DATA) -> dict[str, float]:
    """Reference scales and non-dimensional mass properties from flight data.

    Parameters
    ----------
    data : mapping
        Flight data as in :data:`FLIGHT_DATA` (SI units).

    Returns
    -------
    dict
        ``n`` [Hz], ``t_w`` [s], ``U`` [m/s] (U = 2 Phi n r2), and the
        non-dimensional ``m_plus``, ``Ix_plus``, ``Iz_plus``, ``Ixz_plus``,
        ``g_plus`` as defined at the end of Sect. 2.1, and ``Iy_plus`` (pitch, Sect. 3.5)
        in the same non-dimensionalisation.
    """
    n = data["n"]
    t_w = 1.0 / n
    U = 2.0 * math.radians(data["Phi_deg"]) * n * data["r2_over_R"] * data["R"]
    S_t = 2.0 * data["S_wing"]
    m = data["m_body"] + 2.0 * data["m_wing"]
    q_force = 0.5 * data["rho"] * U * S_t * t_w
    q_inertia = 0.5 * data["rho"] * U**2 * S_t * data["c"] * t_w**2
    return {
        "n": n,
        "t_w": t_w,
        "U": U,
        "m_plus": m / q_force,
        "Ix_plus": data["Ix"] / q_inertia,
        "Iz_plus": data["Iz"] / q_inertia,
        "Ixz_plus": data["Ixz"] / q_inertia,
        "Iy_plus": data["Iy"] / q_inertia,
        "g_plus": data["g"] * t_w / U,
    }


#: Wing-beat frequency [Hz] (Sect. 2.4).
N_HZ: float = FLIGHT_DATA["n"]
#: Reference velocity U = 2 Phi n r2 [m/s] (Sect. 2.4).
U_M_PER_S: float = reference_scales()["U"]


def scale_vector(u_m_per_s: float = U_M_PER_S, n_hz: float = N_HZ) -> tuple[float, ...]:
    """[U, n, n, 1]: the dimensional state is x = x+ * scale (element-wise)."""
    return (u_m_per_s, n_hz, n_hz, 1.0)


def to_nondimensional(x: Sequence[float], u_m_per_s: float = U_M_PER_S,
                      n_hz: float = N_HZ) -> tuple[float, ...]:
    """(dv [m/s], dp [rad/s], dr [rad/s], dgamma [rad]) -> x+ (non-dimensional)."""
    return (x[0] / u_m_per_s, x[1] / n_hz, x[2] / n_hz, float(x[3]))


def to_dimensional(x_plus: Sequence[float], u_m_per_s: float = U_M_PER_S,
                   n_hz: float = N_HZ) -> tuple[float, ...]:
    """x+ -> (dv [m/s], dp [rad/s], dr [rad/s], dgamma [rad])."""
    return (x_plus[0] * u_m_per_s, x_plus[1] * n_hz, x_plus[2] * n_hz, float(x_plus[3]))


def plant_scales(parameters: Mapping[str, float]) -> tuple[float, ...]:
    """[U, n, n, 1] from a plant's parameter values ``U`` [m/s] and ``n`` [Hz].

    ``parameters`` is any mapping that holds them, e.g. the start values of a
    plant FMU's model description. Raises :class:`DroneflyError` if one is
    missing or not a finite positive number.
    """
    out = {}
    for name in ("n", "U"):
        value = parameters.get(name)
        if value is None:
            raise DroneflyError(f"the plant has no parameter {name!r}: its reference scales "
                                "(U [m/s], n [Hz]) are needed to read its state as x+")
        value = float(value)
        if not (math.isfinite(value) and value > 0.0):
            raise DroneflyError(f"{name} = {value!r} must be finite and > 0")
        out[name] = value
    return scale_vector(out["U"], out["n"])


def eigen_order(values: Sequence[complex]) -> list[int]:
    """Indices that put eigenvalues in the order of every table: descending real part,
    then descending imaginary part."""
    return sorted(range(len(values)), key=lambda i: (-complex(values[i]).real,
                                                     -complex(values[i]).imag))


def sort_eigenvalues(values: Iterable[complex]) -> list[complex]:
    """Eigenvalues in the order of :func:`eigen_order`."""
    v = [complex(z) for z in values]
    return [v[i] for i in eigen_order(v)]


_PARAM_TEXT = {
    "m_plus": "non-dimensional mass m/(0.5 rho U S_t t_w)",
    "Ix_plus": "non-dimensional roll inertia",
    "Iz_plus": "non-dimensional yaw inertia",
    "Ixz_plus": "non-dimensional product of inertia",
    "g_plus": "non-dimensional gravity g t_w/U",
}


def parameter_description(name: str) -> str:
    """Description of a lateral model parameter (``m_plus``, ``Yv_plus``, ``L_Phi_a_plus``, ...)."""
    if name in _PARAM_TEXT:
        return _PARAM_TEXT[name]
    force, rest = name[0], name[1:-len("_plus")]
    what = {"Y": "side force", "L": "roll moment", "N": "yaw moment"}[force]
    if rest.startswith("_"):
        return f"control derivative of {what} w.r.t. delta{rest} (Table 1)"
    return f"stability derivative of {what} w.r.t. delta {rest}+ (from Eq. 12)"
