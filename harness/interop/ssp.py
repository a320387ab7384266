"""The closed loop as an SSP 1.0 file.

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

``build/fmi3/DroneFlyClosedLoop.ssp`` is the same system of the FMI 3.0 FMUs (SSD and SSV files
alike: SSP 1.0 binds the FMI 3.0 array ``K`` by its elements ``K[i,j]``, which
``dronefly cosim --system`` resolves). fmpy's ``simulate_ssp`` cannot run it (it instantiates
every FMU as FMI 2.0), so :func:`run_ssp` refuses it; docs/fmi3.md says what Ecos does with it.
"""

from __future__ import annotations

import io
import re
import tempfile
import zipfile
from pathlib import Path
from typing import Mapping
from xml.etree import ElementTree as ET

import numpy as np
from fmpy.ssp.simulation import simulate_ssp
from fmpy.ssp.ssd import Parameter, ParameterSet, find_components, read_ssd

from ..builder.closedloop import CLOSED_LOOP, PLANT, plant_md_scales
from ...models.lateral_interface import STATE_NAMES
from ..cosim.fmu3 import read_view
from ..cosim.master import CoSimError
from ..cosim.ssp import SSD_NS
from ..cosim.identification import Verdict, unit_start_values, verdict_of

__all__ = ["run_ssp", "ssp_parameter_set", "ssp_verdict"]


def ssp_parameter_set(ssp: str | Path):
    """One fmpy ``ParameterSet`` of every component binding of the SSP, named
    ``<component>.<variable>`` as fmpy's ``simulate_ssp`` expects."""

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
    with zipfile.ZipFile(ssp) as z:
        root = ET.fromstring(z.read("SystemStructure.ssd"))
    stop = float(root.find(f"{{{SSD_NS}}}DefaultExperiment").get("stopTime"))
    with zipfile.ZipFile(ssp) as z:
        n = plant_md_scales(_md_from_bytes(z.read(f"resources/{PLANT}.fmu")))[0]
    return 0.1 / n, stop


def _fmi_versions(ssp: str | Path) -> dict[str, str]:
    """fmiVersion of every FMU in the SSP's resources, by file name."""

    out = {}
    with zipfile.ZipFile(ssp) as z:
        for name in z.namelist():
            if name.startswith("resources/") and name.endswith(".fmu"):
                with zipfile.ZipFile(io.BytesIO(z.read(name))) as fmu:
                    head = fmu.read("modelDescription.xml")[:4096].decode("utf-8", "replace")
                m = re.search(r'fmiVersion\s*=\s*"([^"]*)"', head)
                out[name[len("resources/"):]] = m.group(1) if m else "?"
    return out


def _md_from_bytes(data: bytes):
    with tempfile.TemporaryDirectory(prefix="dronefly_md_") as tmp:
        p = Path(tmp, "x.fmu")
        p.write_bytes(data)
        return read_view(p)


def run_ssp(ssp: str | Path, *, step_s: float | None = None, stop_s: float | None = None,
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

    fmi3 = [name for name, version in _fmi_versions(ssp).items() if version.startswith("3")]
    if fmi3:  # fmpy/ssp/simulation.py instantiates every FMU as an FMU2Slave
        raise CoSimError(f"fmpy's simulate_ssp runs FMI 2.0 FMUs only, and {str(ssp)!r} holds "
                         f"FMI 3.0 ones ({', '.join(fmi3)}): run it with dronefly cosim --system")
    d_step, d_stop = _ssp_step_stop(ssp)
    pset = ssp_parameter_set(ssp)
    for name, value in (overrides or {}).items():
        hits = [p for p in pset.parameters if p.name == name]
        if not hits:
            raise CoSimError(f"the SSP binds no parameter {name!r}")
        for p in hits:
            p.value = repr(float(value))
    step = d_step if step_s is None else step_s
    stop = d_stop if stop_s is None else stop_s
    # fmpy steps while time < stop; stop half a step early so that float accumulation of
    # the time cannot add one step
    return simulate_ssp(str(ssp), start_time=0.0, stop_time=stop - 0.5 * step,
                        step_size=step, parameter_set=pset)


def ssp_verdict(ssp: str | Path, n_steps: int = 20) -> Verdict:
    """Identify and classify the loop as fmpy's SSP simulation runs it.

    One run per unit initial state x+_0 = e_i (the SSP's gains). By the master described in
    :func:`run_ssp` the rows hold x_1, x_2, ... and the controller's first input is 0, so each
    run is [0; x_1; x_2; ...] in the delayed (Jacobi) form of ``harness.cosim.identification.identify``.

    Raises
    ------
    CrossCheckError
        The fit's residual exceeds :data:`~dronefly.harness.cosim.identification.FIT_RESIDUAL_TOL`
        (the runs are not the loop identified, e.g. a controller with a sensing delay).
    """
    d_step, _ = _ssp_step_stop(ssp)
    with zipfile.ZipFile(ssp) as z:
        n, scale = plant_md_scales(_md_from_bytes(z.read(f"resources/{PLANT}.fmu")))
    runs = []
    for start in unit_start_values(scale, prefix="plant."):
        res = run_ssp(ssp, stop_s=(n_steps + 0.5) * d_step, overrides=start)
        xs = np.column_stack([res[f"plant.{s}"] for s in STATE_NAMES]) / scale
        runs.append(np.vstack([np.zeros(len(STATE_NAMES)), xs]))
    return verdict_of(runs, d_step * n, delay=True, where=f"fmpy SSP {ssp}")
