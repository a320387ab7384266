"""Result files of a sweep: the rows of ``sweep.csv``, the summary and the PNG maps.

``sweep.csv`` has one row per case (``COLUMNS``), floats written with ``repr`` so
that they read back exactly; files are written to ``NAME.part`` and renamed.

A map shows, over a two-dimensional slice of initial disturbances (the whole
Sect. 3.6 validity box on both axes, the other two components zero), the peak
over the run of max_i(|x_i| / bound_i, |u| / 0.4 rad): green where the trajectory
stays inside the bounds, red where it leaves them; the black line is peak = 1.
One figure per slice (and bound scale); one panel per gain set and step.
"""

from __future__ import annotations

import csv
import math
import textwrap
from collections import defaultdict
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from ...core.extras import optional
from ...core.files import atomic_path, write_csv_atomic
from .cases import AXES, CONTROL_BOUND, STATE_BOUNDS_SECT36, Case, SweepInputError
from .two_systems import COMPARE_COLUMNS, format_comparison
from .delaymap import format_delay_groups, write_delay_map

__all__ = ["COLUMNS", "DELAY_COLUMNS", "RESULT_COLUMNS", "column_units", "csv_header", "format_summary", "load_done", "read_rows", "result_row",
           "summarize", "write_maps", "write_results"]

_CASE_COLS = ["case", "key", "family", "label", "amplitude", *(f"x0_{a}" for a in AXES), "gains",
              "step_wb", "scale", "stop_wb", "n_steps", "master"]
_PEAKS = [*(f"peak_{a}" for a in AXES), "peak_u", "peak"]
RESULT_COLUMNS = [*_PEAKS, "t_exit_wb", "verdict", *(f"final_{a}" for a in AXES), "error"]
#: Columns of ``sweep.csv``: the case, then its result.
COLUMNS = _CASE_COLS + RESULT_COLUMNS
#: Columns added by the delay axes (:mod:`.delays`).
DELAY_COLUMNS = ["delay_wb", "sample_period_wb", "delay_ms", "sample_period_ms", "stability",
                 "stability_rate", "stability_identified", "stability_deviation"]

_X_PLUS = {"dv": "1 (dv/U)", "dp": "1 (dp/n)", "dr": "1 (dr/n)", "dgamma": "rad"}
_OF_BOUND = "1 (of the bound)"
_UNITS = {
    "case": "1", "amplitude": "1 (of the box)", "step_wb": "wing beats",
    "scale": "1 (factor on the bounds)", "stop_wb": "wing beats", "n_steps": "1",
    "peak_u": "1 (of 0.4 rad)", "peak": _OF_BOUND, "t_exit_wb": "wing beats",
    "delay_wb": "wing beats", "sample_period_wb": "wing beats", "delay_ms": "ms",
    "sample_period_ms": "ms", "stability_rate": "1/wing beat",
    "stability_deviation": "1/wing beat", "err_lateral": _OF_BOUND,
    "err_longitudinal": _OF_BOUND, "cmp_peak": _OF_BOUND, "altitude_lost_m": "m",
    "drift_m": "m",
    **{f"x0_{a}": u for a, u in _X_PLUS.items()}, **{f"final_{a}": u for a, u in _X_PLUS.items()},
    **{f"peak_{a}": _OF_BOUND for a in AXES},
    **{c: _OF_BOUND for c in COMPARE_COLUMNS if c.startswith("err_")},
    **{c: "text" for c in ("key", "family", "label", "gains", "master", "verdict", "error",
                           "stability", "stability_identified", "cmp_verdict")},
}


def column_units(header: Sequence[str]) -> dict[str, str]:
    """The unit of each column of ``sweep.csv`` (``sweep.json``'s ``units``): ``1 (dv/U)``
    for a non-dimensional state, ``1 (of the bound)`` for a ratio to a Sect. 3.6 bound,
    ``text`` for a word; a column without an entry is a bug (KeyError)."""
    return {c: _UNITS[c] for c in header}


def csv_header(rows: Sequence[dict[str, str]]) -> list[str]:
    """The columns of ``sweep.csv`` for these rows (the delay and comparison columns when
    the rows have them)."""
    return (COLUMNS + (DELAY_COLUMNS if rows and "delay_wb" in rows[0] else [])
            + (COMPARE_COLUMNS if rows and "err_dv" in rows[0] else []))


_AXIS_LABEL = {"dv": "dv+ = dv/U", "dp": "dp+ = dp t_w", "dr": "dr+ = dr t_w",
               "dgamma": "dgamma [rad]"}


