"""The co-simulation harness: verdicts, exactness against the sampled-data solution, bad input."""

from __future__ import annotations

import json
import re
import zipfile

import numpy as np
import pytest
from numpy.testing import assert_allclose

from dronefly.harness.paper import printed as pv
from dronefly.cli.app import main
from dronefly.core.errors import DroneflyError
from dronefly.harness.stability.run import cosimulate
from dronefly.harness.cosim.fmu import FMU, FMUError
from dronefly.harness.cosim.master import CoSimError, Loop

pytestmark = pytest.mark.integration

#: Table 2 (per wing beat) and the Eq. (27) target: lambda1 -> 0, the others unchanged.
LAMBDA1_OPEN = float(pv.EQ19_A_LNN[0][0])  # Eq. (19), 4 decimals; Table 2 prints 0.079
OTHERS = list(pv.table2_eigenvalues()[1:])


@pytest.fixture(scope="module")
def fmus(built_fmus):
    return built_fmus["DroneFlyLateral"], built_fmus["StateFeedback"]


@pytest.fixture(scope="module", params=["gauss-seidel", "jacobi"])
def runs(request, fmus, tmp_path_factory):
    out = tmp_path_factory.mktemp(request.param)
    return {g: cosimulate(*fmus, gains=g, master=request.param, stop_wingbeats=100,
                          out_dir=out, plot=False) for g in ("open", "paper")}


def test_open_loop_is_unstable(runs):
    r = runs["open"]
    assert r.verdict == "unstable"
    assert_allclose(r.identification.dominant_growth_rate, LAMBDA1_OPEN, atol=1e-3,
                    err_msg="Table 2 / Eq. (19): lambda1")


def test_paper_gains_are_neutral(runs):
    r = runs["paper"]
    assert r.verdict == "neutral"
    ev = r.identification.eigenvalues
    assert abs(ev[0]) <= 1e-3, "Eq. (27): lambda1 = 0 within the rounding of the gains"
    assert_allclose(ev[1:4], OTHERS, atol=1e-3, err_msg="Eq. (27) targets: Table 2 values")


@pytest.mark.parametrize("gains", ["open", "paper"])
def test_identified_equals_sampled_data_and_near_continuous(runs, gains):
    r = runs[gains]
    assert_allclose(r.identification.eigenvalues, r.sampled_eigenvalues, rtol=0, atol=1e-9,
                    err_msg="identified vs exact ZOH closed loop at the same step")
    assert_allclose(r.identification.eigenvalues[:4], r.continuous_eigenvalues, atol=1e-3,
                    err_msg="step 0.1 wing beat vs eig(A1 + B1 K)")


@pytest.mark.parametrize("gains", ["open", "paper"])
def test_trajectory_equals_sampled_data_solution(runs, gains):
    """Gauss-Seidel: x_(k+1) = (Phi + Gamma K) x_k; Jacobi: the same with one step of delay."""
    assert runs[gains].trajectory_error <= 1e-9


def test_jacobi_is_the_delayed_loop(fmus, tmp_path):
    gs = cosimulate(*fmus, gains="paper", stop_wingbeats=5, out_dir=None)
    ja = cosimulate(*fmus, gains="paper", stop_wingbeats=5, master="jacobi", out_dir=None)
    u_gs, u_ja = gs.run.column("delta_Phi_a"), ja.run.column("delta_Phi_a")
    assert u_ja[0] == u_gs[0]  # both start from K x0
    assert not np.allclose(u_ja[2:], u_gs[2:], rtol=1e-6)  # the delay changes the loop


def test_csv_is_fmpy_compatible(fmus, tmp_path):
    from fmpy.util import read_csv

    r = cosimulate(*fmus, gains="paper", stop_wingbeats=10, out_dir=tmp_path, plot=False)
    data = read_csv(str(r.csv))
    assert list(data.dtype.names) == ["time", *r.run.names]
    assert_allclose(data["delta_gamma"], r.run.column("delta_gamma"), rtol=1e-15)
    summary = json.loads(r.csv.with_suffix(".json").read_text())
    assert summary["verdict"] == "neutral" and summary["complete"] is True


