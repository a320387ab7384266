"""Benchmark part: the cost of a plant step, the nonlinear 6-DOF plant against the linear ones.

The nonlinear plant DroneFlyHover6DOF replaces two linear plants, DroneFlyLateral and
DroneFlyLongitudinal: in a closed loop one doStep of it replaces two doSteps. Its target ("the
nonlinear plant's doStep should cost no more than 5x the linear plant's") is therefore
checked against the pair it replaces, at both steps timed. DroneFlyLateral alone is reported
beside it (the linear plant of the paper's lateral loop), for the reader who reads "the linear
plant" as one FMU; it is not the target's baseline. Timed:

  model  in-process, the model classes alone: ``Hover6DOF.step`` against
         ``LateralModel.step_list`` + ``LongitudinalModel.step_list`` (what the FMUs' doStep
         call)
  fmi    through fmpy, one communication step of a plant as a master drives it: set the
         inputs, fmi2DoStep, get the outputs (6-DOF: 7 inputs, 8 state outputs; the pair: 3
         and 4 inputs, 4 and 4 outputs, two doSteps; the lateral plant alone: 3 inputs, 4
         outputs)

at communication steps of 0.1 wing beat (the closed-loop benchmark's step: one Runge-Kutta
sub-step) and 1 wing beat (the comparison sweep's: five sub-steps of 0.2 wing beat). Held
controls of 0.01 rad from the Sect. 3.6 box edge (dp = 0.15, dgamma = 0.22). The plants are
open-loop unstable, so every run restarts from that state after :data:`SEGMENT_WB` wing beats;
the restart (through FMI an fmi2SetFMUstate to the state saved after initialization) is not
timed. The nonlinear plant's cost grows with its rotation rate (shorter sub-steps): a state
left to grow for hundreds of wing beats would time a tumbling body, not a plant near hover.

Timed in CPU time of this process (``time.process_time``): on a shared machine the wall time
of a step grows with the other processes' load, unevenly between the timings compared; the
CPU time a step takes much less so. BLAS is held to one thread while timing
(``threadpoolctl``, as the sweep's workers): an (untimed) set-up that calls numpy's BLAS,
such as the linear plants' initialization, otherwise leaves OpenBLAS's worker threads spinning,
and their CPU time, counted as this process's, doubled the timings that followed.

Part of ``benchmarks/run.py``; alone: ``python benchmarks/plants.py [--steps N] [--repeats R]``
(builds the three plant FMUs into a temporary folder; exits 1 when a ratio 6-DOF/pair through
FMI is 5 or more at either step).
"""

from __future__ import annotations

import argparse
import contextlib
import os
import statistics
import sys
import tempfile
import time
from ctypes import c_double, c_uint
from datetime import datetime, timezone
from pathlib import Path

#: communication steps timed, wing beats
STEPS_WB = (0.1, 1.0)
#: wing beats run from the initial state before a restart (the rates stay below 0.5 rad per
#: wing beat, where the sub-steps are at their longest)
SEGMENT_WB = 10.0
#: target: 6-DOF / the pair it replaces, through FMI, at every step of STEPS_WB
TARGET_RATIO = 5.0
#: the plant FMUs timed: the 6-DOF plant, the pair it replaces, the lateral plant alone
SIDES = {"6dof": ("DroneFlyHover6DOF",), "pair": ("DroneFlyLateral", "DroneFlyLongitudinal"),
         "lateral": ("DroneFlyLateral",)}
_STARTS = {"delta_gamma_start": 0.22, "delta_p_start": 0.15 * 164.0}
_LAT_IN = ("delta_Phi_a", "delta_alpha_1a", "delta_alpha_2a")
_LON_IN = ("delta_Phi", "delta_alpha_1", "delta_phibar", "delta_alpha_2")
_LAT_OUT = ("delta_v", "delta_p", "delta_r", "delta_gamma")
_LON_OUT = ("delta_u", "delta_w", "delta_q", "delta_theta")


