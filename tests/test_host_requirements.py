"""What a host needs to run the FMUs: a CPython 3 interpreter, no packages.

Every FMU that ``dronefly build`` writes (FMI 2.0 and 3.0) is run by a small ctypes host
(tests/c_host/ctypes_host.py, standard library only) in an interpreter started without
site-packages (``-I -S``: no numpy, scipy or fmpy can be imported), on every CPython 3 this
machine has; a broken import is refused at instantiation with one line naming the cause.
"""

from __future__ import annotations

import ast
import functools
import glob
import os
import shutil
import subprocess
import sys
import zipfile
from dataclasses import dataclass
from pathlib import Path
from xml.etree import ElementTree as ET

import pytest

from dronefly.harness.builder.build import FMUS, fmu_sources
from dronefly.harness.builder.entry import HOST_REQUIREMENT, NEWEST_TESTED_PYTHON, OLDEST_PYTHON
from dronefly.models.lateral_interface import N_HZ

pytestmark = pytest.mark.integration

HOST = Path(__file__).parent / "c_host" / "ctypes_host.py"
#: the input set in initialization mode (rad for the plants' controls, the state's unit for
#: the controllers' inputs): small, inside the linear range
INPUT = 0.01
STEPS, STEP = 20, 0.1 / N_HZ  # 20 steps of 0.1 wing beat (the delayed controllers: 10 steps)


@dataclass(frozen=True)
class Extracted:
    """An FMU unpacked for the ctypes host."""

    folder: Path
    fmi: int
    model: str
    token: str
    inputs: tuple[tuple[str, int], ...]
    outputs: tuple[tuple[str, int], ...]


def _extract(fmu: Path, folder: Path, fmi: int) -> Extracted:
    with zipfile.ZipFile(fmu) as z:
        z.extractall(folder)
    root = ET.parse(folder / "modelDescription.xml").getroot()
    model = root.find("CoSimulation").get("modelIdentifier")
    token = root.get("guid" if fmi == 2 else "instantiationToken")
    variables = (root.find("ModelVariables").findall("ScalarVariable") if fmi == 2 else
                 [v for v in root.find("ModelVariables").findall("Float64")
                  if v.find("Dimension") is None])
    if fmi == 2:
        variables = [v for v in variables if v.find("Real") is not None]

    def of(causality: str) -> tuple[tuple[str, int], ...]:
        return tuple((v.get("name"), int(v.get("valueReference"))) for v in variables
                     if v.get("causality") == causality)
    return Extracted(folder, fmi, model, token, of("input"), of("output"))


@pytest.fixture(scope="module")
def extracted(built_fmus, built_fmus3, tmp_path_factory) -> dict[tuple[int, str], Extracted]:
    out = {}
    base = tmp_path_factory.mktemp("extracted")
    for fmi, fmus in ((2, built_fmus), (3, built_fmus3)):
        for name, path in fmus.items():
            if Path(path).suffix == ".fmu" and name != "DroneFlyClosedLoop":
                out[fmi, name] = _extract(Path(path), base / f"fmi{fmi}_{name}", fmi)
    return out


@dataclass
class HostRun:
    returncode: int
    instance: str
    statuses: list[int]
    outputs: list[float]
    modules: list[str] | None
    logs: list[str]
    stderr: str


def _args(fmu: Extracted, steps: int) -> list[str]:
    args = [str(fmu.folder), fmu.model, fmu.token, str(fmu.fmi), str(steps), "--step", repr(STEP)]
    if fmu.inputs:
        args += ["--set", f"{fmu.inputs[0][1]}={INPUT!r}"]
    for _, vr in fmu.outputs:
        args += ["--output", str(vr)]
    return args


