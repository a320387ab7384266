"""``dronefly cosim --system FILE.ssp``: co-simulate any system, and give per-axis verdicts.

:func:`cosimulate_system` is the Python API of the command. It opens the system (an SSP
file or a :class:`System`), applies ``instance.NAME=VALUE`` settings, runs it with the
:class:`SystemMaster`, records the outputs, and, for every plant of the system (see
:mod:`..cosim.verdicts`), identifies the closed-loop eigenvalues from runs of the whole system:

- at the run's communication step: the verdict, and the deviation from the exact
  sampled-data loop at that step;
- at a step of :data:`CHECK_STEP_WB` wing beats: the deviation from eig(A + B K) of the
  continuous loop (the sampled-data loop differs from it by O(step)), which must not exceed
  :data:`CHECK_TOL_PER_WINGBEAT`: a larger one is a failed cross-check
  (:attr:`SystemResult.check_failures`; ``dronefly cosim`` exits 1). Where the identified
  eigenvalues are not as many (the Jacobi loop's delay modes) there is no comparison.

With ``open_loop`` each plant's open loop is identified as well, from runs with the gains of
its controller set to zero (:func:`..cosim.verdicts.open_loop_verdicts`), and cross-checked against
eig(A) in the same way.

Times are in wing beats of the system's wing-beat frequency (the parameter ``n`` of its
plants, which must agree); a system without one counts in seconds (n = 1 Hz).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np

from ...core.extras import pyplot
from ...core.files import run_name, write_run_files
from ...core.text import complex_text
from ..cosim.fmu import column_units
from ..cosim.master import LoopRun, step_count
from ..cosim.system import System, SystemSpecError
from ..cosim.system_master import SystemMaster
from ..cosim.verdicts import AxisVerdict, NotIdentified, axis_verdicts, open_loop_verdicts

__all__ = ["CHECK_STEP_WB", "CHECK_TOL_PER_WINGBEAT", "SystemResult", "cosimulate_system"]

#: step of the identification that is compared with eig(A + B K), wing beats
CHECK_STEP_WB = 1e-5
#: largest deviation of the eigenvalues identified at CHECK_STEP_WB from eig(A + B K) (open
#: loop: eig(A)) that passes the cross-check, per wing beat
CHECK_TOL_PER_WINGBEAT = 1e-6


@dataclass
class SystemResult:
    """Everything one co-simulation of a system established."""

    system: str
    run: LoopRun
    master: str
    step_wingbeats: float
    stop_wingbeats: float
    n_hz: float
    axes: list[AxisVerdict]
    continuous_deviation: dict[str, float | None] = field(default_factory=dict)
    csv: Path | None = None
    plot: Path | None = None
    #: per plant instance, with ``open_loop``: its open-loop verdict (or why there is none)
    open_loop: dict[str, AxisVerdict | NotIdentified] | None = None
    open_loop_deviation: dict[str, float | None] = field(default_factory=dict)
    #: the failed cross-checks, one sentence each (empty: all passed or none possible)
    check_failures: list[str] = field(default_factory=list)
    check_tol: float = CHECK_TOL_PER_WINGBEAT
    #: the unit of the step and stop: "wing beats", or "s" when no instance has a wing-beat
    #: frequency n [Hz] (then a "wing beat" is one second)
    time_unit: str = "wing beats"
    #: the verdicts were sought (asked for, and the run complete): no axes then means no plant
    sought_verdicts: bool = False
    #: the outputs that cannot be recorded, with their types (``SystemMaster.unrecordable``)
    unrecordable: dict[str, str] = field(default_factory=dict)
    #: the unit of every recorded column, as its FMU declares it (``time`` in s)
    units: dict[str, str] = field(default_factory=dict)

    def to_json(self) -> dict[str, Any]:
        axes = []
        for a in self.axes:
            j = a.to_json()
            j["continuous_check"] = self._check_json(self.continuous_deviation, a)
            if self.open_loop is not None:
                o = self.open_loop[a.plant.instance]
                j["open_loop"] = o.to_json()
                if isinstance(o, AxisVerdict):
                    j["open_loop"]["zeroed"] = [f"{a.plant.controller}.{k}"
                                                for k in a.plant.gains]
                    j["open_loop"]["continuous_check"] = self._check_json(
                        self.open_loop_deviation, o)
            axes.append(j)
        return {"system": self.system, "complete": self.run.complete,
                "failure": None if self.run.complete else str(self.run.failure),
                "master": self.master, "step_wingbeats": self.step_wingbeats,
                "stop_wingbeats": self.stop_wingbeats, "wingbeat_frequency_hz": self.n_hz,
                "time_unit": self.time_unit, "ended_at_s": self._ended_at(),
                "axes": axes, "check_failures": list(self.check_failures),
                "recorded": list(self.run.names), "not_recorded": dict(self.unrecordable),
                "units": dict(self.units),
                "csv": None if self.csv is None else str(self.csv),
                "plot": None if self.plot is None else str(self.plot)}

    def _check_json(self, deviation: dict[str, float | None], a: AxisVerdict) -> dict[str, Any]:
        dev = deviation.get(a.plant.instance)
        return {"step_wingbeats": CHECK_STEP_WB, "max_deviation": dev,
                "tolerance": self.check_tol,
                "passed": None if dev is None else _passed(dev, self.check_tol)}

    def _ended_at(self) -> float | None:
        """The time [s] an FMU ended the run at before the stop time (None: it did not)."""
        n_steps = round(self.stop_wingbeats / self.step_wingbeats)
        if self.run.complete and len(self.run.time) - 1 < n_steps:
            return float(self.run.time[-1])
        return None

    def summary(self) -> str:
        u = self.time_unit
        lines = [f"system {self.system}: {self.master} master, step {self.step_wingbeats:g} "
                 f"{u}, {len(self.run.time) - 1} steps to {self.stop_wingbeats:g} "
                 f"{u}, {len(self.run.names)} outputs recorded"]
        if self.unrecordable:
            shown = ", ".join(f"{n} ({t})" for n, t in self.unrecordable.items())
            lines.append(f"not recorded: {shown}: the records are doubles, and integers are "
                         "read as 32-bit ones (Real, Boolean and integer types up to Int32 are "
                         "recorded)")
        ended = self._ended_at()
        if ended is not None:
            lines.append(f"an FMU ended the run at t = {ended:g} s (terminateSimulation / "
                         "fmi2Terminated), before the stop time")
        if self.sought_verdicts and not self.axes:
            lines.append(("open loop" if self.open_loop is not None else "no verdict") +
                         f": nothing to identify: the system has no plant ({_PLANT})")
        for a in self.axes:
            ev = ", ".join(complex_text(z) for z in a.identification.eigenvalues)
            lines.append(f"{a.plant.instance} ({a.plant.model}): {a.verdict} (dominant rate "
                         f"{a.identification.dominant_growth_rate:+.5f} per wing beat); "
                         f"identified {ev}")
            if a.continuous is not None:
                lines.append(f"  eig(A + B K): {', '.join(complex_text(z) for z in a.continuous)}"
                             + self._check_text(self.continuous_deviation, a))
            o = None if self.open_loop is None else self.open_loop[a.plant.instance]
            if isinstance(o, NotIdentified):
                lines.append(f"  open loop: not identified ({o.reason})")
            elif o is not None:
                lines.append(f"  open loop: {o.verdict} (dominant rate "
                             f"{o.identification.dominant_growth_rate:+.5f} per wing beat)"
                             + ("" if o.continuous is None else "; eig(A): " + ", ".join(
                                 complex_text(z) for z in o.continuous)
                                 + self._check_text(self.open_loop_deviation, o)))
        if not self.run.complete:
            lines.append(f"INCOMPLETE: {self.run.failure}")
        lines += [f"CROSS-CHECK FAILED: {f}" for f in self.check_failures]
        for label, path in (("csv", self.csv), ("plot", self.plot)):
            if path:
                lines.append(f"{label}: {path}")
        return "\n".join(lines)

    def _check_text(self, deviation: dict[str, float | None], a: AxisVerdict) -> str:
        dev = deviation.get(a.plant.instance)
        if dev is None:
            return ""
        # A passed check prints its tolerance, not the deviation: identified at a step of h,
        # the deviation is round-off amplified by 1/h, its digits differ between machines
        # (the JSON's max_deviation has the value).
        if _passed(dev, self.check_tol):
            return (f" (identified at a step of {CHECK_STEP_WB:g} wing beats: max deviation "
                    f"< {self.check_tol:g})")
        return (f" (identified at a step of {CHECK_STEP_WB:g} wing beats: max deviation "
                f"{dev:.1e} > {self.check_tol:g}: cross-check failed)")


#: what makes an instance a plant whose loop this master identifies (harness.cosim.verdicts)
_PLANT = "an instance with an x_start parameter per Real output x and the scales n and U"


def _passed(dev: float, tol: float) -> bool:
    return dev <= tol  # False for NaN


def _has_wingbeats(master: SystemMaster) -> bool:
    return any((v := fmu.variables.get("n")) is not None and v.causality == "parameter"
               and v.unit == "Hz" for fmu in master.fmus.values())


def _shared_scale(master: SystemMaster, name: str, unit: str) -> set[float]:
    """The values of the reference scale ``name`` [``unit``] over the instances that have it
    (each reads the others' states with its own: they must agree)."""
    found = {}
    for inst, fmu in master.fmus.items():
        v = fmu.variables.get(name)
        if v is not None and v.causality == "parameter" and v.unit == unit:
            found[inst] = float(master.system.parameters.get(inst, {}).get(name, v.start))
    values = set(found.values())
    if len(values) > 1:
        raise SystemSpecError(f"the instances disagree on {name} [{unit}]: " + ", ".join(
            f"{i}.{name} = {v!r}" for i, v in found.items()))
    return values


def _wingbeat_frequency(master: SystemMaster) -> float:
    _shared_scale(master, "U", "m/s")
    values = _shared_scale(master, "n", "Hz")
    n = values.pop() if values else 1.0
    if not (math.isfinite(n) and n > 0):
        raise SystemSpecError(f"n = {n!r} Hz must be finite and > 0")
    return n


def cosimulate_system(system: System | str | Path, *, step_wingbeats: float = 0.1,
                      stop_wingbeats: float | None = None, master: str = "gauss-seidel",
                      set_values: Mapping[str, Any] | None = None,
                      record: Sequence[str] | None = None, verdicts: bool = True,
                      out_dir: str | Path | None = "build/cosim", plot: bool = True,
                      name: str | None = None, open_loop: bool = False) -> SystemResult:
    """Co-simulate a system and identify each plant's loop.

    Parameters
    ----------
    system : System or path
        The system, or an SSP file to read it from.
    step_wingbeats : float
        Communication step in wing beats (in seconds for a system without a wing-beat
        frequency: no instance with a parameter ``n`` in Hz).
    stop_wingbeats : float, optional
        Stop time in wing beats (seconds, as the step; default: the SSP's
        DefaultExperiment, else 300).
    master : {'gauss-seidel', 'jacobi'}
    set_values : mapping, optional
        ``{"instance.NAME": value}``: parameter or input values, in the FMU's unit, as
        numbers, booleans or text (as ``--set`` gives them), converted to each variable's
        declared type when the system is opened (:mod:`..cosim.typed_values`).
    record : sequence of str, optional
        Variables ``instance.name`` to record: any Real, Integer or Boolean variable of any
        instance (default: every Real, Integer and Boolean output).
    verdicts : bool
        Identify each plant's loop (extra short runs).
    out_dir : path or None
        Where the CSV, JSON (and PNG) go; None writes nothing.
    open_loop : bool
        With ``verdicts``: also identify each plant's open loop (its controller's gains set
        to zero) and cross-check it against eig(A).

    A failed cross-check (see the module text) does not raise: it is listed in the result's
    ``check_failures``, and the outputs are written as for any run.
    """
    if not isinstance(system, System):
        system = System.from_ssp(system)
    if set_values:
        system = system.with_values(set_values)
    with SystemMaster(system, master) as m:
        n = _wingbeat_frequency(m)
        unit = "wing beats" if _has_wingbeats(m) else "s"
        default_stop = ((system.stop_s - system.start_s) * n if system.stop_s is not None
                        else 300.0)  # the SSP's DefaultExperiment
        stop = stop_wingbeats if stop_wingbeats is not None else default_stop
        n_steps = step_count(stop, step_wingbeats)
        stop = round(n_steps * step_wingbeats, 12)
        run = m.run(step_wingbeats / n, n_steps, record=record)
        units = column_units(run.names, m.fmus)
        axes, deviation, opened, open_dev = [], {}, None, {}
        if verdicts and run.complete:
            axes = axis_verdicts(m, step_wingbeats)
            deviation = _deviations(axis_verdicts(m, CHECK_STEP_WB) if axes else [])
            if open_loop:
                opened = {o.plant.instance: o for o in open_loop_verdicts(m, step_wingbeats)}
                open_dev = _deviations([o for o in open_loop_verdicts(m, CHECK_STEP_WB)
                                        if isinstance(o, AxisVerdict)])
    tol = CHECK_TOL_PER_WINGBEAT
    failures = _failures(axes, deviation, "eig(A + B K)", tol) + _failures(
        [o for o in (opened or {}).values() if isinstance(o, AxisVerdict)], open_dev,
        "eig(A) (open loop)", tol)
    result = SystemResult(system.name, run, master, step_wingbeats, stop, n, axes, deviation,
                          open_loop=opened, open_loop_deviation=open_dev,
                          check_failures=failures, check_tol=tol, time_unit=unit,
                          sought_verdicts=verdicts and run.complete,
                          unrecordable=dict(m.unrecordable), units=units)
    if out_dir is not None:
        inputs = {k: v for k, v in (
            ("set", {k: repr(v) for k, v in sorted(dict(set_values or {}).items())} or None),
            ("step_wb", None if step_wingbeats == 0.1 else step_wingbeats),
            ("stop_wb", None if stop_wingbeats is None or stop_wingbeats == default_stop
             else stop_wingbeats), ("record", list(record or ()) or None),
            ("open_loop", open_loop or None)) if v is not None}
        write_run_files(result, out_dir, name or run_name(f"cosim_{system.name}_{master}", inputs),
                        _plot if plot else None)
    return result


def _deviations(fine: list[AxisVerdict]) -> dict[str, float | None]:
    """Per plant: max |identified - continuous| (None: nothing to compare, or not as many)."""
    out: dict[str, float | None] = {}
    for a in fine:
        ident = a.identification.eigenvalues
        out[a.plant.instance] = (float(np.max(np.abs(ident - a.continuous)))
                                 if a.continuous is not None and len(a.continuous) == len(ident)
                                 else None)
    return out


def _failures(axes: list[AxisVerdict], deviation: dict[str, float | None], against: str,
              tol: float) -> list[str]:
    out = []
    for a in axes:
        if a.continuous is None:
            continue  # nothing to check against (no A, B or K)
        # None: not as many eigenvalues (the Jacobi loop's delay modes): no comparison
        dev = deviation.get(a.plant.instance)
        if dev is not None and not dev <= tol:
            out.append(f"{a.plant.instance}: the eigenvalues identified at a step of "
                       f"{CHECK_STEP_WB:g} wing beats deviate from {against} by {dev:.1e} "
                       f"> {tol:g} per wing beat")
    return out


def _plot(result: SystemResult, path: Path) -> None:
    plt = pyplot()

    run = result.run
    groups: dict[str, list[int]] = {}
    for j, full in enumerate(run.names):
        groups.setdefault(full.partition(".")[0], []).append(j)
    fig, axs = plt.subplots(len(groups) or 1, 1, figsize=(10, 2.4 * max(len(groups), 1)),
                            sharex=True, squeeze=False, layout="constrained")
    t = run.time * result.n_hz
    verdict = {a.plant.instance: a.verdict for a in result.axes}
    for ax, (inst, cols) in zip(axs[:, 0], groups.items()):
        units = list(dict.fromkeys(result.units.get(run.names[j], "1") for j in cols))
        for j in cols:
            label = run.names[j].partition(".")[2]
            unit = result.units.get(run.names[j], "1")
            ax.plot(t, run.signals[:, j], label=label if len(units) == 1 else f"{label} [{unit}]")
        ax.set_title(f"{inst}" + (f" ({verdict[inst]})" if inst in verdict else ""),
                     fontsize=9)
        # the unit of every curve (SI, as the FMU declares it): on the axis if they share one
        ax.set_ylabel(f"[{units[0]}]" if len(units) == 1 else "SI units (legend)")
        ax.grid(True, alpha=0.3)
        # beside the axes, never over the curves
        ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0)
    axs[-1, 0].set_xlabel("time [wing beats]" if result.time_unit == "wing beats" else
                          "time [s]")
    fig.savefig(path, format="png", dpi=90)
    plt.close(fig)
