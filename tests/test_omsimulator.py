"""The native FMUs in OMSimulator, a C++ FMI host with no Python inside (../shared/tools/omsimulator,
built from OpenModelica's v3.0 sources; its README says what it does).

- Its command line runs every native FMU (FMI 2.0 and 3.0) and the native closed-loop container,
  with ``LD_PRELOAD``, ``PYTHONHOME`` and ``PYTHONPATH`` unset: exit 0, no error in its log but
  the one named below, and the numbers of FMPy's run of the same FMU (each FMU alone) or of the
  pythonfmu loop of ``dronefly cosim`` (the container).
- Its Python API runs the closed-loop SSP of the native FMUs, FMI 2.0 and 3.0, in a child
  process (a crash in it cannot take the test run along), equal to the same loop.

OMSimulator writes its CSV with 12 significant digits: a printed value is within 5e-12 of its
magnitude, so a column agrees to 1e-11 of its peak where the runs agree to round-off.

Two limits of this OMSimulator build, seen with the pythonfmu FMUs too or traced to the host:
- FMI 3.0 arrays: it cannot address an element of an array parameter (an SSV's ``K[1,1]``:
  "Unknown signal", then a segmentation fault), so the FMI 3.0 SSP is run with the controller's
  K bindings dropped, after checking that they equal the FMU's own start values (the same
  system). Fetching the plants' calculated array parameters ``A`` (4 x 4) and ``B`` (4 x 3)
  for its result file, it asks for one value each (nValues = 1, traced in a debug build of the
  FMU); the native FMU refuses the call, as FMI 3.0 says (nValues counts every element), and
  OMSimulator logs "failed to fetch variable B" and writes no result row at all. The
  pythonfmu3 FMUs answer one value and pass. The SSP run leaves A and B out of the result
  file (``removeSignalsFromResults``); the command line has no such option, but it runs a Lua
  script (OMSimulator's own scripting, inside its binary: no Python) that does the same, so the
  FMI 3.0 plants run there through one (:func:`_lua_run`), and the refusal stays.
- The Python API's SSP run uses OMSimulator's default step (1e-3 s) unless told: the test sets
  the SSP's 0.1 wing beat.
"""

from __future__ import annotations

import csv
import io
import json
import os
import re
import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest

from dronefly.harness.builder import native
from dronefly.harness.builder.closedloop import write_ssp
from dronefly.harness.builder.toolchain import find_toolchain, host_platform, missing_reason
from dronefly.harness.cosim.fmu import FMU
from dronefly.harness.cosim.master import Loop
from shared_files import ON_CI

pytestmark = pytest.mark.integration

REPO = Path(__file__).resolve().parents[1]
OMS = REPO.parent / "shared" / "tools" / "omsimulator"
OMS_EXE = OMS / "bin" / "OMSimulator"
OMS_PY = OMS / "lib" / "x86_64-linux-gnu"
H = 0.1 / 164.0  # 0.1 wing beat, s
N = 300
STATES = ("delta_v", "delta_p", "delta_r", "delta_gamma")
#: 12 printed significant digits (5e-12 of the value) plus the native/pythonfmu round-off (1e-12)
TOL_PRINTED = 1e-11
#: the one error line an FMI 3.0 run may log (the module text says why)
_ARRAY_FETCH = re.compile(r"^error:\s+\[updateSignals\] failed to fetch variable B$")

if not (sys.platform.startswith("linux") and host_platform("2.0") == "linux64"):
    pytest.skip("the OMSimulator build is for Linux x86_64", allow_module_level=True)
if not OMS_EXE.is_file():
    if ON_CI:  # the CI layout provides ../shared: a missing build there is a failure
        pytest.fail(f"no OMSimulator build at {OMS}: the CI layout provides ../shared",
                    pytrace=False)
    pytest.skip(f"no OMSimulator build at {OMS} (the shared tools folder beside the checkout)",
                allow_module_level=True)


def _no_python_env() -> dict[str, str]:
    return {k: v for k, v in os.environ.items()
            if k not in ("LD_PRELOAD", "PYTHONHOME", "PYTHONPATH")}


def _read_csv(path: Path) -> tuple[list[str], np.ndarray]:
    """OMSimulator's result: header and rows; a time written twice (before and after an
    event iteration) keeps its last row."""
    rows = list(csv.reader(io.StringIO(path.read_text())))
    header = [h.strip().strip('"') for h in rows[0]]
    data = np.array([[float(x) for x in r] for r in rows[1:] if r])
    if data.size == 0:
        return header, data
    keep = np.append(data[1:, 0] != data[:-1, 0], True)
    return header, data[keep]


def _rel_dev(a: np.ndarray, b: np.ndarray) -> float:
    peak = np.maximum(np.abs(b).max(axis=0), 1e-300)
    return float(np.max(np.abs(a - b) / peak))


