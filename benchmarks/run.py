"""Benchmark: microseconds per closed-loop communication step.

Measures, in one run, interleaved repeat by repeat (so that the machine's noise hits all
alike):
  ours    DroneFlyLateral + StateFeedback through the harness's pair API (harness.cosim.master.
          Loop, instances reused: an adapter onto the system master)
  master  do-nothing pythonfmu FMUs with the same interface through the same master
  floor   the same six FMI calls per step on the do-nothing FMUs, no master, no recording
  pair    the lateral pair through the dedicated pair master (tests/pair_master.py,
          kept as the baseline) and through the system master
          (harness.cosim.system_master.SystemMaster), Gauss-Seidel, fresh instances in both
  systems 2, 3 and 4 FMUs through the system master: the lateral pair; the pair and the
          longitudinal plant in open loop; the hover system (both axes with their controllers)
  plants  one plant step: the nonlinear DroneFlyHover6DOF against the linear pair it replaces
          (DroneFlyLateral + DroneFlyLongitudinal) and against DroneFlyLateral alone, through
          FMI, and against the pair in-process (model classes), at steps of 0.1 and 1 wing
          beat (benchmarks/plants.py)
Prints medians and the ratios ours/floor (target <= 1.2: everything we add, FMU
code and master, over the unavoidable FMI calls), master/floor (what the master alone adds),
SystemMaster/dedicated pair master (target <= 1.05), and per system the cost per step (a run of
N steps less a run of 1 step, over N - 1: without instantiation), the FMI calls per step
(counted) and the cost per FMI call; the plants' costs and the ratios 6-DOF/pair through
FMI at 0.1 and at 1 wing beat (target < 5 at each: one doStep of the 6-DOF plant replaces
the pair's two).
Timed in CPU time of this thread (``time.thread_time``; the FMUs run in it): on a shared
machine the wall time also counts the other users' load, and the process's CPU time BLAS
threads spinning after numpy calls.
``--clock wall`` times in wall time (``time.perf_counter``).
Usage: python benchmarks/run.py [--steps N] [--repeats R] [--clock cpu|wall]
"""

from __future__ import annotations

import argparse
import contextlib
import statistics
import sys
import tempfile
import time
from ctypes import c_double, c_uint
from pathlib import Path

HERE = Path(__file__).resolve().parent
#: the clock of every measurement here: the CPU time of this thread, which makes every FMI call
#: (default; on a shared machine the wall time also counts the other users' load, and the
#: process's CPU time BLAS threads spinning after the analyses' numpy calls), or the wall time
#: (``--clock wall``)
CLOCK = [time.thread_time]
#: the closed-loop step's target: ours/floor at most this
TARGET_OURS = 1.2
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parent / "tests"))  # the dedicated pair master: the tests' oracle
from pair_master import PairMaster  # noqa: E402
from plants import TARGET_RATIO, PlantBench, report as plants_report, steps_for  # noqa: E402


def _build(out: Path) -> dict[str, Path]:
    from pythonfmu import FmuBuilder

    from dronefly.harness.builder.build import build_all

    fmus = {p.stem: p for p in build_all(out) if p.suffix == ".fmu"}  # not DroneFlyHover6DOF.ssp
    for name in ("NullPlant", "NullController"):
        fmus[name] = Path(FmuBuilder.build_FMU(HERE / "null_fmus" / f"{name}.py", dest=out))
    return fmus


def _time_loop(loop, p, c, steps: int) -> float:
    h = 0.1 / 164.0
    t0 = CLOCK[0]()
    run = loop.run(h, steps, instances=(p, c))
    elapsed = (CLOCK[0]() - t0) / steps * 1e6
    assert run.complete, run.failure
    return elapsed


