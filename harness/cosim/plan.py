"""The buffers and the calls of one communication step of :class:`~.master.SystemMaster`.

Every Real output that a connection or the record needs lies in one ctypes buffer; each
instance's inputs read it in place where they lie in order (no copy), else through a gather.
The other recorded variables (parameters, locals, Integer and Boolean ones...) follow the
outputs in that buffer (:func:`record_ops`); a recorded input that a Real output drives is
that output's place in the buffer (no call), one that an Integer or Boolean output drives is
read as that output, an unconnected one as itself. The calls of a step are planned once per run as
:data:`Op` tuples (instance, FMI call, function, arguments), so that a failed call names its
instance and call.
"""

from __future__ import annotations

from ctypes import c_double, c_int, c_uint
from typing import Any, Container, Mapping, Sequence

import numpy as np

from .system import Connection, SystemSpecError

__all__ = ["RECORDABLE", "Node", "Op", "build_nodes", "gather", "get_ops", "put_ops", "record_ops",
           "split_sources", "start_ops"]


class Node:
    """One instance's buffers: its Real outputs, and where each of its inputs comes from.

    Parameters
    ----------
    name : str
        The instance name.
    fmu : FMU
        The instance's FMU (:class:`~dronefly.harness.cosim.fmu.FMU`).
    outputs : list of str
        The Real outputs to read at every communication point.
    """

    def __init__(self, name: str, fmu: Any, outputs: list[str]) -> None:
        self.name, self.fmu = name, fmu
        self.types = {v.name: v.type for v in fmu.model_description.modelVariables}
        self.out_names = outputs
        self.out_vr = (c_uint * len(outputs))(*[fmu.vr(n) for n in outputs])
        self.out = (c_double * len(outputs))()
        self.at = 0  # where ``out`` starts in the buffer of every output (see ``place``)
        self.in_real: list[tuple[int, "Node", int]] = []  # (vr, source node, source index)
        self.in_other: list[tuple[str, int, "Node", int]] = []  # (type, vr, node, index)
        self.extra: dict[str, list[str]] = {}  # other recorded variables by getter type
        self.inst: Any = None

    def place(self, every_out: Any, at: int) -> None:
        """Make ``out`` a view of ``every_out`` from ``at`` on (one buffer for all outputs)."""
        self.at = at
        self.out = (c_double * len(self.out_names)).from_buffer(every_out, 8 * at)

    def finish(self, every_out: Any) -> None:
        """Input buffers; inputs that are one run of ``every_out`` read it in place (no copy)."""
        real = sorted(self.in_real, key=lambda r: r[1].at + r[2])
        where = [node.at + i for _, node, i in real]
        if where and where == list(range(where[0], where[0] + len(where))):
            self.in_real = real
            self.in_buf = (c_double * len(real)).from_buffer(every_out, 8 * where[0])
            self.in_src: list[tuple[Any, int]] = []
        else:
            self.in_buf = (c_double * len(self.in_real))()
            self.in_src = [(node.out, i) for _, node, i in self.in_real]
        self.in_vr = (c_uint * len(self.in_real))(*[vr for vr, _, _ in self.in_real])


#: one call of a step: (instance node, FMI call named on failure, function, arguments)
Op = tuple[Node, str, Any, tuple]


#: variable types that can be recorded or connected, and the FMI getter of each (Integer
#: ones into 32-bit ints: FMI 3.0's integer types up to Int32, read through the adapter)
RECORDABLE = {"Real": "Real", "Integer": "Integer", "Enumeration": "Integer",
              "Boolean": "Boolean",
              **{t: "Integer" for t in ("Int8", "UInt8", "Int16", "UInt16", "Int32")}}