#: the native FMU's logged answer to that fetch (nValues = 1 for an array): its refusal, named
_ARRAY_REFUSED = re.compile(r"^error:\s+\[fmi3logger\] \[fmi3Error\] .*fmi3GetFloat64: "
                            r"nValues = 1 is fewer than the values of the 1 value references")


def _errors(log: str, fmi: int) -> list[str]:
    lines = [ln.rstrip() for ln in log.splitlines() if ln.startswith("error")]
    return [ln for ln in lines
            if not (fmi == 3 and (_ARRAY_FETCH.match(ln) or _ARRAY_REFUSED.match(ln)))]


@pytest.fixture(scope="module")
def natives(tmp_path_factory):
    """Every native FMU, FMI 2.0 and 3.0, and the native container: {(name, fmi): path}."""
    tc = find_toolchain("linux64")
    assert tc is not None, missing_reason("linux64")
    out = tmp_path_factory.mktemp("native")
    fmus = {}
    for fmi, where in ((2, out), (3, out / "fmi3")):
        paths, platforms = native.build_native_all(where, fmi, tc, (host_platform(f"{fmi}.0"),))
        assert platforms == (host_platform(f"{fmi}.0"),)
        fmus.update({(p.stem, fmi): p for p in paths})
    fmus["DroneFlyClosedLoop", 2] = native.build_native_container(out)
    return fmus


def _oms(args: list[str], cwd: Path) -> subprocess.CompletedProcess:
    return subprocess.run([str(OMS_EXE), *args, f"--tempDir={cwd}"], cwd=cwd,
                          env=_no_python_env(), capture_output=True, text=True, timeout=120)


def _lua_run(path: Path, leave_out: list[str], stop: float, step: float,
             cwd: Path) -> tuple[subprocess.CompletedProcess, list[str], np.ndarray]:
    """The command line on a Lua script that runs the FMU as the plain command line does (one
    FMU, a fixed step, no event rows) with the variables ``leave_out`` left out of the result
    file (``oms_removeSignalsFromResults``, an anchored regular expression per name): the run,
    and the result's header (variable names) and rows."""
    result = cwd / "lua.csv"
    q = json.dumps  # a Lua string literal for these ASCII paths and names
    lines = ['oms_setCommandLineOption("--suppressPath=true --emitEvents=false")',
             f"oms_setTempDirectory({q(str(cwd))})", 'oms_newModel("model")',
             'oms_addSystem("model.root", oms_system_wc)',
             f'oms_addSubModel("model.root.fmu", {q(str(path))})',
             f'oms_setResultFile("model", {q(str(result))})']
    prefix = re.escape("model.root.fmu.")
    lines += [f'oms_removeSignalsFromResults("model", {q(f"^{prefix}{re.escape(n)}$")})'
              for n in leave_out]
    lines += [f'oms_setStopTime("model", {stop!r})',
              f'oms_setFixedStepSize("model.root", {step!r})',
              'oms_instantiate("model")', 'oms_initialize("model")', 'oms_simulate("model")',
              'oms_terminate("model")', 'oms_delete("model")']
    script = cwd / "run.lua"
    script.write_text("\n".join(lines) + "\n")
    r = _oms([str(script)], cwd)
    header, rows = _read_csv(result) if result.exists() else ([], np.zeros((0, 0)))
    return r, [h.removeprefix("model.root.fmu.") for h in header], rows


@pytest.mark.parametrize("fmi", [2, 3])
@pytest.mark.parametrize("name", list(native.NATIVE_FMUS))
def test_every_native_fmu_runs_in_the_command_line(natives, tmp_path, name, fmi):
    """Each FMU alone, 50 communication steps of its default step (0.1 wing beat where it has
    none), inputs at their start values; the outputs equal FMPy's run of the same FMU."""
    import fmpy

    assert {n for (n, v) in natives if v == fmi} == set(native.NATIVE_FMUS) | (
        {"DroneFlyClosedLoop"} if fmi == 2 else set())
    path = natives[name, fmi]
    md = fmpy.read_model_description(str(path))
    step = float(md.defaultExperiment.stepSize) if md.defaultExperiment and \
        md.defaultExperiment.stepSize else H
    stop = 50 * step
    result = tmp_path / f"{name}_{fmi}.csv"
    r = _oms([str(path), f"--stopTime={stop!r}", f"--stepSize={step!r}",
              f"--resultFile={result}"], tmp_path)
    assert r.returncode == 0, f"exit {r.returncode}\n{r.stdout[-3000:]}"
    assert not _errors(r.stdout + r.stderr, fmi), r.stdout[-3000:]
    header, rows = _read_csv(result)
    if fmi == 3 and rows.size == 0:
        arrays = sorted(v.name for v in md.modelVariables
                        if v.dimensions and v.causality == "calculatedParameter")
        assert arrays == ["A", "B"] and "failed to fetch variable B" in r.stdout + r.stderr, arrays
        # OMSimulator asks one value of the arrays A and B (nValues = 1), the FMU refuses as
        # FMI 3.0 says, and the command line writes no result row: a Lua script leaves them out
        r, header, rows = _lua_run(path, arrays, stop, step, tmp_path)
        assert r.returncode == 0, f"exit {r.returncode}\n{r.stdout[-3000:]}"
        assert not [ln for ln in (r.stdout + r.stderr).splitlines() if ln.startswith("error")], \
            r.stdout[-3000:]
        assert not set(arrays) & set(header), header
    outputs = [v.name for v in md.modelVariables if v.causality == "output"]
    assert outputs and set(outputs) <= set(header), header
    ref = fmpy.simulate_fmu(str(path), stop_time=stop, output_interval=step, output=outputs)
    assert rows.shape[0] == len(ref) == 51, (rows.shape, len(ref))
    np.testing.assert_allclose(rows[:, 0], ref["time"], rtol=0, atol=1e-12)
    got = rows[:, [header.index(o) for o in outputs]]
    want = np.column_stack([ref[o] for o in outputs])
    assert _rel_dev(got, want) <= TOL_PRINTED


