"""modelDescription.xml of a :class:`dronefly.fmi.SlaveBase` subclass.

Generated at build time from the variable table; not shipped inside the FMUs.
Element order, attributes and ModelStructure follow the FMI 2.0 standard (see
the compliance notes): UnitDefinitions with base-unit exponents and display
units, explicit variability on parameters, Outputs with their dependencies
(``""`` = no direct feedthrough) and complete InitialUnknowns.
"""

from __future__ import annotations

from xml.dom.minidom import parseString
from xml.etree.ElementTree import Element, SubElement, tostring

from ...fmi import SlaveBase
from .entry import HOST_REQUIREMENT

__all__ = ["add_units_and_log_categories", "format_value", "model_description",
           "model_description_bytes"]


def format_value(value: float | bool | int) -> str:
    """A start value as the model description writes it (repr-exact floats, true/false,
    integers as integers)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    return repr(float(value))


def add_units_and_log_categories(root: Element, cls: type[SlaveBase], used: set[str],
                                 fmi: str = "fmi2") -> None:
    """``UnitDefinitions`` (SI base-unit exponents, display units) of the units in ``used``,
    then ``LogCategories`` (their descriptions name the calls of FMI version ``fmi``)."""
    units = SubElement(root, "UnitDefinitions")
    for name in sorted(used):
        exps, displays = cls.UNITS[name]
        unit = SubElement(units, "Unit", {"name": name})
        SubElement(unit, "BaseUnit", {k: str(e) for k, e in exps.items()})
        for dname, factor in displays.items():
            SubElement(unit, "DisplayUnit", {"name": dname, "factor": repr(factor)})
    cats = SubElement(root, "LogCategories")
    for name, text in cls.log_categories.items():
        SubElement(cats, "Category", {"name": name, "description": text.replace("fmi2", fmi)})


def _dependency_indices(cls: type[SlaveBase], names: tuple[str, ...]) -> str:
    index = {v.name: i + 1 for i, v in enumerate(cls.VARIABLES)}
    return " ".join(str(index[n]) for n in sorted(names, key=index.__getitem__))


def model_description(cls: type[SlaveBase], guid: str) -> Element:
    """The FMI 2.0 modelDescription of a :class:`SlaveBase` subclass."""
    root = Element("fmiModelDescription", {
        "fmiVersion": "2.0",
        "modelName": cls.MODEL_NAME,
        "guid": guid,
        "description": f"{cls.MODEL_DESCRIPTION.rstrip('.')}. {HOST_REQUIREMENT}",
        "generationTool": cls.GENERATION_TOOL,
        "variableNamingConvention": "structured",
        "numberOfEventIndicators": "0",
    })
    SubElement(root, "CoSimulation", {
        "modelIdentifier": cls.MODEL_NAME,
        "needsExecutionTool": "true",  # a CPython 3 (stdlib; numpy: the flapping plant)
        "canHandleVariableCommunicationStepSize": "true",
        "canInterpolateInputs": "false",
        "maxOutputDerivativeOrder": "0",
        "canRunAsynchronuously": "false",
        "canBeInstantiatedOnlyOncePerProcess": "false",
        "canNotUseMemoryManagementFunctions": "true",
        "canGetAndSetFMUstate": "true",
        "canSerializeFMUstate": "true",
        "providesDirectionalDerivative": "false",
    })
    add_units_and_log_categories(root, cls, {v.unit for v in cls.VARIABLES if v.unit is not None})
    start, stop, step = cls.DEFAULT_EXPERIMENT
    SubElement(root, "DefaultExperiment", {
        "startTime": repr(start), "stopTime": repr(stop), "stepSize": repr(step)})
    mv = SubElement(root, "ModelVariables")
    for i, v in enumerate(cls.VARIABLES):
        attrs = {"name": v.name, "valueReference": str(i), "description": v.description,
                 "causality": v.causality, "variability": v.variability}
        if v.initial is not None:
            attrs["initial"] = v.initial
        sv = SubElement(mv, "ScalarVariable", attrs)
        tattrs: dict[str, str] = {}
        if v.type == "Real" and v.unit is not None:
            tattrs["unit"] = v.unit
            if v.display_unit is not None:
                tattrs["displayUnit"] = v.display_unit
        if v.start is not None:
            tattrs["start"] = format_value(v.start)
        SubElement(sv, v.type, tattrs)
    ms = SubElement(root, "ModelStructure")
    outputs = [(i, v.dependencies) for i, v in enumerate(cls.VARIABLES) if v.causality == "output"]
    _unknowns(cls, ms, "Outputs", outputs)
    initial = [(i, v.initial_dependencies) for i, v in enumerate(cls.VARIABLES)
               if (v.causality == "output" and v.initial in ("approx", "calculated"))
               or v.causality == "calculatedParameter"]
    _unknowns(cls, ms, "InitialUnknowns", initial)
    return root


def _unknowns(cls: type[SlaveBase], parent: Element, tag: str,
              items: list[tuple[int, tuple[str, ...] | None]]) -> None:
    """``<tag><Unknown index=.. dependencies=../>...`` (no element when there are none)."""
    if not items:
        return
    node = SubElement(parent, tag)
    for i, deps in items:
        a = {"index": str(i + 1)}
        if deps is not None:  # None: depends on all knowns, the attribute is omitted
            a["dependencies"] = _dependency_indices(cls, deps)
        SubElement(node, "Unknown", a)


def model_description_bytes(cls: type[SlaveBase], guid: str) -> bytes:
    """Deterministic, pretty-printed modelDescription.xml."""

    return parseString(tostring(model_description(cls, guid), "utf-8")).toprettyxml(
        indent="  ", encoding="UTF-8")