def test_mismatched_fmus_are_refused(fmus):
    with FMU(fmus[0]) as p, pytest.raises(CoSimError, match="'delta_Phi_a'"):
        Loop(p, p)


def test_corrupt_fmu_is_refused(tmp_path):
    bad = tmp_path / "bad.fmu"
    bad.write_bytes(b"not a zip")
    with pytest.raises(FMUError, match="bad.fmu"):
        FMU(bad)
    empty = tmp_path / "empty.fmu"
    with zipfile.ZipFile(empty, "w") as z:
        z.writestr("x.txt", "x")
    with pytest.raises(FMUError, match="empty.fmu"):
        FMU(empty)


def test_failure_mid_run_keeps_partial_result(fmus, tmp_path):
    """Overflow of the linear state: the plant refuses the step; the run stops and says where."""
    r = cosimulate(*fmus, gains="open", x0="1e306,0,0,0", stop_wingbeats=300, out_dir=tmp_path,
                   plot=False)
    assert not r.run.complete
    f = r.run.failure
    assert (f.fmu, f.call) == ("DroneFlyLateral", "fmi2DoStep") and f.time > 0
    assert "state overflow" in f.message
    assert 1 < len(r.run.time) < 3001 and np.isfinite(r.run.signals).all()
    summary = json.loads(r.csv.with_suffix(".json").read_text())
    assert summary["complete"] is False and "fmi2DoStep" in summary["failure"]


def test_cli_json(fmus, tmp_path, capsys):
    code = main(["cosim", "--plant", str(fmus[0]), "--controller", str(fmus[1]), "--gains", "open",
                 "--stop", "50", "--step", "0.5", "--out", str(tmp_path), "--json", "--no-plot"])
    assert code == 0
    out = json.loads(capsys.readouterr().out)
    assert out["verdict"] == "unstable" and out["step_wingbeats"] == 0.5
    assert out["stop_wingbeats"] == 50 and len(out["eigenvalues_per_wingbeat"]) == 4
    assert_allclose(out["dominant_growth_rate_per_wingbeat"], LAMBDA1_OPEN, atol=1e-3)
    assert out["csv"].endswith(".csv") and out["plot"] is None


@pytest.mark.parametrize("args, fragment", [
    (["--gains", "1,2,3"], "gains '1,2,3': row 1 has 3 values, expected 4"),
    (["--gains", "nan,0,0,0"], "gains 'nan,0,0,0': K[1,1] = nan is not finite"),
    (["--gains", "1,2,3,4;5,6,7,8"], "2 rows, expected 3"),
    (["--gains", "missing.json"], "gains file 'missing.json'"),
    (["--set", "plant.Lv_plus"], "expected NAME=VALUE"),
    (["--set", "Lv_plus=abc"], "Lv_plus = 'abc' is not a number"),
    (["--set", "plant.nope=1"], "plant has no variable 'nope'"),
    (["--set", "n=164"], "'n' is a variable of plant and controller"),
    (["--set", "plant.delta_v=1"], "only parameters and inputs can be set"),
    (["--set", "controller.limit_enabled=2"], "controller.limit_enabled = '2': a Boolean takes "
                                              "true, false, 1 or 0"),
    (["--set", "controller.K[1,1]=true"], "controller.K[1,1] = 'true' is not a number (a Real)"),
    (["--record", "controller.nope"], "cannot record 'controller.nope'"),
    (["--x0", "0,0,x,0"], "x0 = '0,0,x,0'"),
    (["--x0", "0,0,0,inf"], "x0 = '0,0,0,inf'"),
    (["--step", "0"], "'0' must be > 0"),
    (["--step", "nan"], "'nan' is not finite"),
    (["--stop", "0.05"], "stop = 0.05 is shorter than one step"),
    (["--plant", "missing.fmu"], "'missing.fmu' does not exist"),
    (["--master", "newton"], "invalid choice"),
])
def test_cli_bad_input(fmus, tmp_path, capsys, args, fragment):
    base = {"--plant": str(fmus[0]), "--controller": str(fmus[1])}
    for flag in list(base):
        if flag in args:
            del base[flag]
    argv = ["cosim", *[x for kv in base.items() for x in kv], "--out", str(tmp_path / "o"), *args]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert fragment in err[-1] and not any("Traceback" in line for line in err)
    assert not (tmp_path / "o").exists(), "no partial result files"


