"""The closed loop as one artefact: an SSP file and a container FMU holding plant and controller.

``DroneFlyClosedLoop.ssp``
    SSP 1.0 archive: ``SystemStructure.ssd`` (components ``plant`` and ``controller``, their
    input/output connectors, the connections by name, a default experiment),
    ``resources/DroneFlyLateral.fmu``, ``resources/StateFeedback.fmu`` and the parameter
    values ``resources/plant.ssv`` and ``resources/controller.ssv``, each bound to its component
    (SSP 1.0 ParameterBinding; names are the FMU's variable names). fmpy's ``simulate_ssp``
    does not apply an SSD's bindings itself; it takes one parameter set with hierarchical
    names (``plant.delta_gamma_start``, ``controller.K[1,1]``), so :func:`ssp_parameter_set`
    reads the bound sets with fmpy's ``read_ssd`` and prefixes each name with its component's
    name. libcosim (``CosimExecution.from_ssp_file``) applies component bindings itself and
    runs the same file; a system-level binding it would ignore.

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

Both archives are reproducible (fixed zip timestamps, sorted entries, GUID derived from the
two FMUs' GUIDs), like the FMUs themselves.
"""

from __future__ import annotations

import json
import math
import tempfile
import uuid
import zipfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Mapping
from xml.sax.saxutils import quoteattr

import numpy as np

from ..controller.law import default_gains, gain_name
from ..plant.model import STATE_NAMES
from .master import CoSimError
from .stability import Identification

__all__ = ["CLOSED_LOOP", "CONTAINER_TYPES", "ClosedLoopSpec", "build_closed_loop",
           "container_configuration", "container_verdict", "fix_connection_types",
           "run_container", "run_ssp", "ssp_parameter_set", "ssp_verdict", "write_container",
           "write_ssp"]

CLOSED_LOOP = "DroneFlyClosedLoop"
PLANT, CONTROLLER = "DroneFlyLateral", "StateFeedback"
#: FMI 2 type name -> container type name; the mapping fmpy's write_configuration already
#: applies to container variables.
CONTAINER_TYPES = {"Real": "Float64", "Integer": "Int32"}
_ZIP_DATE = (1980, 1, 1, 0, 0, 0)
_NAMESPACE = uuid.UUID("0b6f8a8e-4f1d-4e55-9d0b-7c1e2f3a4b5c")


@dataclass(frozen=True)
class ClosedLoopSpec:
    """What the artefacts fix: initial state x+ (non-dimensional), gains, step and stop."""

    x0: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 0.1)
    gains: tuple[tuple[float, ...], ...] = default_gains()
    step_wingbeats: float = 0.1
    stop_wingbeats: float = 300.0


# -----------------------------------------------------------------------------
# shared helpers
def _md(path: str | Path):
    import fmpy

    return fmpy.read_model_description(str(path))


def _starts(md) -> dict[str, float]:
    return {v.name: float(v.start) for v in md.modelVariables
            if v.type == "Real" and v.start is not None}


def _scales(plant_md) -> tuple[float, np.ndarray]:
    s = _starts(plant_md)
    n, U = s["n"], s["U"]
    return n, np.array([U, n, n, 1.0])


def _connections(plant_md, ctrl_md) -> list[tuple[str, str, str, str]]:
    """(start element, variable, end element, variable): every controller input from the plant
    output of that name, then every plant input from the controller output of that name."""
    p_out = {v.name for v in plant_md.modelVariables if v.causality == "output"}
    c_out = {v.name for v in ctrl_md.modelVariables if v.causality == "output"}
    cons = []
    for v in ctrl_md.modelVariables:
        if v.causality == "input":
            if v.name not in p_out:
                raise CoSimError(f"controller input {v.name!r} has no plant output of that name")
            cons.append(("plant", v.name, "controller", v.name))
    for v in plant_md.modelVariables:
        if v.causality == "input":
            if v.name not in c_out:
                raise CoSimError(f"plant input {v.name!r} has no controller output of that name")
            cons.append(("controller", v.name, "plant", v.name))
    return cons


