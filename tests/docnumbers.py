"""Compare the text of a document with the text the code renders, numbers as numbers.

A document quotes numbers the code computes. The same computation on another machine (another
BLAS kernel, another libm) differs in the last bits, and a number printed to d digits then
differs by at most one unit of its last printed digit: the two roundings of two values a few
ulps apart land on either side of a rounding edge (0.04774345 prints 0.0477435 or 0.0477434).
So a number compares equal to its rendered twin when they differ by at most one unit of the
last digit that either prints, and the words around the numbers compare exactly.

That tolerance is right only for a well-conditioned quantity (one whose relative error is a
few ulps). A quantity that is not (round-off itself, a near-double root, an identification
that amplifies round-off by 1/h) must be printed as a bound or with the digits that survive
its conditioning; the comparison here then sees identical text, and a number that still
drifts by more than one unit fails, pointing at the print that needs fixing.

Integers (no decimal point and no exponent: equation numbers, counts, percentages rounded to
whole units) compare exactly: an integer printed from a rounded value that can sit on a
rounding edge must be printed with the tolerance its test states, not here.
"""

from __future__ import annotations

import re
from decimal import Decimal

__all__ = ["NumericText", "assert_same_numbers", "doc_block", "numbers_differ", "same_numbers"]

_NUMBER = re.compile(r"(?<![\w.])[-+−]?(?:\d+\.\d*|\.\d+|\d+)(?:[eE][-+]?\d+)?(?![\w])")


def doc_block(text: str, tag: str, doc: str = "the document") -> str:
    """The text of the ```text block after the marker ``<!-- TAG -->`` in a document (the
    numbers a test computes again); a missing marker fails the test, naming it and ``doc``."""
    m = re.search(rf"<!-- {re.escape(tag)} -->\n```text\n(.*?)\n```", text, re.S)
    assert m, f"no {tag} block in {doc}"
    return m.group(1)


def _is_real(token: str) -> bool:
    return "." in token or "e" in token.lower()


def _unit(token: str) -> Decimal:
    """One unit of the last printed digit of ``token`` (1e-7 for 0.0477435, 1e-16 for 5.6e-16)."""
    return Decimal(1).scaleb(Decimal(token.replace("−", "-")).as_tuple().exponent)


def _split(text: str) -> tuple[list[str], list[str]]:
    """The words between the numbers, and the numbers, of ``text``."""
    return _NUMBER.split(text), _NUMBER.findall(text)


def numbers_differ(a: str, b: str) -> bool:
    """True when the printed numbers ``a`` and ``b`` are not the same quantity to their digits.

    Reals: more than one unit of the coarser last digit apart; integers: not equal.
    """
    if _is_real(a) != _is_real(b):
        return True
    da, db = Decimal(a.replace("−", "-")), Decimal(b.replace("−", "-"))
    if not _is_real(a):
        return da != db
    return abs(da - db) > max(_unit(a), _unit(b))


def same_numbers(expected: str, actual: str) -> str | None:
    """None when the texts agree (words exactly, numbers within a unit of the last digit), else
    the first difference, described in one line."""
    words_e, nums_e = _split(expected)
    words_a, nums_a = _split(actual)
    for k, (we, wa) in enumerate(zip(words_e, words_a)):
        if we != wa:
            return f"words differ after number {k}: {we[:80]!r} vs {wa[:80]!r}"
    if len(nums_e) != len(nums_a):
        return f"{len(nums_e)} numbers vs {len(nums_a)}"
    for k, (ne, na) in enumerate(zip(nums_e, nums_a)):
        if numbers_differ(ne, na):
            return f"number {k} differs: {ne} vs {na} (context {words_e[k][-60:]!r})"
    return None


def assert_same_numbers(expected: str, actual: str, hint: str = "") -> None:
    """Raise AssertionError naming the first difference unless :func:`same_numbers` agrees."""
    diff = same_numbers(expected, actual)
    if diff is not None:
        raise AssertionError(diff + (f"; {hint}" if hint else ""))


class NumericText:
    """A document's text in which ``needle in text`` and ``text == other`` compare numbers as
    numbers (see the module docstring); whitespace runs compare as one space."""

    def __init__(self, text: str) -> None:
        self.text = " ".join(text.split())

    def __contains__(self, needle: str) -> bool:
        return self.find(needle) is not None

    def find(self, needle: str) -> str | None:
        """The passage of the text that quotes ``needle``, or None."""
        needle = " ".join(needle.split())
        words, nums = _split(needle)
        pattern = _NUMBER.pattern.join(re.escape(w) for w in words)
        for m in re.finditer(pattern, self.text):
            if same_numbers(needle, m.group(0)) is None:
                return m.group(0)
        return None

    def __eq__(self, other: object) -> bool:
        other_text = other.text if isinstance(other, NumericText) else other
        if not isinstance(other_text, str):
            return NotImplemented
        return same_numbers(" ".join(other_text.split()), self.text) is None

    def __repr__(self) -> str:
        return f"NumericText({self.text[:60]!r}...)"
