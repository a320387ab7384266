"""Build the project's FMUs reproducibly.

Each FMU ships the Python sources it runs inside a package whose name carries a
hash of those sources (``dronefly_lateral_<hash>``). pythonfmu runs every FMU
of a process in one interpreter and reuses modules by name, so a fixed name
would let one FMU (or the host) shadow another's code; a content-addressed
name cannot collide with a different version. The GUID is derived from the
same hash, and the zip has fixed timestamps, so two builds from the same
sources are byte-identical.

The package name also tells whether an FMU file is the project's and from which sources: a
build never overwrites a file at its target that it did not write (:class:`BuildError` naming
it), and :func:`ensure_fmu` (what the commands that build on demand use) rebuilds an FMU only
when it is missing or its sources changed.
"""

from __future__ import annotations

import contextlib
import hashlib
import importlib
import re
import uuid
import zipfile
from dataclasses import dataclass
from importlib.metadata import PackageNotFoundError, distribution
from pathlib import Path
from typing import Callable, Iterator

from ...core.errors import DroneflyError
from ...core.files import write_zip
from ...core.interrupt import checkpoint
from ...fmi.base3 import fmi3_class
from ..cosim.ssp import HOVER, HOVER_6DOF, hover_system, write_system_ssp
from .closedloop import CLOSED_LOOP, CONTROLLER, PLANT, ClosedLoopSpec, write_container, write_ssp
from .entry import entry2, entry3, host_documentation
from .modeldescription import model_description_bytes
from .modeldescription3 import model_description3_bytes

__all__ = ["FMI3_FILES", "FMI3_OUT", "FMUS", "NEEDS_NUMPY", "BuildError", "build_all", "build_closed_loop", "build_fmu", "ensure_fmu",
           "fmu_sources", "project_fmus", "project_systems", "report_built", "reporting"]

#: the pythonfmu versions the FMUs are built with (FMI 2.0: pythonfmu's binary; FMI 3.0:
#: pythonfmu3's; both ship pythonfmu's Python facade)
_WRAPPERS = {"pythonfmu": "0.7.0", "pythonfmu3": "0.3.4"}
#: the sources an FMI 3.0 FMU ships besides its FMI 2.0 twin's
FMI3_FILES = ("fmi/base3.py", "fmi/table3.py")
#: where ``dronefly build`` writes the FMI 3.0 FMUs, below its output folder
FMI3_OUT = "fmi3"
_PKG_ROOT = Path(__file__).resolve().parents[2]  # the package root: harness/builder/../..
_NAMESPACE = uuid.UUID("6f1d3c52-1a0e-4b8f-9a58-2f4f3f7d1e10")


class BuildError(DroneflyError):
    """An FMU could not be built, or a given FMU file does not exist."""


@dataclass(frozen=True)
class _Spec:
    module: str  # slave module, dotted, relative to the package root
    cls: str
    files: tuple[str, ...]  # modules shipped, as paths below the package root
    readme: str
    reference: str


#: what every FMU ships: the exception base, the FMU runtime, the interface of both axes
_FMI = ("core/errors.py", "fmi/__init__.py", "fmi/base.py", "fmi/calls.py", "fmi/host.py",
        "fmi/state.py", "fmi/access.py", "fmi/vars.py", "models/axes.py", "models/lateral_interface.py")
_PLANT = (*_FMI, "models/linear.py", "models/linear_algebra.py", "fmu_src/linear_slave.py")
_CONTROLLER = (*_FMI, "models/longitudinal_interface.py", "models/feedback.py", "controller/delay.py",
               "controller/timing.py", "controller/variables.py", "controller/slave.py")

#: the quasi-steady wing model (numpy), a package
_QUASI_STEADY = tuple(f"models/quasisteady/{m}.py" for m in (
    "__init__", "wing", "elements", "kinematics", "trim", "instantaneous", "cycle", "model"))


def _controller(cls: str) -> _Spec:
    """A controller FMU: one slave module, one README, its reference files in controller/."""
    return _Spec(module="controller.slave", cls=cls, files=_CONTROLLER,
                 readme="controller/README.md", reference=f"controller/{cls}_ref.csv")