def build_nodes(fmus: Mapping[str, Any], connections: Sequence[Connection],
                names: Sequence[str]) -> tuple[dict[str, Node], Any, list[int]]:
    """The nodes of every instance, the buffer of every value they read, and where each of
    ``names`` lies in that buffer.

    The buffer holds the Real outputs that connections or ``names`` need, then the other
    recorded variables (``Node.extra``: parameters, calculated parameters, locals, Integer
    and Boolean variables, unconnected inputs), read by :func:`record_ops`. A connected
    input is recorded as its source output (the value set for the step from each point):
    a Real one from the source's place in the buffer, an Integer or Boolean one read as
    the source's variable.

    Raises
    ------
    SystemSpecError
        A name to record that is not ``instance.name`` of a Real, Integer or Boolean variable.
    """
    wanted: dict[str, list[str]] = {i: [] for i in fmus}
    extra: dict[str, dict[str, list[str]]] = {i: {} for i in fmus}
    for c in connections:
        if fmus[c.source].variables[c.output].type == "Real" and \
                c.output not in wanted[c.source]:
            wanted[c.source].append(c.output)
    driven = {(c.target, c.input): c for c in connections}
    alias: dict[str, str] = {}  # recorded input -> the source output read for it
    for full in names:
        inst, _, var = full.partition(".")
        if inst not in fmus:
            raise SystemSpecError(f"cannot record {full!r}: no instance {inst!r} (instances: "
                                  f"{', '.join(fmus)})")
        v = fmus[inst].variables.get(var)
        if v is None or v.type not in RECORDABLE:
            raise SystemSpecError(f"cannot record {full!r}: " + (
                f"{inst} has no variable {var!r}" if v is None else
                f"a {v.type} variable (Real, Integer and Boolean ones can be recorded)"))
        c = driven.get((inst, var))
        if c is not None:  # the value the source gives it: read with the point's outputs
            alias[full] = f"{c.source}.{c.output}"
            inst, var = c.source, c.output
            v = fmus[inst].variables[var]
        if v.causality == "output" and v.type == "Real":
            if var not in wanted[inst]:
                wanted[inst].append(var)
        elif var not in extra[inst].setdefault(RECORDABLE[v.type], []):
            extra[inst][RECORDABLE[v.type]].append(var)
    nodes = {i: Node(i, f, wanted[i]) for i, f in fmus.items()}
    for c in connections:
        src, dst = nodes[c.source], nodes[c.target]
        kind = RECORDABLE.get(src.types[c.output])
        vr = dst.fmu.vr(c.input)
        if kind is None:
            raise SystemSpecError(f"connection {c}: a {src.types[c.output]} connection, which "
                                  "the master cannot carry (Real, Integer, Boolean, and FMI "
                                  "3.0 integers up to Int32)")
        if kind == "Real":
            dst.in_real.append((vr, src, src.out_names.index(c.output)))
        else:
            dst.in_other.append((kind, vr, src, src.fmu.vr(c.output)))
    n_out = sum(len(n.out_names) for n in nodes.values())
    at = {}  # recorded variable -> its place in the buffer
    for kind in ("Real", "Integer", "Boolean"):  # Real extras first, the ints in one run
        for i, n in nodes.items():
            for var in extra[i].get(kind, []):
                n.extra.setdefault(kind, []).append(var)
                at[f"{i}.{var}"] = n_out + len(at)
    every_out = (c_double * (n_out + len(at)))()
    k = 0
    for n in nodes.values():
        n.place(every_out, k)
        k += len(n.out_names)
    for n in nodes.values():
        n.finish(every_out)
    where = []
    for full in names:
        key = alias.get(full, full)
        inst, _, var = key.partition(".")
        where.append(at[key] if key in at else nodes[inst].at + nodes[inst].out_names.index(var))
    return nodes, every_out, where


def record_ops(nodes: Mapping[str, Node], every_out: Any) -> list[Op]:
    """Read the recorded variables that are not Real outputs into their places in the
    buffer (Integer and Boolean ones through an int buffer, converted by a last copy).

    Only gets: the master reads them together with the point's outputs, before the inputs
    of the next step are set (and sets nothing more at the last point)."""

    ops: list[Op] = []
    base = sum(len(n.out_names) for n in nodes.values())
    reals = sum(len(n.extra.get("Real", [])) for n in nodes.values())
    ints = (c_int * (sum(len(v) for n in nodes.values() for v in n.extra.values()) - reals))()
    k = {"Real": base, "Integer": 0, "Boolean": 0}
    for kind in ("Real", "Integer", "Boolean"):
        for n in nodes.values():
            names = n.extra.get(kind, [])
            if not names:
                continue
            s, vrs = n.inst.slave, [n.fmu.vr(v) for v in names]
            if kind == "Real":
                buf = (c_double * len(names)).from_buffer(every_out, 8 * k["Real"])
            else:
                buf = (c_int * len(names)).from_buffer(ints, 4 * (k["Integer"] + k["Boolean"]))
            if kind == "Real" and n.fmu.fmi_version == 3 and any(
                    vr in n.fmu.elements for vr in vrs):  # FMI 3.0 array elements
                ops.append((n, "fmi3GetFloat64", _elements, (s, vrs, buf)))
            else:
                ops.append((n, f"fmi2Get{kind}", getattr(s, f"fmi2Get{kind}"),
                            (s.component, (c_uint * len(names))(*vrs), len(names), buf)))
            k[kind] += len(names)
    if len(ints):
        dst = np.frombuffer(every_out, dtype=np.float64)[base + reals:]
        src = np.frombuffer(ints, dtype=np.int32)
        first = next(iter(nodes.values()))
        ops.append((first, "recording", np.copyto, (dst, src)))
    return ops