def hosts(python: str, fmus: list[Extracted], modules: bool = False,
          steps: int = STEPS) -> list[HostRun]:
    """Run the ctypes host on ``fmus``, one after the other in one ``python -I -S`` process:
    each FMU's first input set to INPUT, ``steps`` steps of STEP, every output read. The
    return code, the modules and stderr are the process's."""
    cmd = [python, "-I", "-S", str(HOST)]
    for k, fmu in enumerate(fmus):
        cmd += (["+"] if k else []) + _args(fmu, steps)
    if modules:
        cmd.append("--modules")
    r = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
    lines = r.stdout.splitlines()
    mods = [ln[len("modules:"):].split() for ln in lines if ln.startswith("modules:")]
    starts = [i for i, ln in enumerate(lines) if ln.startswith("fmu ")] + [len(lines)]
    out = []
    for a, b in zip(starts, starts[1:]):
        part = lines[a + 1:b]
        pick = lambda prefix: [ln[len(prefix):] for ln in part if ln.startswith(prefix)]  # noqa
        out.append(HostRun(r.returncode, (pick("instance: ") or ["?"])[0],
                           [int(ln.split()[-1]) for ln in pick("status ")],
                           [float(x) for x in pick("output ")],
                           mods[0] if mods else None, pick("log: "), r.stderr))
    if len(out) < len(fmus):  # the process ended early: report it on the missing FMUs
        out += [HostRun(r.returncode, "?", [], [], None, [], r.stderr)] * (len(fmus) - len(out))
    return out


def host(python: str, fmu: Extracted, modules: bool = False, steps: int = STEPS) -> HostRun:
    """:func:`hosts` of one FMU."""
    return hosts(python, [fmu], modules, steps)[0]


def _fmpy_outputs(fmu: Extracted) -> list[float]:
    """The same experiment through fmpy in this process (which has numpy and scipy)."""
    import fmpy

    start = {fmu.inputs[0][0]: INPUT} if fmu.inputs else {}
    res = fmpy.simulate_fmu(str(fmu.folder), start_time=0.0, stop_time=STEPS * STEP,
                            step_size=STEP, output_interval=STEP, start_values=start,
                            output=[n for n, _ in fmu.outputs])
    return [float(res[n][-1]) for n, _ in fmu.outputs]


def _assert_same(outputs: list[float], expected: list[float], rtol: float) -> None:
    """Equal to ``rtol`` of the largest output (outputs near zero are compared on that scale)."""
    assert len(outputs) == len(expected)
    scale = max(max(map(abs, expected)), 1e-300)
    worst = max(abs(a - b) for a, b in zip(outputs, expected)) / scale
    assert worst <= rtol, (worst, outputs, expected)


FMU_NAMES = ("DroneFlyLateral", "StateFeedback", "DroneFlyLongitudinal",
             "StateFeedbackLongitudinal", "StateFeedbackDelayed",
             "StateFeedbackLongitudinalDelayed", "DroneFlyHover6DOF")


@pytest.mark.parametrize("fmi", [2, 3])
@pytest.mark.parametrize("name", FMU_NAMES)
def test_fmu_imports_only_the_standard_library(extracted, name, fmi):
    """Run without site-packages, the FMU instantiates, steps (every status OK) and loads no
    module outside the standard library besides its own package and pythonfmu's facade; its
    outputs are fmpy's for the same experiment in this interpreter (the same code and
    interpreter: equal but for the last bit, 1e-13 of the largest output)."""
    from dronefly.harness.builder.build import FMUS, NEEDS_NUMPY

    # every FMU but the flapping plant, which needs numpy (its README says so)
    assert set(FMU_NAMES) == set(FMUS) - NEEDS_NUMPY
    fmu = extracted[fmi, name]
    r = host(sys.executable, fmu, modules=True)
    assert r.returncode == 0, r.stderr
    assert r.instance == "ok", r.logs
    assert r.statuses and set(r.statuses) == {0}, r.logs
    assert r.modules == [], r.modules
    assert any(r.outputs), "the experiment moves an output"
    _assert_same(r.outputs, _fmpy_outputs(fmu), 1e-13)


def _break(fmu: Extracted, folder: Path) -> Extracted:
    """A copy of ``fmu`` whose model module imports a package that is not installed."""
    shutil.copytree(fmu.folder, folder)
    (model,) = glob.glob(str(folder / "resources" / "dronefly*" / "models"
                             / "lateral_dynamics.py"))
    with open(model, "a") as f:
        f.write("\nimport dronefly_not_installed_package  # noqa: E402,F401\n")
    return Extracted(folder, fmu.fmi, fmu.model, fmu.token, fmu.inputs, fmu.outputs)


