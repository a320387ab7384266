"""Tests of the analysis of Zhang & Sun: the table's coverage, the API, the CLI, the designs.

Every printed value comes from ``dronefly.harness.paper.printed`` (one place). The rows themselves
(match, reason, errata, rounding) are checked in ``test_reproduction_rows.py``.
"""

from __future__ import annotations

import itertools
import json
from pathlib import Path

import numpy as np
import pytest
from numpy.testing import assert_allclose
from docnumbers import same_numbers

from dronefly.cli.app import main
from dronefly.harness.paper import analysis as an
from dronefly.harness.paper import printed as pv
from dronefly.harness.paper.design import lqr_gains, move_lambda1_gains, stabilising_designs
from dronefly.harness.paper.report import render
from dronefly.harness.paper.reproduction import analyze, reproduction_table
from dronefly.harness.paper.rows import (NOISE, format_bound, format_number, format_vector,
                                         rounds_to)
from dronefly.models import lateral_dynamics
from dronefly.models import lateral_interface

pytestmark = pytest.mark.numeric  # also run under a second BLAS kernel (.ci/run)

ROWS = {(r.source, r.quantity): r for r in reproduction_table()}


def test_every_printed_number_has_a_row() -> None:
    count = {"Eq. (12)": 16, "Eq. (24)": 20, "Table 2": 4, "Table 3": 24, "Eq. (19)": 16, "Eq. (20)": 12,
             "Eq. (26a)": 5, "Eq. (26b)": 5, "Eq. (26c)": 5, "Eq. (26d)": 5, "Eq. (27)": 8,
             "Sect. 3.5": 32, "Eq. (31)": 20, "Eq. (32)": 16}
    got: dict[str, int] = {}
    for s, _ in ROWS:
        got[s] = got.get(s, 0) + 1
    assert got == count


def test_half_unit_of_printed_digits() -> None:
    # Half a unit in the last printed digit: 4 decimals, scientific, one digit, degrees, and a
    # bare 0 or 1 in a matrix printed to 4 decimals (a structural entry printed without them)
    texts = [pv.EQ19_A_LNN[0][0], pv.EQ26["c"][1], pv.EQ26["b"][1], pv.TABLE3_PHASE_DEG[0][1], "0",
             "1"]
    got = [pv.half_unit(t, 4 if t in ("0", "1") else None) for t in texts]
    assert_allclose(got, [5e-5, 5e-7, 5e-5, 0.05, 5e-5, 5e-5], rtol=1e-12)


#: The paper's matrices, printed to four decimals (every entry that has a decimal point has
#: four; the structural 0 and 1 are printed bare): rows of these sources but the eigenvalues
MATRIX_SOURCES = ("Eq. (12)", "Eq. (19)", "Eq. (20)", "Eq. (24)", "Eq. (31)", "Eq. (32)",
                  "Sect. 3.5")


def _digits_half_unit(text: str, bare_decimals: int) -> float:
    """Half a unit of the last digit of ``text``, counted from its characters: the digits after
    the point, shifted by an exponent; ``bare_decimals`` for a number printed without a point."""
    mantissa, _, exponent = text.lower().partition("e")
    decimals = len(mantissa.partition(".")[2]) if "." in mantissa else bare_decimals
    return 0.5 * 10.0 ** (int(exponent or 0) - decimals)


def test_every_rows_tolerance_is_half_a_unit_of_its_printed_digits() -> None:
    """A row matches within half a unit of the last digit the paper prints; in a matrix printed
    to four decimals, its bare structural 0 and 1 are read to four decimals too (a 1 read as
    +-0.5 would let a wrong structural entry of the model pass)."""
    for (src, qty), r in ROWS.items():
        in_matrix = src in MATRIX_SOURCES and not qty.startswith("eigenvalue")
        if in_matrix and "." in r.printed:
            assert len(r.printed.partition(".")[2]) == 4, (src, qty, r.printed)
        want = _digits_half_unit(r.printed, 4 if in_matrix else 0)
        assert r.tolerance == pytest.approx(want, rel=1e-12), (src, qty, r.printed)


