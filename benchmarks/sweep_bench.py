"""Benchmark of ``dronefly sweep``: cases per second with 1 and 2 workers, per-case overhead.

Every case is 2,000 communication steps (step 0.1 wing beat, 200 wing beats, paper gains).
Measured:
  loop     median wall time of a bare ``Loop.run`` of one case (instances reused), s
  1 / 2    cases per second of ``run_sweep`` with 1 worker (in-process) and 2 worker
           processes, whole sweep (start-up, chunking, CSV and JSON writing included)
  ratio    throughput with 2 workers / with 1 (target >= 1.7)
  overhead in-worker: time per case in the sweep worker / time inside Loop.run - 1;
           end-to-end (1 worker): sweep wall time per case / bare Loop.run time - 1
           (target < 5 %)
Usage: python benchmarks/sweep_bench.py [--cases N] [--repeats R] [--json]
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import tempfile
import time
from pathlib import Path


def _bare_loop_s(plant: Path, controller: Path, repeats: int) -> float:
    from dronefly.models.feedback import default_gains, gain_name
    from dronefly.harness.cosim.fmu import FMU
    from dronefly.harness.cosim.master import Loop

    K = default_gains()
    gains = {gain_name(i, j): v for i, row in enumerate(K) for j, v in enumerate(row)}
    with FMU(plant) as pf, FMU(controller) as cf:
        loop = Loop(pf, cf)
        n = float(pf.variables["n"].start)
        with pf.instantiate(logging=False) as p, cf.instantiate(logging=False) as c:
            out = []
            for _ in range(repeats + 1):
                t0 = time.perf_counter()
                run = loop.run(0.1 / n, 2000, plant_start={"delta_gamma_start": 0.1},
                               controller_params=gains, instances=(p, c))
                out.append(time.perf_counter() - t0)
                assert run.complete, run.failure
    return statistics.median(out[1:])


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", type=int, default=160, help="cases per sweep (default 160)")
    ap.add_argument("--repeats", type=int, default=2, help="sweeps per worker count (default 2)")
    ap.add_argument("--json", action="store_true", help="print JSON")
    args = ap.parse_args(argv)

    from dronefly.harness.builder.build import build_all
    from dronefly.harness.sweep.run import run_sweep
    from dronefly.harness.sweep.cases import DEFAULT_DIRECTIONS, SweepSpec

    amplitudes = max(1, args.cases // len(DEFAULT_DIRECTIONS))
    spec = SweepSpec(disturbances=("directions",), amplitudes=amplitudes, gains=("paper",),
                     steps_wb=(0.1,), stop_wb=200.0)
    with tempfile.TemporaryDirectory() as tmp:
        fmus = {p.stem: p for p in build_all(Path(tmp) / "fmus")}
        plant, controller = fmus["DroneFlyLateral"], fmus["StateFeedback"]
        bare = _bare_loop_s(plant, controller, 10)
        res: dict[int, list[dict]] = {1: [], 2: []}
        for _ in range(args.repeats):
            for w in (1, 2):
                r = run_sweep(spec, Path(tmp) / f"w{w}", plant=plant, controller=controller,
                              workers=w, fresh=True, plot=False, progress_bar=False)
                res[w].append(r.summary)
    n = res[1][0]["computed_cases"]
    best = {w: min(res[w], key=lambda s: s["elapsed_s"]) for w in res}
    rate = {w: n / best[w]["elapsed_s"] for w in best}
    out = {
        "cases": n, "steps_per_case": 2000, "bare_loop_run_s": bare,
        "cases_per_s_1_worker": rate[1], "cases_per_s_2_workers": rate[2],
        "speedup_2_vs_1": rate[2] / rate[1],
        "overhead_in_worker_1": best[1]["per_case_overhead"],
        "overhead_in_worker_2": best[2]["per_case_overhead"],
        "overhead_end_to_end_1": best[1]["elapsed_s"] / n / bare - 1.0,
        "elapsed_s": {w: [s["elapsed_s"] for s in res[w]] for w in res},
    }
    if args.json:
        print(json.dumps(out, indent=2))
    else:
        print(f"{n} cases of 2000 steps; bare Loop.run {bare * 1e3:.1f} ms per case")
        print(f"1 worker : {rate[1]:6.2f} cases/s")
        print(f"2 workers: {rate[2]:6.2f} cases/s   ratio {out['speedup_2_vs_1']:.2f} "
              f"(target >= 1.7)")
        print(f"per-case overhead in the worker: {100 * out['overhead_in_worker_1']:.2f} % "
              f"(1 worker), {100 * out['overhead_in_worker_2']:.2f} % (2 workers); "
              f"end-to-end, 1 worker: {100 * out['overhead_end_to_end_1']:.2f} % (target < 5 %)")
    ok = out["speedup_2_vs_1"] >= 1.7 and max(out["overhead_in_worker_1"],
                                              out["overhead_in_worker_2"]) < 0.05
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