def _parameters(plant_md, spec: ClosedLoopSpec) -> dict[str, float]:
    """Hierarchical name -> value: the plant's initial state and the controller's gains."""
    _, scale = _scales(plant_md)
    out = {f"plant.{s}_start": float(v) for s, v in zip(STATE_NAMES, np.array(spec.x0) * scale)}
    for i, row in enumerate(spec.gains):
        for j, k in enumerate(row):
            out[f"controller.{gain_name(i, j)}"] = float(k)
    return out


def _write_zip(target: Path, files: Mapping[str, bytes]) -> Path:
    target.parent.mkdir(parents=True, exist_ok=True)
    tmp = target.with_name(target.name + ".part")
    with zipfile.ZipFile(tmp, "w", zipfile.ZIP_DEFLATED) as z:
        for rel in sorted(files):
            info = zipfile.ZipInfo(rel, date_time=_ZIP_DATE)
            info.external_attr = 0o644 << 16
            info.compress_type = zipfile.ZIP_DEFLATED
            z.writestr(info, files[rel])
    tmp.replace(target)
    return target


def _fmt(x: float) -> str:
    return repr(float(x))


# -----------------------------------------------------------------------------
# SSP
def write_ssp(plant: str | Path, controller: str | Path, out_dir: str | Path = "build",
              spec: ClosedLoopSpec = ClosedLoopSpec()) -> Path:
    """Write ``DroneFlyClosedLoop.ssp`` (see the module text) and return its path."""
    pmd, cmd = _md(plant), _md(controller)
    n, _ = _scales(pmd)
    params = _parameters(pmd, spec)

    def connectors(md) -> str:
        rows = [f'          <ssd:Connector name={quoteattr(v.name)} kind="{v.causality}">'
                f"<ssc:Real/></ssd:Connector>"
                for v in md.modelVariables if v.causality in ("input", "output")
                and v.type == "Real"]
        return "\n".join(rows)

    cons = "\n".join(
        f"      <ssd:Connection startElement={quoteattr(a)} startConnector={quoteattr(x)} "
        f"endElement={quoteattr(b)} endConnector={quoteattr(y)}/>"
        for a, x, b, y in _connections(pmd, cmd))
    step = spec.step_wingbeats / n
    ssd = f"""<?xml version="1.0" encoding="UTF-8"?>
<ssd:SystemStructureDescription xmlns:ssc="http://ssp-standard.org/SSP1/SystemStructureCommon"
    xmlns:ssd="http://ssp-standard.org/SSP1/SystemStructureDescription"
    version="1.0" name="{CLOSED_LOOP}">
  <ssd:System name="{CLOSED_LOOP}" description="DroneFlyLateral plant with StateFeedback controller (Zhang &amp; Sun, Eq. 27); communication step {spec.step_wingbeats:g} wing beat = {_fmt(step)} s">
    <ssd:Elements>
      <ssd:Component name="plant" source="resources/{PLANT}.fmu" type="application/x-fmu-sharedlibrary">
        <ssd:Connectors>
{connectors(pmd)}
        </ssd:Connectors>
        <ssd:ParameterBindings>
          <ssd:ParameterBinding source="resources/plant.ssv"/>
        </ssd:ParameterBindings>
      </ssd:Component>
      <ssd:Component name="controller" source="resources/{CONTROLLER}.fmu" type="application/x-fmu-sharedlibrary">
        <ssd:Connectors>
{connectors(cmd)}
        </ssd:Connectors>
        <ssd:ParameterBindings>
          <ssd:ParameterBinding source="resources/controller.ssv"/>
        </ssd:ParameterBindings>
      </ssd:Component>
    </ssd:Elements>
    <ssd:Connections>
{cons}
    </ssd:Connections>
  </ssd:System>
  <ssd:DefaultExperiment startTime="0.0" stopTime="{_fmt(spec.stop_wingbeats / n)}"/>
</ssd:SystemStructureDescription>
"""
    files = {"SystemStructure.ssd": ssd.encode(),
             f"resources/{PLANT}.fmu": Path(plant).read_bytes(),
             f"resources/{CONTROLLER}.fmu": Path(controller).read_bytes()}
    for comp in ("plant", "controller"):
        rows = "\n".join(
            f"    <ssv:Parameter name={quoteattr(k.split('.', 1)[1])}>"
            f"<ssv:Real value=\"{_fmt(v)}\"/></ssv:Parameter>"
            for k, v in params.items() if k.split(".", 1)[0] == comp)
        files[f"resources/{comp}.ssv"] = f"""<?xml version="1.0" encoding="UTF-8"?>
<ssv:ParameterSet xmlns:ssv="http://ssp-standard.org/SSP1/SystemStructureParameterValues"
    version="1.0" name="{comp}">
  <ssv:Parameters>
{rows}
  </ssv:Parameters>
</ssv:ParameterSet>
""".encode()
    return _write_zip(Path(out_dir) / f"{CLOSED_LOOP}.ssp", files)