def test_an_input_entrys_own_row_moves_by_its_rounding() -> None:
    """Eq. (12)'s A1 and Sect. 3.5's A and B are inputs of the analysis, and the model gives
    them back unchanged (derivatives recovered, matrices rebuilt: a round trip), so the
    input-rounding interval of each such entry's own row is its value +- its half unit (to the
    round trip's round-off, 1e-12 relative); a structural entry is no input and moves by 0."""
    structural = {"Eq. (12)": pv.EQ12_STRUCTURAL, "A": pv.LONGITUDINAL_STRUCTURAL["A"],
                  "B": pv.LONGITUDINAL_STRUCTURAL["B"]}
    seen = 0
    for (src, qty), r in ROWS.items():
        if src not in ("Eq. (12)", "Sect. 3.5"):
            continue
        i, j = int(qty[qty.index("(") + 1]) - 1, int(qty[qty.index(",") + 1]) - 1
        fixed = (i, j) in structural[src if src == "Eq. (12)" else qty[0]]
        lo, hi = r.interval
        assert (lo + hi) / 2 == pytest.approx(r.computed, abs=1e-15), (src, qty)
        assert (hi - lo) / 2 == pytest.approx(0.0 if fixed else 5e-5, rel=1e-9, abs=1e-15), (src, qty)
        seen += 1
    assert seen == 16 + 32


def test_tables_2_and_3_within_rounding() -> None:
    """Table 2 and Table 3: all match except |dp+| of mode 2, which is |lambda2| = 0.10548 (Eq. 12 rounding)."""
    rows = [r for (s, _), r in ROWS.items() if s in ("Table 2", "Table 3")]
    assert [r.quantity for r in rows if not r.match] == ["|dp+| mode 2"]
    w, _ = an.ordered_eigen(an.lateral_system()[0])
    assert_allclose(ROWS[("Table 3", "|dp+| mode 2")].computed, abs(w[1]), rtol=1e-12)


def test_eq27_recovered_from_the_papers_targets() -> None:
    """Eq. (27) to 4 decimals (atol 5e-5) from Eq. (19)'s eigenvalues and Eq. (24)'s b, three ways."""
    A, B = an.lateral_system()
    b = np.array([float(t) for t in pv.EQ24_B_COLUMN])
    e = [[float(t) for t in r] for r in pv.EQ19_A_LNN]
    t = [0.0, complex(e[1][1], e[1][2]), complex(e[1][1], -e[1][2]), e[3][3]]
    k = an.coefficient_matching_gains(A, b, t)
    assert_allclose(k, [float(g) for g in pv.EQ27_GAINS], rtol=0, atol=5e-5, err_msg="Eq. (27)")
    assert_allclose(an.place_poles_gains(A, b, t), k, rtol=0, atol=1e-10)
    assert_allclose(an.ackermann_gains(A, b, t), k, rtol=0, atol=1e-10)
    assert_allclose(np.sort_complex(np.linalg.eigvals(an.closed_loop_matrix(A, b, k))), np.sort_complex(t),
                    atol=1e-10)


