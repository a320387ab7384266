"""The native (C) FMUs: one interface with the pythonfmu FMUs, the same numbers, the same
refusals, FMU states, and the matrix exponential in C against Python's and scipy's.

Where no C compiler is on the machine the tests that run a binary skip, naming it (a platform
reason); CI installs gcc.
"""

from __future__ import annotations

import ctypes
import math
import os
import subprocess
import sys
import zipfile
from pathlib import Path
from xml.etree import ElementTree as ET

import numpy as np
import pytest

from dronefly.harness.builder import native
from dronefly.harness.builder.build import build_fmu
from dronefly.harness.builder.native import NATIVE_FMUS, build_native
from dronefly.harness.builder.toolchain import find_toolchain, host_platform, missing_reason
from dronefly.harness.compliance.reference import check_reference, reference_paths

pytestmark = pytest.mark.integration

_EPS = np.finfo(float).eps
#: set by test_native_cases_under_address_and_undefined_behaviour_sanitizers for the run of this
#: file's native cases that it starts: every binary built with -fsanitize=address,undefined
_SANITIZE = os.environ.get("DRONEFLY_NATIVE_SANITIZE") == "1"


class _Built(dict):
    """FMUs by (model, FMI version), each built on first use (a test that needs two builds two)."""

    def __init__(self, make):
        super().__init__()
        self._make = make

    def __missing__(self, key):
        self[key] = path = self._make(*key)
        return path

    def all(self) -> list[Path]:
        return [self[name, fmi] for fmi in (2, 3) for name in NATIVE_FMUS]


@pytest.fixture(scope="session")
def native_fmus(tmp_path_factory: pytest.TempPathFactory) -> _Built:
    """The native FMUs, FMI 2.0 and 3.0, for this machine: (model, version) -> path, each built
    once on first use, by the host's compiler where there is one (the quickest), else zig cc."""
    why = missing_reason(sanitize=_SANITIZE)
    if why is not None:
        pytest.skip(why)
    out = tmp_path_factory.mktemp("native")
    tc = find_toolchain(sanitize=True) or find_toolchain()
    return _Built(lambda name, fmi: build_native(name, out / f"fmi{fmi}", fmi, tc,
                                                 (host_platform(f"{fmi}.0"),),
                                                 sanitize=_SANITIZE)[0])


@pytest.fixture(scope="session")
def python_fmus(tmp_path_factory: pytest.TempPathFactory) -> _Built:
    """The pythonfmu twins of the native FMUs, each built on first use."""
    out = tmp_path_factory.mktemp("pythonfmu")
    return _Built(lambda name, fmi: build_fmu(name, out / f"fmi{fmi}", fmi))


def _md(path: Path) -> ET.Element:
    with zipfile.ZipFile(path) as z:
        return ET.fromstring(z.read("modelDescription.xml"))


def _differences(a: ET.Element, b: ET.Element, where: str = "") -> set[str]:
    """Where two model descriptions differ: ``tag@attribute`` for an attribute, ``tag/child``
    for an element only one of them has (element by element, in order)."""
    here = f"{where}/{a.tag}"
    out = {f"{here}@{k}" for k in set(a.attrib) | set(b.attrib) if a.get(k) != b.get(k)}
    ka, kb = list(a), list(b)
    extra_b = [c for c in kb if c.tag not in {x.tag for x in ka}]
    out |= {f"{here}/{c.tag}" for c in extra_b}
    kb = [c for c in kb if c not in extra_b]
    assert [c.tag for c in ka] == [c.tag for c in kb], f"{here}: children differ"
    for x, y in zip(ka, kb):
        out |= _differences(x, y, here)
    return out


#: what may differ between a pythonfmu and a native model description, and nothing else
_ALLOWED = {
    2: {"/fmiModelDescription@guid", "/fmiModelDescription@generationTool",
        "/fmiModelDescription@description", "/fmiModelDescription/CoSimulation@needsExecutionTool",
        "/fmiModelDescription/CoSimulation/SourceFiles"},
    3: {"/fmiModelDescription@instantiationToken", "/fmiModelDescription@generationTool",
        "/fmiModelDescription@description",
        "/fmiModelDescription/CoSimulation@needsExecutionTool"},
}


@pytest.mark.parametrize("fmi", (2, 3))
@pytest.mark.parametrize("name", sorted(NATIVE_FMUS))
def test_model_description_is_the_pythonfmu_one(python_fmus, name, fmi):
    """Variables, value references, units, display units, descriptions, causality,
    variability, ModelStructure, default experiment and capability flags are the pythonfmu
    FMU's (one table, one generator); only the identity, the tool, the host requirement and
    needsExecutionTool differ (and FMI 2.0 lists the sources)."""
    token, files = native.native_sources(name, fmi)
    ours = ET.fromstring(files["modelDescription.xml"])
    theirs = _md(python_fmus[name, fmi])
    assert _differences(theirs, ours) == _ALLOWED[fmi]
    assert ours.find("CoSimulation").get("needsExecutionTool") == "false"
    assert ours.get("description").endswith(native.NATIVE_HOST)
    assert token in files["sources/vars.h"].decode()


