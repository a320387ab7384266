"""FMI 3.0 builds: the same model and controller code behind pythonfmu3.

Every FMU of the project as an FMI 3.0 Co-Simulation FMU: fmpy validate clean; arrays, the
independent variable, units and dependencies in the model description; the slave's FMI 3.0
answers (statuses, arrays, states); co-simulation through fmpy's FMU3Slave equal to FMI 2.0
(pairs, the closed-loop SSP and the hover system, FMI 3.0 only and mixed); dronefly check on
every FMI 3.0 FMU, and broken ones (one defect per FMI 3.0 check, and a crash) failing it.
"""

from __future__ import annotations

import math
import re
import os
import zipfile
from pathlib import Path
from xml.etree import ElementTree as ET

import numpy as np
import pytest

from dronefly.harness.builder.build import FMUS

pytestmark = pytest.mark.integration

# -- the slave in this process (no FMU built) -----------------------------------------------


@pytest.fixture
def feedback3():
    from dronefly.controller.slave import StateFeedback
    from dronefly.fmi.base3 import fmi3_class

    return fmi3_class(StateFeedback)(instance_name="c3")


def _vr(slave, name):
    return next(vr for vr, e in enumerate(slave.TABLE3) if e.name == name)


def test_slave_arrays_time_and_statuses(feedback3):
    s = feedback3
    K = _vr(s, "K")
    assert s.TABLE3[0].name == "time" and s.TABLE3[K].dims == (3, 4)
    assert s.do_step(0.0, 1e-3).status == 3  # fmi3Error: not initialized
    assert "fmi3DoStep is not allowed in state 'instantiated'" in s.log_queue[-1].msg
    s.enter_initialization_mode()
    s.exit_initialization_mode()
    k = s.get_float64([K])
    assert len(k) == 12 and k[0] == pytest.approx(-0.3192)
    s.set_float64([K], [0.0] * 12)
    s.set_float64([_vr(s, "delta_p")], [1.0])
    assert s.get_float64([_vr(s, "delta_Phi_a")]) == [0.0]
    s.set_float64([K], [1.0] * 3)  # too few values for a 3 x 4 array
    msg = s.log_queue[-1]
    assert "12 values needed, 3 given" in msg.msg and msg.status == 3 and msg.debug is False
    assert s.do_step(0.5, 1e-3).status == 3  # the rejected set, named
    assert s.do_step(0.5, 1e-3).status == 0  # the first step's time is the start (pythonfmu3)
    assert s.get_float64([0]) == [0.501]
    s.set_float64([_vr(s, "delta_v")], [math.nan])
    assert s.do_step(0.501, 1e-3).status == 2  # fmi3Discard: a bad value
    assert "delta_v = nan" in s.log_queue[-1].msg
    assert math.isnan(s.get_float64([2 ** 30])[0])  # logged, never raises
    assert "fmi3GetFloat64 of valueReference 1073741824" in s.log_queue[-1].msg


def test_slave_state_round_trip_and_foreign_state(feedback3):
    from dronefly.controller.slave import StateFeedback

    s = feedback3
    s.enter_initialization_mode()
    s.exit_initialization_mode()
    assert s.do_step(0.25, 1e-3).status == 0
    blob = type(s)._fmu_state_to_bytes(s._get_fmu_state())
    fmi2 = StateFeedback(instance_name="c2")
    s.do_step(0.251, 1e-3)
    s._set_fmu_state(type(s)._fmu_state_from_bytes(blob))
    assert s._time == 0.251 and s._t0_known
    s._set_fmu_state(fmi2._get_fmu_state())  # a state of the FMI 2.0 class: refused
    assert "fmi3SetFMUState refused" in s.log_queue[-1].msg


def test_slave_warns_off_the_grid_naming_fmi_3(feedback3):
    """The off-grid warning names the FMU's own standard: 'FMI 3.0 co-simulation'."""
    from dronefly.models.lateral_interface import N_HZ

    s = feedback3
    s.enter_initialization_mode()
    s.set_float64([_vr(s, "sample_period")], [0.3 / N_HZ])
    s.exit_initialization_mode()
    assert s.do_step(0.0, 1.0 / N_HZ).status == 0
    [msg] = [m for m in s.log_queue if m.status == 1]
    assert "(FMI 3.0 co-simulation)" in msg.msg and "FMI 2.0" not in msg.msg, msg.msg