def ssp_parameter_set(ssp: str | Path):
    """One fmpy ``ParameterSet`` of every component binding of the SSP, named
    ``<component>.<variable>`` as fmpy's ``simulate_ssp`` expects."""
    from fmpy.ssp.ssd import Parameter, ParameterSet, find_components, read_ssd

    ssd = read_ssd(str(ssp))  # validates the SSD and the SSV files against the SSP 1.0 schema
    merged = ParameterSet(name=CLOSED_LOOP)
    for comp in find_components(ssd.system):
        for binding in comp.parameterBindings:
            prefix = binding.prefix or ""
            for pset in binding.parameterValues:
                for p in pset.parameters:
                    name = p.name[len(prefix):] if p.name.startswith(prefix) else p.name
                    merged.parameters.append(Parameter(name=f"{comp.name}.{name}", type=p.type,
                                                       value=p.value, unit=p.unit))
    return merged


def _ssp_step_stop(ssp: str | Path) -> tuple[float, float]:
    from lxml import etree

    with zipfile.ZipFile(ssp) as z:
        root = etree.fromstring(z.read("SystemStructure.ssd"))
    ns = {"ssd": "http://ssp-standard.org/SSP1/SystemStructureDescription"}
    stop = float(root.find("ssd:DefaultExperiment", ns).get("stopTime"))
    with zipfile.ZipFile(ssp) as z:
        n = _scales(_md_from_bytes(z.read(f"resources/{PLANT}.fmu")))[0]
    return 0.1 / n, stop


def _md_from_bytes(data: bytes):
    with tempfile.TemporaryDirectory(prefix="dronefly_md_") as tmp:
        p = Path(tmp, "x.fmu")
        p.write_bytes(data)
        return _md(p)


def run_ssp(ssp: str | Path, *, step: float | None = None, stop_time: float | None = None,
            overrides: Mapping[str, float] | None = None) -> np.ndarray:
    """Simulate the SSP with fmpy's ``simulate_ssp`` and the SSP's own parameter values.

    ``overrides`` replace bound values by hierarchical name (e.g. ``plant.delta_v_start``).
    Default step: 0.1 wing beat; default stop: the SSD's DefaultExperiment.

    fmpy's SSP master (read from fmpy/ssp/simulation.py, and measured): connectors start at 0;
    in every step each component gets its inputs from the connector values, steps, and its
    outputs are read; then all connections are applied. The row stamped t_j therefore holds
    the values *after* the step, at t_(j+1), and the plant's control over step k is
    u_k = K x_(k-1) for k >= 2, with u_0 = u_1 = 0 (the controller sees 0 in its first step).
    """
    from fmpy.ssp.simulation import simulate_ssp

    d_step, d_stop = _ssp_step_stop(ssp)
    pset = ssp_parameter_set(ssp)
    for name, value in (overrides or {}).items():
        hits = [p for p in pset.parameters if p.name == name]
        if not hits:
            raise CoSimError(f"the SSP binds no parameter {name!r}")
        for p in hits:
            p.value = repr(float(value))
    step = d_step if step is None else step
    stop = d_stop if stop_time is None else stop_time
    # fmpy steps while time < stop; stop half a step early so that float accumulation of
    # the time cannot add one step
    return simulate_ssp(str(ssp), start_time=0.0, stop_time=stop - 0.5 * step,
                        step_size=step, parameter_set=pset)