class PlantBench:
    """Timers of one plant step; ``keys`` name them, ``time(key, steps)`` -> us per step."""

    def __init__(self, fmus: dict[str, Path], stack: contextlib.ExitStack) -> None:
        from dronefly.harness.cosim.fmu import FMU
        from dronefly.models import lateral_dynamics
        from dronefly.models.rigid_body import Hover6DOF, quaternion_from_euler
        from dronefly.models import longitudinal_dynamics

        lp, np_ = lateral_dynamics.default_parameters(), longitudinal_dynamics.default_parameters()
        self._nl = Hover6DOF(lp, np_)
        self._lat, self._lon = lateral_dynamics.LateralModel(lp), longitudinal_dynamics.LongitudinalModel(np_)
        self._x6 = [0.0, 0.0, 0.0, 0.15, 0.0, 0.0, *quaternion_from_euler(0.22, 0.0, 0.0),
                    0.0, 0.0, 0.0]
        self._x4 = [0.0, 0.15, 0.0, 0.22]
        self._inst = {}
        for name in ("DroneFlyHover6DOF", "DroneFlyLateral", "DroneFlyLongitudinal"):
            fmu = stack.enter_context(FMU(fmus[name]))
            self._inst[name] = stack.enter_context(fmu.instantiate(logging=False))
        self.keys = [*(f"model {side} {h:g}" for h in STEPS_WB for side in ("6dof", "pair")),
                     *(f"fmi {side} {h:g}" for h in STEPS_WB for side in SIDES)]

    def time(self, key: str, steps: int) -> float:
        from threadpoolctl import threadpool_limits

        kind, side, h = key.split()
        h_wb = float(h)
        with threadpool_limits(limits=1, user_api="blas"):
            if kind == "model":
                return (self._model_6dof if side == "6dof" else self._model_pair)(h_wb, steps)
            return self._fmi([self._inst[n] for n in SIDES[side]], h_wb, steps)

    def _model_6dof(self, h: float, steps: int) -> float:
        step, cl, cn = self._nl.step, [0.01] * 3, [0.01] * 4
        total = 0.0
        for n in _segments(h, steps):
            x = self._x6
            t0 = time.process_time()
            for _ in range(n):
                x = step(x, cl, cn, h)
            total += time.process_time() - t0
        return total / steps * 1e6

    def _model_pair(self, h: float, steps: int) -> float:
        a, b = self._lat.step_list, self._lon.step_list
        cl, cn = [0.01] * 3, [0.01] * 4
        total = 0.0
        for n in _segments(h, steps):
            x, z = self._x4, [0.0] * 4
            t0 = time.process_time()
            for _ in range(n):
                x = a(x, cl, h)
                z = b(z, cn, h)
            total += time.process_time() - t0
        return total / steps * 1e6

    @staticmethod
    def _fmi(instances, h_wb: float, steps: int) -> float:
        h, total = h_wb / 164.0, 0.0
        calls = [_start(inst) for inst in instances]
        saved = [(inst.slave, inst.slave.getFMUstate()) for inst in instances]
        for n in _segments(h_wb, steps):
            for s, state in saved:  # back to the initial state (the clock too)
                s.setFMUstate(state)
            status = 0
            t0 = time.process_time()
            for k in range(n):
                t = k * h
                for set_, do, get, c, in_vr, ni, u, out_vr, no, y in calls:
                    set_(c, in_vr, ni, u)
                    status |= do(c, t, h, 1)
                    get(c, out_vr, no, y)
            total += time.process_time() - t0
            assert status == 0, "a step was refused"
        for s, state in saved:
            s.freeFMUstate(state)
        return total / steps * 1e6


