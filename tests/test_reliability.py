"""Reliability of the built FMUs in a host process: the fuzz, and processes that must exit 0.

Every case runs in a child process (a crash is counted, never fatal to pytest). The fuzz runs
on every FMU that ``dronefly build`` produces, so a new FMU is covered from its first build.
"""

from __future__ import annotations

import json
import math
import os
import shutil
import subprocess
import sys
import textwrap
import zipfile
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import pytest

from dronefly.harness.builder.build import FMUS, NEEDS_NUMPY
from dronefly.harness.compliance.fuzz import fuzz_fmu
from fmu_helpers import build_crashing_fmu, model_description
from shared_files import ON_CI

pytestmark = pytest.mark.integration

HOST = Path(__file__).parent / "c_host" / "ctypes_host.py"

BUILT = [*FMUS, "DroneFlyClosedLoop"]
#: FMUs whose slave class another FMU shares (LinearPlantSlave, the feedback law's slave):
#: the shared code is fuzzed in full on the lateral ones; these get the same groups with fewer
#: random calls and instances (their variable tables still get every value and sequence case)
#: the delayed controllers: that slave code again, with another variable table and
#: ModelStructure; logging on only (logging off is the same code, fuzzed on the others)
_VARIANTS = {"StateFeedbackDelayed", "StateFeedbackLongitudinalDelayed"}
_SHARED = {"DroneFlyLongitudinal", "StateFeedbackLongitudinal", *_VARIANTS}
#: the FMUs fuzzed with logging on and off (one per slave class, and the container); the
#: others run the same slave classes with other tables: logging on only (suite time)
BUILT_SLAVE_CLASSES = {"DroneFlyLateral", "StateFeedback", "DroneFlyHover6DOF",
                       "DroneFlyFlapping", "DroneFlyClosedLoop"}


@pytest.mark.parametrize("name", BUILT)
def test_fuzz_finds_no_crash_no_fatal_no_silent_refusal(built_fmus, name):
    # the container nests the lateral FMUs (fuzzed in full above): fewer random calls too; the
    # flapping plant's steps cost 100 times the others' (suite time)
    small = name in _SHARED or name == "DroneFlyClosedLoop" or name in NEEDS_NUMPY
    report = fuzz_fmu(built_fmus[name], seed=1, random_calls=60 if small else 300,
                      instances=10 if small else 50,
                      logging=(True, False) if name in BUILT_SLAVE_CLASSES else (True,))
    assert not report.crashes, report.summary()
    assert report.fatal == 0, report.summary()
    assert report.passed, report.summary()
    counts = report.status_counts()
    # the fuzz did reach refusals (not a run of OKs), with logging on and off
    assert counts.get("Discard", 0) + counts.get("Error", 0) > 50, counts
    assert (any(c.case.endswith("(logging off)") for c in report.cases)
            or name not in BUILT_SLAVE_CLASSES)
    assert len(report.cases) > 200


_CHILD = textwrap.dedent("""
    import math, sys
    from dronefly.harness.cosim.fmu import FMU
    paths, err = sys.argv[1:4], sys.argv[4] == "1"
    for path in paths:
        with FMU(path) as f, f.instantiate("x", logging=err) as inst:
            s = inst.slave
            s.setupExperiment(startTime=0.0)
            s.enterInitializationMode()
            if err:
                s.setReal([f.vr(f.names("input")[0])], [math.nan])
            s.exitInitializationMode()
            try:
                s.doStep(0.0, 1e-3)
            except Exception:
                pass
""")


def test_processes_using_the_fmus_exit_cleanly(built_fmus):
    """Plant, controller, plant again in one process through fmpy, with and without errors:
    exit code 0 (a smoke test; the exit handler itself is checked under valgrind below)."""
    paths = [str(built_fmus[n]) for n in ("DroneFlyLateral", "StateFeedback", "DroneFlyLateral")]

    def run(k: int) -> subprocess.CompletedProcess:
        return subprocess.run([sys.executable, "-c", _CHILD, *paths, str(k % 2)],
                              capture_output=True, text=True, timeout=120)

    with ThreadPoolExecutor(max_workers=2) as pool:
        results = list(pool.map(run, range(4)))
    bad = [(r.returncode, r.stderr[-300:]) for r in results if r.returncode != 0]
    assert not bad, f"{len(bad)} of 4 processes failed: {bad[:3]}"


