"""One printed number of the paper against its computed value, and how numbers are shown.

Shared by the reproduction (:mod:`.reproduction`), its notes (:mod:`.notes`) and its
renderings (:mod:`.report`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Iterable, Sequence

import numpy as np

__all__ = ["NOISE", "Row", "format_bound", "format_number", "format_vector", "markdown_table",
           "rounds_to", "summary"]

#: Computed values below this magnitude are floating-point noise of structurally zero entries
#: (their last bits differ between BLAS builds): shown as 0.
NOISE = 1e-12


def format_number(x: float, spec: str = ".6g") -> str:
    """``x`` formatted with ``spec``; noise (|x| < :data:`NOISE`) shown as 0, without a sign."""
    return format(0.0 if abs(x) < NOISE else float(x), spec)


def format_bound(x: float, bound: float = NOISE) -> str:
    """``x`` as the bound it is known to: ``"< 1e-12"`` for round-off (``|x| < bound``),
    whose digits differ between machines, else ``x`` to two digits.

    For quantities that are zero in exact arithmetic (a structural zero, the disagreement of
    two exact methods): their computed value is round-off, a few ulps of the O(1) entries
    it is computed from, and only its size below ``bound`` is the same on every machine.
    """
    return f"< {bound:.0e}" if abs(x) < bound else f"{x:.1e}"


def markdown_table(header: Sequence[str], rows: Iterable[Sequence[str]]) -> list[str]:
    """A Markdown table as the documents print it: ``| a | b |`` lines, the header first,
    then ``|---|---|``, then one line per row (cells as given: escape a ``|`` in them)."""
    def line(cells: Sequence[str]) -> str:
        return "| " + " | ".join(cells) + " |"

    return [line(header), "|" + "---|" * len(header), *(line(r) for r in rows)]


def format_vector(x: np.ndarray, d: int = 4) -> str:
    """``(x1, x2, ...)`` with ``d`` decimals."""
    return "(" + ", ".join(format_number(v, f".{d}f") for v in np.ravel(x)) + ")"


@dataclass(frozen=True)
class Row:
    """One printed number against its computed value (see the module docstring)."""

    source: str
    quantity: str
    printed: str
    computed: float
    tolerance: float
    match: bool
    reason: str
    note: str
    interval: tuple[float, float] | None = None

    def as_dict(self) -> dict:
        """JSON-ready row: source, quantity, printed, computed, match, note (+ extras)."""
        return {"source": self.source, "quantity": self.quantity, "printed": float(self.printed),
                "printed_text": self.printed, "computed": self.computed, "match": self.match,
                "tolerance": self.tolerance, "reason": self.reason, "note": self.note,
                "input_rounding_interval": list(self.interval) if self.interval else None}


def rounds_to(computed: float, printed: str, half_unit: float) -> bool:
    """Whether ``computed`` is ``printed`` to its digits: |computed - printed| <= ``half_unit``
    (half a unit of the last printed digit), with 1e-12 of slack for a value on the decimal
    edge, whose float difference exceeds the half unit by round-off (0.07855 against "0.0786":
    5.000000000000004e-05 > 5e-05)."""
    return abs(computed - float(printed)) <= half_unit + 1e-12


def summary(rows: Sequence[Row]) -> dict:
    """Counts of rows, matches and mismatches by reason."""
    bad = [r for r in rows if not r.match]
    reasons: dict[str, int] = {}
    for r in bad:
        reasons[r.reason] = reasons.get(r.reason, 0) + 1
    return {"rows": len(rows), "matches": len(rows) - len(bad), "mismatches": len(bad),
            "mismatches_by_reason": reasons}
