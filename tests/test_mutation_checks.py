"""The checker's checks that read an archive or call a binary (harness/compliance/static.py,
names.py, ...), on small inputs in-process: tiny FMU archives written in tmp_path, stub contexts
(the attributes a check reads), the Modelica Reference-FMUs. Written against the mutants that
survived the other tests (docs/mutation.md). Oracles: the FMI standard's text (FMI 2.0 2.3 and
FMI 3.0 2.5 for the archive's layout, 2.2.9 / 2.4.7.5 for the names' grammar, the sections of
the model description), and defects seeded by hand. No FMU is built: a mutant costs seconds."""

from __future__ import annotations

import ctypes
import math
import sys
import dataclasses
import zipfile
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from fmpy import platform, platform_tuple, read_model_description
from fmpy.fmi1 import FMICallException

from dronefly.harness.compliance import binary, exchange, names, reference, refusals, runtime, static
from dronefly.harness.compliance.rules import CheckFailed, CheckSkipped
from shared_files import edited_copy, need_shared


# --- helpers: a modelDescription.xml, an archive holding it, a context of it -----------------

_OUT2 = ('<ScalarVariable name="y" valueReference="1" causality="output"><Real/>'
         '</ScalarVariable>')
_STRUCT2 = ('<Outputs><Unknown index="1"/></Outputs>'
            '<InitialUnknowns><Unknown index="1"/></InitialUnknowns>')
_OUT3 = ('<Float64 name="time" valueReference="0" causality="independent" '
         'variability="continuous"/><Float64 name="y" valueReference="1" causality="output"/>')
_STRUCT3 = '<Output valueReference="1"/><InitialUnknown valueReference="1"/>'


def _xml(fmi: int = 2, variables: str | None = None, structure: str | None = None,
         interfaces: str = '<CoSimulation modelIdentifier="m"/>', naming: str = "") -> str:
    if fmi == 2:
        variables = _OUT2 if variables is None else variables
        structure = _STRUCT2 if structure is None else structure
        head = 'fmiVersion="2.0" modelName="m" guid="{0}"'
    else:
        variables = _OUT3 if variables is None else variables
        structure = _STRUCT3 if structure is None else structure
        head = 'fmiVersion="3.0" modelName="m" instantiationToken="{0}"'
    return (f'<?xml version="1.0" encoding="UTF-8"?>\n<fmiModelDescription {head} {naming}>\n'
            f'{interfaces}\n<ModelVariables>\n{variables}\n</ModelVariables>\n'
            f'<ModelStructure>\n{structure}\n</ModelStructure>\n</fmiModelDescription>\n')


def _archive(tmp_path: Path, xml: str | None, files=("sources/m.c",), name: str = "m.fmu") -> Path:
    path = tmp_path / name
    with zipfile.ZipFile(path, "w") as z:
        if xml is not None:
            z.writestr("modelDescription.xml", xml)
        for f in files:
            z.writestr(f, "")
    return path


def _ctx(path: Path, fmi: int = 2) -> SimpleNamespace:
    md = read_model_description(str(path), validate=False)
    fmu = SimpleNamespace(path=path, fmi_version=fmi, model_description=md,
                          model_description3=md if fmi == 3 else None)
    return SimpleNamespace(fmu=fmu, warnings=[])


# --- static.py: validate ---------------------------------------------------------------------

@pytest.mark.parametrize("problem, s2, s3", [
    # the sections of the model description each problem speaks of (FMI 2.0 / FMI 3.0)
    ("ModelStructure/Outputs lists 1 twice", "2.2.8", "2.4.8"),
    ("InitialUnknowns does not contain y", "2.2.8", "2.4.8"),
    ("the declaredType 'T' is not defined", "2.2.3", "2.4.3"),
    ("the unit 'm' is not defined", "2.2.2", "2.4.2"),
    ("displayUnit 'km' of x", "2.2.2", "2.4.2"),
    ('causality="input" requires a start value', "2.2.7", "2.4.7"),
    ("variable x must have a start value", "2.2.7", "2.4.7"),
    ("Element 'Foo': this element is not expected", "2.2", "2.4"),
    ("something else entirely", "2.2", "2.4"),  # no match: the description's section
])
def test_section_of_a_problem_is_the_section_it_speaks_of(problem, s2, s3):
    assert static.section_of(problem, 2) == f"FMI 2.0 {s2}"
    assert static.section_of(problem, 3) == f"FMI 3.0 {s3}"


def test_validate_passes_a_compliant_description_fmi2_and_fmi3(tmp_path):
    for fmi in (2, 3):
        ctx = _ctx(_archive(tmp_path, _xml(fmi), name=f"ok{fmi}.fmu"), fmi)
        assert "no problems" in static.check_validate(ctx)
        assert ctx.warnings == []


def test_validate_lists_fmpys_problems_and_ours_numbered_with_their_sections(tmp_path):
    # seeded: the output left out of InitialUnknowns (FMPy finds it, FMI 2.0 2.2.8) and a
    # parameter with min > max and start > max (FMPy does not look; ours, 2.2.7)
    xml = _xml(2, _OUT2 + '<ScalarVariable name="p" valueReference="2" causality="parameter" '
               'variability="fixed"><Real start="5" min="2" max="1"/></ScalarVariable>',
               '<Outputs><Unknown index="1"/></Outputs>')
    with pytest.raises(CheckFailed) as e:
        static.check_validate(_ctx(_archive(tmp_path, xml)))
    msg = str(e.value)
    assert msg.startswith("3 problem(s): (1) FMI 2.0 2.2.8: ModelStructure/InitialUnknowns "), msg
    assert "Expected {y} but was {}; (2) FMI 2.0 2.2.7: variable 'p': min 2.0 > max 1.0; " \
           "(3) FMI 2.0 2.2.7: variable 'p': start 5.0 > max 1.0" in msg, msg
    assert not msg.endswith(".")


def test_validate_lists_a_problem_both_find_once(tmp_path, monkeypatch):
    """A problem FMPy words as ours is listed once; ours of the same section stay listed."""
    xml = _xml(2, _OUT2 + '<ScalarVariable name="p" valueReference="2" causality="parameter" '
               'variability="fixed"><Real start="5" min="2" max="1"/></ScalarVariable>')
    monkeypatch.setattr(static, "validate_fmu", lambda path: [
        "variable 'p': start 5.0 > max 1.0.", "the schema: x: y"])
    with pytest.raises(CheckFailed) as e:
        static.check_validate(_ctx(_archive(tmp_path, xml)))
    assert str(e.value) == (
        "3 problem(s): (1) FMI 2.0 2.2.7: variable 'p': start 5.0 > max 1.0; "
        "(2) FMI 2.0 2.2: the schema: x: y; (3) FMI 2.0 2.2.7: variable 'p': min 2.0 > max 1.0")


def test_validate_notes_fmi2_aliases_of_different_variability_and_passes(tmp_path):
    xml = _xml(2, _OUT2 + '<ScalarVariable name="a" valueReference="7" variability="discrete">'
               '<Real/></ScalarVariable><ScalarVariable name="b" valueReference="7" '
               'variability="continuous"><Real/></ScalarVariable>')
    ctx = _ctx(_archive(tmp_path, xml))
    static.check_validate(ctx)
    assert len(ctx.warnings) == 1 and "'a', 'b' (value reference 7)" in ctx.warnings[0]


# --- static.py: archive (FMI 2.0 2.3, FMI 3.0 2.5) --------------------------------------------

_FILES2 = ("binaries/linux64/m.so", "binaries/win64/m.dll", "binaries/darwin64/m.dylib",
           "binaries/win32/m.so",  # a Linux library in a Windows folder: not m's binary there
           "binaries/linux32/", "binaries/linux32/other.so", "binaries/linux64/x/m.so",
           "binaries/Linux64/m.so",  # no system "Linux": no binary, an unknown folder
           "binaries/x86_64-linux/m.so", "documentation/m.so",
           "resources/linux/m.so", "documentation/win64/m.dll",  # 2.3: only binaries/ holds binaries
           "binaries//m.so",  # a folder with no name is no platform folder either
           "sources/")


def test_layout_fmi2_reads_binaries_by_platform_folder(tmp_path):
    lay = static.layout(_archive(tmp_path, _xml(2), _FILES2), 2)
    assert lay.binaries == {"linux64": ["m"], "win64": ["m"], "darwin64": ["m"],
                            "linux32": ["other"], "x86_64-linux": ["m"]}
    assert lay.unknown_platforms == ["Linux64", "x86_64-linux", ""]  # each once, in order
    assert lay.sources is False  # an empty folder is no sources
    assert lay.here == platform == "linux64"
    assert lay.runs_here("m") and not lay.runs_here("other")
    assert lay.platforms_with("m") == ["darwin64", "linux64", "win64", "x86_64-linux"]
    assert lay.platforms_with("nothing") == []
    with pytest.raises(dataclasses.FrozenInstanceError):  # what the archive holds: a value
        lay.sources = True  # type: ignore[misc]


def test_layout_fmi3_platform_tuples(tmp_path):
    files = ("binaries/x86_64-linux/m.so", "binaries/aarch64-darwin/m.dylib",
             "binaries/x86-windows/m.dll", "binaries/x86_64-windows/m.so",
             "binaries/linux64/m.so", "binaries/x86_64-linux/m.so.1", "sources/m.c")
    lay = static.layout(_archive(tmp_path, _xml(3), files), 3)
    assert lay.binaries == {"x86_64-linux": ["m"], "aarch64-darwin": ["m"],
                            "x86-windows": ["m"], "linux64": ["m"]}
    assert lay.unknown_platforms == ["linux64"]
    assert lay.sources is True
    assert lay.here == platform_tuple == "x86_64-linux"
    assert lay.runs_here("m")


def test_archive_passes_binaries_or_sources(tmp_path):
    ctx = _ctx(_archive(tmp_path, _xml(2), ("binaries/win64/m.dll", "binaries/linux64/m.so")))
    assert static.check_archive(ctx) == "binaries for linux64, win64"
    ctx = _ctx(_archive(tmp_path, _xml(3), ("sources/m.c",), "s.fmu"), 3)
    assert static.check_archive(ctx) == "binaries for none; sources"
    # Model Exchange only: its identifier's binary is the implementation
    xml = _xml(2, interfaces='<ModelExchange modelIdentifier="e"/>')
    ctx = _ctx(_archive(tmp_path, xml, ("binaries/linux64/e.so", "sources/e.c"), "e.fmu"))
    assert static.check_archive(ctx) == "binaries for linux64; sources"


@pytest.mark.parametrize("fmi, section", [(2, "2.3"), (3, "2.5")])
def test_archive_without_an_implementation_fails_citing_the_distribution_section(
        tmp_path, fmi, section):
    # a binary under another name than a model identifier is no implementation of it
    xml = _xml(fmi, interfaces='<ModelExchange modelIdentifier="e"/>'
                               '<CoSimulation modelIdentifier="c"/>')
    folder = "linux64" if fmi == 2 else "x86_64-linux"
    ctx = _ctx(_archive(tmp_path, xml, (f"binaries/{folder}/m.so", "sources/")), fmi)
    with pytest.raises(CheckFailed) as e:
        static.check_archive(ctx)
    assert str(e.value) == (
        "no implementation: neither a binary binaries/<platform>/c|e.<dll|so|dylib> nor "
        f"sources/ (FMI {fmi}.0 {section}: an FMU is distributed in source code and/or "
        "binary form)")


def test_archive_fails_platform_folders_the_standard_does_not_name(tmp_path):
    ctx = _ctx(_archive(tmp_path, _xml(2), ("binaries/linux64/m.so", "binaries/linux/m.so")))
    with pytest.raises(CheckFailed) as e:
        static.check_archive(ctx)
    assert str(e.value) == ("binaries/linux: not a platform folder of FMI 2.0 2.3 (win32, win64, "
                            "linux32, linux64, darwin32 or darwin64)")
    ctx = _ctx(_archive(tmp_path, _xml(3), ("binaries/x86_64-linux/m.so",
                                            "binaries/win64/m.dll"), "3.fmu"), 3)
    with pytest.raises(CheckFailed) as e:
        static.check_archive(ctx)
    assert str(e.value).startswith("binaries/win64: not a platform folder of FMI 3.0 2.5 "
                                   "(<arch>-<sys> ")


def test_cannot_run_says_why_the_fmu_cannot_run_here(tmp_path):
    def why(files, fmi=2, xml=None, name="w.fmu"):
        return static.cannot_run(_ctx(_archive(tmp_path, xml or _xml(fmi), files, name), fmi))

    assert why(("binaries/linux64/m.so",), name="a.fmu") is None
    assert why(("binaries/x86_64-linux/m.so",), 3, name="b.fmu") is None
    assert why(("binaries/win64/m.dll", "binaries/darwin64/m.dylib"), name="c.fmu") == \
        "cannot run on linux64: binaries for darwin64, win64 only"
    assert why(("sources/m.c",), 3, name="d.fmu") == (
        "cannot run on x86_64-linux: no binary for it, only sources (dronefly check does not "
        "compile them)")
    assert why((), name="e.fmu") == "cannot run on linux64: no implementation (see archive)"
    # Model Exchange only: its identifier decides
    me = _xml(2, interfaces='<ModelExchange modelIdentifier="e"/>')
    assert why(("binaries/linux64/e.so",), xml=me, name="f.fmu") is None
    # both: the Co-Simulation interface's binary decides
    both = _xml(2, interfaces='<ModelExchange modelIdentifier="e"/>'
                              '<CoSimulation modelIdentifier="c"/>')
    assert why(("binaries/linux64/e.so",), xml=both, name="g.fmu") == \
        "cannot run on linux64: no implementation (see archive)"


# --- names.py: validate_fmu, FMPy's validate_fmu with the names decided here -------------------

def _same_as_fmpys(path) -> list[str]:
    """Our problems of ``path``, checked against FMPy's own validation of it (the oracle: the
    same problems in the same words; FMPy leaves out an archive's backslash paths when the
    description fails)."""
    import fmpy.validation

    ours, theirs = names.validate_fmu(str(path)), fmpy.validation.validate_fmu(str(path))
    assert sorted(ours) == sorted(theirs), (ours, theirs)
    return ours


def test_flat_names_must_not_hold_a_carriage_return_line_feed_or_tab(tmp_path):
    # FMI 2.0 2.2.9: a flat name is any Unicode string without CR (#xD), LF (#xA) nor tab (#x9)
    variables = _OUT2 + "".join(
        f'<ScalarVariable name="{n}" valueReference="{k}"><Real/></ScalarVariable>'
        for k, n in ((2, "a&#13;b"), (3, "c&#10;d"), (4, "e&#9;f"), (5, "g h.'i'[1]"),
                     (6, "&#9;x&#10;"), (7, "1x")))
    got = _same_as_fmpys(_archive(tmp_path, _xml(2, variables)))
    assert sorted(p.split(" contains an illegal ")[1] for p in got) == sorted([
        "carriage return character (U+000D).", "line feed character (U+000A).",
        "tab character (U+0009).", "line feed character (U+000A).", "tab character (U+0009)."])
    assert all(p.startswith('Variable "') for p in got)


def test_structured_names_outside_the_grammar_are_listed(tmp_path):
    variables = _OUT2 + "".join(
        f'<ScalarVariable name="{n}" valueReference="{k}"><Real/></ScalarVariable>'
        for k, n in ((2, "1x"), (3, "a.b[1,2]"), (4, "der(a.b)"), (5, "a b")))
    got = names.validate_fmu(str(_archive(tmp_path, _xml(
        2, variables, naming='variableNamingConvention="structured"'))))
    assert [p.split(" (line ")[0] for p in got] == ['"1x"', '"a b"']
    assert all(p.endswith('is not a legal variable name for naming convention "structured".')
               for p in got)


def test_a_schema_violation_is_listed_alone_as_fmpy_lists_it(tmp_path):
    """FMPy checks the names in the pass after the schema: a description that fails the schema
    lists the schema's problems, not the names'."""
    variables = _OUT2 + ('<ScalarVariable name="1x" valueReference="2" bogus="1"><Real/>'
                         '</ScalarVariable>')
    got = _same_as_fmpys(_archive(tmp_path, _xml(
        2, variables, naming='variableNamingConvention="structured"')))
    assert got and not any("legal variable name" in p for p in got)
    assert any("bogus" in p for p in got), got