def _host_args(fmu: Path, folder: Path) -> list[str]:
    """The ctypes host's arguments for ``fmu`` unpacked into ``folder``: 3 steps, logging on,
    its first input set to NaN (a refused step: the error paths run too)."""
    with zipfile.ZipFile(fmu) as z:
        z.extractall(folder)
    root = model_description(fmu)
    first_input = next(v for v in root.iter("ScalarVariable") if v.get("causality") == "input")
    return [str(folder), root.find("CoSimulation").get("modelIdentifier"), root.get("guid"),
            "2", "3", "--set", f"{first_input.get('valueReference')}=nan"]


@pytest.mark.skipif(shutil.which("valgrind") is None and not ON_CI,
                    reason="valgrind is not installed (.ci/setup-c-host.sh installs it; on CI "
                           "its absence fails)")
def test_no_invalid_read_at_exit_under_valgrind(built_fmus, tmp_path):
    """pythonfmu's exit double free (docs/fmi-limits.md, "Process exit") is deterministic under
    valgrind: a host that keeps an FMU loaded until it exits (the ctypes host,
    standard library only) shows "Invalid read ... in finalizePythonInterpreter" without the
    FMUs' exit handler (measured: error exit 99, one invalid read per library), and nothing
    with it. Aborts by glibc are only occasional (0 of 150 plain runs without the handler, on
    this project's machine), so counting exit codes would miss the regression."""
    # addressability checks only (--undef-value-errors=no): an invalid read is still reported,
    # at half the run time
    cmd = ["valgrind", "--error-exitcode=99", "-q", "--undef-value-errors=no",
           sys.executable, "-I", "-S", str(HOST)]
    # one library: the exit handler is the entry module's, the same in every pythonfmu FMU,
    # and each library without it shows its own invalid read (suite time: valgrind runs
    # Python at a twentieth of its speed)
    cmd += _host_args(built_fmus["DroneFlyLateral"], tmp_path / "DroneFlyLateral")
    # the system allocator, so that valgrind sees every block (pymalloc's arenas hide them)
    env = {"PATH": os.environ.get("PATH", ""), "PYTHONMALLOC": "malloc"}
    r = subprocess.run(cmd, capture_output=True, text=True, timeout=300, env=env)
    invalid = [ln for ln in r.stderr.splitlines() if "Invalid" in ln or " at 0x" in ln]
    assert r.returncode == 0 and not invalid, (r.returncode, invalid[:6])
    assert r.stdout.count("instance: ok") == 1, r.stdout[-800:]


def test_the_fuzz_survives_and_counts_a_crashing_fmu(tmp_path):
    fmu = build_crashing_fmu(tmp_path)
    report = fuzz_fmu(fmu, groups=("sequence",), logging=(False,), timeout_s=60)
    crashed = {c.case for c in report.crashes}
    assert any("fmi2DoStep in stepping" in c for c in crashed), report.summary()
    assert "killed by SIGSEGV" in {c.crash for c in report.crashes}
    # the group went on after each crash: later cases ran and were recorded
    assert any(c.case.startswith("fmi2GetReal") and c.crash is None for c in report.cases)