def _bound(ref: np.ndarray, names: list[str], steps: int, columns: int, growth: float) -> float:
    """Round-off of a reference run: each step's row product of ``columns`` terms rounds each
    term and partial sum (at most ``columns`` eps of the largest value), the error of a step
    carried on by the loop at most ``growth`` (the largest exp(Re lambda T) over the run)."""
    top = max(float(np.max(np.abs(ref[n].astype(float)))) for n in names)
    return growth * steps * columns * _EPS * max(top, 1e-300)


def _growth(name: str, span_s: float) -> float:
    """How much a plant's open loop can amplify an error over ``span_s``: exp(largest real part
    of eig(A) per wing beat x the wing beats) (lateral: 10.6 over 30 wing beats; longitudinal:
    17.9 over 60); for the rigid body, the larger of the two (linearised about hover it is the
    two linear plants, and the reference run stays near hover: the lateral one's, 112 over its
    60 wing beats); 1
    for a controller, whose outputs are each step's product alone."""
    from dronefly.models import lateral_dynamics, longitudinal_dynamics
    from dronefly.models.lateral_interface import N_HZ

    modules = {"DroneFlyLateral": (lateral_dynamics,),
               "DroneFlyLongitudinal": (longitudinal_dynamics,),
               "DroneFlyHover6DOF": (lateral_dynamics, longitudinal_dynamics)}.get(name, ())
    rate = 0.0
    for module in modules:
        A = module.system_matrices(module.default_parameters())[0]
        rate = max(rate, float(np.max(np.linalg.eigvals(A).real)))
    return math.exp(rate * span_s * N_HZ)


#: rounded operations per value and step: a linear plant's or controller's row product (8
#: terms); the rigid body's order-6 sub-step (one per step in its reference run: 0.1 wing beat
#: is under MAX_SUBSTEP_WB, and its turn rates are far under 0.5 rad per wing beat): 7 stages of
#: at most 15 operations of the right-hand side (_RHS's a_u line with gravity and transport)
#: and 11 of a stage's input, and the result's 11: 7 * (15 + 11) + 11 = 193
_OPERATIONS = {"DroneFlyHover6DOF": 193}


@pytest.mark.parametrize("fmi", (2, 3))
@pytest.mark.parametrize("name", sorted(NATIVE_FMUS))
def test_native_reproduces_the_reference(native_fmus, python_fmus, name, fmi):
    """The reference result to round-off (the bound derived in :func:`_bound`), and the
    pythonfmu FMU's result bit for bit (the same operations in the same order: the matrix
    exponential with correctly rounded sums, the products summed left to right, no fused
    multiply-add)."""
    import fmpy
    from fmpy.util import read_csv

    check = check_reference(name, native_fmus[name, fmi])
    assert check.cross_check_outliers == 0.0
    inp, opt, ref_path = reference_paths(name)
    ref = read_csv(str(ref_path))
    names = list(ref.dtype.names[1:])
    kw = dict(start_time=float(ref["time"][0]), stop_time=float(ref["time"][-1]),
              output_interval=float(ref["time"][1] - ref["time"][0]), output=names)
    if inp.exists():
        kw["input"] = read_csv(str(inp))
    got = fmpy.simulate_fmu(str(native_fmus[name, fmi]), **kw)
    twin = fmpy.simulate_fmu(str(python_fmus[name, fmi]), **kw)
    steps = len(ref) - 1
    bound = _bound(ref, names, steps, _OPERATIONS.get(name, 8),
                   _growth(name, float(ref["time"][-1] - ref["time"][0])))
    for n in names:
        a, b = got[n].astype(float), ref[n].astype(float)
        assert np.max(np.abs(a - b)) <= bound, (n, np.max(np.abs(a - b)), bound)
        assert np.array_equal(a, twin[n].astype(float)), n


def _exported_expm(path: Path, tmp: Path):
    """fmu_expm of the FMU's sources/expm.c, built by the toolchain as a library of its own
    that exports it (the FMU's binary exports the FMI functions only)."""
    with zipfile.ZipFile(path) as z:
        z.extractall(tmp / "fmu")
    target = (find_toolchain(sanitize=True) or find_toolchain()).compile(
        [tmp / "fmu" / "sources" / "expm.c"], tmp / "expm.so", host_platform("3.0"),
        extra_flags=("-fvisibility=default",), sanitize=_SANITIZE)
    lib = ctypes.CDLL(str(target))
    f = lib.fmu_expm
    f.argtypes = [ctypes.POINTER(ctypes.c_double), ctypes.c_int, ctypes.POINTER(ctypes.c_double)]
    f.restype = None

    def expm(a: np.ndarray) -> np.ndarray:
        a = np.ascontiguousarray(a, dtype=float)
        n = a.shape[0]
        out = np.zeros((n, n))
        f(a.ctypes.data_as(ctypes.POINTER(ctypes.c_double)), n,
          out.ctypes.data_as(ctypes.POINTER(ctypes.c_double)))
        return out

    return expm


