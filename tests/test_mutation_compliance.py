"""The checker's rules and static checks (harness/compliance/) on small in-memory inputs, written
against the mutants that survived the other tests (docs/mutation.md). Oracles: the FMI
standard's text (the status codes of fmi2Functions.h / fmi3FunctionTypes.h, the tables of FMI
2.0 2.2.7 and 2.2.8), and the definitions the module documents. No FMU is built or run: a
mutant costs seconds."""

from __future__ import annotations

import dataclasses

import pytest

from fmpy.model_description import read_model_description

from dronefly.harness.compliance import rules
from dronefly.harness.compliance.structure import alias_notes, structure_problems


# --- rules.py --------------------------------------------------------------------------------

# fmi2Functions.h: typedef enum { fmi2OK, fmi2Warning, fmi2Discard, fmi2Error, fmi2Fatal,
# fmi2Pending } fmi2Status; FMI 3.0's fmi3Status has the first five in the same order
@pytest.mark.parametrize("status, fmi, name", [
    (0, 2, "fmi2OK"), (1, 2, "fmi2Warning"), (2, 2, "fmi2Discard"), (3, 2, "fmi2Error"),
    (4, 2, "fmi2Fatal"), (5, 2, "fmi2Pending"), (0, 3, "fmi3OK"), (2, 3, "fmi3Discard"),
    (4, 3, "fmi3Fatal"),
    # outside the enumeration: the number, never an IndexError or a wrong name from the end
    (6, 2, "fmi2status 6"), (-1, 2, "fmi2status -1"), (7, 3, "fmi3status 7"),
])
def test_status_name_is_the_standards_enumerator(status, fmi, name):
    assert rules.status_name(status, fmi) == name


def test_rule_of_names_the_versions_rule_and_the_profiles_promise():
    r2, r3, ours = rules.RULES["call-sequence"]
    assert ours  # this check adds a dronefly promise
    assert rules.rule_of("call-sequence", 2, "standard") == r2
    assert rules.rule_of("call-sequence", 3, "standard") == r3
    assert rules.rule_of("call-sequence", 2, "dronefly") == f"{r2}; dronefly profile: {ours}"
    assert rules.rule_of("call-sequence", 3, "dronefly") == f"{r3}; dronefly profile: {ours}"
    r2, r3, ours = rules.RULES["reset"]
    assert not ours  # no promise beyond the standard: nothing appended
    assert rules.rule_of("reset", 2, "dronefly") == r2
    assert rules.rule_of("reset", 3, "dronefly") == r3
    assert rules.rule_of("no such check", 2, "dronefly") == ""
    assert rules.rule_of("no such check", 3, "standard") == ""


def test_results_and_reports_are_untimed_until_timed_and_results_are_values(tmp_path):
    """A result or report made without a duration took no measured time (0 s), and a result
    cannot change after it is made (a frozen dataclass: the report holds what was found)."""
    assert rules.CheckResult("x", True).duration_s == 0.0
    assert rules.FMUReport(tmp_path).duration_s == 0.0
    with pytest.raises(dataclasses.FrozenInstanceError):
        rules.CheckResult("x", True).passed = False  # type: ignore[misc]
    with pytest.raises(dataclasses.FrozenInstanceError):
        rules.CheckOptions().only = ("state",)  # type: ignore[misc]


def test_check_result_status_is_skipped_passed_or_failed():
    assert rules.CheckResult("x", True).status == "passed"
    assert rules.CheckResult("x", False).status == "failed"
    assert rules.CheckResult("x", True, skipped=True).status == "skipped"
    assert rules.CheckResult("x", False, skipped=True).status == "skipped"


@pytest.mark.parametrize("only, skip, name, want", [
    ((), (), "state", True),
    (("state",), (), "state", True),
    (("state",), (), "reset", False),
    ((), ("state",), "state", False),
    ((), ("state",), "reset", True),
    (("state", "reset"), ("reset",), "reset", False),
    (("state", "reset"), ("reset",), "state", True),
])
def test_check_options_select_only_and_skip(only, skip, name, want):
    assert rules.CheckOptions(only=only, skip=skip).wants(name) is want