def _fmt(v: Any) -> str:
    if isinstance(v, str):
        return v
    if isinstance(v, (int, np.integer)) and not isinstance(v, bool):
        return str(int(v))
    f = float(v)
    return "" if math.isnan(f) else repr(f)


def result_row(case: Case, result: dict[str, Any], compare: bool = False) -> dict[str, str]:
    """One row of ``sweep.csv``; ``compare`` adds the comparison columns (empty if missing), a
    result with ``stability`` the delay columns (:mod:`.delays`)."""
    vals = [case.case, case.key, case.family, case.label, case.amplitude, *case.x0, case.gains,
            case.step_wb, case.scale, case.stop_wb, case.n_steps, case.master]
    row = {c: _fmt(v) for c, v in zip(_CASE_COLS, vals)}
    row.update({c: _fmt(result[c]) for c in RESULT_COLUMNS})
    if "stability" in result:
        row.update({c: _fmt({"delay_wb": case.delay_wb, "sample_period_wb": case.sample_period_wb,
                             **result}[c]) for c in DELAY_COLUMNS})
    if compare:
        row.update({c: _fmt(result.get(c, math.nan)) for c in COMPARE_COLUMNS})
    return row


def write_results(path: Path, rows: list[dict[str, str]]) -> None:
    """``sweep.csv``: the rows in case order, atomically (the one CSV writer of the project)."""
    write_csv_atomic(path, csv_header(rows), sorted(rows, key=lambda r: int(r["case"])))


def read_rows(path: str | Path) -> list[dict[str, str]]:
    """Rows of a ``sweep.csv`` as strings (raises :class:`SweepInputError` if it is not one)."""
    try:
        with open(path, newline="", encoding="utf-8") as fh:
            reader = csv.DictReader(fh)
            if reader.fieldnames not in [COLUMNS + d + c for d in ([], DELAY_COLUMNS)
                                         for c in ([], COMPARE_COLUMNS)]:
                raise SweepInputError(f"{str(path)!r} is not a sweep result (its columns differ); "
                                      "use another output folder or --fresh")
            return list(reader)
    except (OSError, UnicodeDecodeError, csv.Error) as e:
        raise SweepInputError(f"cannot read {str(path)!r}: {e}") from e


def load_done(path: Path, keys: set[str], compare: bool = False) -> dict[str, dict[str, Any]]:
    """Results already in ``path`` by key; refuses a file from a different sweep."""
    if not path.exists():
        return {}
    done: dict[str, dict[str, Any]] = {}
    rows = read_rows(path)
    if rows and ("err_dv" in rows[0]) != compare:
        raise SweepInputError(f"{str(path)!r} holds a sweep " + ("without" if compare else "with")
                              + " --compare; use another output folder or --fresh")
    columns = RESULT_COLUMNS + (COMPARE_COLUMNS if compare else [])
    for row in rows:
        if row["key"] not in keys:
            raise SweepInputError(f"{str(path)!r} holds case {row['case']} (key {row['key']}) that "
                                  "is not in this sweep; use another output folder or --fresh")
        done[row["key"]] = {c: (row[c] if c in ("verdict", "error", "cmp_verdict")
                                else (float(row[c]) if row[c] else math.nan))
                            for c in columns}
    return done


def _f(text: str) -> float:
    return float(text) if text else math.nan