@pytest.mark.parametrize("norm", (0.01, 0.2, 0.9, 2.0, 5.0, 40.0, 700.0))
def test_expm_in_c_against_python_and_scipy(native_fmus, tmp_path, norm):
    """The C matrix exponential: every Pade degree (3 to 13) and scaling, on 7 x 7 and 8 x 8
    matrices of the plants' shape ([[A h, B h], [0, 0]]): the Python FMUs' floats bit for bit,
    and scipy's expm to its condition: relative error <= 1e3 n eps ||M||_1, the growth of
    round-off through the s squarings (Higham 2005, Sect. 3) times a margin of 10."""
    from scipy.linalg import expm as scipy_expm

    from dronefly.models.linear_algebra import expm as python_expm

    expm = _exported_expm(native_fmus["DroneFlyLateral", 2], tmp_path)
    rng = np.random.default_rng(37)
    for n_x, n_u in ((4, 3), (4, 4)):
        n = n_x + n_u
        m = np.zeros((n, n))
        m[:n_x, :] = rng.standard_normal((n_x, n))
        m *= norm / np.max(np.sum(np.abs(m), axis=0))
        ours = expm(m)
        assert ours.tolist() == python_expm(m.tolist())
        ref = scipy_expm(m)
        rel = np.max(np.abs(ours - ref)) / np.max(np.abs(ref))
        assert rel <= 1e3 * n * _EPS * max(norm, 1.0), (norm, rel)


@pytest.mark.parametrize("plant", ("DroneFlyLateral", "DroneFlyLongitudinal"))
@pytest.mark.parametrize("fmi", (2, 3))
def test_a_hold_whose_control_derivatives_dwarf_the_plant_is_the_pythons(native_fmus,
                                                                        python_fmus, fmi,
                                                                        plant):
    """Control derivatives 1e12 times the paper's, over steps of 20 wing beats from a
    non-zero state with a small constant input: B h dwarfs A h, and the hold scales it down
    (fmu_expm_hold in C, hold_exponential in Python, whose accuracy tests/test_expm.py checks
    against scipy). Every output equals the pythonfmu plant's bit for bit."""
    import fmpy

    md = fmpy.read_model_description(str(python_fmus[plant, fmi]))
    values = {v.name: v for v in md.modelVariables}
    controls = {v.name for v in md.modelVariables if v.causality == "input"}
    start = {name: 1e12 * float(v.start) for name, v in values.items()
             if v.causality == "parameter" and "_" in name and name.endswith("_plus")
             and any(name.split("_", 1)[1].startswith(c.split("_", 1)[1]) for c in controls)}
    assert len(start) == 3 * len(controls), sorted(start)  # Y, L, N (X, Z, M) of each
    start.update({name: 0.01 for name in values if name.endswith("_start")})
    start.update({name: 1e-13 for name in controls})
    wing_beat_s = 1.0 / float(values["n"].start)
    kw = dict(stop_time=30 * 20 * wing_beat_s, output_interval=20 * wing_beat_s,
              start_values=start)
    got = fmpy.simulate_fmu(str(native_fmus[plant, fmi]), **kw)
    want = fmpy.simulate_fmu(str(python_fmus[plant, fmi]), **kw)
    assert len(got) == 31
    for name in got.dtype.names[1:]:
        assert np.array_equal(got[name], want[name]), name
        assert np.all(np.isfinite(got[name])), name


def test_expm_in_c_of_entries_whose_norm_overflows(native_fmus, tmp_path):
    """Finite entries whose 1-norm overflows (a column of two 1e308; converting the infinite
    log2 to int would be undefined behaviour): exp(N) = I + N exactly for this nilpotent N,
    in C as in Python."""
    expm = _exported_expm(native_fmus["DroneFlyLateral", 2], tmp_path)
    n = np.array([[0.0, 0.0, 1e308], [0.0, 0.0, 1e308], [0.0, 0.0, 0.0]])
    assert expm(n).tolist() == [[1.0, 0.0, 1e308], [0.0, 1.0, 1e308], [0.0, 0.0, 1.0]]


def _run_messages(path: Path, fmi: int, prepare, t0: float = 0.0, h: float = 1e-3):
    """Status of one step after ``prepare(slave, vr)`` and the messages logged."""
    from dronefly.harness.cosim.fmu import FMU

    with FMU(path) as fmu, fmu.instantiate("probe") as inst:
        s = inst.slave
        s.setupExperiment(startTime=t0)
        s.enterInitializationMode()
        s.exitInitializationMode()
        t, h2 = prepare(s, fmu)
        from dronefly.harness.compliance.fuzzkit import status_of

        before = len(inst.messages)
        status = status_of(lambda: s.doStep(currentCommunicationPoint=t, communicationStepSize=h2))
        return status, [m.message for m in inst.messages[before:]]


def _nan_input(s, fmu):
    s.setReal([fmu.vr("delta_Phi_a")], [math.nan])
    return 0.0, 1e-3


