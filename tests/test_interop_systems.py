"""The systems of FMUs in libcosim, an importer that is not FMPy (FMI Library, its own master).

libcosim loads ``DroneFlyHover6DOF.ssp`` (the nonlinear plant and both controllers, parameter
values in SSV files) and ``DroneFlyHover.ssp`` itself; its fixed-step master is Jacobi (see
:mod:`dronefly.harness.interop.libcosim`), so its trajectory must equal the system master's
Jacobi run at the same step (whole nanoseconds), and differ from the Gauss-Seidel one.
"""

from __future__ import annotations

import numpy as np
import pytest

from dronefly.harness.interop.libcosim import libcosim_available, step_ns
from dronefly.harness.system.description import System
from dronefly.harness.system.master import SystemMaster

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
        pytest.skip(why)
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
