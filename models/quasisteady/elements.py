"""The blade elements of a wing: the Gauss-Jacobi nodes of its beta planform (Ellington 1984),
each element's span position, chord and quadrature weight, the roots of both wings and the
added mass's span sums (:func:`blade_elements`)."""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from .wing import Array, Terms, WingGeometry

__all__ = ["BladeElements", "blade_elements", "gauss_jacobi"]


def gauss_jacobi(n: int, a: float, b: float) -> tuple[Array, Array]:
    """Nodes and weights of the n-point Gauss-Jacobi rule on [-1, 1], weight
    (1 - x)^a (1 + x)^b (a, b > -1): the eigenvalues of the Jacobi matrix of the orthonormal
    Jacobi polynomials and the squared first components of its eigenvectors (Golub & Welsch
    1969), in numpy alone (no scipy: the 6-DOF FMU's quasi-steady aerodynamics run on this
    module; tests/test_aero.py checks it against ``scipy.special.roots_jacobi``)."""
    k = np.arange(n, dtype=float)
    s = 2.0 * k + a + b
    diag = np.where(k == 0, (b - a) / (a + b + 2.0),
                    (b * b - a * a) / np.where(k == 0, 1.0, s * (s + 2.0)))
    k1, s1 = k[1:], s[1:]
    off = np.sqrt(4.0 * k1 * (k1 + a) * (k1 + b) * (k1 + a + b)
                  / (s1 * s1 * (s1 + 1.0) * (s1 - 1.0)))
    x, v = np.linalg.eigh(np.diag(diag) + np.diag(off, 1) + np.diag(off, -1))
    mu0 = 2.0 ** (a + b + 1.0) * math.gamma(a + 1.0) * math.gamma(b + 1.0) / math.gamma(a + b + 2.0)
    return x, mu0 * v[0] ** 2


class BladeElements(NamedTuple):
    """The span quadrature of one wing (both wings share it, the left mirrored in y).

    Attributes
    ----------
    r : array, shape (n_span,)
        Each element's distance from the root [mean chords c].
    cw : array, shape (n_span,)
        Its quadrature weight: the integral of f(r) c(r) dr over the span is sum f(r_i) cw_i
        [c^2].
    chord : array, shape (n_span,)
        Its chord c(r) [c].
    roots : array, shape (2, 3)
        The roots (x, y, z) of the left and right wing from the centre of mass [c].
    added_mass_sums : tuple of 5 floats
        The sums over the span of m_a r^j (j = 0, 1, 2) and of m_a mid r^j (j = 0, 1): m_a =
        rho (pi/4) c^2 dr the element's added mass and mid its mid-chord's lever arm over the
        pitch rate, non-dimensional as the forces (all 0 without the added mass term).
    """

    r: Array
    cw: Array
    chord: Array
    roots: Array
    added_mass_sums: tuple[float, ...]


def blade_elements(geometry: WingGeometry, terms: Terms, n_span: int) -> BladeElements:
    """The ``n_span`` blade elements of the planform of ``geometry`` (with the added mass's sums
    where ``terms`` has it)."""
    g = geometry
    # nodes x in [-1, 1] with weight (1-x)^(q-1) (1+x)^(p-1); r_hat = (1+x)/2
    x, w = gauss_jacobi(n_span, g.q - 1.0, g.p - 1.0)
    r_hat = 0.5 * (1.0 + x)
    # chord c(r) = C r^(p-1) (1-r)^(q-1) with the integral of c over the span = S_wing
    beta = math.gamma(g.p) * math.gamma(g.q) / math.gamma(g.p + g.q)
    C = g.S_wing / (g.R * beta)
    # integral of f(r) c(r) dr over [0, R] = sum f(r_i) * cw_i
    r = g.R * r_hat
    cw = C * g.R * w * 0.5 ** (g.p + g.q - 1.0)
    chord = C * r_hat ** (g.p - 1.0) * (1.0 - r_hat) ** (g.q - 1.0)
    roots = np.array([[g.hinge[0], -g.hinge[1], g.hinge[2]], list(g.hinge)])
    # the added mass m_a = rho (pi/4) c^2 dr of each element and its mid-chord's lever
    # arm over the pitch rate: sums of m_a r^j, j = 0, 1, 2, and of m_a mid r^j, j = 0, 1
    m_a = 0.5 * math.pi * g.k * chord * cw if terms.added_mass else 0.0 * r
    mid = g.k * (0.5 - g.x0_hat) * chord
    sums = tuple(float(np.sum(m_a * r ** j)) for j in range(3)) + \
        tuple(float(np.sum(m_a * mid * r ** j)) for j in range(2))
    return BladeElements(r, cw, chord, roots, sums)
