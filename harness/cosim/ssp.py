"""Write a :class:`~.system.System` as an SSP 1.0 file, and the systems of the project: the
hover system (both axes) and the flapping insect's lateral loop.

The archive holds ``SystemStructure.ssd`` (one component per instance with its Real, Integer
and Boolean input/output connectors, the connections, a DefaultExperiment), each FMU once under
``resources/`` and, per instance with parameter values, ``resources/<instance>.ssv`` bound to
its component (SSP 1.0 ParameterBinding; names are the FMU's variable names). It is read back
by :meth:`System.from_ssp`, fmpy's ``read_ssd`` (which validates it against the SSP schema) and
libcosim. Zip entries have fixed timestamps: the same system gives the same bytes.
"""

from __future__ import annotations

from pathlib import Path
import math
from typing import Mapping, Sequence
from xml.etree import ElementTree as ET

import numpy as np

from ...core.files import write_zip
from ...models import lateral_interface, longitudinal_interface
from ...models.feedback import PAPER_GAINS_EQ27
from ...models.flapping import orbit_start
from .fmu3 import read_view
from .system import System, SystemSpecError

__all__ = ["FLAPPING", "FLAPPING_FMUS", "HOVER", "HOVER_6DOF", "HOVER_6DOF_FMUS", "HOVER_FMUS",
           "SSC_NS", "SSD_NS", "SSV_NS", "flapping_starts", "flapping_system", "hover_system",
           "write_system_ssp", "xml_bytes"]

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
FLAPPING = "DroneFlyFlappingLateral"
#: instance -> model of the flapping insect's lateral loop: the wing-beat-resolved plant and the
#: lateral controller; the plant's four longitudinal controls are left unconnected (they keep
#: their start values, 0: the averaged trim's kinematics)
FLAPPING_FMUS = {"plant": "DroneFlyFlapping", "lateral_controller": "StateFeedback"}


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
                     stop_s: float | None = None, entries: Mapping[str, str] | None = None,
                     connector_types: Sequence[str] = ("Real", "Integer", "Boolean")) -> Path:
    """Write ``system`` as an SSP 1.0 archive at ``path`` and return the path: the project's
    one SSP writer (:meth:`System.from_ssp` is its reader).

    Parameters
    ----------
    system : System
        The FMUs, connections and parameter values; an instance named in
        ``system.parameters`` gets a ParameterBinding and its ``.ssv`` even if it binds no value.
    path : str or Path
        The archive to write.
    description : str
        The System element's description.
    stop_s : float, optional
        The DefaultExperiment's stop time, s (default ``system.stop_s``; none if both None).
    entries : mapping, optional
        Instance -> the FMU's file name under ``resources/`` (default: the file's own name).
    connector_types : sequence of str
        The SSP connector types (``Real``, ``Integer``, ``Boolean``) written as connectors.

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
        file_name = (entries or {}).get(inst, Path(fmu).name)
        entry = sources.setdefault(data, f"resources/{file_name}")
        if files.get(entry, data) != data:
            raise SystemSpecError(f"two different FMUs are named {file_name!r}")
        files[entry] = data
        comp = ET.SubElement(elements, f"{{{_SSD}}}Component", {
            "name": inst, "source": entry, "type": "application/x-fmu-sharedlibrary"})
        ports = [(v.name, v.causality, _SSP_TYPES[v.type]) for v in read_view(fmu).modelVariables
                 if v.causality in ("input", "output")
                 and _SSP_TYPES.get(v.type) in connector_types]
        if ports:  # the schema wants a Connector in Connectors: none without
            connectors = ET.SubElement(comp, f"{{{_SSD}}}Connectors")
            for name, kind, ssp_type in ports:
                con = ET.SubElement(connectors, f"{{{_SSD}}}Connector",
                                    {"name": name, "kind": kind})
                ET.SubElement(con, f"{{{_SSC}}}{ssp_type}")
        values = system.parameters.get(inst)
        if values is not None:
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


def _system(fmus: Mapping[str, str | Path], models: Mapping[str, str],
            params: dict[str, dict[str, object]], name: str, stop_wb: float) -> System:
    """The instances ``models`` of the FMU files ``fmus`` (by model name), connected by name
    (:meth:`System.by_name`: an input no other instance provides stays unconnected), with
    ``params`` and a DefaultExperiment stop time of ``stop_wb`` wing beats."""
    missing = [m for m in models.values() if m not in fmus]
    if missing:
        raise SystemSpecError(f"the {name} system needs the FMUs {', '.join(missing)}")
    paths = {inst: Path(fmus[model]) for inst, model in models.items()}
    system = System.by_name(paths, parameters=params, name=name)
    system.stop_s = stop_wb / lateral_interface.N_HZ
    return system


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
    params: dict[str, dict[str, object]] = {}
    for inst, axis, x0 in (("lateral", lateral_interface.LATERAL, x0_lateral),
                           ("longitudinal", longitudinal_interface.LONGITUDINAL, x0_longitudinal)):
        scale = axis.scale_vector(lateral_interface.U_M_PER_S, lateral_interface.N_HZ)
        params.setdefault("plant" if nonlinear else inst, {}).update(
            {f"{s}_start": float(v) * k for s, v, k in zip(axis.state_names, x0, scale)})
    return _system(fmus, models, params, HOVER_6DOF if nonlinear else HOVER, stop_wingbeats)


def flapping_starts(z: Sequence[float], roll0_rad: float = 0.0) -> dict[str, float]:
    """The ``*_start`` parameters (SI) of ``DroneFlyFlapping`` (and ``DroneFlyHover6DOF``)
    that start it at a reduced state with a roll added (heading and position 0).

    Parameters
    ----------
    z : sequence of 8 floats
        (u+, v+, w+, p+, q+, r+, phi, theta): velocities over U, rates times t_w, angles [rad].
    roll0_rad : float
        Added to the roll angle phi [rad].

    The FMU takes the attitude as delta_gamma_start and delta_theta_start (gamma =
    asin(sin phi cos theta), the paper's roll angle;
    :func:`dronefly.models.rigid_body.initial_state` inverts it): the same attitude to round-off.
    """
    U, n = lateral_interface.U_M_PER_S, lateral_interface.N_HZ
    u, v, w, p, q, r, phi, theta = (float(x) for x in z)
    phi += float(roll0_rad)
    return {"delta_u_start": u * U, "delta_v_start": v * U, "delta_w_start": w * U,
            "delta_p_start": p * n, "delta_q_start": q * n, "delta_r_start": r * n,
            "delta_gamma_start": math.asin(math.sin(phi) * math.cos(theta)),
            "delta_theta_start": theta}


def flapping_system(fmus: Mapping[str, str | Path],
                    gains: Sequence[float] = PAPER_GAINS_EQ27, roll0_rad: float = 0.1,
                    stop_wb: float = 30.0, z0: Sequence[float] | None = None) -> System:
    """The paper's lateral loop on the flapping insect: ``DroneFlyFlapping`` (instance
    ``plant``) and ``StateFeedback`` (``lateral_controller``) with gains ``gains`` on
    delta_Phi_a (row 1 of K; the other rows 0), the plant starting on its periodic orbit
    with a roll.

    The plant's longitudinal controls (delta_Phi, delta_alpha_1, delta_phibar,
    delta_alpha_2) are left unconnected: SSP and the master let an unconnected input keep
    its start value (0, the averaged trim's kinematics), so no longitudinal controller
    flies them (the paper's longitudinal design is for its CFD derivatives and drives
    delta_phibar past the plant's limit on the flapping insect).

    Parameters
    ----------
    fmus : mapping
        Model name (``DroneFlyFlapping``, ``StateFeedback``) -> FMU path.
    gains : sequence of 4 floats
        Non-dimensional gains of delta_Phi_a [rad] on x+ = (dv+, dp+, dr+, dgamma)
        (default Eq. (27)).
    roll0_rad : float
        Roll angle phi added to the orbit's start [rad] (default 0.1).
    stop_wb : float
        Stop time of the SSP's DefaultExperiment, in wing beats.
    z0 : sequence of 8 floats, optional
        The orbit's start (:func:`dronefly.models.flapping.orbit_start`, computed if not
        given: a Newton shooting).
    """
    if len(gains) != len(lateral_interface.STATE_NAMES):
        raise SystemSpecError(f"gains = {list(gains)!r}: expected {len(lateral_interface.STATE_NAMES)} "
                              "values (delta_Phi_a on dv+, dp+, dr+, dgamma)")
    z = orbit_start() if z0 is None else np.asarray(z0, dtype=float)
    params: dict[str, dict[str, object]] = {
        "plant": flapping_starts(z, roll0_rad),
        "lateral_controller": {f"K[1,{j + 1}]": float(k) for j, k in enumerate(gains)}}
    return _system(fmus, FLAPPING_FMUS, params, FLAPPING, stop_wb)
