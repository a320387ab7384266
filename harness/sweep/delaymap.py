"""The map over sensing delay x sample period of a ``dronefly sweep --delays ... --sample-periods``.

``map_delay_period.png`` (``..._stepH``/``..._scaleS`` when a sweep has several): one panel per
gain set; rows are the sensing delays, columns the sample periods (0: every communication
step), both in wing beats with ms at the plant's n. Each cell's colour is the share of the
case's disturbances whose trajectory stays within the Sect. 3.6 bounds (scaled); its text is
the closed loop's verdict with the delay states (:mod:`.delays`: S stable, N neutral,
U unstable, hatched) and that share. Written when both axes have more than one value.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Sequence

import numpy as np

from ...core.extras import optional
from ...core.files import atomic_path

__all__ = ["format_delay_groups", "write_delay_map"]

_LETTER = {"stable": "S", "neutral": "N", "unstable": "U", "": "?"}


def _cells(rs: Sequence[dict[str, str]], delays: list[float],
           periods: list[float]) -> tuple[np.ndarray, np.ndarray]:
    """Share within the bounds and verdict per (delay, period)."""
    share = np.full((len(delays), len(periods)), np.nan)
    verdict = np.full(share.shape, "", dtype=object)
    for i, d in enumerate(delays):
        for j, T in enumerate(periods):
            sub = [r for r in rs if float(r["delay_wb"]) == d and float(r["sample_period_wb"]) == T]
            if sub:
                share[i, j] = sum(r["verdict"] == "within" for r in sub) / len(sub)
                verdict[i, j] = sub[0]["stability"]
    return share, verdict


def _ms(rs: Sequence[dict[str, str]], column: str, value: float) -> float:
    return next(float(r[column.replace("_wb", "_ms")]) for r in rs if float(r[column]) == value)


def write_delay_map(rows: Sequence[dict[str, str]], out_dir: str | Path) -> list[Path]:
    """The maps of the module text (none unless both delay axes have more than one value)."""
    if not rows or "delay_wb" not in rows[0]:
        return []
    delays = sorted({float(r["delay_wb"]) for r in rows})
    periods = sorted({float(r["sample_period_wb"]) for r in rows})
    if len(delays) < 2 or len(periods) < 2:
        return []
    Figure = optional("matplotlib.figure", "Figure")
    Rectangle = optional("matplotlib.patches", "Rectangle")

    combos = sorted({(float(r["step_wb"]), float(r["scale"])) for r in rows})
    written = []
    for h, s in combos:
        rs = [r for r in rows if (float(r["step_wb"]), float(r["scale"])) == (h, s)]
        gains = list(dict.fromkeys(r["gains"] for r in rs))
        fig = Figure(figsize=(1.6 + 0.9 * len(periods) * len(gains) + 1.2 * len(gains),
                              1.6 + 0.42 * len(delays)), dpi=110, layout="constrained")
        axes = fig.subplots(1, len(gains), squeeze=False, sharey=True)[0]
        mesh = None
        for ax, g in zip(axes, gains):
            sub = [r for r in rs if r["gains"] == g]
            share, verdict = _cells(sub, delays, periods)
            mesh = ax.pcolormesh(np.arange(len(periods) + 1) - 0.5, np.arange(len(delays) + 1) - 0.5,
                                 np.ma.masked_invalid(share), cmap="RdYlGn", vmin=0.0, vmax=1.0)
            for i in range(len(delays)):
                for j in range(len(periods)):
                    if verdict[i, j] == "unstable":
                        ax.add_patch(Rectangle((j - 0.5, i - 0.5), 1, 1, fill=False, hatch="//",
                                               ec="0.25", lw=0))
                    if np.isfinite(share[i, j]):
                        ax.text(j, i, f"{_LETTER.get(verdict[i, j], '?')} {100 * share[i, j]:.0f}%",
                                ha="center", va="center", fontsize=7)
            ax.set_xticks(range(len(periods)), [
                "every\nstep" if T == 0 else f"{T:g}\n({_ms(sub, 'sample_period_wb', T):.1f} ms)"
                for T in periods], fontsize=7)
            ax.set_yticks(range(len(delays)), [
                f"{d:g} ({_ms(sub, 'delay_wb', d):.1f} ms)" for d in delays], fontsize=7)
            ax.set_xlabel("sample period, wing beats")
            ax.set_title(f"{g} gains", fontsize=9)
        axes[0].set_ylabel("sensing delay, wing beats")
        fig.colorbar(mesh, ax=list(axes), shrink=0.85).set_label(
            "share of disturbances within the bounds")
        fig.suptitle(f"Sensing delay x sample period, step {h:g} wb, {float(rs[0]['stop_wb']):g} "
                     "wing beats" + (f", bounds x {s:g}" if s != 1.0 else "")
                     + "\nverdict with the delay states: S stable, N neutral, U unstable "
                     "(hatched); colour and %: within the Sect. 3.6 bounds", fontsize=9)
        name = ("map_delay_period" + (f"_step{h:g}" if len({c[0] for c in combos}) > 1 else "")
                + (f"_scale{s:g}" if len({c[1] for c in combos}) > 1 or s != 1.0 else ""))
        path = Path(out_dir) / f"{name}.png"
        with atomic_path(path) as tmp:
            fig.savefig(tmp, format="png")
        written.append(path)
    return written


def _num(v: Any, fmt: str) -> str:
    return "-" if v is None else format(v, fmt)


def format_delay_groups(summary: dict[str, Any]) -> list[str]:
    """Terminal lines of :func:`.delays.delay_summary`'s groups (see ``summary['delay_groups']``)."""
    lines = []
    for g in summary["delay_groups"]:
        lines.append(
            f"  {g['gains']:<12} step {g['step_wb']:g} wb, delay {g['delay_wb']:g} wb "
            f"({g['delay_ms']:.1f} ms), sample period {g['sample_period_wb']:g} wb"
            + (f", scale {g['scale']:g}" if g["scale"] != 1.0 else "")
            + f": {g['stability'] or 'no model'} ({_num(g['stability_rate'], '+.2e')}/wb; "
            f"identified {g['stability_identified'] or '-'}, "
            f"rate off by {_num(g['stability_deviation'], '.0e')}), "
            f"{100 * g['fraction_within_bounds']:5.1f} % within, peak |u| "
            f"{_num(g['peak_u'], '.2f')} x 0.4 rad")
    if summary["stability_disagreements"]:
        lines.append(f"  identification disagrees with the model in "
                     f"{summary['stability_disagreements']} configuration(s)")
    return lines
