"""The closed loop as an fmpy container FMU.

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

pythonfmu 0.7.0 and the container together also stopped the container for good after one
refused component step, fmi2Reset included: on Linux the nested FMUs' library is pythonfmu's
behind a small forwarding shim that answers ``fmi2Terminated`` truthfully (see
:mod:`dronefly.harness.interop.nestedshim`; ``shim=False`` builds without it).
"""

from __future__ import annotations

import json
import tempfile
import uuid
import zipfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Mapping

import numpy as np
from fmpy import read_model_description

from ...core.files import write_zip
from .closedloop import (GUID_NAMESPACE, CLOSED_LOOP, CONTAINER_TYPES, ClosedLoopSpec,
    parameter_values, reference_scales)
from .nestedshim import install_shims
from ..cosim.master import connect_by_name
from ..cosim.stability import Identification, checked, identify
from ...models.lateral import STATE_NAMES

__all__ = ["Verdict", "container_configuration", "container_verdict", "fix_connection_types", "run_container",
           "write_container"]


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

    pmd, cmd = read_model_description(plant), read_model_description(controller)
    n, scale = reference_scales(pmd)
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


@dataclass(frozen=True)
class Verdict:
    """How an importer ran the closed loop: the identification and the runs it used."""

    identification: Identification
    runs: list[np.ndarray]  # non-dimensional state trajectories, one per unit initial state

    @property
    def verdict(self) -> str:
        """``unstable``, ``neutral`` or ``stable`` (see :mod:`dronefly.harness.cosim.stability`)."""
        return self.identification.verdict


def write_container(plant: str | Path, controller: str | Path, out_dir: str | Path = "build",
                    spec: ClosedLoopSpec = ClosedLoopSpec(), *, fix: bool = True,
                    shim: bool = True, name: str = CLOSED_LOOP) -> Path:
    """Write the container FMU ``<name>.fmu``. ``fix=False`` keeps fmpy's connection types,
    ``shim=False`` pythonfmu's bare nested binaries (only to show what each workaround is for)."""
    config = container_configuration(plant, controller, spec)
    return write_zip(Path(out_dir) / f"{name}.fmu", _container_files(config, fix, shim))


def run_container(fmu: str | Path, *, start_values: Mapping[str, float] | None = None,
                  stop_s: float | None = None) -> np.ndarray:
    """``fmpy.simulate_fmu`` with the container's default experiment (output every step)."""
    import fmpy

    md = read_model_description(fmu)
    step = float(md.defaultExperiment.stepSize)
    stop = float(md.defaultExperiment.stopTime) if stop_s is None else stop_s
    return fmpy.simulate_fmu(str(fmu), stop_time=stop, output_interval=step,
                             start_values=dict(start_values or {}),
                             output=[v.name for v in md.modelVariables
                                     if v.causality == "output"])


def container_verdict(fmu: str | Path, n_steps: int = 20) -> Verdict:
    """Identify and classify the loop as the container runs it (one run per unit x+_0).

    The container's master, measured (``tests/test_interop.py``,
    ``test_container_is_the_gauss_seidel_loop``): it resolves its connections in
    initialization, where the plant's outputs already hold x_0, so u_0 = K x_0, and after every
    step (plant -> controller -> plant; the controller is direct feedthrough): u_k = K x_k. The
    rows are the Gauss-Seidel loop from x_0, and the identification uses them without delay.

    Raises
    ------
    CrossCheckError
        The fit's residual exceeds :data:`~dronefly.harness.cosim.stability.FIT_RESIDUAL_TOL`
        (the runs are not the loop identified, e.g. a controller with a sensing delay).
    """
    md = read_model_description(fmu)
    n, scale = reference_scales(md)
    step = float(md.defaultExperiment.stepSize)
    runs = []
    for e in np.eye(len(STATE_NAMES)):
        res = run_container(fmu, start_values={f"{x}_start": float(v)
                                               for x, v in zip(STATE_NAMES, e * scale)},
                            stop_s=(n_steps + 1) * step)
        runs.append(np.column_stack([res[x] for x in STATE_NAMES]) / scale)
    return Verdict(checked(identify(runs, step * n, delay=False), f"container {fmu}"), runs)
