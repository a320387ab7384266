"""Oracles for the analysis of the paper's matrices (``harness.paper.analysis`` and
``.design``) written against the survivors of their mutation runs (docs/mutation.md):
controllability by Kalman's rank and by the PBH test on systems whose reachable modes are
known by construction, the checks on a user's target eigenvalues at their bounds, and the
designs beyond the paper against the exact response exp((A + b k) t) x0, python-control's LQR
and the eigenvectors of A.
"""

from __future__ import annotations

import math
import re

import numpy as np
import pytest
from numpy.testing import assert_allclose
from scipy.linalg import expm

from dronefly.harness.paper.analysis import (AnalysisInputError, UncontrollableError,
                                             coefficient_matching_gains, controllability,
                                             LONGITUDINAL_CONVENTION, eigenvector_table,
                                             kalman_rank, lateral_system, longitudinal_system,
                                             modal_decomposition, validate_targets)
from dronefly.harness.cosim.params import ParameterError
from dronefly.harness.paper.design import (analysis_report, lqr_gains, move_lambda1_gains,
                                           peak_control, stabilising_designs)
from dronefly.harness.paper.gains import as_gain_matrix, gain_matrix, parse_gains
from dronefly.harness.paper.printed import EQ27_GAINS
from dronefly.harness.paper.report import render
from dronefly.harness.paper.reproduction import analyze
from dronefly.models.lateral_interface import CONTROL_NAMES

pytestmark = pytest.mark.numeric  # SVDs, eigenvectors, expm and Riccati go through the BLAS kernel

#: A block-diagonal system whose reachable modes are read off its B: the modes -1 and -2
#: (states 1 and 2) and the pair -0.1 +- 0.5i (states 3 and 4). u1 = (1, 0, 1, 0) reaches -1
#: and the pair, not -2; u2 = (0, 1, 0, 0) reaches -2 only.
A_BLOCKS = np.array([[-1.0, 0, 0, 0], [0, -2.0, 0, 0], [0, 0, -0.1, 0.5], [0, 0, -0.5, -0.1]])
B_BLOCKS = np.array([[1.0, 0], [0, 1.0], [1.0, 0], [0, 0]])


