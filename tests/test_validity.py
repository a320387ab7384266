"""``dronefly sweep --compare``: the nonlinear plant against the linear ones, and docs/validity.md.

Oracles: the same closed loops on the model classes (harness.nonlinear.terms: exact
zero-order hold for the linear loop, the model's own stepping for the nonlinear one) against
the co-simulation through the FMUs; the numbers docs/validity.md quotes, recomputed.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from dronefly.cli import main
from dronefly.harness.nonlinear.terms import linearisation_error, term_errors
from dronefly.harness.sweep.cases import STATE_BOUNDS_SECT36, SweepInputError, SweepSpec, \
    direction_vector
from dronefly.harness.sweep.compare import LONGITUDINAL_AXES, compare_summary
from dronefly.harness.sweep.run import run_sweep

pytestmark = pytest.mark.integration

DOC = (Path(__file__).resolve().parents[1] / "docs" / "validity.md").read_text(encoding="utf-8")
AXES = ("dv", "dp", "dr", "dgamma")


def _pct(x: float) -> str:
    return f"{100 * x:.1f} %"


@pytest.fixture(scope="module")
def systems(built_fmus):
    return built_fmus["DroneFlyHover.ssp"], built_fmus["DroneFlyHover6DOF.ssp"]


def _compare(systems, spec, out, **kw):
    return run_sweep(spec, out, progress_bar=False, plot=False, system=systems[0],
                     compare=systems[1], **kw)


def test_fmus_agree_with_the_model_loops(systems, tmp_path):
    spec = SweepSpec(disturbances=("directions",), directions=("+dp", "-dr", "+dgamma", "+dv"),
                     amplitudes=2, gains=("paper",), steps_wb=(1.0,), stop_wb=60.0)
    r = _compare(systems, spec, tmp_path / "c", workers=1)
    assert r.summary["errors"] == 0
    for row in r.rows:
        x0 = [float(row[f"x0_{a}"]) for a in AXES]
        want = linearisation_error(x0, stop_wb=60.0)
        got = [float(row[f"err_{a}"]) for a in (*AXES, *LONGITUDINAL_AXES)]
        np.testing.assert_allclose(got, want, rtol=1e-8, atol=1e-12)
        assert float(row["err_lateral"]) == pytest.approx(max(want[:4]), rel=1e-8)
    # small lateral disturbances: the longitudinal error is of second order; the lateral one
    # of third (the mirror symmetry y -> -y makes it odd in the disturbance)
    e1, e2 = (linearisation_error(a * np.array([0, 0.15, 0, 0])) for a in (0.1, 0.05))
    assert e1[4:].max() / e2[4:].max() == pytest.approx(4.0, rel=0.1)
    assert e1[:4].max() / e2[:4].max() == pytest.approx(8.0, rel=0.1)


def test_docs_in_box_numbers_through_the_fmus(systems, tmp_path):
    """The in-box cases of the default comparison (its 25-point grid over 3 boxes holds the
    9-point grid over the box; its amplitudes 0.25 .. 3 hold 0.25 .. 1) give the numbers of
    'The answer'."""
    spec = SweepSpec(grid_points=9, amplitudes=4, gains=("paper",), steps_wb=(1.0,),
                     stop_wb=100.0)
    r = _compare(systems, spec, tmp_path / "box", workers=2)
    c = compare_summary(r.rows)
    assert c["in_box_cases"] == c["cases"] == 283
    assert f"Of the {c['in_box_cases']} initial states inside the box, the " \
           f"{c['in_box_staying_cases']} whose" in DOC
    assert f"at most {_pct(c['in_box_staying_max_err_lateral'])} of the bounds" in DOC
    assert f"{100 * c['in_box_fraction_lateral_within_10pct']:.0f} % of the initial states" in DOC
    assert f"up to {100 * c['in_box_max_err_lateral']:.0f} % of\nthe bounds" in DOC
    assert f"up to {1000 * c['in_box_max_altitude_lost_m']:.1f} mm" in DOC
    assert c["in_box_staying_max_err_lateral"] < 0.10 < c["in_box_max_err_lateral"]


def _row(direction: str) -> list[str]:
    line = next(ln for ln in DOC.splitlines() if ln.startswith(f"| {direction} "))
    return [c.strip() for c in line.strip("|").split("|")]


@pytest.mark.parametrize("direction", ["dv", "dp", "dr", "dgamma", "mode1"])
def test_docs_box_edge_table(direction):
    d = f"+{direction}"
    e = linearisation_error(direction_vector(d) * np.array(STATE_BOUNDS_SECT36))
    row = _row(direction)
    err = e[:4].max()
    text = f"{100 * err:.1f} %" if err >= 0.005 else f"{100 * err:.2f} %"
    assert row[1] == text
    assert row[2] == AXES[int(np.argmax(e[:4]))]
    best = None
    for k in range(1, 13):  # amplitudes 0.25 .. 3 box, as the default comparison
        a = k / 4
        if linearisation_error(a * direction_vector(d) * np.array(STATE_BOUNDS_SECT36))[:4].max() \
                > 0.10:
            break
        best = a
    assert row[3] == (f"{best:g} or more" if best == 3.0 else f"{best:g}")
    sink = term_errors(d, 1.0).altitude_lost_m["all"]
    assert row[4] == f"{1000 * sink:.1f} mm"


def test_docs_terms():
    dr, dp = term_errors("+dr"), term_errors("+dp")
    assert dr.first == "gyroscopic" and dp.first == "kinematics"
    assert f"its error is {_pct(dr.lateral['all'])} with all terms and " \
           f"{_pct(dr.lateral['no gyroscopic'])} without the" in DOC
    assert f"({_pct(dp.lateral['kinematics only'])} with every" in DOC
    assert f"({_pct(dp.lateral['all'])} with all terms)" in DOC
    gravity = max(abs(term_errors(d).contributions["gravity"])
                  for d in ("+dv", "+dp", "+dr", "+dgamma", "+mode1"))
    assert gravity <= 0.002 and "by more than 0.2 % of\nthe bounds" in DOC
    pitch = [linearisation_error(direction_vector(d) * np.array(STATE_BOUNDS_SECT36))
             for d in ("+dp", "+dr")]
    worst = max(p[4:].max() for p in pitch)
    assert all(LONGITUDINAL_AXES[int(np.argmax(p[4:]))] == "dtheta" for p in pitch)
    assert f"by {100 * worst:.0f} % of its bound" in DOC
    m = re.search(r"box-edge roll of 0\.22 rad it loses ([0-9.]+) mm", DOC)
    assert m and float(m.group(1)) == round(1000 * term_errors("+dgamma").altitude_lost_m["all"],
                                            1)


def test_compare_needs_a_reference_and_a_matching_folder(systems, tmp_path):
    spec = SweepSpec(disturbances=("directions",), directions=("+dp",), amplitudes=1,
                     gains=("paper",), steps_wb=(1.0,), stop_wb=10.0)
    with pytest.raises(SweepInputError, match="--compare needs --system"):
        run_sweep(spec, tmp_path / "a", compare=systems[1])
    run_sweep(spec, tmp_path / "b", workers=1, progress_bar=False, plot=False,
              system=systems[0])
    with pytest.raises(SweepInputError, match="without --compare"):
        _compare(systems, spec, tmp_path / "b", workers=1)
    with pytest.raises(SweepInputError, match="nobody.x"):
        _compare(systems, spec, tmp_path / "c", workers=1, set_values={"nobody.x": 1.0})


def test_cli_compare(systems, tmp_path, capsys):
    out = tmp_path / "v"
    code = main(["sweep", "--system", str(systems[0]), "--compare", str(systems[1]),
                 "--disturbances", "grid", "--grid", "3", "--slices", "dr:dp", "--stop", "20",
                 "--no-progress", "--out", str(out)])
    text = capsys.readouterr().out
    assert code == 0 and "comparison: 9 cases" in text
    assert (out / "compare_dr_dp.png").stat().st_size > 10_000
    header = (out / "sweep.csv").read_text().splitlines()[0]
    assert header.endswith("err_lateral,err_longitudinal,cmp_peak,cmp_verdict,altitude_lost_m,"
                           "drift_m")


def test_readme_quotes_the_same_answer():
    readme = (Path(__file__).resolve().parents[1] / "README.md").read_text(encoding="utf-8")
    section = readme.split("## Where the linear theory holds", 1)[1].split("\n## ", 1)[0]
    for fragment in re.findall(r"\d+\.\d %|\d+\.\d mm|\d+ % of the pitch", section):
        number = fragment.split()[0]
        assert number in DOC, fragment  # every number of the README's answer is the doc's