def test_a_backslash_in_an_archive_path_is_listed(tmp_path):
    # a zip file's paths are separated by "/" (FMPy's rule, ZIP's APPNOTE 4.4.17)
    path = _archive(tmp_path, _xml(2), ("sources\\m.c", "sources/n.c"))
    assert _same_as_fmpys(path) == ['The file path "sources\\m.c" contains a backslash.']
    # kept beside the description's problems (FMPy's validate_fmu drops it there)
    path = _archive(tmp_path, _xml(2, structure=""), ("sources\\m.c",), "b.fmu")
    got = names.validate_fmu(str(path))
    assert got[0] == 'The file path "sources\\m.c" contains a backslash.' and len(got) > 1


def test_an_extracted_fmu_and_an_unreadable_one(tmp_path):
    folder = tmp_path / "extracted"
    folder.mkdir()
    (folder / "modelDescription.xml").write_text(_xml(2))
    assert _same_as_fmpys(folder) == []
    # an archive without modelDescription.xml: FMPy's failure, as text
    got = _same_as_fmpys(_archive(tmp_path, None, ("sources/m.c",), "none.fmu"))
    assert len(got) == 1 and "modelDescription.xml" in got[0], got


# --- binary.py: the functions a binary exports, its version strings, what its logger gets ------

REF = Path(__file__).resolve().parents[1].parent / "shared" / "reference-fmus"

# fmi2Functions.h (FMI 2.0 2.1.1, 3.2, 4.2): the common functions, then Model Exchange's and
# Co-Simulation's, and those a capability flag asks for
_FMI2_COMMON = {"fmi2GetTypesPlatform", "fmi2GetVersion", "fmi2SetDebugLogging",
                "fmi2Instantiate", "fmi2FreeInstance", "fmi2SetupExperiment",
                "fmi2EnterInitializationMode", "fmi2ExitInitializationMode", "fmi2Terminate",
                "fmi2Reset", "fmi2GetReal", "fmi2GetInteger", "fmi2GetBoolean", "fmi2GetString",
                "fmi2SetReal", "fmi2SetInteger", "fmi2SetBoolean", "fmi2SetString"}
_FMI2_STATE = {"fmi2GetFMUstate", "fmi2SetFMUstate", "fmi2FreeFMUstate"}
_FMI2_SERIAL = {"fmi2SerializedFMUstateSize", "fmi2SerializeFMUstate",
                "fmi2DeSerializeFMUstate"}
_FMI2_ME = {"fmi2EnterEventMode", "fmi2NewDiscreteStates", "fmi2EnterContinuousTimeMode",
            "fmi2CompletedIntegratorStep", "fmi2SetTime", "fmi2SetContinuousStates",
            "fmi2GetDerivatives", "fmi2GetEventIndicators", "fmi2GetContinuousStates",
            "fmi2GetNominalsOfContinuousStates"}
_FMI2_CS = {"fmi2SetRealInputDerivatives", "fmi2GetRealOutputDerivatives", "fmi2DoStep",
            "fmi2CancelStep", "fmi2GetStatus", "fmi2GetRealStatus", "fmi2GetIntegerStatus",
            "fmi2GetBooleanStatus", "fmi2GetStringStatus"}
# fmi3Functions.h (FMI 3.0 2.2.1, 3.2, 4.2)
_FMI3_COMMON = {"fmi3GetVersion", "fmi3SetDebugLogging", "fmi3FreeInstance",
                "fmi3EnterInitializationMode", "fmi3ExitInitializationMode", "fmi3Terminate",
                "fmi3Reset", "fmi3EnterConfigurationMode", "fmi3ExitConfigurationMode"} | {
    f"fmi3{a}{t}" for a in ("Get", "Set") for t in (
        "Float32", "Float64", "Int8", "UInt8", "Int16", "UInt16", "Int32", "UInt32", "Int64",
        "UInt64", "Boolean", "String", "Binary")}
_FMI3_STATE = {"fmi3GetFMUState", "fmi3SetFMUState", "fmi3FreeFMUState"}
_FMI3_SERIAL = {"fmi3SerializedFMUStateSize", "fmi3SerializeFMUState",
                "fmi3DeserializeFMUState"}
_FMI3_CS = {"fmi3InstantiateCoSimulation", "fmi3DoStep", "fmi3EnterStepMode"}
_FMI3_ME = {"fmi3InstantiateModelExchange", "fmi3EnterEventMode", "fmi3UpdateDiscreteStates",
            "fmi3EnterContinuousTimeMode", "fmi3CompletedIntegratorStep", "fmi3SetTime",
            "fmi3SetContinuousStates", "fmi3GetContinuousStateDerivatives",
            "fmi3GetEventIndicators", "fmi3GetContinuousStates",
            "fmi3GetNominalsOfContinuousStates", "fmi3GetNumberOfEventIndicators",
            "fmi3GetNumberOfContinuousStates"}


def _caps(state=False, serial=False, dd=False, dd_attr="providesDirectionalDerivative",
          ident="m"):
    return SimpleNamespace(modelIdentifier=ident, canGetAndSetFMUstate=state,
                           canSerializeFMUstate=serial, **{dd_attr: dd})


@pytest.mark.parametrize("fmi, interface, common, own, state, serial", [
    (2, "cs", _FMI2_COMMON, _FMI2_CS, _FMI2_STATE, _FMI2_SERIAL),
    (2, "me", _FMI2_COMMON, _FMI2_ME, _FMI2_STATE, _FMI2_SERIAL),
    (3, "cs", _FMI3_COMMON, _FMI3_CS, _FMI3_STATE, _FMI3_SERIAL),
    (3, "me", _FMI3_COMMON, _FMI3_ME, _FMI3_STATE, _FMI3_SERIAL),
])
def test_required_functions_are_the_interfaces_and_the_declared_capabilities(
        fmi, interface, common, own, state, serial):
    # the capabilities of the interface asked for count, not the other one's
    def md(caps):
        other = _caps(True, True, True, "providesDirectionalDerivative")
        return SimpleNamespace(modelExchange=caps if interface == "me" else other,
                               coSimulation=caps if interface == "cs" else other)

    dd = f"fmi{fmi}GetDirectionalDerivative"
    got = binary.required_functions(md(_caps()), fmi, interface)
    assert len(got) == len(set(got)) and set(got) == common | own
    assert set(binary.required_functions(md(_caps(state=True)), fmi, interface)) == \
        common | own | state
    assert set(binary.required_functions(md(_caps(serial=True)), fmi, interface)) == \
        common | own | serial
    assert set(binary.required_functions(md(_caps(dd=True)), fmi, interface)) == \
        common | own | {dd}
    # FMI 3.0 names the attribute providesDirectionalDerivatives
    assert set(binary.required_functions(
        md(_caps(dd=True, dd_attr="providesDirectionalDerivatives")), fmi, interface)) == \
        common | own | {dd}
    # an object without FMI 2.0's attribute (FMI 3.0's name only, not declared): none
    assert set(binary.required_functions(
        md(_caps(dd=False, dd_attr="providesDirectionalDerivatives")), fmi, interface)) == \
        common | own
    # what the description says where the object does not (FMPy's FMI 3.0 objects)
    assert set(binary.required_functions(md(_caps()), fmi, interface, True)) == \
        common | own | {dd}
    assert set(binary.required_functions(md(_caps(dd=True)), fmi, interface, False)) == \
        common | own
    if interface == "cs":
        assert set(binary.required_functions(md(_caps()), fmi)) == common | own  # the default


class _Function:
    def __init__(self, value):
        self.value, self.restype, self.argtypes, self.calls = value, None, None, 0

    def __call__(self):
        assert self.restype is ctypes.c_char_p and self.argtypes == []  # as the header declares
        self.calls += 1
        return self.value


def _fake_libraries(monkeypatch, exports: dict[str, set[str]], versions=None):
    """ctypes.CDLL as binary.py calls it, on libraries (by file name) that export ``exports``;
    the version functions answer ``versions`` (name -> bytes or None)."""
    versions = {"fmi2GetVersion": b"2.0", "fmi2GetTypesPlatform": b"default",
                "fmi3GetVersion": b"3.0", **(versions or {})}

    def cdll(path, mode=0):
        lib = SimpleNamespace()
        for n in exports[Path(path).name]:
            setattr(lib, n, _Function(versions[n]) if n in versions else object())
        return lib

    monkeypatch.setattr(binary.ctypes, "CDLL", cdll)


def _binary_ctx(tmp_path, fmi, interfaces=("cs",), files=("m.so",), cs="m", me="m",
                caps=None):
    folder = tmp_path / "binaries" / (platform if fmi == 2 else platform_tuple)
    folder.mkdir(parents=True, exist_ok=True)
    for f in files:
        (folder / f).write_bytes(b"")
    (tmp_path / "modelDescription.xml").write_text(_xml(fmi, interfaces=(
        f'<ModelExchange modelIdentifier="{me}"/>' if "me" in interfaces else "")
        + f'<CoSimulation modelIdentifier="{cs}"/>'))
    md = SimpleNamespace(coSimulation=caps or _caps(ident=cs),
                         modelExchange=_caps(ident=me) if "me" in interfaces else None)
    fmu = SimpleNamespace(fmi_version=fmi, model_description=md,
                          model_description3=md if fmi == 3 else None, _unzipdir=str(tmp_path))
    events: list[dict] = []
    return SimpleNamespace(fmu=fmu, interfaces=interfaces, unusable=None, events=events,
                           event=lambda **row: events.append(row))


def test_binary_passes_a_library_with_every_function_and_the_right_versions(
        tmp_path, monkeypatch):
    _fake_libraries(monkeypatch, {"m.so": _FMI2_COMMON | _FMI2_CS | _FMI2_ME})
    ctx = _binary_ctx(tmp_path, 2, ("cs", "me"))
    # one library for both interfaces: each function once
    assert binary.check_binary(ctx) == (
        f"{len(_FMI2_COMMON | _FMI2_CS | _FMI2_ME)} required functions exported; "
        "fmi2GetVersion, fmi2GetTypesPlatform right")
    assert ctx.unusable is None
    assert {"call": "fmi2GetVersion()"} in ctx.events
    ctx = _binary_ctx(tmp_path / "3", 3)
    _fake_libraries(monkeypatch, {"m.so": _FMI3_COMMON | _FMI3_CS})
    assert binary.check_binary(ctx) == (f"{len(_FMI3_COMMON | _FMI3_CS)} required functions "
                                        "exported; fmi3GetVersion right")


@pytest.mark.parametrize("fmi, missing", [(2, "fmi2CancelStep"), (3, "fmi3EnterStepMode"),
                                          (2, "fmi2GetVersion")])
def test_a_function_not_exported_fails_binary_and_makes_the_fmu_unusable(
        tmp_path, monkeypatch, fmi, missing):
    common, cs = (_FMI2_COMMON, _FMI2_CS) if fmi == 2 else (_FMI3_COMMON, _FMI3_CS)
    _fake_libraries(monkeypatch, {"m.so": (common | cs) - {missing}})
    ctx = _binary_ctx(tmp_path, fmi)
    with pytest.raises(CheckFailed) as e:
        binary.check_binary(ctx)
    assert str(e.value) == f"not exported: {missing}"
    assert ctx.unusable and "lacks functions" in ctx.unusable


@pytest.mark.parametrize("fmi, versions, problem", [
    (2, {"fmi2GetVersion": b"2.1"}, "fmi2GetVersion() returned '2.1', not '2.0'"),
    (2, {"fmi2GetTypesPlatform": None}, "fmi2GetTypesPlatform() returned None, not 'default'"),
    (2, {"fmi2GetVersion": b"3.0", "fmi2GetTypesPlatform": b"x"},
     "fmi2GetVersion() returned '3.0', not '2.0'; fmi2GetTypesPlatform() returned 'x', not "
     "'default'"),
    (3, {"fmi3GetVersion": b"2.0"}, "fmi3GetVersion() returned '2.0', not '3.0'"),
])
def test_a_wrong_version_string_fails_binary(tmp_path, monkeypatch, fmi, versions, problem):
    common, cs = (_FMI2_COMMON, _FMI2_CS) if fmi == 2 else (_FMI3_COMMON, _FMI3_CS)
    _fake_libraries(monkeypatch, {"m.so": common | cs}, versions)
    ctx = _binary_ctx(tmp_path, fmi)
    with pytest.raises(CheckFailed) as e:
        binary.check_binary(ctx)
    assert str(e.value) == problem
    assert ctx.unusable is None  # every function is there: a host can use it


def test_binary_without_this_platforms_library_is_skipped_and_a_second_one_missing_fails(
        tmp_path, monkeypatch):
    with pytest.raises(binary.CheckSkipped, match="^no binary m.so for this platform$"):
        binary.check_binary(_binary_ctx(tmp_path, 2, files=()))
    # Co-Simulation and Model Exchange with their own identifiers: each needs its library
    _fake_libraries(monkeypatch, {"c.so": _FMI2_COMMON | _FMI2_CS,
                                  "e.so": _FMI2_COMMON | _FMI2_ME - {"fmi2SetTime"}})
    ctx = _binary_ctx(tmp_path / "a", 2, ("cs", "me"), ("c.so",), cs="c", me="e")
    with pytest.raises(CheckFailed) as e:
        binary.check_binary(ctx)
    assert str(e.value) == "no binary e.so for this platform beside c.so"
    ctx = _binary_ctx(tmp_path / "b", 2, ("cs", "me"), ("c.so", "e.so"), cs="c", me="e")
    with pytest.raises(CheckFailed) as e:
        binary.check_binary(ctx)
    assert str(e.value) == "not exported: fmi2SetTime"


@pytest.fixture(scope="module")
def reference_dahlquist(tmp_path_factory):
    """The Reference-FMUs' Dahlquist, FMI 2.0 and 3.0, extracted: {version: (folder, md)}."""
    import fmpy

    out = {}
    for fmi in (2, 3):
        source = REF / f"fmi{fmi}" / "Dahlquist.fmu"
        need_shared(source, "the Reference-FMUs")
        folder = tmp_path_factory.mktemp(f"dahlquist{fmi}")
        fmpy.extract(str(source), str(folder))
        out[fmi] = (folder, read_model_description(str(source)))
    return out


def _reference_ctx(reference_dahlquist, fmi):
    folder, md = reference_dahlquist[fmi]
    fmu = SimpleNamespace(fmi_version=fmi, model_description=md,
                          model_description3=md if fmi == 3 else None, _unzipdir=str(folder))
    return SimpleNamespace(fmu=fmu, interfaces=("cs", "me"), unusable=None, start=0.0,
                           stop=1.0, event=lambda **row: None)


@pytest.mark.parametrize("fmi", [2, 3])
def test_the_reference_fmus_binary_passes(reference_dahlquist, fmi):
    ctx = _reference_ctx(reference_dahlquist, fmi)
    assert binary.check_binary(ctx).endswith(
        "fmi2GetVersion, fmi2GetTypesPlatform right" if fmi == 2 else "fmi3GetVersion right")
    assert ctx.unusable is None


@pytest.mark.parametrize("fmi", [2, 3])
def test_the_reference_fmus_logger_gets_what_the_host_passed(reference_dahlquist, fmi):
    # Dahlquist logs one message with logging on (its fmi2DoStep / fmi3DoStep of size 0)
    assert binary.logger_passes_back(_reference_ctx(reference_dahlquist, fmi)) == ("", 1)


class _Slave2:
    """An FMI 2.0 slave (FMPy's FMU2Slave as binary.py calls it) whose fmi2DoStep logs
    ``messages``: (componentEnvironment, instance name) pairs, None for what the FMU takes from
    the host (FMI 2.0 2.1.5: the logger gets the host's componentEnvironment and the instance's
    name)."""

    messages: list = []
    log: list = []

    def __init__(self, guid, unzipDirectory, modelIdentifier, instanceName):
        self.name, self.component = instanceName, 1

    def instantiate(self, callbacks, loggingOn):
        assert loggingOn is True  # no logging, no message to check
        self.cb = callbacks

    def setupExperiment(self, startTime, stopTime):
        pass

    def enterInitializationMode(self):
        pass

    def exitInitializationMode(self):
        pass

    def doStep(self, currentCommunicationPoint, communicationStepSize):
        assert communicationStepSize == 0.0
        for env, name in self.messages:
            self.cb.logger(self.cb.componentEnvironment if env is None else env,
                           (self.name if name is None else name).encode(), 0, b"c", b"m")

    def fmi2FreeInstance(self, component):
        self.log.append("free")

    def freeLibrary(self):
        self.log.append("unload")


