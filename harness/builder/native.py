"""Native (C) Co-Simulation FMUs, FMI 2.0 and 3.0, from the same interface as the pythonfmu ones.

The C sources are the project's own: the FMI plumbing once (``native/fmu.c``, for both
versions), the shared linear plant (``native/linear_plant.c``), the matrix exponential
(``native/expm.c``) and one file of equations per model (``model.c`` and ``model.h`` in the
FMU's folder). What the interface says is generated here from the variable table of the
pythonfmu slave class (``VARIABLES``): the model description (by
:mod:`.modeldescription` / :mod:`.modeldescription3`, the very functions that describe the
pythonfmu FMUs; only GUID, generation tool, host requirement and ``needsExecutionTool``
differ) and ``vars.h`` / ``vars.c`` (value references, names, types, start values, what may
be set, and for FMI 3.0 the rows of each array variable). The FMI headers come from the
installed fmpy package at build time.

Every native FMU ships ``sources/`` (FMI 3.0: with ``buildDescription.xml``; FMI 2.0: the
``SourceFiles`` of the model description), so a tool can compile it for its own platform. A
binary is added for each platform the toolchain builds for; without a toolchain the FMU is a
source-code FMU.
"""

from __future__ import annotations

import hashlib
import importlib
import re
import tempfile
import uuid
import zipfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Sequence
from xml.dom.minidom import parseString
from xml.etree.ElementTree import Element, SubElement, tostring

from ...core.errors import DroneflyError
from ...core.files import write_zip
from ...fmi.base3 import fmi3_class
from ...fmi.table3 import fmi3_table
from .build import report_built
from .closedloop import write_container
from .entry import HOST_REQUIREMENT
from .modeldescription import model_description
from .modeldescription3 import model_description3
from .toolchain import (FMI2_PLATFORMS, FMI3_PLATFORMS, PLATFORMS, Toolchain, ToolchainError,
                        find_toolchain, fmi_include_dir, host_platform)

__all__ = ["GENERATION_TOOL", "NATIVE_FMUS", "NATIVE_HOST", "NATIVE_OUT", "NativeBuildError",
           "build_native", "build_native_all", "build_native_container", "c_name", "ensure_native",
           "native_model_description", "native_pair", "native_platforms", "native_sources",
           "vars_c"]

#: where ``dronefly build`` writes the native FMUs, below its output folder (FMI 3.0 in
#: ``native/fmi3``)
NATIVE_OUT = "native"
GENERATION_TOOL = "dronefly-fmu (native C)"
NATIVE_HOST = ("Host requirements: none (native code; binaries for the platforms in binaries/, "
               "C sources in sources/ for any other)")

_ROOT = Path(__file__).resolve().parents[2]
_NAMESPACE = uuid.UUID("0b7f0a36-5c43-4e59-9b1e-0d8a3c1f4e21")


class NativeBuildError(DroneflyError):
    """A native FMU could not be built."""


@dataclass(frozen=True)
class _NativeSpec:
    module: str  # the pythonfmu slave module whose class holds the interface table
    cls: str
    model_dir: str  # the folder of model.c and model.h
    shared: tuple[str, ...]  # shared C files below native/
    #: other models' files that model.c includes: (name in sources/, path in the package)
    included: tuple[tuple[str, str], ...] = ()


_PLANT_C = ("exact.h", "fmu.c", "fmu.h", "expm.c", "expm.h", "linear_plant.c", "linear_plant.h")
_CONTROLLER_C = ("exact.h", "fmu.c", "fmu.h")
#: the rigid body takes its aerodynamic rows from the linear plants' A and B, their own C
_HOVER_INCLUDED = (("lateral_plant.inc", "fmu_src/lateral/model.c"),
                   ("longitudinal_plant.inc", "fmu_src/longitudinal/model.c"))

