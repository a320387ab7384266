"""Benchmark: microseconds per closed-loop communication step.

Measures, in one run, with the same master (harness.master.Loop, Gauss-Seidel):
  ours   DroneFlyLateral + StateFeedback
  floor  do-nothing pythonfmu FMUs with the same interface (same FMI call sequence)
  bare   the same six FMI calls per step on the do-nothing FMUs, without the master
Prints medians over repeats and the ratios ours/floor (target <= 1.5) and floor/bare
(what the master itself adds). Usage: python benchmarks/run.py [--steps N] [--repeats R]
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


def _time_loop(loop, steps: int, repeats: int) -> list[float]:
    h = 0.1 / 164.0
    out = []
    with loop.plant.instantiate(logging=False) as p, loop.controller.instantiate(logging=False) as c:
        for _ in range(repeats):
            t0 = time.perf_counter()
            run = loop.run(h, steps, instances=(p, c))
            out.append((time.perf_counter() - t0) / steps * 1e6)
            assert run.complete, run.failure
    return out


def _time_bare(plant, controller, steps: int, repeats: int) -> list[float]:
    h = 0.1 / 164.0
    out = []
    with plant.instantiate(logging=False) as p, controller.instantiate(logging=False) as c:
        ys = ["delta_v", "delta_p", "delta_r", "delta_gamma"]
        us = ["delta_Phi_a", "delta_alpha_1a", "delta_alpha_2a"]
        y_vr, ys_vr = (c_uint * 4)(*p.vrs(ys)), (c_uint * 4)(*c.vrs(ys))
        u_vr_c, u_vr_p = (c_uint * 3)(*c.vrs(us)), (c_uint * 3)(*p.vrs(us))
        y, u = (c_double * 4)(), (c_double * 3)()
        for _ in range(repeats):
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
            out.append((time.perf_counter() - t0) / steps * 1e6)
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--steps", type=int, default=2000)
    ap.add_argument("--repeats", type=int, default=7)
    args = ap.parse_args(argv)
    from dronefly.harness.fmu import FMU
    from dronefly.harness.master import Loop

    with tempfile.TemporaryDirectory() as tmp:
        fmus = _build(Path(tmp))
        with FMU(fmus["DroneFlyLateral"]) as P, FMU(fmus["StateFeedback"]) as C, \
                FMU(fmus["NullPlant"]) as NP, FMU(fmus["NullController"]) as NC:
            ours = _time_loop(Loop(P, C), args.steps, args.repeats)
            floor = _time_loop(Loop(NP, NC), args.steps, args.repeats)
            bare = _time_bare(NP, NC, args.steps, args.repeats)
    med = {k: statistics.median(v) for k, v in (("ours", ours), ("floor", floor), ("bare", bare))}
    print(f"closed-loop communication step, median of {args.repeats} x {args.steps} steps [us/step]")
    print(f"  ours  (DroneFlyLateral + StateFeedback, harness master): {med['ours']:8.2f}")
    print(f"  floor (do-nothing pythonfmu FMUs, harness master):       {med['floor']:8.2f}")
    print(f"  bare  (do-nothing FMUs, the six FMI calls, no master):   {med['bare']:8.2f}")
    ratio = med["ours"] / med["floor"]
    print(f"ratio ours/floor = {ratio:.2f} (target <= 1.5); "
          f"master overhead floor/bare = {med['floor'] / med['bare']:.2f}")
    return 0 if ratio <= 1.5 else 1


if __name__ == "__main__":
    sys.exit(main())