def test_a_report_passes_when_something_was_checked_and_nothing_failed(tmp_path):
    ok, bad = rules.CheckResult("a", True), rules.CheckResult("b", False)
    assert not rules.FMUReport(tmp_path).passed  # nothing checked
    assert rules.FMUReport(tmp_path, [ok]).passed
    assert not rules.FMUReport(tmp_path, [ok, bad]).passed
    # an FMU skipped with a reason passes unless a check it ran failed
    assert rules.FMUReport(tmp_path, skipped="no binary for this platform").passed
    assert rules.FMUReport(tmp_path, [ok], skipped="why").passed
    assert not rules.FMUReport(tmp_path, [bad], skipped="why").passed


def test_require_fails_the_check_only_when_the_condition_is_false():
    rules.require(True, "not raised")
    with pytest.raises(rules.CheckFailed, match="the message"):
        rules.require(False, "the message")
    assert issubclass(rules.CheckFailed, AssertionError)


# --- structure.py: FMI 2.0 2.2.7 / 2.2.8 and FMI 3.0 2.4.7 / 2.4.8 on small descriptions ------

def _md(tmp_path, variables: str, structure: str = "", units: str = "", types: str = "",
        fmi: int = 2):
    """FMPy's model description of a modelDescription.xml holding ``variables``."""
    if fmi == 2:
        text = (f'<?xml version="1.0" encoding="UTF-8"?>\n<fmiModelDescription fmiVersion="2.0" '
                f'modelName="m" guid="{{0}}">\n<CoSimulation modelIdentifier="m"/>\n'
                f'{units}{types}<ModelVariables>\n{variables}\n</ModelVariables>\n'
                f'<ModelStructure>\n{structure}\n</ModelStructure>\n</fmiModelDescription>\n')
    else:
        text = (f'<?xml version="1.0" encoding="UTF-8"?>\n<fmiModelDescription fmiVersion="3.0" '
                f'modelName="m" instantiationToken="{{0}}">\n<CoSimulation modelIdentifier="m"/>'
                f'\n{units}{types}<ModelVariables>\n{variables}\n</ModelVariables>\n'
                f'<ModelStructure>\n{structure}\n</ModelStructure>\n</fmiModelDescription>\n')
    path = tmp_path / f"md{len(list(tmp_path.iterdir()))}.xml"
    path.write_text(text)
    return read_model_description(str(path), validate=False)


def _sv(name: str, vr: int, attrs: str = "", real: str = "", type_: str = "Real") -> str:
    return (f'<ScalarVariable name="{name}" valueReference="{vr}" {attrs}>'
            f'<{type_} {real}/></ScalarVariable>')


def _problems(tmp_path, *args, **kwargs) -> list[tuple[str, str]]:
    md = _md(tmp_path, *args, **kwargs)
    return structure_problems(md, kwargs.get("fmi", 2))


_OUT = '<Outputs><Unknown index="1"/></Outputs>'


@pytest.mark.parametrize("causality, variability, problem", [
    # 2.2.7's table: the variabilities each causality allows (FMPy's reader refuses these, so
    # the variable's attributes are changed after reading)
    ("parameter", "continuous", "causality 'parameter' with variability 'continuous' is not a "
                                "combination the standard allows"),
    ("input", "fixed", "causality 'input' with variability 'fixed'"),
    ("independent", "discrete", "causality 'independent' with variability 'discrete'"),
    ("output", "tunable", "causality 'output' with variability 'tunable'"),
])
def test_a_causality_variability_pair_outside_the_table_is_listed(tmp_path, causality,
                                                                  variability, problem):
    md = _md(tmp_path, _sv("x", 1, 'causality="local" variability="continuous"', ''))
    md.modelVariables[0].causality, md.modelVariables[0].variability = causality, variability
    got = structure_problems(md, 2)
    assert [s for s, p in got if problem in p] == ["2.2.7"], got


