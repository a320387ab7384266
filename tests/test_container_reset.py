"""The container FMU after a refused component step.

Without a shim one refused step (K[1,1] = NaN) stops FMPy's container for good: pythonfmu
answers fmi2Terminated with true after any fmi2Discard, and the container keeps that answer
through fmi2Reset ("Expected currentCommunicationPoint=0 but was 0.00061"). The build puts a
shim in front of the nested FMUs' Linux library (``dronefly.harness.builder.nestedshim``); fmi2Reset and a
new initialization then give a container that runs exactly like a new instance. Each case runs in
a child process (FMPy's container can take the host down).
"""

from __future__ import annotations

import json
import platform
import subprocess
import sys
import textwrap
import zipfile

import pytest

from dronefly.harness.builder.closedloop import write_container
from dronefly.harness.builder.nestedshim import REAL_SUFFIX, shim_library
from shared_files import provided_on_ci

pytestmark = pytest.mark.integration

N_STEPS = 5

_CHILD = textwrap.dedent("""
    import json, math, sys
    from fmpy.fmi1 import FMICallException
    from dronefly.harness.cosim.fmu import FMU
    path, logging, n = sys.argv[1], sys.argv[2] == "1", int(sys.argv[3])
    with FMU(path) as f:
        h = float(f.model_description.defaultExperiment.stepSize)
        out = [0] + [f.vr(v.name) for v in f.model_description.modelVariables
                     if v.causality == "output"]  # vr 0: the container's time

        def status(fn, *args):
            try:
                fn(*args)
                return 0
            except FMICallException as e:
                return int(e.status)

        def run(s):  # initialize, n steps from 0: statuses and the outputs after each step
            s.setupExperiment(startTime=0.0)
            s.enterInitializationMode()
            s.exitInitializationMode()
            steps, rows = [], []
            for k in range(n):
                steps.append(status(s.doStep, k * h, h))
                rows.append(list(s.getReal(out)))
            return steps, rows

        with f.instantiate("fresh", logging=logging) as inst:
            fresh = run(inst.slave)
        with f.instantiate("reset", logging=logging) as inst:
            s = inst.slave
            s.setupExperiment(startTime=0.0)
            s.enterInitializationMode()
            s.exitInitializationMode()
            first = status(s.doStep, 0.0, h)
            s.setReal([f.vr("K[1,1]")], [math.nan])
            refused = [status(s.doStep, h, h), status(s.doStep, h, h)]
            reset = status(s.reset)
            again = run(s)  # K[1,1] back at its start value: the container's reset sets it
        print(json.dumps({"h": h, "fresh": fresh, "first": first, "refused": refused,
                          "reset": reset, "again": again}))
""")