class _Slave3:
    """An FMI 3.0 slave whose fmi3DoStep logs with the instanceEnvironments ``messages`` (None:
    the host's); ``instance``: what fmi3InstantiateCoSimulation returns."""

    messages: list = []
    instance = 1
    log: list = []

    def __init__(self, guid, unzipDirectory, modelIdentifier, instanceName):
        self.component = None

    def fmi3InstantiateCoSimulation(self, name, token, resources, visible, logging_on,
                                    event_mode_used, early_return_allowed, required, n_required,
                                    env, log_message, intermediate_update):
        # the check runs in batch, logging on, with no events or early returns handled
        assert (visible, logging_on, event_mode_used, early_return_allowed, n_required) == \
            (False, True, False, False, 0)
        self.env, self.log_message = env.value, log_message
        return self.instance

    def enterInitializationMode(self, startTime, stopTime):
        pass

    def exitInitializationMode(self):
        pass

    def doStep(self, currentCommunicationPoint, communicationStepSize):
        assert communicationStepSize == 0.0
        for env in self.messages:
            self.log_message(self.env if env is None else env, 0, b"c", b"m")

    def freeInstance(self):
        self.log.append("free")

    def freeLibrary(self):
        self.log.append("unload")


def _logger_ctx(fmi):
    md = SimpleNamespace(guid="{0}", instantiationToken="{0}",
                         coSimulation=SimpleNamespace(modelIdentifier="m"))
    fmu = SimpleNamespace(fmi_version=fmi, model_description=md,
                          model_description3=md if fmi == 3 else None, _unzipdir="/nowhere")
    return SimpleNamespace(fmu=fmu, start=0.0, stop=1.0, event=lambda **row: None)


@pytest.mark.parametrize("messages, want", [
    ([(None, None), (None, None)], ("", 2)),
    ([], ("", 0)),
    ([(None, None), (7, None), (8, None)],
     ("the logger got componentEnvironment 7, not the 0x5eed the host passed", 3)),
    ([(None, "someone"), (None, "other")],
     ("the logger got instance name 'someone', not 'dronefly binary check'", 2)),
    ([(9, "x")], ("the logger got componentEnvironment 9, not the 0x5eed the host passed; the "
                  "logger got instance name 'x', not 'dronefly binary check'", 1)),
])
def test_an_fmi2_logger_given_something_else_is_found(monkeypatch, messages, want):
    monkeypatch.setattr(_Slave2, "messages", messages)
    monkeypatch.setattr(_Slave2, "log", [])
    monkeypatch.setattr(binary, "FMU2Slave", _Slave2)
    assert binary.logger_passes_back(_logger_ctx(2)) == want
    assert _Slave2.log == ["free", "unload"]


@pytest.mark.parametrize("messages, want", [
    ([None, None, None], ("", 3)),
    ([None, 5, 6], ("the logger got instanceEnvironment 5, not the 0x5eed the host passed", 3)),
])
def test_an_fmi3_logger_given_something_else_is_found(monkeypatch, messages, want):
    monkeypatch.setattr(_Slave3, "messages", messages)
    monkeypatch.setattr(_Slave3, "log", [])
    monkeypatch.setattr(binary, "FMU3Slave", _Slave3)
    assert binary.logger_passes_back(_logger_ctx(3)) == want
    assert _Slave3.log == ["free", "unload"]


def test_an_fmi3_instance_that_is_null_fails(monkeypatch):
    monkeypatch.setattr(_Slave3, "instance", None)
    monkeypatch.setattr(binary, "FMU3Slave", _Slave3)
    with pytest.raises(CheckFailed, match="^fmi3InstantiateCoSimulation returned NULL$"):
        binary.logger_passes_back(_logger_ctx(3))


@pytest.mark.parametrize("fmi, attribute", [(2, "providesDirectionalDerivative"),
                                             (3, "providesDirectionalDerivatives")])
def test_a_declared_directional_derivative_must_be_exported(tmp_path, monkeypatch, fmi,
                                                            attribute):
    """FMI 2.0 2.1.1 / FMI 3.0 2.2.1: the capability flag of the interface element (FMI 2.0's
    providesDirectionalDerivative, FMI 3.0's providesDirectionalDerivatives) asks for
    fmi2GetDirectionalDerivative / fmi3GetDirectionalDerivative; read from the description as
    FMPy reads it."""
    xml = _xml(fmi, interfaces=f'<CoSimulation modelIdentifier="m" {attribute}="true"/>')
    (tmp_path / "modelDescription.xml").write_text(xml)
    folder = tmp_path / "binaries" / (platform if fmi == 2 else platform_tuple)
    folder.mkdir(parents=True)
    (folder / "m.so").write_bytes(b"")
    md = read_model_description(str(tmp_path / "modelDescription.xml"))
    fmu = SimpleNamespace(fmi_version=fmi, model_description=md,
                          model_description3=md if fmi == 3 else None, _unzipdir=str(tmp_path))
    ctx = SimpleNamespace(fmu=fmu, interfaces=("cs",), unusable=None, event=lambda **row: None)
    common, cs = (_FMI2_COMMON, _FMI2_CS) if fmi == 2 else (_FMI3_COMMON, _FMI3_CS)
    _fake_libraries(monkeypatch, {"m.so": common | cs})
    with pytest.raises(CheckFailed) as e:
        binary.check_binary(ctx)
    assert str(e.value) == f"not exported: fmi{fmi}GetDirectionalDerivative"
    _fake_libraries(monkeypatch, {"m.so": common | cs | {f"fmi{fmi}GetDirectionalDerivative"}})
    assert binary.check_binary(ctx).startswith(f"{len(common | cs) + 1} required functions")


@pytest.mark.parametrize("interfaces, want", [
    ('<CoSimulation modelIdentifier="m" providesDirectionalDerivatives="1"/>', (True, False)),
    ('<CoSimulation modelIdentifier="m" providesDirectionalDerivatives="false"/>'
     '<ModelExchange modelIdentifier="m" providesDirectionalDerivatives="true"/>', (False, True)),
    ('<ModelExchange modelIdentifier="m" providesDirectionalDerivatives="0"/>', (False, False)),
])
def test_fmi3_directional_derivatives_are_read_per_interface(tmp_path, interfaces, want):
    (tmp_path / "modelDescription.xml").write_text(_xml(3, interfaces=interfaces))
    ctx = SimpleNamespace(fmu=SimpleNamespace(fmi_version=3, _unzipdir=str(tmp_path)))
    assert (binary.declares_directional(ctx, "cs"), binary.declares_directional(ctx, "me")) \
        == want
    # FMI 2.0: FMPy's model description holds the flag
    ctx = SimpleNamespace(fmu=SimpleNamespace(fmi_version=2, _unzipdir=str(tmp_path)))
    assert binary.declares_directional(ctx, "cs") is None


# --- refusals.py: the calls an FMU must refuse or survive -------------------------------------

@pytest.fixture
def reference_context():
    """A checker's Context of a Reference-FMU (known-good FMUs), loaded in-process."""
    from dronefly.harness.compliance.driver import Context
    from dronefly.harness.compliance.rules import CheckOptions
    from dronefly.harness.cosim.fmu import FMU

    opened = []

    def make(fmi: int, name: str, profile: str | None = None, interface: str = "cs",
             path: Path | None = None, **options):
        source = REF / f"fmi{fmi}" / f"{name}.fmu"
        need_shared(source, "the Reference-FMUs")
        opened.append(FMU(path or source))
        ctx = Context(opened[-1], CheckOptions(profile=profile, **options), None)
        ctx.interface = interface
        return ctx

    yield make
    for fmu in opened:
        fmu.close()


@pytest.mark.parametrize("fmi", [2, 3])
def test_the_reference_fmus_refuse_bad_input_and_log_as_the_standard_asks(reference_context,
                                                                         fmi):
    """Feedthrough answers each illegal step fmiXError, logged, and fmiXReset recovers it
    (FMI 2.0 2.1.3, FMI 3.0 2.2.4): the standard profile's bad-input and logger-format pass;
    FMI 3.0's state-machine too."""
    ctx = reference_context(fmi, "Feedthrough")
    detail = refusals.check_bad_input(ctx)
    h = ctx.step
    assert detail == (f"communicationStepSize = 0.0: Error; communicationStepSize = {-h!r}: "
                      f"Error; currentCommunicationPoint = {10 * h!r} (the last was 0.0): "
                      f"Error; fmi{fmi}Reset recovered the instance")
    assert ctx.warnings == []
    assert refusals.check_logger_format(ctx).startswith("1 message(s) carry the ")
    if fmi == 3:
        assert refusals.check_state_machine(ctx).startswith(
            "fmi3DoStep before initialization and after fmi3Terminate: fmi3Error")
    else:
        for check in (refusals.check_state_machine, refusals.check_discard,
                      refusals.check_state_refusal):
            with pytest.raises(CheckSkipped, match="an FMI 3.0 check; this FMU is FMI 2.0"):
                check(ctx)
    assert ctx.warnings == []


class _FakeSlave:
    """An FMU's slave as the checks drive it (FMPy's FMU2Slave / the harness's FMI 3.0 adapter),
    in Python: a compliant FMU of the dronefly profile (FMI 2.0 3.x / 4.2 states; illegal
    arguments refused fmiXDiscard with a message naming the value, illegal calls fmiXError with
    a message naming the state) unless ``defects`` changes one answer:

    ``nan`` / ``h`` / ``t``: the status of a step with a NaN input, a step size <= 0, a
    communication point off the last one; ``state``: of a step outside Step Mode; ``set_output``:
    of a step after an output or the time was set; ``quiet``: log nothing; ``reset``: the status
    fmiXReset returns; ``unknown_vr``: what an unknown value reference reads; ``corrupt``: the
    status of setting a corrupt state (None: accepted silently); ``drift``: an output that
    changes after a refused state; ``steps_ok``: how many steps it makes before it refuses
    every one; ``sticky``: no step after an Error until a reset.
    The host's illegal calls (a step off the grid after an accepted one) land in ``illegal``."""

    def __init__(self, inst, fmi, names, **defects):
        self.inst, self.fmi, self.names, self.d = inst, fmi, names, defects
        self.state, self.t, self.start = "instantiated", None, 0.0
        self.values = {vr: 1.0 for vr in names}
        self.set_output, self.error = None, False
        self.steps: list = []
        self.illegal: list = []
        self.off_grid: list = []  # steps from another point than the last one reached
        self.drift = 0.0
        self.component = 1

    def _log(self, status, text):
        if not self.d.get("quiet"):
            self.inst.messages.append(SimpleNamespace(status=status, category="log",
                                                      message=text))

    def _answer(self, status, text):
        if status:
            self._log(status, text)
            self.error = status >= 3 and self.state == "step"
            raise FMICallException(f"fmi{self.fmi}DoStep", status)

    def setupExperiment(self, startTime, stopTime):
        self.start = startTime

    def enterInitializationMode(self):
        self.state = "initialization"

    def exitInitializationMode(self):
        self.state, self.t = "step", self.start
        if self.d.get("chatty"):
            self._log(0, "initialized")

    def terminate(self):
        self.state = "terminated"

    def reset(self):
        status = self.d.get("reset", 0)
        if status:
            raise FMICallException(f"fmi{self.fmi}Reset", status)
        self.state, self.set_output, self.error, self.t = "instantiated", None, False, None
        self.values = {vr: 1.0 for vr in self.names}

    def getReal(self, vrs):
        if self.d.get("nan_out"):  # the outputs read NaN
            return [math.nan if self.names[vr] not in self.d["inputs"] else self.values[vr]
                    for vr in vrs]
        return [self.values[vr] + self.drift for vr in vrs]

    def setReal(self, vrs, xs):
        self.values.update(zip(vrs, xs))

    def getFloat64(self, vrs):
        if any(vr not in self.values for vr in vrs):
            self._log(3, f"unknown valueReference {vrs}")
            return [self.d.get("unknown_vr", math.nan)]
        return self.getReal(vrs)

    def fmi3SetFloat64(self, component, vrs, n, xs, nx):
        # scalars: as many values as value references (FMI 3.0 2.2.6.2), read up to the counts
        if n != nx:
            raise FMICallException("fmi3SetFloat64", 3)
        for k in range(n):
            self.set_output = (self.names[vrs[k]], xs[k])

    def getBooleanStatus(self, kind):
        return False

    def getRealStatus(self, kind):
        return self.t

    def doStep(self, currentCommunicationPoint, communicationStepSize):
        t, h = currentCommunicationPoint, communicationStepSize
        self.steps.append((t, h))
        if self.t is not None and not math.isclose(t, self.t, rel_tol=1e-9):
            self.off_grid.append((t, h))
        if self.error:  # FMI 2.0 2.1.3, FMI 3.0 2.2.4: after Error, reset or free only
            self.illegal.append((t, h))
        if len(self.steps) > self.d.get("steps_ok", 10 ** 9) or \
                self.error and self.d.get("sticky"):
            self._answer(3, "cannot go on")
        if self.state != "step":
            self._answer(self.d.get("state", 3), f"fmi{self.fmi}DoStep: not allowed in state "
                                                 f"'{self.state}'")
            self.t = t  # accepted: a step from wherever it was asked
        for vr, x in self.values.items():
            if x != x:
                self._answer(self.d.get("nan", 2), self.d.get("long") or
                             f"{self.names[vr]} = nan")
        if self.set_output:
            (name, x), self.set_output = self.set_output, None
            self._answer(self.d.get("set_output", 3), f"{name} = {x!r} rejected")
        if h <= 0:
            self._answer(self.d.get("zero", self.d.get("h", 2)) if h == 0 else
                         self.d.get("h", 2), f"communicationStepSize = {h!r}")
        if not math.isclose(t, self.t, rel_tol=1e-9):  # FMI 2.0 4.2.2: where the last ended
            self._answer(self.d.get("t", 2), f"currentCommunicationPoint = {t!r}")
        if h == 0.0 and not self.d.get("h"):
            self.illegal.append((t, h))  # only reached by an FMU that accepts it
        self.t = t + h
        return (False, False, False, self.t) if self.fmi == 3 else None

    def getFMUstate(self):
        return "state"

    def serializeFMUstate(self, state):
        return b"\x01\x02\x03\x04"

    def deSerializeFMUstate(self, blob):
        return blob

    def setFMUstate(self, state):
        if state != b"\x01\x02\x03\x04":
            corrupt = self.d.get("corrupt", 3)
            if corrupt is None:
                self.drift = self.d.get("drift", 0.0)
                return
            self._log(corrupt, "the serialized state is corrupt: refused")
            self.drift = self.d.get("drift", 0.0)
            raise FMICallException("fmi3SetFMUState", corrupt)


class _FakeInstance:
    def __init__(self, fmi, names, defects):
        self.messages: list = []
        self.interface = "cs"
        self.slave = _FakeSlave(self, fmi, names, **defects)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        return None


def _fake_ctx(fmi=2, profile="dronefly", tool="dronefly-fmu 1.0", inputs=("u", "w"),
              outputs=("y",), n=10, locals_=0, **defects):
    """A Context (the attributes the checks read) of an FMU with Real ``inputs`` and
    ``outputs`` (value references 1, 2, ...), a time variable (value reference 0), a run of
    ``n`` steps of 0.1 s from 0; its instances are :class:`_FakeInstance` with ``defects``."""
    from dronefly.harness.compliance.driver import Var, reader

    names = {0: "time", **{k: n_ for k, n_ in enumerate((*inputs, *outputs), 1)}}
    var = [Var(n_, "Real", vr, None) for vr, n_ in names.items() if vr]
    names.update({len(names) + k: f"x{k}" for k in range(locals_)})  # locals (not in ctx)
    defects["inputs"] = inputs
    mv = [SimpleNamespace(valueReference=0, causality="independent"),
          *(SimpleNamespace(valueReference=v.vr, causality="input") for v in var)]
    md = SimpleNamespace(generationTool=tool, modelVariables=mv)
    ctx = SimpleNamespace(
        fmu=SimpleNamespace(fmi_version=fmi, model_description=md,
                            model_description3=md if fmi == 3 else None),
        profile=profile, ours=profile == "dronefly", fmi=f"fmi{fmi}", on_event=None,
        inputs=var[:len(inputs)], outputs=var[len(inputs):], start=0.0, step=0.1,
        stop=0.1 * n, n=n, warnings=[], instances=[], event=lambda **row: None,
        excited=var[:len(inputs)], input_start={v.vr: 1.0 for v in var[:len(inputs)]})
    ctx.read_outputs = reader(ctx.outputs)

    def instantiate(name):
        ctx.instances.append(_FakeInstance(fmi, names, defects))
        ctx.instances[-1].name = name
        return ctx.instances[-1]

    ctx.instantiate = instantiate
    return ctx