def _bad_step(s, fmu):
    return 0.0, -1.0


@pytest.mark.parametrize("fmi", (2, 3))
@pytest.mark.parametrize("case", (_nan_input, _bad_step), ids=("nan-input", "bad-step"))
@pytest.mark.parametrize("name", ("DroneFlyLateral", "DroneFlyHover6DOF"))
def test_the_same_refusals_with_the_same_message(native_fmus, python_fmus, name, fmi, case):
    """A NaN input (Discard) and a step size that is not > 0 (FMI 2.0: Discard, 3.0: Error):
    the native FMU answers with the pythonfmu FMU's status and logs its message, which names
    the value."""
    got = _run_messages(native_fmus[name, fmi], fmi, case)
    want = _run_messages(python_fmus[name, fmi], fmi, case)
    assert got[0] == want[0] != 0
    assert any(("nan" in m or "-1.0" in m) for m in got[1])
    assert [m.split(": ", 1)[1] for m in got[1]] == [m.split(": ", 1)[1] for m in want[1]]


def _gamma_overflow(s, fmu):
    """A control derivative of 1e290 and a step of 1000 wing beats: exp(A1 h) is finite (the
    fastest growth, 0.079 per wing beat, gives e^79), Gamma = (integral of exp(A1 s)) B1 is not."""
    s.setReal([fmu.vr("L_Phi_a_plus"), fmu.vr("delta_Phi_a")], [1e290, 0.1])
    return 0.0, 1000.0 / float(fmu.variables["n"].start)


@pytest.mark.parametrize("fmi", (2, 3))
def test_an_overflowing_hold_of_the_controls_is_refused_as_the_pythonfmu_plant_refuses(
        native_fmus, python_fmus, fmi):
    """Where only Gamma overflows, the refusal says so (not that exp(A1 h) overflows, which is
    finite), in C as in Python: the same status and message."""
    got = _run_messages(native_fmus["DroneFlyLateral", fmi], fmi, _gamma_overflow)
    want = _run_messages(python_fmus["DroneFlyLateral", fmi], fmi, _gamma_overflow)
    assert got[0] == want[0] != 0
    assert any("overflows the hold of the controls" in m and "exp(A1 h) is finite" in m
               for m in got[1]), got[1]
    assert [m.split(": ", 1)[1] for m in got[1]] == [m.split(": ", 1)[1] for m in want[1]]


def _initialization_messages(path: Path, name: str, value: float) -> tuple[list[int], list[str]]:
    """Statuses of setReal(``name`` = ``value``) before initialization and of entering and
    leaving Initialization Mode, and the messages logged (the instance name cut off)."""
    from dronefly.harness.compliance.fuzzkit import status_of
    from dronefly.harness.cosim.fmu import FMU

    with FMU(path) as fmu, fmu.instantiate("probe") as inst:
        s = inst.slave
        s.setupExperiment(startTime=0.0)
        statuses = [status_of(lambda: s.setReal([fmu.vr(name)], [value])),
                    status_of(s.enterInitializationMode), status_of(s.exitInitializationMode)]
        return statuses, [m.message.split(": ", 1)[1] for m in inst.messages]


@pytest.mark.parametrize("value", (-1000.0, -1e-05, -0.0001, -1e16, -1e15, -123.456, -0.1,
                                   -2.5e-07, -1e300, -5e-324, -1.7976931348623157e308, 0.0,
                                   -0.0, -123456789012.25, -3.0000000000000004))
def test_a_refused_value_is_written_as_python_writes_it(native_fmus, python_fmus, value):
    """The native FMUs write the values their messages name as Python's repr does (shortest
    digits that read back; positional from 1e-4 to below 1e16, with a point; else 1e+16,
    1e-05): the longitudinal plant refusing m_plus <= 0 logs the pythonfmu plant's message."""
    got = _initialization_messages(native_fmus["DroneFlyLongitudinal", 2], "m_plus", value)
    want = _initialization_messages(python_fmus["DroneFlyLongitudinal", 2], "m_plus", value)
    assert any(f"m_plus = {value!r} must be > 0" in m for m in got[1]), got[1]
    assert got == want