def test_cli_incomplete_run_exits_1(fmus, tmp_path, capsys):
    argv = ["cosim", "--plant", str(fmus[0]), "--controller", str(fmus[1]), "--gains", "open",
            "--x0", "1e306,0,0,0", "--out", str(tmp_path), "--no-plot"]
    assert main(argv) == 1
    assert "run incomplete: DroneFlyLateral: fmi2DoStep" in capsys.readouterr().err


def test_plot_is_written(fmus, tmp_path):
    import matplotlib  # noqa: F401  (the test extra installs it: a broken install fails)
    r = cosimulate(*fmus, gains="paper", stop_wingbeats=20, out_dir=tmp_path)
    assert r.plot is not None and r.plot.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


@pytest.mark.parametrize("args, fragment", [
    (["--stop", "1e12"], "exceeds the limit of 1000000"),
    (["--step", "1e-300", "--stop", "1"], "exceeds the limit of 1000000"),
    (["--stop=1e308"], "exceeds the limit of 1000000"),
    (["--step=1e-320"], "exceeds the limit of 1000000"),
])
def test_cli_refuses_runs_too_long_to_record(fmus, tmp_path, capsys, args, fragment):
    argv = ["cosim", "--plant", str(fmus[0]), "--controller", str(fmus[1]),
            "--out", str(tmp_path / "o"), *args]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and fragment in err[0]
    assert not (tmp_path / "o").exists()


def test_stop_is_whole_steps_never_past(fmus):
    r = cosimulate(*fmus, gains="paper", stop_wingbeats=0.3, step_wingbeats=0.2, out_dir=None)
    assert r.stop_wingbeats == 0.2 and len(r.run.time) == 2


def test_plant_without_reference_scales_is_refused(tmp_path, fmus):
    from pathlib import Path

    from pythonfmu import FmuBuilder

    src = Path(__file__).resolve().parents[1] / "benchmarks" / "null_fmus" / "NullPlant.py"
    null = FmuBuilder.build_FMU(src, dest=tmp_path)
    # refused before anything runs: it has no state x with x_start (nor n and U)
    with pytest.raises(DroneflyError, match="cannot identify the loop: .* x_start"):
        cosimulate(null, fmus[1], out_dir=tmp_path / "o")
    assert not (tmp_path / "o").exists()


def test_record_adds_columns_and_leaves_the_default_ones_bit_for_bit(fmus, tmp_path):
    """cosimulate(record=): the CSV is the default one with the recorded columns appended
    (each line byte for byte); the recorded values against independent oracles: the
    controller's input as set equals the plant's output at the point (Gauss-Seidel), A[1,1]
    is Eq. (9)'s A1[1,1] from dronefly.models.lateral_dynamics, no limit means never saturated."""
    from dronefly.models import lateral_dynamics

    record = ["controller.delta_p", "plant.A[1,1]", "controller.saturated"]
    base = cosimulate(*fmus, stop_wingbeats=10, out_dir=tmp_path / "a", plot=False, name="r")
    more = cosimulate(*fmus, stop_wingbeats=10, out_dir=tmp_path / "b", plot=False, name="r",
                      record=record)
    lines = base.csv.read_text().splitlines()
    with_more = more.csv.read_text().splitlines()
    assert with_more[0] == lines[0] + "," + ",".join(f'"{n}"' if "," in n else n for n in record)
    assert [line.rsplit(",", len(record))[0] for line in with_more[1:]] == lines[1:]
    assert more.run.names == [*base.run.names, *record]
    assert json.loads(more.csv.with_suffix(".json").read_text())["recorded"] == more.run.names
    assert np.array_equal(more.run.column("controller.delta_p"), more.run.column("delta_p"))
    A, _ = lateral_dynamics.system_matrices(lateral_dynamics.default_parameters())
    assert_allclose(more.run.column("plant.A[1,1]"), A[0, 0], rtol=1e-12)
    assert not more.run.column("controller.saturated").any()
    with pytest.raises(DroneflyError, match=r"cannot record 'delta_v': no instance 'delta_v'"):
        cosimulate(*fmus, stop_wingbeats=1, out_dir=None, record=["delta_v"])