def test_json_output_has_rows_matrices_and_exact_gains(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["analyze", "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert {"source", "quantity", "printed", "computed", "match", "note"} <= set(data["reproduction"][0])
    assert len(data["reproduction"]) == len(ROWS)
    assert len(data["gains"]["eq27_exact (exact eigenvalues, model b)"]) == 4
    assert np.array(data["lateral"]["modal_eq20_convention"]["B_ln"]).shape == (4, 3)
    assert data["lateral"]["controllability"]["all"]["kalman_rank"] == 4


def test_json_puts_the_design_asked_for_first(capsys: pytest.CaptureFixture[str]) -> None:
    """`analyze --targets ... --json`: the design for the user's targets is the document's first
    key, and its gains place the targets (eig(A + b k) against them, 1e-9: a well-separated
    spectrum of size 1)."""
    targets = [-0.1, -0.2, -0.3, -0.4]
    assert main(["analyze", "--targets=" + ",".join(map(str, targets)), "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert list(data)[0] == "custom_design"
    A, B = an.lateral_system()
    k = np.array(data["custom_design"]["gains"])
    got = np.sort(np.linalg.eigvals(A + np.outer(B[:, 0], k)).real)
    assert_allclose(got, sorted(targets), atol=1e-9)


def test_a_value_on_the_decimal_edge_rounds_to_the_printed_number() -> None:
    """"match" is |computed - printed| <= half a unit, the edge included: 0.07855 against
    "0.0786" matches though its float difference is 5.000000000000004e-05; a value 1e-11
    beyond the edge (ten times the slack) does not."""
    assert abs(0.07855 - float("0.0786")) > 5e-5  # the edge in floats: why the slack exists
    assert rounds_to(0.07855, "0.0786", 5e-5) and rounds_to(-0.07865, "-0.0786", 5e-5)
    assert not rounds_to(0.07855 - 1e-11, "0.0786", 5e-5)
    assert not rounds_to(0.0787, "0.0786", 5e-5)


def test_how_the_reports_print_numbers() -> None:
    """format_number: noise under NOISE (1e-12) is a signless 0; format_bound: a value known
    only as a bound is "< 1e-12" strictly under it, else two digits; format_vector: four
    decimals unless told."""
    assert NOISE == 1e-12
    assert [format_number(x) for x in (-3e-13, 2e-12, 0.1234567)] == ["0", "2e-12", "0.123457"]
    assert format_number(-0.25, ".3f") == "-0.250"
    assert [format_bound(x) for x in (9.9e-13, 1e-12, -3.456e-9)] == ["< 1e-12", "1.0e-12",
                                                                      "-3.5e-09"]
    assert format_bound(2e-10, bound=1e-9) == "< 1e-09"
    assert format_vector(np.array([0.123456, -2.0, 5e-13])) == "(0.1235, -2.0000, 0.0000)"
    assert format_vector(np.array([[1.0], [0.5]]), d=2) == "(1.00, 0.50)"


def test_eq24_b_interval_by_vertices() -> None:
    """The first-order interval of b(2) agrees with all 2^7 corners of the input box (Sect. 2.1, Table 1)."""
    p0 = lateral_dynamics.default_parameters()
    decimals = {**pv.SECT21_DECIMALS, "Y_Phi_a_plus": pv.TABLE1_DECIMALS, "L_Phi_a_plus": pv.TABLE1_DECIMALS,
                "N_Phi_a_plus": pv.TABLE1_DECIMALS}
    names = list(decimals)
    h = [0.5 * 10.0 ** -decimals[n] for n in names]
    vals = [lateral_dynamics.system_matrices(p0.with_values(**{n: getattr(p0, n) + s * d for n, s, d in zip(names, sg, h)}))
            [1][1, 0] for sg in itertools.product((-1, 1), repeat=7)]
    lo, hi = ROWS[("Eq. (24)", "b(2) [B1 column of delta_Phi_a]")].interval
    assert_allclose([min(vals), max(vals)], [lo, hi], rtol=0, atol=2e-5)
    assert min(vals) <= float(pv.EQ24_B_COLUMN[1]) <= max(vals)


def test_characteristic_coefficients_are_affine_in_k() -> None:
    A, B = an.lateral_system()
    c0, G = an.characteristic_affine(A, B[:, 0])
    k = np.array([0.3, -1.2, 0.7, 2.0])
    assert_allclose(c0 + G @ k, an.char_coefficients(an.closed_loop_matrix(A, B[:, 0], k)), rtol=0, atol=1e-12)


def test_modal_form_and_controllability() -> None:
    A, B = an.lateral_system()
    mf = an.modal_decomposition(A, B)
    assert_allclose(mf.M @ mf.A_nn @ np.linalg.inv(mf.M), A, atol=1e-12)
    ctl = an.controllability(A, B, lateral_interface.CONTROL_NAMES, mf)
    for name in (*lateral_interface.CONTROL_NAMES, "all"):
        assert ctl[name]["kalman_rank"] == 4 and all(m["controllable"] for m in ctl[name]["modes"]), name


def test_single_input_designs_stabilise() -> None:
    A, B = an.lateral_system()
    for u in lateral_interface.CONTROL_NAMES:
        k = move_lambda1_gains(A, B, u, -0.1)
        ev = np.linalg.eigvals(an.closed_loop_matrix(A, B[:, lateral_interface.CONTROL_NAMES.index(u)], k))
        assert np.min(np.abs(ev + 0.1)) < 1e-9 and ev.real.max() < 0, u
        assert np.linalg.eigvals(an.closed_loop_matrix(A, B[:, lateral_interface.CONTROL_NAMES.index(u)],
                                                       lqr_gains(A, B, u))).real.max() < 0, u
    paper = [d for d in stabilising_designs(extra={"Eq. (27)": [float(g) for g in pv.EQ27_GAINS]})
             if d.method == "Eq. (27)"][0]
    # Sect. 3.4: 0.5 rad roll along mode 1 needs "only a few degrees" of dPhi_a (4.05 deg over 100
    # wing beats; with model.py's b the printed gains leave lambda1 = +1e-4, so |u| creeps up slowly).
    assert 2.0 < paper.mode1.peak_control_deg < 5.0


@pytest.mark.parametrize("text, needle", [
    ("nan,-0.1,-0.2,-0.3", "nan"), ("inf,-0.1,-0.2,-0.3", "inf"),
    ("-0.1,-0.2+0.1j,-0.2,-0.3", "(-0.2+0.1j)"), ("-0.1,-0.2,-0.3", "got 3"), ("-0.1,x,-0.2,-0.3", "'x'")])
def test_bad_targets_name_the_value(text: str, needle: str) -> None:
    with pytest.raises(an.AnalysisInputError, match=None) as e:
        an.parse_targets(text)
    assert needle in str(e.value) and isinstance(e.value, ValueError)


def test_uncontrollable_input_is_refused() -> None:
    A, B = an.lateral_system()
    B0 = B.copy()
    B0[:, 2] = 0.0
    with pytest.raises(an.UncontrollableError, match="'delta_alpha_2a'.*Kalman rank 0"):
        an.coefficient_matching_gains(A, B0, [-0.1, -0.2, -0.3, -0.4], "delta_alpha_2a")
    with pytest.raises(an.AnalysisInputError, match="'bogus'"):
        an.input_index("bogus")


@pytest.mark.parametrize("argv, needle", [
    (["--targets=nan,-0.1,-0.2,-0.3"], "nan"),
    (["--targets=-0.1,-0.2+0.1j,-0.2,-0.3"], "not closed under conjugation"),
    (["--input", "bogus"], "'bogus'")])
def test_cli_bad_input_exit_2(argv: list[str], needle: str, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["analyze", *argv]) == 2
    out, err = capsys.readouterr()
    assert out == "" and err.count("\n") == 1 and needle in err and "Traceback" not in err


def test_cli_text_and_custom_design(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["analyze", "--targets=-0.2,-0.089+0.057i,-0.089-0.057i,-0.51", "--input",
                 "delta_alpha_1a"]) == 0
    out = capsys.readouterr().out
    assert f"{len(ROWS)} rows" in out and "Design for the given targets with delta_alpha_1a" in out


def test_docs_reproduction_md_is_current() -> None:
    """The words exactly, the numbers to a unit of their last digit (tests/docnumbers.py: a
    well-conditioned number rounds either way on another machine; round-off is printed as a
    bound, so it compares as text)."""
    doc = Path(__file__).resolve().parents[1] / "docs" / "reproduction.md"
    diff = same_numbers(render(analyze(), "markdown"), doc.read_text(encoding="utf-8"))
    assert diff is None, f"{diff}; regenerate: dronefly analyze --markdown --out docs/reproduction.md"


@pytest.mark.parametrize("targets", ["-0.1,-0.1,-0.1,-0.1", "0,0,0,0"])
def test_repeated_targets_are_placed_and_said_so(targets):
    """Coefficient matching places a repeated root (the characteristic polynomial is the
    target one); the report says why place_poles is skipped."""
    from dronefly.harness.paper.design import analysis_report

    c = analysis_report(targets, "delta_Phi_a")["custom_design"]
    A, B = lateral_dynamics.system_matrices(lateral_dynamics.default_parameters())
    k = np.array(c["gains"])
    want = np.poly([complex(t) for t in targets.split(",")]).real
    assert_allclose(np.poly(A + np.outer(B[:, 0], k)), want, atol=1e-12)
    assert c["gains_place_poles"] is None and "repeated targets" in c["note"]


def test_analyze_out_naming_a_folder_is_refused(tmp_path, capsys):
    assert main(["analyze", "--out", str(tmp_path)]) == 2
    assert "is a folder" in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == [] and not list(tmp_path.parent.glob("*.part"))


def test_pole_placement_agrees_with_python_control():
    """Our hand-written Ackermann formula and Kalman rank against python-control (u = -K x in
    python-control, u = K x here)."""
    import control  # the test extra installs it: a broken install fails
    A, B = an.lateral_system()
    for j in range(B.shape[1]):
        b = B[:, [j]]
        targets = [-0.1, -0.2, complex(-0.089, 0.057), complex(-0.089, -0.057)]
        ours = an.ackermann_gains(A, B, targets, j)
        theirs = -np.asarray(control.acker(A, b, targets)).ravel()
        assert_allclose(ours, theirs, rtol=1e-8, atol=1e-12)
        rank, _ = an.kalman_rank(A, b)
        assert rank == np.linalg.matrix_rank(control.ctrb(A, b)) == 4
    A_lon, B_lon = an.longitudinal_system()
    for j in range(B_lon.shape[1]):
        assert an.kalman_rank(A_lon, B_lon[:, [j]])[0] == np.linalg.matrix_rank(
            control.ctrb(A_lon, B_lon[:, [j]]))
