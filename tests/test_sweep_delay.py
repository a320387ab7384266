"""``dronefly sweep --delays/--sample-periods``: the delay axes against oracles.

Oracles: the case key of a case without delay axes (the formula, written here);
the sweep without the options (byte for byte); the controller parameters a case sets; model (b)
of :mod:`dronefly.harness.latency.sampled` (``verdict_map``) for the loop's verdict with the
delay states, for the paper's gains, the stabilising design and an LQR design; the real
co-simulated trajectories for the timing model on the communication grid (which the doc's
numbers come from). docs/latency.md quotes :mod:`harness.sweep.delaytable`.
"""

from __future__ import annotations

import hashlib
import json
import re
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from docnumbers import NumericText, assert_same_numbers

from dronefly.harness.sweep.cases import SweepSpec
from dronefly.harness.sweep.run import COLUMNS, read_rows, run_sweep

pytestmark = [pytest.mark.integration, pytest.mark.numeric]

ROOT = Path(__file__).resolve().parents[1]
TODAY = SweepSpec(disturbances=("grid", "directions"), slices=(("dgamma", "dp"),), grid_points=3,
                  directions=("+dp", "-mode1"), amplitudes=1, gains=("paper",), steps_wb=(1.0,),
                  stop_wb=8.0)


@pytest.fixture(scope="module")
def fmus(built_fmus: dict[str, Path]) -> dict[str, Path]:
    return {"plant": built_fmus["DroneFlyLateral"], "controller": built_fmus["StateFeedback"]}


@pytest.fixture(autouse=True, scope="module")
def one_blas_thread():
    from threadpoolctl import threadpool_limits

    with threadpool_limits(limits=1, user_api="blas"):
        yield


def _cli(fmus: dict[str, Path], *args: str) -> int:
    from dronefly.cli.app import main

    return main(["sweep", "--plant", str(fmus["plant"]), "--controller", str(fmus["controller"]),
                 "--no-progress", "--workers", "1", *args])


def test_default_axes_are_today_s_sweep_bit_for_bit(fmus, tmp_path, capsys):
    for c in TODAY.cases():  # the key formula of a case without delay axes
        ident = repr((tuple(map(float, c.x0)), tuple(tuple(map(float, r)) for r in c.K),
                      float(c.step_wb), float(c.scale), c.n_steps, c.master))
        assert c.key == hashlib.sha1(ident.encode()).hexdigest()[:16]
        assert (c.delay_wb, c.sample_period_wb) == (0.0, 0.0)
    assert [c.key for c in replace(TODAY, delays_wb=(0.0,), sample_periods_wb=(0.0,)).cases()] \
        == [c.key for c in TODAY.cases()]
    common = ["--slices", "dgamma:dp", "--grid", "3", "--directions", "+dp,-mode1",
              "--amplitudes", "1", "--gains", "paper", "--steps", "1", "--stop", "8", "--no-plot"]
    assert _cli(fmus, *common, "--out", str(tmp_path / "a")) == 0
    assert _cli(fmus, *common, "--delays", "0", "--sample-periods", "0",
                "--out", str(tmp_path / "b")) == 0
    capsys.readouterr()
    a = (tmp_path / "a" / "sweep.csv").read_bytes()
    assert a == (tmp_path / "b" / "sweep.csv").read_bytes()
    assert a.decode().splitlines()[0] == ",".join(COLUMNS) and "delay_wb" not in COLUMNS
    assert "delay_groups" not in json.loads((tmp_path / "b" / "sweep.json").read_text())


def _lqr_file(tmp_path: Path) -> str:
    from dronefly.harness.latency.designs import design

    path = tmp_path / "lqr.json"
    path.write_text(json.dumps({"K": design("lqr").K.tolist()}))
    return str(path)


