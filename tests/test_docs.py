"""The documents run verbatim and their numbers are the code's.

Every fenced ``sh``/``bash``/``console`` block of README.md and docs/*.md runs as written with
bash, and every ``python`` block in a fresh interpreter, each in a scratch folder (cwd: a tmp dir;
``DRONEFLY_REPO`` = the checkout, for the one block that compiles a source file of it). A block
runs in the core install (``pip install dronefly-fmu`` without extras: tests/core_install.py, its
bin first on PATH), so every documented example is shown to need no optional package; a block
marked ``<!-- doc-test: needs ... -->`` (an extra, gcc, Ecos, ../shared) runs in this
environment, with everything installed (``needs ../shared``: beside a link to the checkout's
../shared, which CI provides). Each must exit 0, print what the document says it prints where
it says so ("prints" and a block, or "prints `...`", right after it), and leave the checkout as
it was. A block is left out only with a reason: a ``<!-- doc-test: skip (why) -->`` line right
before it, counted below, so a new block runs by default. The numbers the README and docs quote are compared with
what the code computes.
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
from docnumbers import NumericText, same_numbers
from shared_files import need_shared, provided_on_ci
from test_interop_ecos import require_ecos

ROOT = Path(__file__).resolve().parents[1]
DOCS = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
_FENCE = re.compile(r"(?:^<!-- doc-test: (?P<mark>[^\n]*?) -->\n)?^```(?P<lang>sh|bash|console|python)\n"
                    r"(?P<body>.*?)^```$", re.M | re.S)


#: what a document says a block prints, right after the block: "prints" and a fenced block
#: (possibly under a generated-block marker), or "prints `...`" inline
_PRINTS = re.compile(r"\n*prints\n\n(?:<!-- [^\n]* -->\n)?```(?:text)?\n(?P<block>.*?)\n```"
                     r"|\n*prints `(?P<inline>[^`]*)`", re.S)


def _blocks() -> list:
    out = []
    for doc in DOCS:
        text = doc.read_text(encoding="utf-8")
        for k, m in enumerate(_FENCE.finditer(text)):
            line = text[:m.start("body")].count("\n")
            shown = _PRINTS.match(text, m.end())
            printed = None if shown is None else (shown.group("block") or shown.group("inline"))
            out.append(pytest.param(doc, m.group("lang"), m.group("body"), m.group("mark") or "",
                                    printed, id=f"{doc.name}:{line}"))
    return out


def _status() -> str:
    return subprocess.run(["git", "status", "--porcelain", "--untracked-files=all"], cwd=ROOT,
                          capture_output=True, text=True).stdout


def _env(bin_dir: Path, tmp: Path) -> dict[str, str]:
    env = dict(os.environ)
    env["TMPDIR"] = str(tmp)  # a block's `mktemp -d` folders: in the test's own, removed with it
    env["PATH"] = f"{bin_dir}{os.pathsep}{env.get('PATH', '')}"
    env.pop("PYTHONPATH", None)
    env["DRONEFLY_REPO"] = str(ROOT)
    return env


# The blocks marked skip, by document: a new skip must be added here on purpose.
SKIPPED = {"README.md": 1, "latency.md": 1, "mutation.md": 1, "sweep.md": 1, "usage.md": 1}


def test_every_block_is_run_or_skipped_with_a_reason():
    blocks = _blocks()
    skipped: dict[str, int] = {}
    for p in blocks:
        doc, _, _, mark, _ = p.values
        if mark and not mark.startswith(("skip (", "needs ")):
            raise AssertionError(f"{p.id}: unknown doc-test mark {mark!r}")
        if mark.startswith("skip ("):
            assert mark.endswith(")") and len(mark) > len("skip ()") + 3, f"{p.id}: no reason"
            skipped[doc.name] = skipped.get(doc.name, 0) + 1
    assert skipped == SKIPPED
    assert len(blocks) - sum(SKIPPED.values()) >= 7


@pytest.mark.integration
@pytest.mark.parametrize("doc, lang, body, mark, printed",
                         [p for p in _blocks() if not p.values[3].startswith("skip (")])
def test_block_runs_verbatim(doc, lang, body, mark, printed, tmp_path, request):
    """Every block not marked skip (those never run here, each with its reason, counted by
    test_every_block_is_run_or_skipped_with_a_reason: they are not cases)."""
    cwd = tmp_path
    if mark.startswith("needs ../shared"):  # a block that names files beside the checkout:
        need_shared(ROOT.parent / "shared", "../shared")  # run beside a link to them
        (tmp_path / "shared").symlink_to(ROOT.parent / "shared", target_is_directory=True)
        cwd = tmp_path / "work"
        cwd.mkdir()
    # the core install unless the block says what more it needs
    bin_dir = (Path(sys.executable).parent if mark.startswith("needs ")
               else request.getfixturevalue("core_env"))
    if mark.startswith("needs gcc"):
        from dronefly.harness.interop.libcosim import libpython_path

        if shutil.which("gcc") is None or libpython_path() is None:
            provided_on_ci("no gcc or no shared libpython (.ci/setup-c-host.sh installs them)")
    if mark.startswith("needs ecospy"):
        from dronefly.harness.interop.ecos import ecos_available

        require_ecos(ecos_available())  # fails where the test extra installs it (Linux x86_64)
    before = _status()
    tmp = tmp_path / "tmp"
    tmp.mkdir()
    if lang == "python":
        script = tmp_path / "block.py"
        script.write_text(body)
        r = subprocess.run([str(bin_dir / "python"), str(script)], cwd=cwd,
                           env=_env(bin_dir, tmp), capture_output=True, text=True, timeout=300)
    else:
        r = subprocess.run(["bash", "-c", body], cwd=cwd, env=_env(bin_dir, tmp),
                           capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, f"{doc.name}: exit {r.returncode}\n{r.stdout[-1500:]}\n{r.stderr[-1500:]}"
    assert _status() == before, f"{doc.name}: the block changed the checkout"
    if printed is not None:  # what the document says it prints: words exactly, numbers to a
        # unit of their last printed digit (tests/docnumbers.py)
        diff = same_numbers(" ".join(printed.split()), " ".join(r.stdout.split()))
        assert diff is None, f"{doc.name}: the block prints other than the document says: {diff}"


def test_readme_is_short_and_its_layout_names_every_folder():
    """The README stays at most 12 kB, and its layout table names every folder of
    the package's floors (the top-level ones, those of harness/ and fmu_src/) and the two
    helper folders tests/c_host and benchmarks/null_fmus."""
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    assert len(readme.encode("utf-8")) <= 12_000
    rows = {m.group(1) for m in re.finditer(r"^\| `([^`]+)/` \|", readme, re.M)}
    files = subprocess.run(["git", "ls-files"], cwd=ROOT, capture_output=True, text=True,
                           check=True).stdout.split()
    nested = [f for f in files if "/" in f]
    folders = {str(Path(f).parent) for f in nested} | {f.split("/")[0] for f in nested}
    want = {d for d in folders if "/" not in d or d.split("/")[0] in ("harness", "fmu_src")
            and d.count("/") == 1}
    want |= {"tests/c_host", "benchmarks/null_fmus", "build"}  # build/: generated, not in git
    assert want <= rows, sorted(want - rows)


# --- numbers ---------------------------------------------------------------------------------
@pytest.mark.numeric
def test_readme_verdict_table_is_what_demo_prints(tmp_path):
    from dronefly.harness.stability.demo import verdict_table

    table = verdict_table(out_dir=tmp_path / "cosim")
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    for gains in ("open", "paper"):
        got = next(ln for ln in table.splitlines() if ln.startswith(gains + " "))
        want = next(ln for ln in readme.splitlines() if ln.startswith(gains + " "))
        diff = same_numbers("  ".join(got.split("  ")[:3]), "  ".join(want.split("  ")[:3]))
        assert diff is None, (diff, got, want)


@pytest.mark.numeric
def test_readme_numbers_of_the_demo_and_the_reproduction(tmp_path):
    from dronefly.harness.stability.run import cosimulate
    from dronefly.harness.paper.reproduction import reproduction_table
    from dronefly.harness.paper.rows import summary

    readme = NumericText((ROOT / "README.md").read_text(encoding="utf-8"))
    from dronefly.harness.cosim.identification import TOL_PER_WINGBEAT

    r = cosimulate(out_dir=None, plot=False, build_dir=tmp_path)
    assert f"leave {r.identification.dominant_growth_rate:.1e} per wing beat" in readme
    assert f"neutral tolerance of {TOL_PER_WINGBEAT:.0e}" in readme
    open_rate = cosimulate(gains="open", out_dir=None, plot=False,
                           build_dir=tmp_path).identification.dominant_growth_rate
    share = 100 * TOL_PER_WINGBEAT / open_rate  # 1.27 %: "under 1.3 %"
    assert 1.2 < share < 1.3 and "under 1.3 % of the open-loop divergence rate" in readme
    s = summary(reproduction_table())
    by = s["mismatches_by_reason"]
    assert (f"all {s['rows']} numbers" in readme and f"{s['matches']} match" in readme
            and f"{by['rounding']} differ" in readme and f"{by['error in print']} are errors" in readme)


@pytest.mark.numeric
def test_simulate_deviation_quoted_in_readme(tmp_path):
    from dronefly.harness.stability.simulate import simulate_plant

    run = simulate_plant(out_dir=tmp_path)
    assert run.max_rel_error < 1e-13  # README: "about 1e-14"
    assert "(about 1e-14)" in (ROOT / "README.md").read_text(encoding="utf-8")


@pytest.mark.numeric
def test_sweep_case_counts_quoted_in_docs():
    from dronefly.harness.sweep.cases import SweepSpec

    cases = SweepSpec().cases()
    text = (ROOT / "docs" / "sweep.md").read_text(encoding="utf-8")
    assert f"{len(cases):,} cases ({len({c.key for c in cases}):,} distinct" in text