def _plant(folder: str, cls: str, *models: str) -> _Spec:
    """A plant FMU of ``fmu_src/<folder>/``: its slave, README and reference files there."""
    return _Spec(module=f"fmu_src.{folder}.slave", cls=cls,
                 files=(*models, f"fmu_src/{folder}/slave.py"),
                 readme=f"fmu_src/{folder}/README.md",
                 reference=f"fmu_src/{folder}/{cls}_ref.csv")


FMUS: dict[str, _Spec] = {
    "DroneFlyLateral": _plant("lateral", "DroneFlyLateral", *_PLANT,
                              "models/lateral_dynamics.py"),
    "StateFeedback": _controller("StateFeedback"),
    "DroneFlyLongitudinal": _plant("longitudinal", "DroneFlyLongitudinal", *_PLANT,
                                   "models/longitudinal_interface.py", "models/longitudinal_dynamics.py"),
    "StateFeedbackLongitudinal": _controller("StateFeedbackLongitudinal"),
    "StateFeedbackDelayed": _controller("StateFeedbackDelayed"),  # delay > 0, no feedthrough
    "StateFeedbackLongitudinalDelayed": _controller("StateFeedbackLongitudinalDelayed"),
    "DroneFlyHover6DOF": _plant(
        "hover6dof", "DroneFlyHover6DOF", *_FMI, "models/linear.py", "models/linear_algebra.py",
        "models/longitudinal_interface.py", "models/hover6dof.py", "models/lateral_dynamics.py",
        "models/longitudinal_dynamics.py", "models/rigid_body.py",
        *_QUASI_STEADY,  # imported (with numpy) only with aerodynamics = 2
        "fmu_src/body_variables.py"),
    # the one FMU that needs numpy in the host's Python (see NEEDS_NUMPY)
    "DroneFlyFlapping": _plant(
        "flapping", "DroneFlyFlapping", *_FMI, "models/linear.py", "models/linear_algebra.py",
        "models/longitudinal_interface.py", "models/hover6dof.py", "models/lateral_dynamics.py",
        "models/longitudinal_dynamics.py", "models/rigid_body.py", *_QUASI_STEADY,
        "models/shooting.py", *(f"models/flapping/{m}.py" for m in ("__init__", "model", "flight",
                                                                    "orbit")),
        "fmu_src/body_variables.py"),
}
#: the FMUs that import numpy (the others run on the standard library alone)
NEEDS_NUMPY = frozenset({"DroneFlyFlapping"})


def _source_path(rel: str) -> Path:
    """Where a file below the package root lives."""
    return _PKG_ROOT / rel


def _installed(dist: str) -> Path:
    """The folder of an installed wrapper package: the installed distribution, not
    ``sys.modules``, which after an FMU built by it ran in this process may be the FMU's own
    (since deleted) copy."""
    try:
        return Path(str(distribution(dist).locate_file(dist))).resolve()
    except PackageNotFoundError as e:
        raise BuildError(f"{dist} is not installed: pip install {dist}=={_WRAPPERS[dist]}") from e


def _wrapper_files(fmi: int) -> dict[str, bytes]:
    """What the FMU ships of its wrapper: pythonfmu's Python facade (the base class of
    :class:`dronefly.fmi.SlaveBase`, for both versions) and the binaries of the version's wrapper
    (pythonfmu for FMI 2.0, pythonfmu3 for FMI 3.0); ``{model}`` stands for the model name."""
    out = {f"resources/pythonfmu/{f.name}": f.read_bytes()
           for f in sorted(_installed("pythonfmu").glob("*.py"))}
    dist = "pythonfmu" if fmi == 2 else "pythonfmu3"
    root = _installed(dist)
    binaries = {f"binaries/{f.parent.name}/{{model}}{f.suffix}": f.read_bytes()
                for f in sorted((root / "resources" / "binaries").rglob("*"))
                if f.suffix in (".so", ".dll", ".dylib")}
    if not binaries:
        raise BuildError(f"no {dist} binaries under {root}: reinstall {dist}")
    return {**out, **binaries}


