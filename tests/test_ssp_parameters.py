"""Every SSP the build writes loads in a strict importer: each SSV
parameter names a variable of its FMU, in FMI 2.0 and 3.0 alike, and OMSimulator (a native
SSP importer, ../shared/tools/omsimulator) runs the closed loops as our master does."""

from __future__ import annotations

import io
import os
import platform
import subprocess
import sys
import textwrap
import zipfile
from pathlib import Path
from xml.etree import ElementTree as ET

import numpy as np
import pytest
from shared_files import need_shared

ROOT = Path(__file__).resolve().parents[1]
OMS = ROOT.parent / "shared" / "tools" / "omsimulator"
OMS_PY = OMS / "lib" / "x86_64-linux-gnu"
SSPS = ("DroneFlyClosedLoop.ssp", "DroneFlyHover.ssp", "DroneFlyHover6DOF.ssp")


def _local(tag: str) -> str:
    return tag.rsplit("}", 1)[-1]


def ssv_parameters(ssp: Path) -> list[tuple[str, str, set[str]]]:
    """(component, SSV parameter name, the names of the FMU's variables) of every parameter
    an SSP binds, read from the archive's own XML (the FMU's modelDescription.xml as written,
    FMI 2.0 ScalarVariables or FMI 3.0 variables, no view of ours in between)."""
    out = []
    with zipfile.ZipFile(ssp) as z:
        ssd = ET.fromstring(z.read("SystemStructure.ssd"))
        for comp in ssd.iter():
            if _local(comp.tag) != "Component":
                continue
            with zipfile.ZipFile(io.BytesIO(z.read(comp.get("source")))) as fmu:
                md = ET.fromstring(fmu.read("modelDescription.xml"))
            names = {v.get("name") for v in md.iter()
                     if v.get("valueReference") is not None and v.get("name")}
            for binding in comp.iter():
                if _local(binding.tag) != "ParameterBinding":
                    continue
                values = (ET.fromstring(z.read(binding.get("source")))
                          if binding.get("source") else binding)
                out += [(comp.get("name"), p.get("name"), names) for p in values.iter()
                        if _local(p.tag) == "Parameter"]
    return out


@pytest.mark.parametrize("fmi", [2, 3])
@pytest.mark.parametrize("name", SSPS)
def test_every_ssv_parameter_names_a_variable_of_its_fmu(built_fmus, built_fmus3, fmi, name):
    ssp = (built_fmus if fmi == 2 else built_fmus3)[name]
    params = ssv_parameters(ssp)
    assert params, f"{name} binds no parameter"
    wrong = [f"{comp}.{p}" for comp, p, names in params if p not in names]
    assert wrong == [], f"{ssp}: SSV parameters that name no variable of their FMU: {wrong}"


def test_fmi3_closed_loop_with_other_gains_is_refused(built_fmus3, tmp_path):
    """SSP 1.0 binds scalars only: gains other than the FMI 3.0 controller's start values of
    its array K cannot be written into an SSV, so the SSP is refused, not written wrong."""
    from dronefly.harness.builder.closedloop import ClosedLoopSpec, write_ssp
    from dronefly.harness.cosim.master import CoSimError
    from dronefly.models.feedback import default_gains

    gains = [list(row) for row in default_gains()]
    gains[0][1] = -0.25
    with pytest.raises(CoSimError, match=r"controller.K\[1,2\] = -0.25: .* SSP 1.0 binds"):
        write_ssp(built_fmus3["DroneFlyLateral"], built_fmus3["StateFeedback"], tmp_path,
                  ClosedLoopSpec(gains=tuple(map(tuple, gains))))
    assert not list(tmp_path.iterdir())


_OMS_RUN = textwrap.dedent("""
    import sys
    from OMSimulator import SSP
    from OMSimulator.capi import Capi
    # its FMI 3.0 importer reads InitialUnknowns (FMI 3.0: InitialUnknown) and so invents
    # algebraic loops; the fixed-point solver works around it (its README)
    Capi.setCommandLineOption("--algLoopSolver=fixedpoint")
    model = SSP(sys.argv[1]).instantiate()
    model.setResultFile(sys.argv[2])
    model.setStopTime(float(sys.argv[3]))
    model.setFixedStepSize(float(sys.argv[4]))
    model.initialize()
    model.simulate()
    model.terminate()
    model.delete()
""")


def _oms_missing() -> str | None:
    if not (OMS_PY / "OMSimulator").is_dir():
        if sys.platform.startswith("linux") and platform.machine() == "x86_64":
            # the build in ../shared is for this platform: CI provides it (an error there)
            need_shared(OMS_PY / "OMSimulator", "OMSimulator's native build")
        return f"no OMSimulator build for {sys.platform}/{platform.machine()} (../shared " \
               "holds a Linux x86_64 one)"
    try:
        import lxml  # noqa: F401  (its Python API needs it)
    except ImportError:
        return "OMSimulator's Python API needs lxml (pip install lxml)"
    return None


@pytest.mark.integration
@pytest.mark.parametrize("fmi", [2, 3])
def test_omsimulator_runs_the_closed_loop_ssp_as_our_master(built_fmus, built_fmus3, fmi,
                                                             tmp_path):
    """OMSimulator loads build/(fmi3/)DroneFlyClosedLoop.ssp with its SSV bindings and runs 10
    wing beats; its states agree with `cosim --system` on the same SSP (both hold the control
    over each step of 0.1 wing beat and the plant steps by the matrix exponential: 1e-12)."""
    why = _oms_missing()
    if why:
        pytest.skip(why)
    from dronefly.harness.stability.system_verdicts import cosimulate_system

    ssp = (built_fmus if fmi == 2 else built_fmus3)["DroneFlyClosedLoop.ssp"]
    ours = cosimulate_system(ssp, stop_wingbeats=10, out_dir=None, plot=False, verdicts=False)
    step_s = float(ours.run.time[1] - ours.run.time[0])
    stop_s = float(ours.run.time[-1])
    csv = tmp_path / "oms.csv"
    # TMPDIR: OMSimulator's Python API leaves two temporary folders of its own per run
    env = {**os.environ, "PYTHONPATH": str(OMS_PY), "TMPDIR": str(tmp_path)}
    r = subprocess.run([sys.executable, "-c", _OMS_RUN, str(ssp), str(csv), repr(stop_s),
                        repr(step_s)], cwd=tmp_path, env=env, capture_output=True, text=True,
                       timeout=120)
    assert r.returncode == 0, r.stdout[-2000:] + r.stderr[-2000:]
    header = [h.strip().strip('"') for h in csv.read_text().splitlines()[0].split(",")]
    data = np.loadtxt(csv, delimiter=",", skiprows=1, ndmin=2)
    last = data[-1]
    assert last[0] == pytest.approx(stop_s, abs=1e-9)
    for state in ("delta_v", "delta_p", "delta_r", "delta_gamma"):
        col = next(i for i, h in enumerate(header) if h.endswith(f".plant.{state}"))
        mine = ours.run.column(f"plant.{state}")[-1]
        assert last[col] == pytest.approx(mine, rel=1e-9, abs=1e-12), state
