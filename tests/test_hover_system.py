"""The four-FMU hover system (both axes with their controllers) and ``cosim --system``.

Oracles: eig(A + B K) computed here from the model modules and the control laws directly
(not through the FMUs, the SSP or the verdicts' mapping of gains through connections), and
the coefficient-matching designs of Sect. 3.5 (harness.paper.longitudinal).
"""

from __future__ import annotations

import json
import zipfile

import numpy as np
import pytest
from docnumbers import same_numbers
from sigint_at import install_at_check

from dronefly.cli.app import main
from dronefly.models.feedback import PAPER_GAINS_EQ27, LONGITUDINAL_GAINS_DESIGN_B, gain_name
from dronefly.harness.cosim.system import Connection, System
from dronefly.harness.cosim.system_master import SystemMaster
from dronefly.harness.stability.system_verdicts import cosimulate_system
from dronefly.harness.cosim.ssp import hover_system, write_system_ssp
from dronefly.models.lateral_interface import sort_eigenvalues
from dronefly.models import lateral_dynamics
from dronefly.models import longitudinal_dynamics

pytestmark = [pytest.mark.integration, pytest.mark.numeric]

PHIBAR_ROW = 2  # delta_phibar is row 3 of the longitudinal controller (B column order)


def _k(system_gains: dict[tuple[int, int], float], rows: int) -> np.ndarray:
    K = np.zeros((rows, 4))
    for (i, j), v in system_gains.items():
        K[i, j] = v
    return K


def _eig_lateral(K_row0: np.ndarray) -> list[complex]:
    A, B = lateral_dynamics.system_matrices(lateral_dynamics.default_parameters())
    K = np.zeros((3, 4))
    K[0] = K_row0
    return sort_eigenvalues(np.linalg.eigvals(np.asarray(A) + np.asarray(B) @ K))


def _eig_longitudinal(K_phibar: np.ndarray) -> list[complex]:
    A, B = longitudinal_dynamics.system_matrices(longitudinal_dynamics.default_parameters())
    K = np.zeros((4, 4))
    K[PHIBAR_ROW] = K_phibar
    return sort_eigenvalues(np.linalg.eigvals(np.asarray(A) + np.asarray(B) @ K))


def _set_row(instance: str, row: int, values, rows: int = 4) -> dict[str, float]:
    out = {f"{instance}.{gain_name(i, j)}": 0.0 for i in range(rows) for j in range(4)}
    out.update({f"{instance}.{gain_name(row, j)}": float(v) for j, v in enumerate(values)})
    return out


@pytest.fixture(scope="module")
def hover_ssp(built_fmus):
    return built_fmus["DroneFlyHover.ssp"]


def _axes(result) -> dict[str, object]:
    return {a.plant.instance: a for a in result.axes}


def _check_axis(result, instance: str, verdict: str, expected: list[complex]) -> None:
    a = _axes(result)[instance]
    assert a.verdict == verdict, (instance, a.identification.eigenvalues)
    # the verdicts' own eig(A + B K) (A, B from the FMU, K through the connections) ...
    np.testing.assert_allclose(a.continuous, expected, atol=1e-12)
    # ... and the identification from runs at 1e-5 wing beats agrees with it to 1e-6
    assert result.continuous_deviation[instance] <= 1e-6


def test_hover_ssp_describes_four_fmus_both_loops(hover_ssp):
    system = System.from_ssp(hover_ssp)
    assert set(system.fmus) == {"lateral", "lateral_controller", "longitudinal",
                                "longitudinal_controller"}
    wires = {str(c) for c in system.connections}
    assert len(wires) == 4 + 3 + 4 + 4  # states to both controllers, controls to both plants
    for s in ("delta_v", "delta_p", "delta_r", "delta_gamma"):
        assert f"lateral.{s} -> lateral_controller.{s}" in wires
    for s in ("delta_u", "delta_w", "delta_q", "delta_theta"):
        assert f"longitudinal.{s} -> longitudinal_controller.{s}" in wires
    for u in ("delta_Phi", "delta_alpha_1", "delta_phibar", "delta_alpha_2"):
        assert f"longitudinal_controller.{u} -> longitudinal.{u}" in wires
    assert not any(c.source.startswith("lat") == c.target.startswith("lon")
                   for c in system.connections)  # the axes are not coupled


