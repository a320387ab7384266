"""``dronefly sweep --compare``: the nonlinear plant against the linear ones, and docs/validity.md.

Oracles: the same closed loops on the model classes (harness.nonlinear.terms: exact
zero-order hold for the linear loop, the model's own stepping for the nonlinear one) against
the co-simulation through the FMUs; the numbers docs/validity.md quotes, recomputed.
"""

from __future__ import annotations

import csv
import re
from pathlib import Path

import numpy as np
import pytest
from docnumbers import NumericText, same_numbers

from dronefly.cli.app import main
from dronefly.harness.validity.terms import line_profile, linearisation_error, term_errors
from dronefly.harness.sweep.cases import (STATE_BOUNDS_SECT36, SweepInputError, SweepSpec,
    direction_vector)
from dronefly.harness.sweep.two_systems import LONGITUDINAL_AXES, compare_summary
from dronefly.harness.sweep.run import run_sweep

pytestmark = [pytest.mark.integration, pytest.mark.numeric]

DOC = (Path(__file__).resolve().parents[1] / "docs" / "validity.md").read_text(encoding="utf-8")
#: the document with its line breaks as spaces (the fragments below do not depend on them),
#: its numbers compared to a unit of their last digit (tests/docnumbers.py)
TEXT = NumericText(DOC)
#: the README's paragraph on the same question: its numbers are checked where they are computed
#: (the in-box and contour numbers below; the altitude in test_cosim_verdicts.py)
README = NumericText((Path(__file__).resolve().parents[1] / "README.md").read_text(
    encoding="utf-8").split("## Where the linear theory holds", 1)[1].split("\n## ", 1)[0])
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
    n, stay = c["in_box_cases"], c["in_box_staying_cases"]
    # every case starts in the box (extent 1): a 9 x 9 grid on each of the 3 slices and
    # 4 amplitudes along each of the 10 directions (+/- the four axes and mode 1), none lost
    assert (len(spec.slices), len(spec.directions)) == (3, 10)
    assert n == c["cases"] == 3 * 9 ** 2 + 10 * 4  # = 283
    assert f"Of the {n} initial states inside the box, the {stay} whose" in TEXT
    assert f"at most {_pct(c['in_box_staying_max_err_lateral'])} of the bounds in the lateral" \
           in TEXT
    assert c["in_box_staying_lateral_within_10pct"] == stay  # "there ... within 10 %"
    lon_ok = c["in_box_staying_longitudinal_within_10pct"]
    assert f"by up to {_pct(c['in_box_staying_max_err_longitudinal'])} of the bounds, and only " \
           f"{lon_ok} of the {stay} are within 10 %" in TEXT
    staying = [row for row in r.rows if row["verdict"] == "within"]
    over = [max(LONGITUDINAL_AXES, key=lambda a: float(row[f"err_{a}"])) for row in staying
            if float(row["err_longitudinal"]) > 0.10]  # the worst longitudinal state of each
    pitch, heave = over.count("dtheta"), over.count("dw")
    assert pitch + heave == len(over) == stay - lon_ok
    assert f"({len(over)} of them exceed 10 %): {pitch} of the {len(over)} in pitch, which the " \
           f"roll and yaw rates drive at second order (below), {heave} in heave." in TEXT
    assert f"{100 * c['in_box_fraction_lateral_within_10pct']:.0f} % of the initial states in " \
           f"the box are within 10 % laterally and " \
           f"{100 * c['in_box_fraction_longitudinal_within_10pct']:.0f} % longitudinally" in TEXT
    assert f"up to {100 * c['in_box_max_err_lateral']:.0f} % of the bounds laterally and " \
           f"{100 * c['in_box_max_err_longitudinal']:.0f} % longitudinally" in TEXT
    assert f"up to {1000 * c['in_box_max_altitude_lost_m']:.1f} mm" in TEXT
    assert f"for the {stay} initial states in the Sect. 3.6 box whose linear trajectory stays " \
           f"within the bounds, the lateral states differ by at most " \
           f"{_pct(c['in_box_staying_max_err_lateral'])} of the bounds, the longitudinal ones by " \
           f"up to {_pct(c['in_box_staying_max_err_longitudinal'])} (only {lon_ok} of the {stay} " \
           f"within 10 %)" in README
    assert c["in_box_staying_max_err_lateral"] < 0.10 < c["in_box_max_err_lateral"]
    assert c["in_box_staying_max_err_longitudinal"] > 0.10 and lon_ok < stay


def _first_over(profile, column: int, limit: float = 0.10):
    """The first amplitude of a :func:`line_profile` whose ``column`` exceeds ``limit``."""
    return next(row for row in profile if row[column] > limit)