def get_ops(n: Node) -> list[Op]:
    """Read the node's Real outputs into its part of the output buffer."""
    s = n.inst.slave
    return [(n, "fmi2GetReal", s.fmi2GetReal, (s.component, n.out_vr, len(n.out), n.out))
            ] if len(n.out) else []


def _other_ops(n: Node, ready: Container[str] | None = None) -> list[Op]:
    s, ops = n.inst.slave, []
    for kind, vr, src, svr in n.in_other:
        if ready is not None and src.name not in ready:
            continue
        value = (c_int * 1)()  # fmi2Integer and fmi2Boolean are both int
        ss = src.inst.slave
        ops.append((src, f"fmi2Get{kind}", getattr(ss, f"fmi2Get{kind}"),
                    (ss.component, (c_uint * 1)(svr), 1, value)))
        ops.append((n, f"fmi2Set{kind}", getattr(s, f"fmi2Set{kind}"),
                    (s.component, (c_uint * 1)(vr), 1, value)))
    return ops


def split_sources(ops: Sequence[Op]) -> tuple[list[Op], list[Op]]:
    """The gets of :func:`put_ops` calls (the Integer and Boolean source outputs of the
    connections) and the rest (the sets), in order: a Jacobi master reads the sources with
    the point's outputs, before any input is set."""
    gets = [op for op in ops if op[1].startswith("fmi2Get")]
    return gets, [op for op in ops if not op[1].startswith("fmi2Get")]


def put_ops(n: Node) -> list[Op]:
    """Set the node's inputs from their sources' outputs."""
    s, ops = n.inst.slave, []
    if n.in_src:  # inputs from scattered outputs: copied first
        ops.append((n, "fmi2SetReal", gather, (n.in_buf, n.in_src)))
    if len(n.in_buf):
        ops.append((n, "fmi2SetReal", s.fmi2SetReal,
                    (s.component, n.in_vr, len(n.in_buf), n.in_buf)))
    return ops + _other_ops(n)


def start_ops(n: Node, given: Mapping[str, float] | None, connected: bool = True,
              ready: Container[str] | None = None) -> list[Op]:
    """:func:`put_ops` for initialization (only ``given`` if not ``connected``): the Real
    inputs in ``given`` take these values instead of their sources' (connected or not), in
    one fmi2SetReal with the other Real inputs. Inputs whose source instance is not in
    ``ready`` (not yet initialized: later in an algebraic loop) keep their start or given
    value."""
    late = ready is not None and any(
        src.name not in ready for src in [*(r[1] for r in n.in_real), *(o[2] for o in n.in_other)])
    if not given and not late:
        return put_ops(n) if connected else []
    s = n.inst.slave
    fixed = {n.fmu.vr(name): float(v) for name, v in (given or {}).items()}
    real = [r for r in n.in_real if ready is None or r[1].name in ready] if connected else []
    vrs = [vr for vr, _, _ in real]
    src = [(node.out, i) for _, node, i in real]
    vrs += [vr for vr in fixed if vr not in vrs]
    buf = (c_double * len(vrs))()

    def fill() -> None:
        buf[:] = [fixed[vr] if vr in fixed else src[k][0][src[k][1]]
                  for k, vr in enumerate(vrs)]

    others = _other_ops(n, ready) if connected else []
    if not vrs:
        return others
    return [(n, "fmi2SetReal", fill, ()),
            (n, "fmi2SetReal", s.fmi2SetReal, (s.component, (c_uint * len(vrs))(*vrs),
                                                len(vrs), buf)), *others]


def _elements(slave: Any, vrs: list[int], buf: Any) -> None:
    buf[:] = slave.getReal(vrs)


def gather(buf: Any, src: list[tuple[Any, int]]) -> None:
    """Copy the values of inputs whose sources are not one run of the outputs into ``buf``."""
    buf[:] = [b[i] for b, i in src]
