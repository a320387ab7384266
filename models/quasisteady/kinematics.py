"""The wings' motion: the controls by name, each wing's stroke and pitch angles from the
controls and the trim (:func:`wing_kinematics`), their time histories over the cycle
(:func:`stroke`, :func:`pitch`) and the frames and element positions at the cycle's samples
(:func:`sampled_motion`); the cross product of the frames' vectors (:func:`cross`)."""

from __future__ import annotations

import math
from typing import Mapping, Sequence

import numpy as np

from ...core.errors import DroneflyError
from .trim import Trim
from .wing import CONTROLS, Array, WingGeometry

__all__ = ["SIDE", "controls_by_name", "cross", "named", "pitch", "rotation_profile",
           "sampled_motion", "stroke", "wing_kinematics"]

#: the wings' sides (left, right): the left wing mirrors the right in y
SIDE = np.array([-1.0, 1.0])
_NEXT, _AFTER = np.array([1, 2, 0]), np.array([2, 0, 1])


def cross(a: Array, b: Array) -> Array:
    """Cross product along the last axis of two arrays (..., 3), broadcast: component i is
    a_j b_k - a_k b_j, (i, j, k) the cyclic permutations of (0, 1, 2)."""
    return a[..., _NEXT] * b[..., _AFTER] - a[..., _AFTER] * b[..., _NEXT]


def named(values: Mapping[str, float] | None, names: Sequence[str], what: str) -> dict[str, float]:
    """``values`` by name over ``names`` (0 where not named), each a finite float; a name not
    among ``names`` or a value that is not finite is refused naming it (``what``: the kind)."""
    out = {n: 0.0 for n in names}
    for key, value in (values or {}).items():
        if key not in out:
            raise DroneflyError(f"{what} {key!r}: expected one of {', '.join(names)}")
        v = float(value)
        if not math.isfinite(v):
            raise DroneflyError(f"{what} {key} = {value!r} is not finite")
        out[key] = v
    return out


def controls_by_name(control: Mapping[str, float] | None) -> dict[str, float]:
    """The seven control increments [rad] by name (:data:`CONTROLS`), 0 where not named."""
    return named(control, CONTROLS, "control")


def rotation_profile(t: Array, start: float, duration: float) -> tuple[Array, Array, Array]:
    """tau - sin(2 pi tau)/(2 pi) and its first two derivatives in t, 0/1 outside."""
    tau = np.mod(t - start, 1.0) / duration
    inside = tau < 1.0
    tau_c = np.where(inside, tau, 1.0)
    f = tau_c - np.sin(2 * np.pi * tau_c) / (2 * np.pi)
    df = np.where(inside, (1.0 - np.cos(2 * np.pi * tau_c)) / duration, 0.0)
    ddf = np.where(inside, 2 * np.pi * np.sin(2 * np.pi * tau_c) / duration**2, 0.0)
    return f, df, ddf


def stroke(t: Array, Phi: Array, phibar: Array) -> tuple[Array, Array]:
    """The stroke angle phi [rad] and its rate dphi/dt+ [rad per wing beat] of each wing (rows)
    at the phases ``t`` (columns): phi = phibar - (Phi/2) cos(2 pi t+)."""
    phi = phibar[:, None] - 0.5 * Phi[:, None] * np.cos(2 * np.pi * t)  # (2, T)
    dphi = np.pi * Phi[:, None] * np.sin(2 * np.pi * t)
    return phi, dphi


def pitch(t: Array, rotation_fraction: float, alpha_d: Array,
          alpha_u: Array) -> tuple[Array, Array, Array]:
    """psi [rad], dpsi/dt+, d2psi/dt+2 for each wing (rows) at the phases ``t`` (columns)."""
    dr = rotation_fraction
    ad, au = alpha_d[:, None], alpha_u[:, None]
    up_psi = np.pi - au
    if dr == 0.0:  # an instantaneous flip at the reversals (t+ = 0 and 0.5, between samples)
        psi = np.where(t < 0.5, ad, up_psi)
        return psi, np.zeros_like(psi), np.zeros_like(psi)
    f1, d1, dd1 = rotation_profile(t, 0.5 - dr / 2, dr)  # end of downstroke
    f2, d2, dd2 = rotation_profile(t, 1.0 - dr / 2, dr)  # end of upstroke
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


def wing_kinematics(geometry: WingGeometry, trim: Trim,
                    control: Mapping[str, float] | None = None) -> dict[str, Array]:
    """Per-wing (left, right) stroke amplitude ``Phi``, mean stroke angle ``phibar`` and angles
    of attack ``alpha_d``, ``alpha_u`` [rad]: the trim's plus the control increments [rad] by
    name (:data:`CONTROLS`; unnamed ones are 0), the lateral ones split between the wings
    (Sect. 2.1)."""
    u = controls_by_name(control)
    tr = trim
    side = SIDE  # left, right; lateral controls add +d/2 on the left
    Phi = geometry.Phi_rad + u["delta_Phi"] - side * u["delta_Phi_a"] / 2
    phibar = tr.phibar + u["delta_phibar"] + 0.0 * side
    ad = (tr.alpha_d + u["delta_alpha_1"] + u["delta_alpha_2"] / 2
          - side * (u["delta_alpha_1a"] + u["delta_alpha_2a"]) / 2)
    au = (tr.alpha_u + u["delta_alpha_1"] - u["delta_alpha_2"] / 2
          - side * (u["delta_alpha_1a"] - u["delta_alpha_2a"]) / 2)
    return {"Phi": Phi, "phibar": phibar, "alpha_d": ad, "alpha_u": au}


def sampled_motion(geometry: WingGeometry, r: Array, t: Array, Phi: Array, phibar: Array,
                   alpha_d: Array, alpha_u: Array) -> dict[str, Array]:
    """The body-motion-free part of the wing motion at the samples ``t`` of the cycle, by
    components, each an array (wing, time, element): the span and stroke directions e_r, e_t
    (x, y), the pitch's cosine, sine and rate, the wing's side, the elements' positions from
    the centre of mass [c] and their flapping speed [U] (``r`` the elements' span positions)."""
    g = geometry
    side = SIDE[:, None]
    phi, dphi = stroke(t, Phi, phibar)
    psi, dpsi, _ = pitch(t, g.rotation_fraction, alpha_d, alpha_u)
    sphi, cphi = np.sin(phi), np.cos(phi)
    cpsi, spsi = np.cos(psi), np.sin(psi)
    r = r[None, None, :]
    return {
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