def _time_bare(p, c, steps: int) -> float:
    h = 0.1 / 164.0
    ys = ["delta_v", "delta_p", "delta_r", "delta_gamma"]
    us = ["delta_Phi_a", "delta_alpha_1a", "delta_alpha_2a"]
    y_vr, ys_vr = (c_uint * 4)(*p.vrs(ys)), (c_uint * 4)(*c.vrs(ys))
    u_vr_c, u_vr_p = (c_uint * 3)(*c.vrs(us)), (c_uint * 3)(*p.vrs(us))
    y, u = (c_double * 4)(), (c_double * 3)()
    for inst in (p, c):
        inst.slave.reset()
        inst.slave.setupExperiment(startTime=0.0)
        inst.slave.enterInitializationMode()
        inst.slave.exitInitializationMode()
    pg, ps, pd, pc = p.slave.fmi2GetReal, p.slave.fmi2SetReal, p.slave.fmi2DoStep, p.slave.component
    cg, cs, cd, cc = c.slave.fmi2GetReal, c.slave.fmi2SetReal, c.slave.fmi2DoStep, c.slave.component
    t0 = CLOCK[0]()
    for k in range(steps):
        t = k * h
        pg(pc, y_vr, 4, y)
        cs(cc, ys_vr, 4, y)
        cg(cc, u_vr_c, 3, u)
        ps(pc, u_vr_p, 3, u)
        pd(pc, t, h, 1)
        cd(cc, t, h, 1)
    return (CLOCK[0]() - t0) / steps * 1e6


def _time_run(run, steps: int) -> float:
    """Wall time of ``run(steps)`` [s]; the run must be complete."""
    t0 = CLOCK[0]()
    result = run(steps)
    elapsed = CLOCK[0]() - t0
    assert result.complete, result.failure
    return elapsed


def _fmi_calls_per_step(run, steps: int = 50) -> float:
    """FMI calls per communication step of ``run``, counted on every fmpy FMI call
    (the calls of a run of 2 x steps less those of a run of steps)."""
    from fmpy.fmi1 import _FMU

    real, count = _FMU._call, [0]

    def counting(self, fname, *args):
        count[0] += 1
        return real(self, fname, *args)

    _FMU._call = counting
    try:
        calls = []
        for n in (steps, 2 * steps):
            count[0] = 0
            run(n)
            calls.append(count[0])
    finally:
        _FMU._call = real
    return (calls[1] - calls[0]) / steps


