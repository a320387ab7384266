"""modelDescription.xml (FMI 3.0) of an FMI 3.0 slave class (:func:`dronefly.fmi.base3.fmi3_class`).

Generated at build time from the same variable table as the FMI 2.0 one
(:mod:`dronefly.harness.builder.modeldescription`), replacing pythonfmu3's: the independent variable
``time``, 2-D Float64 arrays with ``<Dimension>``, units and display units, descriptions,
explicit variability, and a ModelStructure whose ``Output`` and ``InitialUnknown``
elements list their dependencies by value reference (``""`` = none; an array depends on
the union of what its elements depend on).
"""

from __future__ import annotations

from typing import Any
from xml.dom.minidom import parseString
from xml.etree.ElementTree import Element, SubElement, tostring

from ...fmi.table3 import Var3, array_dependencies
from .entry import HOST_REQUIREMENT
from .modeldescription import add_units_and_log_categories, format_value

__all__ = ["model_description3", "model_description3_bytes"]

_TYPES = {"Real": "Float64", "Boolean": "Boolean", "Integer": "Int32"}


def _deps(cls: Any, entry: Var3, initial: bool) -> tuple[int, ...] | None:
    rows = [cls.VARIABLES[k] for k in entry.indices]
    return array_dependencies(cls.TABLE3, cls.VARIABLES,
                              [v.initial_dependencies if initial else v.dependencies
                               for v in rows])


def _variable(parent: Element, vr: int, e: Var3, cls: Any) -> None:
    v = e.var
    attrs = {"name": e.name, "valueReference": str(vr), "description": e.description,
             "causality": v.causality, "variability": v.variability}
    if v.initial is not None:
        attrs["initial"] = v.initial
    starts = [cls.VARIABLES[k].start for k in e.indices]
    if starts and all(s is not None for s in starts):
        attrs["start"] = " ".join(format_value(s) for s in starts)
    if v.type == "Real" and v.unit is not None:
        attrs["unit"] = v.unit
        if v.display_unit is not None:
            attrs["displayUnit"] = v.display_unit
    node = SubElement(parent, _TYPES[v.type], attrs)
    for d in e.dims:
        SubElement(node, "Dimension", {"start": str(d)})


def model_description3(cls: Any, token: str) -> Element:
    """The FMI 3.0 modelDescription of an FMI 3.0 slave class."""
    root = Element("fmiModelDescription", {
        "fmiVersion": "3.0",
        "modelName": cls.MODEL_NAME,
        "instantiationToken": token,
        "description": f"{cls.MODEL_DESCRIPTION.rstrip('.')}. {HOST_REQUIREMENT}",
        "generationTool": cls.GENERATION_TOOL,
        "variableNamingConvention": "structured",
    })
    SubElement(root, "CoSimulation", {
        "modelIdentifier": cls.MODEL_NAME,
        "needsExecutionTool": "true",  # a CPython 3 (stdlib; numpy: the flapping plant)
        "canBeInstantiatedOnlyOncePerProcess": "false",
        "canGetAndSetFMUState": "true",
        "canSerializeFMUState": "true",
        "providesDirectionalDerivatives": "false",
        "providesAdjointDerivatives": "false",
        "providesPerElementDependencies": "false",
        "canHandleVariableCommunicationStepSize": "true",
        "hasEventMode": "false",
        "canReturnEarlyAfterIntermediateUpdate": "false",
        "providesIntermediateUpdate": "false",
    })
    table = cls.TABLE3
    add_units_and_log_categories(
        root, cls, {e.var.unit for e in table if e.var.type == "Real" and e.var.unit is not None},
        fmi="fmi3")
    start, stop, step = cls.DEFAULT_EXPERIMENT
    SubElement(root, "DefaultExperiment", {
        "startTime": repr(start), "stopTime": repr(stop), "stepSize": repr(step)})
    mv = SubElement(root, "ModelVariables")
    for vr, e in enumerate(table):
        _variable(mv, vr, e, cls)
    ms = SubElement(root, "ModelStructure")
    for vr, e in enumerate(table):
        if e.var.causality == "output":
            _unknown(ms, "Output", vr, _deps(cls, e, initial=False))
    for vr, e in enumerate(table):
        v = e.var
        if (v.causality == "output" and v.initial in ("approx", "calculated")) \
                or v.causality == "calculatedParameter":
            _unknown(ms, "InitialUnknown", vr, _deps(cls, e, initial=True))
    return root


def _unknown(parent: Element, tag: str, vr: int, deps: tuple[int, ...] | None) -> None:
    a = {"valueReference": str(vr)}
    if deps is not None:  # None: depends on all knowns, the attribute is omitted
        a["dependencies"] = " ".join(str(d) for d in deps)
    SubElement(parent, tag, a)


def model_description3_bytes(cls: Any, token: str) -> bytes:
    """Deterministic, pretty-printed modelDescription.xml."""

    return parseString(tostring(model_description3(cls, token), "utf-8")).toprettyxml(
        indent="  ", encoding="UTF-8")