@pytest.mark.parametrize("fmi", (2, 3))
@pytest.mark.parametrize("name", ("DroneFlyLateral", "DroneFlyHover6DOF"))
def test_state_get_set_serialize_and_reset(native_fmus, name, fmi):
    """A serialized state restored into another instance continues bit for bit; a refused
    (corrupt) state leaves the instance unchanged; reset starts over."""
    from dronefly.harness.cosim.fmu import FMU

    path = native_fmus[name, fmi]
    h = 1e-3
    with FMU(path) as fmu:
        outs = [fmu.vr(n) for n in ("delta_v", "delta_p", "delta_r", "delta_gamma")]
        u = fmu.vr("delta_Phi_a")

        def run(inst, t0, steps):
            rows = []
            for k in range(steps):
                inst.slave.setReal([u], [0.01 * math.sin(7.0 * (t0 + k * h))])
                inst.slave.doStep(currentCommunicationPoint=t0 + k * h, communicationStepSize=h)
                rows.append(inst.slave.getReal(outs))
            return rows

        with fmu.instantiate("a") as a, fmu.instantiate("b") as b:
            for inst in (a, b):
                inst.slave.setupExperiment(startTime=0.0)
                inst.slave.enterInitializationMode()
                inst.slave.exitInitializationMode()
            first = run(a, 0.0, 10)
            blob = a.slave.serializeFMUstate(a.slave.getFMUstate())
            later = run(a, 10 * h, 10)
            b.slave.setFMUstate(b.slave.deSerializeFMUstate(blob))
            assert run(b, 10 * h, 10) == later
            bad = bytearray(blob)
            bad[-3] ^= 0x55
            before = b.slave.getReal(outs)
            state = b.slave.deSerializeFMUstate(bytes(bad))
            with pytest.raises(Exception):
                b.slave.setFMUstate(state)
            assert "checksum" in b.messages[-1].message
            assert b.slave.getReal(outs) == before
            a.slave.reset()
            a.slave.setupExperiment(startTime=0.0)
            a.slave.enterInitializationMode()
            a.slave.exitInitializationMode()
            assert run(a, 0.0, 10) == first


def test_closed_loop_equals_the_pythonfmu_loop(native_fmus, tmp_path):
    """dronefly cosim's master on the native pair against the pythonfmu pair: 300 steps of the
    paper's loop, equal to 1e-12 (the issue's bound; measured: bit for bit)."""
    from dronefly.harness.stability.run import cosimulate

    runs = []
    for plant, controller in ((native_fmus["DroneFlyLateral", 2], native_fmus["StateFeedback", 2]),
                              (None, None)):
        r = cosimulate(plant, controller, stop_wingbeats=30.0, out_dir=None, plot=False,
                       build_dir=tmp_path)
        runs.append(r.run)
    a, b = runs
    assert len(a.time) == len(b.time) == 301 and a.names == b.names
    assert np.max(np.abs(a.signals - b.signals)) <= 1e-12


def test_source_code_fmu_compiled_by_fmpy_gives_the_same_results(native_fmus, tmp_path):
    """Without a toolchain the build writes source-code FMUs (sources/ with buildDescription.xml
    for FMI 3.0, SourceFiles for FMI 2.0, no binaries/); fmpy compiles them with its own CMake
    project (fmpy.build.build_platform_binary) and they give the native FMU's results."""
    pytest.importorskip("cmake", reason="fmpy compiles with CMake (the cmake package)")
    import fmpy
    from fmpy.build import build_platform_binary
    from fmpy.util import read_csv

    for fmi in (2, 3):
        path, platforms = build_native("DroneFlyLateral", tmp_path / f"src{fmi}", fmi,
                                       toolchain=None)
        assert platforms == ()
        with zipfile.ZipFile(path) as z:
            names = z.namelist()
        assert not any(n.startswith("binaries/") for n in names)
        assert ("sources/buildDescription.xml" in names) == (fmi == 3)
        unzipped = tmp_path / f"unzipped{fmi}"
        with zipfile.ZipFile(path) as z:
            z.extractall(unzipped)
        (tmp_path / f"cmake{fmi}").mkdir()
        build_platform_binary(unzipped, build_dir=tmp_path / f"cmake{fmi}")
        inp, opt, _ = reference_paths("DroneFlyLateral")
        kw = dict(stop_time=0.05, output_interval=1e-3, input=read_csv(str(inp)))
        got = fmpy.simulate_fmu(str(unzipped), **kw)
        want = fmpy.simulate_fmu(str(native_fmus["DroneFlyLateral", fmi]), **kw)
        for n in ("delta_v", "delta_p", "delta_r", "delta_gamma"):
            assert np.array_equal(got[n], want[n]), n


@pytest.mark.parametrize("profile", ("standard", "dronefly"))
def test_dronefly_check_passes_every_native_fmu(native_fmus, profile):
    """``dronefly check`` (both profiles; the dronefly profile with the fuzz on the FMI 2.0
    FMUs, where it applies) passes every native FMU, FMI 2.0 and 3.0; its validate check is
    ``fmpy validate``."""
    from dronefly.harness.compliance.checker import CheckOptions
    from dronefly.harness.compliance.suite import check_fmus

    paths = sorted(native_fmus.all())
    reports = check_fmus(paths, jobs=2, fuzz=profile == "dronefly",
                         options=CheckOptions(profile=profile))
    for r in reports:
        assert r.passed, (r.path, [(c.name, c.detail) for c in r.checks if not c.passed])
        assert any(c.name == "validate" and c.passed and not c.skipped for c in r.checks)
        if profile == "dronefly" and "fmi3" not in str(r.path):
            assert any(c.name == "fuzz" and c.passed and not c.skipped for c in r.checks)