def _segments(h_wb: float, steps: int) -> list[int]:
    """``steps`` split into runs of at most :data:`SEGMENT_WB` wing beats."""
    per = max(1, round(SEGMENT_WB / h_wb))
    return [per] * (steps // per) + ([steps % per] if steps % per else [])


def _start(inst) -> tuple:
    """Reset and initialize an instance at the box edge; its set/doStep/get calls and buffers."""
    s = inst.slave
    s.reset()
    s.setupExperiment(startTime=0.0)
    s.enterInitializationMode()
    starts = {k: v for k, v in _STARTS.items() if k in inst.fmu.variables}
    s.setReal(inst.vrs(list(starts)), list(starts.values()))
    s.exitInitializationMode()
    ins = [n for n in (*_LAT_IN, *_LON_IN) if n in inst.fmu.variables]
    outs = [n for n in (*_LAT_OUT, *_LON_OUT) if n in inst.fmu.variables]
    in_vr, out_vr = (c_uint * len(ins))(*inst.vrs(ins)), (c_uint * len(outs))(*inst.vrs(outs))
    u, y = (c_double * len(ins))(*[0.01] * len(ins)), (c_double * len(outs))()
    return (s.fmi2SetReal, s.fmi2DoStep, s.fmi2GetReal, s.component, in_vr, len(ins), u,
            out_vr, len(outs), y)


def report(med: dict[str, float]) -> tuple[list[str], dict[float, float]]:
    """Lines of the report and, per step [wing beats], the ratio 6-DOF / pair through FMI."""
    lines = ["\nthe nonlinear 6-DOF plant against the linear plants, per communication step "
             "[us/step]",
             "  through FMI (set inputs, doStep, get outputs): 6-DOF against the pair it "
             "replaces (lateral + longitudinal: two doSteps) and against the lateral plant "
             "alone",
             "  step [wb]     6-DOF      pair  6-DOF/pair   lateral  6-DOF/lateral"]
    ratios = {}
    for h in STEPS_WB:
        f6, fp, fl = (med[f"fmi {side} {h:g}"] for side in SIDES)
        ratios[h] = f6 / fp
        lines.append(f"  {h:9g} {f6:9.2f} {fp:9.2f} {f6 / fp:11.2f} {fl:9.2f} {f6 / fl:14.2f}")
    lines += ["  in-process (the model classes' step, no FMI): 6-DOF against the pair",
              "  step [wb]     6-DOF      pair  6-DOF/pair"]
    for h in STEPS_WB:
        m6, mp = med[f"model 6dof {h:g}"], med[f"model pair {h:g}"]
        lines.append(f"  {h:9g} {m6:9.2f} {mp:9.2f} {m6 / mp:11.2f}")
    lines.append("ratio 6-DOF/pair through FMI: " + ", ".join(
        f"{r:.2f} at {h:g} wing beat" for h, r in ratios.items())
        + f" (target < {TARGET_RATIO:g} at each)")
    return lines, ratios


def steps_for(key: str, steps: int) -> int:
    """Steps timed for ``key``: a step of 1 wing beat costs about five of 0.1 (five
    sub-steps against one), so a fifth of them at 1 wing beat."""
    return steps if key.endswith(" 0.1") else max(steps // 5, 2)


def _load() -> str:
    return "load average {:.2f}, {:.2f}, {:.2f} (1, 5, 15 min)".format(*os.getloadavg())


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--steps", type=int, default=2000)
    ap.add_argument("--repeats", type=int, default=9)
    args = ap.parse_args(argv)
    if args.steps < 2 or args.repeats < 1:
        ap.error("--steps must be >= 2 and --repeats >= 1")
    from dronefly.harness.builder.build import build_fmu

    start = datetime.now(timezone.utc)
    print(f"started {start:%Y-%m-%d %H:%M} UTC, {os.cpu_count()} cores, {_load()}")
    times: dict[str, list[float]] = {}
    with tempfile.TemporaryDirectory() as tmp, contextlib.ExitStack() as stack:
        fmus = {n: build_fmu(n, tmp) for n in dict.fromkeys(n for s in SIDES.values() for n in s)}
        bench = PlantBench(fmus, stack)
        for key in bench.keys:  # warm up (the linear models' matrix exponentials)
            bench.time(key, 2)
        for r in range(args.repeats):  # interleaved, the order reversed every other repeat
            for key in (bench.keys if r % 2 == 0 else bench.keys[::-1]):
                times.setdefault(key, []).append(bench.time(key, steps_for(key, args.steps)))
    med = {k: statistics.median(v) for k, v in times.items()}
    print(f"medians of {args.repeats} interleaved repeats x {args.steps} steps (a fifth at 1 "
          "wing beat), CPU time")
    lines, ratios = report(med)
    print("\n".join(lines))
    print(f"finished {datetime.now(timezone.utc):%Y-%m-%d %H:%M} UTC, {_load()}")
    return 0 if all(r < TARGET_RATIO for r in ratios.values()) else 1


if __name__ == "__main__":
    sys.exit(main())