def _fails(check, ctx) -> str:
    with pytest.raises(CheckFailed) as e:
        check(ctx)
    return str(e.value)


@pytest.mark.parametrize("fmi", [2, 3])
def test_bad_input_of_the_dronefly_profile_wants_discard_or_error_naming_the_value(fmi):
    ctx = _fake_ctx(fmi)
    # two NaN inputs, two step sizes, a communication point ahead: all refused
    assert refusals.check_bad_input(ctx) == ("5 cases refused with a logged message naming "
                                             "the value; the instance recovered")
    assert [i.slave.illegal for i in ctx.instances] == [[]]
    ctx = _fake_ctx(fmi, nan=3, h=3, t=3)  # fmiXError is a refusal too
    assert refusals.check_bad_input(ctx).startswith("5 cases refused")
    # another tool's FMU: the statuses only
    ctx = _fake_ctx(fmi, tool="fmpy", quiet=True)
    assert refusals.check_bad_input(ctx) == ("5 cases refused (messages not checked: not our "
                                             "code); the instance recovered")
    ctx = _fake_ctx(fmi, tool=None, quiet=True)
    assert refusals.check_bad_input(ctx).startswith("5 cases refused (messages not checked")


@pytest.mark.parametrize("fmi, defects, problem", [
    (2, {"nan": 0}, "u = nan: fmi2DoStep returned fmi2OK"),
    (3, {"nan": 4}, "u = nan: fmi3DoStep returned fmi3Fatal"),
    (2, {"nan": 1}, "u = nan: fmi2DoStep returned fmi2Warning"),
    (2, {"quiet": True}, "u = nan: not named in the log (''"),
    (3, {"h": 0}, "communicationStepSize = 0.0: fmi3DoStep returned fmi3OK"),
    # two steps made (one after each input's case), then ten ahead: 0.2 + 1.0
    (2, {"t": 4}, f"currentCommunicationPoint = {0.1 + 0.1 + 10 * 0.1!r}: fmi2DoStep returned "
                  "fmi2Fatal"),
])
def test_bad_input_of_the_dronefly_profile_fails_an_accepted_or_fatal_case(fmi, defects,
                                                                           problem):
    assert _fails(refusals.check_bad_input, _fake_ctx(fmi, **defects)).startswith(problem)


def test_bad_input_names_the_input_refused(fmi=2):
    ctx = _fake_ctx(fmi, inputs=("u",))
    assert refusals.check_bad_input(ctx).startswith("4 cases refused")
    ctx = _fake_ctx(fmi, inputs=())
    assert refusals.check_bad_input(ctx).startswith("3 cases refused")


def test_bad_input_of_the_standard_profile_wants_no_fatal_and_a_reset_after_error():
    for fmi in (2, 3):
        ctx = _fake_ctx(fmi, "standard", h=3, t=3)
        assert refusals.check_bad_input(ctx) == (
            "communicationStepSize = 0.0: Error; communicationStepSize = -0.1: Error; "
            f"currentCommunicationPoint = {10 * 0.1!r} (the last was 0.0): Error; "
            f"fmi{fmi}Reset recovered the instance")
        assert ctx.warnings == [] and ctx.instances[0].slave.illegal == []
    # FMI 2.0: Discard is an answer; OK a warning (the step size 0 taken as a step)
    ctx = _fake_ctx(2, "standard", h=0, quiet=True)
    assert refusals.check_bad_input(ctx) == (
        "communicationStepSize = 0.0: OK; communicationStepSize = -0.1: OK; "
        f"currentCommunicationPoint = {10 * 0.1!r} (the last was 0.0): Discard; "
        "fmi2Reset recovered the instance")
    assert ctx.warnings == ["communicationStepSize = 0.0: fmi2DoStep returned fmi2OK",
                            "communicationStepSize = -0.1: fmi2DoStep returned fmi2OK"]


@pytest.mark.parametrize("fmi, defects, problem", [
    (2, {"h": 4}, "communicationStepSize = 0.0: fmi2DoStep returned fmi2Fatal"),
    (3, {"h": 3, "t": 4}, f"currentCommunicationPoint = {10 * 0.1!r} (the last was 0.0): "
                          "fmi3DoStep returned fmi3Fatal"),
    # FMI 3.0 2.2.4: an illegal argument is answered fmi3Error, with a message logged first
    (3, {"h": 2}, "communicationStepSize = 0.0: fmi3DoStep detected an illegal argument and "
                  "returned fmi3Discard; FMI 3.0 2.2.4 requires fmi3Error"),
    (3, {"h": 3, "quiet": True}, "communicationStepSize = 0.0: fmi3Error without a logged "
                                 "message (FMI 3.0 2.2.4: the FMU must call logMessage before "
                                 "returning fmi3Error, logging on)"),
    # after Error, fmiXReset is allowed (FMI 2.0 2.1.3, FMI 3.0 2.2.4) and must work
    (2, {"h": 3, "reset": 3}, "communicationStepSize = 0.0: fmi2DoStep returned fmi2Error, "
                              "then fmi2Reset, the call FMI 2.0 2.1.3 allows after it, "
                              "returned fmi2Error"),
    (3, {"h": 3, "reset": 4}, "communicationStepSize = 0.0: fmi3DoStep returned fmi3Error, "
                              "then fmi3Reset, the call FMI 3.0 2.2.4 allows after it, "
                              "returned fmi3Fatal"),
])
def test_bad_input_of_the_standard_profile_fails_fatal_discard_silence_or_no_reset(
        fmi, defects, problem):
    assert _fails(refusals.check_bad_input, _fake_ctx(fmi, "standard", **defects)) == problem


def test_bad_input_of_the_standard_profile_an_fmi2_error_needs_no_message():
    ctx = _fake_ctx(2, "standard", h=3, t=3, quiet=True)
    assert refusals.check_bad_input(ctx).endswith("fmi2Reset recovered the instance")


@pytest.mark.parametrize("n, steps", [
    # a few steps on the grid, then one of size 0 at the point reached
    (10, [(0.0, 0.1), (0.1, 0.1), (0.2, 0.1), (3 * 0.1, 0.0)]),
    (2, [(0.0, 0.1), (0.1, 0.1), (0.2, 0.0)]),
])
def test_logger_format_fmi2_logs_through_a_printf_style_instance_name(monkeypatch, n, steps):
    monkeypatch.setattr(refusals, "logger_passes_back", lambda ctx: ("", 2))
    ctx = _fake_ctx(2, n=n)
    assert refusals.check_logger_format(ctx) == (
        "2 message(s) carry the componentEnvironment and instance name the host passed; "
        "instance '%s%s%s%s%n', 1 messages logged through a printf-style logger, no crash")
    inst = ctx.instances[0]
    assert inst.name == "%s%s%s%s%n" and inst.slave.steps == steps
    assert inst.slave.illegal == [] and ctx.warnings == []


def test_logger_format_stops_stepping_at_a_refused_step(monkeypatch):
    monkeypatch.setattr(refusals, "logger_passes_back", lambda ctx: ("", 1))
    ctx = _fake_ctx(2, steps_ok=1)
    assert refusals.check_logger_format(ctx).endswith("1 messages logged through a "
                                                      "printf-style logger, no crash")
    assert ctx.instances[0].slave.steps == [(0.0, 0.1), (0.1, 0.1)]
    assert ctx.instances[0].slave.illegal == []


@pytest.mark.parametrize("fmi, passed", [(2, "componentEnvironment and instance name"),
                                         (3, "instanceEnvironment")])
def test_logger_format_fails_what_the_logger_got_and_notes_a_silent_fmu(monkeypatch, fmi,
                                                                        passed):
    monkeypatch.setattr(refusals, "logger_passes_back", lambda ctx: ("the logger got x", 3))
    assert _fails(refusals.check_logger_format, _fake_ctx(fmi)) == "the logger got x"
    monkeypatch.setattr(refusals, "logger_passes_back", lambda ctx: ("", 0))
    ctx = _fake_ctx(fmi)
    note = (f"the FMU logged nothing when a step of size 0 was refused: the {passed} its "
            "logger gets not checked")
    detail = refusals.check_logger_format(ctx)
    assert ctx.warnings == [note] and detail.startswith(note)
    if fmi == 3:
        assert detail == f"{note}; the message is plain text in FMI 3.0 (no printf format)"
        assert ctx.instances == []  # nothing to print through


def test_fmi3_state_machine_of_the_dronefly_profile():
    ctx = _fake_ctx(3)
    # before initialization, an unknown value reference, the output and the time set, after
    # fmi3Terminate, the run after fmi3Reset
    assert refusals.check_state_machine(ctx) == ("6 illegal calls answered fmi3Error with a "
                                                 "logged message, none Fatal; recovered by "
                                                 "fmi3Reset")
    steps = ctx.instances[0].slave.steps
    assert steps[-3:] == [(0.0, 0.1), (0.1, 0.1), (0.2, 0.1)]  # the run after the reset
    assert refusals.check_state_machine(_fake_ctx(3, outputs=())).startswith("5 illegal calls")


@pytest.mark.parametrize("defects, problem", [
    ({"state": 4}, "fmi3DoStep before initialization: fmi3Fatal"),
    ({"state": 2}, "fmi3DoStep before initialization: fmi3Discard, expected fmi3Error"),
    ({"quiet": True}, "fmi3DoStep before initialization: \"not allowed in state "
                      "'instantiated'\" not in the log (''"),
    ({"unknown_vr": 0.0}, "an unknown value reference is not answered NaN with a logged error"),
    ({"set_output": 0}, "a step after setting y: fmi3OK, expected fmi3Error"),
    ({"set_output": 4}, "a step after setting y: fmi3Fatal"),
])
def test_fmi3_state_machine_of_the_dronefly_profile_fails(defects, problem):
    assert _fails(refusals.check_state_machine, _fake_ctx(3, **defects)).startswith(problem)


def test_fmi3_state_machine_of_the_dronefly_profile_wants_the_time_refused_and_a_run_after():
    ctx = _fake_ctx(3, outputs=(), set_output=0)
    assert _fails(refusals.check_state_machine, ctx) == ("a step after setting time: fmi3OK, "
                                                         "expected fmi3Error")
    ctx = _fake_ctx(3, outputs=(), sticky=True)
    assert _fails(refusals.check_state_machine, ctx) == "no recovery after the refused step"
    ctx = _fake_ctx(3, steps_ok=6)  # refuses the second step after the reset
    assert _fails(refusals.check_state_machine, ctx) == "no run after fmi3Reset"


def test_fmi3_state_machine_of_the_standard_profile():
    ctx = _fake_ctx(3, "standard")
    assert refusals.check_state_machine(ctx).startswith("fmi3DoStep before initialization "
                                                        "and after fmi3Terminate: fmi3Error")
    assert ctx.instances[0].slave.steps[-3:] == [(0.0, 0.1), (0.1, 0.1), (0.2, 0.1)]
    for defects, problem in (
            ({"state": 0}, "fmi3DoStep before initialization: fmi3OK, expected fmi3Error"),
            ({"state": 4}, "fmi3DoStep before initialization: fmi3Fatal"),
            ({"quiet": True}, "fmi3DoStep before initialization: fmi3Error without a logged "
                              "message"),
            ({"steps_ok": 2}, "no run after fmi3Reset"),
            ({"steps_ok": 4}, "no run after fmi3Reset")):
        assert _fails(refusals.check_state_machine, _fake_ctx(3, "standard", **defects)) == \
            problem, defects


def test_fmi3_discard_of_a_nan_input():
    assert refusals.check_discard(_fake_ctx(3)) == "u = nan: fmi3Discard, then the step works"
    for defects, problem in (({"nan": 0}, "a NaN input: fmi3OK, expected fmi3Discard"),
                             ({"nan": 3}, "a NaN input: fmi3Error, expected fmi3Discard"),
                             ({"nan": 4}, "a NaN input: fmi3Fatal"),
                             ({"quiet": True}, "a NaN input: 'u = nan' not in the log"),
                             ({"steps_ok": 1}, "no step after the discarded one")):
        assert _fails(refusals.check_discard, _fake_ctx(3, **defects)).startswith(problem)
    with pytest.raises(CheckSkipped, match="^no Float64 inputs$"):
        refusals.check_discard(_fake_ctx(3, inputs=()))
    with pytest.raises(CheckSkipped, match="an FMI 3.0 check"):
        refusals.check_discard(_fake_ctx(2))


def test_fmi3_state_refusal_of_corrupt_bytes():
    ctx = _fake_ctx(3)
    assert refusals.check_state_refusal(ctx) == ("corrupt serialized state refused (logged), "
                                                 "the instance unchanged")
    assert [i.slave.steps for i in ctx.instances] == [[(0.0, 0.1), (0.1, 0.1)]] * 2
    for defects, problem in (({"corrupt": 4}, "fmi3SetFMUState of corrupt bytes: fmi3Fatal"),
                             ({"corrupt": None}, "corrupt state not refused in the log ('')"),
                             ({"drift": 1.0}, "the instance changed after a refused state"),
                             ({"steps_ok": 0}, "first step failed"),
                             ({"steps_ok": 1}, "the step after failed")):
        assert _fails(refusals.check_state_refusal, _fake_ctx(3, **defects)) == problem, defects
    with pytest.raises(CheckSkipped, match="an FMI 3.0 check"):
        refusals.check_state_refusal(_fake_ctx(2))


def test_bad_input_of_the_standard_profile_makes_the_calls_its_cases_name():
    """Each case is the call its text names (the report names what the FMU was asked): a step
    of size 0 and one of -h at the start, one from ten steps ahead; an FMU that takes a step of
    size 0 but refuses a negative one is warned of the first only."""
    ctx = _fake_ctx(2, "standard", zero=0, h=3, t=3)
    assert refusals.check_bad_input(ctx).startswith(
        "communicationStepSize = 0.0: OK; communicationStepSize = -0.1: Error; ")
    assert ctx.warnings == ["communicationStepSize = 0.0: fmi2DoStep returned fmi2OK"]
    assert ctx.instances[0].slave.steps == [(0.0, 0.0), (0.0, -0.1), (10 * 0.1, 0.1),
                                            (0.0, 0.1)]


def test_a_missing_fragment_quotes_the_first_200_characters_of_the_log():
    got = _fails(refusals.check_discard, _fake_ctx(3, long="x" * 300))
    assert got == f"a NaN input: 'u = nan' not in the log ({'x' * 200!r})"


def test_fmi3_state_machine_calls_are_illegal_only_as_they_mean_to_be():
    """The unknown value reference's message is the last one logged, whatever the FMU logged
    before (here at initialization); each output is set by its own value reference, one value
    for one reference; the step after fmi3Terminate continues from the point reached (only the
    state is wrong); a model with many variables has no variable at the probe's reference."""
    ctx = _fake_ctx(3, outputs=("y", "z"), chatty=True, locals_=100)
    assert refusals.check_state_machine(ctx).startswith("6 illegal calls")
    assert ctx.instances[0].slave.off_grid == []



# --- runtime.py: the runtime semantics, on the Reference-FMUs and on seeded defects ------------

def _seeded(tmp_path: Path, fmi: int, name: str, *edits: tuple[str, str],
            every: bool = False) -> Path:
    """A copy of a Reference-FMU whose modelDescription.xml has ``edits`` (old, new) made: a
    description that no longer tells the truth about the unchanged binary."""
    source = REF / f"fmi{fmi}" / f"{name}.fmu"
    need_shared(source, "the Reference-FMUs")
    return edited_copy(source, tmp_path / f"{name}{fmi}.fmu", edits, every=every)