@pytest.mark.parametrize("fmi", [2, 3])
def test_a_broken_import_is_refused_with_one_line_and_a_clean_exit(extracted, tmp_path, fmi):
    """A plant whose Python import fails: instantiation returns NULL, the host's stderr has one
    line naming the model, the Python version and the missing module (whatever the logging
    setting), the wrapper's log names it too, and the process exits 0, in 20 of 20 runs (the
    interpreter guard released at exit as for a started FMU)."""
    fmu = _break(extracted[fmi, "DroneFlyLateral"], tmp_path / "broken")
    version = ".".join(map(str, sys.version_info[:3]))
    for run in range(20):
        r = host(sys.executable, fmu)
        assert r.returncode == 0, (run, r.returncode, r.stderr)
        assert r.instance == "NULL", (run, r.logs)
        lines = r.stderr.splitlines()
        assert len(lines) == 1, lines
        assert lines[0].startswith(f"DroneFlyLateral: the FMU's Python side cannot start in "
                                   f"Python {version}: ModuleNotFoundError: No module named "
                                   "'dronefly_not_installed_package'"), lines
        assert any("dronefly_not_installed_package" in ln for ln in r.logs), r.logs


def _interpreters() -> dict[str, str]:
    """Every CPython 3 found on this machine: version -> executable (the system's, pyenv's,
    manylinux's /opt/python, and this one), one per version."""
    found = {}
    for pattern in ("/usr/bin/python3.*", "/usr/local/bin/python3.*",
                    "/root/.pyenv/versions/*/bin/python3", "/opt/python/*/bin/python3",
                    "/opt/_internal/*/bin/python3", sys.executable):
        for exe in sorted(glob.glob(pattern)):
            if not os.access(exe, os.X_OK) or exe.endswith("-config"):
                continue
            try:
                out = subprocess.run([exe, "-I", "-S", "-c", "import sys, platform; print("
                                      "platform.python_implementation(), *sys.version_info[:3])"],
                                     capture_output=True, text=True, timeout=30).stdout.split()
            except (OSError, subprocess.SubprocessError):
                continue
            if len(out) == 4 and out[0] == "CPython" and out[1] == "3":
                found.setdefault(".".join(out[1:]), exe)
    return dict(sorted(found.items(), key=lambda kv: tuple(map(int, kv[0].split(".")))))


INTERPRETERS = _interpreters()
#: FMUs run on each interpreter: the three plants and one controller, FMI 2.0 and 3.0
ON_EVERY_PYTHON = ("DroneFlyLateral", "DroneFlyLongitudinal", "DroneFlyHover6DOF",
                   "StateFeedbackDelayed")


@pytest.fixture(scope="module")
def reference_outputs(extracted) -> list[list[float]]:
    """The outputs in this interpreter (the test environment's Python), in the order of
    :func:`_every_python_fmus`."""
    return [r.outputs for r in hosts(sys.executable, _every_python_fmus(extracted))]


def _every_python_fmus(extracted) -> list[Extracted]:
    return [extracted[fmi, n] for fmi in (2, 3) for n in ON_EVERY_PYTHON]


def test_interpreters_found():
    """The machine's CPython 3 interpreters, listed in the test report: at least this one and
    one other (the image ships several); the newest is the newest the FMUs' documentation says
    was tested (NEWEST_TESTED_PYTHON), so that a newer interpreter updates it."""
    print("CPython 3 interpreters:", ", ".join(f"{v} ({e})" for v, e in INTERPRETERS.items()))
    assert len(INTERPRETERS) >= 2, INTERPRETERS
    newest = max(tuple(map(int, v.split(".")[:2])) for v in INTERPRETERS)
    if newest < NEWEST_TESTED_PYTHON:
        pytest.skip(f"this machine's newest CPython is {newest}: cannot confirm "
                    f"{NEWEST_TESTED_PYTHON}")
    assert newest == NEWEST_TESTED_PYTHON, "update NEWEST_TESTED_PYTHON after this test passes"