def ssp_verdict(ssp: str | Path, n_steps: int = 20) -> tuple[Identification, list[np.ndarray]]:
    """Identify and classify the loop as fmpy's SSP simulation runs it.

    One run per unit initial state x+_0 = e_i (the SSP's gains). By the master described in
    :func:`run_ssp` the rows hold x_1, x_2, ... and the controller's first input is 0, so each
    run is [0; x_1; x_2; ...] in the delayed (Jacobi) form of ``harness.stability.identify``.
    """
    from .interop import unit_runs_verdict

    d_step, _ = _ssp_step_stop(ssp)
    with zipfile.ZipFile(ssp) as z:
        n, scale = _scales(_md_from_bytes(z.read(f"resources/{PLANT}.fmu")))
    runs = []
    for e in np.eye(len(STATE_NAMES)):
        res = run_ssp(ssp, stop_time=(n_steps + 0.5) * d_step,
                      overrides={f"plant.{s}_start": float(v)
                                 for s, v in zip(STATE_NAMES, e * scale)})
        xs = np.column_stack([res[f"plant.{s}"] for s in STATE_NAMES]) / scale
        runs.append(np.vstack([np.zeros(len(STATE_NAMES)), xs]))
    return unit_runs_verdict(runs, d_step * n, delay=True), runs


# -----------------------------------------------------------------------------
# container FMU
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
    from fmpy.container_fmu.config import Component, Configuration, Connection
    from fmpy.model_description import (BaseUnit, CoSimulation, DefaultExperiment,
                                        ModelDescription, ModelVariable, Unit, Unknown)

    pmd, cmd = _md(plant), _md(controller)
    n, scale = _scales(pmd)
    comps = {"plant": Component(name="plant", filename=Path(plant), modelDescription=pmd),
             "controller": Component(name="controller", filename=Path(controller),
                                     modelDescription=cmd)}
    pvars = {v.name: v for v in pmd.modelVariables}
    cvars = {v.name: v for v in cmd.modelVariables}
    values = _parameters(pmd, spec)
    step = spec.step_wingbeats / n
    guid = "{" + str(uuid.uuid5(_NAMESPACE, f"{CLOSED_LOOP}:{pmd.guid}:{cmd.guid}:{spec!r}")) + "}"
    md = ModelDescription(fmiVersion="2.0", modelName=CLOSED_LOOP,
                          description="DroneFlyLateral plant with StateFeedback controller "
                                      "(fmpy container FMU)",
                          generationTool="dronefly build (fmpy.container_fmu)",
                          variableNamingConvention="structured")
    md.guid = guid
    md.coSimulation = CoSimulation(modelIdentifier="container_fmu", needsExecutionTool=True,
                                   canHandleVariableCommunicationStepSize=False,
                                   fixedInternalStepSize=step)
    md.defaultExperiment = DefaultExperiment(startTime="0.0", stopTime=_fmt(spec.stop_wingbeats / n),
                                             stepSize=_fmt(step))
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
            v.start = _fmt(start)
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

    connections = [Connection(startElement=comps[a], startConnectors=[
        (pvars if a == "plant" else cvars)[x]], endElement=comps[b],
        endConnectors=[(pvars if b == "plant" else cvars)[y]])
        for a, x, b, y in _connections(pmd, cmd)]
    return Configuration(parallelDoStep=False, modelDescription=md,
                         components=list(comps.values()), connections=connections,
                         variableMappings=mappings)


