"""The ``dronefly`` command line: the parser, argument converters and exit codes.

Each subcommand maps onto one function of :mod:`dronefly.cli.commands`, which calls one Python
function. Exit codes: 0 success; 1 a check failed or a run stopped early (its partial result
is kept); 2 bad input (a :class:`~dronefly.core.errors.DroneflyError` or an ``OSError`` on a file:
one line naming the value, nothing written); 130 interrupted (Ctrl-C). Any other exception is
a bug: one line saying so and exit 1 (``--debug`` shows the traceback).

Units: options that are times of the co-simulation are in wing beats (t_w = 1/n); initial
states given with ``--x0`` are non-dimensional (x+ of Sect. 2.1); ``--gamma0`` and ``--set``
values are SI (the FMU's own unit: rad, m/s, rad/s, Hz).
"""

from __future__ import annotations

import argparse
import importlib
import sys
import traceback
from pathlib import Path
from types import ModuleType
from typing import Callable, Sequence

from .. import __version__
from ..harness.builder.build import reporting
from .commands import COMMANDS, EXIT_FAILED, EXIT_USAGE
from .args import (converter, finite, floats_arg, int_arg, out_dir, out_file, parse_gains,
    parse_names, parse_setting, parse_x0, positive)
from ..core.errors import CrossCheckError, DroneflyError
from ..core.interrupt import EXIT_INTERRUPTED, deferred_sigint, sigint_at_once

__all__ = ["main"]

_UNITS = ("\nunits: --step/--stop in wing beats (1 wing beat = 1/n = 6.1 ms); --x0 non-dimensional "
          "x+ = (dv/U, dp/n, dr/n, dgamma); --gains non-dimensional (rad per unit of x+); --set "
          "values in the FMU's SI unit (rad, m/s, rad/s, Hz)")
_SWEEP_UNITS = ("\nunits: --steps/--delays/--sample-periods/--stop in wing beats (1 wing beat = "
                "1/n = 6.1 ms); --gains non-dimensional (rad per unit of x+ = (dv/U, dp/n, dr/n, "
                "dgamma)); --set values in the FMU's SI unit (rad, m/s, rad/s, Hz)")
