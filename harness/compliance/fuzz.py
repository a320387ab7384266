"""Fuzz an FMI 2.0 co-simulation FMU as a user of FMI tools would, crash-proof.

The groups of cases (:mod:`.fuzzcases`) run in a Python process of their own (one per
logging setting) through fmpy's low-level API, so that a crash, an abort (also at process exit)
or a hang of the FMU is counted, not fatal to the caller. After a crash the cases continue with
the next one in a new process. Works on any FMU, the project's and other people's (``dronefly check``).

Result per case: the FMI statuses seen, problems (a Fatal status, a refusal without a log
message or, for the project's own FMUs, without naming the variable or call, a state changed
by a refused call) and, if the process died, how.
"""

from __future__ import annotations

import json
import signal
import sys
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path

from .child import run_child

__all__ = ["FuzzCase", "FuzzReport", "GROUP_NAMES", "describe_exit", "fuzz_fmu"]

GROUP_NAMES = ("values", "sequence", "states", "format", "random", "churn")
_STATUS = ("OK", "Warning", "Discard", "Error", "Fatal")


@dataclass
class FuzzCase:
    group: str
    case: str
    statuses: list[int] = field(default_factory=list)
    problems: list[str] = field(default_factory=list)
    crash: str | None = None  # how the process died during this case

    @property
    def passed(self) -> bool:
        return self.crash is None and not self.problems


@dataclass
class FuzzReport:
    path: Path
    cases: list[FuzzCase]

    @property
    def crashes(self) -> list[FuzzCase]:
        return [c for c in self.cases if c.crash is not None]

    @property
    def fatal(self) -> int:
        return sum(4 in c.statuses for c in self.cases)

    @property
    def passed(self) -> bool:
        return all(c.passed for c in self.cases)

    def status_counts(self) -> dict[str, int]:
        """How many cases saw each FMI status."""
        n: Counter[str] = Counter(_STATUS[s] for c in self.cases for s in c.statuses)
        return dict(sorted(n.items(), key=lambda kv: _STATUS.index(kv[0])))

    def summary(self) -> str:
        failed = [c for c in self.cases if not c.passed]
        text = (f"{len(self.cases)} cases, {len(self.crashes)} crashes, {self.fatal} with "
                f"fmi2Fatal; statuses seen: {self.status_counts()}")
        for c in failed[:5]:
            text += f"\n  {c.group}: {c.case}: {c.crash or '; '.join(c.problems)}"
        if len(failed) > 5:
            text += f"\n  ... and {len(failed) - 5} more"
        return text


def describe_exit(returncode: int) -> str:
    """How a process ended: ``killed by SIGSEGV`` or ``exit code 3``."""
    if returncode < 0:
        try:
            return f"killed by {signal.Signals(-returncode).name}"
        except ValueError:
            return f"killed by signal {-returncode}"
    return f"exit code {returncode}"


def fuzz_fmu(path: str | Path, *, groups: tuple[str, ...] = GROUP_NAMES, seed: int = 0,
             random_calls: int = 300, instances: int = 50, logging: tuple[bool, ...] = (True, False),
             timeout_s: float = 120.0) -> FuzzReport:
    """Run the fuzz groups on one FMU; never raises for what the FMU does.

    Parameters
    ----------
    path : str or Path
        The FMU file.
    groups : tuple of str
        Which of :data:`GROUP_NAMES` to run.
    seed : int
        Seed of the random call sequences.
    random_calls, instances : int
        Length of the random call sequence; instances in the churn group.
    logging : tuple of bool
        Run every group with the FMU's logging on, off, or both (the default).
    timeout_s : float
        Wall-clock limit of one process [s]; a process past it counts as a hang.
    """
    path = Path(path).resolve()
    cases: list[FuzzCase] = []
    for log in logging:
        start = 0
        while True:
            done, died = _run(path, groups, seed, random_calls, instances, start, log, timeout_s)
            cases.extend(done)
            if died is None:
                break
            cases.append(died)
            if died.case.startswith(("process exit", "loading the FMU")):
                break
            start += len(done) + 1  # go on after the case that killed the process
    return FuzzReport(path, cases)


def _run(path: Path, groups: tuple[str, ...], seed: int, random_calls: int, instances: int,
         start: int, logging: bool, timeout_s: float) -> tuple[list[FuzzCase], FuzzCase | None]:
    cmd = [sys.executable, "-m", "dronefly.harness.compliance.fuzzcases", str(path),
           ",".join(groups), str(seed), str(random_calls), str(instances), str(start),
           "1" if logging else "0"]
    label = "" if logging else " (logging off)"
    proc = run_child(cmd, timeout_s)  # its temporary files removed at any end; Ctrl-C raises
    out = proc.stdout
    died = (f"hung for more than {timeout_s:g} s" if proc.returncode is None
            else None if proc.returncode == 0 else describe_exit(proc.returncode))
    done: list[FuzzCase] = []
    current: tuple[str, str] | None = None
    for line in out.splitlines():
        try:
            row = json.loads(line)
        except ValueError:
            continue
        if "begin" in row:
            current = (row["group"], row["begin"])
        else:
            done.append(FuzzCase(row["group"], row["case"] + label, row["statuses"],
                                 row["problems"]))
            current = None
    if died is None:
        return done, None
    if current is None and not done and start == 0 and died:
        current = (groups[0] if groups else "", "loading the FMU")
    # died inside `current`, or after the last case (at process exit)
    group, case = current or (done[-1].group if done else "", "process exit")
    return done, FuzzCase(group, case + label, crash=died)
