"""``make figures`` (``python -m dronefly.cli.figures``) makes every figure of docs/, and each draws
its computation.

The regeneration runs on small inputs into a scratch folder (docs/ is never written). What each
figure draws is read from the matplotlib figure as it is saved (a spy on ``Figure.savefig``: the
lines' and meshes' data) and compared with the computation it shows: the quasi-steady model's
forces and derivatives (Fig. 2), its pair scans (the linearity maps), the co-simulation's CSV
(the closed loop) and the sweeps' CSVs (the maps), whose numbers their own tests check against
closed forms (tests/test_sweep.py, tests/test_aero.py).
"""

from __future__ import annotations

import csv
import shutil
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from matplotlib.figure import Figure

from dronefly.cli.figures import FIGURES, main, regenerate
from dronefly.harness.aero.beside_paper import (CONTROL_BOX_RAD, LATERAL_PAIRS, derivatives,
                                           pair_scan)
from dronefly.models.quasisteady import FORCES, QuasiSteadyModel

ROOT = Path(__file__).resolve().parents[1]
PNG = b"\x89PNG\r\n\x1a\n"


def _drawn(fig: Any) -> list[dict[str, Any]]:
    """Per axes: its lines (label, x, y), its meshes' arrays and its title (a panel has lines
    or a title; a colour bar has a mesh and neither)."""
    out = []
    for ax in fig.axes:
        lines = [(ln.get_label(), np.asarray(ln.get_xdata(), float),
                  np.asarray(ln.get_ydata(), float)) for ln in ax.get_lines()]
        meshes = [np.ma.filled(np.ma.asarray(c.get_array(), float), np.nan)
                  for c in ax.collections if type(c).__name__ == "QuadMesh"]
        out.append({"lines": lines, "meshes": meshes, "title": ax.get_title()})
    return out