_RUNTIME = ("check_call_sequence", "check_start_values", "check_dependencies", "check_reset",
            "check_two_instances", "check_state")


@pytest.mark.parametrize("fmi", [2, 3])
@pytest.mark.parametrize("interface", ["cs", "me"])
@pytest.mark.parametrize("name, stop, steps", [("Feedthrough", None, 100),
                                               ("Dahlquist", None, 100),
                                               ("Stair", 8.0, 40)])
def test_the_reference_fmus_pass_the_runtime_checks(reference_context, fmi, interface, name,
                                                    stop, steps):
    """The Reference-FMUs (Stair to 8 s, before it asks to terminate) pass every runtime check
    through either interface (docs/compliance.md, the validation table); their default
    experiments: Feedthrough 2 s in steps of 0.02 s, Dahlquist 10 s of 0.1 s, Stair 0.2 s."""
    ctx = reference_context(fmi, name, interface=interface, stop_time=stop)
    details = {}
    for check in _RUNTIME:
        try:
            details[check] = getattr(runtime, check)(ctx)
        except CheckSkipped as e:
            details[check] = f"skipped: {e}"
    assert details["check_call_sequence"] == (
        f"{steps} steps of {ctx.step:.6g} s to {ctx.start + steps * ctx.step:.6g} s")
    assert details["check_reset"] == f"identical after fmi{fmi}Reset"
    assert details["check_two_instances"] == "independent"
    half = steps // 2
    assert details["check_state"].startswith(
        f"bit-for-bit continuation from t = {half * ctx.step:.6g} s: get/set, serialized (")
    assert details["check_start_values"].endswith("hold their start values")
    if name == "Feedthrough":
        assert details["check_dependencies"].endswith(": no undeclared dependency")
    else:  # no inputs
        assert details["check_dependencies"].startswith("skipped: no inputs")
    assert ctx.warnings == []


@pytest.mark.parametrize("fmi", [2, 3])
def test_stairs_reset_keeps_its_terminate_request(reference_context, fmi):
    """Stair at its default experiment asks to terminate at 9 s, and its fmiXReset keeps the
    request: the run after the reset ends after one step (a defect of the FMU, FMI 2.0 2.1.6:
    after fmi2Reset the FMU is as after fmi2Instantiate), docs/compliance.md."""
    ctx = reference_context(fmi, "Stair")
    assert runtime.check_call_sequence(ctx) == (
        "45 steps of 0.2 s; the FMU ended the run at t = 9 s (before the stop time 10 s)")
    assert _fails(runtime.check_reset, ctx) == (
        f"the run after fmi{fmi}Reset differs from the first: the FMU ended it at t = 0.2 s, "
        "the first at t = 9 s")
    # through Model Exchange the request is recomputed: the runs agree
    ctx = reference_context(fmi, "Stair", interface="me")
    assert runtime.check_reset(ctx) == f"identical after fmi{fmi}Reset"


def test_a_stop_time_off_the_grid_is_said(reference_context):
    ctx = reference_context(2, "Dahlquist", stop_time=1.05)
    assert runtime.check_call_sequence(ctx) == (
        "10 steps of 0.1 s to 1 s (the stop time 1.05 s is not a whole number of steps)")


@pytest.mark.parametrize("fmi", [2, 3])
def test_a_declared_start_the_fmu_does_not_hold_fails_start_values(tmp_path, reference_context,
                                                                   fmi):
    # Dahlquist's k: declared 1 (parameter, fixed: initial exact), the binary holds 1
    old = '<Real start="1"/>' if fmi == 2 else 'start="1"'
    path = _seeded(tmp_path, fmi, "Dahlquist", (old, old.replace('"1"', '"1.5"')))
    ctx = reference_context(fmi, "Dahlquist", path=path)
    got = _fails(runtime.check_start_values, ctx)
    assert ": declared start 1.5, holds 1.0" in got, got


_OUT5 = '<Unknown index="5" dependencies="4" dependenciesKind="constant"/>'  # Feedthrough 2.0


@pytest.mark.parametrize("interface", ["cs", "me"])
@pytest.mark.parametrize("declared, what", [
    ('dependencies=""', "no dependency"),
    ('dependencies="6" dependenciesKind="constant"', "dependencies on Float64_discrete_input"),
])
@pytest.mark.parametrize("where", ["Outputs", "InitialUnknowns"])
def test_an_undeclared_dependency_fails_dependencies(tmp_path, reference_context, interface,
                                                     declared, what, where):
    """Feedthrough's continuous output is its continuous input (FMI 2.0 2.2.8: the Outputs
    and InitialUnknowns list the inputs an output depends on); declared otherwise in one list,
    the probe of that list finds the input."""
    new = _OUT5.replace('dependencies="4" dependenciesKind="constant"', declared)
    # the first Unknown of index 5 is in Outputs, the second in InitialUnknowns
    edits = [(_OUT5, new)] if where == "Outputs" else \
        [("<InitialUnknowns>\n      " + _OUT5, "<InitialUnknowns>\n      " + new)]
    ctx = reference_context(2, "Feedthrough", interface=interface,
                            path=_seeded(tmp_path, 2, "Feedthrough", *edits))
    got = _fails(runtime.check_dependencies, ctx)
    mode = ("in Initialization Mode" if where == "InitialUnknowns" else
            "in Step Mode (two continuations from one saved FMU state differ by O(1), not "
            "O(h), over a small step)" if interface == "cs" else
            "through Model Exchange (set, then get: continuous inputs in Continuous-Time Mode, "
            "discrete ones in Event Mode)")
    assert got == (f"Float64_continuous_output (declared in {where} with {what} among the "
                   f"inputs) changed when only Float64_continuous_input was set, {mode}")


def _var(kind="Real", type_=None, lo=None, hi=None, name="u"):
    from dronefly.harness.compliance.driver import Var

    return Var(name, kind, 1, SimpleNamespace(type=type_ or kind, min=lo, max=hi))


_EPS = sys.float_info.epsilon


@pytest.mark.parametrize("a, b, moved", [
    (1.0, 1.0, False), (math.nan, math.nan, False), (math.inf, math.inf, False),
    (1.0, math.nan, True), (math.nan, 1.0, True), (math.inf, 1.0, True), (1.0, -math.inf, True),
    # round-off: 4 ulp-sized epsilons of the larger magnitude
    (1.0, 1.0 + 4 * _EPS, False), (1.0, 1.0 + 5 * _EPS, True), (1.0, 1.0 + 8 * _EPS, True),
    (1.0 - 4 * _EPS, 1.0, False),  # exactly 4 epsilons of the larger: round-off still
    (-2.0, -2.0 - 8 * _EPS, False), (-2.0, -2.0 - 16 * _EPS, True),
    (1.0 + 8 * _EPS, 1.0, True), (0.0, 1e-300, True), (3.0, 4.0, True),
])
def test_moved_is_a_change_beyond_round_off(a, b, moved):
    assert runtime._moved(a, b) is moved


@pytest.mark.parametrize("var, x, want", [
    (_var("Boolean"), 1.0, 0.0), (_var("Boolean"), 0.0, 1.0),
    (_var("Integer", "Enumeration"), 1.0, None),  # no value known to be legal
    (_var("Integer"), 3.0, 4.0), (_var(), 3.0, 4.0),
    (_var(hi=3.0), 3.0, 2.0),  # at its max: down by one
    (_var(lo=3.0, hi=3.0), 3.0, None),  # no other value allowed
    (_var(hi=3.5), 3.0, 3.5),  # within the bounds
    (_var(lo=2.8, hi=3.0), 3.0, 2.8),
])
def test_perturbed_moves_an_input_by_a_unit_within_its_bounds(var, x, want):
    assert runtime._perturbed(var, x) == want


@pytest.mark.parametrize("var, x, want", [
    (_var(), 0.0, 1e-3), (_var(), 2000.0, 2002.0), (_var(), -2000.0, -1998.0),
    (_var(), 0.5, 0.501),  # at least 1e-3
    (_var(hi=0.5), 0.5, 0.499), (_var(lo=0.5, hi=0.5), 0.5, None),
    (_var("Boolean"), 0.0, 1.0), (_var("Integer"), 3.0, 4.0),
])
def test_nudged_moves_a_real_input_by_a_thousandth_of_its_size(var, x, want):
    got = runtime._nudged(var, x)
    assert got == (None if want is None else pytest.approx(want, rel=1e-12, abs=0))


def test_lies_are_the_inputs_seen_beyond_the_declared_ones():
    declared = {"w": None, "y": set(), "z": {"a"}, "v": {"a", "b"}}
    seen = {"y": {"b", "a"}, "z": {"a", "c"}, "w": {"a"}, "v": {"b"}}
    assert runtime._lies(declared, seen, "here", "Outputs") == [
        "y (declared in Outputs with no dependency among the inputs) changed when only a was "
        "set, here",
        "y (declared in Outputs with no dependency among the inputs) changed when only b was "
        "set, here",
        "z (declared in Outputs with dependencies on a among the inputs) changed when only c "
        "was set, here"]
    assert runtime._lies({"y": {"a"}}, {}, "here", "Outputs") == []


def _ref_ctx(path, ref=None, inputs=None):
    return SimpleNamespace(fmu=SimpleNamespace(path=path),
                           options=SimpleNamespace(ref=ref, inputs=inputs))


def test_reference_files_follow_the_cross_check_layout_or_the_options(tmp_path):
    fmu = tmp_path / "M.fmu"
    assert runtime.reference_files(_ref_ctx(fmu)) is None
    (tmp_path / "M_ref.csv").write_text("")
    assert runtime.reference_files(_ref_ctx(fmu)) == (tmp_path / "M_ref.csv", None, None)
    (tmp_path / "M_in.csv").write_text("")
    (tmp_path / "M_ref.opt").write_text("")
    assert runtime.reference_files(_ref_ctx(fmu)) == (
        tmp_path / "M_ref.csv", tmp_path / "M_in.csv", tmp_path / "M_ref.opt")
    # --ref: its own .opt beside it, no inputs unless --in
    (tmp_path / "other").mkdir()
    ref = tmp_path / "other" / "X_ref.csv"
    assert runtime.reference_files(_ref_ctx(fmu, str(ref))) == (ref, None, None)
    (tmp_path / "other" / "X_ref.opt").write_text("")
    assert runtime.reference_files(_ref_ctx(fmu, str(ref), "in.csv")) == (
        ref, Path("in.csv"), tmp_path / "other" / "X_ref.opt")
    plain = tmp_path / "other" / "X.csv"
    assert runtime.reference_files(_ref_ctx(fmu, str(plain))) == (plain, None, None)
    # --in alone, with the layout's reference
    assert runtime.reference_files(_ref_ctx(fmu, None, "in.csv")) == (
        tmp_path / "M_ref.csv", Path("in.csv"), tmp_path / "M_ref.opt")


class _Held:
    """An instance whose variables hold ``values`` (value reference -> value)."""

    def __init__(self, values):
        self.slave = SimpleNamespace(
            setupExperiment=lambda **kw: None, enterInitializationMode=lambda: None,
            exitInitializationMode=lambda: None,
            getReal=lambda vrs: [values[v] for v in vrs],
            getInteger=lambda vrs: [int(values[v]) for v in vrs],
            getBoolean=lambda vrs: [bool(values[v]) for v in vrs])
        self.messages = []

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        return None


def _start_ctx(variables, values, float32=()):
    """A Context of an FMU declaring ``variables`` (name, type, start, causality, variability,
    initial), value references 1, 2, ... in order, whose instance holds ``values``."""
    mv = [SimpleNamespace(name=n, type=t, start=st, causality=c, variability=var, initial=i,
                          valueReference=k)
          for k, (n, t, st, c, var, i) in enumerate(variables, 1)]
    md3 = (SimpleNamespace(modelVariables=[SimpleNamespace(valueReference=v.valueReference,
                                                           type="Float32") for v in mv
                                           if v.name in float32]) if float32 else None)
    held = dict(enumerate(values, 1))
    return SimpleNamespace(
        fmu=SimpleNamespace(model_description=SimpleNamespace(modelVariables=mv),
                            model_description3=md3, elements={}),
        fmi="fmi2", start=0.0, stop=1.0, event=lambda **row: None,
        instantiate=lambda name: _Held(held))


_PAR = ("parameter", "fixed", "exact")


@pytest.mark.parametrize("declared, held, f32, ok", [
    # the writer's rounding: 4 epsilons of a double relative to the start, 1e-6 of a Float32
    ("1.0", 1.0, False, True), ("0", 0.0, False, True),
    (repr(1.0 + 4 * _EPS), 1.0, False, True), (repr(1.0 + 5 * _EPS), 1.0, False, False),
    ("2.0", 2.0 + 8 * _EPS, False, True),  # at the tolerance itself
    ("2.0", 2.0 + 10 * _EPS, False, False), ("-2.0", -2.0 - 8 * _EPS, False, True),
    ("1024.0", 1024.0 * (1 + 4 * _EPS), False, True),
    ("0.1", 0.1 + 1e-8, False, False), ("0.1", 0.1 + 1e-8, True, True),
    ("0.1", 0.1 + 2e-7, True, False), ("1.5", 1.0, False, False), ("1.5", 1.0, True, False),
])
def test_start_values_are_held_up_to_the_writers_rounding(declared, held, f32, ok):
    ctx = _start_ctx([("p", "Real", declared, *_PAR)], [held], ["p"] if f32 else [])
    if ok:
        assert runtime.check_start_values(ctx) == ('1 variable(s) with initial="exact" hold '
                                                   'their start values')
    else:
        assert _fails(runtime.check_start_values, ctx) == (
            f"p: declared start {float(declared)!r}, holds {held!r}")


def test_start_values_are_those_of_initial_exact():
    """FMI 2.0 2.2.7: the start of a variable with initial="exact" (a constant's default) is
    the value it holds; approx and calculated ones, the independent variable, an Enumeration
    without a start and a variable without a start are not compared."""
    variables = [
        ("time", "Real", "5", "independent", "continuous", "exact"),  # illegal start: left out
        ("n", "Integer", None, "output", "discrete", "exact"),  # no start: left out
        ("e", "Enumeration", " ", "parameter", "fixed", "exact"),
        ("a", "Real", "7", "local", "continuous", "approx"),
        ("b", "Real", "7", "local", "continuous", None),
        ("c", "Real", "2", "local", "constant", None),  # constant: exact by default
        ("f", "Boolean", "true", "parameter", "fixed", "exact"),
        ("g", "Boolean", "1", "parameter", "fixed", "exact"),
        ("h", "Boolean", "false", "parameter", "fixed", "exact"),
        ("i", "Enumeration", "2", "parameter", "fixed", "exact"),
        ("s", "String", "x", "parameter", "fixed", "exact"),
    ]
    values = [0.0, 0, 9, 0.0, 0.0, 2.0, True, True, False, 2, 0.0]
    ctx = _start_ctx(variables, values)
    assert runtime.check_start_values(ctx) == ('5 variable(s) with initial="exact" hold their '
                                               'start values')
    for k, wrong, message in ((5, 3.0, "c: declared start 2.0, holds 3.0"),
                              (6, False, "f: declared start 1.0, holds 0.0"),
                              (8, True, "h: declared start 0.0, holds 1.0"),
                              (9, 3, "i: declared start 2.0, holds 3.0")):
        bad = list(values)
        bad[k] = wrong
        assert _fails(runtime.check_start_values, _start_ctx(variables, bad)) == message
    with pytest.raises(CheckSkipped, match='^no variable with initial="exact"$'):
        runtime.check_start_values(_start_ctx(variables[:5], values[:5]))


def test_the_derivatives_are_the_real_variables_modelstructure_lists():
    mv = [SimpleNamespace(name=n, type=t, valueReference=k) for k, (n, t) in enumerate(
        (("dx", "Real"), ("dv[1]", "Real"), ("dv[2]", "Real"), ("dx2", "Real"),
         ("dn", "Integer"), ("x", "Real")))]
    md = SimpleNamespace(derivatives=[SimpleNamespace(variable=SimpleNamespace(name=n))
                                      for n in ("dx", "dv", "dn")], modelVariables=mv)
    ctx = SimpleNamespace(fmu=SimpleNamespace(model_description=md, model_description3=None))
    assert [v.name for v in runtime._derivatives(ctx)] == ["dx", "dv[1]", "dv[2]"]
    md.derivatives = None
    assert runtime._derivatives(ctx) == []


