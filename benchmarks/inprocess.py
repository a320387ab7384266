"""Benchmark: the Python cost of our FMUs per closed-loop step, in-process.

Calls the six FMI functions of a co-simulation step (plant get, controller set, controller
get, plant set, both doSteps) directly on the slave objects, no FMI wrapper, no master:
DroneFlyLateral + StateFeedback against the do-nothing pythonfmu slaves of ``null_fmus/``.
What ``run.py``'s ours/floor cannot separate from the wrapper and the machine's noise: the
cost of our own Python code. Prints the medians and minima over the repeats [us/step].
Usage: python benchmarks/inprocess.py [--steps N] [--repeats R]
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path
from typing import Any

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE / "null_fmus"))
from NullController import NullController  # noqa: E402
from NullPlant import NullPlant  # noqa: E402

STATES = ["delta_v", "delta_p", "delta_r", "delta_gamma"]
CONTROLS = ["delta_Phi_a", "delta_alpha_1a", "delta_alpha_2a"]


def _pair(plant_cls: Any, controller_cls: Any) -> tuple[Any, ...]:
    """Initialised plant and controller and the value references of the six calls."""
    p, c = plant_cls(instance_name="p"), controller_cls(instance_name="c")
    for s in (p, c):
        s.setup_experiment(0.0, None, None)
        s.enter_initialization_mode()
        s.exit_initialization_mode()

    def vrs(s: Any, names: list[str]) -> list[int]:
        # ours: a variable's value reference is its index in VARIABLES (dronefly.fmi.base)
        table = getattr(s, "VARIABLES", None)
        refs = ({v.name: i for i, v in enumerate(table)} if table is not None
                else {v.name: v.value_reference for v in s.vars.values()})
        return [refs[n] for n in names]

    return p, c, vrs(p, STATES), vrs(c, STATES), vrs(c, CONTROLS), vrs(p, CONTROLS)


def _time(pair: tuple[Any, ...], steps: int) -> float:
    """Microseconds per step of ``steps`` closed-loop steps of 0.1 wing beat."""
    p, c, y_p, y_c, u_c, u_p = pair
    h = 0.1 / 164.0
    t0 = time.perf_counter()
    for k in range(steps):
        t = k * h
        c.set_real(list(y_c), p.get_real(list(y_p)))
        p.set_real(list(u_p), c.get_real(list(u_c)))
        if not (p.do_step(t, h) and c.do_step(t, h)):
            raise RuntimeError(f"a step was refused at t = {t!r} s")
    return (time.perf_counter() - t0) / steps * 1e6


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--steps", type=int, default=5000)
    ap.add_argument("--repeats", type=int, default=7)
    args = ap.parse_args(argv)
    from dronefly.controller.slave import StateFeedback
    from dronefly.fmu_src.lateral.slave import DroneFlyLateral

    times: dict[str, list[float]] = {"ours": [], "null": []}
    for _ in range(args.repeats):  # interleaved, fresh instances per repeat
        times["ours"].append(_time(_pair(DroneFlyLateral, StateFeedback), args.steps))
        times["null"].append(_time(_pair(NullPlant, NullController), args.steps))
    print(f"six FMI calls per step on the slave objects, {args.repeats} repeats x {args.steps} "
          "steps [us/step]")
    for key, label in (("ours", "DroneFlyLateral + StateFeedback"),
                       ("null", "do-nothing pythonfmu slaves   ")):
        v = times[key]
        print(f"  {label}: median {statistics.median(v):6.2f}, min {min(v):6.2f}")
    ours, null = (statistics.median(times[k]) for k in ("ours", "null"))
    print(f"what our code adds: {ours - null:.2f} us/step (ours/null {ours / null:.2f})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
