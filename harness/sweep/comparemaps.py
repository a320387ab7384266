"""Maps of a ``dronefly sweep --compare``: the linearisation error beside the in-box map.

One PNG per grid slice, ``compare_X_Y.png``, two panels over the same initial disturbances:
left, the reference system's map (peak over the run of max(|x_i|/bound_i, |u|/0.4 rad), as
``map_X_Y.png``); right, the largest lateral linearisation error (peak |x_compared -
x_reference| / bound, max over the four lateral states) with contours at 5 % and 10 %. The
dashed rectangle is the Sect. 3.6 box.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from ...core.extras import optional
from ...core.files import atomic_path
from .cases import AXES, STATE_BOUNDS_SECT36

__all__ = ["write_compare_maps"]

_LABEL = {"dv": "dv+ = dv/U", "dp": "dp+ = dp t_w", "dr": "dr+ = dr t_w",
          "dgamma": "dgamma [rad]"}


def _grid(rs: list[dict[str, str]], sx: str, sy: str, column: str) -> tuple:
    xs = sorted({float(r[f"x0_{sx}"]) for r in rs})
    ys = sorted({float(r[f"x0_{sy}"]) for r in rs})
    Z = np.full((len(ys), len(xs)), np.nan)
    for r in rs:
        v = r.get(column, "")
        Z[ys.index(float(r[f"x0_{sy}"])), xs.index(float(r[f"x0_{sx}"]))] = (
            float(v) if v else math.nan)
    return xs, ys, Z


def _box(ax: Any, sx: str, sy: str) -> None:
    Rectangle = optional("matplotlib.patches", "Rectangle")

    bx, by = (STATE_BOUNDS_SECT36[AXES.index(a)] for a in (sx, sy))
    ax.add_patch(Rectangle((-bx, -by), 2 * bx, 2 * by, fill=False, ls="--", lw=1.2, ec="k"))


def write_compare_maps(rows: Sequence[dict[str, str]], out_dir: str | Path) -> list[Path]:
    """``compare_X_Y.png`` per grid slice of the first gain set and step (see module text)."""
    LogNorm = optional("matplotlib.colors", "LogNorm")
    Figure = optional("matplotlib.figure", "Figure")

    grid = [r for r in rows if r["family"] == "grid" and r.get("err_lateral")]
    if not grid:
        return []
    g0, h0 = grid[0]["gains"], grid[0]["step_wb"]
    grid = [r for r in grid if r["gains"] == g0 and r["step_wb"] == h0]
    written = []
    for label in dict.fromkeys(r["label"] for r in grid):
        sx, sy = label.split(":")
        rs = [r for r in grid if r["label"] == label]
        fig = Figure(figsize=(10.5, 4.4), dpi=110, layout="constrained")
        left, right = fig.subplots(1, 2, sharex=True, sharey=True)
        xs, ys, P = _grid(rs, sx, sy, "peak")
        m1 = left.pcolormesh(xs, ys, P, cmap="RdYlGn_r", vmin=0.0, vmax=2.0, shading="nearest")
        if np.nanmin(P) < 1.0 < np.nanmax(P):
            left.contour(xs, ys, P, levels=[1.0], colors="k", linewidths=1.5)
        fig.colorbar(m1, ax=left, shrink=0.85, extend="max").set_label(
            "reference: peak of max(|x_i|/bound_i, |u|/0.4)")
        left.set_title("linear loop: stays within the bounds (peak < 1)?", fontsize=9)
        xs, ys, E = _grid(rs, sx, sy, "err_lateral")
        m2 = right.pcolormesh(xs, ys, np.clip(E, 1e-4, None), cmap="magma_r",
                              norm=LogNorm(1e-3, 3.0), shading="nearest")
        if np.nanmin(E) < 0.10 < np.nanmax(E) or np.nanmin(E) < 0.05 < np.nanmax(E):
            cs = right.contour(xs, ys, E, levels=[0.05, 0.10], colors=["#1f78b4", "k"],
                               linewidths=1.5)
            right.clabel(cs, fmt={0.05: "5 %", 0.10: "10 %"}, fontsize=8)
        fig.colorbar(m2, ax=right, shrink=0.85, extend="both").set_label(
            "peak |x_nonlinear - x_linear| / bound (lateral, max)")
        right.set_title("linearisation error (contours 5 %, 10 %)", fontsize=9)
        for ax in (left, right):
            _box(ax, sx, sy)
            ax.set_xlabel(_LABEL[sx])
        left.set_ylabel(_LABEL[sy])
        fig.suptitle(f"Slice {sx} x {sy} (others 0), {g0} gains, step {float(h0):g} wing beats, "
                     f"{float(rs[0]['stop_wb']):g} wing beats; dashed: the Sect. 3.6 box",
                     fontsize=10)
        path = Path(out_dir) / f"compare_{sx}_{sy}.png"
        with atomic_path(path) as tmp:
            fig.savefig(tmp, format="png")
        written.append(path)
    return written