_HYGIENE = textwrap.dedent("""
    import gc, json, sys, tracemalloc
    from dronefly.harness.cosim.fmu import FMU
    def cycle(f):
        with f.instantiate("x", logging=True) as inst:
            s = inst.slave
            s.setupExperiment(startTime=0.0)
            s.enterInitializationMode()
            s.exitInitializationMode()
            s.doStep(0.0, 1e-3)
            st = s.getFMUstate()
            s.setFMUstate(st)
            s.freeFMUstate(st)

    with FMU(sys.argv[1]) as f:
        # warm-up: fills the bounded caches (256 freed-state tombstones; the 6-DOF model's
        # compiled equations per parameter set, made at initialization)
        with f.instantiate("x", logging=False) as inst:  # (the tombstones are per process)
            for _ in range(260):
                inst.slave.freeFMUstate(inst.slave.getFMUstate())
        for _ in range(3):
            cycle(f)
        gc.collect()
        n_path = len(sys.path)
        tracemalloc.start(1)  # the filter and the grouping look at the newest frame only
        before = tracemalloc.take_snapshot()
        for _ in range(int(sys.argv[2])):
            cycle(f)
        gc.collect()
        after = tracemalloc.take_snapshot()
        ours = [tracemalloc.Filter(True, "*dronefly_*")]  # the FMU's own shipped package
        grown = sum(s.size_diff for s in after.filter_traces(ours).compare_to(
            before.filter_traces(ours), "filename"))
        print(json.dumps({"path": len(sys.path) - n_path, "ours": grown}))
""")