def test_default_hover_system_lateral_neutral_longitudinal_stable(hover_ssp, monkeypatch):
    import dronefly.harness.stability.system_verdicts as run_module

    def no_open_loop(*args, **kw):
        raise AssertionError("open-loop runs without open_loop")

    monkeypatch.setattr(run_module, "open_loop_verdicts", no_open_loop)
    r = cosimulate_system(hover_ssp, stop_wingbeats=30, out_dir=None)
    assert r.run.complete and len(r.run.time) == 301
    assert r.open_loop is None and r.check_failures == []
    assert "open loop" not in r.summary() and "open_loop" not in r.to_json()["axes"][0]
    _check_axis(r, "lateral", "neutral", _eig_lateral(np.array(PAPER_GAINS_EQ27)))
    _check_axis(r, "longitudinal", "stable",
                _eig_longitudinal(np.array(LONGITUDINAL_GAINS_DESIGN_B)))
    # design (b): the oscillatory pair mirrored, the others kept
    lon = _axes(r)["longitudinal"].continuous
    A, _ = longitudinal_dynamics.system_matrices(longitudinal_dynamics.default_parameters())
    open_loop = sort_eigenvalues(np.linalg.eigvals(np.asarray(A)))
    pair = [z for z in open_loop if abs(z.imag) > 1e-9]
    assert sorted(-z.real for z in pair) == pytest.approx(
        sorted(z.real for z in lon if abs(z.imag) > 1e-9), abs=1e-12)


def test_design_a_makes_the_longitudinal_loop_neutral(hover_ssp):
    from dronefly.harness.paper.longitudinal import design

    k = design("neutral", ("delta_phibar",)).K[PHIBAR_ROW]
    r = cosimulate_system(hover_ssp, stop_wingbeats=30, out_dir=None,
                          set_values=_set_row("longitudinal_controller", PHIBAR_ROW, k))
    _check_axis(r, "longitudinal", "neutral", _eig_longitudinal(k))
    _check_axis(r, "lateral", "neutral", _eig_lateral(np.array(PAPER_GAINS_EQ27)))


def _eig_open(model) -> np.ndarray:
    A, _ = model.system_matrices(model.default_parameters())
    return np.array(sort_eigenvalues(np.linalg.eigvals(np.asarray(A))))


@pytest.mark.parametrize("master", ["gauss-seidel", "jacobi"])
def test_open_loop_is_unstable_in_both_axes(hover_ssp, master):
    """open_loop: after the closed loop (unchanged), each plant's loop with its controller's
    gains zeroed, identified and checked against eig(A) of the models (not the FMUs)."""
    r = cosimulate_system(hover_ssp, stop_wingbeats=30, out_dir=None, master=master,
                          open_loop=True)
    if master == "gauss-seidel":
        _check_axis(r, "lateral", "neutral", _eig_lateral(np.array(PAPER_GAINS_EQ27)))
        _check_axis(r, "longitudinal", "stable",
                    _eig_longitudinal(np.array(LONGITUDINAL_GAINS_DESIGN_B)))
    else:  # the Jacobi loop's delay modes: no comparison with eig(A + B K)
        assert [(a.plant.instance, a.verdict) for a in r.axes] == [
            ("lateral", "neutral"), ("longitudinal", "stable")]
        assert set(r.continuous_deviation.values()) == {None}
    lat, lon = r.open_loop["lateral"], r.open_loop["longitudinal"]
    for o, model, rows in ((lat, lateral_dynamics, 3), (lon, longitudinal_dynamics, 4)):
        expected = _eig_open(model)
        assert o.verdict == "unstable"
        np.testing.assert_allclose(o.continuous, expected, atol=1e-12)
        np.testing.assert_allclose(o.identification.dominant_growth_rate,
                                   max(expected.real), atol=1e-6)
        assert r.open_loop_deviation[o.plant.instance] <= 1e-6
        assert set(o.plant.gains) == {gain_name(i, j) for i in range(rows) for j in range(4)}
    assert lat.identification.dominant_growth_rate == pytest.approx(0.0786, abs=5e-5)
    pair = [z for z in lon.identification.eigenvalues if abs(z.imag) > 1e-3]
    assert len(pair) == 2 and all(abs(z - complex(0.0481, np.sign(z.imag) * 0.0976)) < 5e-5
                                  for z in pair)
    assert r.check_failures == []
    j = r.to_json()["axes"]
    assert [a["open_loop"]["verdict"] for a in j] == ["unstable", "unstable"]
    assert j[0]["open_loop"]["zeroed"][0] == "lateral_controller.K[1,1]"
    assert j[0]["open_loop"]["continuous_check"]["passed"] is True


