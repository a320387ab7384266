"""The structured-name check of ``dronefly check`` (harness/compliance/names.py) against FMPy's
Earley parser of the same grammar (the oracle), on names generated from the grammar and on
their one-character mutations; escapes against the standard's text (FMI 2.0 section 2.2.9)."""

from __future__ import annotations

import random
import zipfile
from pathlib import Path
from unittest import mock

import fmpy.validation
import lark
import pytest
from fmpy.model_description import ModelDescription, ScalarVariable

from dronefly.harness.compliance.names import is_structured_name, validate_fmu

from shared_files import need_shared

REF = Path(__file__).resolve().parents[1].parent / "shared" / "reference-fmus"

#: characters a mutation draws from: every class of the grammar and some outside it
_ALPHABET = "aZ_09.,[]()'\"! #$%&*+-/:;<>=?@^{}|~`\u00e9\t"


def _fmpy_parser() -> lark.Lark:
    """FMPy's parser for structured names, its grammar taken from ``fmpy.validation`` as it
    builds it (so the oracle follows FMPy's version)."""
    seen = {}
    real = lark.Lark

    def spy(grammar, **kw):
        seen.update(grammar=grammar, kw=kw)
        return real(grammar, **kw)

    md = ModelDescription()
    md.variableNamingConvention = "structured"
    md.modelVariables = [ScalarVariable(name="x", valueReference=0)]
    with mock.patch.object(lark, "Lark", spy):
        assert fmpy.validation._validate_variable_names(md) == []
    return real(seen["grammar"], **seen["kw"])


def _generated(rng: random.Random) -> str:
    """A name drawn from the grammar (no escapes: FMPy reads those differently, see below)."""
    def bname():
        if rng.random() < 0.2:
            return "'" + "".join(rng.choice("ab9 .[]()!#$%&*+,-/:;<>=?@^{}|~")
                                 for _ in range(rng.randint(1, 4))) + "'"
        return rng.choice("_aZ") + "".join(rng.choice("_a9Z") for _ in range(rng.randint(0, 3)))

    def part():
        idx = ("[" + ",".join(str(rng.randint(0, 12)) for _ in range(rng.randint(1, 3))) + "]"
               if rng.random() < 0.3 else "")
        return bname() + idx

    ident = ".".join(part() for _ in range(rng.randint(1, 3)))
    if rng.random() < 0.25:
        return f"der({ident}" + (f",{rng.randint(1, 3)}" if rng.random() < 0.5 else "") + ")"
    return ident


def _mutated(rng: random.Random, name: str) -> str:
    i = rng.randrange(len(name) + 1)
    c = rng.choice(_ALPHABET)
    return rng.choice((name[:i] + c + name[i:], name[:i] + name[i + 1:],
                       name[:i] + c + name[i + 1:]))


def test_the_structured_name_check_agrees_with_fmpys_parser():
    """200 generated names and 200 one-character mutations of them (a seeded draw): legal for
    us exactly where FMPy's parser accepts them. Both kinds occur, so a check that accepts
    or refuses everything fails."""
    parser, rng = _fmpy_parser(), random.Random(20261203)
    names = [_generated(rng) for _ in range(200)]
    names += [_mutated(rng, n) for n in names]
    names = [n for n in names if "\\" not in n]
    verdicts = {}
    for name in names:
        try:
            parser.parse(name)
            verdicts[name] = True
        except lark.exceptions.LarkError:
            verdicts[name] = False
    assert 100 < sum(verdicts.values()) < len(verdicts) - 50  # both kinds, plenty of each
    wrong = {n: v for n, v in verdicts.items() if is_structured_name(n) != v}
    assert not wrong, wrong


@pytest.mark.parametrize("name, legal", [
    (r"'a\'b'", True),    # an escaped quote inside a Q-name
    (r"'\\'", True),      # an escaped backslash
    (r"'\n\t\?'", True),  # the C escapes the grammar lists
    (r"'\'", False),      # the quote is escaped: the Q-name never closes
    (r"'\q'", False),     # not an escape of the grammar
    ("'a\"b'", False),    # a bare double quote is no Q-char
    ("der(der(x))", False),  # der( takes an identifier
    ("x[]", False), ("x[1,]", False), ("a.", False), ("", False),
])
def test_escapes_and_edges_follow_the_standard(name, legal):
    """Where FMPy's grammar reads the escapes as single characters (it accepts ``'\\'``), the
    standard's text decides: an escape is a backslash and one of ``'"?\\abfnrtv``."""
    assert is_structured_name(name) is legal


def test_validate_fmu_gives_fmpys_problems(tmp_path):
    """On a Reference-FMU (clean) and on a copy made structured with an illegal name, our
    ``validate_fmu`` and FMPy's give the same problems (FMPy adds its parser's message)."""
    source = REF / "fmi2" / "BouncingBall.fmu"
    need_shared(source, "the Reference-FMUs")
    assert validate_fmu(str(source)) == fmpy.validation.validate_fmu(str(source)) == []
    bad = tmp_path / "BouncingBall.fmu"
    with zipfile.ZipFile(source) as zin, zipfile.ZipFile(bad, "w") as zout:
        for item in zin.infolist():
            data = zin.read(item)
            if item.filename == "modelDescription.xml":
                data = data.replace(b'name="h"', b'name="1h"', 1).replace(
                    b"<fmiModelDescription", b'<fmiModelDescription variableNamingConvention='
                    b'"structured"', 1)
            zout.writestr(item, data)
    ours, theirs = validate_fmu(str(bad)), fmpy.validation.validate_fmu(str(bad))
    cut = '"structured".'  # FMPy then quotes its parser's message
    assert ours and sorted(ours) == sorted(p.partition(cut)[0] + cut if cut in p else p
                                           for p in theirs)