def test_fmi3_binary_folder_is_the_loaded_librarys_or_this_machines_platform_tuple(
        monkeypatch, tmp_path):
    """The exit handler of pythonfmu3's binary (binaries/<platform tuple>/<model>.so) is
    registered for the folder the host loaded it from (an aarch64-linux FMU: aarch64-linux),
    else this machine's FMI 3.0 platform tuple (the standard's <arch>-<sys> names)."""
    from dronefly.fmi import host

    assert [host.platform_tuple(m, s) for m, s in (
        ("x86_64", "Linux"), ("aarch64", "Linux"), ("AMD64", "Windows"), ("arm64", "Darwin"),
        ("i686", "Linux"), ("armv7l", "Linux"), ("riscv64", "Linux"))] == [
        "x86_64-linux", "aarch64-linux", "x86_64-windows", "aarch64-darwin", "x86-linux",
        "aarch32-linux", "riscv64-linux"]
    lib = tmp_path / "fmu" / "binaries" / "aarch64-linux" / "M.so"
    monkeypatch.setattr(host, "loaded_libraries", lambda: {str(lib): [str(lib)]})
    resources = "/" + str(tmp_path / "fmu" / "resources")  # '//tmp/...', as hosts may spell it
    assert host.binary_folder3(resources, "M") == "aarch64-linux"
    registered = []
    monkeypatch.setattr("atexit.register", lambda f, path: registered.append(path))
    host.finalize_at_exit(resources, "M", host.binary_folder3(resources, "M"))
    assert [os.path.normpath("/" + p.lstrip("/")) for p in registered] == [str(lib)]
    monkeypatch.setattr(host, "loaded_libraries", dict)  # none loaded from this FMU
    monkeypatch.setattr("platform.machine", lambda: "aarch64")
    assert host.binary_folder3(str(tmp_path / "other" / "resources"), "M") == "aarch64-linux"


# -- the built FMUs --------------------------------------------------------------------------


def test_fmi3_binary_releases_its_interpreter_guard_at_exit(built_fmus3):
    """pythonfmu3's binary (binaries/x86_64-linux/<model>.so) frees its interpreter guard twice
    at process exit unless an exit handler released it first (fmi/host.py): the FMU
    registers that handler for the library the host loaded. Without it an Ecos child aborted
    at exit ("corrupted double-linked list") in 6 of 30 runs of build/fmi3/DroneFlyHover.ssp."""
    import posixpath
    import sys

    from dronefly.harness.cosim.fmu import FMU

    with FMU(built_fmus3["StateFeedback"]) as fmu, fmu.instantiate("guard"):
        hosts = [m for n, m in sys.modules.items()
                 if n.startswith("dronefly3_statefeedback_") and n.endswith(".fmi.host")]
        assert hosts
        guarded = {posixpath.normpath(lib) for h in hosts for lib in h.guarded_libraries()}
        loaded = hosts[0].loaded_libraries()
        assert [lib for lib in guarded if lib in loaded
                and lib.endswith("/binaries/x86_64-linux/StateFeedback.so")]


def _md(path):
    with zipfile.ZipFile(path) as z:
        return ET.fromstring(z.read("modelDescription.xml"))


def test_every_fmu_built_and_validate_clean(built_fmus3):
    from fmpy.validation import validate_fmu

    assert set(FMUS) <= set(built_fmus3)
    assert {"DroneFlyClosedLoop.ssp", "DroneFlyHover.ssp",
            "DroneFlyHover6DOF.ssp"} <= set(built_fmus3)
    for name in FMUS:
        assert validate_fmu(str(built_fmus3[name])) == [], name
        assert _md(built_fmus3[name]).get("fmiVersion") == "3.0"


def _scalar_deps(md2, index_attr):
    """{name: set of dependency names} of an FMI 2.0 ModelStructure section."""
    names = [sv.get("name") for sv in md2.find("ModelVariables")]
    out = {}
    for u in md2.find("ModelStructure").find(index_attr) or []:
        deps = u.get("dependencies")
        out[names[int(u.get("index")) - 1]] = None if deps is None else {
            names[int(i) - 1] for i in deps.split()}
    return out