def _systems(fmus: dict[str, Path]) -> dict[int, object]:
    """Systems of 2, 3 and 4 FMUs: the lateral pair, the pair and the open-loop longitudinal
    plant, the hover system (instances and initial states of ``hover_system``)."""
    from dronefly.harness.cosim.system import System
    from dronefly.harness.cosim.ssp import hover_system

    hover = hover_system(fmus)
    out: dict[int, object] = {}
    for n, keep in ((2, ("lateral", "lateral_controller")),
                    (3, ("lateral", "lateral_controller", "longitudinal")), (4, tuple(hover.fmus))):
        out[n] = System({i: hover.fmus[i] for i in keep},
                        [c for c in hover.connections if c.source in keep and c.target in keep],
                        {i: v for i, v in hover.parameters.items() if i in keep})
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--steps", type=int, default=2000)
    ap.add_argument("--repeats", type=int, default=9)
    ap.add_argument("--clock", choices=("cpu", "wall"), default="cpu",
                    help="CPU time of this process (default) or wall time")
    args = ap.parse_args(argv)
    CLOCK[0] = time.thread_time if args.clock == "cpu" else time.perf_counter
    if args.steps < 2 or args.repeats < 1:
        ap.error("--steps must be >= 2 and --repeats >= 1")
    from dronefly.harness.cosim.fmu import FMU
    from dronefly.harness.cosim.master import Loop
    from dronefly.harness.cosim.system_master import SystemMaster

    h, N = 0.1 / 164.0, args.steps
    times: dict[str, list[float]] = {}
    with tempfile.TemporaryDirectory() as tmp, contextlib.ExitStack() as stack:
        fmus = _build(Path(tmp))
        P, C, NP, NC = (stack.enter_context(FMU(fmus[m])) for m in (
            "DroneFlyLateral", "StateFeedback", "NullPlant", "NullController"))
        p, c, np_, nc = (stack.enter_context(f.instantiate(logging=False)) for f in (P, C, NP, NC))
        ours, null = Loop(P, C), Loop(NP, NC)
        systems = _systems(fmus)
        sm = {n: stack.enter_context(SystemMaster(systems[n])) for n in systems}
        x0 = systems[2].parameters["lateral"]
        # the pair master and the system master: whole runs with fresh instances (both
        # instantiate their FMUs), of N steps and of 1 step (the difference has no set-up).
        # The dedicated pair master gets FMUs of its own so that, as for the system master, no
        # live instance keeps their libraries loaded between runs (p and c do for P and C).
        pair = PairMaster(*(stack.enter_context(FMU(fmus[m])) for m in ("DroneFlyLateral",
                                                                         "StateFeedback")))
        # the same recording: the system master records every output by default, the
        # controller's Boolean output too (a seventh FMI call per step), which the pair master
        # does not read; the pair's system records what the pair master records
        same = [v for v in sm[2].names if v != "lateral_controller.saturated"]
        assert pair.names == [v.partition(".")[2] for v in same]
        runs = {"loop": lambda n: pair.run(h, n, plant_start=x0),
                **{f"sys{k}": (lambda n, m=m, r=same if k == 2 else None: m.run(h, n, record=r))
                   for k, m in sm.items()}}
        for run in runs.values():  # warm up (imports, first instantiation)
            _time_run(run, 2)
        plants = PlantBench(fmus, stack)
        for key in plants.keys:  # warm up (the linear models' matrix exponentials)
            plants.time(key, 2)
        for r in range(args.repeats):
            times.setdefault("ours", []).append(_time_loop(ours, p, c, N))
            times.setdefault("master", []).append(_time_loop(null, np_, nc, N))
            times.setdefault("floor", []).append(_time_bare(np_, nc, N))
            for key in (list(runs) if r % 2 == 0 else list(runs)[::-1]):
                for n in (N, 1):
                    times.setdefault(f"{key}/{n}", []).append(_time_run(runs[key], n))
            for key in (plants.keys if r % 2 == 0 else plants.keys[::-1]):
                times.setdefault(key, []).append(plants.time(key, steps_for(key, N)))
        calls = {key: _fmi_calls_per_step(run) for key, run in runs.items()}
    med = {k: statistics.median(v) for k, v in times.items()}
    print(f"closed-loop communication step, median of {args.repeats} interleaved repeats x "
          f"{N} steps [us/step, {args.clock} time]")
    print(f"  ours   (DroneFlyLateral + StateFeedback, harness master): {med['ours']:8.2f}")
    print(f"  master (do-nothing pythonfmu FMUs, harness master):       {med['master']:8.2f}")
    print(f"  floor  (do-nothing FMUs, the six FMI calls, no master):   {med['floor']:8.2f}")
    ratio = med["ours"] / med["floor"]
    print(f"ratio ours/floor = {ratio:.2f} (target <= {TARGET_OURS}); "
          f"master alone: master/floor = {med['master'] / med['floor']:.2f}")
    # us per step: of a whole run (/ N), and without set-up ((N steps - 1 step) / (N - 1))
    whole = {k: med[f"{k}/{N}"] / N * 1e6 for k in runs}
    step = {k: (med[f"{k}/{N}"] - med[f"{k}/1"]) / (N - 1) * 1e6 for k in runs}
    ratio_pair = whole["sys2"] / whole["loop"]
    print(f"\nlateral pair, Gauss-Seidel, fresh instances per run, {N} steps [us/step]")
    for key, label in (("loop", "former pair master (pair_master.py): "),
                       ("sys2", "SystemMaster (harness.cosim.system_master):")):
        print(f"  {label} {whole[key]:8.2f} whole run, {step[key]:8.2f} per step without set-up")
    print(f"ratio SystemMaster/former pair master = {ratio_pair:.3f} (target <= 1.05); per step "
          f"without set-up {step['sys2'] / step['loop']:.3f}")
    print("\nsystems through SystemMaster, per step without set-up")
    print("  FMUs  us/step  FMI calls/step  us/FMI call  step cost / pair's")
    for n in sm:
        k = f"sys{n}"
        print(f"  {n:4d} {step[k]:8.2f} {calls[k]:15.1f} {step[k] / calls[k]:12.2f} "
              f"{step[k] / step['sys2']:19.2f}")
    print(f"  (the pair through the former pair master: {calls['loop']:.1f} FMI calls per step)")
    lines, ratios_6dof = plants_report(med)
    print("\n".join(lines))
    plants_ok = all(r < TARGET_RATIO for r in ratios_6dof.values())
    return 0 if ratio <= TARGET_OURS and ratio_pair <= 1.05 and plants_ok else 1


if __name__ == "__main__":
    sys.exit(main())
