"""``dronefly sweep --system FILE.ssp``: the sweep's cases run on a whole system of FMUs.

The system must hold one lateral plant (Real outputs ``delta_v``, ``delta_p``, ``delta_r``,
``delta_gamma`` with ``*_start`` parameters, ``n`` and ``U``; see
:func:`dronefly.harness.cosim.verdicts.find_plants`) whose inputs are driven by one
controller with gain parameters ``K[i,j]``. Each case sets the lateral plant's initial state
and the controller's gains (mapped through the connections: row = the controller output
that drives the plant's control, column = the controller input that senses the plant's
state) and runs every FMU of the system on the :class:`SystemMaster`; the measurement is the
one of the plant/controller sweep, on the lateral plant and its controls. Other instances
(for example the longitudinal loop of ``DroneFlyHover.ssp``) run along unchanged.

With a system, a case's ``plant_values`` are the ``--set instance.NAME=VALUE`` settings of
any instance, as ``("instance.NAME", value)``; they are part of the case key. The
longitudinal states (of the instance that has them) start at zero whatever the SSP's start
values, unless ``--set`` gives them: a case is a lateral disturbance.
"""

from __future__ import annotations

import tempfile
import threading
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np

from ...models.feedback import gain_name
from ...models.lateral_interface import CONTROL_NAMES, STATE_NAMES, plant_scales
from ...models.longitudinal_interface import LONGITUDINAL
from ..cosim.fmu import FMUError
from ..cosim.system import System, SystemSpecError
from ..cosim.system_master import SystemMaster
from .parse import SweepInputError

__all__ = ["EARTH", "LateralLoop", "SystemRef", "check_system", "close_systems", "open_system",
           "run_system_case"]

#: the earth-axis position outputs of a six-degree-of-freedom plant, m
EARTH = ("x_earth", "y_earth", "z_earth")
_LOCK = threading.Lock()
_OPEN: dict[tuple[int, str, str], tuple[Any, "LateralLoop"]] = {}  # (thread, digest, master)


@dataclass(frozen=True)
class SystemRef:
    """An SSP file and the SHA-1 of its bytes (as :class:`~.worker.FmuRef`)."""

    path: str
    digest: str


@dataclass(frozen=True)
class LateralLoop:
    """Where the lateral loop sits in a system; ``names``/``states``/``controls`` as a Loop's.

    ``record`` is the lateral plant's states, the controller outputs that drive its controls,
    then (if the system has them) the longitudinal states and the earth-axis position.
    """

    plant: str
    controller: str
    record: tuple[str, ...]
    controls: tuple[str, ...]  # the plant inputs that are driven, in CONTROL_NAMES order
    gains: tuple[tuple[int, int, str], ...]  # (control row, state column, K[i,j] name)
    longitudinal: str | None = None  # the instance with the longitudinal states
    earth: str | None = None  # the instance with x_earth, y_earth, z_earth

    @property
    def states(self) -> tuple[str, ...]:
        return STATE_NAMES

    @property
    def names(self) -> tuple[str, ...]:
        return (*STATE_NAMES, *self.controls)


def _instances_with(master: Any, outputs: Sequence[str], starts: bool = True) -> list[str]:
    """Instances with all these Real outputs (and, if ``starts``, ``*_start``, n and U)."""
    out = []
    for inst, fmu in master.fmus.items():
        v = fmu.variables
        if all(n in v and v[n].causality == "output" and v[n].type == "Real" for n in outputs) \
                and (not starts or all(k in v for k in (*(f"{n}_start" for n in outputs),
                                                        "n", "U"))):
            out.append(inst)
    return out