#: the native FMUs: model name -> where its equations and interface live
NATIVE_FMUS: dict[str, _NativeSpec] = {
    "DroneFlyLateral": _NativeSpec("fmu_src.lateral.slave", "DroneFlyLateral", "fmu_src/lateral",
                                   _PLANT_C),
    "StateFeedback": _NativeSpec("controller.slave", "StateFeedback", "controller", _CONTROLLER_C),
    "DroneFlyLongitudinal": _NativeSpec("fmu_src.longitudinal.slave", "DroneFlyLongitudinal",
                                        "fmu_src/longitudinal", _PLANT_C),
    "StateFeedbackLongitudinal": _NativeSpec("controller.slave", "StateFeedbackLongitudinal",
                                             "controller", _CONTROLLER_C),
    "StateFeedbackDelayed": _NativeSpec("controller.slave", "StateFeedbackDelayed", "controller",
                                        _CONTROLLER_C),
    "StateFeedbackLongitudinalDelayed": _NativeSpec(
        "controller.slave", "StateFeedbackLongitudinalDelayed", "controller", _CONTROLLER_C),
    "DroneFlyHover6DOF": _NativeSpec("fmu_src.hover6dof.slave", "DroneFlyHover6DOF",
                                     "fmu_src/hover6dof", _CONTROLLER_C, _HOVER_INCLUDED),
}

def c_name(name: str) -> str:
    """A variable name as a C identifier suffix: ``A[1,2]`` -> ``A_1_2``."""
    return re.sub(r"_+$", "", re.sub(r"[^0-9A-Za-z_]+", "_", name))


def _c_string(text: str) -> str:
    return '"' + text.replace("\\", "\\\\").replace('"', '\\"') + '"'


def _c_double(x: float) -> str:
    text = repr(float(x))
    return text if re.search(r"[.e]", text) else text + ".0"


def _settable(v: Any) -> str:
    if v.causality == "input":
        return "VS_INPUT"
    if v.causality == "parameter":
        return "VS_TUNABLE" if v.variability == "tunable" else "VS_FIXED"
    return "VS_NONE"


def _start(v: Any) -> float:
    if v.start is None:
        return 0.0
    if isinstance(v.start, bool):
        return 1.0 if v.start else 0.0
    return float(v.start)


def vars_c(cls: Any, token: str) -> tuple[str, str]:
    """``vars.h`` and ``vars.c`` of a slave class: the interface table as C."""
    variables = cls.VARIABLES
    table3 = fmi3_table(variables)
    types = {"Real": "VT_REAL", "Boolean": "VT_BOOLEAN", "Integer": "VT_INTEGER"}
    names = [c_name(v.name) for v in variables]
    if len(set(names)) != len(names):
        raise NativeBuildError(f"{cls.MODEL_NAME}: two variables have the same C name")
    h = ["/* Generated by dronefly.harness.builder.native from the variable table of "
         f"{cls.__module__}.{cls.__name__}: do not edit. */",
         "#ifndef DRONEFLY_VARS_H", "#define DRONEFLY_VARS_H",
         f"#define MODEL_NAME {_c_string(cls.MODEL_NAME)}",
         f"#define MODEL_TOKEN {_c_string(token)}",
         f"#define N_VARS {len(variables)}",
         f"#define N_VARS3 {len(table3)}",
         f"#define DIRECT_FEEDTHROUGH {1 if cls.DIRECT_FEEDTHROUGH else 0}",
         "enum { VT_REAL = 0, VT_BOOLEAN = 1, VT_INTEGER = 2 };",
         "enum { VS_NONE = 0, VS_INPUT = 1, VS_TUNABLE = 2, VS_FIXED = 3 };",
         "extern const double VAR_START[N_VARS];",
         "extern const unsigned char VAR_TYPE[N_VARS];",
         "extern const unsigned char VAR_SET[N_VARS];",
         "extern const char *const VAR_NAME[N_VARS];",
         "/* FMI 3.0: value reference -> its rows (time: none) */",
         "extern const int VAR3_FIRST[N_VARS3];", "extern const int VAR3_COUNT[N_VARS3];",
         "extern const int VAR3_ROWS[];", "extern const char *const VAR3_NAME[N_VARS3];",
         "/* the FMI 2.0 value reference (the row) of each variable */"]
    h += [f"#define VR_{n} {i}" for i, n in enumerate(names)]
    h.append("#endif")
    rows3: list[int] = []
    first3, count3 = [], []
    for e in table3:
        first3.append(len(rows3))
        count3.append(len(e.indices))
        rows3.extend(e.indices)
    c = ["/* Generated by dronefly.harness.builder.native: do not edit. */", '#include "vars.h"',
         "const double VAR_START[N_VARS] = {" + ", ".join(_c_double(_start(v)) for v in variables)
         + "};",
         "const unsigned char VAR_TYPE[N_VARS] = {" + ", ".join(types[v.type] for v in variables)
         + "};",
         "const unsigned char VAR_SET[N_VARS] = {" + ", ".join(_settable(v) for v in variables)
         + "};",
         "const char *const VAR_NAME[N_VARS] = {" + ", ".join(_c_string(v.name) for v in variables)
         + "};",
         "const int VAR3_FIRST[N_VARS3] = {" + ", ".join(map(str, first3)) + "};",
         "const int VAR3_COUNT[N_VARS3] = {" + ", ".join(map(str, count3)) + "};",
         "const int VAR3_ROWS[] = {" + ", ".join(map(str, rows3 or [0])) + "};",
         "const char *const VAR3_NAME[N_VARS3] = {" + ", ".join(_c_string(e.name) for e in table3)
         + "};"]
    return "\n".join(h) + "\n", "\n".join(c) + "\n"


