"""The doc comparison of tests/docnumbers.py: numbers within a unit of their last digit, words
and integers exactly."""

import pytest

from docnumbers import NumericText, numbers_differ, same_numbers

pytestmark = pytest.mark.numeric  # also run under a second BLAS kernel (.ci/run)


@pytest.mark.parametrize("a, b, differ", [
    ("0.0477435", "0.0477434", False),  # a rounding edge: one unit of the last digit
    ("0.0477435", "0.0477437", True),   # two units: not the same value to its digits
    ("5.6e-16", "1.4e-15", True),       # round-off printed as a number: must be a bound
    ("1.0e-18", "-1.0e-18", True),
    ("-0.0000", "0.0000", False),
    ("0.12", "0.1201", False),          # the coarser print decides the unit
    ("43", "44", True),                 # integers exactly
    ("43", "43.0", True),               # an integer is not a real
])
def test_numbers(a, b, differ):
    assert numbers_differ(a, b) is differ


def test_texts():
    assert same_numbers("rate -0.00888 per wb, Eq. (27)", "rate -0.00889 per wb, Eq. (27)") is None
    assert "words differ" in same_numbers("rate -0.00888 per wb", "rate -0.00888 per wing beat")
    assert "differs: 27 vs 26" in same_numbers("Eq. (27)", "Eq. (26)")
    assert "words differ" in same_numbers("a 1.0 b 2.0", "a 1.0 b")
    text = NumericText("The margin is 36.6 ms\n(6.0 wing beats) with a continuous delay.")
    assert "margin is 36.7 ms (6.0 wing beats)" in text
    assert "margin is 36.8 ms (6.0 wing beats)" not in text
    assert "margin is 36.6 ms (6 wing beats)" not in text
    assert NumericText("a 0.31\nb") == "a 0.32 b" and NumericText("a 0.31 b") != "a 0.33 b"
