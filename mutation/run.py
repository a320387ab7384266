"""Mutation testing of the modules that carry the physics and the verdicts (docs/mutation.md).

Cosmic Ray (the ``mutation`` extra) writes each mutant into the module's file in place, runs
the module's own fast test selection against it and puts the file back. In place suits this
checkout, whose root is the package ``dronefly``: the editable install imports the mutated
file with no copy of the tree. One session database per module under ``build/mutation/``;
a run that stops resumes where it stopped (``cosmic-ray exec`` runs only the pending work).

Usage::

    python mutation/run.py                       # every module of TARGETS
    python mutation/run.py models/axes.py        # some of them
    python mutation/run.py --report-only         # the report of the sessions run so far
    python mutation/run.py --fresh models/axes.py  # forget a module's results, run it again
    python mutation/run.py --retry-survivors     # run the survivors again, after new tests
    python mutation/run.py --budget-s 600        # stop after 10 min (the rest stays pending)

The report (``build/mutation/report.md``) gives per module the mutants run, killed and
survived, the share killed, and each survivor with its diff.
"""

from __future__ import annotations

import argparse
import os
import signal
import sqlite3
import subprocess
import time
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
OUT = ROOT / "build" / "mutation"
BIN = Path(sys.executable).parent

# Module -> the tests that cover it, the fastest selection that exercises it (seconds, not
# the whole suite per mutant).
# the oracle tests written against the survivors come first: a mutant they kill costs least
_MODELS = "tests/test_mutation_models.py"
_CONTROLLER = "tests/test_mutation_controller.py"
_COMPLIANCE = "tests/test_mutation_compliance.py"
_CHECKS = "tests/test_mutation_checks.py"
_EXPM = ["tests/test_expm.py", "--deselect",  # a second process under another BLAS kernel
         "tests/test_expm.py::test_zero_order_hold_is_the_same_under_another_blas_kernel"]
