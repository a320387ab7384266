"""The wing and its options: the names of the state, controls and loads, the Sect. 2.4 body
data, the non-dimensional geometry (:class:`WingGeometry`), the translational coefficient sets
(:data:`COEFFICIENT_SETS`) and the force terms (:class:`Terms`)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable, Mapping

import numpy as np
from numpy.typing import NDArray

from ..lateral_interface import FLIGHT_DATA, reference_scales

__all__ = ["BODY_DATA", "COEFFICIENT_SETS", "CONTROLS", "FORCES", "STATES", "Array",
           "CoefficientSet", "Terms", "WingGeometry"]

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