class _Plant:
    """A slave of x' = u (Euler, exact for a held u), outputs y = x (through the state) and
    z = u (direct), inputs u0, u (value references 1, 2; y 3, z 4), its state saved and
    restored; steps shorter than ``refuse_below`` refused fmi2Error (FMI 2.0 4.2.2)."""

    def __init__(self, refuse_below=0.0):
        self.u = {1: 1.0, 2: 1.0}
        self.x, self.t, self.refuse_below, self.steps = 0.0, 0.0, refuse_below, []

    def setupExperiment(self, startTime, stopTime):
        self.t = startTime

    def enterInitializationMode(self):
        pass

    def exitInitializationMode(self):
        pass

    def setReal(self, vrs, xs):
        self.u.update(zip(vrs, xs))

    def getReal(self, vrs):
        return [self.u[v] if v in self.u else self.x if v == 3 else self.u[2] for v in vrs]

    def getInteger(self, vrs):
        return [int(x) for x in self.getReal(vrs)]

    def terminate(self):
        pass

    def doStep(self, currentCommunicationPoint, communicationStepSize):
        self.steps.append(communicationStepSize)
        if communicationStepSize < self.refuse_below:
            raise FMICallException("fmi2DoStep", 3)
        self.x += self.u[2] * communicationStepSize
        self.t = currentCommunicationPoint + communicationStepSize

    def getFMUstate(self):
        return (self.x, self.t, dict(self.u))

    def setFMUstate(self, state):
        self.x, self.t, u = state
        self.u = dict(u)

    def freeFMUstate(self, state):
        pass


def _plant_ctx(outputs_deps, initial_deps=None, refuse_below=0.0, can_probe=True,
               enumeration=False):
    """A Context of :class:`_Plant` declaring ``outputs_deps`` (output -> inputs) in
    ModelStructure Outputs and ``initial_deps`` in InitialUnknowns."""
    from dronefly.harness.compliance.driver import Var, reader

    inputs = [Var(n, "Real", vr, SimpleNamespace(type="Real", min=None, max=None,
                                                 variability="continuous"))
              for vr, n in ((1, "u0"), (2, "u"))]
    if enumeration:  # u0 an Enumeration: no other value known to be legal, never moved
        inputs[0] = Var("u0", "Integer", 1, SimpleNamespace(type="Enumeration", min=None,
                                                            max=None, variability="discrete"))
    outputs = [Var(n, "Real", vr, None) for vr, n in ((3, "y"), (4, "z"))]

    def unknowns(deps):
        return [SimpleNamespace(variable=SimpleNamespace(name=o),
                                dependencies=[SimpleNamespace(name=u) for u in d])
                for o, d in (deps or {}).items()]

    md = SimpleNamespace(outputs=unknowns(outputs_deps), initialUnknowns=unknowns(initial_deps),
                         coSimulation=SimpleNamespace(canGetAndSetFMUstate=can_probe))
    plants: list = []

    def instantiate(name):
        plants.append(_Plant(refuse_below))
        return SimpleNamespace(slave=plants[-1], messages=[], interface="cs")

    ctx = SimpleNamespace(
        fmu=SimpleNamespace(model_description=md, model_description3=None, fmi_version=2),
        interface="cs", inputs=inputs, outputs=outputs, excited=inputs,
        input_start={1: 1.0, 2: 1.0}, start=0.0, stop=1.0, step=0.1, n=10, fmi="fmi2",
        on_event=None, warnings=[], plants=plants, event=lambda **row: None,
        read_outputs=reader(outputs))
    ctx.instantiate = lambda name: _Entered(instantiate(name))
    return ctx


class _Entered:
    def __init__(self, inst):
        self.inst = inst

    def __enter__(self):
        return self.inst

    def __exit__(self, *exc):
        return None


_STEP_MODE = ("in Step Mode (two continuations from one saved FMU state differ by O(1), not "
              "O(h), over a small step)")


def test_the_step_mode_probe_tells_a_direct_dependency_from_one_through_a_state():
    """y follows u through the state (O(h) apart over a step h), z follows it directly (O(1)):
    FMI 2.0 2.2.8's Outputs dependencies are the direct ones, so y declared without u is true,
    z declared without u a lie. The probe steps are 1e-3 and 1e-4 of the run's step, each
    taken twice from the saved state; u0, declared by every output, is not probed."""
    ctx = _plant_ctx({"y": ["u0"], "z": ["u", "u0"]})
    assert runtime.check_dependencies(ctx) == ("2 output(s) with declared Outputs dependencies "
                                               "probed in Step Mode from a saved FMU state: no "
                                               "undeclared dependency")
    assert ctx.warnings == []
    h = ctx.step
    assert ctx.plants[0].steps == [h, 1e-3 * h, 1e-3 * h, 1e-4 * h, 1e-4 * h]
    ctx = _plant_ctx({"y": ["u0"], "z": ["u0"]})
    assert _fails(runtime.check_dependencies, ctx) == (
        "z (declared in Outputs with dependencies on u0 among the inputs) changed when only u "
        f"was set, {_STEP_MODE}")


def test_the_step_mode_probe_notes_the_inputs_whose_steps_were_refused():
    ctx = _plant_ctx({"y": [], "z": []}, refuse_below=0.05)
    assert runtime.check_dependencies(ctx).endswith("no undeclared dependency")
    assert ctx.warnings == ["not probed in Step Mode (a step refused): u0 (fmi2DoStep: "
                            "fmi2Error), u (fmi2DoStep: fmi2Error)"]


def test_dependencies_without_a_state_to_save_probe_the_initial_unknowns_only():
    ctx = _plant_ctx({"y": [], "z": []}, can_probe=False)
    with pytest.raises(CheckSkipped) as e:
        runtime.check_dependencies(ctx)
    assert str(e.value) == ("no output among the ModelStructure InitialUnknowns, and no "
                            "Outputs dependencies to probe in Step Mode (canGetAndSetFMUstate "
                            "is not declared)")
    ctx = _plant_ctx({})
    ctx.fmu.model_description.outputs = [SimpleNamespace(
        variable=SimpleNamespace(name=o), dependencies=None) for o in ("y", "z")]
    with pytest.raises(CheckSkipped) as e:
        runtime.check_dependencies(ctx)
    assert str(e.value) == ("no output among the ModelStructure InitialUnknowns, and no "
                            "Outputs dependencies to probe in Step Mode")
    ctx.inputs = []
    with pytest.raises(CheckSkipped, match="^no inputs or no outputs$"):
        runtime.check_dependencies(ctx)


_OUT7 = '<Unknown index="7" dependencies="6" dependenciesKind="constant"/>'  # discrete output
_INIT = "<InitialUnknowns>\n      "


def _feedthrough(tmp_path, reference_context, interface, *edits, every=False):
    return reference_context(2, "Feedthrough", interface=interface,
                             path=_seeded(tmp_path, 2, "Feedthrough", *edits, every=every))


@pytest.mark.parametrize("interface, outputs_part", [
    ("cs", "5 output(s) with declared Outputs dependencies probed in Step Mode from a saved FMU "
           "state"),
    ("me", "5 output(s) and 0 derivative(s) with declared dependencies, 4 input(s) set one at a "
           "time (continuous ones in Continuous-Time Mode, discrete ones in Event Mode)"),
])
def test_a_declared_dependency_not_seen_is_noted(tmp_path, reference_context, interface,
                                                 outputs_part):
    """Feedthrough's six outputs (five of a kind the checks read: not the String) declare
    their own input each; four inputs can be moved (not the Enumeration: no other value known
    to be legal). A dependency declared on an input that does not move the output is noted,
    not failed (it may be conditional)."""
    ctx = _feedthrough(tmp_path, reference_context, interface,
                       (_INIT + _OUT5, _INIT + _OUT5.replace('"4"', '"4 6"')))
    assert runtime.check_dependencies(ctx) == (
        "5 output(s) with declared initial dependencies, 4 input(s) set one at a time in "
        f"Initialization Mode; {outputs_part}: no undeclared dependency")
    assert ctx.warnings == ["declared dependencies not seen (a dependency may be conditional, "
                            "e.g. on a gain that is zero): Float64_continuous_output on "
                            "Float64_discrete_input"]


def test_a_discrete_inputs_undeclared_dependency_is_found_in_event_mode(tmp_path,
                                                                        reference_context):
    ctx = _feedthrough(tmp_path, reference_context, "me",
                       (_OUT7, _OUT7.replace('dependencies="6" dependenciesKind="constant"',
                                             'dependencies=""')))
    assert _fails(runtime.check_dependencies, ctx) == (
        "Float64_discrete_output (declared in Outputs with no dependency among the inputs) "
        "changed when only Float64_discrete_input was set, through Model Exchange (set, then "
        "get: continuous inputs in Continuous-Time Mode, discrete ones in Event Mode)")


@pytest.mark.parametrize("interface", ["cs", "me"])
def test_a_lie_in_initialunknowns_is_reported_before_the_outputs_are_probed(
        tmp_path, reference_context, interface):
    new = _OUT5.replace('dependencies="4" dependenciesKind="constant"', 'dependencies=""')
    ctx = _feedthrough(tmp_path, reference_context, interface, (_OUT5, new), every=True)
    assert _fails(runtime.check_dependencies, ctx) == (
        "Float64_continuous_output (declared in InitialUnknowns with no dependency among the "
        "inputs) changed when only Float64_continuous_input was set, in Initialization Mode")


@pytest.mark.parametrize("interface, why", [
    ("cs", "no output among the ModelStructure InitialUnknowns, and no Outputs dependencies to "
           "probe in Step Mode"),
    ("me", "no output among the ModelStructure InitialUnknowns, and no Outputs or Derivatives "
           "dependencies declared"),
])
def test_dependencies_with_nothing_declared_are_skipped(tmp_path, reference_context, interface,
                                                        why):
    import re

    need_shared(REF / "fmi2" / "Feedthrough.fmu", "the Reference-FMUs")
    text = zipfile.ZipFile(REF / "fmi2" / "Feedthrough.fmu").read(
        "modelDescription.xml").decode()
    bare = re.sub(r" dependencies=\"\d+\" dependenciesKind=\"constant\"", "",
                  re.sub(r"<InitialUnknowns>.*</InitialUnknowns>", "", text, flags=re.S))
    ctx = reference_context(2, "Feedthrough", interface=interface,
                            path=_seeded(tmp_path, 2, "Feedthrough", (text, bare)))
    with pytest.raises(CheckSkipped) as e:
        runtime.check_dependencies(ctx)
    assert str(e.value) == why


def test_outputs_dependencies_without_fmu_states_are_not_probed(tmp_path, reference_context):
    old = 'canHandleVariableCommunicationStepSize="true"\n    canNotUseMemoryManagementFunctions' \
          '="true"\n    canGetAndSetFMUstate="true"'
    ctx = _feedthrough(tmp_path, reference_context, "cs",
                       (old, old.replace('canGetAndSetFMUstate="true"',
                                         'canGetAndSetFMUstate="false"')))
    assert runtime.check_dependencies(ctx) == (
        "5 output(s) with declared initial dependencies, 4 input(s) set one at a time in "
        "Initialization Mode; Outputs dependencies not probed in Step Mode "
        "(canGetAndSetFMUstate is not declared): no undeclared dependency")


class _Proxy:
    """A slave with some of its functions replaced (a defect seeded into a known-good FMU)."""

    def __init__(self, slave, **replaced):
        self._slave = slave
        self.__dict__.update(replaced)

    def __getattr__(self, name):
        return getattr(self._slave, name)


def _seed(ctx, make):
    """``ctx`` whose instances' slaves are ``make(name, slave)``."""
    instantiate = ctx.instantiate

    def seeded(name):
        inst = instantiate(name)
        inst.slave = make(name, inst.slave)
        return inst

    ctx.instantiate = seeded
    return ctx


@pytest.mark.parametrize("fmi", [2, 3])
def test_two_instances_that_share_a_value_are_found(reference_context, fmi):
    """Dahlquist with a seeded defect: the instance named "right" (the second one alive) reads
    its output off by one, as an FMU whose instances share a global would."""
    def make(name, slave):
        if name != "right":
            return slave
        return _Proxy(slave, getReal=lambda vrs: [x + 1.0 for x in slave.getReal(vrs)])

    ctx = _seed(reference_context(fmi, "Dahlquist"), make)
    assert _fails(runtime.check_two_instances, ctx) == ("interleaved instances differ from a "
                                                        "single run")


def test_two_instances_of_an_fmu_instantiated_once_per_process_are_not_tried(
        tmp_path, reference_context):
    ctx = reference_context(2, "Dahlquist", path=_seeded(
        tmp_path, 2, "Dahlquist", ("<CoSimulation", '<CoSimulation '
                                   'canBeInstantiatedOnlyOncePerProcess="true"')))
    with pytest.raises(CheckSkipped, match="^canBeInstantiatedOnlyOncePerProcess is declared$"):
        runtime.check_two_instances(ctx)


def _restores_wrong(after: int):
    """A slave whose outputs read 1 off once fmiXSetFMUstate was called ``after`` times."""
    def make(name, slave):
        calls: list = []

        def set_state(state):
            calls.append(state)
            slave.setFMUstate(state)

        return _Proxy(slave, setFMUstate=set_state, getReal=lambda vrs: [
            x + (len(calls) >= after) for x in slave.getReal(vrs)])

    return make


@pytest.mark.parametrize("fmi", [2, 3])
def test_a_state_that_does_not_restore_fails_state(reference_context, fmi):
    v = f"fmi{fmi}"
    ctx = _seed(reference_context(fmi, "Dahlquist"), _restores_wrong(1))
    assert _fails(runtime.check_state, ctx) == f"continuation after {v}SetFMUstate differs"
    ctx = _seed(reference_context(fmi, "Dahlquist"), _restores_wrong(2))
    assert _fails(runtime.check_state, ctx) == \
        f"continuation after {v}DeSerializeFMUstate differs"


def test_state_checks_what_the_fmu_declares(tmp_path, reference_context):
    old = 'canGetAndSetFMUstate="true"\n    canSerializeFMUstate="true">\n    <SourceFiles>\n' \
          '      <File name="all.c"/>\n    </SourceFiles>\n  </CoSimulation>'
    ctx = reference_context(2, "Dahlquist", path=_seeded(
        tmp_path, 2, "Dahlquist", (old, old.replace('canSerializeFMUstate="true"',
                                                    'canSerializeFMUstate="false"'))))
    assert runtime.check_state(ctx) == "bit-for-bit continuation from t = 5 s: get/set"
    (tmp_path / "b").mkdir()
    ctx = reference_context(2, "Dahlquist", path=_seeded(
        tmp_path / "b", 2, "Dahlquist", (old, old.replace('="true"', '="false"'))))
    with pytest.raises(CheckSkipped, match="^canGetAndSetFMUstate is not declared$"):
        runtime.check_state(ctx)
    # Stair asks to terminate at 9 s: before the middle of a 20 s run
    ctx = reference_context(2, "Stair", stop_time=20.0)
    with pytest.raises(CheckSkipped, match="^the FMU ended the run before t = 10 s$"):
        runtime.check_state(ctx)


@pytest.mark.parametrize("fmi", [2, 3])
def test_call_sequence_non_finite_or_constant_outputs(reference_context, fmi):
    """Dahlquist's x decays from 1 (e^-t: 0.99995 of a unit over its 10 s), finite. Seeded: x
    read NaN, or constant; the dronefly profile fails both (its FMUs promise finite outputs
    that respond), the standard one notes the NaN only."""
    steps = "100 steps of 0.1 s to 10 s"
    assert runtime.check_call_sequence(reference_context(fmi, "Dahlquist", "dronefly")) == steps

    def nan(name, s):
        return _Proxy(s, getReal=lambda vrs: [math.nan] * len(vrs))

    def constant(name, s):
        return _Proxy(s, getReal=lambda vrs: [0.5] * len(vrs))

    ctx = _seed(reference_context(fmi, "Dahlquist", "dronefly"), nan)
    assert _fails(runtime.check_call_sequence, ctx) == "non-finite values returned with OK: x"
    ctx = _seed(reference_context(fmi, "Dahlquist", "standard"), nan)
    assert runtime.check_call_sequence(ctx) == steps
    assert ctx.warnings == ["non-finite values returned with OK: x"]
    ctx = _seed(reference_context(fmi, "Dahlquist", "dronefly"), constant)
    assert _fails(runtime.check_call_sequence, ctx) == "outputs do not respond to the inputs"
    ctx = _seed(reference_context(fmi, "Dahlquist", "standard"), constant)
    assert runtime.check_call_sequence(ctx) == steps and ctx.warnings == []