def _slave_class(name: str) -> Any:
    spec = NATIVE_FMUS[name]
    return getattr(importlib.import_module(f"...{spec.module}", __package__), spec.cls)


def _c_files(name: str) -> dict[str, bytes]:
    """The hand-written C files of one native FMU, by their name in ``sources/``."""
    spec = NATIVE_FMUS[name]
    files = {f: (_ROOT / "native" / f).read_bytes() for f in spec.shared}
    for f in ("model.c", "model.h"):
        files[f] = (_ROOT / spec.model_dir / f).read_bytes()
    for f, path in spec.included:
        files[f] = (_ROOT / path).read_bytes()
    return files


def _token(name: str, fmi: int, files: dict[str, bytes]) -> str:
    h = hashlib.sha256(f"{name}:{fmi}".encode())
    for rel, data in sorted(files.items()):
        h.update(rel.encode() + b"\0" + hashlib.sha256(data).digest())
    for v in _slave_class(name).VARIABLES:
        h.update(repr(v).encode())
    return "{" + str(uuid.uuid5(_NAMESPACE, h.hexdigest())) + "}"


def _nativise(root: Element) -> Element:
    """What differs between a native and a pythonfmu model description: generation tool,
    host requirement, needsExecutionTool."""
    root.set("generationTool", GENERATION_TOOL)
    root.set("description", root.get("description", "").replace(HOST_REQUIREMENT, NATIVE_HOST))
    cs = root.find("CoSimulation")
    assert cs is not None
    cs.set("needsExecutionTool", "false")
    return root


def native_model_description(name: str, fmi: int, token: str,
                             sources: Sequence[str] = ()) -> bytes:
    """The model description of the native FMU ``name`` (FMI ``fmi``), from the same table and
    the same generator as the pythonfmu FMU's; FMI 2.0 lists ``sources`` (the C files)."""
    cls = _slave_class(name)
    if fmi == 3:
        root = _nativise(model_description3(fmi3_class(cls), token))
    else:
        root = _nativise(model_description(cls, token))
        cs = root.find("CoSimulation")
        assert cs is not None
        files = SubElement(cs, "SourceFiles")
        for f in sources:
            SubElement(files, "File", {"name": f})
    return parseString(tostring(root, "utf-8")).toprettyxml(indent="  ", encoding="UTF-8")


