"""Check family: what an FMU is without running it (``dronefly check``).

``validate`` lists every problem of modelDescription.xml, each with its rule and section: those
FMPy's validation finds (schema, names, causality/variability/initial, units, ModelStructure)
and those of :mod:`.structure` (beyond FMPy's). ``archive`` checks the FMU's layout: an
implementation (FMI 2.0 2.3, FMI 3.0 2.5: a binary for some platform or the sources), platform
folders with the names the standard gives. Each is ``check(ctx) -> detail``, FMI 2.0 and 3.0
alike; neither loads the FMU's binary, so both run on an FMU that cannot run here.
"""

from __future__ import annotations

import re
import zipfile
from dataclasses import dataclass
from pathlib import Path

from fmpy import platform, platform_tuple, sharedLibraryExtension

from .driver import Context
from .names import validate_fmu
from .rules import require
from .structure import alias_notes, structure_problems

__all__ = ["Layout", "check_archive", "check_validate", "layout", "section_of"]

#: FMI 2.0 2.3: the platform folders of binaries/
FMI2_PLATFORMS = ("win32", "win64", "linux32", "linux64", "darwin32", "darwin64")
#: FMI 3.0 2.5.1.4: a platform tuple <arch>-<sys>
FMI3_PLATFORM = re.compile(r"^(aarch32|aarch64|riscv32|riscv64|x86|x86_64|ppc32|ppc64)-"
                           r"(darwin|linux|windows)$")
_EXTENSIONS = {"win": ".dll", "windows": ".dll", "linux": ".so", "darwin": ".dylib"}

#: the section of a problem FMPy's validation reports, by what it speaks of (first match);
#: (FMI 2.0, FMI 3.0)
_SECTIONS = [
    (re.compile(r"ModelStructure|InitialUnknown|Derivatives|Outputs", re.I), ("2.2.8", "2.4.8")),
    (re.compile(r"declaredType|TypeDefinition|SimpleType", re.I), ("2.2.3", "2.4.3")),
    (re.compile(r"\bunit\b|displayUnit|UnitDefinition", re.I), ("2.2.2", "2.4.2")),
    (re.compile(r"causality|variability|initial|start|must have|derivative|previous", re.I),
     ("2.2.7", "2.4.7")),
    (re.compile(r"schema|element|attribute|XML", re.I), ("2.2", "2.4")),
]


def section_of(problem: str, fmi_version: int) -> str:
    """``FMI 2.0 2.2.7`` for a problem of FMPy's validation about a variable's variability."""
    for pattern, (s2, s3) in _SECTIONS:
        if pattern.search(problem):
            return f"FMI {fmi_version}.0 {s3 if fmi_version == 3 else s2}"
    return f"FMI {fmi_version}.0 {'2.4' if fmi_version == 3 else '2.2'}"


def check_validate(ctx: Context) -> str:
    v = ctx.fmu.fmi_version
    found = [f"{section_of(p, v)}: {p.strip().rstrip('.')}" for p in validate_fmu(str(ctx.fmu.path))]
    ours = [f"FMI {v}.0 {section}: {text}" for section, text
            in structure_problems(ctx.fmu.model_description3 or ctx.fmu.model_description, v)]
    ctx.warnings.extend(alias_notes(ctx.fmu.model_description3 or ctx.fmu.model_description))
    seen = {p.split(": ", 1)[1] for p in found}
    problems = found + [p for p in ours if p.split(": ", 1)[1] not in seen]
    require(not problems, f"{len(problems)} problem(s): "
                          + "; ".join(f"({k}) {p}" for k, p in enumerate(problems, 1)))
    return "no problems (FMPy's validation and the rules of docs/compliance.md)"


@dataclass(frozen=True)
class Layout:
    """What an FMU archive holds: binaries by platform folder, sources, odd folder names."""

    binaries: dict[str, list[str]]  # platform folder -> the model identifiers with a binary
    sources: bool
    unknown_platforms: list[str]
    here: str  # this platform's folder name (linux64 / x86_64-linux)

    def runs_here(self, identifier: str) -> bool:
        return identifier in self.binaries.get(self.here, [])

    def platforms_with(self, identifier: str) -> list[str]:
        return sorted(p for p, ids in self.binaries.items() if identifier in ids)


def layout(path: Path, fmi_version: int) -> Layout:
    """The :class:`Layout` of the FMU file ``path``."""
    with zipfile.ZipFile(path) as z:
        names = z.namelist()
    binaries: dict[str, list[str]] = {}
    unknown = []
    for n in names:
        parts = n.split("/")
        if len(parts) != 3 or parts[0] != "binaries" or not parts[2]:
            continue
        folder, file = parts[1], parts[2]
        known = (folder in FMI2_PLATFORMS if fmi_version == 2
                 else FMI3_PLATFORM.match(folder) is not None)
        if not known and folder not in unknown:
            unknown.append(folder)
        system = re.sub(r"\d+$", "", folder.split("-")[-1])
        ext = _EXTENSIONS.get(system)
        if ext and file.endswith(ext):
            binaries.setdefault(folder, []).append(file[: -len(ext)])
    sources = any(n.startswith("sources/") and not n.endswith("/") for n in names)
    here = platform if fmi_version == 2 else platform_tuple
    assert _EXTENSIONS.get(re.sub(r"\d+$", "", here.split("-")[-1])) == sharedLibraryExtension
    return Layout(binaries, sources, unknown, here)


def _identifiers(ctx: Context) -> list[str]:
    md = ctx.fmu.model_description3 or ctx.fmu.model_description
    return sorted({i.modelIdentifier for i in (md.coSimulation, md.modelExchange,
                                               getattr(md, "scheduledExecution", None))
                   if i is not None})


def check_archive(ctx: Context) -> str:
    v = ctx.fmu.fmi_version
    lay = layout(ctx.fmu.path, v)
    section = "2.5" if v == 3 else "2.3"
    named = ("win32, win64, linux32, linux64, darwin32 or darwin64" if v == 2
             else "<arch>-<sys> (x86_64-linux, aarch64-darwin, x86-windows, ...)")
    problems = [f"binaries/{p}: not a platform folder of FMI {v}.0 {section} ({named})"
                for p in lay.unknown_platforms]
    ids = _identifiers(ctx)
    implemented = [i for i in ids if lay.platforms_with(i)]
    if not implemented and not lay.sources:
        problems.append(f"no implementation: neither a binary binaries/<platform>/"
                        f"{'|'.join(ids)}.<dll|so|dylib> nor sources/ (FMI {v}.0 {section}: "
                        "an FMU is distributed in source code and/or binary form)")
    require(not problems, "; ".join(problems))
    where = ", ".join(f"{p}" for p in sorted(lay.binaries)) or "none"
    return f"binaries for {where}" + ("; sources" if lay.sources else "")


def cannot_run(ctx: Context) -> str | None:
    """Why the FMU cannot run on this machine (its Co-Simulation interface, or its Model
    Exchange one if it has no other), or None."""
    md = ctx.fmu.model_description
    ident = (md.coSimulation or md.modelExchange).modelIdentifier
    lay = layout(ctx.fmu.path, ctx.fmu.fmi_version)
    if lay.runs_here(ident):
        return None
    others = lay.platforms_with(ident)
    if others:
        return f"cannot run on {lay.here}: binaries for {', '.join(others)} only"
    if lay.sources:
        return (f"cannot run on {lay.here}: no binary for it, only sources (dronefly check "
                "does not compile them)")
    return f"cannot run on {lay.here}: no implementation (see archive)"