@pytest.mark.parametrize("attrs, real, ok", [
    ('causality="parameter" variability="fixed"', 'start="1"', True),
    ('causality="parameter" variability="tunable" initial="exact"', 'start="1"', True),
    ('causality="input" variability="continuous"', 'start="1"', True),
    ('causality="local" variability="continuous" initial="calculated"', '', True),
    ('causality="local" variability="continuous"', '', True),  # default: calculated
    ('causality="local" variability="fixed" initial="approx"', 'start="1"', True),
    ('causality="output" variability="constant"', 'start="1"', True),
    ('causality="calculatedParameter" variability="fixed"', '', True),
    ('causality="independent" variability="continuous"', '', True),
])
def test_combinations_the_table_allows_are_not_listed(tmp_path, attrs, real, ok):
    x = _sv("x", 1, attrs, real)
    structure = _OUT if 'causality="output"' in attrs else ""
    assert _problems(tmp_path, x, structure) == []


@pytest.mark.parametrize("attrs, real, problem", [
    ('causality="parameter" variability="fixed" initial="calculated"', '',
     "initial='calculated' is not allowed for causality 'parameter', variability 'fixed' "
     "(allowed: exact)"),
    ('causality="independent" variability="continuous" initial="exact"', 'start="0"',
     "initial='exact' is not allowed for causality 'independent', variability 'continuous' "
     "(allowed: none)"),
    ('causality="parameter" variability="fixed"', '',
     "no start value, required for causality 'parameter', variability 'fixed', initial 'exact'"),
    ('causality="input" variability="continuous"', '',
     "no start value, required for causality 'input'"),
    ('causality="local" variability="constant"', '',
     "no start value, required for causality 'local', variability 'constant'"),
    ('causality="local" variability="continuous" initial="approx"', '',
     "no start value, required for causality 'local', variability 'continuous', initial "
     "'approx'"),
    ('causality="local" variability="continuous" initial="calculated"', 'start="1"',
     "a start value with initial 'calculated'"),
    ('causality="local" variability="continuous"', 'start="1"',
     "a start value with initial 'calculated'"),  # the default initial of a local
])
def test_initial_and_start_follow_the_table(tmp_path, attrs, real, problem):
    got = _problems(tmp_path, _sv("x", 1, attrs, real))
    assert [p for s, p in got if s == "2.2.7" and problem in p], got


def test_the_independent_variable_has_no_start(tmp_path):
    got = _problems(tmp_path, _sv("time", 1, 'causality="independent" variability="continuous"',
                                  'start="0"'))
    assert ("2.2.7", "variable 'time': the independent variable has a start value") in got


def test_a_string_input_without_start_is_not_listed_but_a_real_one_is(tmp_path):
    assert _problems(tmp_path, _sv("s", 1, 'causality="input" variability="discrete"', '',
                                   "String")) == []
    assert _problems(tmp_path, _sv("s", 1, 'causality="input" variability="discrete"', '',
                                   "Integer"))


@pytest.mark.parametrize("real, problems", [
    ('start="1" min="0" max="2"', []),
    ('start="0" min="0" max="0"', []),  # the bounds are inclusive
    ('start="1" min="2" max="1"', ["min 2.0 > max 1.0", "start 1.0 < min 2.0"]),
    ('start="-1" min="0"', ["start -1.0 < min 0.0"]),
    ('start="3" max="2"', ["start 3.0 > max 2.0"]),
    ('start="1" nominal="2"', []),
    ('start="1" nominal="0"', ["nominal 0.0 is not > 0"]),
    ('start="1" nominal="-1"', ["nominal -1.0 is not > 0"]),
    ('start="1" nominal="INF"', ["nominal inf is not > 0"]),
])
def test_min_start_max_and_nominal(tmp_path, real, problems):
    got = _problems(tmp_path, _sv("p", 1, 'causality="parameter" variability="fixed"', real))
    assert sorted(p.split(": ", 1)[1] for _, p in got) == sorted(problems)


def test_start_within_bounds_is_checked_for_integers_not_for_booleans(tmp_path):
    attrs = 'causality="parameter" variability="fixed"'
    assert _problems(tmp_path, _sv("i", 1, attrs, 'start="5" max="4"', "Integer"))
    assert _problems(tmp_path, _sv("b", 1, attrs, 'start="true"', "Boolean")) == []


