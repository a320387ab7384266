"""The reproduction rows against the paper, by invariants (no snapshot of our own output).

Every mismatch has a reason and a note; the rows classified "error in print" are exactly
``values.ERRATA``, and each correction is recomputed here with numpy; every "rounding" row is
confirmed by an oracle written here (numpy from the printed inputs, its own first-order spread).
"""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from dronefly.harness.paper import printed as pv
from dronefly.harness.paper.reproduction import reproduction_table
from dronefly.models import lateral_dynamics
from dronefly.models import lateral_interface

pytestmark = pytest.mark.numeric  # also run under a second BLAS kernel (.ci/run)

ROWS = {(r.source, r.quantity): r for r in reproduction_table()}

REASONS = {"convention", "rounding", "error in print"}


@pytest.mark.parametrize("key", list(ROWS), ids=[f"{s} {q}" for s, q in ROWS])
def test_row(key: tuple[str, str]) -> None:
    """One printed number: a match is within half a unit of its last digit; a mismatch has a
    reason and a note, and a "rounding" mismatch lies inside the interval obtained by moving
    every printed input by half a unit (first order), widened by the print's own rounding."""
    r = ROWS[key]
    source = f"{r.source} {r.quantity}: printed {r.printed}"
    off = abs(r.computed - float(r.printed))
    assert r.match == (off <= r.tolerance + 1e-12), source
    if r.match:
        assert r.reason == "", source
        return
    assert r.reason in REASONS and r.note.endswith(".") and len(r.note) > 40, source
    if r.reason == "rounding":
        lo, hi = r.interval
        assert lo - r.tolerance <= float(r.printed) <= hi + r.tolerance, source
    if r.reason == "error in print":
        assert key in pv.ERRATA, source


def test_errors_in_print_are_exactly_the_errata_table() -> None:
    assert {k for k, r in ROWS.items() if r.reason == "error in print"} == set(pv.ERRATA)
    for key, (printed, corrected, why) in pv.ERRATA.items():
        r = ROWS[key]
        assert r.printed == printed and why
        lo, hi = r.interval  # the printed value is outside what rounding allows, the corrected in
        tol = pv.half_unit(corrected)
        assert not lo - r.tolerance <= float(printed) <= hi + r.tolerance, key
        assert lo - tol <= float(corrected) <= hi + tol, key


def _char_poly(A: np.ndarray) -> np.ndarray:
    """lambda^4 + b lambda^3 + c lambda^2 + d lambda + e, by numpy (not by the analysis code)."""
    return np.real(np.poly(A))


def test_erratum_26d_sign_of_e() -> None:
    """e = det(A1') at k = 0 = det(A1): negative, since exactly one eigenvalue is positive."""
    A1 = np.array(pv.EQ12_A1, dtype=float)
    e = _char_poly(A1)[4]
    assert e == pytest.approx(np.linalg.det(A1), rel=1e-12)
    assert e < 0 and np.sum(np.linalg.eigvals(A1).real > 0) == 1
    printed, corrected, _ = pv.ERRATA[("Eq. (26d)", "e: constant")]
    assert abs(e - float(corrected)) <= pv.half_unit(corrected)
    assert np.sign(float(printed)) != np.sign(e)


def test_erratum_26c_exponent_of_d_k4() -> None:
    """d's k4 coefficient = dd/dk4, by finite differences of numpy's characteristic polynomial
    of A1 + b k with Eq. (24)'s printed b; it equals c's k2 coefficient (dgamma' = dp+)."""
    A1 = np.array(pv.EQ12_A1, dtype=float)
    b = np.array([float(t) for t in pv.EQ24_B_COLUMN])

    def coeff(row: int, j: int) -> float:
        k = np.zeros(4)
        k[j] = 1e-3
        return (_char_poly(A1 + np.outer(b, k))[row] - _char_poly(A1 - np.outer(b, k))[row]) / 2e-3

    d_k4, c_k2 = coeff(3, 3), coeff(2, 1)
    printed, corrected, _ = pv.ERRATA[("Eq. (26c)", "d: coefficient of k4")]
    assert d_k4 == pytest.approx(c_k2, rel=1e-9)
    assert d_k4 == pytest.approx(float(corrected), abs=pv.half_unit(corrected))
    assert d_k4 == pytest.approx(float(pv.EQ26["c"][2]), abs=pv.half_unit(pv.EQ26["c"][2]))
    assert abs(d_k4 - float(printed)) > 10 * pv.half_unit(printed)