_EPILOG = {
    "cosim": "examples:\n  dronefly cosim\n  dronefly cosim --native\n  dronefly cosim --gains open --json\n"
             "  dronefly cosim --gains=-0.3,-0.3,-0.2,-0.1 --step 1 --master jacobi\n"
             "  (a value starting with '-' needs the form --gains=... or --x0=...)\n"
             "  dronefly cosim --plant my/Plant.fmu --controller my/Controller.fmu\n"
             "  dronefly cosim --plant build/DroneFlyLongitudinal.fmu "
             "--controller build/StateFeedbackLongitudinal.fmu\n"
             "  dronefly cosim --gains='-0.3,-0.3,-0.2,-0.1;0,0,0,0;0.1,0,0,0'  (rows: "
             "delta_Phi_a; delta_alpha_1a; delta_alpha_2a)\n"
             "  dronefly cosim --gains my_gains.json --set plant.Lv_plus=0.25 --set u_max=0.3\n"
             "  dronefly cosim --system build/DroneFlyHover.ssp\n"
             "  dronefly cosim --system build/DroneFlyHover.ssp --open-loop\n"
             "  dronefly cosim --system my.ssp --set lateral.delta_p_start=1 "
             "--record lateral.delta_p,lateral.delta_gamma\n"
             "  dronefly cosim --step 1 --set controller.sensing_delay=0.036585365853658534 "
             "--set controller.sample_period=0.006097560975609756\n"
             "exit codes: 0 ok, 1 the run stopped early (partial result kept) or its "
             "cross-check failed: the identified loop against the exact sampled-data loop "
             "(with --system: against eig(A + B K), open loop eig(A); outputs kept), 2 bad "
             "input (also plant and controller with different n or U, without "
             "--allow-scale-mismatch), 130 interrupted" + _UNITS,
    "demo": "examples:\n  dronefly demo\n  dronefly demo --native --no-plot\n  dronefly demo --no-plot --set plant.Nr_plus=-5\n"
            "exit codes: 0 ok, 1 a run's cross-check failed (outputs kept), 2 bad input",
    "check": "examples:\n  dronefly check\n  dronefly check build/DroneFlyLateral.fmu --json\n"
             "  dronefly check Model.fmu --ref Model_ref.csv --in Model_in.csv\n"
             "exit codes: 0 all checks passed, 1 a check failed, 2 bad input",
    "analyze": "examples:\n  dronefly analyze\n  dronefly analyze --json\n"
               "  dronefly analyze --markdown --out docs/reproduction.md\n"
               "  dronefly analyze --targets=-0.2,-0.089+0.057j,-0.089-0.057j,-0.51 "
               "--input delta_Phi_a",
    "sweep": "examples:\n  dronefly sweep\n  dronefly sweep --native\n  dronefly sweep --gains paper,stabilising,open "
             "--steps 0.1,0.5,1,2,3\n"
             "  dronefly sweep --disturbances lhs --lhs 500 --scales 1,1.5,2 --out build/lhs\n"
             "  dronefly sweep --scheduler tcp://10.0.0.5:8786\n"
             "rerun with the same --out to resume an interrupted sweep (--fresh starts over)\n"
             "  dronefly sweep --gains paper,my_gains.csv --set plant.Nr_plus=-5\n"
             "  dronefly sweep --system build/DroneFlyHover.ssp --disturbances directions\n"
             "  dronefly sweep --compare nonlinear --out build/validity\n"
             "  dronefly sweep --steps 0.5 --delays 0,1,2,4 --sample-periods 0,1,2 "
             "--disturbances directions\n"
             "exit codes: 0 ok, 1 some cases failed (recorded in the CSV), 2 bad input, "
             "130 interrupted (rerun to resume)" + _SWEEP_UNITS,
    "build": "examples:\n  dronefly build\n  dronefly build --out /tmp/fmus\n  dronefly build --native",
    "aero": "examples:\n  dronefly aero\n  dronefly aero --json --coefficients wang2004\n"
            "  dronefly aero forces --state delta_v=0.1 --control delta_Phi_a=0.2 --json\n"
            "  dronefly aero --no-rotational --added-mass-form sane2001\n"
            "units: states non-dimensional (x+: dv/U, dp t_w, ...), controls in rad; forces "
            "over 0.5 rho U^2 S_t, moments over 0.5 rho U^2 S_t c",
    "floquet": "examples:\n  dronefly floquet\n  dronefly floquet --json\n"
               "  dronefly floquet --plant build/DroneFlyLateral.fmu --period 0.006097560975609756\n"
               "units: --period in s (default 1/n, one wing beat); exponents per wing beat",
    "simulate": "examples:\n  dronefly simulate\n  dronefly simulate --gamma0 0.05 --stop 50\n"
                "units: --stop/--step in wing beats; --gamma0 in rad (SI)",
}


class _Parser(argparse.ArgumentParser):
    """argparse with a one-line error (the usage is one ``--help`` away)."""

    def error(self, message: str) -> None:  # type: ignore[override]
        self.exit(EXIT_USAGE, f"{self.prog}: error: {message} ('{self.prog} --help' shows "
                              "the usage)\n")