def summarize(rows: Sequence[dict[str, str]], cases: Sequence[Case]) -> dict[str, Any]:
    """JSON-ready summary: counts, per-group fractions, per-direction amplitude limits.

    ``largest_amplitude_within_bounds`` is, per gain set, step, scale and direction,
    the largest sampled amplitude (box units) such that it and every smaller one stay
    within the bounds (None if even the smallest leaves); ``linear_limit_amplitude``
    is amplitude / peak of the largest sampled amplitude, exact for a linear loop.
    """
    n = len(rows)
    within = sum(r["verdict"] == "within" for r in rows)
    groups: dict[tuple, list[dict[str, str]]] = defaultdict(list)
    dirs: dict[tuple, list[dict[str, str]]] = defaultdict(list)
    timed = bool(rows) and "delay_wb" in rows[0]  # the delay axes: groups per delay and period
    for r in rows:
        g = (r["gains"], float(r["step_wb"]), float(r["scale"]),
             *((float(r["delay_wb"]), float(r["sample_period_wb"])) if timed else ()))
        groups[g].append(r)
        if r["family"] == "direction":
            dirs[(*g, r["label"])].append(r)
    group_list = []
    for (gains, h, s, *dT), rs in groups.items():
        left: dict[str, int] = defaultdict(int)
        for r in rs:
            if r["verdict"] != "within":
                left[r["verdict"]] += 1
        k = sum(r["verdict"] == "within" for r in rs)
        group_list.append({"gains": gains, "step_wb": h, "scale": s,
                           **dict(zip(("delay_wb", "sample_period_wb"), dT)), "cases": len(rs),
                           "within_bounds": k, "fraction_within_bounds": k / len(rs),
                           "verdicts": dict(sorted(left.items()))})
    amp_list = []
    for (gains, h, s, *dT, label), rs in dirs.items():
        rs = sorted(rs, key=lambda r: float(r["amplitude"]))
        largest = None
        for r in rs:
            if r["verdict"] != "within":
                break
            largest = float(r["amplitude"])
        top = rs[-1]
        peak = _f(top["peak"])
        limit = float(top["amplitude"]) / peak if math.isfinite(peak) and peak > 0 else None
        amp_list.append({"gains": gains, "step_wb": h, "scale": s,
                         **dict(zip(("delay_wb", "sample_period_wb"), dT)), "direction": label,
                         "largest_amplitude": largest, "linear_limit_amplitude": limit})
    gain_sets = {c.gains: [list(row) for row in c.K] for c in cases}
    return {
        "cases": n,
        "within_bounds": within,
        "fraction_within_bounds": within / n if n else None,
        "errors": sum(r["verdict"] == "error" for r in rows),
        "bounds": {"state_nondimensional": dict(zip(AXES, STATE_BOUNDS_SECT36)),
                   "control_rad": CONTROL_BOUND},
        "stop_wb": sorted({float(r["stop_wb"]) for r in rows}),
        "master": sorted({r["master"] for r in rows}),
        "groups": group_list,
        "largest_amplitude_within_bounds": amp_list,
        "gain_sets": gain_sets,
        "complete": True,
    }


def format_summary(summary: dict[str, Any]) -> str:
    """A few lines for the terminal: totals, per-group fractions, per-direction limits."""
    s = summary
    dup = s.get("duplicate_cases", 0)
    lines = [f"sweep: {s['cases']} cases: {s['computed_cases']} run, {s['resumed_cases']} resumed "
             f"from an earlier run"
             + (f", {dup} identical to another case (same initial state, gains, step, stop "
                "and bounds: run once, recorded for each)" if dup else "")
             + f"; {s['elapsed_s']:.1f} s on {s['workers']} worker(s) ({s['backend']})",
             f"within bounds: {s['within_bounds']}/{s['cases']} "
             f"({100 * (s['fraction_within_bounds'] or 0):.1f} %), errors: {s['errors']}"]
    if "delay_groups" in s:  # the delay axes: one line per configuration, with its verdict

        lines += format_delay_groups(s)
    for g in ([] if "delay_groups" in s else s["groups"]):
        lines.append(f"  {g['gains']:<12} step {g['step_wb']:g} wb, scale {g['scale']:g}: "
                     f"{100 * g['fraction_within_bounds']:5.1f} % within")
        amps = [a for a in s["largest_amplitude_within_bounds"]
                if (a["gains"], a["step_wb"], a["scale"]) == (g["gains"], g["step_wb"], g["scale"])]
        if amps:
            best = [(a["direction"], a["largest_amplitude"]) for a in amps]
            lines.append("    largest amplitude within bounds: " + ", ".join(
                f"{d} {'-' if v is None else format(v, 'g')}" for d, v in best))
    if "comparison" in s:
        lines += format_comparison(s["comparison"])
    lines.append(f"csv: {s['csv']}")
    lines.append(f"json: {Path(s['csv']).with_name('sweep.json')}")
    lines += [f"map: {m}" for m in s["maps"]]
    return "\n".join(lines)


#: Colour classes of the peak ratio: greens inside the bounds, reds outside.
_EDGE = 1.0 + 1e-6  # a peak of exactly 1 (a start on the box face) counts as within
_LEVELS = (0.0, 0.2, 0.4, 0.6, 0.8, _EDGE, 1.25, 1.5, 2.0, 3.0, 5.0)
_COLOURS = ("#00441b", "#1b7837", "#5aae61", "#a6dba0", "#d9f0d3",
            "#fddbc7", "#f4a582", "#d6604d", "#b2182b", "#67001f")


