"""Figures of the quasi-steady model: the paper's Fig. 2 redrawn, and the linearity maps.

Needs matplotlib (the ``plot`` extra), imported when a figure is drawn.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from ...core.extras import pyplot
from ...models.quasisteady import FORCES, QuasiSteadyModel
from .beside_paper import (CONTROL_BOX_RAD, LATERAL_PAIRS, STATE_BOX, derivatives, linearity_scan,
                      pair_scan)

__all__ = ["plot_fig2", "plot_linearity_maps"]

_LATERAL_CONTROLS = ("delta_Phi_a", "delta_alpha_1a", "delta_alpha_2a")


def plot_fig2(model: QuasiSteadyModel, path: str | Path, extent: float = 2.0,
              points: int = 33) -> Path:
    """Y+, L+, N+ against each lateral control at ``points`` values out to ``extent`` times
    +/-0.4 rad, with the tangent at hover and the box of Sect. 3.6 (the paper's Fig. 2, from the
    model)."""
    plt = pyplot()

    scan = linearity_scan(model, _LATERAL_CONTROLS, ("Y", "L", "N"), extent=extent, points=points)
    d = derivatives(model, 1e-3, _LATERAL_CONTROLS)
    f0 = model.forces_vector()
    fig, axes = plt.subplots(1, 3, figsize=(12, 3.6), sharey=False)
    for ax, name in zip(axes, _LATERAL_CONTROLS):
        per = scan["inputs"][name]  # type: ignore[index]
        s = np.asarray(per["values"])
        for o, colour in zip("YLN", ("tab:blue", "tab:orange", "tab:green")):
            k = FORCES.index(o)
            ax.plot(s, per[o]["forces"], "o", ms=3, color=colour, label=f"{o}+ model")
            ax.plot(s, f0[k] + s * d[name][k], "-", lw=0.8, color=colour, label=f"{o}+ tangent")
        ax.axvspan(-CONTROL_BOX_RAD, CONTROL_BOX_RAD, color="0.92", zorder=0)
        ax.set_xlabel(f"{name} [rad]")
        ax.grid(True, lw=0.3)
    axes[0].set_ylabel("cycle-averaged force / moment (non-dimensional)")
    axes[0].legend(fontsize=7, ncol=2)
    fig.suptitle(f"quasi-steady model ({model.coefficients.name}): Fig. 2 of the paper redrawn; "
                 "grey: the +/-0.4 rad box of Sect. 3.6", fontsize=9)
    return _save(fig, path)


def plot_linearity_maps(model: QuasiSteadyModel, path: str | Path, extent: float = 2.0,
                        points: int = 17) -> Path:
    """Error of the linear Y+, L+, N+ over each pair of lateral states on ``points`` x
    ``points`` values out to ``extent`` times the box, the largest of the three outputs in per
    cent of its scale, with the 1, 5 and 10 % contours and the box."""
    plt = pyplot()

    fig, axes = plt.subplots(1, 3, figsize=(12, 3.8))
    for ax, pair in zip(axes, LATERAL_PAIRS):
        r = pair_scan(model, pair, "YLN", extent=extent, points=points)
        s = np.asarray(r["values"])
        err = np.max([np.asarray(r[o]["error_pct"]) for o in "YLN"], axis=0)  # type: ignore[index]
        mesh = ax.pcolormesh(s, s, err.T, shading="nearest", cmap="viridis")
        cs = ax.contour(s, s, err.T, levels=[1.0, 5.0, 10.0], colors="w", linewidths=0.8)
        ax.clabel(cs, fmt="%g %%", fontsize=7)
        b = STATE_BOX
        ax.plot([-b, b, b, -b, -b], [-b, -b, b, b, -b], "r-", lw=0.8)
        ax.set_xlabel(pair[0] + "+")
        ax.set_ylabel(pair[1] + "+")
        fig.colorbar(mesh, ax=ax, label="max error of Y+, L+, N+ [%]")
    fig.suptitle("quasi-steady model: error of the tangent at hover over pairs of the lateral "
                 "state (red: the box of Sect. 3.6)", fontsize=9)
    return _save(fig, path)


def _save(fig: "Any", path: str | Path) -> Path:
    """Lay out, write (110 dpi) and close ``fig``; the path written."""
    plt = pyplot()

    fig.tight_layout()
    out = Path(path)
    fig.savefig(out, dpi=110)
    plt.close(fig)
    return out