def test_plot_draws_the_controls_by_name_not_the_recorded_columns(fmus, tmp_path, monkeypatch):
    """The controls panel holds the plant's three inputs (each its run column in degrees),
    whatever else is recorded after them."""
    import matplotlib.pyplot as plt  # the test extra installs it
    figures, close = [], plt.close
    monkeypatch.setattr(plt, "close", figures.append)
    r = cosimulate(*fmus, stop_wingbeats=5, out_dir=tmp_path, record=["plant.n",
                   "controller.saturated", "controller.K[1,1]"])
    assert r.plot.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    controls = figures[0].axes[4]
    assert [line.get_label() for line in controls.get_lines()] == [
        "delta_Phi_a", "delta_alpha_1a", "delta_alpha_2a"]
    assert_allclose(controls.get_lines()[0].get_ydata(),
                    np.degrees(r.run.column("delta_Phi_a")), rtol=1e-15)
    close(figures[0])


def test_values_are_converted_to_the_declared_types(fmus):
    """resolve_assignments types values as the system master does (Integer whole, Boolean
    true/false/1/0), against a model description with every type, and names the bad ones."""
    from types import SimpleNamespace as V

    from dronefly.harness.cosim.params import ParameterError, resolve_assignments

    md = V(modelVariables=[V(name="count", causality="parameter", variability="fixed",
                             type="Integer"),
                           V(name="on", causality="parameter", variability="tunable",
                             type="Boolean"),
                           V(name="label", causality="parameter", variability="fixed",
                             type="String"),
                           V(name="gain", causality="input", variability="continuous",
                             type="Real")])
    got = resolve_assignments({"c.count": "3", "on": "0", "label": "x", "c.gain": "2.5"},
                              {"c": md})
    assert got == {"c": {"count": 3, "on": False, "label": "x", "gain": 2.5}}
    assert type(got["c"]["count"]) is int and type(got["c"]["on"]) is bool
    for given, message in [({"count": "3.5"}, "c.count = '3.5': an Integer takes a whole number"),
                           ({"c.count": 2 ** 31}, "c.count = 2147483648 is outside the Integer"),
                           ({"on": "yes"}, "c.on = 'yes': a Boolean takes true, false, 1 or 0"),
                           ({"gain": "inf"}, "c.gain = 'inf' is not finite")]:
        with pytest.raises(ParameterError, match=re.escape(message)):
            resolve_assignments(given, {"c": md})


def test_result_files_are_written_together_or_not_at_all(tmp_path):
    """dronefly.core.files.write_run_files (both cosim commands): a failing plot leaves no file;
    otherwise CSV, PNG and JSON, the JSON naming the other two."""
    from types import SimpleNamespace

    from dronefly.core.files import write_run_files
    from dronefly.harness.cosim.records import LoopRun

    run = LoopRun(["a"], np.array([0.0, 0.5]), np.array([[1.0], [0.1 + 0.2]]))
    result = SimpleNamespace(run=run, csv=None, plot=None)
    result.to_json = lambda: {"csv": str(result.csv), "plot": str(result.plot)}

    def broken(res, path):
        raise OSError("disk full")

    with pytest.raises(OSError, match="disk full"):
        write_run_files(result, tmp_path / "o", "r", broken)
    assert list((tmp_path / "o").iterdir()) == []
    write_run_files(result, tmp_path / "o", "r", lambda res, path: path.write_bytes(b"png"))
    assert (tmp_path / "o" / "r.csv").read_text() == "time,a\n0.0,1.0\n0.5,0.30000000000000004\n"
    assert json.loads((tmp_path / "o" / "r.json").read_text()) == {
        "csv": str(tmp_path / "o" / "r.csv"), "plot": str(tmp_path / "o" / "r.png")}
    assert (tmp_path / "o" / "r.png").read_bytes() == b"png"


