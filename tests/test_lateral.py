"""The lateral interface module: one home for names, units, scales and eigenvalue order."""

from __future__ import annotations

import ast
import math

import numpy as np
import pytest

from dronefly.models import lateral_interface
from dronefly.harness.builder.build import fmu_sources
from dronefly.controller.slave import StateFeedback
from dronefly.fmu_src.lateral.slave import DroneFlyLateral

pytestmark = pytest.mark.numeric  # also run under a second BLAS kernel (.ci/run)


def test_reference_scales_from_flight_data():
    # U = 2 Phi n r2 (Sect. 2.4), computed here from the printed flight data
    d = lateral_interface.FLIGHT_DATA
    U = 2 * d["Phi_deg"] * math.pi / 180 * d["n"] * d["r2_over_R"] * d["R"]
    assert lateral_interface.U_M_PER_S == pytest.approx(U, rel=1e-15)
    assert lateral_interface.N_HZ == d["n"]


def test_scale_vector_round_trip():
    x = (0.3, -12.0, 4.5, 0.1)
    xp = lateral_interface.to_nondimensional(x, 3.7, 164.0)
    assert xp == pytest.approx((0.3 / 3.7, -12.0 / 164.0, 4.5 / 164.0, 0.1), rel=1e-15)
    assert lateral_interface.to_dimensional(xp, 3.7, 164.0) == pytest.approx(x, rel=1e-15)
    assert np.allclose(np.array(xp) * lateral_interface.scale_vector(3.7, 164.0), x, rtol=1e-15)


def test_sort_eigenvalues_matches_lexsort():
    rng = np.random.default_rng(1)
    ev = np.linalg.eigvals(rng.normal(size=(7, 7)))
    ref = ev[np.lexsort((-ev.imag, -ev.real))]
    assert np.array_equal(np.array(lateral_interface.sort_eigenvalues(ev)), ref)


@pytest.mark.parametrize("cls", [DroneFlyLateral, StateFeedback])
def test_slaves_use_the_interface(cls):
    by_name = {v.name: v for v in cls.VARIABLES}
    for name, (unit, disp) in zip(lateral_interface.STATE_NAMES, lateral_interface.STATE_UNITS):
        assert (by_name[name].unit, by_name[name].display_unit) == (unit, disp)
    for name in lateral_interface.CONTROL_NAMES:
        assert (by_name[name].unit, by_name[name].display_unit) == lateral_interface.CONTROL_UNIT
    assert by_name["n"].start == lateral_interface.N_HZ and by_name["U"].start == lateral_interface.U_M_PER_S


def test_controller_fmu_needs_no_numpy_or_scipy():
    """The controller ships names and scales only, not the plant model: plain Python."""
    pkg, files = fmu_sources("StateFeedback")
    imported = set()
    for rel, data in files.items():
        if rel.startswith(f"resources/{pkg}/") and rel.endswith(".py"):
            for node in ast.walk(ast.parse(data)):
                if isinstance(node, ast.Import):
                    imported |= {a.name.split(".")[0] for a in node.names}
                elif isinstance(node, ast.ImportFrom) and not node.level:
                    imported.add((node.module or "").split(".")[0])
    assert not imported & {"numpy", "scipy"}, imported
    assert not any("fmu_src/" in rel or "_dynamics" in rel for rel in files)