def fmu_sources(name: str, fmi: int = 2) -> tuple[str, dict[str, bytes]]:
    """Package name and ``{path in FMU: content}`` of one FMU (no model description), for
    FMI 2.0 (pythonfmu's binary) or FMI 3.0 (pythonfmu3's binary; the FMU ships the same model
    code plus :data:`FMI3_FILES`, in its own package ``dronefly3_<name>_<hash>``)."""
    spec = FMUS[name]
    rels = spec.files if fmi == 2 else (*spec.files, *FMI3_FILES)
    sources = {rel: _source_path(rel).read_bytes() for rel in rels}
    wrapper = _wrapper_files(fmi)
    entry = entry2 if fmi == 2 else entry3
    entry_text = entry("{pkg}", spec.module, spec.cls, name)  # hashed with the package unnamed
    h = hashlib.sha256(name.encode() + entry_text.encode())
    for rel, data in sorted({**sources, **wrapper}.items()):
        h.update(rel.encode() + b"\0" + hashlib.sha256(data).digest())
    pkg = f"dronefly{'' if fmi == 2 else '3'}_{name.lower()}_{h.hexdigest()[:16]}"
    files: dict[str, bytes] = {}
    for rel, data in sources.items():
        files[f"resources/{pkg}/{rel}"] = data
        parts = rel.split("/")[:-1]
        for i in range(len(parts) + 1):
            files.setdefault(f"resources/{pkg}/{'/'.join(parts[:i] + ['__init__.py'])}", b"")
    entry_module = f"{pkg}_slave"
    files[f"resources/{entry_module}.py"] = entry(pkg, spec.module, spec.cls, name).encode()
    files["resources/slavemodule.txt"] = entry_module.encode()
    for rel, data in wrapper.items():
        files[rel.replace("{model}", name)] = data
    files.update(host_documentation(name, _source_path(spec.readme).read_bytes()))
    return pkg, files


def _model_description(name: str, guid: str, fmi: int = 2) -> bytes:
    """Generate the XML from the package's own slave class.

    The FMU ships these very modules, byte for byte (:func:`fmu_sources`), and they import one
    another by relative imports only, so the class described is the one the FMU's wrapper
    instantiates. That the shipped set is complete (nothing imported that is not shipped) is
    checked by the tests: statically for every FMU, and by running every built FMU in an
    interpreter without this package (``tests/test_host_requirements.py``).
    """

    spec = FMUS[name]
    cls = getattr(importlib.import_module(f"...{spec.module}", __package__), spec.cls)
    if fmi == 3:  # the FMI 3.0 class the wrapper instantiates
        return model_description3_bytes(fmi3_class(cls), guid)
    return model_description_bytes(cls, guid)


def _built_package(path: Path, name: str, fmi: int) -> str | None:
    """The source package of the project's FMU ``name`` at ``path``; None if the file there
    is not one (not a zip, another FMU, a user's file)."""

    try:
        with zipfile.ZipFile(path) as z:
            entry = z.read("resources/slavemodule.txt").decode("ascii")
    except (OSError, KeyError, zipfile.BadZipFile, UnicodeDecodeError):
        return None
    prefix = f"dronefly{'' if fmi == 2 else '3'}_{name.lower()}_"
    if re.fullmatch(re.escape(prefix) + "[0-9a-f]{16}_slave", entry) is None:
        return None
    return entry[:-len("_slave")]


def _has_member(path: Path, member: str) -> bool:
    """Whether ``path`` is a zip archive holding ``member`` (an artefact the build wrote)."""

    try:
        with zipfile.ZipFile(path) as z:
            return member in z.namelist()
    except (OSError, zipfile.BadZipFile):
        return False


def _refuse_foreign(path: Path, what: str, ours: bool) -> None:
    """Raise :class:`BuildError` if a file the build did not write is at ``path``."""
    if path.is_dir() or (path.exists() and not ours):
        raise BuildError(f"{str(path)!r} exists and is not {what} that dronefly build wrote: "
                         "it is left alone (move it away, or build into another folder)")


#: the callbacks of :func:`reporting`, each called with every artefact the build writes
_REPORTERS: list[Callable[[Path], None]] = []


