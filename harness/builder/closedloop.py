"""The closed loop as one artefact: the SSP file and the container FMU, and what they share.

Both archives are reproducible (fixed zip timestamps, sorted entries, GUID derived from the
two FMUs' GUIDs), like the FMUs themselves. They are run by :mod:`dronefly.harness.interop`.

``DroneFlyClosedLoop.ssp``
    SSP 1.0 archive (written with :mod:`dronefly.harness.cosim.ssp`'s namespaces): see
    :func:`write_ssp`.

``DroneFlyClosedLoop.fmu``
    An FMI 2.0 co-simulation FMU made with fmpy's container FMU (``fmpy.container_fmu``): its
    native ``container_fmu`` binary instantiates the two FMUs (extracted under ``resources/``)
    and connects them as ``resources/container.json`` says. Parameters: the initial state
    (``delta_*_start``), the gains ``K[i,j]`` and the reference scales ``n``, ``U`` (each
    mapped to both FMUs); outputs: the four states and the three controls.

fmpy 0.3.32 bug worked around here: ``write_configuration`` writes each *connection*'s
``variableType`` from the FMI 2 type name (``"Real"``), while the container binary only knows
FMI 3 names (``Float64``, ...) and fails at fmi2Instantiate with "unknown variant `Real`,
expected one of `Float32`, `Float64`, ...". (For container *variables* fmpy already maps
Real -> Float64 and Integer -> Int32.) :func:`fix_connection_types` applies the same mapping to
the connections of the configuration fmpy wrote, and nothing else; the JSON is otherwise
fmpy's own. ``tests/test_interop.py`` checks both that fmpy's output still needs it and that
the fixed container runs.

pythonfmu 0.7.0 in fmpy's container stops the container for good after one refused component
step, fmi2Reset included, so on Linux the nested FMUs' library is pythonfmu's behind a small
forwarding shim that answers ``fmi2Terminated`` truthfully (see
:mod:`dronefly.harness.builder.nestedshim`; ``shim=False`` builds without it).
"""

from __future__ import annotations

import json
import math
import tempfile
import uuid
import zipfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import fmpy.container_fmu as cfmu
import numpy as np
from fmpy import read_model_description
from fmpy.container_fmu.config import Component, Configuration, Connection
from fmpy.model_description import (BaseUnit, CoSimulation, DefaultExperiment, ModelDescription,
                                    ModelVariable, Unit, Unknown, write_model_description)

from ...core.files import write_zip
from ..cosim.fmu3 import read_view
from ..cosim.fmu import start_values
from ..cosim.master import CoSimError, connect_by_name
from ..cosim.ssp import write_system_ssp
from ..cosim.system import Connection as SystemConnection, System
from ...models.feedback import default_gains, gain_name
from ...models.lateral_interface import STATE_NAMES, plant_scales
from .nestedshim import install_shims

__all__ = ["CLOSED_LOOP", "CONTAINER_TYPES", "CONTROLLER", "GUID_NAMESPACE", "PLANT",
           "ClosedLoopSpec", "container_configuration", "fix_connection_types",
           "parameter_values", "plant_md_scales", "write_container", "write_ssp"]

CLOSED_LOOP = "DroneFlyClosedLoop"
PLANT, CONTROLLER = "DroneFlyLateral", "StateFeedback"
#: FMI 2 type name -> container type name; the mapping fmpy's write_configuration already
#: applies to container variables.
CONTAINER_TYPES = {"Real": "Float64", "Integer": "Int32"}
GUID_NAMESPACE = uuid.UUID("0b6f8a8e-4f1d-4e55-9d0b-7c1e2f3a4b5c")


