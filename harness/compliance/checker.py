"""``dronefly check``: a co-simulation compliance suite for FMI 2.0 and FMI 3.0 FMUs.

The runner. The checks live in their families, one home each, every one a function
``check(ctx) -> detail`` for FMI 2.0 and 3.0 alike:

* :mod:`.static` (the FMU without running it): ``validate``, ``archive``;
* :mod:`.binary` (the shared library as a host links and calls it): ``binary``;
* :mod:`.runtime` (runtime semantics): ``call-sequence``, ``start-values``, ``dependencies``,
  ``reset``, ``two-instances``, ``state``, ``reference``;
* :mod:`.exchange` (the Model Exchange interface): ``model-exchange`` (the event iteration,
  FMPy's Model Exchange simulation); and the runtime checks above once more through Model
  Exchange, named ``me:call-sequence``, ``me:start-values``, ``me:dependencies``,
  ``me:reset``, ``me:two-instances``, ``me:state`` (the same functions, their instances
  :class:`..cosim.exchange.MEStepper`: ``ctx.interface == "me"``);
* :mod:`.refusals` (calls to refuse or survive): ``bad-input``, ``state-machine``,
  ``discard``, ``state-refusal``, ``logger-format``.

Their rules are :mod:`.rules`'; :mod:`.driver` drives the FMU. :data:`CHECKS` lists them in
order with what each needs: a binary for this platform (static checks run without one), the
interface it drives, the FMI versions and profiles it is listed for by default, and the checks
whose failure leaves it ``not run`` (a failure is reported once, under the rule the FMU broke).
A check of an interface the FMU lacks is not listed, except ``call-sequence`` and
``model-exchange``, which say "not applicable: no ... interface" for their interface's checks.
The checks run in this process; :mod:`.suite` runs them in a child process (so a crashing FMU is a failed check)
and adds the fuzz.
"""

from __future__ import annotations

import time
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import Callable

from ...core.interrupt import pending
from ..cosim.fmu import FMU, FMUError
from . import binary, exchange, refusals, runtime, static
from .driver import Context, experiment, profile_for
from .rules import (PROFILES, RULES, CheckFailed, CheckOptions, CheckResult, CheckSkipped,
                    FMUReport, rule_of)

__all__ = ["CHECKS", "CHECK_NAMES", "INTERFACES", "PROFILES", "RULES", "Check", "CheckFailed",
           "CheckOptions", "CheckResult", "CheckSkipped", "FMUReport", "experiment", "listed", "profile_for",
           "rule_of", "run_checks"]


@dataclass(frozen=True)
class Check:
    """One check: its name (a key of :data:`RULES`), its function and what it needs."""

    name: str
    fn: Callable[[Context], str]
    #: it calls the FMU (needs a binary for this platform)
    runs: bool = True
    #: the FMI versions and profiles it is listed for when not selected by name
    versions: tuple[int, ...] = (2, 3)
    profiles: tuple[str, ...] = PROFILES
    #: the checks whose failure leaves it not run (it would fail on their finding)
    needs: tuple[str, ...] = ()
    #: the interface it drives: "cs" (Co-Simulation), "me" (Model Exchange) or "any"
    interface: str = "cs"
    #: listed on an FMU without its interface, to say that it does not apply
    announces: bool = False


_RUN = ("call-sequence",)
_ME = ("model-exchange",)
_ME_RUN = ("model-exchange", "me:call-sequence")
CHECKS: tuple[Check, ...] = (
    Check("validate", static.check_validate, runs=False, interface="any"),
    Check("archive", static.check_archive, runs=False, interface="any"),
    Check("binary", binary.check_binary, interface="any"),
    Check("call-sequence", runtime.check_call_sequence, announces=True),
    Check("start-values", runtime.check_start_values),
    Check("dependencies", runtime.check_dependencies),
    Check("reset", runtime.check_reset, needs=_RUN),
    Check("two-instances", runtime.check_two_instances, needs=_RUN),
    Check("state", runtime.check_state, needs=_RUN),
    Check("model-exchange", exchange.check_model_exchange, interface="me", announces=True),
    Check("me:call-sequence", runtime.check_call_sequence, interface="me", needs=_ME),
    Check("me:start-values", runtime.check_start_values, interface="me", needs=_ME),
    Check("me:dependencies", runtime.check_dependencies, interface="me", needs=_ME),
    Check("me:reset", runtime.check_reset, interface="me", needs=_ME_RUN),
    Check("me:two-instances", runtime.check_two_instances, interface="me", needs=_ME_RUN),
    Check("me:state", runtime.check_state, interface="me", needs=_ME_RUN),
    Check("bad-input", refusals.check_bad_input),
    Check("reference", runtime.check_reference, needs=_RUN),
    Check("state-machine", refusals.check_state_machine, versions=(3,)),
    Check("discard", refusals.check_discard, versions=(3,), profiles=("dronefly",), needs=_RUN),
    Check("state-refusal", refusals.check_state_refusal, versions=(3,), profiles=("dronefly",),
          needs=_RUN),
    Check("logger-format", refusals.check_logger_format),  # last: a crash leaves no other out
)
CHECK_NAMES = tuple(c.name for c in CHECKS)
assert set(CHECK_NAMES) == set(RULES)

#: the rule that forbids any call after Fatal, the checker's own calls included
_FATAL_RULE = {"fmi2": "FMI 2.0 2.1.3", "fmi3": "FMI 3.0 2.2.3"}


