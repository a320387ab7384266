"""Output a user can read: names that differ when the inputs differ, the
units of every CSV column in a sidecar (or, for simulate, the docs), plot titles and legends
that stay whole and off the data, axes with units."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import pytest
from docnumbers import doc_block
from fmpy import read_model_description

from dronefly.cli.app import main
from dronefly.harness.cosim.fmu import variable_unit

ROOT = Path(__file__).resolve().parents[1]


def _header(path: Path) -> list[str]:
    with path.open(newline="") as f:
        return next(csv.reader(f))


def _pair(built_fmus) -> list[str]:
    return ["--plant", str(built_fmus["DroneFlyLateral"]), "--controller",
            str(built_fmus["StateFeedback"])]


def test_cosim_runs_with_different_inputs_do_not_share_files(built_fmus, tmp_path, capsys):
    """Two runs with different --set values write two CSVs (the issue's overwritten
    cosim_custom_gauss-seidel.csv); the same inputs write the same name again."""
    base = ["cosim", *_pair(built_fmus), "--gains=-0.3,-0.3,-0.2,-0.1", "--stop", "20",
            "--no-plot", "--out", str(tmp_path)]
    names = []
    for value in ("0.25", "0.3", "0.25"):
        assert main([*base, "--set", f"plant.Lv_plus={value}"]) == 0
        names.append(next(line for line in capsys.readouterr().out.splitlines()
                          if line.startswith("csv: ")))
    assert names[0] != names[1] and names[0] == names[2]
    assert len(list(tmp_path.glob("cosim_custom_gauss-seidel_*.csv"))) == 2
    for system_value in ("0.1", "0.2"):
        assert main(["cosim", "--system", str(built_fmus["DroneFlyHover.ssp"]), "--stop", "5",
                     "--no-plot", "--out", str(tmp_path / "sys"),
                     "--set", f"lateral.delta_gamma_start={system_value}"]) == 0
    assert len(list((tmp_path / "sys").glob("cosim_DroneFlyHover_gauss-seidel_*.csv"))) == 2


def _fmu_units(path: Path) -> dict[str, str]:
    """The units a model description declares, read by fmpy (the oracle)."""
    return {v.name: variable_unit(v) for v in read_model_description(str(path)).modelVariables}


def test_cosim_csv_units_are_in_its_json(built_fmus, tmp_path):
    out = tmp_path / "pair"
    assert main(["cosim", *_pair(built_fmus), "--stop", "10", "--no-plot", "--out", str(out),
                 "--record", "controller.saturated,plant.n"]) == 0
    (csv_path,) = out.glob("*.csv")
    units = json.loads(csv_path.with_suffix(".json").read_text())["units"]
    header = _header(csv_path)
    assert list(units) == header
    plant, controller = _fmu_units(built_fmus["DroneFlyLateral"]), _fmu_units(
        built_fmus["StateFeedback"])
    assert units["time"] == "s" and units["delta_v"] == plant["delta_v"] == "m/s"
    assert units["delta_p"] == "rad/s" and units["delta_gamma"] == "rad"
    assert units["plant.n"] == plant["n"] == "Hz"
    assert units["controller.saturated"] == controller["saturated"] == "1"
    out = tmp_path / "system"
    ssp = built_fmus["DroneFlyHover.ssp"]
    assert main(["cosim", "--system", str(ssp), "--stop", "5", "--no-plot", "--out",
                 str(out)]) == 0
    (csv_path,) = out.glob("*.csv")
    units = json.loads(csv_path.with_suffix(".json").read_text())["units"]
    assert list(units) == _header(csv_path)
    lon = _fmu_units(built_fmus["DroneFlyLongitudinal"])
    assert units["longitudinal.delta_q"] == lon["delta_q"] == "rad/s"


def test_sweep_csv_units_are_in_sweep_json(built_fmus, tmp_path):
    out = tmp_path / "sweep"
    assert main(["sweep", *_pair(built_fmus), "--grid", "2", "--slices", "dgamma:dp",
                 "--disturbances", "grid", "--steps", "1", "--gains", "paper", "--stop", "5",
                 "--workers", "1", "--no-plot", "--no-progress", "--out", str(out)]) == 0
    units = json.loads((out / "sweep.json").read_text())["units"]
    assert list(units) == _header(out / "sweep.csv")
    assert units["x0_dgamma"] == "rad" and units["x0_dv"] == "1 (dv/U)"
    assert units["t_exit_wb"] == "wing beats" and units["peak_dp"] == "1 (of the bound)"


def test_simulate_csv_units_are_in_the_docs(built_fmus, tmp_path, capsys):
    """The docs' line names every column of simulate's CSV with the plant FMU's unit."""
    import shutil

    shutil.copy(built_fmus["DroneFlyLateral"], tmp_path)  # up to date: not rebuilt
    assert main(["simulate", "--stop", "1", "--out", str(tmp_path)]) == 0
    header = _header(tmp_path / "DroneFlyLateral_open_loop.csv")
    line = doc_block((ROOT / "docs" / "usage.md").read_text(encoding="utf-8"), "simulate-units",
                     "docs/usage.md")
    documented = dict(item.strip()[:-1].split(" [") for item in line.split(","))
    plant = _fmu_units(built_fmus["DroneFlyLateral"])
    assert list(documented) == header
    assert documented == {"time": "s", **{c: plant[c] for c in header[1:]}}