@pytest.fixture(scope="module")
def cosim_loop(built_fmus):
    """``dronefly cosim``'s loop of the pythonfmu pair (Gauss-Seidel), from x0 = (0, 0, 0, 0.1),
    the container's and the SSP's start."""
    with FMU(built_fmus["DroneFlyLateral"]) as p, FMU(built_fmus["StateFeedback"]) as c:
        return Loop(p, c).run(H, N, master="gauss-seidel",
                              plant_start={"delta_gamma_start": 0.1})


def test_the_native_container_runs_in_the_command_line(natives, cosim_loop, tmp_path):
    result = tmp_path / "loop.csv"
    r = _oms([str(natives["DroneFlyClosedLoop", 2]), f"--stopTime={N * H!r}",
              f"--stepSize={H!r}", f"--resultFile={result}"], tmp_path)
    assert r.returncode == 0, r.stdout[-3000:]
    assert not _errors(r.stdout + r.stderr, 2), r.stdout[-3000:]
    header, rows = _read_csv(result)
    assert rows.shape[0] == N + 1
    np.testing.assert_allclose(rows[0, [header.index(s) for s in STATES]], [0, 0, 0, 0.1])
    got = rows[:, [header.index(s) for s in STATES]]
    assert _rel_dev(got, cosim_loop.signals[:, :4]) <= TOL_PRINTED


_SSP_RUN = """
import json, sys
import OMSimulator as oms
path, out, stop, step, options, drop = json.loads(sys.argv[1])
for option in options:
    oms.Capi.setCommandLineOption(option)
inst = oms.SSP(path).instantiate()
inst.setResultFile(out)
inst.setStopTime(stop)
inst.setFixedStepSize(step)
for regex in drop:
    oms.Capi.removeSignalsFromResults("model", regex)
inst.initialize()
inst.simulate()
inst.terminate()
inst.delete()
print("done")
"""


@pytest.mark.parametrize("fmi", [2, 3])
def test_the_native_ssp_runs_through_the_python_api(natives, cosim_loop, tmp_path, fmi):
    import lxml  # noqa: F401  (OMSimulator's Python API needs it; the test extra installs it)

    ssp = write_ssp(natives["DroneFlyLateral", fmi], natives["StateFeedback", fmi], tmp_path)
    if fmi == 3:  # SSP 1.0 binds scalars: the array K keeps its start values, the paper's gains
        with zipfile.ZipFile(ssp) as z:
            assert "K[" not in z.read("resources/controller.ssv").decode()
    result = tmp_path / "ssp.csv"
    # TMPDIR: OMSimulator's Python API leaves two temporary folders of its own per run
    env = {**os.environ, "PYTHONPATH": str(OMS_PY), "TMPDIR": str(tmp_path)}
    # FMI 3.0: OMSimulator reads dependencies from "InitialUnknowns" (FMI 3.0 says
    # "InitialUnknown") and invents an algebraic loop (its README's workaround), and it cannot
    # fetch the arrays A and B for its result file (the module text): they are left out of it
    # (its regular expression matches a whole signal name)
    options, drop = (["--algLoopSolver=fixedpoint"], [".*(A|B)"]) \
        if fmi == 3 else ([], [])
    job = json.dumps([str(ssp), str(result), N * H, H, options, drop])
    r = subprocess.run([sys.executable, "-c", _SSP_RUN, job], cwd=tmp_path, env=env,
                       capture_output=True, text=True, timeout=180)
    assert r.returncode == 0 and "done" in r.stdout.splitlines(), r.stdout[-3000:] + r.stderr
    assert not _errors(r.stdout + r.stderr, fmi), r.stdout[-3000:]
    header, rows = _read_csv(result)
    assert rows.shape[0] == N + 1
    cols = [header.index(f"DroneFlyClosedLoop.plant.{s}") for s in STATES]
    assert _rel_dev(rows[:, cols], cosim_loop.signals[:, :4]) <= TOL_PRINTED