def test_native_container_equals_the_pythonfmu_container(native_fmus, built_fmus, tmp_path):
    """The closed loop through FMPy: fmpy's container of the native pair (no pythonfmu shim)
    against the pythonfmu container, 300 steps of 0.1 wing beat, equal to 1e-12 (measured: bit
    for bit)."""
    import fmpy

    from dronefly.harness.builder.native import build_native_container

    folder = native_fmus["DroneFlyLateral", 2].parent
    assert native_fmus["StateFeedback", 2].parent == folder  # (built on first use)
    container = build_native_container(folder)
    md = fmpy.read_model_description(str(container))
    outs = [v.name for v in md.modelVariables if v.causality == "output"]
    step = float(md.defaultExperiment.stepSize)
    kw = dict(stop_time=300 * step, output_interval=step, output=outs)
    got = fmpy.simulate_fmu(str(container), **kw)
    want = fmpy.simulate_fmu(str(built_fmus["DroneFlyClosedLoop"]), **kw)
    assert len(got) == 301
    for n in outs:
        assert np.max(np.abs(got[n] - want[n])) <= 1e-12, n
    with zipfile.ZipFile(container) as z:
        assert not any("shim" in n for n in z.namelist())


def test_native_option_refuses_what_cannot_take_effect(tmp_path, capsys):
    """--native runs the project's pair: with --plant it is refused (exit 2, one line)."""
    from dronefly.cli import main

    assert main(["cosim", "--native", "--plant", str(tmp_path / "x.fmu"), "--no-plot"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--native cannot be combined with --plant" in err[0]


def test_build_without_a_compiler_writes_source_code_fmus(tmp_path, monkeypatch, capsys):
    """No C compiler: ``dronefly build --native`` still writes every native FMU, as source-code FMUs
    (sources/, no binaries/), and says so in one line."""
    import argparse

    from dronefly.cli.commands import build as build_command

    monkeypatch.setattr(native, "_default_toolchain", lambda: None)
    monkeypatch.setattr(build_command, "build_all", lambda out, fmi=2: [])
    assert build_command.run(argparse.Namespace(out=str(tmp_path), native=True)) == 0
    lines = capsys.readouterr().out.splitlines()
    assert sum("no C compiler" in ln for ln in lines) == 1
    fmus = sorted((tmp_path / "native").rglob("*.fmu"))
    assert len(fmus) == 2 * len(NATIVE_FMUS)
    for path in fmus:
        with zipfile.ZipFile(path) as z:
            names = z.namelist()
        assert "sources/fmu.c" in names and not any(n.startswith("binaries/") for n in names)


_CANARY = b"""
#include <stdlib.h>
int canary(int n) { int *a = (int *)malloc(4 * sizeof(int)); a[n] = 1; int v = a[0]; free(a);
                    return v; }
"""
#: this file's cases that run native code, rerun on sanitized binaries
#: (the cases that also run the pythonfmu twins run them in a Python whose every allocation goes
#: through the sanitizer: a few only)
_SANITIZED_CASES = ("expm or dwarf and 2-DroneFlyLateral or written_as_python or "
                    "overflowing_hold or state_get or delay_line or "
                    "reproduces and DroneFlyLateral or aerodynamics or "
                    "variants and sampled-delayed-integral-2")


@pytest.mark.skipif(_SANITIZE, reason="(this is the run the test starts)")
def test_native_cases_under_address_and_undefined_behaviour_sanitizers(tmp_path):
    """This file's native cases (reference runs, the matrix exponential, refusals, FMU states
    with corrupt bytes, the closed loop) on binaries built with -fsanitize=address,undefined
    (the host's compiler; undefined behaviour aborts), in a pytest run with the sanitizer
    runtimes preloaded into Python. A canary with a heap overflow, built the same way, aborts
    in that setup: the sanitizers are live."""
    why = missing_reason(sanitize=True)
    if why is not None or not sys.platform.startswith("linux"):
        pytest.skip(why or "sanitizer runtimes are preloaded on Linux only")
    tc = find_toolchain(sanitize=True)
    runtimes = []
    for lib in ("libasan.so", "libubsan.so"):
        r = subprocess.run([tc.command[0], f"-print-file-name={lib}"], capture_output=True,
                           text=True)
        path = r.stdout.strip()
        if not os.path.isabs(path):
            pytest.skip(f"{tc.command[0]} has no {lib} (the sanitizer runtime) on this machine")
        runtimes.append(path)
    env = dict(os.environ, LD_PRELOAD=" ".join(runtimes), ASAN_OPTIONS="detect_leaks=0",
               UBSAN_OPTIONS="halt_on_error=1:print_stacktrace=1", DRONEFLY_NATIVE_SANITIZE="1")
    (tmp_path / "canary.c").write_bytes(_CANARY)
    canary = tc.compile([tmp_path / "canary.c"], tmp_path / "canary.so", host_platform("3.0"),
                        sanitize=True, extra_flags=("-fvisibility=default",))
    r = subprocess.run([sys.executable, "-c", f"import ctypes; ctypes.CDLL({str(canary)!r})"
                        ".canary(4)"], env=env, capture_output=True, text=True, timeout=120)
    assert r.returncode != 0 and ("AddressSanitizer" in r.stderr
                                  or "runtime error" in r.stderr), r.stderr[-2000:]
    r = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:randomly", "-p",
                        "no:cacheprovider", __file__, "-k", _SANITIZED_CASES],
                       env=env, capture_output=True, text=True, timeout=600,
                       cwd=Path(__file__).parent)
    tail = (r.stdout + r.stderr)[-3000:]
    assert r.returncode == 0, tail
    assert "passed" in r.stdout and "skipped" not in r.stdout.splitlines()[-1], tail


