"""Write a :class:`~.description.System` as an SSP 1.0 file, and the hover system of the project.

The archive holds ``SystemStructure.ssd`` (one component per instance with its Real, Integer
and Boolean input/output connectors, the connections, a DefaultExperiment), each FMU once under
``resources/`` and, per instance with parameter values, ``resources/<instance>.ssv`` bound to
its component (SSP 1.0 ParameterBinding; names are the FMU's variable names). It is read back
by :meth:`System.from_ssp`, fmpy's ``read_ssd`` (which validates it against the SSP schema) and
libcosim. Zip entries have fixed timestamps: the same system gives the same bytes.
"""

from __future__ import annotations

from pathlib import Path
from typing import Mapping, Sequence
from xml.etree import ElementTree as ET

from ...core.files import write_zip
from ...models import lateral, longitudinal
from .fmi3 import read_view
from .system import System, SystemSpecError

__all__ = ["HOVER", "HOVER_6DOF", "HOVER_6DOF_FMUS", "HOVER_FMUS", "SSC_NS", "SSD_NS", "SSV_NS",
           "hover_system", "write_system_ssp", "xml_bytes"]

#: the XML namespaces of SSP 1.0's system structure, common types and parameter values
SSD_NS = "http://ssp-standard.org/SSP1/SystemStructureDescription"
SSC_NS = "http://ssp-standard.org/SSP1/SystemStructureCommon"
SSV_NS = "http://ssp-standard.org/SSP1/SystemStructureParameterValues"
ET.register_namespace("ssd", SSD_NS)
ET.register_namespace("ssc", SSC_NS)
ET.register_namespace("ssv", SSV_NS)
_SSD, _SSC, _SSV = SSD_NS, SSC_NS, SSV_NS

HOVER = "DroneFlyHover"
HOVER_6DOF = "DroneFlyHover6DOF"
#: instance -> model of the hover system: both axes, each with its controller
HOVER_FMUS = {"lateral": "DroneFlyLateral", "lateral_controller": "StateFeedback",
              "longitudinal": "DroneFlyLongitudinal",
              "longitudinal_controller": "StateFeedbackLongitudinal"}
#: the same with the six-degree-of-freedom plant in place of both linear ones
HOVER_6DOF_FMUS = {"plant": "DroneFlyHover6DOF", "lateral_controller": "StateFeedback",
                   "longitudinal_controller": "StateFeedbackLongitudinal"}


#: the SSP 1.0 connector type of each variable type (FMI 3.0: Float64 and Float32 read as Real;
#: the integer types that fit SSP's 32-bit Integer)
_SSP_TYPES = {"Real": "Real", "Integer": "Integer", "Boolean": "Boolean",
              **{t: "Integer" for t in ("Int8", "UInt8", "Int16", "UInt16", "Int32")}}


def xml_bytes(root: ET.Element) -> bytes:
    """An SSP XML document as UTF-8 bytes: indented, with its declaration."""
    ET.indent(root, space="  ")
    return ET.tostring(root, encoding="utf-8", xml_declaration=True) + b"\n"


def _ssv_type(value: object) -> tuple[str, str]:
    if isinstance(value, bool):
        return "Boolean", "true" if value else "false"
    if isinstance(value, int):
        return "Integer", str(value)
    if isinstance(value, str):
        return "String", value
    return "Real", repr(float(value))  # type: ignore[arg-type]