@contextlib.contextmanager
def reporting(callback: Callable[[Path], None]) -> Iterator[None]:
    """Call ``callback(path)`` for every FMU, SSP and container FMU the build writes inside the
    block (the command line says so: what it built and where)."""
    _REPORTERS.append(callback)
    try:
        yield
    finally:
        _REPORTERS.remove(callback)


def report_built(path: Path) -> Path:
    """Tell every :func:`reporting` callback that the build wrote ``path``; returns it."""
    for callback in list(_REPORTERS):
        callback(path)
    return path


def build_fmu(name: str, out_dir: str | Path = "build", fmi: int = 2) -> Path:
    """Build one FMU into ``out_dir`` and return its path (``fmi``: 2 or 3, the FMI version).

    Raises
    ------
    BuildError
        Unknown FMU name, the sources cannot be read or imported, or a file at the target
        that the build did not write (left alone).
    """
    if name not in FMUS:
        raise BuildError(f"unknown FMU {name!r}; known: {', '.join(FMUS)}")
    if fmi not in (2, 3):
        raise BuildError(f"FMI version {fmi!r}: 2 or 3")
    checkpoint()  # Ctrl-C during a build of many: between two FMUs
    out = Path(out_dir)
    target = out / f"{name}.fmu"
    _refuse_foreign(target, f"the {name} FMU", target.is_file()
                    and _built_package(target, name, fmi) is not None)
    try:
        pkg, files = fmu_sources(name, fmi)
        digest = pkg.rsplit("_", 1)[-1]
        guid = "{" + str(uuid.uuid5(_NAMESPACE, f"{name}:{digest}")) + "}"
        files["modelDescription.xml"] = _model_description(name, guid, fmi)
    except (OSError, ImportError) as e:
        raise BuildError(f"cannot build {name}: {e}") from e
    return report_built(write_zip(target, files))


def ensure_fmu(name: str, out_dir: str | Path = "build", fmi: int = 2) -> tuple[Path, bool]:
    """The project's FMU ``name`` in ``out_dir``, built only if it is missing or out of date
    with the sources (its package hash differs); returns (path, whether it was built).

    Raises
    ------
    BuildError
        As :func:`build_fmu`; a file there that the build did not write is left alone.
    """
    if name not in FMUS:
        raise BuildError(f"unknown FMU {name!r}; known: {', '.join(FMUS)}")
    target = Path(out_dir) / f"{name}.fmu"
    if target.is_file() and _built_package(target, name, fmi) is not None:
        try:
            current = fmu_sources(name, fmi)[0]
        except OSError as e:
            raise BuildError(f"cannot read the sources of {name}: {e}") from e
        if _built_package(target, name, fmi) == current:
            return target, False
    return build_fmu(name, out_dir, fmi), True


def project_fmus(plant: str | Path | None = None, controller: str | Path | None = None,
                 out_dir: str | Path = "build", *,
                 built: list[Path] | None = None) -> tuple[Path, Path]:
    """The given plant and controller FMUs, or the project's in ``out_dir``, built there only
    if missing or out of date with the sources (:func:`ensure_fmu`).

    ``built``, if given, is extended with the paths that were built.

    Raises
    ------
    BuildError
        (a ValueError) if a given path is not a file, or a file the build did not write is
        where it would build; nothing is built then.
    """
    for label, path in (("plant", plant), ("controller", controller)):
        if path is not None and not Path(path).is_file():
            raise BuildError(f"{label} FMU {str(path)!r} " + (
                "is a folder, not an FMU file" if Path(path).is_dir() else "does not exist"))
    pairs = ((plant, "DroneFlyLateral"), (controller, "StateFeedback"))
    for given, name in pairs:  # every target checked before anything is built
        target = Path(out_dir) / f"{name}.fmu"
        if given is None:
            _refuse_foreign(target, f"the {name} FMU", target.is_file()
                            and _built_package(target, name, 2) is not None)
    out = []
    for given, name in pairs:
        if given is not None:
            out.append(Path(given))
            continue
        path, fresh = ensure_fmu(name, out_dir)
        out.append(path)
        if fresh and built is not None:
            built.append(path)
    return out[0], out[1]