def _array_of(name):
    return name.split("[")[0]


#: the arrays of each FMU: (states x states) A, (states x controls) B, (controls x states) gains
#: K and KI; lateral 4 states (v, p, r, gamma) and 3 controls (Phi_a, alpha_1a, alpha_2a),
#: longitudinal 4 (u, w, q, theta) and 4 (Phi, alpha_1, phibar, alpha_2); the 6-DOF plant has
#: no matrices
ARRAYS = {"DroneFlyLateral": {"A": [4, 4], "B": [4, 3]},
          "DroneFlyLongitudinal": {"A": [4, 4], "B": [4, 4]},
          "StateFeedback": {"K": [3, 4], "KI": [3, 4]},
          "StateFeedbackDelayed": {"K": [3, 4], "KI": [3, 4]},
          "StateFeedbackLongitudinal": {"K": [4, 4], "KI": [4, 4]},
          "StateFeedbackLongitudinalDelayed": {"K": [4, 4], "KI": [4, 4]},
          "DroneFlyHover6DOF": {}, "DroneFlyFlapping": {}}


def test_arrays_cover_every_fmu():
    assert set(ARRAYS) == set(FMUS)


@pytest.mark.parametrize("name", list(ARRAYS))
def test_model_description_arrays_units_dependencies(built_fmus, built_fmus3, name):
    md2, md3 = _md(built_fmus[name]), _md(built_fmus3[name])
    vars3 = list(md3.find("ModelVariables"))
    by_vr = {int(v.get("valueReference")): v for v in vars3}
    assert by_vr[0].get("name") == "time" and by_vr[0].get("causality") == "independent"
    arrays = {v.get("name"): [int(d.get("start")) for d in v.findall("Dimension")]
              for v in vars3 if v.findall("Dimension")}
    grids: dict[str, list[int]] = {}  # every M[i,j] of the FMI 2.0 table: its largest i, j
    for sv in md2.find("ModelVariables"):
        if "[" in sv.get("name"):
            m, ij = sv.get("name")[:-1].split("[")
            grids[m] = [max(a, int(b)) for a, b in zip(grids.get(m, [0, 0]), ij.split(","))]
    assert arrays == grids == ARRAYS[name]
    assert all(v.tag == "Float64" and v.get("unit") for v in vars3 if v.get("name") in arrays)
    units2 = {sv.get("name"): (sv[0].get("unit"), sv[0].get("displayUnit")) for sv in
              md2.find("ModelVariables") if "[" not in sv.get("name")}
    for v in vars3[1:]:
        if v.get("name") in units2:
            assert (v.get("unit"), v.get("displayUnit")) == units2[v.get("name")]
            assert v.get("description")
    # every FMI 3.0 dependency list is the FMI 2.0 one with the elements collapsed to arrays
    names3 = {int(v.get("valueReference")): v.get("name") for v in vars3}
    for tag2, tag3 in (("Outputs", "Output"), ("InitialUnknowns", "InitialUnknown")):
        deps2 = _scalar_deps(md2, tag2)
        want: dict[str, set | None] = {}
        for n, d in deps2.items():
            a = _array_of(n)
            want[a] = None if d is None or want.get(a, set()) is None else (
                want.get(a, set()) | {_array_of(x) for x in d})
        got = {names3[int(u.get("valueReference"))]:
               None if u.get("dependencies") is None
               else {names3[int(i)] for i in u.get("dependencies").split()}
               for u in md3.find("ModelStructure").findall(tag3)}
        assert got == want, tag3


def _pair(plant, controller, master):
    from dronefly.harness.stability.run import cosimulate

    return cosimulate(plant, controller, master=master, stop_wingbeats=60, out_dir=None,
                      plot=False, set_values={"controller.K[1,2]": -0.25})


