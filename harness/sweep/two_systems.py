"""``dronefly sweep --compare``: each case through two systems, and how far apart they end up.

The reference system (``--system``, by default the linear ``DroneFlyHover.ssp``) and the
compared one (``--compare``, by default the nonlinear ``DroneFlyHover6DOF.ssp``) run the same
case: the same initial state of the lateral plant, the same gains, step and stop. The
*linearisation error* of a state is the peak over the run of |x_compared - x_reference| in
non-dimensional units, relative to that state's Sect. 3.6 bound (the box, whatever the case's
bound scale): 0.1 means the two trajectories differ by a tenth of the bound at worst. The
longitudinal states (where both systems have them) are compared against the same bounds
(|du+|, |dw+|, |dq+| <= 0.15, |dtheta| <= 0.22). For the compared system the row also holds
its own peak and verdict (as the reference's ``peak`` and ``verdict``), whether both stay in
the box, and, where it has an earth-axis position, the altitude lost (the largest z_earth,
positive down) and the horizontal drift at the end, in metres.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from ...models.longitudinal_interface import LONGITUDINAL

from .cases import AXES, STATE_BOUNDS_SECT36

__all__ = ["COMPARE_COLUMNS", "LONGITUDINAL_AXES", "compare_runs", "compare_summary",
           "format_comparison"]

#: short names of the longitudinal states (x+ order)
LONGITUDINAL_AXES: tuple[str, ...] = ("du", "dw", "dq", "dtheta")
#: the columns a comparison adds to ``sweep.csv``
COMPARE_COLUMNS: list[str] = [*(f"err_{a}" for a in (*AXES, *LONGITUDINAL_AXES)),
                              "err_lateral", "err_longitudinal", "cmp_peak", "cmp_verdict",
                              "altitude_lost_m", "drift_m"]


def _block(run: Any, loop: Any, names: tuple[str, ...]) -> np.ndarray | None:
    idx = [run.names.index(n) for n in names if n in run.names]
    return run.signals[:, idx] if len(idx) == len(names) and names else None


def compare_runs(ref: Any, ref_loop: Any, cmp: Any, cmp_loop: Any, scale: np.ndarray,
                 cmp_measure: dict[str, Any]) -> dict[str, Any]:
    """The comparison columns of one case.

    Parameters
    ----------
    ref, cmp : LoopRun
        The runs of the reference and the compared system (same steps).
    ref_loop, cmp_loop : harness.sweep.system_cases.LateralLoop
        Where each system's states are.
    scale : ndarray
        x = x+ * scale of the lateral states (U, n, n, 1); the longitudinal states use
        (U, U, n, 1) with the same U and n.
    cmp_measure : dict
        The compared run's own measurement (``peak``, ``verdict``, ``error``).
    """
    out: dict[str, Any] = {c: math.nan for c in COMPARE_COLUMNS}
    out["cmp_peak"], out["cmp_verdict"] = cmp_measure["peak"], cmp_measure["verdict"]
    if not (ref.complete and cmp.complete) or len(ref.time) != len(cmp.time):
        return out
    bounds = np.array(STATE_BOUNDS_SECT36)
    U, n = float(scale[0]), float(scale[1])
    blocks = [
        (AXES, [f"{ref_loop.plant}.{s}" for s in ref_loop.states],
         [f"{cmp_loop.plant}.{s}" for s in cmp_loop.states], np.asarray(scale)),
        (LONGITUDINAL_AXES,
         [f"{ref_loop.longitudinal}.{s}" for s in LONGITUDINAL.state_names]
         if ref_loop.longitudinal else [],
         [f"{cmp_loop.longitudinal}.{s}" for s in LONGITUDINAL.state_names]
         if cmp_loop.longitudinal else [],
         np.array(LONGITUDINAL.scale_vector(U, n))),
    ]
    for axes, ref_names, cmp_names, sc in blocks:
        a, b = _block(ref, ref_loop, tuple(ref_names)), _block(cmp, cmp_loop, tuple(cmp_names))
        if a is None or b is None:
            continue
        err = np.max(np.abs(b - a), axis=0) / sc / bounds
        out.update({f"err_{k}": float(e) for k, e in zip(axes, err)})
        out["err_lateral" if axes is AXES else "err_longitudinal"] = float(err.max())
    if cmp_loop.earth:
        pos = _block(cmp, cmp_loop, tuple(f"{cmp_loop.earth}.{k}"
                                          for k in ("x_earth", "y_earth", "z_earth")))
        if pos is not None and len(pos):
            out["altitude_lost_m"] = float(max(0.0, pos[:, 2].max()))
            out["drift_m"] = float(math.hypot(pos[-1, 0], pos[-1, 1]))
    return out


def _in_box(r: dict[str, str]) -> bool:
    return all(abs(float(r[f"x0_{a}"])) <= b * (1 + 1e-9)
               for a, b in zip(AXES, STATE_BOUNDS_SECT36))


def _num(text: str) -> float:
    return float(text) if text else math.nan


def compare_summary(rows: list[dict[str, str]]) -> dict[str, Any]:
    """JSON-ready answer of a comparison: where is the linear theory within 5 % and 10 %?

    ``in_box``: the cases whose initial state lies in the Sect. 3.6 box; for them the
    largest lateral and longitudinal errors and the shares within 10 %; ``in_box_staying``:
    those whose reference trajectory also stays within the bounds, their largest errors and
    how many are within 10 % (lateral and longitudinal). ``directions``: per
    direction, the error at the box edge (amplitude 1), the largest sampled amplitude up to
    which the lateral error stays within 5 % and 10 % of the bounds, and the altitude lost
    at the box edge.
    """
    ok = [r for r in rows if r.get("err_lateral")]
    box = [r for r in ok if _in_box(r)]
    out: dict[str, Any] = {"cases": len(ok), "in_box_cases": len(box)}
    if box:
        lat = [_num(r["err_lateral"]) for r in box]
        lon = [_num(r["err_longitudinal"]) for r in box]
        out.update(in_box_max_err_lateral=max(lat), in_box_max_err_longitudinal=max(lon),
                   in_box_fraction_lateral_within_10pct=sum(e <= 0.10 for e in lat) / len(lat),
                   in_box_fraction_longitudinal_within_10pct=sum(e <= 0.10 for e in lon) / len(lon),
                   in_box_max_altitude_lost_m=max(_num(r["altitude_lost_m"]) for r in box))
        stay = [r for r in box if r["verdict"] == "within"]
        out["in_box_staying_cases"] = len(stay)
        for axis in ("lateral", "longitudinal"):
            e = [_num(r[f"err_{axis}"]) for r in stay]
            out[f"in_box_staying_max_err_{axis}"] = max(e) if e else None
            out[f"in_box_staying_{axis}_within_10pct"] = sum(x <= 0.10 for x in e)
    dirs: dict[str, list[dict[str, str]]] = {}
    for r in ok:
        if r["family"] == "direction":
            dirs.setdefault(r["label"], []).append(r)
    out["directions"] = []
    for label, rs in dirs.items():
        rs.sort(key=lambda r: float(r["amplitude"]))
        entry: dict[str, Any] = {"direction": label}
        for pct in (5, 10):
            best = None
            for r in rs:
                if _num(r["err_lateral"]) > pct / 100:
                    break
                best = float(r["amplitude"])
            entry[f"largest_amplitude_within_{pct}pct"] = best
        edge = [r for r in rs if math.isclose(float(r["amplitude"]), 1.0)]
        if edge:
            e = edge[0]
            entry.update(err_lateral_at_box_edge=_num(e["err_lateral"]),
                         err_longitudinal_at_box_edge=_num(e["err_longitudinal"]),
                         worst_state_at_box_edge=max(
                             AXES, key=lambda a: _num(e[f"err_{a}"])),
                         altitude_lost_m_at_box_edge=_num(e["altitude_lost_m"]))
        out["directions"].append(entry)
    return out


def format_comparison(c: dict[str, Any]) -> list[str]:
    """Terminal lines of :func:`compare_summary`."""
    lines = [f"comparison: {c['cases']} cases, {c['in_box_cases']} starting in the box"]
    if c.get("in_box_cases"):
        lines.append(f"  in the box: lateral error <= {100 * c['in_box_max_err_lateral']:.1f} % of "
                     f"the bounds ({100 * c['in_box_fraction_lateral_within_10pct']:.0f} % of the "
                     f"cases within 10 %), longitudinal <= "
                     f"{100 * c['in_box_max_err_longitudinal']:.1f} % ("
                     f"{100 * c['in_box_fraction_longitudinal_within_10pct']:.0f} % within 10 %), "
                     f"altitude lost <= "
                     f"{1000 * c['in_box_max_altitude_lost_m']:.1f} mm")
        if c.get("in_box_staying_cases"):
            n = c["in_box_staying_cases"]
            lines.append(f"  the {n} of them whose linear trajectory stays within the bounds: "
                         f"lateral error <= {100 * c['in_box_staying_max_err_lateral']:.1f} % "
                         f"({c['in_box_staying_lateral_within_10pct']} of {n} within 10 %), "
                         f"longitudinal <= "
                         f"{100 * c['in_box_staying_max_err_longitudinal']:.1f} % "
                         f"({c['in_box_staying_longitudinal_within_10pct']} of {n} within 10 %)")
    for d in c["directions"]:
        if "err_lateral_at_box_edge" in d:
            w5, w10 = (d[f"largest_amplitude_within_{p}pct"] for p in (5, 10))
            lines.append(f"  {d['direction']:<8} at the box edge: lateral error "
                         f"{100 * d['err_lateral_at_box_edge']:.1f} % (worst "
                         f"{d['worst_state_at_box_edge']}); within 5 % up to "
                         f"{'-' if w5 is None else format(w5, 'g')}, within 10 % up to "
                         f"{'-' if w10 is None else format(w10, 'g')} box")
    return lines
