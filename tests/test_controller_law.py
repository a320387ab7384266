"""The feedback law u = K x+ (dronefly.models.feedback), without any FMU."""

from __future__ import annotations

import math
import re

import numpy as np
import pytest
from numpy.testing import assert_allclose

from dronefly.models import feedback as L

from controller_common import ROOT, dimensional, random_gains
from shared_files import need_shared

PAPER = ROOT.parent / "shared" / "paper" / "zhang-sun-lateral-stabilization-control.md"

pytestmark = pytest.mark.numeric  # also run under a second BLAS kernel (.ci/run)


def test_default_gains_are_the_papers_eq27():
    """The default law is Eq. (27) as the paper prints it: delta_Phi_a = -0.3192 dv+ - 0.2879
    dp+ - 0.1969 dr+ - 0.0643 dgamma (u = K x+, so the row of delta_Phi_a holds the printed
    coefficients with their signs), read from the paper's text; no other control is fed back,
    and the paper's law is linear (no limit). The digits' precision is checked against the
    paper's own targets in test_analysis.py::test_eq27_recovered_from_the_papers_targets."""
    need_shared(PAPER, "the paper's text")
    text = PAPER.read_text(encoding="utf-8")
    eq = text[text.rindex("\\begin{align*}", 0, text.index("\\tag{27}")):text.index("\\tag{27}")]
    printed = {axis: float(c.replace(" ", "")) for c, axis in
               re.findall(r"([-+]\s*\d+\.\d+)\s*\\delta\s*(v|p|r|\\gamma)", eq)}
    assert list(printed) == ["v", "p", "r", "\\gamma"], eq
    K = np.array(L.default_gains())
    row = L.CONTROL_NAMES.index("delta_Phi_a")
    assert K.shape == (len(L.CONTROL_NAMES), len(L.STATE_NAMES))
    assert list(K[row]) == list(printed.values())  # the printed digits, exactly
    assert not np.delete(K, row, axis=0).any()
    assert L.FeedbackLaw(L.default_gains()).limit_enabled is False


def test_eq27_gains_defined_once_in_the_project():
    """The gains are numbers in exactly one source file: models/feedback.py.

    (Quoted digit strings, kept elsewhere to analyse the printed precision, are not numbers;
    they are checked against the definition below.)
    """
    hits = []
    for f in ROOT.rglob("*.py"):  # the package: the checkout without tests, docs, benchmarks
        rel = f.relative_to(ROOT)
        if rel.parts[0] in ("tests", "docs", "benchmarks", "build") or rel.parts[0][0] == ".":
            continue
        if re.search(r"(?<![\d.\"'])0\.3192\b(?![\"'])", f.read_text()):
            hits.append(rel.as_posix())
    assert hits == ["models/feedback.py"]


@pytest.mark.parametrize("K", [np.array(L.default_gains()), random_gains()],
                         ids=["eq27", "random"])
def test_law_equals_K_x_plus(K):
    rng = np.random.default_rng(7)
    law = L.FeedbackLaw(tuple(map(tuple, K.tolist())))
    law.validate()
    for xp in rng.normal(0.0, 0.3, (20, 4)):
        x = dimensional(xp)
        u, sat = law.evaluate(x)
        assert_allclose(u, K @ xp, rtol=1e-12, atol=1e-15)
        assert sat is False


def test_law_saturation_is_per_output_and_symmetric():
    K = ((1.0, 0.0, 0.0, 0.0), (0.0, 0.0, 0.0, -1.0), (0.0, 0.0, 0.0, 0.0))
    law = L.FeedbackLaw(K, u_max=0.2, limit_enabled=True)
    u, sat = law.evaluate(dimensional([0.5, 0.0, 0.0, 0.1]))
    assert u == pytest.approx((0.2, -0.1, 0.0), rel=1e-15) and sat is True
    u, sat = law.evaluate(dimensional([-0.1, 0.0, 0.0, 0.3]))
    assert u == pytest.approx((-0.1, -0.2, 0.0), rel=1e-15) and sat is True
    u, sat = law.evaluate(dimensional([0.15, 0.0, 0.0, -0.15]))
    assert u == pytest.approx((0.15, 0.15, 0.0), rel=1e-14) and sat is False
    u, sat = law.evaluate([0.0, 0.0, 0.0, 0.2])  # exactly at the limit: not limited
    assert u == (0.0, -0.2, 0.0) and sat is False


@pytest.mark.parametrize("changes, fragment", [
    ({"K": ((math.nan, 0, 0, 0), (0, 0, 0, 0), (0, 0, 0, 0))}, "K[1,1] = nan"),
    ({"K": ((0, 0, 0, 0), (0, 0, 0, 0), (0, 0, math.inf, 0))}, "K[3,3] = inf"),
    ({"n": 0.0}, "n = 0.0"),
    ({"U": -1.0}, "U = -1.0"),
    ({"u_max": 0.0}, "u_max = 0.0"),
    ({"u_max": math.nan, "limit_enabled": True}, "u_max = nan"),
])
def test_law_validation_names_the_value(changes, fragment):
    law = L.FeedbackLaw(**{"K": L.default_gains(), **changes})
    with pytest.raises(L.LawParameterError, match=re.escape(fragment)):
        law.validate()


def test_law_refuses_non_finite_state():
    with pytest.raises(L.LawParameterError, match=re.escape("delta_r = -inf is not finite")):
        L.FeedbackLaw(L.default_gains()).evaluate([0.0, 0.0, -math.inf, 0.0])