@pytest.mark.parametrize("master", ["gauss-seidel", "jacobi"])
def test_pair_fmi3_and_mixed_equal_fmi2(built_fmus, built_fmus3, master):
    """The lateral loop (with a gain set by element name) through fmpy's FMU3Slave: FMI 3.0
    only and mixed (FMI 2.0 plant, FMI 3.0 controller, and the reverse) equal FMI 2.0."""
    p2, c2 = built_fmus["DroneFlyLateral"], built_fmus["StateFeedback"]
    p3, c3 = built_fmus3["DroneFlyLateral"], built_fmus3["StateFeedback"]
    ref = _pair(p2, c2, master)
    assert ref.run.complete and len(ref.run.signals) == 601
    for p, c in ((p3, c3), (p2, c3), (p3, c2)):
        r = _pair(p, c, master)
        assert r.run.complete and r.verdict == ref.verdict
        assert np.max(np.abs(r.run.signals - ref.run.signals)) <= 1e-12


def test_hover_system_fmi3_ssp_and_mixed_equal_fmi2(built_fmus, built_fmus3):
    """The four-FMU hover system: from build/fmi3/DroneFlyHover.ssp (FMI 3.0 FMUs) and mixed
    (FMI 2.0 plants, FMI 3.0 controllers) equal to the FMI 2.0 system; same verdicts (the
    trajectories decide them: the mixed run's verdicts are not identified again)."""
    from dronefly.harness.stability.system_verdicts import cosimulate_system
    from dronefly.harness.cosim.ssp import hover_system

    kw = dict(stop_wingbeats=60, out_dir=None, plot=False)
    ref = cosimulate_system(built_fmus["DroneFlyHover.ssp"], verdicts=False, **kw)
    mixed = {m: (built_fmus3 if m.startswith("StateFeedback") else built_fmus)[m]
             for m in FMUS}
    for system, verdicts in ((built_fmus3["DroneFlyHover.ssp"], True),
                             (hover_system(mixed), False)):
        r = cosimulate_system(system, verdicts=verdicts, **kw)
        assert r.run.complete and r.run.names == ref.run.names
        assert np.max(np.abs(r.run.signals - ref.run.signals)) <= 1e-12
        if verdicts:
            # the FMI 2.0 system's verdicts (tests/test_hover_system.py)
            assert [a.verdict for a in r.axes] == ["neutral", "stable"]


def test_closed_loop_ssp_fmi3_equals_fmi2(built_fmus, built_fmus3, tmp_path):
    """build/fmi3/DroneFlyClosedLoop.ssp (FMI 3.0 FMUs, SSP 1.0) in our master: the paper's
    neutral verdict and the FMI 2.0 SSP's trajectory over its 300 wing beats, to 1e-12. Its
    controller.ssv binds no K (SSP 1.0 binds scalars, K is an FMI 3.0 array: its start values
    are the gains); gains other than the FMUs' defaults, bound in the FMI 2.0 SSP and set with
    --set controller.K[i,j] on the FMI 3.0 one, still agree, and differ from the default run."""
    from dronefly.models.feedback import default_gains
    from dronefly.harness.builder.closedloop import ClosedLoopSpec
    from dronefly.harness.cosim.master import CoSimError
    from dronefly.harness.builder.closedloop import write_ssp
    from dronefly.harness.interop.ssp import run_ssp
    from dronefly.harness.stability.system_verdicts import cosimulate_system

    kw = dict(out_dir=None, plot=False)
    ref = cosimulate_system(built_fmus["DroneFlyClosedLoop.ssp"], verdicts=False, **kw)
    r = cosimulate_system(built_fmus3["DroneFlyClosedLoop.ssp"], **kw)
    assert r.run.complete and r.run.names == ref.run.names and len(r.run.time) == 3001
    assert np.max(np.abs(r.run.signals - ref.run.signals)) <= 1e-12
    assert [(a.plant.instance, a.verdict) for a in r.axes] == [("plant", "neutral")]
    with pytest.raises(CoSimError, match="simulate_ssp runs FMI 2.0 FMUs only"):
        run_ssp(built_fmus3["DroneFlyClosedLoop.ssp"])  # fmpy instantiates FMU2Slave only
    gains = [list(row) for row in default_gains()]
    gains[0][1], gains[1][0] = -0.25, 0.1
    spec = ClosedLoopSpec(gains=tuple(map(tuple, gains)), stop_wingbeats=60)
    runs = [cosimulate_system(write_ssp(built_fmus["DroneFlyLateral"], built_fmus["StateFeedback"],
                                        tmp_path / "fmi2", spec), verdicts=False, **kw).run,
            cosimulate_system(built_fmus3["DroneFlyClosedLoop.ssp"], verdicts=False,
                              stop_wingbeats=60, set_values={"controller.K[1,2]": -0.25,
                                                             "controller.K[2,1]": 0.1}, **kw).run]
    assert all(run.complete and len(run.time) == 601 for run in runs)
    assert np.max(np.abs(runs[1].signals - runs[0].signals)) <= 1e-12
    assert np.max(np.abs(runs[1].signals - ref.run.signals[:601])) > 1e-3