def _controllability_matrix(A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """[B, AB, A^2 B, A^3 B] from matrix powers (not the repeated product of the module)."""
    return np.hstack([np.linalg.matrix_power(A, i) @ B for i in range(len(A))])


@pytest.mark.parametrize("case, want_rank", [
    ("paper, delta_Phi_a", 4), ("paper, delta_alpha_2a", 4), ("paper, all", 4),
    ("blocks, u1", 3), ("blocks, u2", 1), ("blocks, all", 4), ("no input", 0),
    ("a mode reached at 1e-13 of the rest", 3), ("B alone, 5e-10 of its largest direction", 2)])
def test_kalman_rank_is_the_rank_of_the_controllability_matrix(case, want_rank):
    """The rank known by construction, and the singular values of [B, AB, A^2 B, A^3 B] (a
    well-conditioned SVD of entries of size 1: 1e-12 of the largest)."""
    A, B = lateral_system()
    systems = {"paper, delta_Phi_a": (A, B[:, :1]), "paper, delta_alpha_2a": (A, B[:, 2:]),
               "paper, all": (A, B), "blocks, u1": (A_BLOCKS, B_BLOCKS[:, :1]),
               "blocks, u2": (A_BLOCKS, B_BLOCKS[:, 1:]), "blocks, all": (A_BLOCKS, B_BLOCKS),
               "no input": (A_BLOCKS, np.zeros((4, 1))),
               "a mode reached at 1e-13 of the rest": (A_BLOCKS, B_BLOCKS[:, :1] + [[0], [1e-13],
                                                                                      [0], [0]]),
               # A = 0: the matrix is [B, 0, 0, 0], whose singular values are B's own, 100, 1,
               # 5e-8 and 0; 5e-8 is 5e-10 of the largest, under the relative 1e-9: rank 2
               "B alone, 5e-10 of its largest direction": (np.zeros((4, 4)),
                                                           np.diag([100.0, 1.0, 5e-8, 0.0]))}
    A_case, B_case = systems[case]
    rank, s = kalman_rank(A_case, B_case)
    want_s = np.linalg.svd(_controllability_matrix(A_case, B_case), compute_uv=False)
    assert rank == want_rank
    assert len(s) == len(want_s) and s == pytest.approx(want_s, abs=1e-12 * max(want_s[0], 1.0))
    # a 1-D b is one column
    if B_case.shape[1] == 1:
        assert kalman_rank(A_case, B_case[:, 0])[0] == want_rank


def test_pbh_test_finds_the_modes_an_input_cannot_reach():
    """Per input set: one entry per real mode and per pair (its upper member), the smallest
    singular value of [lambda I - A, B] (computed here from the definition; exactly 0 for a
    mode the input cannot reach, to round-off 1e-15 for the pair), and the set controllable
    exactly when its Kalman rank is 4."""
    mf = modal_decomposition(A_BLOCKS, B_BLOCKS)
    out = controllability(A_BLOCKS, B_BLOCKS, ["u1", "u2"], mf)
    reached = {"u1": {complex(-0.1, 0.5), -1.0}, "u2": {-2.0}, "all": {complex(-0.1, 0.5), -1.0,
                                                                       -2.0}}
    for label, cols in (("u1", [0]), ("u2", [1]), ("all", [0, 1])):
        got = out[label]
        assert got["kalman_rank"] == len(reached[label]) + (complex(-0.1, 0.5) in reached[label])
        assert got["controllable"] == (got["kalman_rank"] == 4)
        eigenvalues = [complex(*m["eigenvalue"]) for m in got["modes"]]
        assert eigenvalues == pytest.approx([complex(-0.1, 0.5), -1.0, -2.0], abs=1e-15)
        for lam, mode in zip(eigenvalues, got["modes"]):
            pbh = np.hstack([lam * np.eye(4) - A_BLOCKS, B_BLOCKS[:, cols]])
            s = np.linalg.svd(pbh, compute_uv=False)
            assert mode["pbh_min_singular_value"] == pytest.approx(s[-1], abs=1e-14)
            assert mode["controllable"] == any(abs(lam - z) < 1e-12 for z in reached[label])
            # the modal input: the RMS of the mode's rows of the modal B (two rows for the pair)
            rows = [0, 1] if lam.imag else [eigenvalues.index(lam) + 1]
            want = np.linalg.norm(mf.B_n[np.ix_(rows, cols)]) / math.sqrt(len(rows))
            assert mode["modal_input_magnitude"] == pytest.approx(want, rel=1e-12)
            assert (mode["modal_input_magnitude"] > 1e-12) == mode["controllable"]


def test_the_paper_plant_is_controllable_from_each_input_alone():
    """Sect. 3.3: each of the three inputs alone controls every lateral mode."""
    A, B = lateral_system()
    out = controllability(A, B, CONTROL_NAMES, modal_decomposition(A, B))
    for label in (*CONTROL_NAMES, "all"):
        assert out[label]["controllable"] and out[label]["kalman_rank"] == 4, label
        assert len(out[label]["modes"]) == 3 and all(m["controllable"] for m in out[label]["modes"])


def test_a_mode_reached_a_millionth_as_strongly_as_the_system_scale_is_not_reached():
    """PBH is relative to the largest singular value of [lambda I - A, b]: with a mode at -1000
    beside -2, -3, -4, the mode -2 reached by 1e-8 gives a smallest singular value of about
    1e-8, 1e-11 of the largest (998), so it counts as unreached, though it is over 1e-9 of
    every other singular value."""
    A = np.diag([-1000.0, -2.0, -3.0, -4.0])
    b = np.array([[1.0], [1e-8], [1.0], [1.0]])
    pbh = np.linalg.svd(np.hstack([-2.0 * np.eye(4) - A, b]), compute_uv=False)
    assert pbh[-1] < 1e-9 * pbh[0] and pbh[-1] > 1e-9 * pbh[1]  # the case this test is about
    out = controllability(A, b, ["u"], modal_decomposition(A, b))["u"]
    flags = {complex(*m["eigenvalue"]).real: m["controllable"] for m in out["modes"]}
    assert flags == {-1000.0: True, -2.0: False, -3.0: True, -4.0: True}


@pytest.mark.parametrize("u, rank", [(0, 3), (1, 1)])
def test_an_input_that_cannot_place_names_its_smallest_singular_value(u, rank):
    """u1 reaches three modes of four, u2 one: the message gives the Kalman rank and the
    smallest singular value of the controllability matrix, which is 0 (a zero row) to
    round-off (1e-15 of its largest, about 10)."""
    with pytest.raises(UncontrollableError, match=rf"Kalman rank {rank} < 4 \(smallest singular "
                                                  r"value (\S+)\)") as e:
        coefficient_matching_gains(A_BLOCKS, B_BLOCKS, [-1, -2, -3, -4], u=u)
    smallest = float(str(e.value).rsplit("value ", 1)[1].rstrip(")"))
    assert abs(smallest) < 1e-13


def test_targets_up_to_1000_per_wing_beat_are_taken():
    """The bound on a target's magnitude (the gains grow with its fourth power): 1000 is
    taken, anything above is refused naming the value and the bound."""
    assert validate_targets([-1000.0, -1.0, -2.0, -3.0])[0] == -1000.0
    assert validate_targets([complex(-600, 800), complex(-600, -800), -1, -2]).shape == (4,)
    with pytest.raises(AnalysisInputError, match=r"\(-1000.5\+0j\) exceeds 1000 per wing beat"):
        validate_targets([-1000.5, -1.0, -2.0, -3.0])


@pytest.mark.parametrize("targets, off, ok", [
    # the conjugate is matched to 1e-9 of the largest target's magnitude, at least 1e-9
    ([-100 + 50j, -100 - 50j, -1, -2], 5e-8, True),  # 1e-9 * 112: within
    ([-100 + 50j, -100 - 50j, -1, -2], 5e-7, False),
    ([-0.3 + 0.4j, -0.3 - 0.4j, -0.1, -0.2], 0.8e-9, True),  # small targets: 1e-9
    ([-0.3 + 0.4j, -0.3 - 0.4j, -0.1, -0.2], 1.5e-9, False),
])
def test_a_pair_is_matched_to_its_conjugate_within_a_relative_tolerance(targets, off, ok):
    t = list(targets)
    t[1] += complex(0, off)  # the lower member moved off the conjugate of the upper
    if ok:
        assert validate_targets(t).shape == (4,)
    else:
        with pytest.raises(AnalysisInputError, match="has no conjugate"):
            validate_targets(t)


# --- the designs beyond the paper (harness.paper.design) -------------------------------------
def _response_by_expm(A, b, k, x0, t_end_wb, dt_wb):
    """Peak |k x(t)|, its time and |x(t_end)| on the grid t_i = i dt, each x(t_i) =
    exp((A + b k) t_i) x0 computed on its own (no stepping, so no accumulated round-off)."""
    Acl = np.asarray(A) + np.outer(b, k)
    n = int(round(t_end_wb / dt_wb))
    xs = [expm(Acl * (i * dt_wb)) @ x0 for i in range(n + 1)]
    u = [abs(np.dot(k, x)) for x in xs]
    i = int(np.argmax(u))
    return u[i], i * dt_wb, float(np.linalg.norm(xs[-1]))


@pytest.mark.parametrize("t_end, dt", [(None, None), (3.0, 0.25)])
def test_peak_control_is_the_peak_of_the_exact_response(t_end, dt):
    """The closed loop of delta_Phi_a with gains that move lambda_1 to -0.1 (peak at t = 0 for
    a pure roll) and with gains that peak later (the LQR design from the mode-1 shape): the
    peak, its time and the final state against exp((A + b k) t) x0 at every grid point (the
    stepped product drifts from it by round-off, 1e-13 relative over 2000 steps)."""
    A, B = lateral_system()
    b = B[:, 0]
    kw = {} if t_end is None else {"t_end": t_end, "dt": dt}
    grid = (100.0, 0.05) if t_end is None else (t_end, dt)
    eta1 = _mode1_shape(A)
    for k, x0 in ((move_lambda1_gains(A, B, "delta_Phi_a", -0.1), np.array([0, 0, 0, 0.5])),
                  (lqr_gains(A, B, "delta_Phi_a"), 0.5 * eta1),
                  (np.array([0.0, 0.0, 0.0, 0.2]), np.array([0.1, 0.0, 0.0, 0.0]))):
        got = peak_control(A, b, k, x0, **kw)
        peak, when, final = _response_by_expm(A, b, k, x0, *grid)
        assert got.peak_control_rad == pytest.approx(peak, rel=1e-10)
        assert got.peak_time == pytest.approx(when, abs=1e-12)
        assert got.final_state_norm == pytest.approx(final, rel=1e-9, abs=1e-15)
        assert got.peak_control_deg == pytest.approx(math.degrees(peak), rel=1e-10)


def _mode1_shape(A):
    """The eigenvector of the real unstable root lambda_1, scaled to dgamma = 1 (Table 3)."""
    w, v = np.linalg.eig(A)
    i = int(np.argmax(w.real))
    assert abs(w[i].imag) < 1e-15 and w[i].real > 0
    return np.real(v[:, i] / v[3, i])


@pytest.mark.parametrize("name, value", [("t_end", 0.0), ("t_end", -0.5), ("t_end", math.nan),
                                         ("dt", 0.0), ("dt", -0.5), ("dt", math.inf)])
def test_peak_control_refuses_a_horizon_or_step_that_is_not_positive(name, value):
    A, B = lateral_system()
    with pytest.raises(AnalysisInputError, match=rf"{name} = {value!r} must be finite and > 0"):
        peak_control(A, B[:, 0], np.zeros(4), np.ones(4), **{name: value})


def test_move_lambda1_moves_only_lambda1_and_only_to_the_left():
    A, B = lateral_system()
    w = np.linalg.eigvals(A)
    k = move_lambda1_gains(A, B, "delta_alpha_1a", -0.3)
    got = np.sort_complex(np.linalg.eigvals(A + np.outer(B[:, 1], k)))
    want = np.sort_complex(np.array([-0.3, *sorted(w, key=lambda z: -z.real)[1:]]))
    assert_allclose(got, want, atol=1e-9)
    for bad in (0.0, 0.5, math.nan):
        with pytest.raises(AnalysisInputError, match=rf"lambda1 = {bad!r} must be finite and < 0"):
            move_lambda1_gains(A, B, "delta_Phi_a", bad)


def test_lqr_gains_are_python_controls():
    """python-control's lqr (SLICOT or scipy's Riccati solver) gives K for u = -K x; ours are
    u = k x. Weights away from identity and r away from 1 (where k / r and k * r differ); the
    Riccati solution of a well-conditioned 4x4 problem agrees to 1e-9."""
    import control  # the test extra installs it: a broken install fails (0.8 s to import)
    A, B = lateral_system()
    for u, q, r in (("delta_Phi_a", (1.0, 1.0, 1.0, 1.0), 1.0),
                    ("delta_alpha_2a", (0.5, 2.0, 0.0, 3.0), 2.5)):
        b = B[:, [list(CONTROL_NAMES).index(u)]]
        K, _, _ = control.lqr(A, b, np.diag(q), np.array([[r]]))
        assert_allclose(lqr_gains(A, B, u, q=q, r=r), -np.asarray(K)[0], rtol=1e-9, atol=1e-12)


@pytest.mark.parametrize("q, r", [((1, 1, 1, 1), 0.0), ((1, 1, 1, 1), -0.5), ((1, 1, 1, 1), math.nan),
                                  ((1, -0.5, 1, 1), 1.0), ((1, math.nan, 1, 1), 1.0)])
def test_lqr_refuses_weights_that_are_not_a_cost(q, r):
    A, B = lateral_system()
    with pytest.raises(AnalysisInputError, match=r"LQR weights .* must be finite, q >= 0, r > 0"):
        lqr_gains(A, B, "delta_Phi_a", q=q, r=r)


def test_the_designs_start_from_the_documented_disturbances():
    """Defaults: lambda_1 -> -0.1, and disturbances of a 0.5 rad roll and 0.5 eta_1 (docs/
    reproduction.md: "after a pure 0.5 rad roll and after 0.5 x the mode-1 eigenvector")."""
    A, B = lateral_system()
    eta1 = _mode1_shape(A)
    for d in stabilising_designs():
        b = B[:, list(CONTROL_NAMES).index(d.input)]
        if d.method.startswith("lambda1"):
            assert d.method == "lambda1 -> -0.1"
            assert min(abs(np.linalg.eigvals(A + np.outer(b, d.gains)) + 0.1)) < 1e-9
        for resp, x0 in ((d.roll, np.array([0, 0, 0, 0.5])), (d.mode1, 0.5 * eta1)):
            assert resp.peak_control_rad == pytest.approx(_response_by_expm(A, b, d.gains, x0, 100.0, 0.05)[0],
                                                          rel=1e-10)
    for bad in (0.0, math.nan):
        with pytest.raises(AnalysisInputError, match=rf"gamma0 = {bad!r} must be finite and nonzero"):
            stabilising_designs(gamma0=bad)
    assert len(stabilising_designs(gamma0=-1.0)) == len(stabilising_designs(gamma0=1.0)) == 6


def test_the_report_of_a_custom_design():
    """analyze --targets: the gains place the targets (the characteristic polynomial to
    round-off), the peak controls are those of the documented disturbances, Eq. (24)'s b is
    B1's delta_Phi_a column, and the Table 3 modal form diagonalises A1 in Table 3's order with
    each real mode's eigenvector at dgamma = 1."""
    targets = [-0.2, complex(-0.089, 0.057), complex(-0.089, -0.057), -0.51]
    r = analysis_report(",".join(str(z).strip("()") for z in targets), "delta_alpha_1a")
    A, B = lateral_system()
    c = r["custom_design"]
    b = B[:, 1]
    k = np.array(c["gains"])
    assert c["char_poly_error"] < 1e-13
    assert_allclose(np.poly(A + np.outer(b, k)), np.real(np.poly(targets)), atol=1e-13)
    eta1 = _mode1_shape(A)
    for key, x0 in (("roll", np.array([0, 0, 0, 0.5])), ("mode1", 0.5 * eta1)):
        want = math.degrees(_response_by_expm(A, b, k, x0, 100.0, 0.05)[0])
        assert c["peak_control_deg"][key] == pytest.approx(want, rel=1e-10), key
    lat = r["lateral"]
    assert lat["eq24_b"] == B[:, 0].tolist() == [row[0] for row in lat["B1"]]
    M = np.array(lat["modal_table3_convention"]["M1"])
    D = np.linalg.solve(M, A @ M)
    w = sorted(np.linalg.eigvals(A), key=lambda z: (-z.real, -z.imag))  # lambda1, pair, lambda4
    assert D[0, 0] == pytest.approx(w[0].real, abs=1e-12) and D[3, 3] == pytest.approx(w[3].real, abs=1e-12)
    assert np.abs(D[0, 1:]).max() < 1e-12 and np.abs(D[3, :3]).max() < 1e-12
    assert_allclose(np.linalg.eigvals(D[1:3, 1:3]), [w[1], w[2]], atol=1e-12)
    assert M[3, 0] == pytest.approx(1.0, abs=1e-14) and M[3, 3] == pytest.approx(1.0, abs=1e-14)
    assert_allclose(np.array(lat["modal_table3_convention"]["B_ln"]), np.linalg.solve(M, B), atol=1e-12)


# --- the modal form and Table 3 (harness.paper.modal) ----------------------------------------
def test_the_modal_forms_list_their_eigenvalues_in_their_order():
    """ModalForm.eigenvalues: eig(A) in the convention's order, a pair as sigma + i omega then
    its conjugate: the lateral form in ordered_eigen's order (lambda_1, the pair, lambda_4),
    the longitudinal one as Eq. (32)'s columns (the pair, the fast, then the slow subsidence)."""
    A, B = lateral_system()
    w = sorted(np.linalg.eigvals(A), key=lambda z: (-z.real, -z.imag))
    got = modal_decomposition(A, B).eigenvalues
    assert_allclose(got, [w[0], w[1], w[2], w[3]], atol=1e-12)
    assert got[1].imag > 0 and got[2] == np.conj(got[1])
    Al, Bl = longitudinal_system()
    ml = modal_decomposition(Al, Bl, LONGITUDINAL_CONVENTION)
    wl = np.linalg.eigvals(Al)
    pair = sorted(wl[np.abs(wl.imag) > 0], key=lambda z: -z.imag)
    real = sorted(wl[wl.imag == 0].real)  # fast (more negative), then slow
    assert_allclose(ml.eigenvalues, [*pair, *real], atol=1e-12)
    # each column of M is its eigenvalue's: A M = M A_nn with A_nn block diagonal in that order
    assert_allclose(ml.A_nn[2:, 2:], np.diag(real), atol=1e-12)


def test_table3_phases_are_wrapped_to_the_half_open_interval():
    """A pair eigenvector whose first component lies at -179.5 degrees from dgamma (the
    reference of Table 3) is printed at -179.5, not +180.5: phases in (-180, 180]. A is built
    from its eigenvectors: real Jordan form J, A = V J V^-1 (V of size 1: exact to 1e-14)."""
    phi = math.radians(-179.5)
    sigma, omega = -0.1, 0.5
    a = np.array([math.cos(phi), 0.3, 0.2, 1.0])  # real and imaginary parts of the pair's
    bvec = np.array([math.sin(phi), -0.4, 0.1, 0.0])  # eigenvector, dgamma = 1 + 0i
    V = np.column_stack([[0.2, 0.1, 0.3, 1.0], a, bvec, [0.5, -0.2, 0.1, 1.0]])
    J = np.array([[0.1, 0, 0, 0], [0, sigma, omega, 0], [0, -omega, sigma, 0], [0, 0, 0, -1.0]])
    A = V @ J @ np.linalg.inv(V)
    w, mag, ph = eigenvector_table(A)
    assert_allclose(w, [0.1, complex(sigma, omega), -1.0], atol=1e-12)
    # the pair's eigenvector for sigma + i omega is a + i b (J's block: A a = sigma a - omega b,
    # A b = omega a + sigma b), with dgamma = a[3] + i b[3] = 1
    want = np.degrees(np.angle(a + 1j * bvec))
    assert ph[0, 1] == pytest.approx(want[0], abs=1e-9) and ph[0, 1] < -179.0
    assert_allclose(ph[:, 1], want, atol=1e-9)
    assert_allclose(mag[:, 1], np.abs(a + 1j * bvec), rtol=1e-12)


# --- gain matrices from the command line (harness.paper.gains) ------------------------------
def test_the_named_gain_sets():
    """paper: Eq. (27) on delta_Phi_a (as printed, the other rows 0); open: 0; stabilising:
    delta_Phi_a's gains that move lambda_1 to -0.1 and keep the other roots of A1."""
    paper = parse_gains(" Paper ")
    assert paper.shape == (3, 4) and paper[0].tolist() == [float(k) for k in EQ27_GAINS]
    assert not paper[1:].any() and not parse_gains("open").any() and gain_matrix("open").shape == (3, 4)
    K = parse_gains("STABILISING")
    assert K.shape == (3, 4) and not K[1:].any()
    A, B = lateral_system()
    got = np.sort_complex(np.linalg.eigvals(A + B @ K))
    w = sorted(np.linalg.eigvals(A), key=lambda z: -z.real)
    assert_allclose(got, np.sort_complex(np.array([-0.1, *w[1:]])), atol=1e-9)
    with pytest.raises(ParameterError, match="unknown gain set 'closed'; choose from paper, "
                                             "stabilising, open"):
        gain_matrix("closed")


def test_gains_inline_and_from_files(tmp_path):
    """One row is delta_Phi_a's (Eq. 22), three rows are the full matrix; a CSV with or
    without a header line, a JSON list of rows or {"K": rows}."""
    full = np.arange(1.0, 13.0).reshape(3, 4)
    assert parse_gains("1,2,3,4").tolist() == [[1, 2, 3, 4], [0] * 4, [0] * 4]
    assert np.array_equal(parse_gains("1,2,3,4; 5,6,7,8 ;9,10,11,12"), full)
    assert np.array_equal(as_gain_matrix([1, 2, 3, 4]), parse_gains("1,2,3,4"))
    assert np.array_equal(as_gain_matrix(full.tolist()), full)
    (tmp_path / "h.csv").write_text("k1,k2,k3,k4\n1,2,3,4\n5,6,7,8\n9,10,11,12\n")
    (tmp_path / "n.CSV").write_text("1,2,3,4\n\n  ,  \n5,6,7,8\n9,10,11,12\n")  # blank lines
    (tmp_path / "l.json").write_text("[[1,2,3,4],[5,6,7,8],[9,10,11,12]]")
    (tmp_path / "d.json").write_text('{"K": [[1,2,3,4]]}')
    for name in ("h.csv", "n.CSV", "l.json"):
        assert np.array_equal(parse_gains(str(tmp_path / name)), full), name
    assert parse_gains(str(tmp_path / "d.json")).tolist() == [[1, 2, 3, 4], [0] * 4, [0] * 4]


@pytest.mark.parametrize("text, message", [
    ("1,2;3,4", "gains '1,2;3,4': 2 rows, expected 3 (delta_Phi_a, delta_alpha_1a, delta_alpha_2a) or 1"),
    ("1,2,3,4;5,6,7;8,9,10,11", "gains '1,2,3,4;5,6,7;8,9,10,11': row 2 has 3 values, expected 4 "
                                "(on delta_v, delta_p, delta_r, delta_gamma as x+)"),
    ("1,2,3", "row 1 has 3 values, expected 4"),
    ("1,nan,3,4", "K[1,2] = nan is not finite"),
    ("1,2,3,4;0,0,0,0;0,0,0,inf", "K[3,4] = inf is not finite"),
    ("1,x,3,4", "gains '1,x,3,4': every entry must be a number"),
])
def test_bad_gains_are_named(text, message):
    with pytest.raises(ParameterError, match=re.escape(message)):
        parse_gains(text)


def test_bad_gain_files_are_named(tmp_path):
    (tmp_path / "bad.json").write_text("[[1,2,3,4]")
    (tmp_path / "dict.json").write_text('{"gains": [[1,2,3,4]]}')
    (tmp_path / "null.json").write_text("[[1,null,3,4]]")
    (tmp_path / "short.csv").write_text("1,2,3\n")
    for name, message in (("missing.csv", "gains file {}: No such file or directory"),
                          ("bad.json", "gains file {} is not JSON: "),  # then json's words
                          ("dict.json", 'gains file {}: expected a list of rows or {{"K": ...}}'),
                          ("null.json", "gains in {}: every entry must be a number"),
                          ("short.csv", "gains in {}: row 1 has 3 values, expected 4 (on "
                                        "delta_v, delta_p, delta_r, delta_gamma as x+)")):
        path = str(tmp_path / name)
        with pytest.raises(ParameterError) as e:
            parse_gains(path)
        want = message.format(repr(path))
        assert str(e.value) == want or want.endswith(": ") and str(e.value).startswith(want)


# --- what `dronefly analyze` prints (harness.paper.report) -----------------------------------
def _row_line(lines: list[str], row) -> int:
    """The index of ``row``'s line in the text report."""
    return next(i for i, ln in enumerate(lines) if ln.startswith(f"{row.source:10} {row.quantity:46} "))


def _greedy_at(lines: list[str], width: int) -> bool:
    """Whether ``lines`` are a paragraph filled to ``width`` columns: none longer, and none
    that could have taken the next line's first word."""
    return all(len(ln) <= width for ln in lines) and all(
        len(a) + 1 + len(b.split()[0]) > width for a, b in zip(lines, lines[1:]))


def test_the_text_report_says_what_the_rows_say():
    """The counts in the findings are the rows' own (counted here), each row has its line with
    its printed and computed value and its verdict, and the designs' lines give the peak
    controls of the report."""
    a = analyze()
    text = render(a, "text")
    lines = text.splitlines()
    rows = a.rows
    bad = [r for r in rows if not r.match]
    reasons = {}
    for r in bad:
        reasons[r.reason] = reasons.get(r.reason, 0) + 1
    assert (f"{len(rows)} rows, {len(rows) - len(bad)} match, {len(bad)} do not ("
            + ", ".join(f"{n} {k}" for k, n in reasons.items()) + ").") in lines
    per_source = {}
    for r in rows:
        m, n = per_source.get(r.source, (0, 0))
        per_source[r.source] = (m + r.match, n + (not r.match))
    assert ("Per source (match / rounding or other mismatch): "
            + "; ".join(f"{s} {m}/{n}" for s, (m, n) in per_source.items()) + ".") in lines
    for r in rows:
        line = lines[_row_line(lines, r)]
        printed, computed, *verdict = line[58:].split()
        assert printed == r.printed and float(computed) == pytest.approx(r.computed, rel=1e-5,
                                                                         abs=1e-12)
        assert " ".join(verdict) == ("yes" if r.match else f"NO ({r.reason})")
    for d in a.report["designs"]:
        resp = d["response"]
        want = (f"peak {resp['roll']['peak_control_deg']:.2f} / "
                f"{resp['mode1']['peak_control_deg']:.2f} deg")
        assert any(d["method"] in ln and d["input"] in ln and ln.endswith(want) for ln in lines)
    assert lines[0] == "Reproduction of Zhang & Sun (lateral stabilization), printed vs computed"


def test_a_custom_design_comes_first_in_every_rendering():
    a = analyze("-0.1,-0.1,-0.1,-0.1")  # repeated: the note on place_poles is shown
    k = a.report["custom_design"]["gains"]
    text = render(a, "text").splitlines()
    assert text[0] == ("Design for the given targets with delta_Phi_a: k = ("
                       + ", ".join(f"{v:.6f}" for v in k) + ")")
    assert text[1].startswith("  repeated targets: placed by coefficient matching")
    md = render(a, "markdown").splitlines()
    assert md.index("## Design for the given targets") < md.index("## Findings")
    with pytest.raises(ValueError, match="format = 'html'; choose text, markdown or json"):
        render(a, "html")


def test_the_text_report_wraps_each_new_note_under_its_row():
    """A row's note follows its line, indented and filled to 100 columns, once: a row whose
    note is its predecessor's shows none."""
    a = analyze()
    lines = render(a, "text").splitlines()
    last = ""
    seen = 0
    for r in a.rows:
        below = []
        for ln in lines[_row_line(lines, r) + 1:]:
            if not ln.startswith("    "):
                break
            below.append(ln)
        if r.note and r.note != last:
            assert " ".join(ln.strip() for ln in below) == " ".join(r.note.split()), r.quantity
            assert _greedy_at(below, 100), r.quantity
            seen += 1
        else:
            assert below == [], r.quantity
        last = r.note
    assert seen >= 10


def test_the_markdown_puts_a_custom_design_between_its_preamble_and_the_findings():
    plain = render(analyze(), "markdown").splitlines()
    custom = render(analyze("-0.2,-0.3,-0.4,-0.5"), "markdown").splitlines()
    head = plain.index("## Findings")
    assert custom[:head] == plain[:head]  # the title and the paragraph on how it was made
    assert custom[head] == "## Design for the given targets"
    assert custom[head + 2].startswith("Design for the given targets with delta_Phi_a: k = (")
    assert custom[custom.index("## Findings") + 1:][:3] == plain[head + 1:][:3]


def test_the_reports_print_gains_to_six_decimals_and_fill_the_design_note():
    """The gain variants differ in their 4th to 6th decimals (Eq. 27 as printed -0.3192, from
    the paper's inputs -0.319193): both renderings print every gain to 6 decimals. The note of
    a custom design is filled to 100 columns (the rows' notes: the wrapping test above)."""
    a = analyze("-0.1,-0.1,-0.1,-0.1")
    text, md = render(a, "text").splitlines(), render(a, "markdown").splitlines()
    for name, values in a.gains.items():
        want = "(" + ", ".join(f"{v:.6f}" for v in values) + ")"
        assert f"  {name}: {want}" in text and f"- {name}: `{want}`" in md, name
    end = next(i for i, ln in enumerate(text) if i and not ln.startswith("  "))
    note = text[1:end]  # the custom design's note, under its first line
    assert len(note) >= 3 and _greedy_at(note, 100)
    assert " ".join(ln.strip() for ln in note) == " ".join(a.report["custom_design"]["note"].split())