class _FakeSlave3:
    """fmpy's FMU3Slave as far as the adapter's typed setters and getters use it: every
    ``set<Type>``/``get<Type>`` call is logged, values are kept by value reference."""

    last = None

    def __init__(self, **kw) -> None:
        self.calls, self.values = [], {}
        _FakeSlave3.last = self
        self.fmi3DoStep = self.fmi3GetFloat64 = self.fmi3SetFloat64 = None

    def __getattr__(self, name: str):
        if name.startswith("set"):
            def setter(vr, values):
                self.calls.append((name, list(vr), list(values)))
                self.values.update(zip(vr, values))
            return setter
        if name.startswith("get"):
            def getter(vr):
                self.calls.append((name, list(vr)))
                return [self.values[v] for v in vr]
            return getter
        raise AttributeError(name)


def test_fmi3_adapter_sets_and_gets_integer_enumeration_and_string_values(monkeypatch):
    """The FMI 3.0 adapter answers the setters the system master calls for String and
    integer values (set<SETTER[type]>, SETTER of the typed values) through FMU3Slave's typed
    calls: an Enumeration is an Int64 in FMI 3.0 (these setters did not exist:
    AttributeError escaped the master)."""
    from ctypes import c_int, c_uint
    from types import SimpleNamespace as NS

    from dronefly.harness.cosim import fmu3
    from dronefly.harness.cosim.fmu3 import FMU3Adapter
    from dronefly.harness.cosim.typed_values import SETTER, typed_value

    monkeypatch.setattr(fmu3, "FMU3Slave", _FakeSlave3)  # the adapter's base, where it looks
    kinds = ["String", "Enumeration", "Int8", "UInt16", "Int32", "UInt64", "Boolean"]
    variables = [NS(valueReference=vr, type=t) for vr, t in enumerate(kinds, start=1)]
    md = NS(guid="g", coSimulation=NS(modelIdentifier="m"), modelVariables=variables)
    a = FMU3Adapter(md, "/nowhere", "x", {})
    fake = _FakeSlave3.last
    given = {"String": "left", "Enumeration": "2", "Int8": -128, "UInt16": "65535",
             "Int32": 7.0, "UInt64": 2 ** 64 - 1, "Boolean": "true"}
    for v in variables:
        getattr(a, f"set{SETTER[v.type]}")([v.valueReference],
                                           [typed_value(f"x.{v.type}", v, given[v.type])])
    assert [c[0] for c in fake.calls] == ["setString", "setInt64", "setInt8", "setUInt16",
                                           "setInt32", "setUInt64", "setBoolean"]
    assert fake.values == {1: "left", 2: 2, 3: -128, 4: 65535, 5: 7, 6: 2 ** 64 - 1, 7: True}
    assert a.getString([1]) == ["left"] and a.getInteger([2, 3, 6]) == [2, -128, 2 ** 64 - 1]
    buf = (c_int * 2)()
    assert a.fmi2GetInteger(None, (c_uint * 2)(2, 5), 2, buf) == 0 and list(buf) == [2, 7]
    a.fmi2SetInteger(None, (c_uint * 1)(5), 1, (c_int * 1)(-3))
    assert fake.calls[-1] == ("setInt32", [5], [-3])
    with pytest.raises(DroneflyError, match="value reference 1 is a String variable"):
        a.setInteger([1], [3])
    with pytest.raises(DroneflyError, match=re.escape("x.u = 256 is outside the UInt8 range "
                                                      "0..255")):
        typed_value("x.u", NS(type="UInt8"), 256)
