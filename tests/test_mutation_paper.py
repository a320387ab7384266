"""Oracles for the analysis of the paper's matrices (``harness.paper.analysis``) written against
the survivors of its mutation run (docs/mutation.md): controllability by Kalman's rank and by
the PBH test on systems whose reachable modes are known by construction, and the checks on a
user's target eigenvalues at their bounds.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from dronefly.harness.paper.analysis import (AnalysisInputError, UncontrollableError,
                                             coefficient_matching_gains, controllability,
                                             kalman_rank, lateral_system, modal_decomposition,
                                             validate_targets)
from dronefly.models.lateral_interface import CONTROL_NAMES

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