def test_open_loop_names_a_plant_without_gains_to_zero(built_fmus):
    """A plant driven by an instance without gains K[i,j] (here the other plant's pitch into
    the roll control) is not guessed at; a plant with no input connected is its open loop."""
    system = System({"lateral": built_fmus["DroneFlyLateral"],
                     "longitudinal": built_fmus["DroneFlyLongitudinal"]},
                    [Connection("longitudinal", "delta_theta", "lateral", "delta_Phi_a")], {})
    r = cosimulate_system(system, stop_wingbeats=2, out_dir=None, open_loop=True)
    assert r.open_loop["lateral"].verdict is None
    assert ("  open loop: not identified (longitudinal has no gains K[i,j] for the inputs of "
            "lateral to set to zero)") in r.summary().splitlines()
    lon = r.open_loop["longitudinal"]
    assert lon.verdict == "unstable" and lon.plant.gains == ()
    np.testing.assert_allclose(lon.continuous, _eig_open(longitudinal_dynamics), atol=1e-12)
    assert r.open_loop_deviation["longitudinal"] <= 1e-6 and r.check_failures == []


def test_cli_a_failed_cross_check_exits_1_with_the_outputs(hover_ssp, tmp_path, capsys):
    """A saturating lateral controller is not the linear law of its gains: its identified loop
    is far from eig(A + B K), which must fail the command (the open loop still passes)."""
    out = tmp_path / "o"
    code = main(["cosim", "--system", str(hover_ssp), "--stop", "5", "--no-plot", "--out",
                 str(out), "--open-loop", "--set", "lateral_controller.limit_enabled=1",
                 "--set", "lateral_controller.u_max=1e-9"])
    cap = capsys.readouterr()
    assert code == 1, cap.err
    lines = cap.out.splitlines()
    assert sum("cross-check failed" in ln for ln in lines) == 1
    assert [ln.startswith("  eig(A + B K)") for ln in lines if "cross-check failed" in ln] == [True]
    assert "lateral: the eigenvalues identified at a step of 1e-05 wing beats deviate from " \
           "eig(A + B K) by" in cap.err
    assert cap.err.count("\n") == 1 and "Traceback" not in cap.err
    assert sorted(p.suffix for p in out.iterdir()) == [".csv", ".json"]
    j = json.loads(next(out.glob("*.json")).read_text())
    assert len(j["check_failures"]) == 1 and j["complete"]
    assert [a["continuous_check"]["passed"] for a in j["axes"]] == [False, True]
    assert [a["open_loop"]["continuous_check"]["passed"] for a in j["axes"]] == [True, True]


def test_cli_open_loop_cross_check_is_enforced_too(hover_ssp, tmp_path, capsys, monkeypatch):
    """With a tolerance no identification meets, every check fails, the open loop's too."""
    import dronefly.harness.stability.system_verdicts as run_module

    monkeypatch.setattr(run_module, "CHECK_TOL_PER_WINGBEAT", 1e-14)
    code = main(["cosim", "--system", str(hover_ssp), "--stop", "2", "--no-plot", "--out",
                 str(tmp_path / "o"), "--open-loop"])
    err = capsys.readouterr().err
    assert code == 1
    assert err.count("eig(A) (open loop)") == 2 and err.count("eig(A + B K)") == 2


