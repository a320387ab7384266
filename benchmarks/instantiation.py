"""Benchmark: what an FMU's instantiation costs, first in a process and again.

The first ``fmi2Instantiate`` of an FMU in a process imports the FMU's Python side (its
content-addressed package, pythonfmu's facade, and whatever they import: the standard library
only); a second instance of the same FMU reuses the imported modules. Each FMU that
``dronefly build`` writes (FMI 2.0) is instantiated in fresh processes (fmpy's FMU2Slave, this
interpreter), each reporting, in CPU time of the process (``time.process_time``: the machine is
shared) and in wall time:

  first   the first instantiation (loading the binary, the import, the slave's constructor)
  second  a second instantiation in the same process
  scipy   whether scipy was imported by then (fmpy imports numpy itself)

Prints the median over the repeats per FMU, and of the first instantiation the mean over the
FMUs. Usage: python benchmarks/instantiation.py [--repeats R] [--fmus DIR]
(DIR: FMUs already built, e.g. from other sources; by default they are built here.)
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import tempfile
import zipfile
from datetime import datetime, timezone
from pathlib import Path

#: run in a fresh process: instantiate the extracted FMU twice, print the timings as JSON
_CHILD = r"""
import json, sys, time
from fmpy import read_model_description
from fmpy.fmi2 import FMU2Slave
folder = sys.argv[1]
md = read_model_description(folder)
out = {}
for label in ("first", "second"):
    c0, w0 = time.process_time(), time.perf_counter()
    fmu = FMU2Slave(guid=md.guid, unzipDirectory=folder,
                    modelIdentifier=md.coSimulation.modelIdentifier, instanceName=label)
    fmu.instantiate()
    out[label] = (time.process_time() - c0, time.perf_counter() - w0)
    fmu.freeInstance()
out["scipy"] = "scipy" in sys.modules
print(json.dumps(out))
"""


def measure(folder: Path, repeats: int) -> dict[str, float]:
    """Medians [ms] of the first and second instantiation (CPU, wall) over fresh processes."""
    runs = []
    for _ in range(repeats):
        r = subprocess.run([sys.executable, "-c", _CHILD, str(folder)], capture_output=True,
                           text=True, timeout=300, check=True)
        runs.append(json.loads(r.stdout.strip().splitlines()[-1]))
    med = {f"{k}_{clock}": statistics.median(run[k][i] for run in runs) * 1e3
           for k in ("first", "second") for i, clock in enumerate(("cpu", "wall"))}
    med["scipy"] = float(any(run["scipy"] for run in runs))
    return med


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--fmus", type=Path, default=None)
    args = ap.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        if args.fmus is None:
            from dronefly.harness.builder.build import FMUS, build_fmu

            fmus = sorted((build_fmu(name, tmp) for name in FMUS), key=lambda p: p.stem)
        else:
            fmus = sorted(p for p in args.fmus.glob("*.fmu") if p.stem != "DroneFlyClosedLoop")
        start = datetime.now(timezone.utc)
        print(f"FMU instantiation [ms], median of {args.repeats} fresh processes "
              f"({start:%Y-%m-%d %H:%M} UTC, Python {sys.version.split()[0]})")
        print(f"  {'FMU':34s} {'first cpu':>10s} {'wall':>8s} {'second cpu':>11s} {'wall':>8s}"
              "  scipy imported")
        firsts = []
        for fmu in fmus:
            folder = Path(tmp, "x", fmu.stem)
            with zipfile.ZipFile(fmu) as z:
                z.extractall(folder)
            m = measure(folder, args.repeats)
            firsts.append(m["first_cpu"])
            print(f"  {fmu.stem:34s} {m['first_cpu']:10.1f} {m['first_wall']:8.1f} "
                  f"{m['second_cpu']:11.2f} {m['second_wall']:8.2f}  "
                  f"{'yes' if m['scipy'] else 'no'}")
        print(f"mean first instantiation over {len(firsts)} FMUs: "
              f"{statistics.fmean(firsts):.1f} ms CPU")
    return 0


if __name__ == "__main__":
    sys.exit(main())