def _panel(ax: Any, rs: list[dict[str, str]], sx: str, sy: str) -> Any:
    BoundaryNorm, ListedColormap = optional("matplotlib.colors", "BoundaryNorm",
                                            "ListedColormap")

    xs = sorted({float(r[f"x0_{sx}"]) for r in rs})
    ys = sorted({float(r[f"x0_{sy}"]) for r in rs})
    P = np.full((len(ys), len(xs)), np.nan)
    for r in rs:
        P[ys.index(float(r[f"x0_{sy}"])), xs.index(float(r[f"x0_{sx}"]))] = _f(r["peak"])
    cmap = ListedColormap(_COLOURS).with_extremes(over=_COLOURS[-1], bad="0.6")  # bad: failed
    mesh = ax.pcolormesh(xs, ys, np.ma.masked_invalid(P), cmap=cmap,
                         norm=BoundaryNorm(_LEVELS, cmap.N), shading="nearest")
    if len(xs) > 1 and len(ys) > 1 and np.nanmin(P) < _EDGE < np.nanmax(P):
        ax.contour(xs, ys, P, levels=[_EDGE], colors="k", linewidths=1.5)
    return mesh


def write_maps(rows: Sequence[dict[str, str]], out_dir: str | Path) -> list[Path]:
    """One PNG per grid slice (and bound scale): ``map_X_Y.png`` (``..._scaleS.png``); with the
    delay axes one per delay and sample period too (``..._delayD_periodT.png``) and the map over
    delay x sample period (:func:`.delaymap.write_delay_map`)."""
    Figure = optional("matplotlib.figure", "Figure")

    grid = [r for r in rows if r["family"] == "grid"]
    timed = bool(rows) and "delay_wb" in rows[0]

    def combo(r: dict[str, str]) -> tuple[float, ...]:
        return (float(r["scale"]), *((float(r["delay_wb"]), float(r["sample_period_wb"]))
                                     if timed else ()))

    combos = sorted({combo(r) for r in grid})
    scales = sorted({c[0] for c in combos})
    written = []
    for label in dict.fromkeys(r["label"] for r in grid):
        sx, sy = label.split(":")
        for s, *dT in combos:
            rs = [r for r in grid if r["label"] == label and combo(r) == (s, *dT)]
            gains = list(dict.fromkeys(r["gains"] for r in rs))
            steps = sorted({float(r["step_wb"]) for r in rs})
            width_in = max(5.0, 1.2 + 3.3 * len(steps))  # one column: room for the title
            fig = Figure(figsize=(width_in, 1.3 + 3.0 * len(gains)), dpi=110,
                         layout="constrained")
            axes = fig.subplots(len(gains), len(steps), squeeze=False, sharex=True, sharey=True)
            mesh = None
            for i, g in enumerate(gains):
                for j, h in enumerate(steps):
                    sub = [r for r in rs if r["gains"] == g and float(r["step_wb"]) == h]
                    ax = axes[i][j]
                    mesh = _panel(ax, sub, sx, sy)
                    k = sum(r["verdict"] == "within" for r in sub)
                    ax.set_title(f"{g} gains, step {h:g} wb: {100 * k / len(sub):.0f}% within",
                                 fontsize=9)
                    if i == len(gains) - 1:
                        ax.set_xlabel(_AXIS_LABEL[sx])
                    if j == 0:
                        ax.set_ylabel(_AXIS_LABEL[sy])
            cb = fig.colorbar(mesh, ax=axes, shrink=0.8, extend="max", ticks=_LEVELS,
                              spacing="uniform", format="%.3g")
            cb.set_label("peak of max(|x_i|/bound_i, |u|/0.4 rad)")
            stop = rs[0]["stop_wb"]
            # wrapped to the figure's width (about 13 characters per inch at 10 pt)
            chars = int(width_in * 13)
            fig.suptitle("\n".join(textwrap.wrap(
                f"Initial disturbances over the Sect. 3.6 box, slice {sx} x {sy} "
                f"(others 0), {float(stop):g} wing beats"
                + (f", bounds x {s:g}" if s != 1.0 else "")
                + (f", delay {dT[0]:g} wb, sample period {dT[1]:g} wb" if dT else ""), chars)
                + textwrap.wrap("green: stays within the bounds; red: leaves them; black "
                                "line: peak = bound", chars)), fontsize=10)
            name = (f"map_{sx}_{sy}" + (f"_scale{s:g}" if len(scales) > 1 or s != 1.0 else "")
                    + (f"_delay{dT[0]:g}_period{dT[1]:g}" if dT else ""))
            path = Path(out_dir) / f"{name}.png"
            with atomic_path(path) as tmp:
                fig.savefig(tmp, format="png")
            written.append(path)
    return written + write_delay_map(rows, out_dir)