@pytest.mark.parametrize("name", list(FMUS))
def test_check_passes_on_fmi3(built_fmus3, name):
    """dronefly check passes on every FMI 3.0 FMU (in this process, about 0.3 s each;
    StateFeedback in its child process, as the CLI runs it, about 1 s)."""
    from dronefly.harness.compliance.suite import check_fmu

    report = check_fmu(built_fmus3[name], fuzz=True, isolate=name == "StateFeedback")
    assert report.passed, report.checks
    names = [c.name for c in report.checks]
    assert {"state-machine", "discard", "state-refusal", "reference"} <= set(names)


def _broken_build(tmp_path, rel, old, new, name="StateFeedback"):
    """An FMI 3.0 FMU of ``name`` built with ``old`` replaced by ``new`` in its copy of the
    dronefly module ``rel`` (nothing else changed)."""
    import dronefly.harness.builder.build as build

    original = build._source_path

    def patched(path_rel):
        path = original(path_rel)
        if path_rel == rel:
            text = path.read_text()
            assert old in text, f"{old!r} not in {rel}"
            path = tmp_path / Path(rel).name
            path.write_text(text.replace(old, new))
        return path

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(build, "_source_path", patched)
        return build.build_fmu(name, tmp_path / "fmu", fmi=3)


#: a defect per FMI 3.0 check: (module, original text, broken text, the failed checks and
#: the start of each one's report line)
BROKEN3 = {
    # illegal calls (doStep before initialization, after a refused set) answered Discard
    "illegal-discard": ("fmi/base3.py", "ILLEGAL_STATUS: ClassVar[Fmi2Status] = Fmi2Status.error",
                        "ILLEGAL_STATUS: ClassVar[Fmi2Status] = Fmi2Status.discard",
                        {"state-machine": "fmi3DoStep before initialization: fmi3Discard, "
                                          "expected fmi3Error"}),
    # a step refused for a bad value (NaN input) answered OK
    "bad-value-ok": ("fmi/base3.py", "_RESULTS = {s: _StepResult(s) for s in (0, 1, 2, 3)}",
                     "_RESULTS = {s: _StepResult(0 if s == 2 else s) for s in (0, 1, 2, 3)}",
                     {"bad-input": "delta_v = nan: fmi3DoStep returned fmi3OK",
                      "discard": "a NaN input: fmi3OK, expected fmi3Discard"}),
    # corrupt state bytes taken without a refusal: fmi3SetFMUState says OK, logs nothing
    "state-taken": ("fmi/state.py", """            self._report(f"{self.FMI}Set{self.STATE_API} refused, the instance is unchanged: "
                         f"{why}", Fmi2Status.error)
            return""", "            return",
                    {"state-refusal": "corrupt state not refused in the log"}),
}


@pytest.fixture(scope="module")
def broken3(tmp_path_factory):
    """The FMUs of BROKEN3, each built once."""
    return {k: _broken_build(tmp_path_factory.mktemp(k), *v[:3]) for k, v in BROKEN3.items()}


@pytest.mark.parametrize("defect", list(BROKEN3))
def test_check_names_the_failed_fmi3_check(broken3, defect):
    """Each defect fails exactly the checks that test for it, with a report line naming the
    check and what was wrong; every other check passes (the checks are specific)."""
    from dronefly.harness.compliance.suite import check_fmu, format_reports

    report = check_fmu(broken3[defect], fuzz=False, isolate=False)
    failed = {c.name: c.detail for c in report.checks if not c.passed}
    expected = BROKEN3[defect][3]
    assert set(failed) == set(expected), failed
    text = format_reports([report])
    for name, detail in expected.items():
        assert failed[name].startswith(detail)
        assert f"[FAIL] {name:<14} {detail}" in text
    assert text.splitlines()[0].endswith(": FAIL (profile dronefly)")
    assert "0 of 1 FMUs passed" in text


