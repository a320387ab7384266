"""The rules ``dronefly check`` enforces, and what a check reports.

Each check enforces one rule of the FMI standard and names it (:data:`RULES`: the rule and its
section of FMI 2.0 and of FMI 3.0, and the dronefly profile's stricter promise). A check runs
under a *profile*:

* ``standard``: the FMI standard alone; the default for any FMU that dronefly did not write.
  Where the standard leaves the FMU free (what it does with a NaN input, the wording of its
  log, whether it detects corrupt serialized state), nothing is demanded.
* ``dronefly``: the stricter promises of the project's own FMUs (a NaN input refused with
  Discard and a logged message naming the value; every refusal logged in our wording; the
  instance continues after a refused step; corrupt states refused; outputs that respond to
  the inputs; the fuzz), with the standard's other checks. Chosen automatically for FMUs whose
  ``generationTool`` is dronefly's.

A check returns its detail line, raises :class:`CheckSkipped` (not applicable) or
:class:`CheckFailed` (an FMI call that raised fails it too).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

__all__ = ["PROFILES", "RULES", "STATUS_NAMES", "CheckFailed", "CheckOptions", "CheckResult",
           "CheckSkipped", "FMUReport", "require", "rule_of", "status_name"]

#: the profiles a check can run under (see the module text)
PROFILES = ("standard", "dronefly")

#: the rule each check enforces: ``{name: (FMI 2.0 rule, FMI 3.0 rule, dronefly profile's
#: stricter promise or "")}``; "" where the check does not apply to that version
RULES: dict[str, tuple[str, str, str]] = {
    "validate": (
        "FMI 2.0 2.2 (FMI Description Schema): modelDescription.xml is schema-valid and "
        "consistent, every problem listed with its section (2.2.7 causality/variability/"
        "initial and start, 2.2.8 ModelStructure, 2.2.2 units, 2.2.3 types, min <= start <= "
        "max, nominal > 0, aliases)",
        "FMI 3.0 2.4 (FMI Description Schema): modelDescription.xml is schema-valid and "
        "consistent, every problem listed with its section (2.4.7 variables, 2.4.8 "
        "ModelStructure, 2.4.2 units, 2.4.3 types, dimensions, clocks)", ""),
    "archive": (
        "FMI 2.0 2.3 (FMU Distribution): the archive holds an implementation (a binary "
        "binaries/<platform>/<modelIdentifier> or sources/), platform folders named as the "
        "standard names them",
        "FMI 3.0 2.5 (FMU Distribution): the archive holds an implementation (a binary "
        "binaries/<platform tuple>/<modelIdentifier> or sources/), platform folders named "
        "<arch>-<sys>", ""),
    "binary": (
        "FMI 2.0 2.1.1, 2.1.4 (the binary): every function the interface and the declared "
        "capabilities require is exported; fmi2GetVersion is \"2.0\" and fmi2GetTypesPlatform "
        "\"default\"",
        "FMI 3.0 2.2.1 (the binary): every function the interface and the declared "
        "capabilities require is exported; fmi3GetVersion is \"3.0\"", ""),
    "call-sequence": (
        "FMI 2.0 4.2.4 (state machine of the calling sequence): instantiate, initialize, "
        "fmi2DoStep to the stop time, terminate, free succeed; 4.2.3: a slave may end the run "
        "(fmi2Discard with fmi2Terminated)",
        "FMI 3.0 4.2 (fmi3DoStep): the calling sequence succeeds; terminateSimulation and "
        "earlyReturn end the run", "outputs are finite and respond to the inputs"),
    "start-values": (
        "FMI 2.0 2.2.7 (initial = \"exact\"): the variable is initialized with its start value",
        "FMI 3.0 2.4.7 (initial = \"exact\"): the variable is initialized with its start value",
        ""),
    "dependencies": (
        "FMI 2.0 2.2.8 (ModelStructure dependencies): an output depends only on the inputs "
        "listed (\"\": on none); InitialUnknowns tested in Initialization Mode, Outputs in Step "
        "Mode by two continuations from one saved FMU state over a small step (4.2.4 forbids a "
        "get after a set without a step)",
        "FMI 3.0 2.4.8 (ModelStructure dependencies): an output depends only on the inputs "
        "listed; InitialUnknown tested in Initialization Mode, Output in Step Mode by two "
        "continuations from one saved FMU state over a small step", ""),
    "reset": (
        "FMI 2.0 2.1.6 (fmi2Reset): the FMU goes into the same state as after fmi2Instantiate",
        "FMI 3.0 2.3 (FMU states, fmi3Reset): the FMU goes into the same state as after "
        "instantiation", ""),
    "two-instances": (
        "FMI 2.0 2.1.5 (fmi2Instantiate): instances are independent unless "
        "canBeInstantiatedOnlyOncePerProcess",
        "FMI 3.0 (fmi3Instantiate*): instances are independent unless "
        "canBeInstantiatedOnlyOncePerProcess", ""),
    "state": (
        "FMI 2.0 2.1.8 (Getting and Setting the Complete FMU State): a restored state "
        "continues as the original did",
        "FMI 3.0 2.2.6.4 (Getting and Setting the Complete FMU State): a restored state "
        "continues as the original did", ""),
    "model-exchange": (
        "FMI 2.0 3.2.3 (Model Exchange state machine): the event iteration of initialization "
        "terminates; FMPy's Model Exchange simulation (CVODE, events) runs to the stop time",
        "FMI 3.0 3 (Model Exchange, its state machine): the event iteration of initialization "
        "terminates; FMPy's Model Exchange simulation (CVODE, events) runs to the stop time", ""),
    "me:call-sequence": (
        "FMI 2.0 3.2.3 (Model Exchange state machine): instantiate, initialize with the event "
        "iteration, Continuous-Time Mode integrated to the stop time (CVODE restarted at each "
        "communication point) with time, state and step events handled in Event Mode, "
        "terminate, free succeed; terminateSimulation ends the run",
        "FMI 3.0 3.2 (Model Exchange state machine): instantiate, initialize with the event "
        "iteration, Continuous-Time Mode integrated to the stop time with time, state and "
        "step events handled in Event Mode, terminate, free succeed; terminateSimulation ends "
        "the run", "outputs are finite and respond to the inputs"),
    "me:start-values": (
        "FMI 2.0 2.2.7 (initial = \"exact\"), through Model Exchange: the variable is "
        "initialized with its start value",
        "FMI 3.0 2.4.7 (initial = \"exact\"), through Model Exchange: the variable is "
        "initialized with its start value", ""),
    "me:dependencies": (
        "FMI 2.0 2.2.8 (ModelStructure dependencies), through Model Exchange: InitialUnknowns "
        "tested in Initialization Mode; Outputs and Derivatives where 3.2.3 allows a get after "
        "a set (each input moved alone: continuous ones in Continuous-Time Mode, discrete ones "
        "in Event Mode)",
        "FMI 3.0 2.4.8 (ModelStructure dependencies), through Model Exchange: InitialUnknown "
        "tested in Initialization Mode; Output and ContinuousStateDerivative where a get after "
        "a set is allowed (continuous inputs in Continuous-Time Mode, discrete ones in Event "
        "Mode)", ""),
    "me:reset": (
        "FMI 2.0 2.1.6 (fmi2Reset), through Model Exchange: the FMU goes into the same state "
        "as after fmi2Instantiate",
        "FMI 3.0 2.3 (FMU states, fmi3Reset), through Model Exchange: the FMU goes into the "
        "same state as after instantiation", ""),
    "me:two-instances": (
        "FMI 2.0 2.1.5 (fmi2Instantiate), through Model Exchange: instances are independent "
        "unless canBeInstantiatedOnlyOncePerProcess",
        "FMI 3.0 (fmi3InstantiateModelExchange): instances are independent unless "
        "canBeInstantiatedOnlyOncePerProcess", ""),
    "me:state": (
        "FMI 2.0 2.1.8 (Getting and Setting the Complete FMU State), through Model Exchange "
        "(its canGetAndSetFMUstate, canSerializeFMUstate): a restored state continues as the "
        "original did",
        "FMI 3.0 2.2.6.4 (Getting and Setting the Complete FMU State), through Model Exchange: "
        "a restored state continues as the original did", ""),
    "bad-input": (
        "FMI 2.0 4.2.2 (fmi2DoStep: communicationStepSize > 0, the communication point "
        "continues the last) and 2.1.3 (after fmi2Error only fmi2Reset, fmi2FreeInstance or "
        "fmi2SetFMUstate)",
        "FMI 3.0 4.2 (fmi3DoStep arguments) and 2.2.4 (after fmi3Error only fmi3Reset, "
        "fmi3FreeInstance or fmi3SetFMUState)",
        "a NaN input and bad arguments answered Discard with a logged message naming the value; "
        "the instance continues"),
    "reference": (
        "FMI cross-check rules (reference results: <Model>_ref.csv, _in.csv, _ref.opt): the "
        "outputs within FMPy's validation band (fmpy.util.validate_signal) of the reference",
        "FMI cross-check rules (reference results: <Model>_ref.csv, _in.csv, _ref.opt): the "
        "outputs within FMPy's validation band (fmpy.util.validate_signal) of the reference", ""),
    "logger-format": (
        "FMI 2.0 2.1.5 (fmi2CallbackLogger): the logger gets the componentEnvironment and the "
        "instance name the host passed; message is a printf format string, so text the FMU "
        "does not mean as a directive (an instance name with %) must reach it escaped (%%)",
        "FMI 3.0 (fmi3LogMessageCallback): the callback gets the instanceEnvironment the host "
        "passed; the message is plain text, no format", ""),
    "state-machine": (
        "", "FMI 3.0 2.2.4 (status returned by functions) and 2.3 (FMU states): a call not "
            "allowed in the current state returns fmi3Error; after it fmi3Reset recovers",
        "our log wording names the state; refused sets and unknown value references"),
    "discard": ("", "dronefly profile only: a NaN input answered fmi3Discard (the standard "
                    "leaves it to the FMU)", "a NaN input answered fmi3Discard"),
    "state-refusal": ("", "dronefly profile only: corrupt serialized state refused (the "
                          "standard does not require detecting it)",
                      "corrupt serialized state refused, the instance unchanged"),
}

STATUS_NAMES = ("OK", "Warning", "Discard", "Error", "Fatal", "Pending")


def status_name(status: int, fmi_version: int) -> str:
    """``fmi2Discard`` for status 2 of an FMI 2.0 FMU (the standard's name, never a number)."""
    name = STATUS_NAMES[status] if 0 <= status < len(STATUS_NAMES) else f"status {status}"
    return f"fmi{fmi_version}{name}"


def rule_of(name: str, fmi_version: int, profile: str) -> str:
    """The rule line of check ``name`` (with the dronefly profile's promise if it adds one)."""
    r2, r3, ours = RULES.get(name, ("", "", ""))
    rule = r3 if fmi_version == 3 else r2
    return rule + (f"; dronefly profile: {ours}" if ours and profile == "dronefly" else "")


@dataclass(frozen=True)
class CheckResult:
    """One check on one FMU: passed, failed or skipped (``skipped`` implies ``passed``; a check
    left out because one it depends on failed is skipped with ``not run: ...``)."""

    name: str
    passed: bool
    detail: str = ""
    rule: str = ""
    skipped: bool = False
    warning: str = ""
    duration_s: float = 0.0

    @property
    def status(self) -> str:
        """``"passed"``, ``"failed"`` or ``"skipped"``."""
        return "skipped" if self.skipped else "passed" if self.passed else "failed"


@dataclass(frozen=True)
class CheckOptions:
    """What to check and how.

    Parameters
    ----------
    profile : {None, "standard", "dronefly"}
        None: ``"dronefly"`` for the project's FMUs, ``"standard"`` for any other.
    stop_time, step : float or None
        The run's stop time and communication step (s); None: the default experiment's.
    only, skip : tuple of str
        Run only these checks / not these (names of :data:`RULES` and ``fuzz``).
    ref, inputs : str or None
        The reference result and its inputs (CSV files) of the ``reference`` check.
    """

    profile: str | None = None
    stop_time: float | None = None
    step: float | None = None
    only: tuple[str, ...] = ()
    skip: tuple[str, ...] = ()
    #: a reference result (CSV, the cross-check layout: time first, one column per output) and
    #: the inputs of its run; None: ``<Model>_ref.csv`` / ``_in.csv`` / ``_ref.opt`` beside the FMU
    ref: str | None = None
    inputs: str | None = None

    def wants(self, name: str) -> bool:
        """Whether check ``name`` is selected."""
        return (not self.only or name in self.only) and name not in self.skip


@dataclass
class FMUReport:
    path: Path
    checks: list[CheckResult] = field(default_factory=list)
    output: str = ""  # what the FMU's binaries printed while being checked
    profile: str = ""
    skipped: str = ""  # why the FMU was not checked at all
    duration_s: float = 0.0

    @property
    def passed(self) -> bool:
        """No check failed, and something was checked (or the FMU was skipped with a reason)."""
        if self.skipped:
            return all(c.passed for c in self.checks)
        return bool(self.checks) and all(c.passed for c in self.checks)


class CheckSkipped(Exception):
    """A check does not apply to this FMU (the message says why)."""


class CheckFailed(AssertionError):
    """The FMU breaks the check's rule (the message says how)."""


def require(cond: bool, msg: str) -> None:
    """Fail the check with ``msg`` unless ``cond``."""
    if not cond:
        raise CheckFailed(msg)
