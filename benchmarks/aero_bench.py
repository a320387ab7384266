"""Benchmark of the quasi-steady wing model: the derivative table, and one
cycle-averaged force evaluation against one step of the linear plant pair it would replace.

- ``table``: ``parity_report`` of the default model from a fresh model (trim, every derivative
  with its per-term split, eigenvalues, controller), wall time; target 10 s.
- ``force``: one ``QuasiSteadyModel.forces_vector`` at a disturbed state (kinematics cached, as
  in a state-only step) and at a new control (kinematics recomputed), on the default grid
  (8 elements, 100 samples, the smallest accurate to 0.1 % in the derivatives), on the fine
  grid (20 x 200) and on a coarse one (8 x 40), against one ``step_list`` of the lateral and one of
  the longitudinal linear model (``LateralModel``, ``LongitudinalModel``) at a step of one wing
  beat: the in-process cost of the linear pair's doStep. Target: the quasi-steady doStep at
  most 20 times the pair; a doStep needs at least one force evaluation, so the ratio of one
  evaluation is a lower bound. Medians of ``--repeats`` interleaved repeats.
- ``6dof``: one step of one wing beat of the 6-DOF plant (``Hover6DOF.step``, the model class
  that ``DroneFlyHover6DOF``'s doStep runs) with the quasi-steady aerodynamics (its
  ``aerodynamics = 2``), the controls new at every step (a closed loop's: the wing motion
  mapped again) and held (an open loop's), against the same step with the linear
  aerodynamics and against the linear pair's step: both ratios, the issue's target at most
  20 times the pair (reported either way).

Usage: python benchmarks/aero_bench.py [--repeats R]; exits 1 when a target is missed.
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time

import numpy as np


def _per_call(fn, n: int) -> float:
    t0 = time.perf_counter()
    for _ in range(n):
        fn()
    return (time.perf_counter() - t0) / n


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeats", type=int, default=5)
    args = ap.parse_args()
    from dronefly.harness.aero import QuasiSteadyModel, parity_report
    from dronefly.models.lateral_dynamics import LateralModel, default_parameters
    from dronefly.models.longitudinal_dynamics import LongitudinalModel
    from dronefly.models.longitudinal_dynamics import default_parameters as lon_parameters

    lat, lon = LateralModel(default_parameters()), LongitudinalModel(lon_parameters())
    x4, u3, u4 = [0.01, 0.02, 0.0, 0.1], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0, 0.0]
    lat.step_list(x4, u3, 1.0), lon.step_list(x4, u4, 1.0)  # compile the products once
    default, fine = QuasiSteadyModel(), QuasiSteadyModel(n_span=20, n_time=200)
    coarse = QuasiSteadyModel(n_span=8, n_time=40)
    default.trim(), fine.trim(), coarse.trim()
    from dronefly.models.rigid_body import Hover6DOF

    six_lin = Hover6DOF(default_parameters(), lon_parameters())
    six_qs = Hover6DOF(default_parameters(), lon_parameters(), aerodynamics=default)
    x13 = [0.0, 0.02, 0.0, 0.02, 0.0, 0.01, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]
    q_new, q_held, s_lin = [], [], []
    j = [0]

    def qs_step_new():
        j[0] += 1
        six_qs.step(x13, [1e-4 * j[0], 0.0, 0.0], [0.0] * 4, 1.0)
    state = np.array([0.0, 0.05, 0.0, 0.02, 0.0, 0.01])
    table, pair, f_state, f_ctrl, c_state, d_state, d_ctrl = [], [], [], [], [], [], []
    k = [0]

    def new_control(m):
        k[0] += 1
        return m.forces_vector(state, {"delta_Phi_a": 1e-3 * k[0]})

    for _ in range(args.repeats):
        t0 = time.perf_counter()
        parity_report(QuasiSteadyModel())
        table.append(time.perf_counter() - t0)
        pair.append(_per_call(lambda: (lat.step_list(x4, u3, 1.0), lon.step_list(x4, u4, 1.0)),
                              2000))
        f_state.append(_per_call(lambda: fine.forces_vector(state), 50))
        f_ctrl.append(_per_call(lambda: new_control(fine), 50))
        c_state.append(_per_call(lambda: coarse.forces_vector(state), 200))
        d_state.append(_per_call(lambda: default.forces_vector(state), 200))
        d_ctrl.append(_per_call(lambda: new_control(default), 100))
        q_new.append(_per_call(qs_step_new, 20))
        q_held.append(_per_call(lambda: six_qs.step(x13, [0.01, 0.0, 0.0], [0.0] * 4, 1.0), 20))
        s_lin.append(_per_call(lambda: six_lin.step(x13, [0.01, 0.0, 0.0], [0.0] * 4, 1.0), 2000))
    med = {name: statistics.median(v) for name, v in
           (("table", table), ("pair", pair), ("force_state", f_state),
            ("force_control", f_ctrl), ("force_coarse", c_state), ("default_state", d_state),
            ("default_control", d_ctrl), ("qs_new", q_new), ("qs_held", q_held),
            ("six_lin", s_lin))}
    print(f"load average {os.getloadavg()[0]:.2f}, {os.cpu_count()} cores, {args.repeats} repeats")
    print(f"derivative table (parity_report, fresh model): {med['table']:.2f} s (target 10 s)")
    print(f"linear pair step (lateral + longitudinal step_list, h = 1 wb): "
          f"{med['pair'] * 1e6:.1f} us")
    for name, label in (("default_state", "force evaluation, default 8 x 100, new state"),
                        ("default_control", "force evaluation, default 8 x 100, new control"),
                        ("force_state", "force evaluation, 20 x 200, new state"),
                        ("force_control", "force evaluation, 20 x 200, new control"),
                        ("force_coarse", "force evaluation, 8 x 40, new state")):
        print(f"{label}: {med[name] * 1e6:.0f} us = {med[name] / med['pair']:.0f} x the pair "
              f"(target 20 x)")
    print(f"6-DOF step, linear aerodynamics (h = 1 wb): {med['six_lin'] * 1e6:.1f} us = "
          f"{med['six_lin'] / med['pair']:.1f} x the pair")
    for name, label in (("qs_new", "new controls"), ("qs_held", "controls held")):
        print(f"6-DOF step, quasi-steady aerodynamics, {label} (h = 1 wb): "
              f"{med[name] * 1e3:.2f} ms = {med[name] / med['six_lin']:.0f} x the linear-aero "
              f"6-DOF step = {med[name] / med['pair']:.0f} x the pair (target 20 x)")
    ok = med["table"] <= 10.0 and med["qs_new"] / med["pair"] <= 20.0
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