@pytest.fixture(scope="module")
def made(built_fmus: dict[str, Path], tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    """Every figure on small inputs, in a scratch working folder whose ``build/`` holds the
    session's freshly built FMUs (the commands find them up to date); what each drew."""
    work = tmp_path_factory.mktemp("figures")
    shutil.copytree(next(iter(built_fmus.values())).parent, work / "build")
    drawn: dict[str, list[dict[str, Any]]] = {}
    save = Figure.savefig

    def spy(self: Figure, fname: Any, *args: Any, **kwargs: Any) -> Any:
        path = Path(str(fname))  # RUN/NAME.png (of a command's run) or out/NAME.png
        drawn[f"{path.parent.name}/{path.name.removesuffix('.part')}"] = _drawn(self)
        return save(self, fname, *args, **kwargs)

    with pytest.MonkeyPatch.context() as mp:
        mp.chdir(work)
        mp.setattr(Figure, "savefig", spy)
        written = regenerate(work / "out", small=True, work_dir=work / "runs")
    return {"written": written, "drawn": drawn, "runs": work / "runs", "work": work}


def _rows(path: Path) -> list[dict[str, str]]:
    with path.open(newline="", encoding="utf-8") as f:
        return list(csv.DictReader(f))


def test_every_figure_of_docs_is_made(made: dict[str, Any]) -> None:
    """One figure per PNG of docs/, each a PNG written where asked; docs/ untouched."""
    in_docs = sorted(p.name for p in (ROOT / "docs").glob("*.png"))
    assert sorted(f.name for f in FIGURES) == in_docs
    assert [p.name for p in made["written"]] == [f.name for f in FIGURES]
    for path in made["written"]:
        assert path.parent == made["work"] / "out"
        assert path.read_bytes()[:8] == PNG


def test_fig2_draws_the_model_forces_and_tangents(made: dict[str, Any]) -> None:
    """Each panel's markers are the model's cycle-averaged Y+, L+, N+ at that control alone, and
    its lines the tangent F0 + s dF/ds of central differences at hover."""
    model = QuasiSteadyModel()
    axes = made["drawn"]["out/aero_fig2.png"]
    controls = ("delta_Phi_a", "delta_alpha_1a", "delta_alpha_2a")
    d = derivatives(model, 1e-3, controls)
    f0 = model.forces_vector()
    for ax, name in zip(axes, controls):
        lines = {label: (x, y) for label, x, y in ax["lines"]}
        for o in "YLN":
            k = FORCES.index(o)
            s, y = lines[f"{o}+ model"]
            assert len(s) == 5 and s[-1] == pytest.approx(2 * CONTROL_BOX_RAD)
            # the model at each control value (another call of the blade-element sum):
            # the same arithmetic, so to round-off
            expect = [model.forces_vector(control={name: v})[k] for v in s]
            np.testing.assert_allclose(y, expect, rtol=1e-12, atol=1e-15)
            s_t, y_t = lines[f"{o}+ tangent"]
            np.testing.assert_allclose(y_t, f0[k] + s_t * d[name][k], rtol=1e-12, atol=1e-15)


def test_linearity_maps_draw_the_pair_scans(made: dict[str, Any]) -> None:
    """Each map is the largest error of Y+, L+, N+ over its pair of states (pair_scan)."""
    model = QuasiSteadyModel()
    axes = [a for a in made["drawn"]["out/aero_linearity.png"] if a["meshes"] and a["lines"]]
    assert len(axes) == len(LATERAL_PAIRS)
    for ax, pair in zip(axes, LATERAL_PAIRS):
        r = pair_scan(model, pair, "YLN", extent=2.0, points=3)
        err = np.max([np.asarray(r[o]["error_pct"]) for o in "YLN"], axis=0)
        np.testing.assert_allclose(ax["meshes"][0].ravel(), err.T.ravel(), rtol=1e-12)
        assert np.max(err) > 0.0  # twice the box: the tangent is not exact


def test_cosim_figure_draws_the_run(made: dict[str, Any]) -> None:
    """The closed-loop lines are the run's CSV columns (in the axis' display unit: one factor
    per state, a power of ten or 180/pi), over the run's 20 wing beats."""
    [csv_path] = (made["runs"] / "cosim_paper").glob("cosim_paper_gauss-seidel*.csv")
    rows = _rows(csv_path)
    axes = made["drawn"][f"cosim_paper/{csv_path.with_suffix('.png').name}"]
    for ax, name in zip(axes, ("delta_v", "delta_p", "delta_r", "delta_gamma")):
        column = np.array([float(r[name]) for r in rows])
        x, y = next((x, y) for label, x, y in ax["lines"] if label == "closed loop")
        assert len(y) == len(column) and x[-1] == pytest.approx(20.0)
        k = int(np.argmax(np.abs(column)))
        factor = y[k] / column[k]
        assert any(factor == pytest.approx(f) for f in (1.0, 1e3, 1e6, 180 / np.pi)), factor
        np.testing.assert_allclose(y, factor * column, rtol=1e-12, atol=1e-300)


@pytest.mark.parametrize("figure, run, slice_", [
    ("sweep_map/map_dgamma_dp.png", "sweep_map", ("dgamma", "dp")),
    ("validity_map/compare_dr_dp.png", "validity_map", ("dr", "dp"))])
def test_maps_draw_the_sweep_rows(made: dict[str, Any], figure: str, run: str,
                                  slice_: tuple[str, str]) -> None:
    """The sweep map's cells are the sweep's peaks, panel by panel (gains x step), on the grid
    of initial states; the comparison map's left panel is the same map of its own sweep."""
    rows = [r for r in _rows(made["runs"] / run / "sweep.csv")
            if r["family"] == "grid" and r["label"] == ":".join(slice_)]
    sx, sy = slice_
    panels = [a for a in made["drawn"][figure] if a["meshes"] and a["title"]]
    combos = list(dict.fromkeys((r["gains"], r["step_wb"]) for r in rows))
    assert len(panels) >= len(combos) >= 1
    for ax, (gains, step) in zip(panels, combos):
        sub = [r for r in rows if (r["gains"], r["step_wb"]) == (gains, step)]
        xs = sorted({float(r[f"x0_{sx}"]) for r in sub})
        ys = sorted({float(r[f"x0_{sy}"]) for r in sub})
        assert len(xs) == len(ys) == 3
        expect = np.full((3, 3), np.nan)
        for r in sub:
            expect[ys.index(float(r[f"x0_{sy}"])), xs.index(float(r[f"x0_{sx}"]))] = float(r["peak"])
        np.testing.assert_array_equal(ax["meshes"][0].reshape(3, 3), expect)


def test_latency_map_draws_the_share_within(made: dict[str, Any]) -> None:
    """Each cell (delay x sample period) is the share of the sweep's cases of that cell that
    stay within the bounds."""
    rows = _rows(made["runs"] / "latency_map" / "sweep.csv")
    panels = [a for a in made["drawn"]["latency_map/map_delay_period.png"] if a["meshes"] and a["title"]]
    gains = list(dict.fromkeys(r["gains"] for r in rows))
    assert gains == ["paper", "stabilising"] and len(panels) == 2
    delays = sorted({float(r["delay_wb"]) for r in rows})
    periods = sorted({float(r["sample_period_wb"]) for r in rows})
    assert delays == periods == [0.0, 1.0]
    for ax, g in zip(panels, gains):
        share = np.array([[np.mean([r["verdict"] == "within" for r in rows if r["gains"] == g
                                    and float(r["delay_wb"]) == d
                                    and float(r["sample_period_wb"]) == T])
                           for T in periods] for d in delays])
        np.testing.assert_array_equal(ax["meshes"][0].reshape(share.shape), share)


def test_cli_refuses_an_unknown_figure(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["--only", "nope.png", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "'nope.png'" in err
    assert not any(tmp_path.iterdir())
