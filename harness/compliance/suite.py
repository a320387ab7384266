"""``dronefly check``: run the compliance checks (:mod:`.checker`) and the fuzz on FMUs, safely.

The checks of one FMU run in a child process (and the fuzz in its own), so an FMU that
crashes its host or hangs is reported, not fatal to ``dronefly check``: the report names
the check, the FMI call it was in (with its arguments and time) and what the FMU logged
before. What the FMU's binaries print (FMPy's container writes ``container::logError(...)``
lines) is kept in ``FMUReport.output``, shown with ``--verbose`` or when a check fails.

Reports go to a terminal (:func:`format_reports`), to JSON (:func:`reports_json`, with
:data:`JSON_SCHEMA`) and to JUnit XML (:func:`reports_junit`).
"""

from __future__ import annotations

import json
import os
import re
import sys
import tempfile
import time
import traceback
import xml.etree.ElementTree as ET
import zipfile
from concurrent.futures import ThreadPoolExecutor, as_completed
from dataclasses import asdict
from pathlib import Path

from .checker import CHECKS, CheckOptions, CheckResult, FMUReport, listed, rule_of, run_checks
from ...core.interrupt import pending
from .child import die_with_parent, run_function
from .fuzz import describe_exit, fuzz_fmu

__all__ = ["JSON_SCHEMA", "JSON_SCHEMA_FILE", "CheckInterrupted", "check_fmu", "check_fmus",
           "format_reports", "interfaces_of", "not_checked",
           "reports_json", "reports_junit"]

#: the version of the ``--json`` document (``{"schema": JSON_SCHEMA, "fmus": [...]}``)
JSON_SCHEMA = "dronefly-check/2"
#: the JSON Schema (draft 2020-12) of that document, shipped with the package
JSON_SCHEMA_FILE = Path(__file__).with_name("check-schema.json")


def check_fmu(path: str | Path, *, fuzz: bool = True, isolate: bool = True,
              options: CheckOptions | None = None, timeout_s: float = 600.0) -> FMUReport:
    """Run every selected check on one FMU; never raises (nor crashes) for a bad FMU.

    Parameters
    ----------
    path : str or Path
        The FMU file.
    fuzz : bool
        Add the short fuzz (``fuzz`` check; the dronefly profile's, FMI 2.0 FMUs).
    isolate : bool
        Run the checks in a child process (default): a crash or a hang is a failed check.
    options : CheckOptions, optional
        Profile, stop time, step, selected checks.
    timeout_s : float
        How long the checks of one FMU may take in the child process (default 600 s, as
        ``dronefly check --timeout``).
    """
    path = Path(path)
    options = options or CheckOptions()
    if pending():
        raise KeyboardInterrupt
    t0 = time.perf_counter()
    reason = not_checked(path)
    if reason is not None:
        return FMUReport(path, skipped=reason)
    report = (_check_isolated(path, options, timeout_s) if isolate
              else run_checks(path, options=options))
    if fuzz and "fuzz" in options.only and options.wants("fuzz") and report.profile \
            and report.profile != "dronefly":
        report.checks.append(CheckResult(
            "fuzz", True, "not applicable: fuzz is the dronefly profile's check (--profile "
            f"dronefly runs it); this FMU is checked under the {report.profile} profile",
            rule="dronefly profile: the fuzz", skipped=True))
    if fuzz and options.wants("fuzz") and report.profile == "dronefly":
        if _fmi_version(path) == "3.0":
            report.checks.append(CheckResult(
                "fuzz", True, "not applicable: the fuzz calls the FMI 2.0 API; FMI 3.0 has "
                "the state-machine check", rule="dronefly profile: the fuzz", skipped=True))
        elif report.checks and report.checks[0].name != "load":
            t1 = time.perf_counter()
            f = fuzz_fmu(path, random_calls=100, instances=5)
            report.checks.append(CheckResult("fuzz", f.passed, f.summary().replace("\n", ";"),
                                             rule="dronefly profile: the fuzz (no crash, no "
                                                  "Fatal, every refusal logged and harmless)",
                                             duration_s=round(time.perf_counter() - t1, 6)))
    report.duration_s = round(time.perf_counter() - t0, 6)
    return report


class CheckInterrupted(KeyboardInterrupt):
    """Ctrl-C stopped :func:`check_fmus`; ``reports`` holds the FMUs whose checks finished
    (in the order of the paths), none of the FMU it was checking."""

    def __init__(self, reports: list[FMUReport]) -> None:
        super().__init__()
        self.reports = reports