def test_cli_open_loop_needs_a_system(tmp_path, capsys):
    code = main(["cosim", "--open-loop", "--no-plot", "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err
    assert code == 2 and "--open-loop needs --system" in err and err.count("\n") == 1


def test_write_system_ssp_round_trip(built_fmus, tmp_path):
    system = hover_system(built_fmus, x0_lateral=(0.1, 0, 0, 0), x0_longitudinal=(0, 0, 0.2, 0),
                          stop_wingbeats=12.5)
    path = write_system_ssp(system, tmp_path / "round.ssp", description="round trip")
    back = System.from_ssp(path)
    assert set(back.fmus) == set(system.fmus)
    assert {str(c) for c in back.connections} == {str(c) for c in system.connections}
    assert back.parameters == system.parameters
    assert back.stop_s == pytest.approx(system.stop_s, rel=1e-15)
    with zipfile.ZipFile(path) as z:
        assert {"SystemStructure.ssd"} <= set(z.namelist())
        assert sum(n.startswith("resources/") and n.endswith(".fmu") for n in z.namelist()) == 4
    names = ["lateral.delta_v", "longitudinal.delta_q"]
    with SystemMaster(system) as a, SystemMaster(back) as b:
        ra, rb = a.run(0.1 / 164, 50, record=names), b.run(0.1 / 164, 50, record=names)
    np.testing.assert_array_equal(ra.signals, rb.signals)
    assert abs(ra.signals[0, 0]) > 0 and abs(ra.signals[0, 1]) > 0


def test_cli_system_json(hover_ssp, tmp_path, capsys):
    out = tmp_path / "o"
    code = main(["cosim", "--system", str(hover_ssp), "--stop", "20", "--no-plot", "--json",
                 "--out", str(out), "--record", "lateral.delta_gamma,longitudinal.delta_theta"])
    assert code == 0
    j = json.loads(capsys.readouterr().out)
    assert {a["instance"] if "instance" in a else a["plant"]["instance"]: a["verdict"]
            for a in j["axes"]} == {"lateral": "neutral", "longitudinal": "stable"}
    assert j["recorded"] == ["lateral.delta_gamma", "longitudinal.delta_theta"]
    assert sorted(p.suffix for p in out.iterdir()) == [".csv", ".json"]


def test_cli_system_typed_values_and_recording_any_variable(hover_ssp, tmp_path, capsys):
    """A Boolean parameter set with 1 (the limit on), array elements, inputs, parameters and
    a Boolean output recorded: the plant's input is the controller's output, limited."""
    out = tmp_path / "o"
    record = ("lateral_controller.K[1,4],lateral_controller.saturated,lateral.delta_Phi_a,"
              "lateral_controller.limit_enabled,lateral_controller.delta_Phi_a")
    code = main(["cosim", "--system", str(hover_ssp), "--stop", "2", "--no-plot", "--json",
                 "--out", str(out), "--set", "lateral_controller.limit_enabled=1",
                 "--set", "lateral_controller.u_max=0.005", "--record", record])
    assert code == 1  # the saturating loop is not eig(A + B K): the cross-check fails
    j = json.loads(capsys.readouterr().out)
    assert j["recorded"] == ["lateral_controller.K[1,4]", *record.split(",")[2:]]
    rows = np.loadtxt(j["csv"], delimiter=",", skiprows=1)
    assert rows.shape == (21, 6)
    assert np.all(rows[:, 1] == PAPER_GAINS_EQ27[3]) and np.all(rows[:, 4] == 1.0)
    assert np.array_equal(rows[:, 3], rows[:, 5])  # the input as set for the step
    assert rows[0, 2] == 1.0 and rows[0, 3] == -0.005  # K x = -0.00643, limited
    assert np.all(np.abs(rows[:, 3]) <= 0.005)


@pytest.mark.parametrize("extra, fragment", [
    (["--gains", "open"], "--gains cannot be combined with --system"),
    (["--set", "nosuch.K[1,1]=0"], "nosuch"),
    (["--set", "lateral_controller.K[9,9]=0"], "K[9,9]"),
    (["--record", "lateral.nosuch"], "lateral.nosuch"),
    (["--set", "lateral_controller.limit_enabled=2"],
     "lateral_controller.limit_enabled = '2': a Boolean takes true, false, 1 or 0"),
    (["--set", "lateral_controller.K[1,1]=true"], "lateral_controller.K[1,1] = 'true' is not a number"),
    (["--set", "lateral_controller.K[1,1]=nan"], "lateral_controller.K[1,1] = 'nan' is not finite"),
    (["--set", "lateral_controller.saturated=1"], "lateral_controller.saturated: no parameter or input"),
    (["--step", "0"], "step"),
])
def test_cli_system_bad_input_exit_2_one_line(hover_ssp, tmp_path, capsys, extra, fragment):
    out = tmp_path / "o"
    code = main(["cosim", "--system", str(hover_ssp), "--stop", "5", "--no-plot",
                 "--out", str(out), *extra])
    err = capsys.readouterr().err
    assert code == 2, err
    assert err.count("\n") == 1 and fragment in err and "Traceback" not in err
    assert not out.exists() or not any(out.iterdir())


@pytest.mark.parametrize("path, fragment", [("missing.ssp", "does not exist"), (".", "folder")])
def test_cli_system_missing_file(tmp_path, capsys, path, fragment):
    code = main(["cosim", "--system", str(tmp_path / path), "--no-plot", "--out", str(tmp_path)])
    err = capsys.readouterr().err
    assert code == 2 and fragment in err and err.count("\n") == 1


def test_cli_system_not_an_ssp(tmp_path, capsys):
    bad = tmp_path / "bad.ssp"
    bad.write_bytes(b"not a zip")
    code = main(["cosim", "--system", str(bad), "--no-plot", "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err
    assert code == 2 and "bad.ssp" in err and err.count("\n") == 1


def test_ctrl_c_stops_the_system_master_between_steps(hover_ssp, monkeypatch, sigint_as_in_a_terminal):
    """SIGINT during a run (sent at the master's 100th check between steps, tests/sigint_at.py):
    all instances terminated, KeyboardInterrupt, the master closes."""
    system = System.from_ssp(hover_ssp)
    install_at_check(monkeypatch, 100)
    with SystemMaster(system) as m:
        with pytest.raises(KeyboardInterrupt):
            m.run(1e-4 / 164, 1_000_000, record=["lateral.delta_v"])
        r = m.run(0.1 / 164, 10, record=["lateral.delta_v"])  # still usable afterwards
    assert r.complete


def test_docs_systems_numbers_are_the_code_s(hover_ssp):
    """docs/systems.md: the printed summary is what the command prints, the design (a) gains
    are the design's."""
    import re
    from pathlib import Path

    from dronefly.harness.paper.longitudinal import design

    doc = (Path(__file__).resolve().parents[1] / "docs" / "systems.md").read_text()
    blocks = [b.split("```", 1)[0].splitlines() for b in doc.split("prints\n\n```\n")[1:]]
    assert len(blocks) == 2  # the default output, then --open-loop's
    for printed, open_loop in zip(blocks, (False, True)):
        r = cosimulate_system(hover_ssp, stop_wingbeats=60, out_dir=None, open_loop=open_loop)
        # numbers to a unit of their last digit (tests/docnumbers.py); the cross-check prints
        # its tolerance, not the round-off-dominated deviation
        diff = same_numbers(r.summary(), "\n".join(ln for ln in printed if not ln.startswith("csv:")))
        assert diff is None, diff
    from dronefly.harness.stability.system_verdicts import CHECK_STEP_WB, CHECK_TOL_PER_WINGBEAT

    assert "by more than 1e-6 per\nwing beat at the 1e-5 step" in doc
    assert (CHECK_TOL_PER_WINGBEAT, CHECK_STEP_WB) == (1e-6, 1e-5)
    k = design("neutral", ("delta_phibar",)).K[PHIBAR_ROW]
    given = {int(j): float(v) for j, v in
             re.findall(r"longitudinal_controller\.K\[3,(\d)\]=(-?[0-9.]+)", doc)}
    assert given == pytest.approx({j + 1: v for j, v in enumerate(k)}, abs=5e-9)


def test_recording_the_same_variables_of_fmi3_and_fmi2_fmus(hover_ssp, built_fmus3):
    """Array elements of FMI 3.0 FMUs (K and A are arrays there, their elements virtual
    value references) and a Boolean: recorded as from the FMI 2.0 FMUs."""
    names = ["lateral_controller.K[1,4]", "longitudinal.A[1,1]", "lateral_controller.saturated",
             "lateral.delta_Phi_a", "lateral.delta_gamma"]
    values = {"lateral_controller": {"limit_enabled": "1", "u_max": 0.005}}
    runs = []
    for ssp in (hover_ssp, built_fmus3["DroneFlyHover.ssp"]):
        with SystemMaster(System.from_ssp(ssp)) as m:
            runs.append(m.run(0.1 / 164, 10, record=names, values=values))
    assert runs[0].complete and runs[1].complete and not np.isnan(runs[1].signals).any()
    np.testing.assert_allclose(runs[1].signals, runs[0].signals, rtol=1e-12, atol=0)
    A, _ = longitudinal_dynamics.system_matrices(longitudinal_dynamics.default_parameters())
    assert runs[1].signals[0, :3].tolist() == [PAPER_GAINS_EQ27[3], np.asarray(A)[0, 0], 1.0]


def test_values_given_as_text_reach_the_verdicts_typed(hover_ssp):
    """--set gives text: the plant's A read for the verdict (its calculated parameters with
    the values set) and K come from the typed values, as eig(A + B K) computed here says."""
    r = cosimulate_system(hover_ssp, stop_wingbeats=10, out_dir=None,
                          set_values={"lateral.Lv_plus": "0.5", "lateral_controller.K[1,1]": "0.1",
                                      "lateral_controller.limit_enabled": "0"})
    A, B = lateral_dynamics.system_matrices(lateral_dynamics.default_parameters().with_values(
        Lv_plus=0.5))
    K = np.zeros((3, 4))
    K[0] = PAPER_GAINS_EQ27
    K[0, 0] = 0.1
    expected = sort_eigenvalues(np.linalg.eigvals(np.asarray(A) + np.asarray(B) @ K))
    _check_axis(r, "lateral", "unstable", expected)