def write_system_ssp(system: System, path: str | Path, *, description: str = "",
                     stop_s: float | None = None) -> Path:
    """Write ``system`` as an SSP 1.0 archive at ``path`` and return the path.

    Raises
    ------
    SystemSpecError
        An instance name that SSP cannot use as a file name, or a value of another type.
    """
    root = ET.Element(f"{{{_SSD}}}SystemStructureDescription",
                      {"version": "1.0", "name": system.name})
    attrs = {"name": system.name}
    if description:
        attrs["description"] = description
    sys_el = ET.SubElement(root, f"{{{_SSD}}}System", attrs)
    elements = ET.SubElement(sys_el, f"{{{_SSD}}}Elements")
    files: dict[str, bytes] = {}
    sources: dict[bytes, str] = {}  # FMU content -> its entry, each FMU stored once
    for inst, fmu in system.fmus.items():
        if not inst.isidentifier():
            raise SystemSpecError(f"instance name {inst!r} must be an identifier")
        data = Path(fmu).read_bytes()
        entry = sources.setdefault(data, f"resources/{Path(fmu).name}")
        if files.get(entry, data) != data:
            raise SystemSpecError(f"two different FMUs are named {Path(fmu).name!r}")
        files[entry] = data
        comp = ET.SubElement(elements, f"{{{_SSD}}}Component", {
            "name": inst, "source": entry, "type": "application/x-fmu-sharedlibrary"})
        ports = [(v.name, v.causality, _SSP_TYPES[v.type]) for v in read_view(fmu).modelVariables
                 if v.causality in ("input", "output") and v.type in _SSP_TYPES]
        if ports:  # the schema wants a Connector in Connectors: none without
            connectors = ET.SubElement(comp, f"{{{_SSD}}}Connectors")
            for name, kind, ssp_type in ports:
                con = ET.SubElement(connectors, f"{{{_SSD}}}Connector",
                                    {"name": name, "kind": kind})
                ET.SubElement(con, f"{{{_SSC}}}{ssp_type}")
        values = system.parameters.get(inst)
        if values:
            bindings = ET.SubElement(comp, f"{{{_SSD}}}ParameterBindings")
            ET.SubElement(bindings, f"{{{_SSD}}}ParameterBinding",
                          {"source": f"resources/{inst}.ssv"})
            files[f"resources/{inst}.ssv"] = _ssv(inst, values)
    if system.connections:  # the schema wants a Connection in Connections: none without
        connections = ET.SubElement(sys_el, f"{{{_SSD}}}Connections")
        for c in system.connections:
            ET.SubElement(connections, f"{{{_SSD}}}Connection", {
                "startElement": c.source, "startConnector": c.output,
                "endElement": c.target, "endConnector": c.input})
    stop = system.stop_s if stop_s is None else stop_s
    if stop is not None:
        ET.SubElement(root, f"{{{_SSD}}}DefaultExperiment",
                      {"startTime": repr(float(system.start_s)), "stopTime": repr(float(stop))})
    files["SystemStructure.ssd"] = xml_bytes(root)
    return write_zip(Path(path), files)


def _ssv(name: str, values: Mapping[str, object]) -> bytes:
    pset = ET.Element(f"{{{_SSV}}}ParameterSet", {"version": "1.0", "name": name})
    plist = ET.SubElement(pset, f"{{{_SSV}}}Parameters")
    for key, value in values.items():
        kind, text = _ssv_type(value)
        p = ET.SubElement(plist, f"{{{_SSV}}}Parameter", {"name": key})
        ET.SubElement(p, f"{{{_SSV}}}{kind}", {"value": text})
    return xml_bytes(pset)


def hover_system(fmus: Mapping[str, str | Path],
                 x0_lateral: Sequence[float] = (0.0, 0.0, 0.0, 0.1),
                 x0_longitudinal: Sequence[float] = (0.0, 0.0, 0.0, 0.1),
                 stop_wingbeats: float = 300.0, nonlinear: bool = False) -> System:
    """Both axes of the hovering drone fly with their controllers.

    Parameters
    ----------
    fmus : mapping
        Model name (``DroneFlyLateral``, ``StateFeedback``, ``DroneFlyLongitudinal``,
        ``StateFeedbackLongitudinal``, ``DroneFlyHover6DOF``) -> FMU path.
    x0_lateral, x0_longitudinal : sequence of 4 floats
        Initial non-dimensional states x+ of the two axes (default: a 0.1 rad roll and a
        0.1 rad pitch disturbance).
    stop_wingbeats : float
        Stop time of the SSP's DefaultExperiment, in wing beats.
    nonlinear : bool
        The six-degree-of-freedom plant (instance ``plant``) in place of the two linear ones
        (:data:`HOVER_6DOF_FMUS`): three FMUs, the same controllers.
    """

    models = HOVER_6DOF_FMUS if nonlinear else HOVER_FMUS
    missing = [m for m in models.values() if m not in fmus]
    if missing:
        raise SystemSpecError(f"the hover system needs the FMUs {', '.join(missing)}")
    paths = {inst: Path(fmus[model]) for inst, model in models.items()}
    params: dict[str, dict[str, object]] = {}
    for inst, axis, x0 in (("lateral", lateral.LATERAL, x0_lateral),
                           ("longitudinal", longitudinal.LONGITUDINAL, x0_longitudinal)):
        scale = axis.scale_vector(lateral.U_M_PER_S, lateral.N_HZ)
        params.setdefault("plant" if nonlinear else inst, {}).update(
            {f"{s}_start": float(v) * k for s, v, k in zip(axis.state_names, x0, scale)})
    system = System.by_name(paths, parameters=params, name=HOVER_6DOF if nonlinear else HOVER)
    system.stop_s = stop_wingbeats / lateral.N_HZ
    return system
