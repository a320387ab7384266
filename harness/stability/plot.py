"""PNG plot of a co-simulation: the four states and the controls against wing beats."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from ...core.extras import MissingExtra, pyplot
from ...models.lateral_interface import CONTROL_NAMES, STATE_BOUNDS_SECT36, STATE_NAMES

__all__ = ["plot_loop"]

_LABELS = {
    "delta_v": ("delta v", "m/s", 1.0),
    "delta_p": ("delta p", "deg/s", 180 / np.pi),
    "delta_r": ("delta r", "deg/s", 180 / np.pi),
    "delta_gamma": ("delta gamma", "deg", 180 / np.pi),
}
#: how a state of another plant is drawn, by its SI unit: (display unit, factor)
_DISPLAY = {"rad": ("deg", 180 / np.pi), "rad/s": ("deg/s", 180 / np.pi)}


def _label(name: str, unit: str) -> tuple[str, str, float]:
    if name in _LABELS:
        return _LABELS[name]
    shown, f = _DISPLAY.get(unit, (unit, 1.0))
    return name.replace("_", " "), shown, f


def plot_loop(result: Any, path: Path) -> bool:
    """Write the plot; returns False when matplotlib (extra ``plot``) is not installed.

    The states and the controls are the run's columns of those names (the controls are
    ``result.extra["controls"]``, the plant's inputs; default the lateral plant's); other
    recorded columns (``plant.NAME``, ``controller.NAME``) are in the CSV, not drawn.

    The run solid (labelled open loop when K = 0), the open loop for comparison (if
    recorded) dashed. The time where the run leaves the Sect. 3.6 validity box of the linear
    model (|dv+|, |dp+|, |dr+| <= 0.15, |dgamma| <= 0.22) is marked and what follows is
    shaded; each axis shows at most three times its box, so a diverging linear solution
    (which the real insect never reaches) does not hide the part where the model holds.
    """
    try:
        plt = pyplot()
    except MissingExtra:
        return False
    run = result.run
    n = 1.0 / (run.time[1] - run.time[0]) * result.step_wingbeats if len(run.time) > 1 else 1.0
    wb = run.time * n
    open_run = result.extra.get("open_loop")
    states = list(result.extra.get("states", STATE_NAMES))
    units = list(result.extra.get("state_units", ("",) * len(states)))
    scale = np.asarray(result.extra.get("scale", (1.0,) * len(states)))
    lateral = states == list(STATE_NAMES)  # the Sect. 3.6 box is the lateral plant's
    t_exit = None
    if lateral:
        xplus = np.column_stack([run.column(s) for s in states]) / scale
        outside = np.any(np.abs(xplus) > np.asarray(STATE_BOUNDS_SECT36), axis=1)
        t_exit = float(wb[int(np.argmax(outside))]) if outside.any() else None
    closed = bool(np.any(result.gains))
    ns = len(states)
    fig, axes = plt.subplots(ns + 1, 1, figsize=(8, 2.2 * (ns + 1)), sharex=True,
                             constrained_layout=True)
    for k, (ax, name) in enumerate(zip(axes, states)):
        label, unit, f = _label(name, units[k])
        y = run.column(name) * f
        ax.plot(wb, y, color="C0" if closed else "C3",
                label="closed loop" if closed else "open loop (K = 0)")
        if open_run is not None:
            ax.plot(open_run.time * n, open_run.column(name) * f, "--", color="C3",
                    label="open loop (K = 0)")
        if lateral:
            box = STATE_BOUNDS_SECT36[k] * scale[k] * f
            lim = min(max(float(np.max(np.abs(y))), 1e-12) * 1.3, 3.0 * box)
            ax.set_ylim(-lim, lim)
            ax.axhspan(-box, box, color="C2", alpha=0.08, lw=0)
        else:  # no box: the run itself sets the scale (a diverging open loop does not hide it)
            lim = max(float(np.max(np.abs(y))), 1e-12) * 3.0
            ax.set_ylim(-lim, lim)
        ax.set_ylabel(f"{label} [{unit}]")
        ax.grid(True, alpha=0.3)
        if t_exit is not None:
            ax.axvline(t_exit, color="k", lw=0.8)
            ax.axvspan(t_exit, wb[-1], color="0.5", alpha=0.12, lw=0)
    for j, name in enumerate(result.extra.get("controls", CONTROL_NAMES)):
        axes[ns].plot(wb, run.column(name) * 180 / np.pi, color=f"C{j}", label=name)
    axes[ns].set_ylabel("controls [deg]")
    axes[ns].grid(True, alpha=0.3)
    axes[ns].legend(loc="upper right", fontsize=8)
    axes[0].legend(loc="upper right", fontsize=8)
    axes[ns].set_xlabel("time [wing beats]")
    where = ("stays inside the Sect. 3.6 linear range (green bands)" if t_exit is None else
             f"leaves the Sect. 3.6 linear range (green bands) at {t_exit:.4g} wing beats (grey)")
    if not lateral:
        where = "is drawn without a linear range (Sect. 3.6 gives the lateral plant's only)"
    fig.suptitle(f"{result.verdict}: dominant rate {result.identification.dominant_growth_rate:+.4f}"
                 f" per wing beat ({result.master}, step {result.step_wingbeats:g} wing beats)\n"
                 f"the state {where}", fontsize=10)
    fig.savefig(path, dpi=90, format="png")
    plt.close(fig)
    return True