def test_check_fails_clearly_on_a_broken_fmi3_fmu(tmp_path, capsys):
    """An FMI 3.0 FMU whose doStep raises: pythonfmu3 answers fmi3Fatal (and frees the Python
    instance while keeping its pointer, so any later call may crash the host). After Fatal no
    function of any instance may be called (FMI 3.0 2.2.3): the check fails the step that
    returned it and runs nothing more, unless the use after free kills it first."""
    from dronefly.cli.app import main

    fmu = _broken_build(tmp_path, "fmi/base3.py", "        return _RESULTS[do_step_status(self, "
                        "current_time, step_size)]", "        raise RuntimeError('broken doStep')",
                        name="DroneFlyLateral")
    assert main(["check", "--no-fuzz", str(fmu)]) == 1
    out = capsys.readouterr().out
    assert "FAIL" in out and "0 of 1 FMUs passed" in out
    assert [line for line in out.splitlines() if line.startswith("  [  ok]")] == [
        "  [  ok] validate       no problems (FMPy's validation and the rules of "
        "docs/compliance.md) [FMI 3.0 2.4]",
        "  [  ok] archive        binaries for x86_64-linux, x86_64-windows [FMI 3.0 2.5]",
        "  [  ok] binary         44 required functions exported; fmi3GetVersion right "
        "[FMI 3.0 2.2.1]"], out
    # The first check that steps gets fmi3Fatal and is reported so; every later check is
    # then "not run". The use after free may instead kill the checking process, in that step
    # or in any later check (up to the heap): the check it died in is reported with the
    # signal and the rest are listed as not run. Either way every check is accounted for.
    fatal = re.findall(r"\[FAIL\] (\S+) +FMICallException: fmi3DoStep failed with status 4 "
                       r"\(fatal\)", out)
    died = re.findall(r"\[FAIL\] (\S+) +the checking process died \(killed by SIG\w+\)", out)
    left = re.search(r"\[FAIL\] not run +([a-z-, ]+) \(the checking process died", out)
    skipped = re.findall(r"\[skip\] (\S+) +not run: the FMU returned fmi3Fatal in", out)
    assert len(fatal) + len(died) >= 1 and len(fatal) <= 1 and len(died) <= 1, out
    # the FMU has no Model Exchange interface: that check does not apply (or, the process
    # dead, it is among those not run)
    inapplicable = re.findall(r"\[skip\] (model-exchange) +not applicable: no Model Exchange "
                              r"interface", out)
    accounted = (fatal + died + skipped + inapplicable
                 + (left.group(1).split(", ") if left else []))
    order = ["call-sequence", "start-values", "dependencies", "reset", "two-instances", "state",
             "model-exchange", "bad-input", "reference", "logger-format", "state-machine",
             "discard", "state-refusal"]
    assert sorted(accounted) == sorted(order), out


@pytest.mark.parametrize("name", ["StateFeedback", "DroneFlyLateral"])
def test_our_fmi3_fmus_pass_the_standard_profile(built_fmus3, name):
    """Our FMI 3.0 FMUs under the standard's profile as well as ours: an illegal step size (0,
    < 0) is fmi3Error with a logged message (FMI 3.0 2.2.4), and fmi3Reset recovers the
    instance. The first step after initialization may start anywhere: pythonfmu3 does not pass
    the start time to the slave (docs/fmi3.md), so that case is OK, a warning of the check."""
    from dronefly.harness.compliance.checker import CheckOptions
    from dronefly.harness.compliance.suite import check_fmu

    std = check_fmu(built_fmus3[name], fuzz=False, isolate=False,
                    options=CheckOptions(profile="standard"))
    assert std.profile == "standard" and std.passed, std.checks
    (bad,) = [c for c in std.checks if c.name == "bad-input"]
    assert bad.detail.count(": Error") == 2 and "communicationStepSize = 0.0: Error" in bad.detail
    assert "currentCommunicationPoint" in bad.warning and "returned fmi3OK" in bad.warning
    ours = check_fmu(built_fmus3[name], fuzz=False, isolate=False,
                     options=CheckOptions(only=("bad-input",)))
    assert ours.profile == "dronefly" and ours.passed
