"""The FMI 3.0 view of a :class:`dronefly.fmi.SlaveBase` variable table.

One table (:class:`~dronefly.fmi.vars.Var`, one scalar per row) serves both FMI versions.
For FMI 3.0 it is regrouped, without any per-FMU code:

- value reference 0 is the independent variable ``time`` [s];
- the scalars ``M[i,j]`` of a complete ``m`` x ``n`` grid whose rows agree in causality,
  variability, type, unit, display unit and initial become one 2-D array variable ``M``
  with dimensions ``(m, n)``, served row-major (``A``, ``B`` of the plants, ``K`` of the
  controllers, and whatever matrix a model adds the same way);
- every other scalar stays a scalar.

Value references follow the order of the table, an array taking the place of its first
element. Shipped inside every FMI 3.0 FMU; imports only the standard library.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Sequence

from .vars import Var

__all__ = ["TIME", "Var3", "array_dependencies", "fmi3_table"]

#: the independent variable (value reference 0)
TIME = Var("time", "independent", "continuous",
           "simulation time, the independent variable (seconds from the start time)", "s")
_DANGLING = {"a", "an", "at", "by", "for", "in", "of", "on", "the", "to", "with"}
_ELEMENT = re.compile(r"^([A-Za-z_]\w*)\[(\d+),(\d+)\]$")


@dataclass(frozen=True)
class Var3:
    """One FMI 3.0 variable: a scalar, a 2-D array, or ``time``.

    ``var`` is the (first) scalar row it comes from (causality, variability, type, unit);
    ``indices`` are the rows of the scalar table it holds, row-major (``()`` for ``time``);
    ``dims`` is ``()`` for a scalar, ``(m, n)`` for an array.
    """

    name: str
    var: Var
    indices: tuple[int, ...]
    dims: tuple[int, ...]
    description: str


def _uniform(rows: Sequence[Var]) -> bool:
    first = rows[0]
    key = (first.causality, first.variability, first.type, first.unit, first.display_unit,
           first.initial)
    return all((v.causality, v.variability, v.type, v.unit, v.display_unit, v.initial) == key
               for v in rows)


def _common_text(texts: Sequence[str]) -> str:
    """What all element descriptions say before they differ, cut at a word boundary."""
    prefix = texts[0]
    for t in texts[1:]:
        k = 0
        while k < min(len(prefix), len(t)) and prefix[k] == t[k]:
            k += 1
        prefix = prefix[:k]
    if len(set(texts)) > 1:
        for sep in (", ", "; ", " "):
            cut = prefix.rfind(sep)
            if cut > 0:
                return prefix[:cut]
    return prefix.rstrip(" ,;")


def _arrays(variables: Sequence[Var]) -> dict[str, tuple[int, int, list[int]]]:
    """Array name -> (m, n, scalar rows row-major) for every complete, uniform grid."""
    grids: dict[str, dict[tuple[int, int], int]] = {}
    for i, v in enumerate(variables):
        m = _ELEMENT.match(v.name)
        if m:
            grids.setdefault(m.group(1), {})[(int(m.group(2)), int(m.group(3)))] = i
    names = {v.name for v in variables}
    out = {}
    for name, cells in grids.items():
        rows = max(i for i, _ in cells)
        cols = max(j for _, j in cells)
        full = [(i, j) for i in range(1, rows + 1) for j in range(1, cols + 1)]
        if name in names or name == TIME.name or len(cells) != len(full) or set(cells) != set(full):
            continue
        order = [cells[c] for c in full]
        if _uniform([variables[k] for k in order]):
            out[name] = (rows, cols, order)
    return out


def fmi3_table(variables: Sequence[Var]) -> tuple[Var3, ...]:
    """The FMI 3.0 variables of a scalar table; index = value reference."""
    arrays = _arrays(variables)
    first = {order[0]: name for name, (_, _, order) in arrays.items()}
    inside = {k for _, _, order in arrays.values() for k in order}
    out = [Var3(TIME.name, TIME, (), (), TIME.description)]
    for i, v in enumerate(variables):
        if i in first:
            name = first[i]
            m, n, order = arrays[name]
            text = _common_text([variables[k].description for k in order])
            words = text.split()
            if len(words) < 3 or words[-1] in _DANGLING:  # show what the first element says
                text = f"{name}[i,j]; {name}[1,1]: {v.description}"
            out.append(Var3(name, v, tuple(order), (m, n),
                            f"{text} ({m} x {n} array, row-major; element [i,j] is "
                            f"{name}[i,j] of the FMI 2.0 FMU)"))
        elif i not in inside:
            out.append(Var3(v.name, v, (i,), (), v.description))
    return tuple(out)


def array_dependencies(table: Sequence[Var3], variables: Sequence[Var],
                       names_of: Sequence[tuple[str, ...] | None]) -> tuple[int, ...] | None:
    """Value references that the union of the given scalar dependency lists names
    (``None`` if any list is ``None``: depends on all knowns)."""
    if any(d is None for d in names_of):
        return None
    vr_of_row = {k: vr for vr, e in enumerate(table) for k in e.indices}
    row = {v.name: k for k, v in enumerate(variables)}
    return tuple(sorted({vr_of_row[row[n]] for deps in names_of for n in deps}))  # type: ignore[union-attr]
