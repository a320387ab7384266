"""The paper's controller on the flapping insect, co-simulated through the project's master.

The system of :func:`dronefly.harness.cosim.ssp.flapping_system`: the ``DroneFlyFlapping`` FMU
and the lateral controller FMU ``StateFeedback`` (gains on delta_Phi_a), the plant's
longitudinal inputs unconnected at their start values, the plant starting on its periodic
orbit with a roll, run by :class:`~dronefly.harness.cosim.system_master.SystemMaster`
(Gauss-Seidel) at a communication step of one wing beat: the controller samples once per
beat, as flies do. For each gain set of :func:`.closed_loop.closed_loop_report`:

- **the verdict identified from runs**: four runs of the system from the orbit with x+ = eps
  e_j added (eps = :data:`AMPLITUDE`), sampled once per wing beat, fitted by the project's one
  identification (:func:`dronefly.harness.cosim.identification.verdict_of`, fit residual within
  :data:`~dronefly.harness.cosim.identification.FIT_RESIDUAL_TOL`; not from the run from the roll,
  whose nonlinearity the fit would leave: 2.4e-6 of |z| at 1e-3 already). The loop's state is
  z = (x+_k, x+_(k-1)): a beat's stroke starts from the rear reversal the last beat reached,
  so the control of the last beat, K x+_(k-1), acts in this one (the Jacobi form of the fit;
  before the first beat the plant flapped with the controls of its initialization, 0, so
  x+_(-1) = 0). The identified exponents are cross-checked against the linearised wing-beat
  map's (:attr:`.closed_loop.ClosedLoopReport.flapping`): a difference beyond
  :data:`~dronefly.harness.cosim.identification.RATE_TOL_PER_WINGBEAT`, or another verdict, is an
  error (:class:`~dronefly.core.errors.CrossCheckError`), not a verdict;
- **the recovery from a 0.1 rad roll**: gamma after 10, 20 and 30 beats, the largest
  |delta_Phi_a|;
- **the oscillation within the last beat**: the same run at a step of 0.1 wing beat (the
  controller then updates its output ten times per beat, and the plant takes the value set
  at each beat's start: the beats' starts are the same bits as at a step of one beat), the
  roll angle's and the position's swing (peak to peak, the beat's drift removed: the growth
  or decay of the roll over the beat is not its oscillation) over the 11 instants of the last
  beat.

Gauss-Seidel, not Jacobi: under Gauss-Seidel the controller answers the state of the same
point, so the control the plant takes at a beat's start is K x+ of that start whatever the
step. Under Jacobi it answers the previous point's: the control taken at beat k is K x+ at
k - h, one communication step stale, a delay that changes with the step (a whole wing beat at
h = 1, a tenth at h = 0.1), so the two steps fly two different loops.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Mapping, Sequence

import numpy as np

from ...core.errors import CrossCheckError, DroneflyError
from ...core.text import complexes_text
from ...models.feedback import PAPER_GAINS_EQ27
from ...models.flapping import STEPS_PER_BEAT
from ...models.lateral_interface import N_HZ, STATE_NAMES, U_M_PER_S
from ..cosim.ssp import flapping_starts, flapping_system, write_system_ssp
from ..cosim.identification import (RATE_TOL_PER_WINGBEAT, Verdict, classify, unit_start_values,
                               verdict_of)
from ..cosim.system_master import SystemMaster
from .closed_loop import ClosedLoopReport, closed_loop_report

__all__ = ["AMPLITUDE", "FINE_STEP_WB", "IDENTIFICATION_BEATS", "MasterLoop", "MasterReport",
           "master_report", "write_flapping_ssp"]

#: size of the initial x+ of the identification runs (non-dimensional). The lateral map is odd
#: in the lateral state (left-right symmetry), so what a linear fit leaves is cubic: 2.4e-10 of
#: |z| at 1e-5 (2.4e-8 at 1e-4, measured over 20-beat runs; 0.8e-10 and 1.2e-10 over the 10
#: beats of IDENTIFICATION_BEATS), round-off 1.2e-10 at 1e-6; 1e-5 keeps the fit within
#: FIT_RESIDUAL_TOL (1e-9) with a factor 4 or more
AMPLITUDE = 1e-5
#: wing beats of each identification run (40 pairs in all for the 8 x 8 fit: the loop is linear
#: to the fit residual, so more beats add nothing)
IDENTIFICATION_BEATS = 10
#: the finer communication step, wing beats
FINE_STEP_WB = 0.1
_SCALE = np.array([U_M_PER_S, N_HZ, N_HZ, 1.0])  # x+ times this: the plant's SI outputs
_STATES = [f"plant.{s}" for s in STATE_NAMES]
_RECORD = [*_STATES, "lateral_controller.delta_Phi_a", "plant.phi", "plant.x_earth",
           "plant.y_earth", "plant.z_earth"]


@dataclass
class MasterLoop:
    """One gain set's loop through the master."""

    gains: list[float]
    verdict: Verdict  # identified from the identification runs, once per wing beat
    map_exponents: list[complex]  # of the linearised wing-beat map, per wing beat
    deviation: float  # max |identified - map| exponent, per wing beat
    states: np.ndarray  # x+ at the beats' starts (step of one wing beat), (beats + 1, 4)
    controls: np.ndarray  # delta_Phi_a taken at each beat's start [rad], (beats,)
    fine_deviation: float  # max |x+ at the beats' starts, step 0.1 minus step 1|
    oscillation: dict[str, float]  # within the last beat: roll_pp_deg, x/y/z_pp_um

    @property
    def gamma(self) -> np.ndarray:
        """dgamma at the beats' starts [rad]."""
        return self.states[:, 3]