def test_derivative_and_previous_name_a_variable_of_the_right_type(tmp_path):
    local = 'causality="local" variability="continuous"'
    ok = _problems(tmp_path, _sv("x", 1, local, 'start="0" ', ) .replace(
        'causality="local"', 'causality="local" initial="exact"') + "\n"
        + _sv("der(x)", 2, local, 'derivative="1"'),
        '<Derivatives><Unknown index="2"/></Derivatives>')
    assert ok == []
    bad = _problems(tmp_path, _sv("i", 1, 'causality="local" variability="discrete"',
                                  '', "Integer") + "\n" + _sv("d", 2, local, 'derivative="1"'))
    assert ("2.2.7", "variable 'd': derivative of 'i', which is not a floating-point "
                     "variable") in bad


def test_unit_and_display_unit_must_be_defined(tmp_path):
    units = ('<UnitDefinitions><Unit name="m"><DisplayUnit name="mm" factor="1000"/></Unit>'
             '<Unit name="s"/></UnitDefinitions>\n')
    par = 'causality="parameter" variability="fixed"'
    assert _problems(tmp_path, _sv("p", 1, par, 'start="1" unit="m" displayUnit="mm"'),
                     units=units) == []
    assert _problems(tmp_path, _sv("p", 1, par, 'start="1" unit="km"'), units=units) == [
        ("2.2.2", "variable 'p': unit 'km' is not among the UnitDefinitions")]
    assert _problems(tmp_path, _sv("p", 1, par, 'start="1" unit="m" displayUnit="ft"'),
                     units=units) == [
        ("2.2.2", "variable 'p': displayUnit 'ft' is not a DisplayUnit of unit 'm'")]
    assert _problems(tmp_path, _sv("p", 1, par, 'start="1" unit="s" displayUnit="ms"'),
                     units=units) == [
        ("2.2.2", "variable 'p': displayUnit 'ms' is not a DisplayUnit of unit 's'")]
    # without UnitDefinitions a unit is not checked (2.2.2 makes them optional)
    assert _problems(tmp_path, _sv("p", 1, par, 'start="1" unit="km"')) == []


def test_aliases_have_one_start_and_a_note_where_variabilities_differ(tmp_path):
    """FMI 2.0: at most one alias has a start value (a problem); aliases of two variabilities
    are allowed ("other parts of the variable definition might be different"): a note."""
    par = 'causality="parameter" variability="fixed"'
    loc = 'causality="local" variability="continuous"'
    assert _problems(tmp_path, _sv("a", 1, par, 'start="1"') + _sv("b", 2, par, 'start="1"')) \
        == []
    md = _md(tmp_path, _sv("a", 1, par, 'start="1"') + _sv("b", 1, loc, ''))
    assert structure_problems(md, 2) == []
    assert alias_notes(md) == ["aliases 'a', 'b' (value reference 1) differ in variability "
                               "(FMI 2.0 allows it; the highest governs)"]
    assert alias_notes(_md(tmp_path, _sv("a", 1, par, 'start="1"') + _sv("b", 2, loc, ''))) == []
    # aliases of one variability: no note; a Real and an Integer of the same value reference
    # are no aliases in FMI 2.0 (value references are per type, 2.2.7): no note either
    assert alias_notes(_md(tmp_path, _sv("a", 1, loc) + _sv("b", 1, loc))) == []
    disc = 'causality="local" variability="discrete"'
    assert alias_notes(_md(tmp_path, _sv("a", 1, par, 'start="1"')
                           + _sv("n", 1, disc, "", "Integer"))) == []
    got = _problems(tmp_path, _sv("a", 1, par, 'start="1"') + _sv("b", 1, par, 'start="1"'))
    assert got == [("2.2.7", "aliases 'a', 'b' (value reference 1): more than one has a start "
                             "value")]
    # the same value reference in another type family (FMI 2.0) is no alias
    assert _problems(tmp_path, _sv("a", 1, par, 'start="1"')
                     + _sv("b", 1, par, 'start="1"', "Integer")) == []