def _build_description(name: str, c_files: Sequence[str]) -> bytes:
    root = Element("fmiBuildDescription", {"fmiVersion": "3.0"})
    conf = SubElement(root, "BuildConfiguration", {"modelIdentifier": name})
    fs = SubElement(conf, "SourceFileSet", {"language": "C99"})
    for f in c_files:
        SubElement(fs, "SourceFile", {"name": f})
    SubElement(fs, "PreprocessorDefinition", {"name": "FMI_VERSION", "value": "3"})
    return parseString(tostring(root, "utf-8")).toprettyxml(indent="  ", encoding="UTF-8")


def native_sources(name: str, fmi: int) -> tuple[str, dict[str, bytes]]:
    """The token and ``{path in FMU: content}`` of a source-code native FMU (no binaries)."""
    if name not in NATIVE_FMUS:
        raise NativeBuildError(f"no native FMU {name!r}; native: {', '.join(NATIVE_FMUS)}")
    hand = _c_files(name)
    token = _token(name, fmi, hand)
    h, c = vars_c(_slave_class(name), token)
    sources = {**hand, "vars.h": h.encode(), "vars.c": c.encode()}
    c_files = sorted(f for f in sources if f.endswith(".c"))
    files = {f"sources/{f}": data for f, data in sources.items()}
    if fmi == 3:
        files["sources/buildDescription.xml"] = _build_description(name, c_files)
    files["modelDescription.xml"] = native_model_description(name, fmi, token, c_files)
    return token, files


def _is_native(path: Path) -> bool:
    """Whether ``path`` is a native FMU that this build wrote (it is then rebuilt)."""
    try:
        with zipfile.ZipFile(path) as z:
            return GENERATION_TOOL.encode() in z.read("modelDescription.xml") and \
                "sources/vars.c" in z.namelist()
    except (OSError, KeyError, zipfile.BadZipFile):
        return False


def _refuse_foreign(target: Path) -> None:
    if target.is_dir() or (target.exists() and not _is_native(target)):
        raise NativeBuildError(f"{str(target)!r} exists and is not a native FMU that dronefly "
                               "build wrote: it is left alone (move it away, or build into "
                               "another folder)")


def native_platforms(fmi: int, toolchain: Toolchain | None) -> tuple[str, ...]:
    """The platforms ``toolchain`` builds the FMI ``fmi`` binaries for: every one the
    standard names with zig cc (FMI 2.0: linux64, win64, darwin64; FMI 3.0 also aarch64), the
    host's own with the host's compiler; none without a toolchain."""
    if toolchain is None:
        return ()
    names = FMI2_PLATFORMS if fmi == 2 else FMI3_PLATFORMS
    return tuple(n for n in names if toolchain.can_build(n))


def _default_toolchain() -> Toolchain | None:
    return find_toolchain()


def build_native(name: str, out_dir: str | Path, fmi: int = 2, toolchain: Any = True,
                 platforms: Sequence[str] | None = None, *,
                 sanitize: bool = False) -> tuple[Path, tuple[str, ...]]:
    """Build the native FMU ``name`` into ``out_dir``: its path and the platforms it has
    binaries for (``()``: a source-code FMU).

    Parameters
    ----------
    toolchain : Toolchain, True, None or False
        True: :func:`dronefly.harness.builder.toolchain.find_toolchain` (zig cc, else the host's
        compiler); None or False: sources only.
    platforms : sequence of str, optional
        Only these platforms (default: every one the toolchain builds for,
        :func:`native_platforms`).
    sanitize : bool
        Build the binaries with ``-fsanitize=address,undefined`` (the host's compiler; for the
        tests).

    Raises
    ------
    NativeBuildError
        Unknown FMU, a file at the target that the build did not write, a platform the
        toolchain cannot build for, or the compiler failed (a bug: the sources compile
        warning-free).
    """
    if fmi not in (2, 3):
        raise NativeBuildError(f"FMI version {fmi!r}: 2 or 3")
    target = Path(out_dir) / f"{name}.fmu"
    _refuse_foreign(target)
    token, files = native_sources(name, fmi)
    chain = _default_toolchain() if toolchain is True else (toolchain or None)
    targets = native_platforms(fmi, chain) if platforms is None else tuple(platforms)
    if chain is not None and targets:
        with tempfile.TemporaryDirectory(prefix="dronefly-native-") as tmp:
            src = Path(tmp) / "sources"
            src.mkdir()
            for rel, data in files.items():
                if rel.startswith("sources/"):
                    (src / rel[len("sources/"):]).write_bytes(data)
            c_files = sorted(src.glob("*.c"))
            for platform in targets:
                suffix = PLATFORMS[platform].suffix
                out = Path(tmp) / f"{platform}{suffix}"
                try:
                    chain.compile(c_files, out, platform, include_dirs=(src, fmi_include_dir()),
                                  defines={"FMI_VERSION": str(fmi)}, sanitize=sanitize)
                except ToolchainError as e:
                    raise NativeBuildError(f"cannot build {name} for {platform}: {e}") from e
                files[f"binaries/{platform}/{name}{suffix}"] = out.read_bytes()
    else:
        targets = ()
    return report_built(write_zip(target, files)), targets