TARGETS: dict[str, list[str]] = {
    "models/axes.py": [_MODELS, "tests/test_model.py"],
    "models/hover6dof.py": [_MODELS, "tests/test_hover6dof.py"],
    # the axes' interfaces: the paper's flight data and scales, the eigenvalue order, the
    # parameters' descriptions (the FMUs' model descriptions are built from them)
    **{f"models/{m}_interface.py": ["tests/test_mutation_interface.py", _MODELS,
                                    "tests/test_model.py", "tests/test_lateral.py",
                                    "tests/test_longitudinal.py"]
       for m in ("lateral", "longitudinal")},
    "models/lateral_dynamics.py": [_MODELS, "tests/test_model.py"],
    "models/longitudinal_dynamics.py": [_MODELS],
    "models/feedback.py": [_MODELS, "tests/test_controller_law.py"],
    "models/linear_algebra.py": ["tests/test_mutation_linear_algebra.py", *_EXPM],
    "models/linear.py": ["tests/test_mutation_linear.py", _MODELS, "tests/test_model.py", *_EXPM],
    "controller/variables.py": [_CONTROLLER, "tests/test_controller_slave.py"],
    "controller/timing.py": [_CONTROLLER],
    "controller/delay.py": [_CONTROLLER, "tests/test_controller_delay.py"],
    # the slave class called in-process (the few built-FMU cases of test_controller_delay.py
    # build from the mutated source too: seconds)
    "controller/slave.py": [_CONTROLLER, "tests/test_controller_slave.py",
                            "tests/test_controller_delay.py", "tests/test_fmi_base.py"],
    # tests/test_cosim_verdicts.py runs the FMUs: a minute a mutant
    "harness/cosim/identification.py": ["tests/test_mutation_stability.py"],
    # the checker's checks: unit tests on small in-memory descriptions (the checks that run an
    # FMU cost seconds to a minute a mutant through tests/test_check_misreports.py)
    "harness/compliance/rules.py": [_COMPLIANCE],
    "harness/compliance/structure.py": [_COMPLIANCE],
    # the nonlinear plant: its equations and steps on small inputs (the FMU tests of
    # test_hover6dof.py, marked integration, build and run the FMU: seconds a mutant)
    "models/rigid_body.py": ["tests/test_mutation_rigid_body.py", "tests/test_hover6dof.py",
                             "-m", '"not integration"'],
    "models/shooting.py": ["tests/test_mutation_shooting.py"],
    # the quasi-steady wings: unit oracles, then the model's tests (python-control's gains
    # left out: two seconds a mutant for a comparison that reads the derivatives only)
    **{f"models/quasisteady/{m}.py": [
        "tests/test_mutation_quasisteady.py", "tests/test_aero.py", "--deselect",
        "tests/test_aero.py::test_matched_gains_against_python_control"]
       for m in ("kinematics", "elements", "wing", "trim", "model")},
    # the blade-element loads: the paper's derivatives and the model's three evaluations of
    # the loads (test_aero.py), the instantaneous forces against the sampled ones
    # (test_flapping.py's comparison on the fine grid included)
    **{f"models/quasisteady/{m}.py": [
        "tests/test_mutation_quasisteady.py", "tests/test_aero.py", "--deselect",
        "tests/test_aero.py::test_matched_gains_against_python_control", "tests/test_flapping.py"]
       for m in ("instantaneous", "cycle")},
    # the wing-beat-resolved model in time for a host (the comparison of the sampled forces
    # on grids of 1000 and 3000, 1.6 s, is about the forces, not the flight)
    **{f"models/flapping/{m}.py": [
        "tests/test_mutation_flapping.py", "tests/test_flapping.py", "--deselect", "tests/test_flapping.py::"
        "test_instantaneous_forces_are_the_sampled_forces_of_the_quasi_steady_model"]
       for m in ("flight", "orbit")},
    # the equations: unit oracles on one beat of 20 steps, then the model's tests (their
    # one-beat integrations against solve_ivp, a second each at most) and the flight's and
    # orbit's (the model through its callers)
    "models/flapping/model.py": [
        "tests/test_mutation_flapping_model.py", "tests/test_flapping.py", "--deselect",
        "tests/test_flapping.py::"
        "test_instantaneous_forces_are_the_sampled_forces_of_the_quasi_steady_model",
        "tests/test_mutation_flapping.py"],
    # the paper's numbers: the analysis of the printed matrices and the designs beyond them
    # (oracles on systems built for the purpose), the modal form, the reproduction's rows
    # against the printed values, and their reports (unit tests, 2 s in all)
    **{f"harness/paper/{m}.py": ["tests/test_mutation_paper.py", "tests/test_analysis.py",
                                 "tests/test_reproduction_rows.py"]
       for m in ("analysis", "design", "modal")},
    **{f"harness/paper/{m}.py": ["tests/test_analysis.py", "tests/test_reproduction_rows.py",
                                 "tests/test_mutation_paper.py"]
       for m in ("reproduction", "rows", "report")},
    "harness/paper/gains.py": ["tests/test_mutation_paper.py", "tests/test_analysis.py",
                               "tests/test_cli_features.py"],
    # the checks that read an archive or call a binary, on tiny archives and stub contexts
    "harness/compliance/static.py": [_CHECKS],
    "harness/compliance/names.py": [_CHECKS, "tests/test_check_names.py"],
    # stub libraries and slaves, and the Reference-FMUs' Dahlquist loaded in-process
    "harness/compliance/binary.py": [_CHECKS],
    # a fake FMU with seeded defects, the Reference-FMUs' Feedthrough in-process
    "harness/compliance/refusals.py": [_CHECKS],
    "harness/compliance/runtime.py": [_CHECKS],
    # the committed reference files, fmpy.simulate_fmu stubbed
    "harness/compliance/reference.py": [_CHECKS],
    # the fuzz: its groups in-process against a fake slave with seeded defects and the
    # Reference-FMUs, the parent's side against a stub child (no process started)
    **{f"harness/compliance/{m}.py": ["tests/test_mutation_fuzz.py"]
       for m in ("fuzzkit", "fuzzrandom", "fuzzcases", "fuzz")},
    # the runner: the check list with stub checks on the Reference-FMUs' Dahlquist
    "harness/compliance/checker.py": ["tests/test_mutation_checker.py"],
    # the Model Exchange family (the Reference-FMUs in-process, FMPy's simulation stubbed for
    # the record's bookkeeping) and the driver every runtime check drives the FMU through
    "harness/compliance/exchange.py": [_CHECKS],
    "harness/compliance/driver.py": ["tests/test_mutation_check_driver.py", _CHECKS],
    # the suite: its reports, its scope, a checking process that crashed (stood in for
    # in-process), the fuzz it adds
    "harness/compliance/suite.py": ["tests/test_mutation_suite.py"],
    # the pytest plugin: its planned tests against an in-process run, its verdicts in pytest
    # runs of their own (a conftest hands it reports written by hand)
    "harness/compliance/pytest_plugin.py": ["tests/test_mutation_plugin.py"],
    # the checking process: the fork server and the fresh interpreter it falls back to (how
    # a child ended is the verdict of a crash or a hang)
    **{f"harness/compliance/{m}.py": ["tests/test_forkserver.py"]
       for m in ("child", "forkserver")},
}