def check_fmus(paths: list[Path], *, jobs: int = 1, **kwargs) -> list[FMUReport]:
    """:func:`check_fmu` on each FMU, ``jobs`` at a time (each in its child process); the
    reports in the order of ``paths``.

    Raises
    ------
    CheckInterrupted
        Ctrl-C (a deferred SIGINT, :mod:`dronefly.core.interrupt`): the FMUs being checked are
        stopped within one poll of their child process, the finished ones are returned in it.
    """
    done: dict[int, FMUReport] = {}
    if jobs <= 1 or len(paths) <= 1:
        try:
            for k, p in enumerate(paths):
                done[k] = check_fmu(p, **kwargs)
        except KeyboardInterrupt:
            raise CheckInterrupted([done[k] for k in sorted(done)]) from None
        return [done[k] for k in range(len(paths))]
    pool = ThreadPoolExecutor(max_workers=jobs)
    try:
        futures = {pool.submit(check_fmu, p, **kwargs): k for k, p in enumerate(paths)}
        for f in as_completed(futures):
            done[futures[f]] = f.result()
    except KeyboardInterrupt:
        pool.shutdown(wait=True, cancel_futures=True)  # the running ones stop at their poll
        raise CheckInterrupted([done[k] for k in sorted(done)]) from None
    finally:
        pool.shutdown(wait=True, cancel_futures=True)
    return [done[k] for k in range(len(paths))]


def _model_description_head(path: Path) -> str | None:
    try:
        with zipfile.ZipFile(path) as z:
            return z.read("modelDescription.xml")[:65536].decode("utf-8", "replace")
    except (OSError, KeyError, zipfile.BadZipFile):
        return None


def _fmi_version(path: Path) -> str | None:
    head = _model_description_head(path)
    m = re.search(r'fmiVersion\s*=\s*"([^"]*)"', head) if head else None
    return m.group(1) if m else None


def interfaces_of(path: Path) -> tuple[str, ...]:
    """The interfaces ("cs", "me") the FMU's modelDescription.xml declares (both if unread)."""
    head = _model_description_head(path)
    if head is None:
        return ("cs", "me")
    return tuple(i for i, tag in (("cs", "<CoSimulation"), ("me", "<ModelExchange"))
                 if tag in head)


def not_checked(path: Path) -> str | None:
    """Why an FMU is out of scope (Scheduled Execution only: neither Co-Simulation nor Model
    Exchange), or None.

    A file that is no readable FMU is not out of scope: its ``load`` check fails.
    """
    head = _model_description_head(path)
    if head is None or "<fmiModelDescription" not in head or "<CoSimulation" in head \
            or "<ModelExchange" in head or "<ScheduledExecution" not in head:
        return None
    return ("not checked: Scheduled Execution only, no Co-Simulation or Model Exchange "
            "interface (dronefly check tests those two)")


def _check_isolated(path: Path, options: CheckOptions, timeout_s: float) -> FMUReport:
    with tempfile.TemporaryDirectory(prefix="dronefly_check_") as tmp:
        rows = Path(tmp, "checks.jsonl")
        opts = json.dumps(asdict(options))
        # the child's own temporary files (the extracted FMU) go to tmp: removed at any end
        proc = run_function("dronefly.harness.compliance.suite", "checking_process",
                            [str(path), str(rows), opts], timeout_s, tmp=tmp)
        if proc.returncode is None:
            died = f"hung for more than {timeout_s:g} s"
        else:
            died = None if proc.returncode == 0 else describe_exit(proc.returncode)
        output = (proc.stdout + proc.stderr).strip()
        report = FMUReport(path)
        current, call, logged, internal = None, None, [], None
        text = rows.read_text(encoding="utf-8", errors="replace") if rows.exists() else ""
        for line in text.splitlines():
            try:
                row = json.loads(line)
            except json.JSONDecodeError:  # the last line, cut by the crash
                continue
            if "begin" in row:
                current, call, logged = row["begin"], None, []
            elif "call" in row:
                call = row["call"]
            elif "log" in row:
                logged.append(row["log"])
            elif "profile" in row:
                report.profile = row["profile"]
            elif "internal" in row:
                internal = row["internal"]
            else:
                report.checks.append(CheckResult(**row))
                current = None
    if internal is not None:  # dronefly check's own error, not the FMU's
        report.checks.append(CheckResult(current or "internal", False,
                                         f"internal error of dronefly check: {internal}"))
        died = None
    if died is not None:
        where = f" in {call}" if call else ""
        before = f"; the FMU logged before: {' | '.join(logged[-3:])}" if logged else ""
        fmi = 3 if _fmi_version(path) == "3.0" else 2
        report.checks.append(CheckResult(current or "process exit", False,
                                         f"the checking process died ({died}){where}{before}",
                                         rule=rule_of(current or "", fmi, report.profile)))
        report.checks += _not_run(path, report, current, options)
    report.output = output
    return report


def _not_run(path: Path, report: FMUReport, crashed: str | None,
             options: CheckOptions) -> list[CheckResult]:
    """One failed row listing the checks a crash left out (none if it left none out)."""

    profile = report.profile or "standard"
    fmi = 3 if _fmi_version(path) == "3.0" else 2
    names = [c.name for c in CHECKS if listed(c, fmi, profile, interfaces_of(path))]
    done = {c.name for c in report.checks}
    rest = [n for n in names if n not in done and options.wants(n)]
    where = f"in {crashed}" if crashed else "between checks"
    return [CheckResult("not run", False, f"{', '.join(rest)} (the checking process died "
                                          f"{where})")] if rest else []


