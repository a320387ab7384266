"""The checker's checks that read an archive or call a binary (harness/compliance/static.py,
names.py, ...), on small inputs in-process: tiny FMU archives written in tmp_path, stub contexts
(the attributes a check reads), the Modelica Reference-FMUs. Written against the mutants that
survived the other tests (docs/mutation.md). Oracles: the FMI standard's text (FMI 2.0 2.3 and
FMI 3.0 2.5 for the archive's layout, 2.2.9 / 2.4.7.5 for the names' grammar, the sections of
the model description), and defects seeded by hand. No FMU is built: a mutant costs seconds."""

from __future__ import annotations

import dataclasses
import zipfile
from pathlib import Path
from types import SimpleNamespace

import pytest

from fmpy import platform, platform_tuple, read_model_description

from dronefly.harness.compliance import names, static
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
