"""PNG plot of a co-simulation: the four states and the controls against wing beats."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

__all__ = ["plot_loop"]

_LABELS = {
    "delta_v": ("delta v", "m/s", 1.0),
    "delta_p": ("delta p", "deg/s", 180 / np.pi),
    "delta_r": ("delta r", "deg/s", 180 / np.pi),
    "delta_gamma": ("delta gamma", "deg", 180 / np.pi),
}


def plot_loop(result: Any, path: Path) -> bool:
    """Write the plot; returns False when matplotlib (extra ``plot``) is not installed.

    Closed loop solid, open loop (if recorded) dashed; the axes are scaled to the
    closed loop, so the diverging open loop leaves the frame where it grows past it.
    """
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return False
    run = result.run
    n = 1.0 / (run.time[1] - run.time[0]) * result.step_wingbeats if len(run.time) > 1 else 1.0
    wb = run.time * n
    open_run = result.extra.get("open_loop")
    fig, axes = plt.subplots(5, 1, figsize=(8, 11), sharex=True, constrained_layout=True)
    for ax, name in zip(axes, _LABELS):
        label, unit, f = _LABELS[name]
        y = run.column(name) * f
        ax.plot(wb, y, color="C0", label="closed loop")
        if open_run is not None:
            ax.plot(open_run.time * n, open_run.column(name) * f, "--", color="C3",
                    label="open loop")
        lim = max(float(np.max(np.abs(y))), 1e-12) * 1.3
        ax.set_ylim(-lim, lim)
        ax.set_ylabel(f"{label} [{unit}]")
        ax.grid(True, alpha=0.3)
    for j, name in enumerate(run.names[4:]):
        axes[4].plot(wb, run.column(name) * 180 / np.pi, color=f"C{j}", label=name)
    axes[4].set_ylabel("controls [deg]")
    axes[4].grid(True, alpha=0.3)
    axes[4].legend(loc="upper right", fontsize=8)
    axes[0].legend(loc="upper right", fontsize=8)
    axes[4].set_xlabel("time [wing beats]")
    fig.suptitle(f"{result.verdict}: dominant rate {result.identification.dominant_growth_rate:+.4f}"
                 f" per wing beat ({result.master}, step {result.step_wingbeats:g} wing beats)")
    fig.savefig(path, dpi=90, format="png")
    plt.close(fig)
    return True