def checking_process(path: str, rows: str, opts: str) -> None:
    """The body of the checking process of :func:`check_fmu`: the checks of the FMU at
    ``path`` with the options ``opts`` (JSON), one JSON row per event written to ``rows``."""
    fd = os.open(rows, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
    try:
        def progress(row: dict) -> None:  # one unbuffered write per row: a crash loses none
            os.write(fd, (json.dumps(row) + "\n").encode("utf-8"))

        try:
            run_checks(Path(path), progress, CheckOptions(**{
                k: tuple(v) if isinstance(v, list) else v for k, v in json.loads(opts).items()}))
        except Exception as e:  # dronefly check's own bug: said as such, never as the FMU's
            progress({"internal": f"{type(e).__name__}: {e} | "
                                  + traceback.format_exc().strip().splitlines()[-2].strip()})
    finally:
        os.close(fd)


def _ref(rule: str) -> str:
    """The short reference of a rule line: ``FMI 2.0 4.2.4`` or ``dronefly profile``."""
    m = re.match(r"(FMI [23]\.0 [\d.]+|FMI [23]\.0|dronefly profile|FMI cross-check)", rule)
    return m.group(1) if m else ""


def format_reports(reports: list[FMUReport], verbose: bool = False) -> str:
    """The report for a terminal; what the binaries printed only if ``verbose`` or failed."""
    lines = []
    for r in reports:
        if r.skipped:
            lines.append(f"{r.path}: SKIP ({r.skipped})")
            continue
        profile = f" (profile {r.profile})" if r.profile else ""
        lines.append(f"{r.path}: {'PASS' if r.passed else 'FAIL'}{profile}")
        for c in r.checks:
            tag = "skip" if c.skipped else "warn" if c.warning else "ok" if c.passed else "FAIL"
            ref = f" [{_ref(c.rule)}]" if _ref(c.rule) else ""
            lines.append(f"  [{tag:>4}] {c.name:<14} {c.detail}{ref}")
            if c.warning:
                lines.append(f"         warning: {c.warning}")
            if c.rule and (verbose or not c.passed):
                lines.append(f"         rule: {c.rule}")
        if r.output and (verbose or not r.passed):
            lines.append("  printed by the FMU's binaries while checked:")
            lines += [f"    {ln}" for ln in r.output.splitlines()]
    ok = sum(r.passed and not r.skipped for r in reports)
    skipped = sum(bool(r.skipped) for r in reports)
    checked = len(reports) - skipped
    lines.append(f"{ok} of {checked} FMUs passed" + (f", {skipped} not checked" if skipped else ""))
    return "\n".join(lines)


def reports_json(reports: list[FMUReport]) -> dict:
    """The ``--json`` document: schema version, one entry per FMU with each check's status
    (``passed``, ``failed``, ``skipped``), rule, detail, warning and duration in seconds."""
    return {"schema": JSON_SCHEMA, "fmus": [{
        "fmu": str(r.path), "status": "skipped" if r.skipped else
        "passed" if r.passed else "failed", "passed": r.passed, "skipped": r.skipped or None,
        "profile": r.profile or None, "duration_s": r.duration_s, "output": r.output,
        "checks": [{"name": c.name, "status": c.status, "passed": c.passed,
                    "skipped": c.skipped, "rule": c.rule, "detail": c.detail,
                    "warning": c.warning or None, "duration_s": c.duration_s}
                   for c in r.checks]} for r in reports]}


def reports_junit(reports: list[FMUReport]) -> str:
    """JUnit XML: a test suite per FMU, a test case per check (skipped as ``<skipped>``,
    failed as ``<failure>`` with the message), each with its duration."""

    root = ET.Element("testsuites", name="dronefly check")
    for r in reports:
        cases = r.checks or [CheckResult("fmu", True, r.skipped, skipped=True)]
        suite = ET.SubElement(root, "testsuite", name=str(r.path), tests=str(len(cases)),
                              failures=str(sum(not c.passed for c in cases)),
                              skipped=str(sum(c.skipped for c in cases)),
                              time=f"{r.duration_s:.6f}")
        for c in cases:
            case = ET.SubElement(suite, "testcase", name=c.name, classname=Path(r.path).stem,
                                 time=f"{c.duration_s:.6f}")
            if c.skipped:
                ET.SubElement(case, "skipped", message=c.detail)
            elif not c.passed:
                failure = ET.SubElement(case, "failure", message=c.detail[:1000])
                failure.text = "\n".join(x for x in (c.detail, c.rule, r.output) if x)
            if c.warning:
                ET.SubElement(case, "system-out").text = f"warning: {c.warning}"
    return ET.tostring(root, encoding="unicode")


if __name__ == "__main__":  # the child process of check_fmu
    die_with_parent()
    checking_process(sys.argv[1], sys.argv[2], sys.argv[3] if len(sys.argv) > 3 else "{}")
