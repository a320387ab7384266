"""Independent oracles for the axes' interfaces (models/lateral_interface.py,
models/longitudinal_interface.py), written for mutation testing (docs/mutation.md): a plant's
reference scales read from its parameters, the descriptions of the plants' parameters (the
FMUs' model descriptions are made of them), and the order of eigenvalues in every table.
Oracles: the paper's naming of the derivatives (Sect. 2.1: Y, L, N the side force, roll and
yaw moments; Sect. 3.5: X, Z, M the x-force, z-force and pitch moment) applied to the
parameters' own names, and orders written out by hand."""

from __future__ import annotations

import dataclasses
import math
import re
from pathlib import Path

import pytest

from dronefly.core.errors import DroneflyError
from dronefly.models import lateral_dynamics, longitudinal_dynamics
from dronefly.models import lateral_interface, longitudinal_interface
from shared_files import need_shared

PAPER = Path(__file__).resolve().parents[1].parent / "shared" / "paper" / \
    "zhang-sun-lateral-stabilization-control.md"


# -- plant_scales ----------------------------------------------------------------------------
def test_plant_scales_are_u_n_n_1_of_the_parameters():
    """x = x+ * [U, n, n, 1] (end of Sect. 2.1), from any mapping holding U and n."""
    assert lateral_interface.plant_scales({"U": 2.5, "n": 164, "other": -1.0}) == (
        2.5, 164.0, 164.0, 1.0)
    assert lateral_interface.plant_scales({"U": "3.25", "n": 1e-3}) == (3.25, 1e-3, 1e-3, 1.0)


@pytest.mark.parametrize("bad", [0.0, -0.0, -1.0, -1e-300, math.nan, math.inf, -math.inf])
@pytest.mark.parametrize("name", ["U", "n"])
def test_plant_scales_refuse_a_scale_that_is_not_finite_and_positive(name, bad):
    """A reference scale divides the state (x+ = x / scale): zero, negative, infinite or nan
    is refused, naming the parameter and its value."""
    values = {"U": 2.5, "n": 164.0, name: bad}
    with pytest.raises(DroneflyError) as e:
        lateral_interface.plant_scales(values)
    assert str(e.value) == f"{name} = {float(bad)!r} must be finite and > 0"


@pytest.mark.parametrize("name", ["U", "n"])
def test_plant_scales_name_a_missing_scale(name):
    values = {"U": 2.5, "n": 164.0}
    del values[name]
    with pytest.raises(DroneflyError, match=f"the plant has no parameter '{name}'"):
        lateral_interface.plant_scales(values)


# -- the order of eigenvalues ------------------------------------------------------------------
def test_eigenvalues_go_by_descending_real_then_descending_imaginary_part():
    values = [-0.5 + 0.0j, 0.1 - 0.3j, 0.1 + 0.3j, -0.5 + 2.0j, 0.0, -2.0 - 1.0j, 3.0]
    want = [3.0, 0.1 + 0.3j, 0.1 - 0.3j, 0.0, -0.5 + 2.0j, -0.5 + 0.0j, -2.0 - 1.0j]
    assert lateral_interface.sort_eigenvalues(values) == want
    assert lateral_interface.eigen_order(values) == [6, 2, 1, 4, 3, 0, 5]
    assert lateral_interface.sort_eigenvalues(iter(values)) == want  # any iterable


# -- the parameters' descriptions ----------------------------------------------------------------
_LATERAL_FORCE = {"Y": "side force", "L": "roll moment", "N": "yaw moment"}
_LONGITUDINAL_FORCE = {"X": "the x-force", "Z": "the z-force", "M": "the pitch moment"}


def _derivatives(parameters, forces, states, controls):
    """(name, force, variable, kind) of every derivative parameter: ``F<state>_plus`` a
    stability derivative of force F w.r.t. the state, ``F_<control>_plus`` a control one."""
    out = []
    for f in dataclasses.fields(parameters):
        name = f.name
        if name[0] not in forces or not name.endswith("_plus") or name[1] not in "_uvwpqr":
            continue
        middle = name[1:-5]
        if middle.startswith("_"):
            control = "delta" + middle
            assert control in controls, name
            out.append((name, forces[name[0]], control, "control"))
        else:
            state = "delta_" + middle
            assert state in states, name
            out.append((name, forces[name[0]], f"delta {middle}+", "stability"))
    return out