def _run(fmu, logging: str) -> dict:
    r = subprocess.run([sys.executable, "-c", _CHILD, str(fmu), logging, str(N_STEPS)],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr[-800:]
    return json.loads(r.stdout.strip().splitlines()[-1])


@pytest.fixture(scope="module")
def shim():
    if shim_library() is None:
        if sys.platform.startswith("linux") and platform.machine() in ("x86_64", "AMD64"):
            provided_on_ci("no C compiler for the nested-FMU shim (.ci/setup-c-host.sh "
                           "installs gcc)")
        pytest.skip(f"the nested-FMU shim is built only on x86_64 Linux (this is "
                    f"{sys.platform}/{platform.machine()})")


@pytest.mark.parametrize("logging", ["0", "1"])
def test_reset_after_a_refused_step_gives_a_usable_container(built_fmus, shim, logging):
    """K[1,1] = NaN: the step is refused (and again), then fmi2Reset, a new initialization and
    five steps from t = 0: every step OK, the container's clock at 5 h, and outputs bit for bit
    those of a new instance."""
    got = _run(built_fmus["DroneFlyClosedLoop"], logging)
    h = got["h"]
    assert got["first"] == 0
    assert all(st >= 2 for st in got["refused"]), got["refused"]  # refused, never OK or Fatal
    assert 4 not in got["refused"]
    assert got["reset"] == 0
    steps, rows = got["again"]
    assert steps == [0] * N_STEPS, steps  # without the shim: [0, 3, 3, 3, 3] (clock stuck at 0)
    assert [row[0] for row in rows] == pytest.approx([(k + 1) * h for k in range(N_STEPS)])
    assert got["again"] == got["fresh"]


def test_the_shim_is_in_the_container_and_still_needed(built_fmus, shim, tmp_path):
    """The built container's nested Linux libraries are the shim in front of pythonfmu's; built
    without the shim, the container still stops for good after a refusal (pythonfmu 0.7.0, FMPy
    0.3.32). If this fails because the bare container recovers, the shim can go."""
    with zipfile.ZipFile(built_fmus["DroneFlyClosedLoop"]) as z:
        names = set(z.namelist())
        for model in ("DroneFlyLateral", "StateFeedback"):
            lib = f"resources/{model}/binaries/linux64/{model}"
            assert z.read(f"{lib}.so") == shim_library()
            assert f"{lib}{REAL_SUFFIX}" in names
    bare = write_container(built_fmus["DroneFlyLateral"], built_fmus["StateFeedback"], tmp_path,
                           shim=False, name="Bare")
    got = _run(bare, "0")
    assert got["reset"] == 0
    assert got["again"][0][0] == 0 and all(st >= 2 for st in got["again"][0][1:]), got["again"][0]


_EXIT_CHILD = textwrap.dedent("""
    import json, sys
    from dronefly.harness.cosim.fmu import FMU
    with FMU(sys.argv[1]) as f:
        with f.instantiate("c", logging=False) as inst:
            s = inst.slave
            s.setupExperiment(startTime=0.0)
            s.enterInitializationMode()
            s.exitInitializationMode()
            s.doStep(0.0, float(f.model_description.defaultExperiment.stepSize))
        # the container is freed: it has unloaded the shims; pythonfmu's libraries stay loaded
        hosts = [m for k, m in sys.modules.items() if k.endswith(".fmi.host")]
        maps = open("/proc/self/maps").read()
        rows = []
        for h in hosts:
            for lib in h.guarded_libraries():
                real = lib[:-3] + h.PYTHONFMU_BESIDE_SHIM
                rows.append([real in maps, str(h.release_interpreter_guard(lib)), real])
        print(json.dumps(rows))
""")


def test_the_exit_handler_reaches_pythonfmu_behind_an_unloaded_shim(built_fmus, shim):
    """The container unloads the shim when it frees its components while pythonfmu's library
    stays loaded. An exit handler that looks only for ``<model>.so`` (the shim) misses the
    guard, and the process aborts at exit now and then (valgrind: invalid read in pythonfmu's
    finalizePythonInterpreter, from _dl_fini: a double free). The handler releases the guard
    through ``<model>.pythonfmu.so``: every nested pythonfmu library still loaded after the free
    (the plant's, here) has its guard released; one that is unloaded with the shim runs its
    destructors then (valgrind: clean)."""
    r = subprocess.run([sys.executable, "-c", _EXIT_CHILD, str(built_fmus["DroneFlyClosedLoop"])],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr[-800:]
    rows = json.loads(r.stdout.strip().splitlines()[-1])
    assert len(rows) == 2  # plant and controller
    assert any(loaded for loaded, _, _ in rows)  # the bug's precondition: one stays loaded
    for loaded, released, real in rows:  # the loaded one's guard released, by its real path
        assert released == (real if loaded else "None"), rows


_DELETED_CHILD = textwrap.dedent("""
    import ctypes, json, os, shutil, sys, tempfile, zipfile
    from dronefly.fmi import host
    tmp = tempfile.mkdtemp()
    with zipfile.ZipFile(sys.argv[1]) as z:
        z.extract("binaries/linux64/DroneFlyLateral.so", tmp)
    lib = os.path.join(tmp, "binaries", "linux64", "DroneFlyLateral.so")
    ctypes.CDLL(lib)  # loaded as a host loads it, by its plain path
    shutil.rmtree(tmp)  # the host deletes its unpacked copy; the library stays mapped
    spelled = "/" + lib  # how pythonfmu hands over file:///tmp/... as a folder: //tmp/...
    print(json.dumps([lib, host.release_interpreter_guard(spelled),
                      host.release_interpreter_guard(lib + ".gone")]))
""")


def test_the_exit_handler_finds_a_deleted_library_spelled_with_two_slashes(built_fmus):
    """Ecos unpacks each SSP run into a temporary folder, deletes it after the run, and one
    DroneFlyLateral.so stays mapped; pythonfmu gives the FMU its resources folder as
    ``//tmp/...``. ``dlopen(RTLD_NOLOAD)`` matches a name that is not the loader's own by
    opening the file, which is gone, so asking the loader for ``//tmp/.../DroneFlyLateral.so``
    leaves the guard unreleased and the process aborts at exit ("corrupted double-linked
    list"). The handler looks the library up among the loaded objects by its normalised path."""
    r = subprocess.run([sys.executable, "-c", _DELETED_CHILD, str(built_fmus["DroneFlyLateral"])],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr[-800:]
    lib, released, not_loaded = json.loads(r.stdout.strip().splitlines()[-1])
    assert released == lib  # not None: found although the file is gone
    assert not_loaded is None