# One FMU per slave class: the delayed controllers ship the code of StateFeedback and
# StateFeedbackLongitudinal, and DroneFlyLongitudinal/StateFeedbackLongitudinal run the slave
# classes of DroneFlyLateral/StateFeedback with other tables (suite time)
@pytest.mark.parametrize("name", [n for n in FMUS if n not in _SHARED])
def test_instantiate_and_free_leave_the_interpreter_as_found(built_fmus, name):
    """100 instantiate/step/state/free cycles (20 for the flapping plant, whose steps under
    tracemalloc cost 0.1 s each): sys.path unchanged, and no memory held by the FMU's own code
    (pythonfmu's findClass leaks about 1.2 kB per instantiation in reprs of the slave class's
    MRO; see docs/fmi-limits.md)."""
    cycles = 20 if name in NEEDS_NUMPY else 100
    r = subprocess.run([sys.executable, "-c", _HYGIENE, str(built_fmus[name]), str(cycles)],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr[-500:]
    got = json.loads(r.stdout.strip().splitlines()[-1])
    assert got["path"] == 0
    assert got["ours"] < 2048, got  # bytes over 100 cycles: a bounded cache at most


_CONTAINER_REFUSAL = textwrap.dedent("""
    import math, sys
    from fmpy.fmi1 import FMICallException
    from dronefly.harness.cosim.fmu import FMU
    with FMU(sys.argv[1]) as f:
        h = float(f.model_description.defaultExperiment.stepSize)
        with f.instantiate("c", logging=sys.argv[2] == "1") as inst:
            s = inst.slave
            s.setupExperiment(startTime=0.0); s.enterInitializationMode(); s.exitInitializationMode()
            s.doStep(0.0, h)
            s.setReal([f.vr("K[1,1]")], [math.nan])
            try:
                s.doStep(h, h)
                print("not refused")
            except FMICallException as e:
                print("refused", e.status, len(inst.messages))
        with f.instantiate("c2", logging=False) as inst:  # a new instance in the same process
            s = inst.slave
            s.setupExperiment(startTime=0.0); s.enterInitializationMode(); s.exitInitializationMode()
            for k in range(5):
                s.doStep(k * h, h)
            print("usable", s.getReal([f.vr("delta_gamma")])[0])
""")


@pytest.mark.parametrize("logging", ["1", "0"])
def test_container_refuses_a_bad_gain_and_the_host_survives(built_fmus, logging):
    """K[1,1] = NaN in the container: the step is refused with a status (and, logging on, a
    message), the host process lives on and exits 0, and a new container instance works.
    (fmi2Reset of the same instance: tests/test_container_reset.py.)"""
    r = subprocess.run([sys.executable, "-c", _CONTAINER_REFUSAL,
                        str(built_fmus["DroneFlyClosedLoop"]), logging],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr[-500:]
    lines = [ln.split() for ln in r.stdout.splitlines() if ln.startswith(("refused", "usable", "not"))]
    assert lines[0][0] == "refused" and int(lines[0][1]) >= 2, r.stdout
    if logging == "1":
        assert int(lines[0][2]) > 0, r.stdout
    assert lines[1][0] == "usable" and math.isfinite(float(lines[1][1])), r.stdout


_CONTAINER_CASES = textwrap.dedent('''
    import json, math, sys
    from fmpy.fmi1 import FMICallException
    from dronefly.harness.cosim.fmu import FMU
    from dronefly.harness.compliance.fuzzkit import PRINTED
    import os
    rows = os.fdopen(os.dup(1), "w")
    os.dup2(PRINTED.file.fileno(), 1)  # what the container binary prints counts as a message
    logging = sys.argv[2] == "1"
    with FMU(sys.argv[1]) as f:
        h = float(f.model_description.defaultExperiment.stepSize)
        vr = f.vr

        def run(name, body):
            with f.instantiate("c", logging=logging) as inst:
                s, seen = inst.slave, []

                def call(fn, *args):
                    n0 = len(inst.messages)
                    PRINTED.new()
                    try:
                        getattr(s, fn)(*args)
                        seen.append((fn, 0, True))
                    except FMICallException as e:
                        said = len(inst.messages) > n0 or bool(PRINTED.new())
                        seen.append((fn, int(e.status), said))

                def init(values=()):
                    call("setupExperiment", None, 0.0)
                    call("enterInitializationMode")
                    for k, v in values:
                        call("setReal", [vr(k)], [v])
                    call("exitInitializationMode")

                body(call, init)
                print(json.dumps({"case": name, "seen": seen}), file=rows, flush=True)

        run("doStep before initialization", lambda call, init: call("doStep", 0.0, h))
        for k, v in (("K[1,1]", math.nan), ("K[1,1]", math.inf), ("n", -1.0), ("U", 0.0),
                     ("delta_gamma_start", 0.5)):
            run(f"{k} = {v} while stepping", lambda call, init, k=k, v=v: (
                init(), call("doStep", 0.0, h), call("setReal", [vr(k)], [v]),
                call("doStep", h, h), call("doStep", 2 * h, h)))
        for k, v in (("n", math.nan), ("U", -3.0), ("delta_gamma_start", math.nan)):
            run(f"{k} = {v} before initialization", lambda call, init, k=k, v=v: (
                init([(k, v)]), call("doStep", 0.0, h)))
        run("unknown value references", lambda call, init: (
            init(), call("getReal", [10**6]), call("setReal", [10**6], [1.0]),
            call("doStep", 0.0, h)))
        run("refusal, retry, reset", lambda call, init: (
            init(), call("setReal", [vr("K[1,1]")], [math.nan]), call("doStep", 0.0, h),
            call("setReal", [vr("K[1,1]")], [-0.3]), call("doStep", 0.0, h), call("reset"),
            init(), call("doStep", 0.0, h)))
        run("call-sequence misuse", lambda call, init: (
            call("exitInitializationMode"), call("terminate"), init(), call("terminate"),
            call("terminate"), call("doStep", 0.0, h)))
''')


@pytest.mark.parametrize("logging", ["1", "0"])
def test_container_misuse_with_logging_does_not_kill_the_host(built_fmus, logging):
    """The container FMU cases that killed the host with logging on: doStep before
    initialization; bad K, n, U, delta_gamma_start while stepping and before initialization;
    unknown value references; a refusal, retry and reset; call-sequence misuse. The process
    survives and exits 0; with logging on, every non-OK status comes with a message (logged, or
    printed by the container binary). No fmi2Fatal."""
    r = subprocess.run([sys.executable, "-c", _CONTAINER_CASES,
                        str(built_fmus["DroneFlyClosedLoop"]), logging],
                       capture_output=True, text=True, timeout=180)
    assert r.returncode == 0, r.stderr[-800:]
    cases = [json.loads(ln) for ln in r.stdout.splitlines() if ln.startswith("{")]
    assert len(cases) == 12
    statuses = [st for c in cases for _, st, _ in c["seen"]]
    assert 4 not in statuses and any(st >= 2 for st in statuses)
    if logging == "1":
        silent = [(c["case"], fn) for c in cases for fn, st, said in c["seen"] if st and not said]
        assert not silent, silent