def test_outputs_are_listed_in_ascending_order(tmp_path):
    out = 'causality="output" variability="continuous"'
    two = _sv("y1", 1, out) + _sv("y2", 2, out)
    assert _problems(tmp_path, two, '<Outputs><Unknown index="1"/><Unknown index="2"/>'
                                    '</Outputs>') == []
    got = _problems(tmp_path, two, '<Outputs><Unknown index="2"/><Unknown index="1"/></Outputs>')
    assert got == [("2.2.8", "ModelStructure/Outputs: indices not in ascending order or repeated "
                             "(2, 1)")]
    got = _problems(tmp_path, two, '<Outputs><Unknown index="1"/></Outputs>')
    assert got == [("2.2.8", "ModelStructure/Outputs: the outputs y2 are not listed")]


def test_a_clock_shares_no_value_reference_in_fmi3(tmp_path):
    """FMI 3.0 2.4.7.4 (Variable Attributes): "The valueReference must be unique for all
    variables of an FMU", and a Clock is a variable (2.4.7.1's Clock element; the
    Reference-FMU Clocks gives its four Clocks their own)."""
    clock = 'causality="input" intervalVariability="constant" intervalDecimal="1.0"'
    par = 'causality="parameter" variability="fixed"'
    assert _problems(tmp_path, f'<Clock name="c" valueReference="1" {clock}/>'
                               f'<Float64 name="a" valueReference="2" {par} start="1"/>',
                     fmi=3) == []
    got = _problems(tmp_path, f'<Clock name="c" valueReference="1" {clock}/>'
                              f'<Float64 name="a" valueReference="1" {par} start="1"/>', fmi=3)
    assert got == [("2.4.7", "variables 'c', 'a' share value reference 1 (FMI 3.0: each "
                             "variable has its own)")]
    got = _problems(tmp_path, f'<Clock name="c" valueReference="5" {clock}/>'
                              f'<Clock name="d" valueReference="5" {clock}/>', fmi=3)
    assert got == [("2.4.7", "variables 'c', 'd' share value reference 5 (FMI 3.0: each "
                             "variable has its own)")]


def test_an_fmi3_alias_shares_its_variables_value_reference(tmp_path):
    """FMI 3.0 2.4.7.5 (Alias variables): an ``<Alias>`` element names its variable again, with
    the variable's value reference; it is not a second variable sharing it (FMPy lists each
    alias after all variables, as a copy with ``alias`` set)."""
    par = 'causality="parameter" variability="fixed"'
    got = _problems(tmp_path, f'<Float64 name="a" valueReference="1" {par} start="1">'
                              '<Alias name="a_too" description="a again"/></Float64>'
                              f'<Float64 name="b" valueReference="2" {par} start="1"/>', fmi=3)
    assert got == []


def test_fmi3_sections_and_unique_value_references(tmp_path):
    par = 'causality="parameter" variability="fixed"'
    got = _problems(tmp_path, f'<Float64 name="e" valueReference="1" {par} start="0.7" min="0.5" '
                              'max="0.6"/>', fmi=3)
    assert got == [("2.4.7", "variable 'e': start 0.7 > max 0.6")]
    got = _problems(tmp_path, f'<Float64 name="a" valueReference="1" {par} start="1"/>'
                              f'<Float64 name="b" valueReference="1" {par} start="1"/>', fmi=3)
    assert got == [("2.4.7", "variables 'a', 'b' share value reference 1 (FMI 3.0: each "
                             "variable has its own)")]
    units = '<UnitDefinitions><Unit name="m"/></UnitDefinitions>\n'
    got = _problems(tmp_path, f'<Float64 name="e" valueReference="1" {par} start="1" '
                              'unit="km"/>', units=units, fmi=3)
    assert got == [("2.4.2", "variable 'e': unit 'km' is not among the UnitDefinitions")]
    # FMI 3.0 lists outputs by value reference: no order to keep
    out = 'causality="output" variability="continuous"'
    got = _problems(tmp_path, f'<Float64 name="y1" valueReference="1" {out}/>'
                              f'<Float64 name="y2" valueReference="2" {out}/>',
                    '<Output valueReference="2"/><Output valueReference="1"/>', fmi=3)
    assert got == []
    got = _problems(tmp_path, f'<Float64 name="y1" valueReference="1" {out}/>'
                              f'<Float64 name="y2" valueReference="2" {out}/>',
                    '<Output valueReference="1"/>', fmi=3)
    assert got == [("2.4.8", "ModelStructure/Outputs: the outputs y2 are not listed")]


