"""Static rules of modelDescription.xml beyond FMPy's validation, each with its section.

:func:`structure_problems` returns every problem found, as ``(section, text)``; the
``validate`` check (:mod:`.static`) lists them with FMPy's. The rules (FMI 2.0 section / FMI
3.0 section):

* causality and variability combine as the standard's table allows; ``continuous`` only for
  floating-point variables; ``independent`` is continuous (2.2.7 / 2.4.7);
* ``initial`` as that table allows for the combination; a start value where ``initial`` is
  exact or approx, for inputs, parameters and constants, and none where it is calculated or
  for the independent variable (2.2.7 / 2.4.7);
* ``min <= start <= max``, ``min <= max``, ``nominal > 0`` (2.2.7 / 2.4.7);
* ``derivative`` and ``previous`` name a variable of the right type (2.2.7 / 2.4.7);
* ``unit`` is a UnitDefinition where there are UnitDefinitions, ``displayUnit`` one of its
  DisplayUnits (2.2.2 / 2.4.2); ``declaredType`` of the variable's type (2.2.3 / 2.4.3);
* ModelStructure: Outputs lists exactly the outputs, each list (Outputs, Derivatives,
  InitialUnknowns) in ascending order of index without repeats, Derivatives are derivatives,
  and every dependency index names a variable (2.2.8 / 2.4.8);
* aliases (variables sharing a value reference) agree in type and variability and at most one
  of them has a start value (2.2.7 / FMI 3.0: value references are unique, 2.4.7);
* FMI 3.0: a dimension given by a value reference names a structural parameter (or constant) of
  an unsigned integer type; a ``clocks`` attribute names Clock variables (2.4.7).
"""

from __future__ import annotations

import math
from collections import defaultdict
from typing import Any

__all__ = ["alias_notes", "structure_problems"]

_FLOAT = ("Real", "Float32", "Float64")
#: FMI 2.0 2.2.7 / FMI 3.0 2.4.7: the variabilities each causality allows
_ALLOWED = {
    "parameter": ("fixed", "tunable"),
    "calculatedParameter": ("fixed", "tunable"),
    "structuralParameter": ("fixed", "tunable"),
    "input": ("discrete", "continuous"),
    "output": ("constant", "discrete", "continuous"),
    "local": ("constant", "fixed", "tunable", "discrete", "continuous"),
    "independent": ("continuous",),
}
#: the values of initial each (causality, variability) allows, the first its default
#: (FMI 2.0 2.2.7's table; FMI 3.0 2.4.7's is the same for these)
_INITIAL = {
    ("parameter", "fixed"): ("exact",), ("parameter", "tunable"): ("exact",),
    ("structuralParameter", "fixed"): ("exact",), ("structuralParameter", "tunable"): ("exact",),
    ("calculatedParameter", "fixed"): ("calculated", "approx"),
    ("calculatedParameter", "tunable"): ("calculated", "approx"),
    # inputs take no initial in FMI 2.0; FMPy fills in "exact" where none is written
    ("input", "discrete"): ("exact",), ("input", "continuous"): ("exact",),
    ("output", "constant"): ("exact",),
    ("output", "discrete"): ("calculated", "exact", "approx"),
    ("output", "continuous"): ("calculated", "exact", "approx"),
    ("local", "constant"): ("exact",),
    ("local", "fixed"): ("calculated", "exact", "approx"),
    ("local", "tunable"): ("calculated", "exact", "approx"),
    ("local", "discrete"): ("calculated", "exact", "approx"),
    ("local", "continuous"): ("calculated", "exact", "approx"),
    ("independent", "continuous"): (None,),
}


def _num(x: Any) -> float | None:
    if x is None:
        return None
    try:
        return float(str(x).split()[0])
    except (TypeError, ValueError, IndexError):
        return None