@pytest.mark.parametrize("fmi", [2, 3])
def test_a_reset_that_keeps_a_parameter_fails_reset(reference_context, fmi):
    """Dahlquist with a seeded defect: after fmiXReset its k is 2 (a value the reset kept),
    not the declared 1: the second run differs (FMI 2.0 2.1.6: after fmi2Reset the FMU is as
    after fmi2Instantiate)."""
    ctx = reference_context(fmi, "Dahlquist")
    k = ctx.fmu.variables["k"].valueReference

    def make(name, s):
        def reset():
            s.reset()
            s.setReal([k], [2.0])

        return _Proxy(s, reset=reset)

    assert _fails(runtime.check_reset, _seed(ctx, make)) == \
        f"the run after fmi{fmi}Reset differs from the first"


def _reference_csv(path: Path, times, scale=1.0, column="x") -> Path:
    path.write_text(f"time,{column}\n" + "".join(f"{t!r},{scale * math.exp(-t)!r}\n"
                                                  for t in times))
    return path


def test_the_reference_run_passes_fmpys_band_and_a_wrong_one_fails(tmp_path, reference_context):
    """Dahlquist's x is e^-t (its k = 1): a reference of e^-t passes FMPy's validation band,
    one of 2 e^-t fails it, one that names no variable of the FMU fails before the run."""
    times = [k / 10 for k in range(101)]
    ref = _reference_csv(tmp_path / "good.csv", times)
    ctx = reference_context(2, "Dahlquist", ref=str(ref))
    assert runtime.check_reference(ctx) == "1 output(s) within FMPy's validation band of good.csv"
    ref = _reference_csv(tmp_path / "bad.csv", times, 2.0)
    got = _fails(runtime.check_reference, reference_context(2, "Dahlquist", ref=str(ref)))
    assert "% of the samples outside FMPy's validation band of bad.csv (first outside: x at " \
           "t = " in got and not got.startswith("0.0%"), got
    ref = _reference_csv(tmp_path / "none.csv", times, column="y")
    assert _fails(runtime.check_reference, reference_context(2, "Dahlquist", ref=str(ref))) == \
        "none.csv: y name no variable of the FMU"


@pytest.mark.parametrize("times, opt, run", [
    # the run the reference was sampled on: its first and last time, its spacing
    ([0.5 + k / 10 for k in range(16)], None, (0.5, 2.0, 0.1)),
    ([0.25, 1.0], None, (0.25, 1.0, 0.75)),
    ([0.0, 1.0, 2.0], "StartTime, 0.5\nStopTime, 1.5\nStepSize, 0.25\nRelTol, 1e-4\n", (0.5, 1.5, 0.25)),
])
def test_the_reference_run_is_the_references_own(tmp_path, reference_context, monkeypatch,
                                                 times, opt, run):
    import shutil

    calls = []

    def simulate(path, **kw):
        calls.append(kw)
        import fmpy as real

        return real.read_csv(str(ref))

    fmu = tmp_path / "Dahlquist.fmu"
    need_shared(REF / "fmi2" / "Dahlquist.fmu", "the Reference-FMUs")
    shutil.copy(REF / "fmi2" / "Dahlquist.fmu", fmu)
    ref = _reference_csv(tmp_path / "Dahlquist_ref.csv", times)
    (tmp_path / "Dahlquist_in.csv").write_text("time,k\n0,1\n")
    if opt:
        (tmp_path / "Dahlquist_ref.opt").write_text(opt)
    monkeypatch.setattr(runtime.fmpy, "simulate_fmu", simulate)
    ctx = reference_context(2, "Dahlquist", path=fmu)
    assert runtime.check_reference(ctx) == ("1 output(s) within FMPy's validation band of "
                                            "Dahlquist_ref.csv with Dahlquist_in.csv")
    (kw,) = calls
    assert (kw["start_time"], kw["stop_time"]) == run[:2]
    assert kw["output_interval"] == pytest.approx(run[2], rel=1e-12)
    assert kw["output"] == ["x"] and kw["fmi_type"] == "CoSimulation"
    assert kw["input"] is not None and list(kw["input"].dtype.names) == ["time", "k"]


def test_check_reference_without_a_reference_result(tmp_path, reference_context, monkeypatch):
    from dronefly.harness.compliance.reference import REFERENCES

    with pytest.raises(CheckSkipped, match=r"^no reference result \(--ref FILE.csv, or "
                                           r"<Model>_ref.csv beside the FMU\)$"):
        runtime.check_reference(reference_context(2, "Dahlquist"))
    with pytest.raises(CheckSkipped, match="^no reference result for this model$"):
        runtime.check_reference(reference_context(2, "Dahlquist", "dronefly"))
    # the project's models: the cross-check of reference.py
    name = next(iter(REFERENCES))
    ctx = SimpleNamespace(fmu=SimpleNamespace(name=name, path=tmp_path / f"{name}.fmu"),
                          options=SimpleNamespace(ref=None, inputs=None), ours=True)
    got = []

    def cross_check(model, path, passed=True):
        got.append((model, path))
        return SimpleNamespace(passed=passed, cross_check_outliers=0.02, max_rel_error=0.3)

    monkeypatch.setattr(runtime, "cross_check", cross_check)
    assert runtime.check_reference(ctx) == "cross-check: no outliers, max relative error 3.0e-01"
    assert got == [(name, ctx.fmu.path)]
    monkeypatch.setattr(runtime, "cross_check", lambda m, p: cross_check(m, p, False))
    assert _fails(runtime.check_reference, ctx) == "2.0% outliers, max relative error 3.00e-01"


def test_an_input_that_cannot_be_moved_does_not_end_the_initialization_probe():
    ctx = _plant_ctx({}, {"y": [], "z": []}, enumeration=True)
    assert _fails(runtime.check_dependencies, ctx) == (
        "z (declared in InitialUnknowns with no dependency among the inputs) changed when only "
        "u was set, in Initialization Mode")


def _outputs_without_dependencies(text: str) -> str:
    import re

    head, rest = text.split("<Outputs>", 1)
    block, tail = rest.split("</Outputs>", 1)
    return head + "<Outputs>" + re.sub(r' dependencies="[\d ]*" dependenciesKind="constant"',
                                       "", block) + "</Outputs>" + tail


_FEED2 = REF / "fmi2" / "Feedthrough.fmu"


def _feed2_text() -> str:
    need_shared(_FEED2, "the Reference-FMUs")
    return zipfile.ZipFile(_FEED2).read("modelDescription.xml").decode()


@pytest.mark.parametrize("interface", ["cs", "me"])
def test_dependencies_with_initialunknowns_only_probe_them(tmp_path, reference_context,
                                                           interface):
    """Outputs without dependencies attributes (they depend on every known: nothing to
    probe there), InitialUnknowns with them: Initialization Mode is probed alone; where
    FMU states are not declared either, nothing is said of the Step Mode probe."""
    text = _feed2_text()
    new = _outputs_without_dependencies(text)
    if interface == "cs":
        new = new.replace('canGetAndSetFMUstate="true"\n    canSerializeFMUstate="true">\n'
                          '    <SourceFiles>\n      <File name="all.c"/>\n    </SourceFiles>\n'
                          '  </CoSimulation>',
                          'canGetAndSetFMUstate="false"\n    canSerializeFMUstate="false">\n'
                          '    <SourceFiles>\n      <File name="all.c"/>\n    </SourceFiles>\n'
                          '  </CoSimulation>')
        assert 'canGetAndSetFMUstate="false"' in new
    ctx = reference_context(2, "Feedthrough", interface=interface,
                            path=_seeded(tmp_path, 2, "Feedthrough", (text, new)))
    assert runtime.check_dependencies(ctx) == (
        "5 output(s) with declared initial dependencies, 4 input(s) set one at a time in "
        "Initialization Mode: no undeclared dependency")


@pytest.mark.parametrize("interface", ["cs", "me"])
@pytest.mark.parametrize("fmi, count, more", [(2, 0, False), (3, 5, True), (3, 0, True)])
def test_a_dependencies_failure_lists_four_lies_then_says_there_are_more(
        tmp_path, reference_context, interface, fmi, count, more):
    """InitialUnknowns declared without dependencies (all of them, or the first ``count``):
    FMI 2.0's Feedthrough has four outputs that follow an input that can be moved (four lies),
    FMI 3.0's first five are its Float32, Float64 and Int8 ones (five lies), all twelve."""
    import re

    source = REF / f"fmi{fmi}" / "Feedthrough.fmu"
    need_shared(source, "the Reference-FMUs")
    text = zipfile.ZipFile(source).read("modelDescription.xml").decode()
    head, rest = text.split("<InitialUnknown", 1)
    new = head + "<InitialUnknown" + re.sub(r'dependencies="[\d ]*"', 'dependencies=""', rest,
                                            count=count)
    ctx = reference_context(fmi, "Feedthrough", interface=interface,
                            path=_seeded(tmp_path, fmi, "Feedthrough", (text, new)))
    got = _fails(runtime.check_dependencies, ctx)
    assert got.count("changed when only") == 4 and got.endswith(" ...") is more, got


@pytest.mark.parametrize("pairs, more", [(6, False), (7, True)])
def test_the_note_of_unseen_dependencies_lists_six_then_says_there_are_more(
        tmp_path, reference_context, pairs, more):
    # FMI 2.0 Feedthrough's indices: 4, 6, 8, 10 the inputs that can be moved; 5, 7, 9 their
    # outputs. Each extra input declared in InitialUnknowns is one dependency not seen
    text = _feed2_text()
    head, tail = text.split("<InitialUnknowns>", 1)
    for out, own, deps in ((5, "4", "4 6 8 10"), (7, "6", "4 6 8" if pairs == 6 else "4 6 8 10"),
                           (9, "8", "4 8")):
        kinds = " ".join(["constant"] * len(deps.split()))
        tail = tail.replace(f'<Unknown index="{out}" dependencies="{own}" '
                            'dependenciesKind="constant"/>',
                            f'<Unknown index="{out}" dependencies="{deps}" '
                            f'dependenciesKind="{kinds}"/>')
    ctx = _feedthrough(tmp_path, reference_context, "cs",
                       (text, head + "<InitialUnknowns>" + tail))
    runtime.check_dependencies(ctx)
    (note,) = ctx.warnings
    listed = note.split("zero): ", 1)[1].removesuffix(" ...").split(", ")
    assert len(listed) == 6 and note.endswith(" ...") is more, note


def test_a_run_that_ends_at_time_zero_ends_at_its_stop_time(tmp_path, reference_context):
    ctx = reference_context(2, "Dahlquist", path=_seeded(
        tmp_path, 2, "Dahlquist", ('startTime="0" stopTime="10"', 'startTime="-1" stopTime="0"')))
    assert runtime.check_call_sequence(ctx) == "10 steps of 0.1 s to 0 s"


def test_a_start_values_failure_lists_five_then_says_there_are_more():
    for n, more in ((5, False), (6, True), (7, True)):
        ctx = _start_ctx([(f"p{k}", "Real", "1.0", *_PAR) for k in range(n)], [2.0] * n)
        got = _fails(runtime.check_start_values, ctx)
        assert got.count("declared start") == 5 and got.endswith(" ...") is more, got


def test_reference_columns_that_name_no_variable_are_listed_four_at_most(tmp_path,
                                                                         reference_context):
    ref = tmp_path / "cols.csv"
    ref.write_text("time,a,b,c,d,e\n0,1,1,1,1,1\n1,1,1,1,1,1\n")
    assert _fails(runtime.check_reference, reference_context(2, "Dahlquist", ref=str(ref))) == \
        "cols.csv: a, b, c, d name no variable of the FMU"


def test_a_reference_of_one_sample_is_a_run_of_no_length(tmp_path, reference_context,
                                                          monkeypatch):
    ref = _reference_csv(tmp_path / "one.csv", [0.5])
    calls = []

    def simulate(path, **kw):
        calls.append(kw)
        import fmpy as real

        return real.read_csv(str(ref))

    monkeypatch.setattr(runtime.fmpy, "simulate_fmu", simulate)
    got = _fails(runtime.check_reference, reference_context(2, "Dahlquist", ref=str(ref)))
    assert got.startswith("100.0% of the samples outside"), got
    assert (calls[0]["start_time"], calls[0]["stop_time"], calls[0]["output_interval"]) == \
        (0.5, 0.5, 0.0)


# --- reference.py: the reference results of the project's FMUs (FMI cross-check layout) -------

def _committed(model):
    import fmpy

    inp, opt, ref = reference.reference_paths(model)
    return (fmpy.read_csv(str(inp)) if inp.exists() else None,
            fmpy.util.read_ref_opt_file(str(opt)), ref)


@pytest.mark.parametrize("model", sorted(reference.REFERENCES))
def test_the_inputs_and_settings_are_those_of_the_committed_references(model):
    """The committed <Model>_in.csv and _ref.opt (the cross-check files the references were
    recorded with) are what the module's inputs and settings give: the doublets and pulses of
    its docstrings, N_HZ wing beats a second, 30 wing beats of 0.1 unless set otherwise."""
    import numpy as np

    inputs, opt, ref = _committed(model)
    setup = reference.REFERENCES[model]
    assert reference._opt(setup) == pytest.approx(opt, rel=1e-12, abs=1e-15)
    assert set(opt) == {"StartTime", "StopTime", "StepSize", "RelTol"}
    table = reference._input_table(model)
    if inputs is None:
        assert table.dtype.names == ("time",) and model == "DroneFlyClosedLoop"
    else:
        assert table.dtype.names == inputs.dtype.names
        for name in inputs.dtype.names:
            assert np.array_equal(np.asarray(table[name], float),
                                  np.asarray(inputs[name], float)), (model, name)
    assert reference.reference_paths(model)[2] == ref == \
        reference._PACKAGE_ROOT / setup.folder / f"{model}_ref.csv"


def test_the_lateral_plants_doublet_is_as_documented():
    """+0.01 rad of delta_Phi_a for 5 wing beats, -0.01 for 5, then 0; a pulse of 0.005 on
    delta_alpha_2a from the 15th wing beat to the 17th (the module's docstring)."""
    import numpy as np

    from dronefly.models.lateral_interface import N_HZ

    wb = np.array([0.0, 4.9, 5.0, 9.9, 10.0, 14.9, 15.0, 16.9, 17.0, 30.0])
    got = reference._plant_inputs(wb / N_HZ)
    assert list(got["delta_Phi_a"]) == [0.01, 0.01, -0.01, -0.01, 0, 0, 0, 0, 0, 0]
    assert list(got["delta_alpha_2a"]) == [0, 0, 0, 0, 0, 0, 0.005, 0.005, 0, 0]
    assert not got["delta_alpha_1a"].any()


def test_reference_outputs_of_a_model_without_a_list_are_the_fmus(monkeypatch):
    """DroneFlyFlapping records every output of its FMU, in the description's order; the
    others their listed ones."""
    fmu = REF / "fmi2" / "Feedthrough.fmu"
    need_shared(fmu, "the Reference-FMUs")
    assert reference.reference_outputs("DroneFlyFlapping", fmu) == [
        "Float64_continuous_output", "Float64_discrete_output", "Int32_output",
        "Boolean_output", "String_output", "Enumeration_output"]
    assert reference.reference_outputs("DroneFlyLateral", fmu) == \
        list(reference.REFERENCES["DroneFlyLateral"].outputs)


def _stub_simulation(monkeypatch, result_of):
    calls = []

    def simulate(path, **kw):
        calls.append((path, kw))
        return result_of(kw)

    monkeypatch.setattr(reference.fmpy, "simulate_fmu", simulate)
    return calls