#: the interfaces by their short names, as a report says them
INTERFACES = {"cs": "Co-Simulation", "me": "Model Exchange"}


def listed(check: Check, fmi_version: int, profile: str,
           interfaces: tuple[str, ...] = ("cs", "me")) -> bool:
    """Whether ``check`` is run (or said not to apply) on such an FMU, with such
    ``interfaces`` ("cs", "me"), when the user selected no check by name."""
    return (fmi_version in check.versions and profile in check.profiles
            and (check.interface == "any" or check.interface in interfaces or check.announces))


def _not_applicable(check: Check, fmi_version: int, profile: str,
                    interfaces: tuple[str, ...]) -> str:
    if check.interface not in ("any", *interfaces):
        return f"no {INTERFACES[check.interface]} interface"
    if fmi_version not in check.versions:
        return f"{check.name} is an FMI 3.0 check; this FMU is FMI 2.0"
    return (f"{check.name} is the dronefly profile's check (--profile dronefly runs it); this "
            f"FMU is checked under the {profile} profile")


def run_checks(path: Path, progress: Callable[[dict], None] | None = None,
               options: CheckOptions | None = None) -> FMUReport:
    """Every selected check on one FMU, in this process.

    ``progress`` is called with ``{"begin": name}`` before each check, the result (as a
    dict) after it, and, while it runs, ``{"call": ...}`` before each FMI call that may not
    return and ``{"log": ...}`` for each message the FMU logs.
    """
    options = options or CheckOptions()
    report = FMUReport(path)
    t0 = time.perf_counter()

    def add(result: CheckResult) -> None:
        report.checks.append(result)
        if progress:
            progress(asdict(result))

    try:  # unvalidated and without a binary for this platform: validate and archive say so
        fmu = FMU(path, validate=False, require_binary=False, require_cosim=False)
    except FMUError as e:
        add(CheckResult("load", False, str(e), rule="FMI 2.0 / 3.0 FMU archive"))
        return report
    with fmu:
        try:
            ctx = Context(fmu, options, progress)
        except FMUError as e:  # the FMU's default experiment leaves no step
            add(CheckResult("experiment", False, str(e), rule="FMI 2.0 4.2.2 / FMI 3.0 4.2: "
                                                                "steps within the experiment"))
            return report
        ctx.cannot_run = static.cannot_run(ctx)
        report.profile = ctx.profile
        if progress:
            progress({"profile": ctx.profile})
        for check in CHECKS:
            if not options.wants(check.name):
                continue
            rule = rule_of(check.name, fmu.fmi_version, ctx.profile)
            if not listed(check, fmu.fmi_version, ctx.profile, ctx.interfaces) or \
                    check.interface not in ("any", *ctx.interfaces):
                if check.name in options.only or listed(check, fmu.fmi_version, ctx.profile,
                                                        ctx.interfaces):
                    # selected by name, or announcing: said why it does not apply
                    add(CheckResult(check.name, True, "not applicable: " + _not_applicable(
                        check, fmu.fmi_version, ctx.profile, ctx.interfaces), rule,
                        skipped=True))
                continue
            if pending():  # Ctrl-C between two checks (in-process runs)
                raise KeyboardInterrupt
            if progress:
                progress({"begin": check.name})
            add(_one(ctx, check, rule))
    report.duration_s = time.perf_counter() - t0
    return report


def _not_run(ctx: Context, check: Check) -> str | None:
    """Why ``check`` is not run on this FMU (a finding it depends on), or None."""
    if ctx.fatal is not None:
        return (f"the FMU returned {ctx.fmi}Fatal in {ctx.fatal}, after which no function of "
                f"any of its instances may be called ({_FATAL_RULE[ctx.fmi]})")
    if check.runs and ctx.cannot_run:
        return ctx.cannot_run
    if check.runs and ctx.unusable:
        return ctx.unusable
    failed = [n for n in check.needs if n in ctx.failed]
    if failed:
        return (f"it depends on {', '.join(failed)}, which failed (the finding is reported "
                "there)")
    return None


def _one(ctx: Context, check: Check, rule: str) -> CheckResult:
    why = _not_run(ctx, check)
    if why is not None:
        return CheckResult(check.name, True, f"not run: {why}", rule, skipped=True)
    ctx.warnings, ctx.instances = [], []
    ctx.interface = "me" if check.interface == "me" else "cs"
    t0 = time.perf_counter()
    try:
        result = CheckResult(check.name, True, check.fn(ctx), rule)
    except CheckSkipped as e:
        result = CheckResult(check.name, True, f"not applicable: {e}", rule, skipped=True)
    except AssertionError as e:  # CheckFailed
        result = CheckResult(check.name, False, str(e), rule)
    except Exception as e:  # an FMI call failed: that is a finding, not a crash
        result = CheckResult(check.name, False, f"{type(e).__name__}: {e}".rstrip("."), rule)
        if getattr(e, "status", None) == 4:
            ctx.fatal = check.name
    finally:
        for inst in ctx.instances if ctx.fatal is None else ():  # nothing after a Fatal
            try:
                inst.free()
            except Exception:
                pass
    if not result.passed:
        ctx.failed.add(check.name)
        try:
            tail = ctx.log_tail()
        except Exception as e:  # after a Fatal the FMU may have corrupted the process
            tail = f"(its log cannot be read: {type(e).__name__})"
        if tail and check.runs:
            result = replace(result, detail=f"{result.detail} (the FMU logged: {tail})")
    return replace(result, warning="; ".join(ctx.warnings),
                   duration_s=round(time.perf_counter() - t0, 6))