def ensure_native(name: str, out_dir: str | Path, fmi: int = 2) -> Path:
    """The native FMU ``name`` in ``out_dir``, built only if it is missing, out of date with
    the sources, or has no binary for this machine.

    Raises
    ------
    NativeBuildError
        No C compiler to build it with, or a file there that the build did not write.
    """
    target = Path(out_dir) / f"{name}.fmu"
    if _is_native(target):
        token = native_sources(name, fmi)[0]
        host = host_platform("2.0" if fmi == 2 else "3.0")
        with zipfile.ZipFile(target) as z:
            current = token.encode() in z.read("modelDescription.xml")
            binary = any(n.startswith(f"binaries/{host}/") for n in z.namelist())
        if current and binary:
            return target
    host = host_platform("2.0" if fmi == 2 else "3.0")
    chain = _default_toolchain()
    if chain is None or host is None or not chain.can_build(host):
        raise NativeBuildError(f"no C compiler to build the native {name} FMU for this machine; "
                               "pip install ziglang, or run the pythonfmu FMUs (without --native)")
    return build_native(name, out_dir, fmi, chain, (host,))[0]


def native_pair(build_dir: str | Path = "build") -> tuple[Path, Path]:
    """The native lateral plant and its controller in ``build_dir``/native, built on demand
    (:func:`ensure_native`): what ``--native`` of ``cosim``, ``demo`` and ``sweep`` runs."""
    out = Path(build_dir) / NATIVE_OUT
    return ensure_native("DroneFlyLateral", out), ensure_native("StateFeedback", out)


def build_native_container(out_dir: str | Path) -> Path:
    """The closed-loop container FMU ``DroneFlyClosedLoop.fmu`` from the native FMI 2.0 plant
    and controller in ``out_dir`` (fmpy's container, as :mod:`.closedloop` builds it from the
    pythonfmu FMUs, without the pythonfmu shim)."""
    out = Path(out_dir)
    try:
        return write_container(out / "DroneFlyLateral.fmu", out / "StateFeedback.fmu", out,
                               shim=False)
    except (OSError, ValueError, KeyError) as e:
        raise NativeBuildError(f"cannot build the native closed-loop container: {e}") from e


def build_native_all(out_dir: str | Path, fmi: int = 2, toolchain: Any = True,
                     platforms: Sequence[str] | None = None) -> tuple[list[Path], tuple[str, ...]]:
    """Every native FMU into ``out_dir``; the paths and the platforms of their binaries."""
    paths: list[Path] = []
    built: tuple[str, ...] = ()
    for name in NATIVE_FMUS:  # every target checked before anything is written
        _refuse_foreign(Path(out_dir) / f"{name}.fmu")
    for name in NATIVE_FMUS:
        path, built = build_native(name, out_dir, fmi, toolchain, platforms)
        paths.append(path)
    return paths, built
