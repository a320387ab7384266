"""Benchmark of ``dronefly check`` on the Reference-FMUs (``../shared/reference-fmus``).

Times ``dronefly check`` by the wall clock (and its CPU time, which a loaded machine does not
inflate), once per FMU it checks (the default checks and profile, the Model Exchange ones
included where the FMU has the interface, Roberts with ``--stop-time 1``; each FMU in its own process, as the CLI runs it), and
then all of them in one command with ``-j 1`` and with ``-j 2``. Reports the median and the
largest time per FMU and the two totals, with the cores and the load average. The targets:
at most 2 s per FMU (median), and ``-j 2`` about half of ``-j 1``; exits 1 when the
median is over 2 s.
Usage: python benchmarks/check_bench.py
"""

from __future__ import annotations

import os
import resource
import statistics
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
REF = ROOT.parent / "shared" / "reference-fmus"
TARGET_S = 2.0


CPU: list[float] = []  # the CPU time (user + system, the command and its children) of each run


def _run(args: list[str]) -> float:
    """The wall time of ``dronefly check ARGS``; its CPU time is appended to :data:`CPU`."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    r = subprocess.run([sys.executable, "-m", "dronefly", "check", *args],
                       capture_output=True, text=True)
    dt = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    CPU.append(after.ru_utime - before.ru_utime + after.ru_stime - before.ru_stime)
    if r.returncode not in (0, 1):
        raise SystemExit(f"dronefly check {' '.join(args)}: exit {r.returncode}\n{r.stderr}")
    return dt


def main() -> int:
    if not REF.is_dir():
        print(f"no Reference-FMUs at {REF}")
        return 2
    fmus = [p for p in sorted(REF.glob("fmi[23]/*.fmu")) if p.stem != "Clocks"]
    opts = {"Roberts": ["--stop-time", "1"]}
    print(f"{os.cpu_count()} cores, load average {os.getloadavg()[0]:.2f}")
    times = {}
    for p in fmus:
        times[p] = _run([*opts.get(p.stem, []), str(p)])
        print(f"  {p.parent.name}/{p.name:<28} {times[p]:6.2f} s wall, {CPU[-1]:5.2f} s CPU")
    median = statistics.median(times.values())
    print(f"per FMU: median {median:.2f} s wall, max {max(times.values()):.2f} s; CPU median "
          f"{statistics.median(CPU):.2f} s (target: median wall <= {TARGET_S} s)")
    rest = [str(p) for p in fmus if p.stem != "Roberts"]
    j1 = _run(["-j", "1", *rest])
    j2 = _run(["-j", "2", *rest])
    print(f"{len(rest)} FMUs in one command: -j 1 {j1:.2f} s, -j 2 {j2:.2f} s "
          f"(ratio {j2 / j1:.2f}); load average {os.getloadavg()[0]:.2f}")
    return 0 if median <= TARGET_S else 1


if __name__ == "__main__":
    sys.exit(main())