@pytest.fixture
def figures(monkeypatch):
    """Every matplotlib figure saved while the test runs, after it is drawn."""
    from matplotlib.figure import Figure

    saved = []
    original = Figure.savefig

    def savefig(self, *args, **kwargs):
        original(self, *args, **kwargs)
        saved.append(self)

    monkeypatch.setattr(Figure, "savefig", savefig)
    return saved


def _inside(inner, outer, slack: float = 1.0) -> bool:
    return (inner.x0 >= outer.x0 - slack and inner.x1 <= outer.x1 + slack
            and inner.y0 >= outer.y0 - slack and inner.y1 <= outer.y1 + slack)


def _texts_whole(fig) -> None:
    renderer = fig._get_renderer()  # the figure was drawn when saved
    texts = [fig._suptitle] if fig._suptitle is not None else []
    for ax in fig.axes:  # titles, axis labels (a colour bar's too), legends
        texts += [ax.title, ax.xaxis.label, ax.yaxis.label]
        if ax.get_legend() is not None:
            texts += list(ax.get_legend().get_texts())
    texts = [t for t in texts if t.get_text() and t.get_visible()]
    assert texts
    for t in texts:
        bb = t.get_window_extent(renderer)
        assert _inside(bb, fig.bbox), f"text cut off the figure: {t.get_text()!r}"


def test_single_column_sweep_map_title_is_whole(built_fmus, tmp_path, figures):
    assert main(["sweep", *_pair(built_fmus), "--grid", "3", "--slices", "dgamma:dp",
                 "--disturbances", "grid", "--steps", "0.1", "--gains", "paper", "--stop", "5",
                 "--workers", "1", "--no-progress", "--out", str(tmp_path)]) == 0
    (fig,) = figures
    assert len(fig.axes) == 2  # one panel and its colour bar: the single-column map
    assert "Initial disturbances over the Sect. 3.6 box" in fig._suptitle.get_text()
    _texts_whole(fig)


def test_system_plot_has_units_and_legends_beside_the_curves(built_fmus, tmp_path, figures):
    assert main(["cosim", "--system", str(built_fmus["DroneFlyHover.ssp"]), "--stop", "5",
                 "--out", str(tmp_path)]) == 0
    (fig,) = figures
    _texts_whole(fig)
    renderer = fig._get_renderer()  # the figure was drawn when saved
    for ax in fig.axes:
        assert ax.get_ylabel().startswith("[") or ax.get_ylabel() == "SI units (legend)"
        if ax.get_ylabel() == "SI units (legend)":
            assert all(t.get_text().endswith("]") for t in ax.get_legend().get_texts())
        legend = ax.get_legend().get_window_extent(renderer)
        assert legend.x0 >= ax.bbox.x1, "the legend lies over the curves"
