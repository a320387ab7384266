"""docs/averaging.md quotes what the code computes: the periodic orbit, the Floquet exponents beside
the averaged model's eigenvalues (with and without the wings' inertia), the averaging experiment
and the answer (numbers compared as numbers, tests/docnumbers.py)."""

from __future__ import annotations

from pathlib import Path

import pytest

from docnumbers import NumericText, assert_same_numbers, doc_block

from dronefly.harness.flapping import (readme_paragraph, convergence, convergence_rows, flapping_trim,
                                       floquet_report, master_report)
from dronefly.models.flapping import FlappingModel

#: the documented orbit and Floquet numbers: run again under a second BLAS kernel (.ci/run)
pytestmark = pytest.mark.numeric

ROOT = Path(__file__).resolve().parents[1]
DOC = ROOT / "docs" / "averaging.md"


def _block(text: str, name: str) -> str:
    return doc_block(text, f"flapping:{name}", DOC.name)


def _same(expected: str, actual: str, hint: str) -> None:
    # columns realign when a sign appears: whitespace runs compare as one space
    assert_same_numbers(" ".join(expected.split()), " ".join(actual.split()), hint)


def _same_kind(a: complex, b: complex) -> bool:
    """The same type of mode (real or oscillatory) and the same stability."""
    return (abs(a.imag) > 1e-9) == (abs(b.imag) > 1e-9) and (a.real > 0) == (b.real > 0)


def test_flapping_doc_is_what_the_code_computes():
    text = DOC.read_text(encoding="utf-8")
    report = floquet_report()
    bare = floquet_report(FlappingModel(report.orbit.model.qs, wing_inertia=False))
    rows = convergence_rows()
    _same(_block(text, "report"), report.text(), "flapping:report")
    _same(_block(text, "no-inertia"), bare.text(), "flapping:no-inertia")
    _same(_block(text, "convergence"), convergence(rows), "flapping:convergence")
    ans = readme_paragraph(report, bare, rows)
    _same(_block(text, "answer"), ans, "flapping:answer")
    assert ans in NumericText((ROOT / "README.md").read_text(encoding="utf-8")), \
        "README does not quote the answer"
    # what the answer says in words: every mode keeps its type and stability, and the error
    # falls as 1/frequency
    for axis, pairs in report.pairs().items():
        for f, a in pairs:
            assert _same_kind(f, a), (axis, f, a)
    lat = [r0[1] / r1[1] for r0, r1 in zip(rows[:-1], rows[1:])]
    lon = [r0[2] / r1[2] for r0, r1 in zip(rows[:-1], rows[1:])]
    # the ratios the text quotes, and what it says of them: the lateral error halves (within
    # 5 %: first-order averaging, its error c/s + O(1/s^2); measured 2.7 % off at worst), the
    # longitudinal ratio grows towards 2 from below
    prose = NumericText(text)
    for kind, ratios in (("lateral", lat), ("longitudinal", lon)):
        quoted = "(ratios " + ", ".join(f"{r:.2f}" for r in ratios) + ")"
        assert quoted in prose, (kind, quoted)
    assert all(abs(r / 2 - 1) < 0.05 for r in lat), lat
    assert all(a < b < 2 for a, b in zip(lon[:-1], lon[1:])), lon


def test_flapping_doc_closed_loop_is_what_the_code_computes():
    from dronefly.harness.flapping.closed_loop import closed_loop_report

    text = DOC.read_text(encoding="utf-8")
    report = closed_loop_report()
    _same(_block(text, "closed-loop"), report.text(), "flapping:closed-loop")
    # what the text says: Eq. (27) leaves both unstable, the quasi-steady design is neutral on
    # the averaged model (its root on the axis to round-off) and unstable on the flapping one
    eq27, qs = "Eq. (27)", "quasi-steady design"
    assert report.flapping[eq27][0].real > 0 and report.averaged_sampled[eq27][0].real > 0
    # (the design's derivatives are central differences of step 1e-3, the twin's forces the
    # cycle average itself: the root lands 7e-6 off the axis)
    assert abs(report.averaged_sampled[qs][0].real) < 1e-4 < report.flapping[qs][0].real
    assert report.runs[eq27].gamma[-1] > 0.1


@pytest.mark.integration
def test_flapping_doc_master_run_is_what_the_code_computes(built_fmus):
    text = DOC.read_text(encoding="utf-8")
    report = master_report(built_fmus)
    _same(_block(text, "master-run"), report.text(), "flapping:master-run")
    # the shell example's output: the CSV that dronefly cosim writes ends at the report's
    # gamma after 30 wing beats (Eq. 27, the SSP's default gains)
    gamma = report.loops["Eq. (27)"].gamma[-1]
    line = next(x for x in _block(text, "master-cli").splitlines() if x.startswith("gamma"))
    _same(line, f"gamma after 30 wing beats: {gamma:+.4f} rad", "flapping:master-cli")


def test_flapping_doc_own_trim_is_what_the_code_computes():
    text = DOC.read_text(encoding="utf-8")
    trim = flapping_trim()
    _same(_block(text, "trim"), trim.text(), "flapping:trim")
    # the trim holds the insect still: the orbit's mean drift, as the oscillation measures it
    osc = trim.orbit.oscillation()
    assert abs(osc["x_drift_mm_per_s"]) < 1e-8 and abs(osc["z_drift_mm_per_s"]) < 1e-8
    # what the text says: the lateral instability nearer the averaged model's +0.1079
    qs_trim, own = trim.lateral_exponents_qs_trim[0].real, trim.lateral_exponents[0].real
    assert 0.1079 < own < qs_trim
