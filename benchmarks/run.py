"""Benchmark: microseconds per closed-loop communication step.

Measures, in one run, interleaved repeat by repeat (so that the machine's noise hits all
three alike):
  ours    DroneFlyLateral + StateFeedback through the harness master (harness.cosim.master.Loop)
  master  do-nothing pythonfmu FMUs with the same interface through the same master
  floor   the same six FMI calls per step on the do-nothing FMUs, no master, no recording
Prints medians and the ratios ours/floor (target <= 1.5: everything we add, FMU code and
master, over the unavoidable FMI calls) and master/floor (what the master alone adds).
Usage: python benchmarks/run.py [--steps N] [--repeats R]
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import time
from ctypes import c_double, c_uint
from pathlib import Path

HERE = Path(__file__).resolve().parent


def _build(out: Path) -> dict[str, Path]:
    from pythonfmu import FmuBuilder

    from dronefly.build import build_all

    fmus = {p.stem: p for p in build_all(out)}
    for name in ("NullPlant", "NullController"):
        fmus[name] = Path(FmuBuilder.build_FMU(HERE / "null_fmus" / f"{name}.py", dest=out))
    return fmus


def _time_loop(loop, p, c, steps: int) -> float:
    h = 0.1 / 164.0
    t0 = time.perf_counter()
    run = loop.run(h, steps, instances=(p, c))
    elapsed = (time.perf_counter() - t0) / steps * 1e6
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
    t0 = time.perf_counter()
    for k in range(steps):
        t = k * h
        pg(pc, y_vr, 4, y)
        cs(cc, ys_vr, 4, y)
        cg(cc, u_vr_c, 3, u)
        ps(pc, u_vr_p, 3, u)
        pd(pc, t, h, 1)
        cd(cc, t, h, 1)
    return (time.perf_counter() - t0) / steps * 1e6


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--steps", type=int, default=2000)
    ap.add_argument("--repeats", type=int, default=9)
    args = ap.parse_args(argv)
    from dronefly.harness.cosim.fmu import FMU
    from dronefly.harness.cosim.master import Loop

    times: dict[str, list[float]] = {"ours": [], "master": [], "floor": []}
    with tempfile.TemporaryDirectory() as tmp:
        fmus = _build(Path(tmp))
        with FMU(fmus["DroneFlyLateral"]) as P, FMU(fmus["StateFeedback"]) as C, \
                FMU(fmus["NullPlant"]) as NP, FMU(fmus["NullController"]) as NC, \
                P.instantiate(logging=False) as p, C.instantiate(logging=False) as c, \
                NP.instantiate(logging=False) as np_, NC.instantiate(logging=False) as nc:
            ours, null = Loop(P, C), Loop(NP, NC)
            for _ in range(args.repeats):
                times["ours"].append(_time_loop(ours, p, c, args.steps))
                times["master"].append(_time_loop(null, np_, nc, args.steps))
                times["floor"].append(_time_bare(np_, nc, args.steps))
    med = {k: statistics.median(v) for k, v in times.items()}
    print(f"closed-loop communication step, median of {args.repeats} interleaved repeats x "
          f"{args.steps} steps [us/step]")
    print(f"  ours   (DroneFlyLateral + StateFeedback, harness master): {med['ours']:8.2f}")
    print(f"  master (do-nothing pythonfmu FMUs, harness master):       {med['master']:8.2f}")
    print(f"  floor  (do-nothing FMUs, the six FMI calls, no master):   {med['floor']:8.2f}")
    ratio = med["ours"] / med["floor"]
    print(f"ratio ours/floor = {ratio:.2f} (target <= 1.5); "
          f"master alone: master/floor = {med['master'] / med['floor']:.2f}")
    return 0 if ratio <= 1.5 else 1


if __name__ == "__main__":
    sys.exit(main())
