"""What the ModelStructure of each FMU says about a system: direct feedthrough, order, loops.

An output that depends directly on an input (ModelStructure ``Outputs`` dependencies; an
omitted attribute means "on every input") makes its FMU a direct-feedthrough FMU for that
input. Gauss-Seidel evaluates such an FMU after the producers of those inputs: a
topological order. A cycle of connections and feedthrough dependencies is an algebraic loop:
refused (with the variables of the cycle named) unless a Jacobi master is asked for.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Mapping, Sequence

from ...core.text import a_or_an
from .system import Connection, SystemSpecError

__all__ = ["Feedthrough", "Order", "check_connections", "evaluation_order", "feedthrough"]

#: instance -> {output name: input names it depends on directly}
Feedthrough = dict[str, dict[str, tuple[str, ...]]]


def feedthrough(md: Any) -> dict[str, tuple[str, ...]]:
    """Output name -> the input names it depends on directly (ModelStructure)."""
    inputs = tuple(v.name for v in md.modelVariables if v.causality == "input")
    out: dict[str, tuple[str, ...]] = {}
    declared = {o.variable.name: o for o in md.outputs}
    for v in md.modelVariables:
        if v.causality != "output":
            continue
        o = declared.get(v.name)
        if o is None or o.dependencies is None:  # no ModelStructure entry: depends on all
            out[v.name] = inputs
        else:
            out[v.name] = tuple(d.name for d in o.dependencies if d.causality == "input")
    return out


def _unit(v: Any) -> str | None:
    unit = getattr(v, "unit", None)
    if unit is None and getattr(v, "declaredType", None) is not None:
        unit = getattr(v.declaredType, "unit", None)
    return unit


def check_connections(mds: Mapping[str, Any], connections: Sequence[Connection]) -> None:
    """Each connection joins an existing output to an existing input of the same type and,
    where both declare one, the same unit (no silent conversion)."""
    for c in connections:
        ends = []
        for inst, name, causality in ((c.source, c.output, "output"), (c.target, c.input, "input")):
            v = next((x for x in mds[inst].modelVariables if x.name == name), None)
            if v is None:
                raise SystemSpecError(f"connection {c}: {inst} has no variable {name!r}")
            if v.causality != causality:
                raise SystemSpecError(f"connection {c}: {inst}.{name} is "
                                      f"{a_or_an(v.causality)}, not {a_or_an(causality)}")
            ends.append(v)
        src, dst = ends
        if src.type != dst.type:
            raise SystemSpecError(f"connection {c}: types differ ({src.type} -> {dst.type})")
        us, ud = _unit(src), _unit(dst)
        if us is not None and ud is not None and us != ud:
            raise SystemSpecError(f"connection {c}: units differ ({us} -> {ud}); a connection "
                                  "does not convert units")


@dataclass(frozen=True)
class Order:
    """Instances whose outputs need no input first (``free``), then the direct-feedthrough
    instances in an order where every producer comes before its consumers (``chained``)."""

    free: tuple[str, ...]
    chained: tuple[str, ...]


def evaluation_order(instances: Sequence[str], ft: Feedthrough,
                     connections: Sequence[Connection], *, allow_loops: bool) -> Order:
    """Gauss-Seidel order; raises :class:`SystemSpecError` naming an algebraic loop."""
    driven = {(c.target, c.input): c for c in connections}
    # variable graph: output -> input (connection), input -> output (feedthrough)
    succ: dict[tuple[str, str], list[tuple[str, str]]] = {}
    for c in connections:
        succ.setdefault((c.source, c.output), []).append((c.target, "in:" + c.input))
    for inst, outs in ft.items():
        for out, ins in outs.items():
            for i in ins:
                succ.setdefault((inst, "in:" + i), []).append((inst, out))
    cycle = _find_cycle(succ)
    if cycle and not allow_loops:
        names = " -> ".join(f"{i}.{v.removeprefix('in:')}" for i, v in cycle)
        raise SystemSpecError(f"algebraic loop through direct-feedthrough FMUs: {names}; "
                              "use the Jacobi master (--master jacobi) to co-simulate it")
    fed = {inst for inst in instances if any(ft[inst].values())}
    free = tuple(i for i in instances if i not in fed)
    # instance graph among feedthrough FMUs: producer -> consumer over feedthrough inputs
    deps = {i: {driven[(i, x)].source for x in {y for ys in ft[i].values() for y in ys}
                if (i, x) in driven} & fed for i in fed}
    chained: list[str] = []
    while len(chained) < len(fed):
        ready = [i for i in instances if i in fed and i not in chained
                 and deps[i] <= set(chained) | {i}]
        if not ready:  # a loop (Jacobi asked for): keep the declared order for the rest
            chained += [i for i in instances if i in fed and i not in chained]
            break
        chained.append(ready[0])
    return Order(free, tuple(chained))


def _find_cycle(succ: Mapping[tuple[str, str], list[tuple[str, str]]]) -> list[tuple[str, str]]:
    """One cycle of the variable graph (a list of nodes), or []."""
    color: dict[tuple[str, str], int] = {}
    stack: list[tuple[str, str]] = []

    def visit(n: tuple[str, str]) -> list[tuple[str, str]]:
        color[n] = 1
        stack.append(n)
        for m in succ.get(n, []):
            if color.get(m) == 1:
                return stack[stack.index(m):] + [m]
            if m not in color:
                found = visit(m)
                if found:
                    return found
        color[n] = 2
        stack.pop()
        return []

    for n in list(succ):
        if n not in color:
            found = visit(n)
            if found:
                return found
    return []
