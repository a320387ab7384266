"""Numbers as the project's reports print them: one rule for every report."""

from __future__ import annotations

from typing import Iterable

__all__ = ["complex_text", "complexes_text"]


def complex_text(z: complex) -> str:
    """``z`` to four decimals: ``+0.1234`` or ``+0.1234-0.0567i``.

    An imaginary part that rounds to zero at four decimals is left out (a real eigenvalue,
    or a pair that round-off split off the real axis), so no ``+0.0000i`` is printed.
    """
    z = complex(z)
    if abs(z.imag) < 5e-5:
        return f"{z.real:+.4f}"
    return f"{z.real:+.4f}{z.imag:+.4f}i"


def complexes_text(values: Iterable[complex]) -> str:
    """:func:`complex_text` of each value, comma-separated."""
    return ", ".join(complex_text(z) for z in values)
