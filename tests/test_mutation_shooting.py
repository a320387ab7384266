"""Independent oracles for models/shooting.py (Newton's chord method for a periodic orbit),
written for mutation testing (docs/mutation.md): affine period maps, whose fixed point numpy's
``solve`` gives and on which the chord method with the exact monodromy takes one step, and a
nonlinear map whose fixed point ``scipy.optimize.fsolve`` finds."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import fsolve

from dronefly.models.shooting import ShootingError, shooting

M = np.array([[0.5, 0.25], [-0.25, 0.5]])  # eigenvalues 0.5 +- 0.25i: a stable orbit
B = np.array([1.0, -2.0])
#: the fixed point of x -> M x + B, (I - M)^-1 B (numpy)
X_STAR = np.linalg.solve(np.eye(2) - M, B)


def affine(x):
    return M @ x + B


def test_affine_map_one_chord_step_reaches_the_fixed_point():
    """With the exact monodromy the first Newton step lands on (I - M)^-1 B (to rounding:
    a 2 x 2 solve of a well-conditioned system, 1e-15); the residuals are the largest
    |map(x) - x|, the first one by hand from x0 = 0: max |B| = 2."""
    x, res = shooting(affine, np.zeros(2), M, 1e-12, 5)
    np.testing.assert_allclose(x, X_STAR, rtol=0, atol=1e-14)
    assert len(res) == 2 and res[0] == 2.0 and res[1] < 1e-12


def test_residuals_are_over_the_scales():
    """With scales the residual is max |r / scales|: from x0 = 0, r = B = (1, -2), over
    (4, 0.25): 8 (exact in floats)."""
    x, res = shooting(affine, np.zeros(2), M, 1e-12, 5, scales=np.array([4.0, 0.25]))
    assert res[0] == 8.0
    np.testing.assert_allclose(x, X_STAR, rtol=0, atol=1e-14)


def test_a_residual_equal_to_the_tolerance_is_not_below_it():
    """The iteration stops when the residual is below ``tol``: a first residual of exactly 2
    with tol = 2 takes one more step (to the fixed point)."""
    x, res = shooting(affine, np.zeros(2), M, 2.0, 5)
    assert len(res) == 2 and res[0] == 2.0
    np.testing.assert_allclose(x, X_STAR, rtol=0, atol=1e-14)


def test_nonlinear_map_converges_with_the_chord_method():
    """x -> M x + B + 0.05 x^2 (componentwise), the chord method with the Jacobian at the
    start (the linear part M): converges linearly to the fixed point of scipy's fsolve
    (xtol 1e-14; the fixed point is O(1) and simple: 1e-12); each residual is smaller than
    the one before; ``max_iter`` one less than the steps it took fails with the residuals."""
    def f(x):
        return M @ x + B + 0.05 * x * x

    want = fsolve(lambda x: f(x) - x, X_STAR, xtol=1e-14)
    x, res = shooting(f, np.zeros(2), M, 1e-13, 100)
    np.testing.assert_allclose(x, want, rtol=0, atol=1e-12)
    assert res[-1] < 1e-13 and len(res) > 3
    assert all(b < a for a, b in zip(res, res[1:]))
    # exactly as many steps as it took passes, one fewer is refused
    shooting(f, np.zeros(2), M, 1e-13, len(res))
    with pytest.raises(ShootingError, match=f"after {len(res) - 1} steps") as info:
        shooting(f, np.zeros(2), M, 1e-13, len(res) - 1)
    assert f"{res[-2]:.3g}" in str(info.value)