def _parser() -> argparse.ArgumentParser:
    p = _Parser(
        prog="dronefly",
        description="FMUs and analysis of the lateral stabilization control of a hovering "
                    "model drone fly (Zhang & Sun).",
        epilog="examples:\n  dronefly build\n  dronefly simulate --stop 100\n  dronefly cosim --json\n"
               "exit codes: 0 ok, 1 a check failed or a run stopped early, 2 bad input, "
               "130 interrupted; an internal error (a bug) exits 1",
        formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--version", action="version", version=f"dronefly {__version__}")
    p.add_argument("--debug", action="store_true",
                   help="show the traceback of an internal error (a bug) or of bad input")
    sub = p.add_subparsers(dest="command", required=True, metavar="COMMAND")

    def add(name: str, helptext: str) -> argparse.ArgumentParser:
        sp = sub.add_parser(name, help=helptext, description=helptext, epilog=_EPILOG.get(name),
                            formatter_class=argparse.RawDescriptionHelpFormatter)
        # also after the subcommand; SUPPRESS keeps a --debug given before it
        sp.add_argument("--debug", action="store_true", default=argparse.SUPPRESS,
                        help="show the traceback of an internal error (a bug) or of bad input")
        return sp

    b = add("build", "build every FMU of the project: FMI 2.0 in DIR, FMI 3.0 in DIR/fmi3")
    b.add_argument("--out", type=out_dir, default="build", metavar="DIR", help="output folder (default: build/)")
    b.add_argument("--native", action="store_true",
                   help="also the native (C) FMUs in DIR/native and DIR/native/fmi3, with binaries "
                        "for every platform the toolchain builds for (zig cc: Linux, Windows, "
                        "macOS; a minute or more) and the closed-loop container (docs/native.md)")

    s = add("simulate", "simulate the open-loop plant FMU with fmpy from a roll disturbance")
    s.add_argument("--stop", type=positive, default=30.0, help="stop time in wing beats (default 30)")
    s.add_argument("--step", type=positive, default=0.1, help="communication step in wing beats (default 0.1)")
    s.add_argument("--gamma0", type=finite, default=0.1,
                   help="initial roll angle delta_gamma in rad, SI (default 0.1)")
    s.add_argument("--out", type=out_dir, default="build", metavar="DIR", help="folder of the FMU and the result CSV")

    c = add("cosim", "co-simulate plant and controller FMUs, or any system of FMUs from an SSP "
            "file, with fmpy and check the stability of each loop")
    c.add_argument("--system", default=None, metavar="SSP",
                   help="co-simulate the system of an SSP file (any number of FMI 2.0 or 3.0 "
                        "CS FMUs); "
                        "--set takes instance.NAME=VALUE; not with --plant/--controller/--gains/"
                        "--x0")
    c.add_argument("--open-loop", action="store_true",
                   help="with --system: also identify each plant's open loop, from runs with the "
                        "gains K[i,j] of the controller that drives it set to zero, and "
                        "cross-check it against eig(A)")
    c.add_argument("--record", type=converter(parse_names), default=None,
                   metavar="INST.NAME,...", help="the variables to record, any Real, Integer "
                   "or Boolean variable of any instance, e.g. lateral.delta_p,"
                   "lateral_controller.K[1,1] with --system (default: every Real, Integer and "
                   "Boolean output); with "
                   "--plant/--controller, plant.NAME or controller.NAME, recorded after the "
                   "states and controls")
    c.add_argument("--native", action="store_true",
                   help="run the native (C) FMUs, DIR/native/DroneFlyLateral.fmu and "
                        "StateFeedback.fmu, built on demand (needs a C compiler; docs/native.md)")
    c.add_argument("--plant", default=None, metavar="FMU",
                   help="plant FMU (default: build/DroneFlyLateral.fmu, built on demand)")
    c.add_argument("--controller", default=None, metavar="FMU",
                   help="controller FMU (default: build/StateFeedback.fmu, built on demand)")
    c.add_argument("--gains", type=converter(parse_gains), default=None, metavar="GAINS",
                   help="non-dimensional 3x4 gain matrix u = K x+ of the lateral pair: paper "
                        "(Eq. 27), stabilising, open, 'k1,k2,k3,k4' (delta_Phi_a only), "
                        "'row1;row2;row3', or a .csv/.json file (default paper; for another "
                        "pair, e.g. the longitudinal one, the controller's own K, and open)")
    c.add_argument("--x0", type=converter(parse_x0), default=None,
                   metavar="dv+,dp+,dr+,dgamma",
                   help="non-dimensional initial state x+, one value per state of the plant "
                        "(default 0,0,0,0.1: a 0.1 rad roll; for another plant 0.1 rad on its "
                        "first angle; or what --set plant.<state>_start gives; not both)")
    c.add_argument("--set", dest="set_values", action="append", default=[],
                   type=parse_setting, metavar="NAME=VALUE",
                   help="set a parameter of the plant or controller (repeatable): plant.NAME=VALUE, "
                        "controller.NAME=VALUE, or NAME=VALUE if only one FMU has NAME; with "
                        "--system, instance.NAME=VALUE of any parameter or input; SI units; the "
                        "value of its declared type (a number, a whole number, true/false/1/0, "
                        "text)")
    c.add_argument("--allow-scale-mismatch", action="store_true",
                   help="accept a plant and a controller whose n or U differ (refused otherwise: "
                        "the controller reads the plant's state with its own n and U)")
    c.add_argument("--build", type=out_dir, default="build", metavar="DIR",
                   help="where the project's FMUs are built if --plant/--controller are not given")
    c.add_argument("--step", type=positive, default=0.1, help="communication step in wing beats (default 0.1)")
    c.add_argument("--stop", type=positive, default=None,
                   help="stop time in wing beats (default 300, or the SSP's DefaultExperiment)")
    c.add_argument("--master", choices=("gauss-seidel", "jacobi"), default="gauss-seidel",
                   help="ordering of the FMU calls (default gauss-seidel)")
    c.add_argument("--out", type=out_dir, default="build/cosim", metavar="DIR", help="folder of CSV, PNG and JSON")
    c.add_argument("--json", action="store_true", help="print a machine-readable summary")
    c.add_argument("--no-plot", action="store_true", help="do not write the PNG")

    k = add("check", "FMI 2.0 and 3.0 co-simulation compliance checks, each naming its rule of "
            "the standard (validate, archive, binary, call sequence, start values, dependencies, "
            "reset, state, Model Exchange, bad input, reference results, logger; for the "
            "project's FMUs also the dronefly profile and the fuzz)")
    k.add_argument("fmus", nargs="*", metavar="FMU", help="FMUs to check (default: build the project "
                   "into --build, FMI 2.0 and FMI 3.0, and check every FMU there)")
    k.add_argument("--build", default="build", metavar="DIR",
                   help="where to build (default build/; the FMI 3.0 FMUs in DIR/fmi3)")
    k.add_argument("--json", action="store_true", help="machine-readable report (with a schema "
                   "version, each check passed/failed/skipped, durations)")
    k.add_argument("--junit", default=None, metavar="FILE",
                   help="also write JUnit XML: a test case per check and FMU")
    k.add_argument("--verbose", action="store_true",
                   help="also show each rule and what the FMU's binaries printed while checked")
    k.add_argument("--no-fuzz", action="store_true", help="skip the short fuzz (faster)")
    k.add_argument("--profile", choices=("auto", "standard", "dronefly"), default="auto",
                   help="standard: the FMI standard alone; dronefly: also the project's stricter "
                        "promises (NaN refused, log wording, corrupt states, fuzz); auto "
                        "(default): dronefly for the project's FMUs, standard for any other")
    k.add_argument("--check", action="append", default=[], metavar="NAME",
                   help="run only this check (repeat, or NAME,NAME)")
    k.add_argument("--skip", action="append", default=[], metavar="NAME",
                   help="do not run this check (repeat, or NAME,NAME)")
    k.add_argument("--stop-time", type=positive, default=None, metavar="S",
                   help="stop time in seconds (default: the FMU's default experiment)")
    k.add_argument("--step", type=positive, default=None, metavar="S",
                   help="communication step in seconds (default: the default experiment's "
                        "stepSize, or a hundredth of the run)")
    k.add_argument("-j", "--jobs", type=int_arg("-j", 1), default=1, metavar="N",
                   help="check N FMUs at once (default 1)")
    k.add_argument("--timeout", type=positive, default=600.0, metavar="S",
                   help="how long the checks of one FMU may take before it is reported as hung "
                        "(default 600 s)")
    k.add_argument("--ref", default=None, metavar="CSV",
                   help="reference result of the one FMU given (FMI cross-check CSV: time, then "
                        "outputs), compared by the reference check (default: <Model>_ref.csv "
                        "beside the FMU, if there)")
    k.add_argument("--in", dest="inputs", default=None, metavar="CSV",
                   help="with --ref: the inputs of the reference run (cross-check CSV)")

    d = add("demo", "open loop and closed loop with the paper's gains: the verdict table")
    d.add_argument("--out", type=out_dir, default="build/cosim", metavar="DIR", help="folder of CSVs and plots")
    d.add_argument("--no-plot", action="store_true", help="do not write the PNGs")
    d.add_argument("--set", dest="set_values", action="append", default=[],
                   type=parse_setting, metavar="NAME=VALUE",
                   help="set a parameter of the plant or controller for both runs (repeatable; "
                        "SI units), as cosim --set")
    d.add_argument("--build", type=out_dir, default="build", metavar="DIR",
                   help="where the project's FMUs are built if missing or out of date")
    d.add_argument("--native", action="store_true",
                   help="run the native (C) FMUs, DIR/native/DroneFlyLateral.fmu and "
                        "StateFeedback.fmu, built on demand (needs a C compiler; docs/native.md)")

    a = add("analyze", "reproduce every number of the paper (Tables 2-3, Eqs. 12-32) from the model")
    form = a.add_mutually_exclusive_group()  # one report: both are refused (exit 2)
    form.add_argument("--json", action="store_true",
                      help="print JSON (table, matrices, eigenvalues, gains); not with --markdown")
    form.add_argument("--markdown", action="store_true",
                      help="print the Markdown report (docs/reproduction.md); not with --json")
    a.add_argument("--targets", default=None, metavar="LIST",
                   help="comma-separated closed-loop eigenvalues per wing beat for an extra "
                        "gain design; write --targets=... when the first one is negative")
    a.add_argument("--input", default=None, metavar="NAME",
                   help="with --targets: the control input of that design: delta_Phi_a "
                        "(default), delta_alpha_1a, delta_alpha_2a")
    a.add_argument("--out", type=out_file, default=None, metavar="FILE", help="write to FILE instead of stdout")
    w = add("sweep", "co-simulate many disturbed closed loops: where do they stay within the "
            "Sect. 3.6 bounds?")
    w.add_argument("--out", type=out_dir, default="build/sweep", metavar="DIR",
                   help="folder of sweep.csv, sweep.json and map_*.png; rerun to resume "
                        "(default build/sweep)")
    w.add_argument("--plant", default=None, metavar="FMU", help="plant FMU (default: built)")
    w.add_argument("--native", action="store_true",
                   help="run the native (C) FMUs, build/native/DroneFlyLateral.fmu and "
                        "StateFeedback.fmu, built on demand (needs a C compiler; docs/native.md)")
    w.add_argument("--controller", default=None, metavar="FMU",
                   help="controller FMU (default: built)")
    w.add_argument("--compare", default=None, metavar="SSP",
                   help="run every case also on this system and measure how far the two "
                        "trajectories differ; 'nonlinear' = the 6-DOF plant "
                        "(build/DroneFlyHover6DOF.ssp) against the linear plants "
                        "(build/DroneFlyHover.ssp), built on demand. Defaults then: --gains "
                        "paper, --steps 1, --stop 100, --grid 25, --amplitudes 12, --extent 3")
    w.add_argument("--halves", action="store_true",
                   help="with --compare nonlinear: also the error of each half of Sect. 3.6 "
                        "(the rigid body, the quasi-steady aerodynamics, both) over the "
                        "direction cases, on the model classes (docs/validity.md; about 1 s "
                        "per case, so not by default)")
    w.add_argument("--extent", type=positive, default=None, metavar="X",
                   help="the disturbances cover X times the Sect. 3.6 box (default 1; 3 with "
                        "--compare)")
    w.add_argument("--system", default=None, metavar="SSP",
                   help="run every case on this system of FMUs (its lateral plant and the "
                        "controller driving it get x0 and gains; --set takes instance.NAME=VALUE)")
    w.add_argument("--disturbances", default="grid,directions", metavar="LIST",
                   help="initial disturbances: grid, lhs, directions (default grid,directions)")
    w.add_argument("--slices", default="dgamma:dv,dgamma:dp,dr:dp", metavar="X:Y,...",
                   help="2-D slices of the box for grid (axes dv, dp, dr, dgamma; "
                        "default dgamma:dv,dgamma:dp,dr:dp)")
    w.add_argument("--grid", type=int_arg("grid", 2), default=None, metavar="N",
                   help="grid points per axis (default 21)")
    w.add_argument("--lhs", type=int_arg("lhs", 1), default=200, metavar="N",
                   help="Latin-hypercube samples (default 200)")
    w.add_argument("--directions", default=",".join(f"{s}{a}" for a in ("dv", "dp", "dr", "dgamma",
                                                                        "mode1") for s in "+-"),
                   metavar="LIST", help="directions for 'directions' (default: +-dv, +-dp, +-dr, "
                                        "+-dgamma, +-mode1 = the unstable eigenvector)")
    w.add_argument("--amplitudes", type=int_arg("amplitudes", 1), default=None, metavar="N",
                   help="amplitudes 1/N..1 of the box per direction (default 10)")
    w.add_argument("--gains", default=None, metavar="LIST",
                   help="gain sets: paper (Eq. 27), stabilising (lambda1 -> -0.1), open, or a "
                        ".csv/.json file with a 3x4 matrix (default paper,stabilising)")
    w.add_argument("--set", dest="set_values", action="append", default=[],
                   type=parse_setting, metavar="NAME=VALUE",
                   help="set a parameter of the plant or controller for every case (repeatable; "
                        "SI units)")
    w.add_argument("--steps", type=floats_arg("steps"), default=None, metavar="LIST",
                   help="communication steps = how often the insect senses and acts, wing beats "
                        "(default 0.1,1,3)")
    w.add_argument("--delays", type=floats_arg("delays"), default="0", metavar="LIST",
                   help="the controller's sensing delays, wing beats (1 wb = 1000/n ms, 6.1 ms "
                        "at 164 Hz; default 0 = not set); adds the loop's verdict with the "
                        "delay states to every row")
    w.add_argument("--sample-periods", type=floats_arg("sample-periods"), default="0",
                   metavar="LIST", help="the controller's sample periods, wing beats (default "
                                        "0 = every communication step)")
    w.add_argument("--scales", type=floats_arg("scales"), default="1", metavar="LIST",
                   help="factors on the bounds (default 1)")
    w.add_argument("--stop", type=floats_arg("stop"), default=None, metavar="WB",
                   help="wing beats per case (default 200)")
    w.add_argument("--master", choices=("gauss-seidel", "jacobi"), default="gauss-seidel",
                   help="ordering of the FMU calls (default gauss-seidel)")
    w.add_argument("--seed", type=int_arg("seed", 0), default=0, metavar="N",
                   help="seed of the Latin hypercube")
    w.add_argument("--workers", type=int_arg("workers", 1), default=None, metavar="N",
                   help="local worker processes (default: all cores; 1 = in this process)")
    w.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help="run on an existing Dask cluster, e.g. tcp://host:8786")
    w.add_argument("--connect-timeout", type=positive, default=10.0, metavar="S",
                   help="seconds to reach the scheduler (default 10)")
    w.add_argument("--fresh", action="store_true", help="discard earlier results in --out")
    w.add_argument("--no-plot", action="store_true", help="do not write the PNG maps")
    w.add_argument("--no-progress", action="store_true", help="no progress bar")
    w.add_argument("--json", action="store_true", help="print the JSON summary")
    q = add("aero", "quasi-steady blade-element model of the wings: its derivatives beside the "
            "paper's CFD values, or its cycle-averaged forces")
    q.add_argument("what", nargs="?", choices=("table", "forces"), default="table",
                   help="table (default): trim, derivatives, eigenvalues, Eq. (27); forces: the "
                        "cycle-averaged X, Y, Z, L, M, N at --state and --control")
    q.add_argument("--state", action="append", default=[], type=parse_setting,
                   metavar="NAME=VALUE", help="with forces: a state delta_u ... delta_r "
                   "(non-dimensional, repeatable)")
    q.add_argument("--control", action="append", default=[], type=parse_setting,
                   metavar="NAME=VALUE", help="with forces: a control delta_Phi_a ... "
                   "delta_alpha_2 in rad (repeatable)")
    q.add_argument("--coefficients", default="dickinson1999", metavar="NAME",
                   help="translational coefficients: dickinson1999 (default), wang2004")
    for term in ("translational", "rotational", "added-mass"):
        q.add_argument(f"--no-{term}", action="store_true", help=f"switch off the {term} term")
    q.add_argument("--added-mass-form", choices=("impulse", "sane2001"), default="impulse",
                   help="added mass as the rate of change of the fluid impulse (default; "
                        "averages to zero over a cycle) or Sane & Dickinson 2001's normal "
                        "acceleration alone")
    q.add_argument("--json", action="store_true", help="print JSON")
    f = add("floquet", "periodic orbit and Floquet exponents of a plant FMU through FMI (get/set "
            "FMU state), beside the averaged model's eigenvalues for the flapping plant")
    f.add_argument("--plant", default=None, metavar="FMU",
                   help="any FMI 2.0 or 3.0 CS FMU that can get and set its state, with an x_start "
                        "parameter per state output x (default: build/DroneFlyFlapping.fmu, "
                        "built if missing)")
    f.add_argument("--period", type=positive, default=None, metavar="S",
                   help="the period in s (default 1/n from the FMU's parameter n)")
    f.add_argument("--steps", type=int_arg("steps", 1), default=1, metavar="N",
                   help="communication steps per period (default 1)")
    f.add_argument("--build", type=out_dir, default="build", metavar="DIR",
                   help="where the default plant is built (default build/)")
    f.add_argument("--json", action="store_true", help="print JSON")
    return p


