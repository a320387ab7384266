"""Reference results (FMI cross-check rules): <Model>_in.csv, _ref.opt, _ref.csv per FMU folder."""

from __future__ import annotations

import shutil

import numpy as np
import pytest

from dronefly.harness.compliance.reference import REFERENCES, check_reference, reference_paths

pytestmark = pytest.mark.integration


@pytest.mark.parametrize("model", sorted(REFERENCES))
def test_reference_reproduces(built_fmus, model):
    """fmpy's cross-check band: no outliers; and, both FMUs being exact, equal to 1e-9 relative."""
    check = check_reference(model, built_fmus[model])
    assert check.cross_check_outliers == 0.0
    assert check.max_rel_error <= 1e-9, check


@pytest.mark.parametrize("model", sorted(REFERENCES))
def test_reference_files_follow_cross_check_rules(model):
    from fmpy.util import read_csv, read_ref_opt_file

    inp, opt, ref = reference_paths(model)
    opts = read_ref_opt_file(str(opt))
    data = read_csv(str(ref))
    assert data["time"][0] == opts["StartTime"]
    assert data["time"][-1] == pytest.approx(opts["StopTime"], rel=1e-12)
    assert np.allclose(np.diff(data["time"]), opts["StepSize"], rtol=1e-9)
    assert list(data.dtype.names[1:]) == list(REFERENCES[model].outputs)
    assert max(np.ptp(data[n]) for n in data.dtype.names[1:]) > 0, \
        "the reference exercises the model"
    if REFERENCES[model].inputs(data["time"]):
        assert read_csv(str(inp)).shape == data.shape
    else:
        assert not inp.exists(), "no _in.csv for a model without inputs"


def test_a_wrong_reference_is_detected(built_fmus, tmp_path):
    """The comparison can fail: a reference whose delta_gamma is 1.5 times the true value from
    row 100 on (far outside fmpy's cross-check band) is reported."""
    model = "DroneFlyLateral"
    for p in reference_paths(model):
        shutil.copy(p, tmp_path / p.name)
    ref = tmp_path / f"{model}_ref.csv"
    lines = ref.read_text().splitlines()
    head, rows = lines[0], [r.split(",") for r in lines[1:]]
    for r in rows[100:]:
        r[4] = repr(float(r[4]) * 1.5)
    ref.write_text("\n".join([head, *(",".join(r) for r in rows)]) + "\n")
    check = check_reference(model, built_fmus[model], folder=tmp_path)
    assert check.cross_check_outliers > 0 and not check.passed
