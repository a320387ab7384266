"""The main job: open loop and the paper's gains, co-simulated, in one verdict table."""

from __future__ import annotations

from pathlib import Path

from dronefly.harness.cosim.run import cosimulate

__all__ = ["verdict_table"]


def verdict_table(out_dir: str | Path = "build/cosim") -> str:
    """Co-simulate open loop and Eq. (27) (Gauss-Seidel, 0.1 wing beat, 300 wing beats)."""
    rows = []
    for gains in ("open", "paper"):
        r = cosimulate(gains=gains, out_dir=out_dir)
        ev = ", ".join(f"{e.real:+.4f}" + (f"{e.imag:+.4f}i" if abs(e.imag) > 5e-5 else "")
                       for e in r.identification.eigenvalues)
        rows.append((gains, ev, r.verdict, str(r.csv), str(r.plot)))
    head = ("gains", "identified eigenvalues per wing beat", "verdict", "csv", "plot")
    widths = [max(len(x[i]) for x in [head, *rows]) for i in range(len(head))]
    line = lambda cells: "  ".join(c.ljust(w) for c, w in zip(cells, widths))  # noqa: E731
    return "\n".join([line(head), line(["-" * w for w in widths]), *(line(r) for r in rows)])