@pytest.mark.parametrize("fmi", [2, 3])
def test_every_fmu_says_what_its_host_needs(extracted, fmi):
    """documentation/index.html (the FMI entry point) and documentation/README.md name the
    Python versions and "no packages"; the modelDescription's description ends with the host
    requirement."""
    versions = "%d.%d to %d.%d" % (*OLDEST_PYTHON, *NEWEST_TESTED_PYTHON)
    for name in FMU_NAMES:
        fmu = extracted[fmi, name]
        for page in ("index.html", "README.md"):
            text = (fmu.folder / "documentation" / page).read_text()
            assert "What the host needs" in text and versions in text, (name, page)
            assert "standard library only" in text and "no package" in text, (name, page)
        root = ET.parse(fmu.folder / "modelDescription.xml").getroot()
        assert root.get("description").endswith(". " + HOST_REQUIREMENT), name


@pytest.mark.parametrize("version", list(INTERPRETERS))
def test_fmus_run_on_every_cpython(extracted, reference_outputs, version):
    """Each CPython 3 of the machine, without site-packages, as the host's interpreter: from
    3.8 on the plants and a controller (FMI 2.0 and 3.0) give this interpreter's outputs to
    1e-12 of the largest (plain float arithmetic, but ``sum`` of floats and ``math.sumprod``
    changed in 3.12: a few round-offs per step over 20 steps of a stable linear map); before,
    instantiation is refused with the one line that names the version, and the host exits 0."""
    exe = INTERPRETERS[version]
    supported = tuple(map(int, version.split(".")[:2])) >= OLDEST_PYTHON
    fmus = _every_python_fmus(extracted)
    runs = hosts(exe, fmus)  # all eight in one process, as a host with several FMUs
    for fmu, r, expected in zip(fmus, runs, reference_outputs):
        assert r.returncode == 0, (fmu.model, fmu.fmi, r.stderr)
        if supported:
            assert r.instance == "ok" and set(r.statuses) == {0}, (fmu.model, fmu.fmi, r.logs)
            _assert_same(r.outputs, expected, 1e-12)
        else:
            assert r.instance == "NULL", (fmu.model, fmu.fmi)
            assert any(f"cannot start in Python {version}:" in ln
                       for ln in r.stderr.splitlines()), r.stderr


@functools.lru_cache(maxsize=None)  # the FMUs ship mostly the same modules: parse each once
def _relative_imports(source: bytes, package: tuple[str, ...]) -> frozenset[tuple[str, ...]]:
    """The modules (paths below the package root) that ``source``, a module of ``package``,
    needs by its relative imports, resolved as the import system does: ``from .x import y``
    needs ``x``; ``from . import y`` needs ``y`` unless the package itself defines it, which
    the caller decides."""
    out: set[tuple[str, ...]] = set()
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.ImportFrom) and node.level:
            base = package[:len(package) - (node.level - 1)]
            if node.module:
                out.add((*base, *node.module.split(".")))
            else:
                out.update((*base, alias.name) for alias in node.names)
    return frozenset(out)


@pytest.mark.parametrize("fmi", [2, 3])
def test_every_module_an_fmu_imports_is_shipped(fmi):
    """The build describes the package's own classes and ships their modules byte for byte;
    this is what makes that sound: every relative import of a shipped module resolves to a
    shipped module, so the FMU's copy imports exactly the code that was described."""
    for name in FMUS:
        pkg, files = fmu_sources(name, fmi)
        prefix = f"resources/{pkg}/"
        modules = {tuple(rel[len(prefix):-3].split("/")) for rel in files
                   if rel.startswith(prefix) and rel.endswith(".py")}
        known = modules | {m[:-1] for m in modules if m[-1] == "__init__"}
        assert ("fmi", "base") in modules and len(modules) > 10  # the test sees the package
        for module in sorted(modules):
            package = module[:-1]
            for target in _relative_imports(files[prefix + "/".join(module) + ".py"], package):
                assert target in known, (f"{name} (FMI {fmi}): {'/'.join(module)}.py imports "
                                         f"{'.'.join(target)}, which the FMU does not ship")