@dataclass(frozen=True)
class ClosedLoopSpec:
    """What the artefacts fix: initial state x+ (non-dimensional), gains, step and stop."""

    x0: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 0.1)
    gains: tuple[tuple[float, ...], ...] = default_gains()
    step_wingbeats: float = 0.1
    stop_wingbeats: float = 300.0

    def __post_init__(self) -> None:
        for name in ("step_wingbeats", "stop_wingbeats"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise CoSimError(f"{name} = {value!r} wing beats must be finite and > 0")


def plant_md_scales(plant_md) -> tuple[float, np.ndarray]:
    """n [Hz] and the scale vector [U, n, n, 1] of a plant's model description."""
    scale = np.array(plant_scales(start_values(plant_md)))
    return float(scale[1]), scale


def parameter_values(plant_md, spec: ClosedLoopSpec) -> dict[str, float]:
    """Hierarchical name -> value: the plant's initial state and the controller's gains."""
    _, scale = plant_md_scales(plant_md)
    out = {f"plant.{s}_start": float(v) for s, v in zip(STATE_NAMES, np.array(spec.x0) * scale)}
    for i, row in enumerate(spec.gains):
        for j, k in enumerate(row):
            out[f"controller.{gain_name(i, j)}"] = float(k)
    return out


def _bindable(params: dict[str, float], fmus: dict[str, tuple[Any, Any]]) -> dict[str, float]:
    """``params`` without the elements of FMI 3.0 arrays: SSP 1.0 binds scalars only, and an
    element ``K[1,2]`` is no variable of the FMU. An element whose value is not its start
    value cannot be bound: refused."""
    out = {}
    names = {comp: {v.name for v in read_model_description(str(path)).modelVariables}
             for comp, (path, _) in fmus.items()}
    for key, value in params.items():
        comp, _, name = key.partition(".")
        path, view = fmus[comp]
        if name in names[comp]:
            out[key] = value
            continue
        start = start_values(view).get(name)
        if start is None or float(start) != float(value):
            raise CoSimError(f"{comp}.{name} = {value!r}: {str(path)!r} has no variable "
                             f"{name!r} (an element of an FMI 3.0 array), and SSP 1.0 binds "
                             f"scalars only, so only its start value {start!r} can be used")
    return out


def fix_connection_types(config: dict[str, Any]) -> dict[str, Any]:
    """Rename FMI 2 type names in the container's connections (Real -> Float64, ...).

    Only ``connections[*].variableType`` is touched; names the container already knows pass
    unchanged, so this is a no-op once fmpy writes them itself. Returns ``config``.
    """
    for c in config.get("connections", []):
        c["variableType"] = CONTAINER_TYPES.get(c["variableType"], c["variableType"])
    return config


def container_configuration(plant: str | Path, controller: str | Path,
                            spec: ClosedLoopSpec = ClosedLoopSpec()):
    """The container described with fmpy's own structures (``fmpy.container_fmu.config``)."""
    pmd, cmd = read_model_description(plant), read_model_description(controller)
    n, scale = plant_md_scales(pmd)
    comps = {"plant": Component(name="plant", filename=Path(plant), modelDescription=pmd),
             "controller": Component(name="controller", filename=Path(controller),
                                     modelDescription=cmd)}
    pvars = {v.name: v for v in pmd.modelVariables}
    cvars = {v.name: v for v in cmd.modelVariables}
    values = parameter_values(pmd, spec)
    step = spec.step_wingbeats / n
    guid = "{" + str(uuid.uuid5(GUID_NAMESPACE, f"{CLOSED_LOOP}:{pmd.guid}:{cmd.guid}:{spec!r}")) + "}"
    md = ModelDescription(fmiVersion="2.0", modelName=CLOSED_LOOP,
                          description="DroneFlyLateral plant with StateFeedback controller "
                                      "(fmpy container FMU)",
                          generationTool="dronefly build (fmpy.container_fmu)",
                          variableNamingConvention="structured")
    md.guid = guid
    md.coSimulation = CoSimulation(modelIdentifier="container_fmu", needsExecutionTool=True,
                                   canHandleVariableCommunicationStepSize=False,
                                   fixedInternalStepSize=step)
    md.defaultExperiment = DefaultExperiment(startTime="0.0", stopTime=repr(float(spec.stop_wingbeats / n)),
                                             stepSize=repr(float(step)))
    units = {}
    for m in (pmd, cmd):
        for u in m.unitDefinitions:
            units.setdefault(u.name, u)
    units.setdefault("s", Unit(name="s", baseUnit=BaseUnit(s=1)))
    mappings: dict = {}
    used_units = {"s"}
    # The container binary serves value reference 0 as the simulation time and maps the
    # configuration's variables to 1, 2, ...: fmpy's create_container_fmu numbers the model
    # variables 0, 1, ..., so the first one must be the (unmapped) independent variable.
    md.modelVariables.append(ModelVariable(name="time", type="Real", causality="independent",
                                           variability="continuous", unit="s",
                                           description="simulation time"))

    def add(name: str, src: ModelVariable, targets: list[tuple[str, ModelVariable]],
            start: float | None = None) -> ModelVariable:
        v = ModelVariable(name=name, type="Real", causality=src.causality,
                          variability=src.variability, initial=src.initial,
                          description=src.description, unit=src.unit,
                          displayUnit=src.displayUnit)
        if start is not None:
            v.start = repr(float(start))
        elif src.start is not None and src.causality == "parameter":
            v.start = src.start
        md.modelVariables.append(v)
        mappings[v] = [(comps[c], tv) for c, tv in targets]
        if src.unit:
            used_units.add(src.unit)
        return v

    outputs = []
    for name in STATE_NAMES:
        outputs.append(add(name, pvars[name], [("plant", pvars[name])]))
    for v in cmd.modelVariables:
        if v.causality == "output" and v.type == "Real":
            outputs.append(add(v.name, v, [("controller", v)]))
    for name in STATE_NAMES:
        key = f"{name}_start"
        add(key, pvars[key], [("plant", pvars[key])], values[f"plant.{key}"])
    for v in cmd.modelVariables:
        if v.name.startswith("K["):
            add(v.name, v, [("controller", v)], values[f"controller.{v.name}"])
    for name in ("n", "U"):  # one value for both FMUs
        add(name, pvars[name], [("plant", pvars[name]), ("controller", cvars[name])])
    md.unitDefinitions = [units[u] for u in sorted(used_units) if u in units]
    md.outputs = [Unknown(variable=v, dependencies=[]) for v in outputs]  # no inputs at all
    md.initialUnknowns = [Unknown(variable=v) for v in outputs]

    def _var(component: str, name: str) -> Any:
        return (pvars if component == "plant" else cvars)[name]

    links = [Connection(startElement=comps[a], startConnectors=[_var(a, x)],
                        endElement=comps[b], endConnectors=[_var(b, y)])
             for a, x, b, y in connect_by_name(pmd, cmd)]
    return Configuration(parallelDoStep=False, modelDescription=md,
                         components=list(comps.values()), connections=links,
                         variableMappings=mappings)


def _container_files(config, fix: bool = True, shim: bool = True) -> dict[str, bytes]:
    """The container's files, written by fmpy's writers (plus the connection-type fix and the
    nested FMUs' shim)."""
    files: dict[str, bytes] = {}
    for i, v in enumerate(config.modelDescription.modelVariables):
        v.valueReference = i  # as fmpy's create_container_fmu numbers them (time is 0)
    with tempfile.TemporaryDirectory(prefix="dronefly_container_") as tmp:
        write_model_description(config.modelDescription, Path(tmp, "modelDescription.xml"))
        files["modelDescription.xml"] = Path(tmp, "modelDescription.xml").read_bytes()
        cfmu.write_configuration(config, Path(tmp, "container.json"))
        data = json.loads(Path(tmp, "container.json").read_text(encoding="utf-8"))
    if fix:
        fix_connection_types(data)
    files["resources/container.json"] = (json.dumps(data, indent=4) + "\n").encode()
    nested: list[set[str]] = []
    for comp in config.components:
        with zipfile.ZipFile(comp.filename) as z:
            nested.append({n.split("/")[1] for n in z.namelist()
                           if n.startswith("binaries/") and n.count("/") >= 2 and not n.endswith("/")})
            for info in z.infolist():
                if not info.is_dir():
                    files[f"resources/{Path(comp.filename).stem}/{info.filename}"] = z.read(info)
    if shim:
        install_shims(files, config.components)
    # a platform only where the container binary AND every nested FMU can run
    platforms = set.intersection(*nested) if nested else set()
    bins = Path(cfmu.__file__).parent / "binaries"
    for tup, fmi2, lib in (("aarch64-darwin", "darwin64", "container_fmu.dylib"),
                           ("x86_64-darwin", "darwin64", "container_fmu.dylib"),
                           ("x86_64-linux", "linux64", "container_fmu.so"),
                           ("x86_64-windows", "win64", "container_fmu.dll")):
        if fmi2 in platforms and (bins / tup / lib).is_file():
            files[f"binaries/{fmi2}/{lib}"] = (bins / tup / lib).read_bytes()
    return files


def write_container(plant: str | Path, controller: str | Path, out_dir: str | Path = "build",
                    spec: ClosedLoopSpec = ClosedLoopSpec(), *, fix: bool = True,
                    shim: bool = True, name: str = CLOSED_LOOP) -> Path:
    """Write the container FMU ``<name>.fmu``. ``fix=False`` keeps fmpy's connection types,
    ``shim=False`` pythonfmu's bare nested binaries (only to show what each workaround is for)."""
    config = container_configuration(plant, controller, spec)
    return write_zip(Path(out_dir) / f"{name}.fmu", _container_files(config, fix, shim))


def _versions(pmd, cmd) -> str:
    """"" for two FMI 2.0 FMUs, else which FMI version each FMU is."""
    v = [str(md.fmiVersion) for md in (pmd, cmd)]
    return "" if v == ["2.0", "2.0"] else f"; FMI {v[0]} plant, FMI {v[1]} controller"


def write_ssp(plant: str | Path, controller: str | Path, out_dir: str | Path = "build",
              spec: ClosedLoopSpec = ClosedLoopSpec()) -> Path:
    """Write ``DroneFlyClosedLoop.ssp`` (see the module text) and return its path.

    The FMUs may be FMI 2.0 or FMI 3.0 (read through the harness's view,
    :func:`dronefly.harness.cosim.fmu3.read_view`). Every SSV parameter names a variable of
    its FMU, as a strict importer requires: SSP 1.0 has no array values, so an FMI 3.0 array
    (the controller's ``K``) is not bound; its start values are the gains (see
    docs/fmi3.md).

    Raises
    ------
    CoSimError
        Gains other than an FMI 3.0 controller's start values of ``K``: SSP 1.0 cannot bind
        them.
    """
    pmd, cmd = read_view(plant), read_view(controller)
    n, _ = plant_md_scales(pmd)
    params = _bindable(parameter_values(pmd, spec), {"plant": (plant, pmd),
                                                     "controller": (controller, cmd)})
    step = spec.step_wingbeats / n
    values: dict[str, dict[str, object]] = {"plant": {}, "controller": {}}
    for k, v in params.items():
        owner, _, name = k.partition(".")
        values[owner][name] = float(v)
    system = System({"plant": Path(plant), "controller": Path(controller)},
                    [SystemConnection(a, x, b, y) for a, x, b, y in connect_by_name(pmd, cmd)],
                    values, name=CLOSED_LOOP, stop_s=float(spec.stop_wingbeats / n))
    return write_system_ssp(
        system, Path(out_dir) / f"{CLOSED_LOOP}.ssp",
        description=f"DroneFlyLateral plant with StateFeedback controller (Zhang & Sun, "
                    f"Eq. 27); communication step {spec.step_wingbeats:g} wing beat = "
                    f"{float(step)!r} s" + _versions(pmd, cmd),
        entries={"plant": f"{PLANT}.fmu", "controller": f"{CONTROLLER}.fmu"},
        connector_types=("Real",))