def test_delayed_verdicts_are_model_b_s(fmus, tmp_path):
    """Eq. (27) sampled once per wing beat with one of delay: neutral; the LQR design (margin
    0.53 wing beats) unstable from one; the stabilising design (margin 6.46) unstable at 8."""
    from dronefly.harness.latency.designs import design
    from dronefly.harness.latency.sampled import verdict_map

    lqr = _lqr_file(tmp_path)
    spec = SweepSpec(disturbances=("directions",), directions=("+dgamma",), amplitudes=1,
                     gains=("paper", "stabilising", lqr), steps_wb=(1.0,), stop_wb=6.0,
                     delays_wb=(0.0, 1.0, 8.0), sample_periods_wb=(0.0, 2.0))
    r = run_sweep(spec, tmp_path / "out", workers=1, progress_bar=False, **fmus)
    names = {"paper": "eq27", "stabilising": "stabilising", lqr: "lqr"}
    expected = {}
    for g, name in names.items():
        v, _ = verdict_map(design(name), [0.0, 1.0, 8.0], [1.0, 2.0])  # period 0: the step
        expected |= {(g, d, T): v[i, j] for i, d in enumerate((0.0, 1.0, 8.0))
                     for j, T in enumerate((0.0, 2.0))}
    rows = read_rows(r.csv)
    assert len(rows) == 18 and rows[0]["stability"]
    for row in rows:
        key = (row["gains"], float(row["delay_wb"]), float(row["sample_period_wb"]))
        assert row["stability"] == expected[key], key
        assert row["stability_identified"] == row["stability"], key
        assert float(row["stability_deviation"]) < 1e-9, key
        assert float(row["delay_ms"]) == pytest.approx(1e3 * key[1] / 164, rel=1e-15)
    assert expected[("paper", 1.0, 0.0)] == "neutral"
    assert expected[(lqr, 0.0, 0.0)] == "stable" and expected[(lqr, 1.0, 0.0)] == "unstable"
    assert expected[("stabilising", 1.0, 2.0)] == "stable"
    assert expected[("stabilising", 8.0, 0.0)] == "unstable"
    assert r.summary["stability_disagreements"] == 0
    assert [m.name for m in r.maps] == ["map_delay_period.png"]
    again = run_sweep(spec, tmp_path / "out", workers=1, plot=False, progress_bar=False, **fmus)
    assert again.summary["resumed_cases"] == 18 and again.csv.read_bytes() == r.csv.read_bytes()


def test_grid_timing_is_the_fmus_and_model_b_where_it_applies(fmus, tmp_path):
    """Off the grid (sample period 1.5 on steps of 1) and with the Jacobi master, the rows equal
    the trajectories simulated from the timing alone; where the samples lie on the grid its
    periodic loop has model (b)'s rates."""
    from dronefly.harness.paper.gains import gain_matrix
    from dronefly.harness.cosim.identification import rates_from_transition
    from dronefly.harness.latency.loop import FeedbackLoop
    from dronefly.harness.latency.sampled import sampled_rates
    from dronefly.harness.paper.analysis import lateral_system
    from dronefly.harness.latency.grid import GridTiming, grid_monodromy, grid_simulate

    A, B = lateral_system()
    K = gain_matrix("stabilising")
    for master in ("gauss-seidel", "jacobi"):
        spec = SweepSpec(disturbances=("directions",), directions=("+dp", "-dgamma"),
                         amplitudes=1, gains=("stabilising",), steps_wb=(1.0,), stop_wb=12.0,
                         delays_wb=(0.0, 1.5), sample_periods_wb=(0.0, 1.5), master=master)
        r = run_sweep(spec, tmp_path / master, workers=1, plot=False, progress_bar=False, **fmus)
        for row, case in zip(read_rows(r.csv), spec.cases()):
            timing = GridTiming(1.0, case.delay_wb, case.sample_period_wb, master == "jacobi")
            x, u = grid_simulate(A, B, K, timing, np.array([case.x0]), 12)
            final = [float(row[f"final_{a}"]) for a in ("dv", "dp", "dr", "dgamma")]
            assert np.max(np.abs(np.array(final) - x[-1, 0])) < 1e-14
            assert float(row["peak_u"]) == pytest.approx(np.max(np.abs(u)) / 0.4, abs=1e-14)
            assert row["stability"] in ("stable", "neutral", "unstable")
    for h, tau, T, jac in ((0.5, 1.7, 1.0, False), (0.5, 0.0, 0.0, True), (1.0, 3.0, 2.0, True),
                           (0.25, 2.0, 0.75, False)):
        timing = GridTiming(h, tau, T, jac)
        grid = rates_from_transition(*grid_monodromy(A, B, K, timing))
        b = sampled_rates(FeedbackLoop(A, B, K), *timing.model_b())
        assert abs(np.max(grid.real) - np.max(b.real)) < 1e-12, (h, tau, T, jac)