def structure_problems(md: Any, fmi_version: int) -> list[tuple[str, str]]:
    """Every problem of the rules above in the model description ``md`` (FMPy's, of the FMU's
    own version), as ``(section, text)``."""
    v3 = fmi_version == 3
    var_s, ms_s = ("2.4.7", "2.4.8") if v3 else ("2.2.7", "2.2.8")
    unit_s, type_s = ("2.4.2", "2.4.3") if v3 else ("2.2.2", "2.2.3")
    out: list[tuple[str, str]] = []
    variables = list(md.modelVariables)
    index = {id(v): k + 1 for k, v in enumerate(variables)}
    units = {u.name: u for u in (md.unitDefinitions or [])}
    for v in variables:
        c = v.causality or "local"
        var = v.variability or ("continuous" if v.type in _FLOAT else "discrete")
        what = f"variable {v.name!r}"
        if var not in _ALLOWED.get(c, (var,)):
            out.append((var_s, f"{what}: causality {c!r} with variability {var!r} is not a "
                               "combination the standard allows"))
            continue
        if var == "continuous" and v.type not in _FLOAT:
            continue  # FMPy's validation reports it (and the declaration is not consistent)
        allowed = _INITIAL.get((c, var))
        initial = v.initial
        if allowed is not None:
            if initial is not None and initial not in allowed:
                out.append((var_s, f"{what}: initial={initial!r} is not allowed for causality "
                                   f"{c!r}, variability {var!r} (allowed: "
                                   f"{', '.join(a for a in allowed if a) or 'none'})"))
            initial = initial or allowed[0]
        has_start = v.start is not None
        if c == "independent" and has_start:
            out.append((var_s, f"{what}: the independent variable has a start value"))
        elif initial in ("exact", "approx") or c == "input" or var == "constant":
            if not has_start and v.type not in ("Clock", "Binary", "String"):
                out.append((var_s, f"{what}: no start value, required for causality {c!r}, "
                                   f"variability {var!r}, initial {initial!r}"))
        elif initial == "calculated" and has_start:
            out.append((var_s, f"{what}: a start value with initial 'calculated'"))
        lo, hi, st, nom = (_num(getattr(v, a, None)) for a in ("min", "max", "start", "nominal"))
        if lo is not None and hi is not None and lo > hi:
            out.append((var_s, f"{what}: min {lo!r} > max {hi!r}"))
        if st is not None and not v.dimensions and v.type not in ("Boolean", "String"):
            if lo is not None and st < lo:
                out.append((var_s, f"{what}: start {st!r} < min {lo!r}"))
            if hi is not None and st > hi:
                out.append((var_s, f"{what}: start {st!r} > max {hi!r}"))
        if nom is not None and not (nom > 0 and math.isfinite(nom)):
            out.append((var_s, f"{what}: nominal {nom!r} is not > 0"))
        for ref in ("derivative", "previous"):
            target = getattr(v, ref, None)
            if target is None:
                continue
            if ref == "derivative" and target.type not in _FLOAT:
                out.append((var_s, f"{what}: derivative of {target.name!r}, which is not a "
                                   "floating-point variable"))
            if ref == "previous" and target.type != v.type:
                out.append((var_s, f"{what}: previous names {target.name!r} of type "
                                   f"{target.type}, not {v.type}"))
        dt = v.declaredType
        if dt is not None and getattr(dt, "type", None) not in (None, v.type) and not (
                v.type == "Enumeration" and dt.type == "Enumeration"):
            out.append((type_s, f"{what}: declaredType {dt.name!r} is a {dt.type} type, the "
                                f"variable a {v.type}"))
        unit = v.unit or (getattr(dt, "unit", None) if dt is not None else None)
        if unit and units and unit not in units:
            out.append((unit_s, f"{what}: unit {unit!r} is not among the UnitDefinitions"))
        display = v.displayUnit or (getattr(dt, "displayUnit", None) if dt is not None else None)
        if display and unit in units and display not in {
                d.name for d in getattr(units[unit], "displayUnits", None) or []}:
            out.append((unit_s, f"{what}: displayUnit {display!r} is not a DisplayUnit of "
                                f"unit {unit!r}"))
        if v3:
            for d in v.dimensions or []:
                t = d.variable
                if d.valueReference is not None and (
                        t is None or t.causality not in ("structuralParameter", None)
                        and t.variability != "constant" or t is not None
                        and not str(t.type).startswith("UInt")):
                    out.append((var_s, f"{what}: a dimension given by "
                                       f"{getattr(t, 'name', d.valueReference)!r}, not a "
                                       "structural parameter or constant of an unsigned "
                                       "integer type"))
            for clock in getattr(v, "clocks", None) or []:
                if getattr(clock, "type", None) != "Clock":
                    out.append(("2.4.7", f"{what}: clocks names {clock.name!r}, not a Clock"))
    for vr, group in _alias_groups(variables, v3):
        names = ", ".join(repr(v.name) for v in group)
        if v3:
            out.append(("2.4.7", f"variables {names} share value reference {vr} (FMI 3.0: each "
                                 "variable has its own)"))
            continue
        starts = [v for v in group if v.start is not None]
        if len(starts) > 1 and any(v.variability != "constant" for v in group):
            out.append(("2.2.7", f"aliases {names} (value reference {vr}): more than one has "
                                 "a start value"))
    # ModelStructure
    for label, unknowns in (("Outputs", md.outputs), ("Derivatives", md.derivatives),
                            ("InitialUnknowns", md.initialUnknowns)):
        idx = [index.get(id(u.variable)) for u in unknowns or []]
        if any(i is None for i in idx):
            out.append((ms_s, f"ModelStructure/{label}: an index names no variable"))
            continue
        if idx != sorted(set(idx)) and not v3:  # FMI 3.0 names value references, no order
            out.append((ms_s, f"ModelStructure/{label}: indices not in ascending order or "
                              f"repeated ({', '.join(map(str, idx[:8]))})"))
        for u in unknowns or []:
            for dep in u.dependencies or []:
                if id(dep) not in index:
                    out.append((ms_s, f"ModelStructure/{label}: a dependency of "
                                      f"{u.variable.name!r} names no variable"))
        if label == "Derivatives":
            for u in unknowns or []:
                if getattr(u.variable, "derivative", None) is None:
                    out.append((ms_s, f"ModelStructure/Derivatives: {u.variable.name!r} is not "
                                      "the derivative of a state (no derivative attribute)"))
    declared = {id(u.variable) for u in md.outputs or []}
    missing = [v.name for v in variables if v.causality == "output" and id(v) not in declared
               and getattr(v, "alias", None) is None]
    if missing:
        out.append((ms_s, f"ModelStructure/Outputs: the outputs {', '.join(missing[:6])} are "
                          "not listed"))
    return out