def _controller_run(path: Path, params: dict, steps: list[float]):
    """A controller stepped with changing inputs and steps: every output before and after
    each step, and the messages logged."""
    from dronefly.harness.cosim.fmu import FMU

    out = []
    with FMU(path) as fmu, fmu.instantiate("c") as inst:
        s = inst.slave
        s.setupExperiment(startTime=0.0)
        s.enterInitializationMode()
        for k, v in params.items():
            (s.setBoolean if isinstance(v, bool) else s.setReal)([fmu.vr(k)], [v])
        s.exitInitializationMode()
        xs = [fmu.vr(n) for n in ("delta_v", "delta_p", "delta_r", "delta_gamma")]
        us = [fmu.vr(n) for n in ("delta_Phi_a", "delta_alpha_1a", "delta_alpha_2a")]
        t = 0.0
        for k, h in enumerate(steps):
            s.setReal(xs, [0.01 * math.sin(k), 0.3 * math.cos(0.7 * k), 0.2 * math.sin(0.3 * k),
                           0.05 * math.cos(0.1 * k)])
            out.append(s.getReal(us) + [s.getBoolean([fmu.vr("saturated")])[0]])
            s.doStep(currentCommunicationPoint=t, communicationStepSize=h)
            t += h
            out.append(s.getReal(us))
        return out, [m.message.split(": ", 1)[1] for m in inst.messages]


@pytest.mark.parametrize("fmi", (2, 3))
@pytest.mark.parametrize("name, params", [
    ("StateFeedback", {"sample_period": 4.1e-4, "KI[1,4]": -0.3, "KI[2,2]": 0.01}),
    ("StateFeedback", {"sample_period": 7.3e-4, "sensing_delay": 2.9e-3, "KI[1,1]": 0.2}),
    ("StateFeedback", {"sensing_delay": 1.7e-3, "limit_enabled": True, "u_max": 0.01}),
    ("StateFeedbackDelayed", {"sample_period": 3e-4, "sensing_delay": 1.1e-3, "KI[3,3]": 0.5}),
    ("StateFeedbackDelayed", {"sensing_delay": 6.1e-3}),
], ids=("sampled-finer-than-the-step-integral", "sampled-delayed-integral", "delayed-limited",
        "delayed-variant-sampled-integral", "delayed-variant"))
def test_controller_variants_step_as_the_pythonfmu_ones(native_fmus, python_fmus, fmi, name,
                                                        params):
    """Sensing delay, sampling (also several sample instants in one step), integral action and
    the limit, on 400 random steps of 0.2 to 1.5 ms with changing inputs: every output equals
    the pythonfmu controller's bit for bit, and the warning about instants inside a step is
    its text."""
    steps = list(np.random.default_rng(1).uniform(2e-4, 1.5e-3, 400))
    got = _controller_run(native_fmus[name, fmi], params, steps)
    want = _controller_run(python_fmus[name, fmi], params, steps)
    assert got[0] == want[0]
    assert got[1] == want[1]


def test_the_delay_line_bound_is_the_documented_one(native_fmus):
    """docs/native.md's bound of the native controllers' delay line is CTRL_LINE of
    controller/model.h; a delay that needs more samples is refused naming the values, one that
    needs fewer runs (and equals the pythonfmu controller, which holds 100,000)."""
    import re as _re

    root = Path(__file__).resolve().parents[1]
    bound = int(_re.search(r"#define CTRL_LINE (\d+)", (root / "controller" / "model.h")
                           .read_text()).group(1))
    doc = (root / "docs" / "native.md").read_text()
    assert f"holds at most {bound} samples" in doc
    h = 1e-3
    for delay_steps, refused in ((bound - 2, False), (bound + 2, True)):
        from dronefly.harness.cosim.fmu import FMU
        from dronefly.harness.compliance.fuzzkit import status_of

        with FMU(native_fmus["StateFeedbackDelayed", 2]) as fmu, fmu.instantiate("d") as inst:
            s = inst.slave
            s.setupExperiment(startTime=0.0)
            s.enterInitializationMode()
            s.setReal([fmu.vr("sensing_delay")], [delay_steps * h])
            s.exitInitializationMode()
            statuses = [status_of(lambda k=k: s.doStep(currentCommunicationPoint=k * h,
                                                       communicationStepSize=h))
                        for k in range(bound + 1)]
            if refused:
                assert statuses[-1] == 2 and statuses[:-1] == [0] * bound
                assert f"more than {bound} samples" in inst.messages[-1].message
                assert f"sensing_delay = {delay_steps * h!r} s" in inst.messages[-1].message
            else:
                assert statuses == [0] * (bound + 1)