def _container_files(config, fix: bool = True) -> dict[str, bytes]:
    """The container's files, written by fmpy's writers (plus the connection-type fix)."""
    import fmpy.container_fmu as cfmu
    from fmpy.model_description import write_model_description

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
    for comp in config.components:
        with zipfile.ZipFile(comp.filename) as z:
            for info in z.infolist():
                if not info.is_dir():
                    files[f"resources/{Path(comp.filename).stem}/{info.filename}"] = z.read(info)
    bins = Path(cfmu.__file__).parent / "binaries"
    for tup, fmi2, lib in (("aarch64-darwin", "darwin64", "container_fmu.dylib"),
                           ("x86_64-darwin", "darwin64", "container_fmu.dylib"),
                           ("x86_64-linux", "linux64", "container_fmu.so"),
                           ("x86_64-windows", "win64", "container_fmu.dll")):
        if (bins / tup / lib).is_file():
            files[f"binaries/{fmi2}/{lib}"] = (bins / tup / lib).read_bytes()
    return files


def write_container(plant: str | Path, controller: str | Path, out_dir: str | Path = "build",
                    spec: ClosedLoopSpec = ClosedLoopSpec(), *, fix: bool = True,
                    name: str = CLOSED_LOOP) -> Path:
    """Write the container FMU ``<name>.fmu``. ``fix=False`` keeps fmpy's connection types
    (only to show that fmpy's output fails)."""
    config = container_configuration(plant, controller, spec)
    return _write_zip(Path(out_dir) / f"{name}.fmu", _container_files(config, fix))


def run_container(fmu: str | Path, *, start_values: Mapping[str, float] | None = None,
                  stop_time: float | None = None) -> np.ndarray:
    """``fmpy.simulate_fmu`` with the container's default experiment (output every step)."""
    import fmpy

    md = _md(fmu)
    step = float(md.defaultExperiment.stepSize)
    stop = float(md.defaultExperiment.stopTime) if stop_time is None else stop_time
    return fmpy.simulate_fmu(str(fmu), stop_time=stop, output_interval=step,
                             start_values=dict(start_values or {}),
                             output=[v.name for v in md.modelVariables
                                     if v.causality == "output"])


def container_verdict(fmu: str | Path,
                      n_steps: int = 20) -> tuple[Identification, list[np.ndarray]]:
    """Identify and classify the loop as the container runs it (one run per unit x+_0).

    The container's master, measured (``tests/test_interop.py``): the plant's first step
    uses u_0 = 0 (nothing is transferred before it); after every step the connections are
    applied in order, plant -> controller then controller -> plant, and the controller is
    direct feedthrough, so from then on u_k = K x_k. Rows 1, 2, ... are thus exactly the
    Gauss-Seidel loop started from x_1 (``Loop.run(master="gauss-seidel")`` from x_1 agrees
    bit for bit), and the identification uses them without delay.
    """
    from .interop import unit_runs_verdict

    md = _md(fmu)
    s = {v.name: float(v.start) for v in md.modelVariables if v.start is not None}
    n, U = s["n"], s["U"]
    scale = np.array([U, n, n, 1.0])
    step = float(md.defaultExperiment.stepSize)
    runs = []
    for e in np.eye(len(STATE_NAMES)):
        res = run_container(fmu, start_values={f"{x}_start": float(v)
                                               for x, v in zip(STATE_NAMES, e * scale)},
                            stop_time=(n_steps + 1) * step)
        xs = np.column_stack([res[x] for x in STATE_NAMES]) / scale
        runs.append(xs[1:])
    return unit_runs_verdict(runs, step * n, delay=False), runs


# -----------------------------------------------------------------------------
def build_closed_loop(out_dir: str | Path, plant: str | Path, controller: str | Path,
                      spec: ClosedLoopSpec = ClosedLoopSpec()) -> list[Path]:
    """``DroneFlyClosedLoop.ssp`` and ``DroneFlyClosedLoop.fmu`` from two built FMUs."""
    if not (math.isfinite(spec.step_wingbeats) and spec.step_wingbeats > 0):
        raise CoSimError(f"step = {spec.step_wingbeats!r} wing beats must be finite and > 0")
    return [write_ssp(plant, controller, out_dir, spec),
            write_container(plant, controller, out_dir, spec)]