def test_erratum_31_sign_of_the_oscillatory_pair() -> None:
    """Eq. (31) against Eq. (32), from the Sect. 3.5 A, B with numpy only.

    With v the eigenvector of sigma + i omega and any complex scale z, the real basis
    [Re(z v), Im(z v)] gives the block [[sigma, +omega], [-omega, sigma]], and the rows 1-2 of
    B_n satisfy B_n(1,j) - i B_n(2,j) = (2/z) c_j, c_j the v-coordinate of column j of B. The
    other orientation [Re(z v), -Im(z v)] gives [[sigma, -omega], [omega, sigma]] (as Eq. 31 is
    printed) and B_n(1,j) + i B_n(2,j) = (2/z) c_j. Eq. (32) fits only the first.
    """
    A, B = (np.array(t, dtype=float) for t in (pv.SECT35_A, pv.SECT35_B))
    w, V = np.linalg.eig(A)
    i = int(np.argmax(w.imag))
    omega = w[i].imag
    c = (np.linalg.inv(V) @ B)[i]
    Bn = np.array(pv.EQ32_B_N, dtype=float)

    def misfit(z: np.ndarray) -> float:  # relative residual of z = (2/zeta) c, best zeta
        return float(np.linalg.norm(z - np.vdot(c, z) / np.vdot(c, c) * c) / np.linalg.norm(z))

    plus, minus = misfit(Bn[0] - 1j * Bn[1]), misfit(Bn[0] + 1j * Bn[1])
    assert plus < 1e-3 < 0.1 < minus, (plus, minus)
    # the similarity transform of that orientation
    others = [j for j in range(4) if abs(w[j].imag) == 0.0]
    M = np.column_stack([V[:, i].real, V[:, i].imag, *(V[:, j].real for j in others)])
    A_nn = np.linalg.solve(M, A @ M)
    assert A_nn[0, 1] == pytest.approx(omega, rel=1e-9) and A_nn[1, 0] == pytest.approx(-omega, rel=1e-9)
    # |omega| moves by at most `spread` when each rounded entry of A moves by half a unit (first order)
    h = pv.half_unit(pv.SECT35_A[0][0])  # printed to 4 decimals
    spread = 0.0
    for r, col in itertools.product(range(4), range(4)):
        if (r, col) not in pv.LONGITUDINAL_STRUCTURAL["A"]:
            d = np.zeros((4, 4))
            d[r, col] = h
            spread += abs(np.linalg.eigvals(A + d).imag.max() - np.linalg.eigvals(A - d).imag.max()) / 2
    for key, want in ((("Eq. (31)", "A_nn(1,2)"), omega), (("Eq. (31)", "A_nn(2,1)"), -omega)):
        printed, corrected, _ = pv.ERRATA[key]
        assert abs(float(corrected) - want) <= spread + pv.half_unit(corrected), key
        assert abs(float(printed) - want) > 1.9 * omega, key


# Independent oracle of the "rounding" rows: every quantity recomputed here with numpy from the
# printed inputs (Eq. 12, Sect. 2.1, Table 1, Table 2; Sect. 3.5), and its first-order worst-case
# spread under half a unit of each input's last digit, without the reproduction module's code.