@dataclass
class MasterReport:
    """Both gain sets' loops through the master, and the step they ran at."""

    beats: int
    roll0_rad: float
    loops: dict[str, MasterLoop]

    def text(self) -> str:
        lines = ["DroneFlyFlapping + StateFeedback through SystemMaster (gauss-seidel), "
                 "a step of 1 wing beat: the controller samples once per beat"]
        for name, loop in self.loops.items():
            ident = loop.verdict.identification
            g, n = loop.gamma, self.beats
            osc = loop.oscillation
            same = ("the same bits" if loop.fine_deviation == 0.0
                    else f"within {loop.fine_deviation:.1e}")
            lines += [
                "",
                f"{name}: {ident.verdict} (dominant rate {ident.dominant_growth_rate:+.4f} per "
                "wing beat)",
                f"  identified from runs (4 x {IDENTIFICATION_BEATS} wing beats from the orbit, "
                f"x+ {AMPLITUDE:g}; fit residual < 1e-9): " + complexes_text(ident.eigenvalues),
                f"  linearised wing-beat map: {complexes_text(loop.map_exponents)} (max deviation "
                f"< {RATE_TOL_PER_WINGBEAT:g})",
                f"  from a {self.roll0_rad:g} rad roll: gamma {g[10]:+.4f} rad after 10 wing "
                f"beats, {g[20]:+.4f} after 20, {g[n]:+.4f} after {n}; largest |delta_Phi_a| "
                f"{np.max(np.abs(loop.controls)):.4f} rad",
                f"  within the last beat (step {FINE_STEP_WB:g} wing beat; beat starts {same} "
                f"as at step 1), peak to peak, the beat's drift removed: roll "
                f"{osc['roll_pp_deg']:.4f} deg, position x {osc['x_pp_um']:.2f}, y "
                f"{osc['y_pp_um']:.2f}, z {osc['z_pp_um']:.2f} um",
            ]
        return "\n".join(lines)


def _swing(x: np.ndarray) -> float:
    """Peak to peak of ``x`` over a beat's equally spaced instants (its first and last the
    beat's start and end), the beat's drift (the straight line between them) removed."""
    tau = np.linspace(0.0, 1.0, len(x))
    dev = x - x[0] - (x[-1] - x[0]) * tau
    return float(dev.max() - dev.min())


