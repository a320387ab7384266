"""``dronefly check``: run the compliance checks (:mod:`.checker`) and the fuzz on FMUs, safely.

The checks of one FMU run in a child process (and the fuzz in its own), so an FMU that
crashes its host is reported, not fatal to ``dronefly check``; what the FMU's binaries print
(FMPy's container writes ``container::logError(...)`` lines) is kept in
``FMUReport.output``, shown with ``--verbose`` or when a check fails.
"""

from __future__ import annotations

import json
import subprocess
import sys
import tempfile
from pathlib import Path

from dronefly.harness.compliance.checker import CHECK_NAMES, CheckResult, FMUReport, run_checks

__all__ = ["check_fmu", "format_reports"]


def check_fmu(path: str | Path, *, fuzz: bool = True, isolate: bool = True) -> FMUReport:
    """Run every check on one FMU; never raises (nor crashes) for a non-compliant FMU.

    Parameters
    ----------
    path : str or Path
        The FMU file.
    fuzz : bool
        Add the short fuzz (``fuzz`` check).
    isolate : bool
        Run the checks in a child process (default): a crash is a failed check.
    """
    report = _check_isolated(Path(path)) if isolate else run_checks(Path(path))
    if fuzz and _fmi_version(Path(path)) == "3.0":
        report.checks.append(CheckResult("fuzz", True, "not run: the fuzz calls the FMI 2.0 API; "
                                         "FMI 3.0 has the state-machine check"))
    elif fuzz and report.checks and report.checks[0].name != "load":
        from dronefly.harness.compliance.fuzz import fuzz_fmu

        f = fuzz_fmu(path, random_calls=100, instances=5)
        report.checks.append(CheckResult("fuzz", f.passed, f.summary().replace("\n", ";")))
    return report


def _fmi_version(path: Path) -> str | None:
    import re
    import zipfile

    try:
        with zipfile.ZipFile(path) as z:
            head = z.read("modelDescription.xml")[:4096].decode("utf-8", "replace")
    except (OSError, KeyError, zipfile.BadZipFile):
        return None
    m = re.search(r'fmiVersion\s*=\s*"([^"]*)"', head)
    return m.group(1) if m else None


def _check_isolated(path: Path, timeout_s: float = 600.0) -> FMUReport:
    from dronefly.harness.compliance.fuzz import describe_exit

    with tempfile.TemporaryDirectory(prefix="dronefly_check_") as tmp:
        rows = Path(tmp, "checks.jsonl")
        try:
            proc = subprocess.run([sys.executable, "-m", "dronefly.harness.compliance.suite",
                                   str(path), str(rows)], capture_output=True, text=True,
                                  timeout=timeout_s)
            died = None if proc.returncode == 0 else describe_exit(proc.returncode)
            output = (proc.stdout + proc.stderr).strip()
        except subprocess.TimeoutExpired:
            died, output = f"hung for more than {timeout_s:g} s", ""
        report = FMUReport(path, output=output)
        current = None
        for line in rows.read_text(encoding="utf-8").splitlines() if rows.exists() else []:
            row = json.loads(line)
            if "begin" in row:
                current = row["begin"]
            else:
                report.checks.append(CheckResult(**row))
                current = None
    if died is not None:
        report.checks.append(CheckResult(current or "process exit", False,
                                         f"the checking process died ({died})"))
        report.checks += _not_run(path, report, current)
    return report


def _not_run(path: Path, report: FMUReport, crashed: str | None) -> list[CheckResult]:
    """One failed row listing the checks a crash left out (none if it left none out)."""
    from dronefly.harness.compliance.fmi3checks import FMI3_CHECKS

    names = [*CHECK_NAMES, *(n for n, _ in FMI3_CHECKS if _fmi_version(path) == "3.0")]
    done = {c.name for c in report.checks}
    rest = [n for n in names if n not in done]
    where = f"in {crashed}" if crashed else "between checks"
    return [CheckResult("not run", False, f"{', '.join(rest)} (the checking process died "
                                          f"{where})")] if rest else []


def _child(path: str, rows: str) -> None:
    with open(rows, "w", encoding="utf-8") as fh:
        def progress(row: dict) -> None:
            fh.write(json.dumps(row) + "\n")
            fh.flush()

        run_checks(Path(path), progress)


def format_reports(reports: list[FMUReport], verbose: bool = False) -> str:
    """The report for a terminal; what the binaries printed only if ``verbose`` or failed."""
    lines = []
    for r in reports:
        lines.append(f"{r.path}: {'PASS' if r.passed else 'FAIL'}")
        for c in r.checks:
            lines.append(f"  [{'ok' if c.passed else 'FAIL':>4}] {c.name:<14} {c.detail}")
        if r.output and (verbose or not r.passed):
            lines.append("  printed by the FMU's binaries while checked:")
            lines += [f"    {ln}" for ln in r.output.splitlines()]
    ok = sum(r.passed for r in reports)
    lines.append(f"{ok} of {len(reports)} FMUs passed")
    return "\n".join(lines)


if __name__ == "__main__":  # the child process of check_fmu
    _child(sys.argv[1], sys.argv[2])