def _command(name: str) -> ModuleType:
    """The module of subcommand ``name`` (:data:`~dronefly.cli.commands.COMMANDS`), imported
    when it runs: each loads its own analyses, and ``dronefly --help`` none."""
    if name not in COMMANDS:  # the parser knows no other
        raise AssertionError(f"subcommand {name!r} has no module")
    return importlib.import_module(f"{__package__}.commands.{name}")


def _say_built(command: str, module: ModuleType) -> Callable[[Path], None]:
    """What a command that builds the project's FMUs says for each (one line on stderr), unless
    it says so itself (``SAYS_WHAT_IT_BUILT`` in its module: build, cosim, simulate)."""

    def say(path: Path) -> None:
        if not getattr(module, "SAYS_WHAT_IT_BUILT", False):
            print(f"dronefly {command}: built {path}", file=sys.stderr, flush=True)

    return say


def main(argv: Sequence[str] | None = None) -> int:
    """Run the CLI; returns the exit code (also used by ``python -m dronefly``)."""
    parser = _parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as e:  # argparse already printed its one-line error, the help or version
        return int(e.code or 0)
    try:
        module = _command(args.command)
        # Ctrl-C lands between steps, never in an FMU; a command that runs none stops at once
        guard = deferred_sigint if getattr(module, "RUNS_FMUS", True) else sigint_at_once
        with guard() as interrupt, reporting(_say_built(args.command, module)):
            code = int(module.run(args))
        if interrupt.requested:
            raise KeyboardInterrupt
        return code
    except CrossCheckError as e:  # a result its own check contradicts: a failed check
        print(f"dronefly {args.command}: error: cross-check failed: {e}", file=sys.stderr)
        return EXIT_FAILED
    except (DroneflyError, OSError) as e:
        if args.debug:
            traceback.print_exc()
        text = str(e).strip().splitlines()[0] if str(e).strip() else type(e).__name__
        print(f"dronefly {args.command}: error: {text}", file=sys.stderr)
        return EXIT_USAGE
    except KeyboardInterrupt:
        print(f"dronefly {args.command}: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    except Exception as e:  # a bug, never reported as bad input
        if args.debug:
            traceback.print_exc()
        print(f"dronefly {args.command}: internal error (a bug, please report it): "
              f"{type(e).__name__}: {e}" + ("" if args.debug else " (--debug shows the traceback)"),
              file=sys.stderr)
        return EXIT_FAILED


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