@pytest.mark.parametrize("size, ok", [
    ('<UInt64 name="n" valueReference="1" causality="structuralParameter" variability="fixed" '
     'start="2"/>', True),
    ('<UInt32 name="n" valueReference="1" causality="local" variability="constant" start="2"/>',
     True),
    ('<UInt64 name="n" valueReference="1" causality="parameter" variability="fixed" '
     'start="2"/>', False),
    ('<Int64 name="n" valueReference="1" causality="structuralParameter" variability="fixed" '
     'start="2"/>', False),
])
def test_fmi3_a_dimension_names_an_unsigned_structural_parameter_or_constant(tmp_path, size, ok):
    array = ('<Float64 name="x" valueReference="2" causality="parameter" variability="fixed" '
             'start="1 2"><Dimension valueReference="1"/></Float64>')
    got = _problems(tmp_path, size + array, fmi=3)
    want = [] if ok else [("2.4.7", "variable 'x': a dimension given by 'n', not a structural "
                                    "parameter or constant of an unsigned integer type")]
    assert got == want


def test_every_variable_is_checked_after_one_that_ends_its_checks(tmp_path):
    """A variable whose combination is refused (or a continuous non-float) ends its own checks,
    not those of the variables after it."""
    par = 'causality="parameter" variability="fixed"'
    for what in ("combination", "continuous integer"):
        md = _md(tmp_path, _sv("a", 1, 'causality="local" variability="discrete"', '',
                               "Integer") + _sv("b", 2, par, 'start="-1" min="0"'))
        a = md.modelVariables[0]
        if what == "combination":
            a.causality, a.variability = "input", "fixed"
        else:
            a.variability = "continuous"
        got = structure_problems(md, 2)
        assert ("2.2.7", "variable 'b': start -1.0 < min 0.0") in got, (what, got)


def test_defaults_where_the_reader_leaves_variability_and_initial_out(tmp_path):
    """FMI 2.0 2.2.7: variability defaults to continuous (discrete for a non-float here) and
    initial to the first of the table's entry (calculated for a continuous local)."""
    md = _md(tmp_path, _sv("x", 1, 'causality="local" variability="continuous"', '')
             + _sv("i", 2, 'causality="local" variability="discrete"', '', "Integer")
             + _sv("time", 3, 'causality="independent" variability="continuous"', ''))
    for v in md.modelVariables:
        v.variability, v.initial = None, None
    assert structure_problems(md, 2) == []
    md.modelVariables[0].start = "1"  # a start value where initial is calculated
    assert structure_problems(md, 2) == [
        ("2.2.7", "variable 'x': a start value with initial 'calculated'")]


def test_bounds_without_a_start_value_are_checked_alone(tmp_path):
    loc = 'causality="local" variability="continuous"'
    assert _problems(tmp_path, _sv("x", 1, loc, 'min="0" max="1"')) == []
    assert _problems(tmp_path, _sv("x", 1, loc, 'min="0" max="1" nominal="0.5"')) == []


def test_previous_names_a_variable_of_the_same_type(tmp_path):
    """FMI 3.0 2.4.7 (previous): the variable and its previous value are of one type (FMPy does
    not resolve the attribute: set here)."""
    disc = 'causality="local" variability="discrete"'
    md = _md(tmp_path, f'<Float64 name="x" valueReference="1" {disc} initial="exact" start="0"/>'
                       f'<Float64 name="y" valueReference="2" {disc}/>'
                       f'<Int32 name="i" valueReference="3" {disc} initial="exact" start="0"/>',
             fmi=3)
    x, y, i = md.modelVariables
    y.previous = x
    assert structure_problems(md, 3) == []
    y.previous = i
    assert structure_problems(md, 3) == [
        ("2.4.7", "variable 'y': previous names 'i' of type Int32, not Float64")]