def _loop(master: SystemMaster, report: ClosedLoopReport, name: str, beats: int,
          roll0_rad: float) -> MasterLoop:
    h = 1.0 / N_HZ
    coarse = master.run(h, beats, record=_RECORD)
    fine_n = round(1.0 / FINE_STEP_WB)
    fine = master.run(FINE_STEP_WB * h, beats * fine_n, record=_RECORD)
    for run in (coarse, fine):
        if not run.complete:
            raise CrossCheckError(f"{name}: the run from a {roll0_rad!r} rad roll failed: "
                                  f"{run.failure}")
    states = coarse.signals[:, :4] / _SCALE
    fine_states = fine.signals[::fine_n, :4] / _SCALE
    last = fine.signals[-(fine_n + 1):]
    oscillation = {"roll_pp_deg": math.degrees(_swing(last[:, 5])),
                   **{f"{c}_pp_um": _swing(last[:, 6 + i]) * 1e6 for i, c in enumerate("xyz")}}
    # the identification: from the orbit with x+ = AMPLITUDE e_j, roll0 0
    orbit = flapping_starts(report.orbit.z0)
    runs = []
    for unit in unit_start_values(_SCALE * AMPLITUDE):
        start = {k: orbit[k] + unit.get(k, 0.0) for k in orbit}
        r = master.run(h, IDENTIFICATION_BEATS, record=_STATES, values={"plant": start})
        if not r.complete:
            raise CrossCheckError(f"{name}: an identification run failed: {r.failure}")
        # x+_(-1) = 0: before the first beat the plant flapped with its initial controls, 0
        runs.append(np.vstack([np.zeros(4), r.signals / _SCALE]))
    verdict = verdict_of(runs, 1.0, delay=True, where=f"the flapping loop ({name})")
    exact = np.array(report.flapping[name], dtype=complex)
    ident = verdict.identification.eigenvalues
    if len(ident) != len(exact):
        raise CrossCheckError(f"{name}: {len(ident)} exponents identified from the runs "
                              f"({list(ident)!r}), the linearised wing-beat map has "
                              f"{len(exact)} ({list(exact)!r})")
    deviation = float(np.max(np.abs(ident - exact)))
    if not deviation <= RATE_TOL_PER_WINGBEAT or verdict.verdict != classify(exact):
        raise CrossCheckError(
            f"{name}: the exponents identified from the runs {list(ident)!r} (verdict "
            f"{verdict.verdict!r}) deviate from the linearised wing-beat map's {list(exact)!r} "
            f"(verdict {classify(exact)!r}) by {deviation:.1e} per wing beat (tolerance "
            f"{RATE_TOL_PER_WINGBEAT:g})")
    return MasterLoop(list(report.gains[name]), verdict, list(exact), deviation, states,
                      coarse.signals[:-1, 4].copy(),
                      float(np.max(np.abs(fine_states - states))), oscillation)


def master_report(fmus: Mapping[str, str | Path], report: ClosedLoopReport | None = None,
                  beats: int = 30, roll0_rad: float = 0.1) -> MasterReport:
    """Both gain sets of ``report`` flown through the master (see the module text).

    Parameters
    ----------
    fmus : mapping
        Model name (``DroneFlyFlapping``, ``StateFeedback``) -> FMU path.
    report : ClosedLoopReport, optional
        The gain sets, the orbit and the linearised map's exponents, computed with the FMU's
        :data:`~dronefly.models.flapping.STEPS_PER_BEAT` (default: computed so).
    beats : int
        Wing beats of the run from the roll (at least 20).
    roll0_rad : float
        The roll added to the orbit's start [rad].

    Raises
    ------
    DroneflyError
        A ``report`` not of the FMU's integration, or fewer than 20 ``beats``.
    CrossCheckError
        A run failed, the identification's fit residual is too large, or the identified
        exponents contradict the linearised map's.
    """
    report = report or closed_loop_report(steps_per_beat=STEPS_PER_BEAT)
    if report.steps_per_beat != STEPS_PER_BEAT or report.orbit is None:
        raise DroneflyError(f"report.steps_per_beat = {report.steps_per_beat!r}: the map "
                              f"must be the FMU's ({STEPS_PER_BEAT} Runge-Kutta steps per beat)")
    if not (isinstance(beats, int) and beats >= 20):
        raise DroneflyError(f"beats = {beats!r} must be a whole number >= 20")
    loops = {}
    for name, gains in report.gains.items():
        system = flapping_system(fmus, gains, roll0_rad, float(beats), report.orbit.z0)
        with SystemMaster(system) as master:
            loops[name] = _loop(master, report, name, beats, roll0_rad)
    return MasterReport(beats, roll0_rad, loops)


def write_flapping_ssp(fmu_dir: str | Path, path: str | Path,
                       gains: Sequence[float] = PAPER_GAINS_EQ27, roll0_rad: float = 0.1,
                       stop_wb: float = 30.0) -> Path:
    """Write the flapping insect's lateral loop
    (:func:`~dronefly.harness.cosim.ssp.flapping_system`) with the FMUs of ``fmu_dir`` as an SSP,
    for ``dronefly cosim --system PATH --step 1``, and return its path.

    Parameters
    ----------
    fmu_dir : str or Path
        The folder of ``DroneFlyFlapping.fmu`` and ``StateFeedback.fmu`` (as ``dronefly build``
        writes them).
    path : str or Path
        The SSP file to write.
    gains : sequence of 4 floats
        Non-dimensional gains of delta_Phi_a [rad] on x+ (default Eq. (27)).
    roll0_rad : float
        Roll added to the orbit's start [rad].
    stop_wb : float
        The SSP's DefaultExperiment stop time [wing beats].
    """
    fmus = {p.stem: p for p in Path(fmu_dir).glob("*.fmu")}
    return write_system_ssp(flapping_system(fmus, gains, roll0_rad, stop_wb), path)
