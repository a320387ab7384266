"""The systems of FMUs in libcosim, an importer that is not FMPy (FMI Library, its own master),
and in FMPy's own SSP route (not our master either).

libcosim loads ``DroneFlyHover6DOF.ssp`` (the nonlinear plant and both controllers, parameter
values in SSV files) and ``DroneFlyHover.ssp`` itself; its fixed-step master is Jacobi (see
:mod:`dronefly.harness.interop.libcosim`), so its trajectory must equal the system master's
Jacobi run at the same step (whole nanoseconds), and differ from the Gauss-Seidel one.
"""

from __future__ import annotations

import platform
import sys

import numpy as np
import pytest

from dronefly.harness.interop.libcosim import libcosim_available, step_ns
from dronefly.harness.cosim.system import System
from dronefly.harness.cosim.system_master import SystemMaster

pytestmark = pytest.mark.integration


def _libcosim_final(ssp, plant: str, names: list[str], h_ns: int, n: int) -> np.ndarray:
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimObserver import CosimObserver

    ex = CosimExecution.from_ssp_file(str(ssp), h_ns)
    obs = CosimObserver.create_last_value()
    ex.add_observer(obs)
    assert ex.step(n)
    infos = {i.name.decode(): i.index for i in ex.slave_infos()}
    refs = {v.name.decode(): v.reference for v in ex.slave_variables(infos[plant])}
    return np.array(obs.last_real_values(infos[plant], [refs[s] for s in names]))


@pytest.mark.parametrize("ssp_name, plant, names", [
    ("DroneFlyHover6DOF.ssp", "plant",
     ["delta_v", "delta_p", "delta_r", "delta_gamma", "delta_u", "delta_w", "delta_q",
      "delta_theta", "z_earth", "y_earth"]),
    ("DroneFlyHover.ssp", "lateral", ["delta_v", "delta_p", "delta_r", "delta_gamma"]),
])
def test_libcosim_runs_the_hover_systems(built_fmus, ssp_name, plant, names):
    why = libcosim_available()
    if why:
        if sys.platform.startswith("linux") and platform.machine() in ("x86_64", "AMD64") \
                or sys.platform == "win32":
            pytest.fail(f"{why}: libcosimpy has wheels for this platform and the test extra "
                        "installs it")
        pytest.skip(f"{why} (no libcosimpy wheel for {sys.platform}/{platform.machine()})")
    ssp = built_fmus[ssp_name]
    h, n = step_ns(0.1, 164.0), 200
    last = _libcosim_final(ssp, plant, names, h, n)
    runs = {}
    for master in ("jacobi", "gauss-seidel"):
        with SystemMaster(System.from_ssp(ssp), master) as m:
            r = m.run(h * 1e-9, n, record=[f"{plant}.{s}" for s in names])
        assert r.complete
        runs[master] = r.signals[-1]
    scale = np.abs(runs["jacobi"]).max()
    assert scale > 1e-3  # the SSP's initial state was applied
    assert np.max(np.abs(last - runs["jacobi"])) / scale <= 1e-12
    assert np.max(np.abs(last - runs["gauss-seidel"])) / scale > 1e-6  # not Gauss-Seidel


def test_fmpy_ssp_runs_the_nonlinear_system_as_a_drop_in(built_fmus):
    """FMPy's own SSP route (``simulate_ssp``, its Jacobi master) runs DroneFlyHover6DOF.ssp
    as it runs DroneFlyHover.ssp: the same variable names, the SSPs' initial states and gains,
    and over 60 wing beats the lateral states differ by far less than the Sect. 3.6 bounds (the
    linearisation error of a disturbance this small) but do differ (the plant is not linear)."""
    from fmpy.ssp.simulation import simulate_ssp

    from dronefly.harness.interop.ssp import ssp_parameter_set
    from dronefly.harness.sweep.cases import STATE_BOUNDS_SECT36
    from dronefly.models.lateral_interface import N_HZ, U_M_PER_S

    last = {}
    for name, plant in (("DroneFlyHover6DOF.ssp", "plant"), ("DroneFlyHover.ssp", "lateral")):
        ssp = built_fmus[name]
        res = simulate_ssp(str(ssp), stop_time=60 / N_HZ, step_size=0.1 / N_HZ,
                           parameter_set=ssp_parameter_set(ssp))
        last[name] = np.array([res[f"{plant}.{s}"][-1] for s in
                               ("delta_v", "delta_p", "delta_r", "delta_gamma")])
    bounds = np.array(STATE_BOUNDS_SECT36) * [U_M_PER_S, N_HZ, N_HZ, 1.0]  # dimensional
    rel = np.abs(last["DroneFlyHover6DOF.ssp"] - last["DroneFlyHover.ssp"]) / bounds
    assert np.abs(last["DroneFlyHover.ssp"]).max() > 1e-3  # the SSP's initial state was applied
    assert 0.0 < rel.max() < 0.01, rel
