"""Numbers as the project's reports print them: one rule for every report."""

from __future__ import annotations

from typing import Iterable

__all__ = ["STATUS_NAMES", "a_or_an", "complex_text", "complexes_text", "float_text", "status_name"]

#: The FMI status values by number (fmi2Status and fmi3Status share 0 to 4; Pending is
#: FMI 2.0's only).
STATUS_NAMES: tuple[str, ...] = ("OK", "Warning", "Discard", "Error", "Fatal", "Pending")


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


def status_name(status: int, call: str = "fmi2") -> str:
    """The FMI name of a status, e.g. ``fmi2Discard`` for 2 after an ``fmi2...`` call
    (``fmi3Discard`` after an ``fmi3...`` one); a value outside the standard's as
    ``status 7 (not an FMI status)``."""
    prefix = call[:4] if call[:4] in ("fmi2", "fmi3") else "fmi2"
    known = isinstance(status, int) and 0 <= status < len(STATUS_NAMES) - (prefix == "fmi3")
    return f"{prefix}{STATUS_NAMES[status]}" if known else f"status {status!r} (not an FMI status)"


def float_text(value: float) -> str:
    """A number as Python writes a float (``1.3365853658536586``), whatever its type: never
    ``np.float64(...)``."""
    return repr(float(value))


def a_or_an(word: str) -> str:
    """``word`` with its indefinite article: ``an output``, ``a parameter``, ``an Integer``."""
    return f"{'an' if word[:1].lower() in 'aeiou' else 'a'} {word}"