def test_fmi3_takes_the_start_and_stop_time(native_fmus):
    """docs/native.md: the native FMI 3.0 FMUs take fmi3EnterInitializationMode's start and
    stop time: a first step elsewhere and a step past the stop time are refused (fmi3Error,
    naming the times); a step within them runs."""
    from dronefly.harness.compliance.fuzzkit import status_of
    from dronefly.harness.cosim.fmu import FMU

    with FMU(native_fmus["DroneFlyLateral", 3]) as fmu, fmu.instantiate("a") as inst:
        s = inst.slave
        s.setupExperiment(startTime=0.0, stopTime=1.0)
        s.enterInitializationMode()
        s.exitInitializationMode()
        step = lambda t, h: status_of(lambda: s.doStep(currentCommunicationPoint=t,  # noqa: E731
                                                       communicationStepSize=h))
        assert step(5.0, 0.1) == 3 and "5.0 s does not continue" in inst.messages[-1].message
        assert step(0.0, 2.0) == 3 and "past stopTime = 1.0 s" in inst.messages[-1].message
        assert step(0.0, 0.5) == 0


def test_fmi3_get_with_too_few_values_is_refused_with_a_message(native_fmus, tmp_path):
    """A host whose nValues is smaller than the arrays it asks for hold (OMSimulator's command
    line asks for one value of the 4 x 4 array A) gets fmi3Error and a logged message naming
    nValues, not a silent refusal; with the right nValues the same call answers."""
    from fmpy import extract, read_model_description
    from fmpy.fmi1 import FMICallException
    from fmpy.fmi3 import FMU3Slave

    path = native_fmus["DroneFlyLateral", 3]
    md = read_model_description(str(path))
    a = next(v for v in md.modelVariables if v.name == "A")
    size = int(a.dimensions[0].start) * int(a.dimensions[1].start)
    messages: list[str] = []
    slave = FMU3Slave(guid=md.guid, unzipDirectory=extract(str(path), unzipdir=tmp_path / "x"),
                      modelIdentifier=md.coSimulation.modelIdentifier, instanceName="probe")
    slave.instantiate(loggingOn=True, logMessage=lambda env, status, category, message:
                      messages.append(message.decode()))
    try:
        slave.enterInitializationMode()
        slave.exitInitializationMode()
        with pytest.raises(FMICallException):
            slave.getFloat64([a.valueReference], nValues=1)
        assert any("nValues = 1 " in m and "GetFloat64" in m for m in messages), messages
        assert len(slave.getFloat64([a.valueReference], nValues=size)) == size == 16
    finally:
        slave.terminate()
        slave.freeInstance()


@pytest.mark.parametrize("fmi", (2, 3))
def test_hover6dof_aerodynamics_quasi_steady_is_refused_with_a_message(native_fmus, python_fmus,
                                                                       fmi):
    """docs/native.md: the native DroneFlyHover6DOF has the linear aerodynamics only. Its
    ``aerodynamics`` parameter is the pythonfmu FMU's (one interface); the value 2
    (quasi_steady) is refused, never computed as something else: the outputs' fetch before
    initialization keeps the last values, the initialization reports and every step is
    refused (Discard), each with a logged message naming the value and the FMU to take. A value that is neither is refused as the pythonfmu FMU refuses it."""
    from dronefly.harness.compliance.fuzzkit import status_of
    from dronefly.harness.cosim.fmu import FMU

    def run(path, value):
        with FMU(path) as fmu, fmu.instantiate("a") as inst:
            s = inst.slave
            s.setupExperiment(startTime=0.0)
            s.enterInitializationMode()
            s.setInteger([fmu.vr("aerodynamics")], [value])
            got = status_of(lambda: s.getReal([fmu.vr("delta_v")]))
            s.exitInitializationMode()
            step = status_of(lambda: s.doStep(currentCommunicationPoint=0.0,
                                              communicationStepSize=1e-3))
            return got, step, [m.message for m in inst.messages]

    _, step, messages = run(native_fmus["DroneFlyHover6DOF", fmi], 2)
    assert step != 0, (step, messages)
    assert sum("aerodynamics = 2 (quasi_steady)" in m and "pythonfmu DroneFlyHover6DOF" in m
               for m in messages) >= 3, messages  # the fetch, the initialization, the step
    assert any("outputs keep their last valid values" in m for m in messages), messages
    ours, theirs = (run(f, 3) for f in (native_fmus["DroneFlyHover6DOF", fmi],
                                        python_fmus["DroneFlyHover6DOF", fmi]))
    assert ours[1] == theirs[1] != 0
    assert any("aerodynamics = 3: expected 1 (linear) or 2 (quasi_steady)" in m for m in ours[2])
    assert any("aerodynamics = 3: expected 1 (linear) or 2 (quasi_steady)" in m for m in theirs[2])