def test_declared_type_agrees_with_the_variable_and_lends_its_unit(tmp_path):
    units = ('<UnitDefinitions><Unit name="m"><DisplayUnit name="mm" factor="1000"/></Unit>'
             '</UnitDefinitions>\n')
    types = ('<TypeDefinitions><SimpleType name="Len"><Real unit="m" displayUnit="mm"/>'
             '</SimpleType><SimpleType name="Bad"><Real unit="km"/></SimpleType>'
             '<SimpleType name="Count"><Integer/></SimpleType>'
             '<SimpleType name="E"><Enumeration><Item name="a" value="1"/></Enumeration>'
             '</SimpleType></TypeDefinitions>\n')
    par = 'causality="parameter" variability="fixed"'
    ok = (_sv("l", 1, par, 'start="1" declaredType="Len"')
          + _sv("e", 2, par, 'start="1" declaredType="E"', "Enumeration"))
    assert _problems(tmp_path, ok, units=units, types=types) == []
    got = _problems(tmp_path, _sv("b", 1, par, 'start="1" declaredType="Bad"'), units=units,
                    types=types)
    assert got == [("2.2.2", "variable 'b': unit 'km' is not among the UnitDefinitions")]
    md = _md(tmp_path, _sv("l", 1, par, 'start="1" declaredType="Len"'), units=units,
             types=types)
    md.modelVariables[0].type = "Integer"  # an Integer variable of a Real type
    got = structure_problems(md, 2)
    assert ("2.2.3", "variable 'l': declaredType 'Len' is a Real type, the variable a "
                     "Integer") in got
    md = _md(tmp_path, _sv("c", 1, par, 'start="1" declaredType="Count"', "Integer"),
             units=units, types=types)
    md.modelVariables[0].type = "Enumeration"  # an Enumeration of an Integer type
    assert ("2.2.3", "variable 'c': declaredType 'Count' is a Integer type, the variable a "
                     "Enumeration") in structure_problems(md, 2)


def test_fmi3_clocks_name_clock_variables(tmp_path):
    disc = 'causality="local" variability="discrete"'
    variables = ('<Clock name="c" valueReference="3" causality="input" variability="discrete" '
                 'intervalVariability="triggered"/>'
                 f'<Float64 name="z" valueReference="4" {disc} clocks="3"/>')
    assert _problems(tmp_path, variables, fmi=3) == []
    md = _md(tmp_path, variables + f'<Float64 name="w" valueReference="5" {disc}/>', fmi=3)
    md.modelVariables[1].clocks = [md.modelVariables[2]]
    assert structure_problems(md, 3) == [("2.4.7", "variable 'z': clocks names 'w', not a Clock")]


def test_aliases_of_integers_and_enumerations_and_several_groups(tmp_path):
    """FMI 2.0: Integer and Enumeration share value references (one type family); every group
    of aliases is checked, also after a variable alone on its reference."""
    types = ('<TypeDefinitions><SimpleType name="E"><Enumeration><Item name="a" value="1"/>'
             '</Enumeration></SimpleType></TypeDefinitions>\n')
    par = 'causality="parameter" variability="fixed"'
    got = _problems(tmp_path, _sv("i", 1, par, 'start="1"', "Integer")
                    + _sv("e", 1, par, 'start="1" declaredType="E"', "Enumeration"), types=types)
    assert got == [("2.2.7", "aliases 'i', 'e' (value reference 1): more than one has a start "
                             "value")]
    got = _problems(tmp_path, _sv("alone", 0, par, 'start="1"') + _sv("a", 1, par, 'start="1"')
                    + _sv("b", 1, par, 'start="1"'))
    assert got == [("2.2.7", "aliases 'a', 'b' (value reference 1): more than one has a start "
                             "value")]
    got = _problems(tmp_path, f'<Float64 name="a" valueReference="1" {par} start="1"/>'
                              f'<Float64 name="b" valueReference="1" {par} start="1"/>'
                              f'<Float64 name="c" valueReference="2" {par} start="1"/>'
                              f'<Float64 name="d" valueReference="2" {par} start="1"/>', fmi=3)
    assert [p for _, p in got] == [
        "variables 'a', 'b' share value reference 1 (FMI 3.0: each variable has its own)",
        "variables 'c', 'd' share value reference 2 (FMI 3.0: each variable has its own)"]