def project_systems(out_dir: str | Path = "build") -> tuple[Path, Path]:
    """``DroneFlyHover.ssp`` (linear plants) and ``DroneFlyHover6DOF.ssp`` (the nonlinear one)
    in ``out_dir``, built (with every FMU) if either is missing."""

    paths = (Path(out_dir) / f"{HOVER}.ssp", Path(out_dir) / f"{HOVER_6DOF}.ssp")
    if not all(p.is_file() for p in paths):
        build_all(out_dir)
    return paths


def build_all(out_dir: str | Path = "build", fmi: int = 2) -> list[Path]:
    """Build every FMU of the project into ``out_dir`` as FMI ``fmi`` (2 or 3) Co-Simulation
    FMUs, then the systems referencing them: ``DroneFlyClosedLoop.ssp`` (the lateral plant and
    its controller), for FMI 2.0 also the container FMU ``DroneFlyClosedLoop.fmu`` (FMI 3.0:
    none, docs/fmi-limits.md), and the hover systems ``DroneFlyHover.ssp`` (both axes with
    their controllers, four FMUs) and ``DroneFlyHover6DOF.ssp``. ``dronefly build`` writes the
    FMI 3.0 set in :data:`FMI3_OUT` below its folder.

    Raises
    ------
    BuildError
        As :func:`build_fmu`; a file at a target that the build did not write is left alone,
        and nothing is written then.
    """
    out = Path(out_dir)
    for name in FMUS:  # every target checked before anything is written
        target = out / f"{name}.fmu"
        _refuse_foreign(target, f"the {name} FMU", _built_package(target, name, fmi) is not None)
    artefacts = [(out / f"{n}.ssp", "SystemStructure.ssd") for n in (CLOSED_LOOP, HOVER, HOVER_6DOF)]
    if fmi == 2:
        artefacts.append((out / f"{CLOSED_LOOP}.fmu", "resources/container.json"))
    for target, member in artefacts:
        _refuse_foreign(target, f"the {target.name}", _has_member(target, member))
    fmus = {name: build_fmu(name, out_dir, fmi) for name in FMUS}
    if fmi == 2:
        loop = build_closed_loop(out_dir, fmus[PLANT], fmus[CONTROLLER])
    else:
        try:
            loop = [write_ssp(fmus[PLANT], fmus[CONTROLLER], out_dir)]
        except (OSError, ValueError) as e:
            raise BuildError(f"cannot build the FMI 3.0 {CLOSED_LOOP}.ssp: {e}") from e
    systems = []
    for name, nonlinear, text in (
            (HOVER, False, "lateral plant with Eq. (27), longitudinal plant with design (b)"),
            (HOVER_6DOF, True, "the nonlinear six-degree-of-freedom plant with the controllers "
                               "of both axes (Eq. 27, design b)")):
        description = (f"The hovering model drone fly (Zhang & Sun): {text}" if fmi == 2 else
                       "The hovering model drone fly (Zhang & Sun), FMI 3.0 FMUs")
        try:
            systems.append(write_system_ssp(hover_system(fmus, nonlinear=nonlinear),
                                            out / f"{name}.ssp", description=description))
        except (OSError, ValueError) as e:
            raise BuildError(f"cannot build {name}.ssp: {e}") from e
    for path in [*loop, *systems]:
        report_built(path)
    return [*fmus.values(), *loop, *systems]


def build_closed_loop(out_dir: str | Path, plant: str | Path, controller: str | Path,
                      spec: ClosedLoopSpec | None = None) -> list[Path]:
    """``DroneFlyClosedLoop.ssp`` and the container FMU ``DroneFlyClosedLoop.fmu`` holding two
    built FMUs (see :mod:`dronefly.harness.interop`).

    Raises
    ------
    BuildError
        The FMUs cannot be read or the artefacts cannot be written.
    """

    spec = ClosedLoopSpec() if spec is None else spec
    try:
        return [write_ssp(plant, controller, out_dir, spec),
                write_container(plant, controller, out_dir, spec)]
    except (OSError, ValueError, KeyError) as e:
        raise BuildError(f"cannot build the closed-loop artefacts: {e}") from e
