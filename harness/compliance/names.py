"""Variable names under ``variableNamingConvention="structured"``, and FMPy's validation with it.

The grammar is the standard's (FMI 2.0 section 2.2.9, FMI 3.0 section 2.4.7.5)::

    name        = identifier | "der(" identifier ["," unsignedInteger] ")"
    identifier  = B-name [arrayIndices] {"." B-name [arrayIndices]}
    B-name      = nondigit {digit | nondigit} | Q-name
    nondigit    = "_" | letters "a" to "z" | letters "A" to "Z"
    Q-name      = "'" (Q-char | escape) {Q-char | escape} "'"
    Q-char      = nondigit | digit | "!" | "#" | "$" | "%" | "&" | "(" | ")" | "*" | "+" | ","
                  | "-" | "." | "/" | ":" | ";" | "<" | ">" | "=" | "?" | "@" | "[" | "]"
                  | "^" | "{" | "}" | "|" | "~" | " "
    escape      = "\\'" | '\\"' | "\\?" | "\\\\" | "\\a" | "\\b" | "\\f" | "\\n" | "\\r"
                  | "\\t" | "\\v"
    arrayIndices = "[" unsignedInteger {"," unsignedInteger} "]"

It is a regular language, so one compiled regular expression decides it, in microseconds. FMPy
decides it with an Earley parser built per FMU (about 30 ms a name), which made the name check
most of ``dronefly check``'s static time. :func:`validate_fmu` is FMPy's ``validate_fmu`` with the
name check done here: the same problems, in FMPy's words. ``tests/test_check_names.py`` holds
the two deciders against each other on generated names.
"""

from __future__ import annotations

import os
import re
import zipfile

from fmpy import read_model_description
from fmpy.model_description import ModelDescription, ValidationError

__all__ = ["is_structured_name", "name_problems", "validate_fmu"]

_NONDIGIT = r"[_a-zA-Z]"
_QCHAR = r"[_a-zA-Z0-9!#$%&()*+,\-./:;<>=?@\[\]^{}|~ ]"
_ESCAPE = r"\\['\"?\\abfnrtv]"
_BNAME = rf"(?:{_NONDIGIT}[_a-zA-Z0-9]*|'(?:{_QCHAR}|{_ESCAPE})+')"
_INDICES = r"(?:\[[0-9]+(?:,[0-9]+)*\])"
_IDENTIFIER = rf"{_BNAME}{_INDICES}?(?:\.{_BNAME}{_INDICES}?)*"
_NAME = re.compile(rf"(?:{_IDENTIFIER}|der\({_IDENTIFIER}(?:,[0-9]+)?\))")


def is_structured_name(name: str) -> bool:
    """Whether ``name`` is legal under the structured naming convention (the grammar above)."""
    return _NAME.fullmatch(name) is not None


def name_problems(md: ModelDescription) -> list[str]:
    """The illegal variable names of ``md``, in FMPy's words (``fmpy.validation``): for the flat
    convention, names holding a carriage return, a line feed or a tab; for the structured one,
    names outside the grammar."""
    problems = []
    for v in md.modelVariables:
        if md.variableNamingConvention == "flat":
            for char, what in (("\r", "carriage return character (U+000D)"),
                               ("\n", "line feed character (U+000A)"),
                               ("\t", "tab character (U+0009)")):
                if char in v.name:
                    problems.append(f'Variable "{v.name}" (line {v.sourceline}) contains an '
                                    f"illegal {what}.")
        elif not is_structured_name(v.name):
            problems.append(f'"{v.name}" (line {v.sourceline}) is not a legal variable name for '
                            'naming convention "structured".')
    return problems


def validate_fmu(filename: str) -> list[str]:
    """FMPy's ``fmpy.validation.validate_fmu`` (the archive's paths, the XML schema, the
    ModelStructure, start values, causality and variability, units), with the variable names
    checked by :func:`name_problems`. The problems, an empty list for none."""
    problems = []
    if os.path.isfile(filename):
        with zipfile.ZipFile(filename) as zf:
            problems += [f'The file path "{f.orig_filename}" contains a backslash.'
                         for f in zf.filelist if "\\" in f.orig_filename]
    try:
        md = read_model_description(filename, validate=True, validate_model_structure=True)
    except ValidationError as e:
        # FMPy's own validation, the names left out, failed: the names are checked when the
        # schema was met (FMPy checks them in the same pass as the structure)
        try:
            md = read_model_description(filename, validate=True)
        except Exception:  # noqa: BLE001 (the schema, or FMPy's parser: as FMPy reports it)
            return problems + e.problems
        return problems + name_problems(md) + e.problems
    except Exception as e:  # noqa: BLE001 (FMPy's validate_fmu reports any failure as text)
        return problems + [str(e)]
    return problems + name_problems(md)