def test_derivatives_and_dependencies_name_variables(tmp_path):
    """2.2.8: each Derivatives entry is a derivative (has the derivative attribute), every
    dependency names a variable of the list."""
    loc = 'causality="local" variability="continuous"'
    x = _sv("x", 1, 'causality="local" variability="continuous" initial="exact"', 'start="0"')
    dx = _sv("der(x)", 2, loc, 'derivative="1"')
    md = _md(tmp_path, x + dx, '<Derivatives><Unknown index="2" dependencies="1"/>'
                               '</Derivatives>')
    assert structure_problems(md, 2) == []
    md.derivatives[0].dependencies.append(object())  # a dependency on no variable of the list
    assert structure_problems(md, 2) == [
        ("2.2.8", "ModelStructure/Derivatives: a dependency of 'der(x)' names no variable")]
    md = _md(tmp_path, x + dx, '<Derivatives><Unknown index="1"/></Derivatives>')
    assert structure_problems(md, 2) == [
        ("2.2.8", "ModelStructure/Derivatives: 'x' is not the derivative of a state (no "
                  "derivative attribute)")]


def test_a_display_unit_of_the_declared_type_is_checked_too(tmp_path):
    units = ('<UnitDefinitions><Unit name="m"><DisplayUnit name="mm" factor="1000"/></Unit>'
             '</UnitDefinitions>\n')
    types = ('<TypeDefinitions><SimpleType name="Len"><Real unit="m" displayUnit="ft"/>'
             '</SimpleType></TypeDefinitions>\n')
    got = _problems(tmp_path, _sv("l", 1, 'causality="parameter" variability="fixed"',
                                  'start="1" declaredType="Len"'), units=units, types=types)
    assert got == [("2.2.2", "variable 'l': displayUnit 'ft' is not a DisplayUnit of unit 'm'")]


def test_aliases_after_a_clock_are_checked(tmp_path):
    par = 'causality="parameter" variability="fixed"'
    got = _problems(tmp_path, '<Clock name="c" valueReference="3" causality="input" '
                              'variability="discrete" intervalVariability="triggered"/>'
                              f'<Float64 name="a" valueReference="1" {par} start="1"/>'
                              f'<Float64 name="b" valueReference="1" {par} start="1"/>', fmi=3)
    assert [p for _, p in got] == [
        "variables 'a', 'b' share value reference 1 (FMI 3.0: each variable has its own)"]


def test_each_model_structure_list_is_checked_after_one_naming_no_variable(tmp_path):
    x = _sv("x", 1, 'causality="local" variability="continuous" initial="exact"', 'start="0"')
    y = _sv("y", 2, 'causality="output" variability="continuous"', '')
    md = _md(tmp_path, x + y, '<Outputs><Unknown index="2"/></Outputs><Derivatives><Unknown '
                              'index="1"/></Derivatives>')
    md.outputs[0].variable = type("Foreign", (), {"name": "ghost"})()
    got = structure_problems(md, 2)
    assert ("2.2.8", "ModelStructure/Outputs: an index names no variable") in got
    assert ("2.2.8", "ModelStructure/Derivatives: 'x' is not the derivative of a state (no "
                     "derivative attribute)") in got


def test_a_long_list_of_indices_or_outputs_is_shown_by_its_head(tmp_path):
    """A message quotes the first 8 indices of an unordered ModelStructure list and the first 6
    outputs left out of it (the problem is one finding however long its list)."""
    out = 'causality="output" variability="continuous"'
    ten = "".join(_sv(f"y{k}", k, out) for k in range(1, 11))
    backwards = "".join(f'<Unknown index="{k}"/>' for k in range(10, 0, -1))
    got = _problems(tmp_path, ten, f"<Outputs>{backwards}</Outputs>")
    assert got == [("2.2.8", "ModelStructure/Outputs: indices not in ascending order or repeated "
                             "(10, 9, 8, 7, 6, 5, 4, 3)")]
    got = _problems(tmp_path, ten, '<Outputs><Unknown index="1"/></Outputs>')
    assert got == [("2.2.8", "ModelStructure/Outputs: the outputs y2, y3, y4, y5, y6, y7 are "
                             "not listed")]