def alias_notes(md: Any) -> list[str]:
    """FMI 2.0 aliases (one value reference, one type family) declared with different
    variabilities. Not a violation: the standard's paragraph on value references says aliases
    "have identical values but other parts of the variable definition might be different", and
    the highest variability then governs (fmi-standard issue #436). A note for the user, since a
    lower one may be a false claim that no static check can refute."""
    if str(getattr(md, "fmiVersion", "2.0")).startswith("3"):
        return []
    return [f"aliases {', '.join(repr(v.name) for v in group)} (value reference {vr}) differ in "
            "variability (FMI 2.0 allows it; the highest governs)"
            for vr, group in _alias_groups(md.modelVariables, False)
            if len({v.variability for v in group}) > 1]


def _alias_groups(variables: Any, v3: bool) -> list[tuple[Any, list[Any]]]:
    """(value reference, variables) of every value reference that two or more variables share:
    per type family in FMI 2.0 (an Enumeration is an Integer); in FMI 3.0 across all variables,
    Clocks included (2.4.7: "The valueReference must be unique for all variables of an FMU"),
    its ``<Alias>`` elements left out."""
    by_vr: dict[Any, list[Any]] = defaultdict(list)
    for v in variables:
        if v3 and getattr(v, "alias", None) is not None:  # FMI 3.0 <Alias>
            continue
        family = v.type if v3 else ("Integer" if v.type == "Enumeration" else v.type)
        by_vr[(v.valueReference, None if v3 else family)].append(v)
    return [(vr, group) for (vr, _), group in by_vr.items() if len(group) > 1]
