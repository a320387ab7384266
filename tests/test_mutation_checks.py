"""The checker's checks that read an archive or call a binary (harness/compliance/static.py,
names.py, ...), on small inputs in-process: tiny FMU archives written in tmp_path, stub contexts
(the attributes a check reads), the Modelica Reference-FMUs. Written against the mutants that
survived the other tests (docs/mutation.md). Oracles: the FMI standard's text (FMI 2.0 2.3 and
FMI 3.0 2.5 for the archive's layout, 2.2.9 / 2.4.7.5 for the names' grammar, the sections of
the model description), and defects seeded by hand. No FMU is built: a mutant costs seconds."""

from __future__ import annotations

import ctypes
import dataclasses
import zipfile
from pathlib import Path
from types import SimpleNamespace

import pytest

from fmpy import platform, platform_tuple, read_model_description

from dronefly.harness.compliance import binary, names, static
from dronefly.harness.compliance.rules import CheckFailed


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
        if not source.is_file():
            pytest.skip(f"{source} is not there (../shared)")
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