# Operators: the classic mutation set (arithmetic swaps, comparison flips and boundary shifts,
# negated conditions, constants +-1, booleans, loops that run zero times, exceptions that no
# longer match). Excluded: a binary operator replaced by an unrelated one (bit shifts and the
# like on floats die at once and only cost time), the variable replacer/inserter (random
# names, not reproducible), removed decorators.
KEEP_BINARY = "Add_Sub|Sub_Add|Mul_Div|Div_Mul|Pow_Mul|FloorDiv_Div|Mod_FloorDiv|MatMult_Mul"
KEEP_COMPARE = ("Eq_NotEq|NotEq_Eq|Lt_GtE|GtE_Lt|Gt_LtE|LtE_Gt|Lt_LtE|LtE_Lt|Gt_GtE|GtE_Gt"
                "|Is_IsNot|IsNot_Is|In_NotIn|NotIn_In")
EXCLUDE = [
    rf"core/ReplaceBinaryOperator_(?!({KEEP_BINARY})$)",
    rf"core/ReplaceComparisonOperator_(?!({KEEP_COMPARE})$)",
    r"core/ReplaceUnaryOperator_(?!(USub_UAdd|Delete_USub|Delete_Not)$)",
    r"core/VariableReplacer",
    r"core/VariableInserter",
    r"core/RemoveDecorator",
]
TIMEOUT_S = 120.0


def config_text(module: str) -> str:
    """The Cosmic Ray configuration of one module (TOML)."""
    tests = " ".join(TARGETS[module])
    command = f"{BIN / 'python'} -m pytest -x -q -p no:randomly -p no:cacheprovider {tests}"
    excluded = ", ".join("'" + e + "'" for e in EXCLUDE)  # TOML literal strings: no escapes
    return (
        "[cosmic-ray]\n"
        f"module-path = '{module}'\n"
        f"timeout = {TIMEOUT_S}\n"
        "excluded-modules = []\n"
        f"test-command = '{command}'\n"
        "[cosmic-ray.distributor]\n"
        "name = 'local'\n"
        "[cosmic-ray.filters.operators-filter]\n"
        f"exclude-operators = [{excluded}]\n"
    )


def _paths(module: str) -> tuple[Path, Path]:
    stem = module.replace("/", "__").removesuffix(".py")
    return OUT / f"{stem}.toml", OUT / f"{stem}.sqlite"


def run_module(module: str, fresh: bool, retry: bool, deadline: float | None) -> bool:
    """Initialise (once) and execute the pending mutants of one module, until ``deadline``
    (``time.monotonic()``; None: no limit). False: stopped before the end.

    With ``retry`` the survivors of an earlier run are run again (after new tests).
    """
    config, session = _paths(module)
    OUT.mkdir(parents=True, exist_ok=True)
    config.write_text(config_text(module))
    if fresh or not session.exists():
        session.unlink(missing_ok=True)
        subprocess.run([BIN / "cosmic-ray", "init", config, session], cwd=ROOT, check=True)
        subprocess.run([BIN / "cr-filter-operators", session, config], cwd=ROOT, check=True)
    elif retry:
        # Cosmic Ray's exec runs the work items without a result: drop the survivors' results
        with sqlite3.connect(session) as db:
            db.execute("DELETE FROM work_results WHERE test_outcome = 'SURVIVED'")
    # a fresh bytecode cache per test session (tests/conftest.py): a mutant written in the same
    # second as the last one, with the same size, would otherwise import the last one's bytecode
    env = dict(os.environ, OPENBLAS_NUM_THREADS="1", DRONEFLY_TEST_PYCACHE="session")
    proc = subprocess.Popen([BIN / "cosmic-ray", "exec", config, session], cwd=ROOT, env=env)
    try:
        proc.wait(timeout=None if deadline is None else max(deadline - time.monotonic(), 0.0))
    except (subprocess.TimeoutExpired, KeyboardInterrupt):
        # SIGINT, never a kill: Cosmic Ray puts the module's text back on its way out (a
        # killed run leaves the mutant in the file); the mutant under test stays pending
        proc.send_signal(signal.SIGINT)
        proc.wait()
        return False
    if proc.returncode != 0:
        raise SystemExit(f"mutation: cosmic-ray exec failed on {module} ({proc.returncode})")
    return True