@pytest.mark.parametrize("model", ["DroneFlyLateral", "DroneFlyClosedLoop"])
def test_check_reference_passes_the_recorded_run_and_fails_another(tmp_path, monkeypatch,
                                                                   model):
    import fmpy
    import numpy as np

    inputs, opt, ref = _committed(model)
    recorded = fmpy.read_csv(str(ref))
    calls = _stub_simulation(monkeypatch, lambda kw: recorded)
    got = reference.check_reference(model, tmp_path / "m.fmu")
    assert got.passed and got.cross_check_outliers == 0.0 and got.max_rel_error == 0.0
    (path, kw), = calls
    assert path == str(tmp_path / "m.fmu")
    assert (kw["start_time"], kw["stop_time"], kw["output_interval"]) == pytest.approx(
        (opt["StartTime"], opt["StopTime"], opt["StepSize"]), rel=1e-12)
    assert kw["output"] == reference.reference_outputs(model, tmp_path / "m.fmu")
    if inputs is None:
        assert kw["input"] is None
    else:
        assert list(kw["input"].dtype.names) == list(inputs.dtype.names)
    # a result 1e-6 of its largest value off in one output: beyond the tight tolerance (1e-9)
    off = recorded.copy()
    name = off.dtype.names[1]
    scale = float(np.max(np.abs(off[name])))
    off[name] = off[name] + 1e-6 * scale
    monkeypatch.setattr(reference.fmpy, "simulate_fmu", lambda path, **kw: off)
    got = reference.check_reference(model, tmp_path / "m.fmu")
    assert not got.passed and got.max_rel_error == pytest.approx(1e-6, rel=1e-6)
    assert got.model == model


def test_check_reference_refuses_settings_other_than_the_models(tmp_path, monkeypatch):
    import shutil

    model = "DroneFlyLateral"
    for p in reference.reference_paths(model):
        shutil.copy(p, tmp_path / p.name)
    opt = tmp_path / f"{model}_ref.opt"
    text = opt.read_text()
    stop = reference._opt(reference.REFERENCES[model])["StopTime"]
    opt.write_text(text.replace(f"StopTime,{stop!r}", f"StopTime,{2 * stop!r}"))
    with pytest.raises(ValueError, match=f"^{model}_ref.opt: StopTime = "):
        reference.check_reference(model, tmp_path / "m.fmu", tmp_path)


def test_passed_is_no_outliers_and_a_tight_error():
    check = reference.ReferenceCheck
    assert check("m", 0.0, 1e-9).passed and check("m", 0.0, 0.0).passed
    assert not check("m", 0.0, 1.1e-9).passed and not check("m", 0.01, 0.0).passed


def test_write_reference_writes_the_cross_check_files(tmp_path, monkeypatch):
    import fmpy

    models = ("DroneFlyLateral", "DroneFlyClosedLoop", "StateFeedback")
    committed = {m: fmpy.read_csv(str(_committed(m)[2])) for m in models}
    for model in models:
        paths = tuple(tmp_path / f"{model}{s}" for s in ("_in.csv", "_ref.opt", "_ref.csv"))
        monkeypatch.setattr(reference, "reference_paths", lambda m, p=paths: p)
        recorded = committed[model]
        _stub_simulation(monkeypatch, lambda kw: recorded)
        assert reference.write_reference(model, tmp_path / "m.fmu") == paths
        inputs, opt, ref = paths
        assert inputs.exists() is (model != "DroneFlyClosedLoop")
        assert fmpy.util.read_ref_opt_file(str(opt)) == reference._opt(
            reference.REFERENCES[model])
        again = fmpy.read_csv(str(ref))
        assert again.dtype.names == recorded.dtype.names
        for name in recorded.dtype.names:
            assert list(again[name]) == list(recorded[name]), (model, name)


def test_the_reference_setups_and_results_are_values():
    with pytest.raises(dataclasses.FrozenInstanceError):
        reference.REFERENCES["DroneFlyLateral"].rel_tol = 1.0  # type: ignore[misc]
    with pytest.raises(dataclasses.FrozenInstanceError):
        reference.ReferenceCheck("m", 0.0, 0.0).max_rel_error = 1.0  # type: ignore[misc]


def test_a_model_with_one_input_has_an_input_file(tmp_path, monkeypatch):
    """A model of one input (a table of time and one column) is simulated with it and gets an
    _in.csv; the cross-check files quote the column names (FMI cross-check rules)."""
    setup = reference._Setup("x", lambda t: {"u": 0.5 * t}, ("y",), stop_wingbeats=1.0)
    monkeypatch.setitem(reference.REFERENCES, "OneInput", setup)
    paths = tuple(tmp_path / f"OneInput{s}" for s in ("_in.csv", "_ref.opt", "_ref.csv"))
    monkeypatch.setattr(reference, "reference_paths", lambda m: paths)

    def simulate(path, **kw):
        calls.append(kw)
        result = kw["input"][["time"]].copy()
        return result

    calls: list = []
    monkeypatch.setattr(reference.fmpy, "simulate_fmu", simulate)
    reference.write_reference("OneInput", tmp_path / "m.fmu")
    assert list(calls[0]["input"].dtype.names) == ["time", "u"]
    assert paths[0].read_text().splitlines()[0] == '"time","u"'
    assert paths[2].read_text().splitlines()[0] == '"time"'


def test_the_reference_error_is_that_of_the_outputs_not_of_the_time(tmp_path, monkeypatch):
    """max_rel_error: max |y - y_ref| / max |y_ref| over the outputs (ReferenceCheck); a
    result whose time column is read a little off, its outputs the recorded ones, has none."""
    import fmpy

    model = "DroneFlyLateral"
    recorded = fmpy.read_csv(str(_committed(model)[2]))
    shifted = recorded.copy()
    shifted["time"] = shifted["time"] * (1 + 1e-7)
    _stub_simulation(monkeypatch, lambda kw: shifted)
    assert reference.check_reference(model, tmp_path / "m.fmu").max_rel_error == 0.0



def test_call_sequence_names_five_non_finite_outputs_then_says_there_are_more():
    outputs = tuple(f"y{k}" for k in range(7))
    got = _fails(runtime.check_call_sequence, _fake_ctx(2, outputs=outputs, nan_out=True))
    assert got == "non-finite values returned with OK: y0, y1, y2, y3, y4"
    got = _fails(runtime.check_call_sequence, _fake_ctx(2, outputs=outputs[:5], nan_out=True))
    assert got == "non-finite values returned with OK: y0, y1, y2, y3, y4"


def test_a_reference_failure_names_the_first_three_signals_outside(tmp_path, reference_context,
                                                                   monkeypatch):
    import fmpy as real

    names = ("Float64_continuous_input", "Float64_continuous_output", "Float64_discrete_input",
             "Float64_discrete_output")
    ref = tmp_path / "four.csv"
    ref.write_text("time," + ",".join(names) + "\n" + "".join(
        f"{k / 10!r}," + ",".join([repr(k / 10)] * 4) + "\n" for k in range(21)))
    off = tmp_path / "off.csv"
    off.write_text("time," + ",".join(names) + "\n" + "".join(
        f"{k / 10!r}," + ",".join([repr(k / 10 + 10.0)] * 4) + "\n" for k in range(21)))
    monkeypatch.setattr(runtime.fmpy, "simulate_fmu", lambda path, **kw: real.read_csv(str(off)))
    got = _fails(runtime.check_reference, reference_context(2, "Feedthrough", ref=str(ref)))
    first = got.split("(first outside: ", 1)[1].rstrip(")").split("; ")
    assert [f.split(" at t = ")[0] for f in first] == list(names[:3]), got


# --- exchange.py: the Model Exchange interface -------------------------------------------------

def _real_outputs(source: Path, fmi: int) -> list[str]:
    """The names of the Real (FMI 3.0: Float32/Float64) outputs, read from the archive's XML
    by hand."""
    import xml.etree.ElementTree as ET

    with zipfile.ZipFile(source) as z:
        root = ET.fromstring(z.read("modelDescription.xml"))
    if fmi == 2:
        return [v.get("name") for v in root.iter("ScalarVariable")
                if v.get("causality") == "output" and v.find("Real") is not None]
    # an FMI 3.0 <Alias> is the same variable under another name; FMPy records it as one more
    return [n.get("name") for v in root.find("ModelVariables")
            if v.get("causality") == "output" and v.tag in ("Float32", "Float64")
            for n in (v, *v.findall("Alias"))]


def _initial_event_iterations(source: Path, fmi: int, tmp_path: Path) -> int:
    """fmi2NewDiscreteStates / fmi3UpdateDiscreteStates after initialization, called through
    FMPy's low-level API until the FMU needs no other iteration: the count the check reports."""
    import fmpy
    from fmpy.fmi2 import FMU2Model
    from fmpy.fmi3 import FMU3Model

    md = read_model_description(str(source))
    folder = fmpy.extract(str(source), str(tmp_path / f"iter{fmi}"))
    if fmi == 2:
        m = FMU2Model(guid=md.guid, unzipDirectory=folder, instanceName="count",
                      modelIdentifier=md.modelExchange.modelIdentifier)
        m.instantiate()
        m.setupExperiment(startTime=0.0)
        m.enterInitializationMode()
        m.exitInitializationMode()
    else:
        m = FMU3Model(guid=md.guid, unzipDirectory=folder, instanceName="count",
                      modelIdentifier=md.modelExchange.modelIdentifier)
        m.instantiate()
        m.enterInitializationMode(startTime=0.0)
        m.exitInitializationMode()
    for k in range(1, 100):
        result = m.newDiscreteStates() if fmi == 2 else m.updateDiscreteStates()
        needed, terminate = result[0], result[1]
        if not needed or terminate:
            break
    m.terminate()
    m.freeInstance()
    return k


@pytest.mark.parametrize("fmi", [2, 3])
@pytest.mark.parametrize("name, stop, end, rows", [
    # Dahlquist to 20 s in steps of 0.1 s: a row each (20 - 0) / 100 = 0.2 s, t = 0 included
    ("Dahlquist", 20.0, "20", 101),
    # Stair counts the seconds and asks to terminate at 9 s, before its stop time 10 s
    ("Stair", None, "9", None),
    ("BouncingBall", None, "3", None),  # its default experiment, rows at its bounces too
])
def test_model_exchange_of_the_reference_fmus(reference_context, tmp_path, fmi, name, stop, end,
                                              rows):
    """The Reference-FMUs pass ``model-exchange``: the event iteration of initialization ends
    after the count FMPy's low-level calls give, FMPy's CVODE run reaches the stop time (or
    the time the FMU ends the run) and records every Real output of the XML."""
    source = REF / f"fmi{fmi}" / f"{name}.fmu"
    ctx = reference_context(fmi, name, interface="me", stop_time=stop)
    detail = exchange.check_model_exchange(ctx)
    n = _initial_event_iterations(source, fmi, tmp_path)
    head = (f"event iteration at initialization: {n} iteration(s); FMPy's Model Exchange "
            f"simulation (CVODE) to t = {end} s, ")
    assert detail.startswith(head), detail
    assert detail.endswith(f" rows, {len(_real_outputs(source, fmi))} output(s)"), detail
    if rows is not None:
        assert f" {rows} rows, " in detail, detail
    assert ctx.warnings == []


def _me_stub_ctx(names, start=0.0, stop=2.0, step=0.5, me=True):
    md = SimpleNamespace(modelExchange=object() if me else None)
    outputs = [SimpleNamespace(name=n, kind="Real") for n in names]
    outputs.append(SimpleNamespace(name="count", kind="Integer"))
    return SimpleNamespace(fmu=SimpleNamespace(model_description=md, model_description3=None,
                                               _unzipdir="unzipped"),
                           outputs=outputs, start=start, stop=stop, step=step, warnings=[],
                           event=lambda **row: None)


@pytest.mark.parametrize("start, stop, step, interval", [
    (0.0, 2.0, 0.5, 0.5),  # the step is the longer: a row per step
    (1.0, 301.0, 0.5, 3.0),  # the run over 100 is the longer: (301 - 1) / 100
])
def test_model_exchange_asks_fmpy_for_the_real_outputs_at_most_every_hundredth(
        monkeypatch, start, stop, step, interval):
    """The check hands FMPy's Model Exchange simulation the Real outputs only, the FMU's
    experiment, and a row interval of max(step, run / 100); outputs that are not finite are a
    warning listing the first five, the rest of the record (other columns) is not counted."""
    names = [f"y{i}" for i in range(7)]
    got = {}

    def simulate(path, **kw):
        got.update(kw, path=path)
        dtype = [("time", float), *((n, float) for n in names), ("extra", float)]
        rec = np.zeros(4, dtype=dtype)
        rec["time"] = [start, start + 1.0, start + 2.0, stop]
        for n in names[:6]:
            rec[n][2] = math.nan if n != "y3" else -math.inf
        rec["extra"][1] = math.nan
        return rec

    monkeypatch.setattr(exchange, "_event_iterations", lambda ctx: 3)
    monkeypatch.setattr(exchange.fmpy, "simulate_fmu", simulate)
    ctx = _me_stub_ctx(names, start, stop, step)
    detail = exchange.check_model_exchange(ctx)
    assert got["path"] == "unzipped" and got["fmi_type"] == "ModelExchange"
    assert got["solver"] == "CVode" and got["output"] == names
    assert (got["start_time"], got["stop_time"]) == (start, stop)
    assert got["output_interval"] == interval
    assert ctx.warnings == ["non-finite outputs through Model Exchange: y0, y1, y2, y3, y4"]
    assert detail == (f"event iteration at initialization: 3 iteration(s); FMPy's Model "
                      f"Exchange simulation (CVODE) to t = {stop:.6g} s, 4 rows, 7 output(s)")


def test_model_exchange_with_finite_outputs_warns_of_nothing_and_asks_for_none_without_reals(
        monkeypatch):
    got = {}

    def simulate(path, **kw):
        got.update(kw)
        return np.zeros(3, dtype=[("time", float), ("count", float)])

    monkeypatch.setattr(exchange, "_event_iterations", lambda ctx: 1)
    monkeypatch.setattr(exchange.fmpy, "simulate_fmu", simulate)
    ctx = _me_stub_ctx([])
    assert exchange.check_model_exchange(ctx).endswith(" 3 rows, 0 output(s)")
    assert got["output"] is None and ctx.warnings == []


def test_model_exchange_without_the_interface_is_skipped_and_a_runaway_iteration_fails(
        monkeypatch, reference_context):
    """An FMU with no Model Exchange interface: the check does not apply (skipped); an event
    iteration that never ends fails the check, naming the limit (FMI 2.0 3.2.3)."""
    from dronefly.harness.cosim.exchange import MAX_EVENT_ITERATIONS, EventIterationError

    with pytest.raises(CheckSkipped, match="no Model Exchange interface"):
        exchange.check_model_exchange(_me_stub_ctx(["y"], me=False))

    def runaway(ctx, inst):
        raise EventIterationError("asked for another each time")

    monkeypatch.setattr(exchange, "initialize", runaway)
    ctx = reference_context(2, "Dahlquist", interface="me")
    assert _fails(exchange.check_model_exchange, ctx) == (
        f"the event iteration of initialization did not terminate in {MAX_EVENT_ITERATIONS} "
        "iterations")


def test_model_exchange_of_an_fmu_whose_description_fmpy_refuses(tmp_path):
    """A description FMPy's validation refuses (an attribute the schema does not allow) is
    the validate check's finding, reported there once: model-exchange runs the FMU as it is."""
    path = _seeded(tmp_path, 2, "Dahlquist",
                   ('modelName="Dahlquist"', 'modelName="Dahlquist" bogus="1"'))
    with pytest.raises(Exception, match="bogus"):  # the finding FMPy's validation makes
        read_model_description(str(path), validate=True)
    from dronefly.harness.compliance.driver import Context
    from dronefly.harness.compliance.rules import CheckOptions
    from dronefly.harness.cosim.fmu import FMU

    with FMU(path, validate=False, require_binary=False, require_cosim=False) as fmu:
        ctx = Context(fmu, CheckOptions(), None)  # as the checker loads an FMU
        ctx.interface = "me"
        assert " to t = 10 s, 101 rows, 1 output(s)" in exchange.check_model_exchange(ctx)