def test_lateral_parameters_are_described_by_force_and_variable():
    """Each derivative of the lateral plant's parameters (Table 1 and Eq. 12) is described as
    the derivative of its force with respect to its variable, the others (mass, inertias,
    gravity) by what they are: every name of Sect. 2.1."""
    li = lateral_interface
    params = lateral_dynamics.default_parameters()
    derivatives = _derivatives(params, _LATERAL_FORCE, li.STATE_NAMES, li.CONTROL_NAMES)
    assert len(derivatives) == 3 * (4 - 1) + 3 * 3  # v, p, r (gamma has none) and 3 controls
    for name, force, variable, kind in derivatives:
        source = "(Table 1)" if kind == "control" else "(from Eq. 12)"
        assert li.parameter_description(name) == (
            f"{kind} derivative of {force} w.r.t. {variable} {source}"), name
    assert li.parameter_description("m_plus") == "non-dimensional mass m/(0.5 rho U S_t t_w)"
    assert li.parameter_description("g_plus") == "non-dimensional gravity g t_w/U"
    assert li.parameter_description("Ixz_plus") == "non-dimensional product of inertia"


def test_longitudinal_parameters_are_described_by_force_and_variable():
    lo = longitudinal_interface
    params = longitudinal_dynamics.default_parameters()
    derivatives = _derivatives(params, _LONGITUDINAL_FORCE, lo.STATE_NAMES, lo.CONTROL_NAMES)
    assert len(derivatives) == 3 * 3 + 3 * 4  # u, w, q (theta has none) and 4 controls
    for name, force, variable, kind in derivatives:
        source = "(from B, Sect. 3.5)" if kind == "control" else "(from A, Sect. 3.5)"
        assert lo.parameter_description(name) == (
            f"{kind} derivative of {force} w.r.t. {variable} {source}"), name
    assert lo.parameter_description("Iy_plus").startswith("non-dimensional pitch inertia")


def test_the_pitch_inertia_is_made_non_dimensional_as_the_roll_inertia():
    """Iy+ and Ix+ share the divisor 0.5 rho U^2 S_t c t_w^2 (end of Sect. 2.1), so
    Iy+ / Ix+ = Iy / Ix of Sect. 2.4 (1308.5 / 657.7), and the pitch inertia stands to the
    longitudinal plant's IY_PLUS (scaled through the printed Ix+ = 10.00) as Ix+ to 10.00
    (a few roundings: 1e-14)."""
    r = lateral_interface.reference_scales()
    assert r["Iy_plus"] / r["Ix_plus"] == pytest.approx(1308.5 / 657.7, rel=1e-14)
    assert r["Iy_plus"] / longitudinal_interface.IY_PLUS == pytest.approx(r["Ix_plus"] / 10.00,
                                                                           rel=1e-14)


def test_the_linear_validity_bounds_are_the_papers_sentence():
    """Sect. 3.6 (the paper's text, read here): "-0.15 <= dv+, dp+ and dr+ <= 0.15 and
    -0.22 <= dgamma <= 0.22": the bounds of (dv+, dp+, dr+, dgamma), as printed."""
    need_shared(PAPER, "the paper's text")
    text = PAPER.read_text(encoding="utf-8")
    start = text.index("when the state variables are in the range of")
    sentence = text[start:text.index("the control variables", start)]
    printed = [float(x) for x in re.findall(r"-?\d+\.\d+", sentence)]
    assert printed == [-0.15, 0.15, -0.22, 0.22]
    vpr, gamma = printed[1], printed[3]
    assert lateral_interface.STATE_BOUNDS_SECT36 == (vpr, vpr, vpr, gamma)