def _lateral_loop(master: Any) -> LateralLoop:
    plants = _instances_with(master, STATE_NAMES)
    if len(plants) != 1:
        raise SweepInputError(f"the system {master.system.name!r} has {len(plants)} lateral "
                              f"plants (outputs {', '.join(STATE_NAMES)} with *_start, n and "
                              "U); the sweep needs exactly one")
    plant = plants[0]
    cons = master.system.connections
    drives = {c.input: c for c in cons if c.target == plant and c.input in CONTROL_NAMES}
    sources = {c.source for c in drives.values()}
    if len(sources) != 1:
        raise SweepInputError(f"the lateral controls of {plant!r} must be driven by one "
                              f"controller instance (found {sorted(sources) or 'none'})")
    ctrl = sources.pop()
    senses = {c.output: c.input for c in cons if c.source == plant and c.target == ctrl}
    md = master.fmus[ctrl].model_description
    c_in = [v.name for v in md.modelVariables if v.causality == "input"]
    c_out = [v.name for v in md.modelVariables if v.causality == "output" and v.type == "Real"]
    controls = tuple(c for c in CONTROL_NAMES if c in drives)
    gains = []
    for a, u in enumerate(CONTROL_NAMES):
        for b, st in enumerate(STATE_NAMES):
            if u in drives and st in senses:
                name = gain_name(c_out.index(drives[u].output), c_in.index(senses[st]))
                if name not in master.fmus[ctrl].variables:
                    raise SweepInputError(f"the controller {ctrl!r} has no gain parameter "
                                          f"{name} (from {st} to {u})")
                gains.append((a, b, name))
    lon = _instances_with(master, LONGITUDINAL.state_names)
    earth = _instances_with(master, EARTH, starts=False)
    record = (*(f"{plant}.{st}" for st in STATE_NAMES),
              *(f"{ctrl}.{drives[u].output}" for u in controls),
              *(f"{lon[0]}.{st}" for st in LONGITUDINAL.state_names[:len(lon) * 4]),
              *(f"{earth[0]}.{n}" for n in EARTH[:len(earth) * 3]))
    return LateralLoop(plant, ctrl, record, controls, tuple(gains),
                       lon[0] if len(lon) == 1 else None, earth[0] if len(earth) == 1 else None)


def check_system(ref: SystemRef, set_values: Mapping[str, Any] | None,
                 master: str = "gauss-seidel") -> tuple[LateralLoop, dict[str, Any]]:
    """Open the system here, before any file is written; apply ``--set`` values and find
    the lateral loop. Returns it and the ``--set`` values converted to their variables'
    declared types (:mod:`dronefly.harness.cosim.typed_values`), by ``instance.NAME``.

    Raises
    ------
    SweepInputError
        Unreadable SSP, a bad ``--set`` name, no lateral loop, a controller without gains.
    """

    try:
        system = System.from_ssp(ref.path).with_values(dict(set_values or {}))
        with SystemMaster(system, master) as m:
            m.run(1e-3, 1, record=[])  # one step: every --set name is checked by the master
            typed = {key: m.system.parameters[key.partition(".")[0]][key.partition(".")[2]]
                     for key in (set_values or {})}
            return _lateral_loop(m), typed
    except (SystemSpecError, FMUError) as e:
        raise SweepInputError(str(e)) from e


def _open(ref: SystemRef, data: bytes | None,
          master: str = "gauss-seidel") -> tuple[Any, LateralLoop]:
    key = (threading.get_ident(), ref.digest, master)
    with _LOCK:
        if key not in _OPEN:
            path = ref.path
            if data is not None and not Path(path).is_file():
                d = tempfile.mkdtemp(prefix="dronefly_sweep_")
                path = str(Path(d, Path(ref.path).name))
                Path(path).write_bytes(data)
            m = SystemMaster(System.from_ssp(path), master)
            _OPEN[key] = (m, _lateral_loop(m))
        return _OPEN[key]


def close_systems(*, forget: bool = False) -> None:
    """Close every system this process opened (worker exit); ``forget``: drop them unclosed
    (a forked worker: they belong to the parent, which deletes their extractions)."""
    with _LOCK:
        for m, _ in ([] if forget else _OPEN.values()):
            m.close()
        _OPEN.clear()


def open_system(ref: SystemRef, data: bytes | None = None) -> None:
    """Open the system in this thread before any case is timed."""
    _open(ref, data)


def run_system_case(ref: SystemRef, case: Any,
                    data: bytes | None = None) -> tuple[Any, LateralLoop, np.ndarray]:
    """Run one sweep case on the system; returns (LoopRun, LateralLoop, x = x+ * scale)."""
    m, loop = _open(ref, data, case.master)
    values: dict[str, dict[str, Any]] = {}
    for full, v in case.plant_values:
        inst, _, name = full.partition(".")
        if inst in m.fmus:  # --compare: each system takes the values of its instances
            values.setdefault(inst, {})[name] = v
    if loop.longitudinal:  # the case is a lateral disturbance: no longitudinal one unless set
        lon = values.setdefault(loop.longitudinal, {})
        for s in LONGITUDINAL.state_names:
            lon.setdefault(f"{s}_start", 0.0)
    plant = {**m.fmus[loop.plant].start_values(), **m.system.parameters.get(loop.plant, {}),
             **values.get(loop.plant, {})}
    scale = np.array(plant_scales(plant))
    n = float(plant["n"])
    values.setdefault(loop.plant, {}).update(
        {f"{s}_start": float(x) for s, x in zip(STATE_NAMES, np.asarray(case.x0) * scale)})
    ctrl = values.setdefault(loop.controller, {})
    for a, b, name in loop.gains:
        ctrl[name] = float(case.K[a][b])
    run = m.run(case.step_wb / n, case.n_steps, record=list(loop.record), values=values)
    return run, loop, scale
