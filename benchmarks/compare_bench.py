"""Benchmark of the comparison sweep's default run, end to end: ``dronefly sweep --compare
nonlinear`` as docs/validity.md gives it (no other option but the output folder and
``--no-progress``).

Runs the command in a fresh scratch folder, so that it also builds the FMUs and the two hover
systems (``build/`` of that folder), and times it by the wall clock, from the start of the
process to its exit: building, the 1995 cases of the default (three slices of 25 x 25 out to
3 times the box, ten directions of 12 amplitudes; each through the linear and the nonlinear
closed loop, 100 wing beats in steps of 1), the CSV, the JSON and the six maps. Reports the
wall time, the sweep's own timing line (cases, workers, seconds), the CPU time of the child
processes, the cores and the load average before and after. The target: within
5 minutes on 2 cores; exits 1 when a run takes longer.
Usage: python benchmarks/compare_bench.py [--repeats R]
"""

from __future__ import annotations

import argparse
import os
import re
import resource
import subprocess
import sys
import tempfile
import time
from datetime import datetime, timezone
from pathlib import Path

#: the target wall time of the default run, s
TARGET_S = 300.0


def _load() -> str:
    return "load average {:.2f}, {:.2f}, {:.2f} (1, 5, 15 min)".format(*os.getloadavg())


def _run_once() -> tuple[float, float, str]:
    """(wall time [s], CPU time of the children [s], the sweep's timing line) of one run."""
    dronefly = Path(sys.executable).with_name("dronefly")
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        done = subprocess.run([str(dronefly), "sweep", "--compare", "nonlinear", "--out",
                               "validity", "--no-progress"], cwd=tmp, capture_output=True,
                              text=True)
        wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if done.returncode != 0:
        raise SystemExit(f"dronefly sweep --compare nonlinear exited {done.returncode}:\n"
                         f"{done.stderr.strip()}")
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    line = next((ln for ln in done.stdout.splitlines() if re.match(r"sweep: \d+ cases", ln)),
                "(no timing line)")
    return wall, cpu, line


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--repeats", type=int, default=1)
    args = ap.parse_args(argv)
    if args.repeats < 1:
        ap.error("--repeats must be >= 1")
    walls = []
    for k in range(args.repeats):
        print(f"run {k + 1}: started {datetime.now(timezone.utc):%Y-%m-%d %H:%M} UTC, "
              f"{os.cpu_count()} cores, {_load()}", flush=True)
        wall, cpu, line = _run_once()
        walls.append(wall)
        print(f"  wall {wall:.1f} s (target <= {TARGET_S:.0f} s), CPU of the processes "
              f"{cpu:.1f} s; {line}")
        print(f"  finished {datetime.now(timezone.utc):%Y-%m-%d %H:%M} UTC, {_load()}",
              flush=True)
    return 0 if max(walls) <= TARGET_S else 1


if __name__ == "__main__":
    sys.exit(main())