def summarise(module: str) -> tuple[int, int, int, list[tuple[str, str, str]]] | None:
    """(run, killed, incompetent, survivors as (operator, line, diff)) of one module's session."""
    from cosmic_ray.work_db import WorkDB, use_db
    from cosmic_ray.work_item import TestOutcome, WorkerOutcome

    _, session = _paths(module)
    if not session.exists():
        return None
    run = killed = incompetent = 0
    survivors = []
    with use_db(str(session), WorkDB.Mode.open) as db:
        for item, result in db.completed_work_items:
            if result.worker_outcome in (WorkerOutcome.SKIPPED, WorkerOutcome.NO_TEST):
                continue
            run += 1
            if result.test_outcome == TestOutcome.SURVIVED:
                m = item.mutations[0]
                survivors.append((m.operator_name.removeprefix("core/"), str(m.start_pos[0]),
                                  result.diff or ""))
            else:
                killed += 1
                incompetent += result.test_outcome == TestOutcome.INCOMPETENT
        pending = len(db.pending_work_items)
    survivors.sort(key=lambda s: (int(s[1]), s[0]))
    return run, killed, pending, survivors


def report(modules: list[str]) -> str:
    """The Markdown report of the sessions run so far."""
    lines = ["# Mutation report", "",
             "| module | mutants | killed | survived | pending | killed % |",
             "|---|---:|---:|---:|---:|---:|"]
    details = []
    for module in modules:
        s = summarise(module)
        if s is None:
            continue
        run, killed, pending, survivors = s
        share = f"{100.0 * killed / run:.1f}" if run else "-"
        lines.append(f"| {module} | {run} | {killed} | {len(survivors)} | {pending} | {share} |")
        if survivors:
            details += ["", f"## {module}: survivors", ""]
            for op, line, diff in survivors:
                body = "\n".join(ln for ln in diff.splitlines()
                                 if ln.startswith(("+", "-")) and not ln.startswith(("+++", "---")))
                details += [f"- line {line}, {op}", "", "```diff", body, "```"]
    return "\n".join(lines + details) + "\n"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("modules", nargs="*", help="modules of TARGETS (default: all)")
    parser.add_argument("--fresh", action="store_true", help="forget earlier results")
    parser.add_argument("--retry-survivors", action="store_true",
                        help="run the survivors of earlier runs again")
    parser.add_argument("--budget-s", type=float, default=None,
                        help="stop after this many seconds (the rest stays pending)")
    parser.add_argument("--report-only", action="store_true", help="write the report only")
    args = parser.parse_args(argv)
    modules = args.modules or list(TARGETS)
    unknown = [m for m in modules if m not in TARGETS]
    if unknown:
        print(f"mutation: not a target module: {unknown[0]}", file=sys.stderr)
        return 2
    if not args.report_only:
        # Cosmic Ray mutates in place: a module that differs from the commit may hold the
        # mutant of a run that was killed before it put the file back
        dirty = subprocess.run(["git", "diff", "--name-only", "HEAD", "--", *TARGETS],
                               cwd=ROOT, capture_output=True, text=True, check=True).stdout
        if dirty.strip():
            print(f"mutation: modules differ from HEAD (a mutant left behind?): "
                  f"{dirty.split()[0]}; restore or commit them first", file=sys.stderr)
            return 2
        deadline = None if args.budget_s is None else time.monotonic() + args.budget_s
        for module in modules:
            if not run_module(module, args.fresh, args.retry_survivors, deadline):
                break
    text = report(list(TARGETS))
    OUT.mkdir(parents=True, exist_ok=True)
    (OUT / "report.md").write_text(text)
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
