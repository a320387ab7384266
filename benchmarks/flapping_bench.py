"""Benchmark of the flapping plant: the cost of a simulated wing beat through FMI and
of the Floquet analysis through FMI.

- ``beat``: ``DroneFlyFlapping`` (FMI 2.0) through fmpy's ``FMU2Slave``, one core, 10 wing beats
  in steps of one wing beat and in steps of 0.1, wall time per simulated wing beat (the first
  beat, which makes the grid's stages for the controls, included); target 10 ms. Also, for
  information, steps of one wing beat with new controls every beat, as a closed loop sets them
  (the stages made again every beat).
- ``floquet``: ``dronefly.harness.flapping.fmi_floquet`` on the FMU (the periodic orbit by
  Newton, the monodromy by central differences, all through fmi2Get/SetFMUstate); target 30 s.

Usage: python benchmarks/flapping_bench.py [--repeats R]; exits 1 when a target is missed.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import time
from pathlib import Path

from dronefly.harness.builder.build import build_fmu
from dronefly.harness.cosim.fmu import FMU
from dronefly.harness.flapping import fmi_floquet
from dronefly.models.lateral_interface import N_HZ
from dronefly.models.quasisteady import CONTROLS

TARGET_MS_PER_BEAT = 10.0
TARGET_FLOQUET_S = 30.0


def _per_beat(path: Path, steps_per_beat: int, beats: int = 10,
              new_controls: bool = False) -> float:
    with FMU(path) as f, f.instantiate("bench", logging=False) as inst:
        s = inst.slave
        vrs = inst.vrs(CONTROLS)
        s.setupExperiment(startTime=0.0)
        s.enterInitializationMode()
        s.exitInitializationMode()
        h = 1.0 / (N_HZ * steps_per_beat)
        t0 = time.perf_counter()
        for k in range(beats * steps_per_beat):
            if new_controls and k % steps_per_beat == 0:  # small, different every beat
                s.setReal(vrs, [1e-3 * ((k + i) % 5 - 2) for i in range(len(vrs))])
            s.doStep(currentCommunicationPoint=k * h, communicationStepSize=h)
        return (time.perf_counter() - t0) / beats * 1e3


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--repeats", type=int, default=3)
    args = p.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        fmu = build_fmu("DroneFlyFlapping", tmp)
        beat1 = statistics.median(_per_beat(fmu, 1) for _ in range(args.repeats))
        beat10 = statistics.median(_per_beat(fmu, 10) for _ in range(args.repeats))
        changing = statistics.median(_per_beat(fmu, 1, new_controls=True)
                                     for _ in range(args.repeats))
        t0 = time.perf_counter()
        r = fmi_floquet(fmu)
        floquet_s = time.perf_counter() - t0
    print(f"beat: {beat1:.1f} ms per wing beat (steps of 1 wing beat), {beat10:.1f} ms (steps "
          f"of 0.1); target {TARGET_MS_PER_BEAT:g} ms")
    print(f"beat with new controls every beat: {changing:.1f} ms (steps of 1 wing beat)")
    print(f"floquet: {floquet_s:.2f} s through FMI ({r.evaluations} periods); target "
          f"{TARGET_FLOQUET_S:g} s")
    ok = max(beat1, beat10) <= TARGET_MS_PER_BEAT and floquet_s <= TARGET_FLOQUET_S
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
