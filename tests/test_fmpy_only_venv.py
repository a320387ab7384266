"""The FMUs in a virtual environment that has only fmpy (which brings numpy, not scipy), as a new
user runs them: ``fmpy.simulate_fmu`` of every FMU that ``dronefly build`` writes, FMI 2.0 and
3.0 (and the FMI 2.0 container FMU holding two of them; the flapping plant, which needs numpy,
with the numpy that fmpy brings), reproduces the reference results in
fmu_*/, controller/ and harness/interop/.

The environment is created once per test session in a temporary folder, as ``pip install
fmpy`` would make it from this environment's packages: links to fmpy and to every distribution
its requirements pull in, nothing else (tests/core_install.py; no scipy, no dronefly-fmu).
"""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

import numpy as np
import pytest
from core_install import make_core_env

from dronefly.harness.compliance.reference import REFERENCES, reference_outputs, reference_paths

pytestmark = pytest.mark.integration

#: run inside the fmpy-only environment: every job of the JSON file given, through fmpy
_RUNNER = r'''
import importlib.util, json, sys
import fmpy
from fmpy.util import read_csv, read_ref_opt_file

jobs = json.load(open(sys.argv[1]))
report = {"scipy": importlib.util.find_spec("scipy") is not None, "fmpy": fmpy.__version__}
for job in jobs:
    opts = read_ref_opt_file(job["opt"])
    inputs = read_csv(job["input"]) if job["input"] else None
    result = fmpy.simulate_fmu(job["fmu"], start_time=opts["StartTime"],
                               stop_time=opts["StopTime"], output_interval=opts["StepSize"],
                               input=inputs, output=job["outputs"])
    json.dump({n: [float(v) for v in result[n]] for n in result.dtype.names},
              open(job["result"], "w"))  # floats exactly (JSON keeps a float's repr)
json.dump(report, open(sys.argv[2], "w"))
'''


@pytest.fixture(scope="session")
def fmpy_only_python(tmp_path_factory) -> Path:
    """The interpreter of a fresh virtual environment with fmpy (and its dependencies) only."""
    python = make_core_env(tmp_path_factory.mktemp("fmpy_only_venv") / "venv", "fmpy") / "python"
    code = ("import importlib.util, sys\n"
            "found = [m for m in ('scipy', 'dronefly', 'pythonfmu') if importlib.util.find_spec(m)]\n"
            "import fmpy, numpy\n"
            "sys.exit(f'more than fmpy: {found}' if found else 0)\n")
    r = subprocess.run([str(python), "-c", code], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr[-2000:]
    return python


def test_every_fmu_reproduces_its_reference_in_an_fmpy_only_venv(
        fmpy_only_python, built_fmus, built_fmus3, tmp_path):
    """Every FMU, FMI 2.0 and 3.0, simulated by fmpy in the fmpy-only environment (no scipy
    there) as its reference's .opt file says, equals the reference CSV to 1e-12 of each output's
    largest value (the references were written when the plants used scipy's matrix
    exponential; the FMUs' own agrees to round-off: measured at most 8.6e-14 of the largest
    output, in the container's closed loop, so 1e-12 leaves a factor 10)."""
    fmus2 = {n for n, p in built_fmus.items() if Path(p).suffix == ".fmu"}
    fmus3 = {n for n, p in built_fmus3.items() if Path(p).suffix == ".fmu"}
    assert set(REFERENCES) == fmus2  # with the container FMU DroneFlyClosedLoop (FMI 2.0 only)
    assert fmus3 == fmus2 - {"DroneFlyClosedLoop"}
    jobs, expected = [], []
    for fmi, fmus, names in ((2, built_fmus, fmus2), (3, built_fmus3, fmus3)):
        for model in sorted(names):  # the flapping plant too: it needs numpy, which fmpy brings
            inp, opt, ref = reference_paths(model)
            result = tmp_path / f"{model}_fmi{fmi}.json"
            jobs.append({"fmu": str(fmus[model]), "input": str(inp) if inp.exists() else None,
                         "opt": str(opt), "outputs": reference_outputs(model, fmus[model]),
                         "result": str(result)})
            expected.append((fmi, model, ref, result))
    job_file, report_file = tmp_path / "jobs.json", tmp_path / "report.json"
    job_file.write_text(json.dumps(jobs))
    runner = tmp_path / "runner.py"
    runner.write_text(_RUNNER)
    r = subprocess.run([str(fmpy_only_python), str(runner), str(job_file), str(report_file)],
                       capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr[-3000:]
    report = json.loads(report_file.read_text())
    assert report["scipy"] is False, "the environment must not have scipy"
    from fmpy.util import read_csv

    for fmi, model, ref, result in expected:
        y, y_ref = json.loads(result.read_text()), read_csv(str(ref))
        assert len(y["time"]) == len(y_ref), (fmi, model)
        np.testing.assert_allclose(y["time"], y_ref["time"], rtol=1e-12, atol=1e-15)
        for name in y_ref.dtype.names[1:]:
            ref_values = np.asarray(y_ref[name], float)  # Boolean flags as 0/1
            scale = max(float(np.max(np.abs(ref_values))), 1e-300)
            worst = float(np.max(np.abs(np.asarray(y[name]) - ref_values))) / scale
            assert worst <= 1e-12, (fmi, model, name, worst)