def _eig_sorted(A: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    w, V = np.linalg.eig(A)
    order = np.lexsort((-w.imag, -w.real))
    return w[order], V[:, order]


def _modal_B(A: np.ndarray, B: np.ndarray, order: tuple[int, ...], signs: tuple[int, ...]) -> np.ndarray:
    """Eq. (14): unit eigenvectors, real ones signed by their largest component, a pair as
    2 Re v, 2 Im v with v's largest component real and positive; returns M^-1 B."""
    w, V = _eig_sorted(A)
    cols, s, k = [], iter(signs), 0
    while k < len(order):
        v = V[:, order[k]] / np.linalg.norm(V[:, order[k]])
        big = v[np.argmax(np.abs(v))]
        if w[order[k]].imag != 0.0:
            v = v * abs(big) / big
            cols += [2 * v.real, 2 * v.imag]
            k += 2
        else:
            cols.append(v.real * np.sign(big.real) * next(s))
            k += 1
    return np.linalg.solve(np.column_stack(cols), B)


def _lateral_inputs() -> dict[str, tuple[float, float]]:
    out = {f"A{i}{j}": (pv.EQ12_A1[i][j], 0.5 * 10.0 ** -pv.EQ12_DECIMALS)
           for i in range(4) for j in range(4) if (i, j) not in pv.EQ12_STRUCTURAL}
    out |= {k: (lateral_interface.INERTIAS_SECT21[k], 0.5 * 10.0 ** -d) for k, d in pv.SECT21_DECIMALS.items()}
    out |= {k: (v, 0.5 * 10.0 ** -pv.TABLE1_DECIMALS) for k, v in lateral_dynamics.CONTROL_DERIVATIVES_TABLE1.items()}
    return out | {k: (float(t), pv.half_unit(t)) for k, t in pv.TABLE2.items() if k != "lambda1"}


def _lateral_quantities(x: dict[str, float]) -> dict[tuple[str, str], float]:
    A1 = np.array(pv.EQ12_A1, dtype=float)
    for i, j in itertools.product(range(4), range(4)):
        A1[i, j] = x.get(f"A{i}{j}", A1[i, j])
    inertias = {k: x[k] for k in pv.SECT21_DECIMALS} | {"g_plus": A1[0, 3]}
    p = lateral_dynamics.LateralParameters(**inertias, **lateral_dynamics.derive_stability_derivatives(A1, inertias),
                                **{k: x[k] for k in lateral_dynamics.CONTROL_DERIVATIVES_TABLE1})
    A, B = lateral_dynamics.system_matrices(p)
    w, V = _eig_sorted(A)
    b = B[:, 0]
    c0 = np.poly(A)[1:]
    G = np.column_stack([np.poly(A + np.outer(b, e))[1:] - c0 for e in np.eye(4)])  # affine in k
    t = [0.0, complex(x["lambda23_re"], x["lambda23_im"]), complex(x["lambda23_re"], -x["lambda23_im"]),
         x["lambda4"]]
    k = np.linalg.solve(G, np.real(np.poly(t))[1:] - c0)
    q = {("Table 3", "|dp+| mode 2"): abs(V[1, 1] / V[3, 1]),
         ("Eq. (19)", "A_lnn(2,2)"): w[1].real, ("Eq. (19)", "A_lnn(3,3)"): w[1].real,
         ("Eq. (19)", "A_lnn(4,4)"): w[3].real}
    Bn = _modal_B(A, B, (0, 1, 2, 3), (-1, 1))
    q |= {("Eq. (20)", f"B_ln({i + 1},{j + 1}) [{lateral_interface.CONTROL_NAMES[j]}]"): Bn[i, j]
          for i in range(4) for j in range(3)}
    q |= {("Eq. (24)", f"b({i + 1}) [B1 column of delta_Phi_a]"): b[i] for i in range(4)}
    for r, name in enumerate("bcde"):
        q |= {(f"Eq. (26{'abcd'[r]})", f"{name}: coefficient of k{j + 1}"): G[r, j] for j in range(4)}
    return q | {("Eq. (27)", f"k{j + 1} (model B1, Table 2 targets)"): k[j] for j in range(4)}


def _longitudinal_inputs() -> dict[str, tuple[float, float]]:
    return {f"{m}{i}{j}": (float(tab[i][j]), pv.half_unit(tab[i][j], 4))
            for m, tab in (("A", pv.SECT35_A), ("B", pv.SECT35_B)) for i in range(4) for j in range(4)
            if (i, j) not in pv.LONGITUDINAL_STRUCTURAL[m]}


def _longitudinal_quantities(x: dict[str, float]) -> dict[tuple[str, str], float]:
    A, B = (np.array(t, dtype=float) for t in (pv.SECT35_A, pv.SECT35_B))
    for i, j in itertools.product(range(4), range(4)):
        A[i, j], B[i, j] = x.get(f"A{i}{j}", A[i, j]), x.get(f"B{i}{j}", B[i, j])
    w, _ = _eig_sorted(A)
    Bn = _modal_B(A, B, (0, 1, 3, 2), (1, 1))
    q = {("Eq. (31)", "A_nn(3,3)"): w[3].real, ("Eq. (31)", "A_nn(4,4)"): w[2].real,
         ("Eq. (31)", "eigenvalue sigma (unstable pair)"): w[0].real,
         ("Eq. (31)", "eigenvalue omega (unstable pair, +/-)"): w[0].imag,
         ("Eq. (31)", "eigenvalue fast subsidence"): w[3].real,
         ("Eq. (31)", "eigenvalue slow subsidence"): w[2].real}
    return q | {("Eq. (32)", f"B_n({i + 1},{j + 1}) [{pv.LONGITUDINAL_CONTROLS[j]}]"): Bn[i, j]
                for i in range(4) for j in range(4)}


def _with_spread(quantities, inputs) -> dict[tuple[str, str], tuple[float, float]]:
    x0 = {k: v for k, (v, _) in inputs.items()}
    f0 = quantities(x0)
    spread = dict.fromkeys(f0, 0.0)
    for name, (v, h) in inputs.items():
        up, dn = quantities(x0 | {name: v + h}), quantities(x0 | {name: v - h})
        for key in f0:
            spread[key] += abs(up[key] - dn[key]) / 2
    return {key: (f0[key], spread[key]) for key in f0}


def test_rounding_rows_by_an_independent_oracle() -> None:
    """Every "rounding" row: the oracle's value equals the row's computed value, and the printed
    value lies within the oracle's input-rounding spread plus the print's own rounding."""
    oracle = (_with_spread(_lateral_quantities, _lateral_inputs())
              | _with_spread(_longitudinal_quantities, _longitudinal_inputs()))
    rounding = {k: r for k, r in ROWS.items() if r.reason == "rounding"}
    assert rounding and set(rounding) <= set(oracle), set(rounding) - set(oracle)
    for key, r in rounding.items():
        value, spread = oracle[key]
        assert value == pytest.approx(r.computed, rel=1e-9, abs=1e-12), key
        assert abs(float(r.printed) - value) <= spread + r.tolerance, (key, r.printed, value, spread)
        assert abs(float(r.printed) - value) > r.tolerance, key  # really a mismatch