@pytest.mark.parametrize("args, named", [
    (["--delays", "-1"], "delay = -1.0 wing beats must be >= 0"),
    (["--delays", "0,nan"], "'nan' is not finite"),
    (["--sample-periods", "inf"], "'inf' is not finite"),
    (["--sample-periods", "1,-0.5"], "sample period = -0.5 wing beats must be >= 0"),
    (["--delays", "1,x"], "'x' is not a number"),
    (["--delays", "1", "--set", "controller.sensing_delay=0.01"], "sensing_delay"),
])
def test_cli_bad_delay_input_exits_2(fmus, tmp_path, capsys, args, named):
    out = tmp_path / "out"
    assert _cli(fmus, "--out", str(out), *args) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and err.startswith("dronefly sweep: error")
    assert named in err
    assert not out.exists()


@pytest.mark.parametrize("how, named", [("system", "--system"),
                                        ("delayed", "sensing_delay defaults to 0")])
def test_delays_with_a_system_or_a_delayed_controller_exit_2(built_fmus, tmp_path, capsys, how,
                                                              named):
    """A system's controllers take their timing by --set; StateFeedbackDelayed's default delay
    would stay in the cases of delay 0, which set nothing."""
    from dronefly.cli.app import main

    out = tmp_path / "out"
    where = (["--system", str(built_fmus["DroneFlyHover.ssp"])] if how == "system" else
             ["--plant", str(built_fmus["DroneFlyLateral"]),
              "--controller", str(built_fmus["StateFeedbackDelayed"])])
    assert main(["sweep", *where, "--delays", "0,1", "--out", str(out), "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and named in err and not out.exists()


def _flat(path: Path) -> NumericText:
    """The text, its numbers compared to a unit of their last digit (tests/docnumbers.py)."""
    return NumericText(path.read_text(encoding="utf-8"))


def test_doc_and_readme_numbers_are_the_code_s():
    """docs/latency.md's table verbatim, its command, and the numbers of its text recomputed
    (its summary of the sweep included): the verdicts
    over the whole map by model (b), the rest by :mod:`harness.sweep.delaytable` (which the
    other tests tie to the co-simulation)."""
    import math

    from dronefly.harness.paper.gains import gain_matrix
    from dronefly.harness.latency.loop import FeedbackLoop
    from dronefly.harness.latency.sampled import verdict_map
    from dronefly.harness.paper.analysis import lateral_system
    from dronefly.harness.sweep import delaytable as dt

    raw = (ROOT / "docs" / "latency.md").read_text(encoding="utf-8")
    m, c = dt.margins(), dt.cells()
    found = re.search(r"<!-- table: delay-period -->\n(.*?)\n<!-- end table -->", raw, re.S)
    assert found
    assert_same_numbers("\n".join(dt.table(m, c)), found.group(1))
    doc = _flat(ROOT / "docs" / "latency.md")
    assert dt.MAP_COMMAND in " ".join(raw.replace("\\\n", " ").split())
    assert (ROOT / "docs" / "latency_map.png").is_file()
    A, B = lateral_system()
    periods = [T or dt.MAP_STEP_WB for T in dt.MAP_PERIODS_WB]
    v = {g: verdict_map(FeedbackLoop(A, B, gain_matrix(g)), dt.MAP_DELAYS_WB, periods)[0]
         for g in ("paper", "stabilising")}
    d = list(dt.MAP_DELAYS_WB)
    assert (v["paper"][:d.index(10) + 1, :4] == "neutral").all() and (v["paper"][-1] == "unstable").all()
    assert (v["paper"][:d.index(8) + 1, 4] == "neutral").all() and v["paper"][d.index(10), 4] == "unstable"
    assert (v["stabilising"][:d.index(5) + 1] == "stable").all()
    assert v["stabilising"][d.index(6), 2] == "neutral"
    assert f"sits on its margin of {m[('stabilising', 2)].tau:.2f} wing beats" in doc
    P, S = "paper", "stabilising"
    pct = {(g, k): f"{100 * c[(g, 1, k)].share:.0f} %" for g in (P, S) for k in (0, 1, 2, 5)}
    assert (f"from {pct[P, 0]} (Eq. 27) and {pct[S, 0]} (stabilising) without delay to "
            f"{pct[P, 1]} and {pct[S, 1]} at one wing beat (the roll reflex), {pct[P, 2]} and "
            f"{pct[S, 2]} at two (pitch), and {pct[P, 5]} and {pct[S, 5]} at five (vision)") in doc
    assert (f"from {pct[P, 0]} (Eq. 27) and {pct[S, 0]} (stabilising) without delay to "
            f"{pct[P, 1]} and {pct[S, 1]} at one wing beat of delay (6.1 ms, the roll reflex), "
            f"{pct[P, 2]} and {pct[S, 2]} at two (pitch) and {pct[P, 5]} and {pct[S, 5]} at five "
            "(vision)") in doc
    assert (f"falls from {m[(P, 0)].tau:.2f} to {m[(P, 4)].tau:.2f} wing beats, that of the "
            f"stabilising design from {m[(S, 0)].tau:.2f} to {m[(S, 4)].tau:.2f}") in doc
    pu = {(g, k): f"{c[(g, 1, k)].peak_control:.2f}" for g in (P, S) for k in (0, 5)}
    assert (f"from {pu[P, 0]} to {pu[P, 5]} rad for Eq. (27) and from {pu[S, 0]} to {pu[S, 5]} "
            "rad for the stabilising design at 5 wing beats") in doc
    top = max(x.peak_control for k, x in c.items() if k[2] <= 5)
    assert f"within {top:.2f} rad (the limit is 0.4 rad)" in doc and f"{top:.2f}" == pu[S, 5]
    rec = {(T, k): c[(S, T, k)].recovery for T in dt.MAP_PERIODS_WB for k in (0, 1, 2, 5)}
    assert all(abs(rec[1, k] - rec[1, 0]) <= 3 for k in (1, 2)) and math.isinf(rec[4, 5])
    assert (f"recovers a roll in {rec[1, 0]:.0f} wing beats without delay and about as fast up "
            f"to 2 wing beats of delay, but in {rec[1, 5]:.0f} wing beats at 5 sampled once per "
            f"wing beat, {rec[2, 5]:.0f} and {rec[3, 5]:.0f} when sampled every 2 and 3") in doc
    assert (f"recovers a roll in {rec[1, 0]:.0f} wing beats without delay and in {rec[1, 5]:.0f} "
            "at five, and Eq. (27) never returns to hover") in doc
    left = [x.settles for k, x in c.items() if k[0] == P]
    assert all(math.isinf(x.recovery) for k, x in c.items() if k[0] == P)
    assert f"({100 * min(left):.0f} % to {100 * max(left):.0f} % of the roll remain)" in doc
    assert f"up to 5 wing beats, {1e3 * 5 / 164:.1f} ms" in doc


def test_a_delay_sweep_on_workers_leaves_no_extracted_fmu(fmus, tmp_path, monkeypatch):
    """The delay axes' verdicts open the pair in the parent before the workers start: those
    extractions are removed there too (they were left in the temporary folder)."""
    import tempfile

    tmp = tmp_path / "tmp"
    tmp.mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(tmp))  # this process and its forked workers
    spec = SweepSpec(disturbances=("directions",), directions=("+dgamma",), amplitudes=1,
                     gains=("paper",), steps_wb=(1.0,), stop_wb=2.0, delays_wb=(0.0, 1.0))
    run_sweep(spec, tmp_path / "out", workers=2, plot=False, progress_bar=False, **fmus)
    assert list(tmp.iterdir()) == []