def test_docs_the_10pct_contour_outside_the_box():
    """Along the diagonals of the dr x dp slice, at the default comparison's quarter-box
    amplitudes (model loops: equal to the FMUs' to 1e-8, test above): along dr = -dp the
    lateral error stays within 10 % far beyond where the linear loop leaves the bounds; along
    dr = dp it passes 10 % where the linear loop leaves them too."""
    amplitudes = [k / 4 for k in range(1, 13)]
    anti = line_profile((0.0, 1.0, -1.0, 0.0), amplitudes)
    last_in = max(a for a, lat, lon, peak in anti if peak <= 1.0)
    first_out = min(a for a, lat, lon, peak in anti if peak > 1.0)
    within = [row for row in anti if row[1] <= 0.10]
    assert within == anti[:len(within)], "within 10 % up to an amplitude, not beyond"
    best, over = within[-1], _first_over(anti, 1)
    assert (last_in, first_out) == (1.0, 1.25) and best[0] == 2.5
    assert f"along dr = -dp (roll and yaw rates of opposite signs) it stays below 10 % out to " \
           f"{best[0]:g} times the box ({_pct(best[1])} there, {_pct(over[1])} at {over[0]:g})" \
           f", while the linear loop leaves the bounds from {first_out:g} times the box on" \
           in TEXT
    lon_over = _first_over(anti, 2)
    assert f"the longitudinal error passes 10 % at {lon_over[0]:g} times the box " \
           f"({_pct(lon_over[2])})" in TEXT
    diag = line_profile((0.0, 1.0, 1.0, 0.0), amplitudes[:2])
    lat_over = _first_over(diag, 1)
    assert lat_over[3] > 1.0 and diag[0][3] < 1.0  # the linear loop leaves there too
    assert f"along dr = dp, the lateral error passes 10 % at {lat_over[0]:g} times the box " \
           f"({_pct(lat_over[1])}), where the linear loop leaves the bounds too" in TEXT
    assert f"the lateral 10 % contour reaches {best[0]:g} times the box along dr = -dp, " \
           f"{lat_over[0]:g} times the box along dr = dp" in README


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
    assert same_numbers(text, row[1]) is None, (row[1], text)
    assert row[2] == AXES[int(np.argmax(e[:4]))]
    best = None
    for k in range(1, 13):  # amplitudes 0.25 .. 3 box, as the default comparison
        a = k / 4
        if linearisation_error(a * direction_vector(d) * np.array(STATE_BOUNDS_SECT36))[:4].max() \
                > 0.10:
            break
        best = a
    assert row[3] == (f"{best:g} or more" if best == 3.0 else f"{best:g}")
    lon = e[4:].max()
    lon_text = f"{100 * lon:.1f} %" if lon >= 0.005 else f"{100 * lon:.2f} %"
    assert same_numbers(lon_text, row[4]) is None, (row[4], lon_text)
    sink = term_errors(d, 1.0).altitude_lost_m["all"]
    assert same_numbers(f"{1000 * sink:.1f} mm", row[5]) is None, (row[5], sink)


def test_docs_terms():
    dr, dp = term_errors("+dr"), term_errors("+dp")
    assert dr.first == "gyroscopic" and dp.first == "kinematics"
    assert f"its error is {_pct(dr.lateral['all'])} with all terms and " \
           f"{_pct(dr.lateral['no gyroscopic'])} without the" in TEXT
    assert f"({_pct(dp.lateral['kinematics only'])} with every" in TEXT
    assert f"({_pct(dp.lateral['all'])} with all terms)" in TEXT
    gravity = max(abs(term_errors(d).contributions["gravity"])
                  for d in ("+dv", "+dp", "+dr", "+dgamma", "+mode1"))
    assert gravity <= 0.002 and "by more than 0.2 % of the bounds" in TEXT
    pitch = [linearisation_error(direction_vector(d) * np.array(STATE_BOUNDS_SECT36))
             for d in ("+dp", "+dr")]
    worst = max(p[4:].max() for p in pitch)
    assert all(LONGITUDINAL_AXES[int(np.argmax(p[4:]))] == "dtheta" for p in pitch)
    assert f"by {100 * worst:.0f} % of its bound" in TEXT
    m = re.search(r"box-edge roll of 0\.22 rad it loses ([0-9.]+) mm", TEXT.text)
    # well-conditioned (a smooth integral): the printed digit to a unit of the last place
    assert m and abs(float(m.group(1)) - 1000 * term_errors("+dgamma").altitude_lost_m["all"]) <= 0.1


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
    assert (out / "compare_dr_dp.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    # what the CLI writes is the comparison: each case's errors are those of the model loops
    # (the oracle of test_fmus_agree_with_the_model_loops, to the same 1e-8)
    with open(out / "sweep.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == 9
    # the 3 x 3 grid of the dr x dp slice out to 3 times the box (--compare's default extent,
    # docs/validity.md), the other axes at 0
    edge = 3 * np.array(STATE_BOUNDS_SECT36)
    grid = sorted((float(r["x0_dr"]), float(r["x0_dp"])) for r in rows)
    np.testing.assert_allclose(grid, [(a * edge[2], b * edge[1]) for a in (-1, 0, 1)
                                      for b in (-1, 0, 1)], atol=1e-15)
    assert all(float(r["x0_dv"]) == float(r["x0_dgamma"]) == 0.0 for r in rows)
    for row in rows:
        want = linearisation_error([float(row[f"x0_{a}"]) for a in AXES], stop_wb=20.0)
        got = [float(row[f"err_{a}"]) for a in (*AXES, *LONGITUDINAL_AXES)]
        np.testing.assert_allclose(got, want, rtol=1e-8, atol=1e-12)
        assert float(row["err_lateral"]) == pytest.approx(max(want[:4]), rel=1e-8)
