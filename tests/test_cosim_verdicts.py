"""No silent wrong answers: every verdict is that of the loop the FMUs run, and a
verdict that the run's own cross-check contradicts is an error.

Oracles: model (b) of docs/latency.md (the exact delayed sampled-data loop, itself checked
against an event-by-event simulation in test_latency.py) from the paper's A and B
(harness.paper.analysis.lateral_system, not the FMU's); the sweep's verdict for the same
delays; the deliberately mismatched cases are loops that are not linear (a control clipped at
u_max = 1e-3 rad, far inside what the unit initial states ask for) or that hold a state the
identified map has not (a delayed controller where the importer's identification assumes
none), so any verdict from them contradicts the run's own check.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from dronefly.cli.app import main
from dronefly.models.feedback import integral_gain_name
from dronefly.harness.stability.run import RATE_TOL_PER_WINGBEAT, cosimulate
from dronefly.harness.cosim.identification import classify
from dronefly.harness.latency.designs import DESIGNS, design
from dronefly.harness.latency.sampled import sampled_margin, sampled_rates
from dronefly.models.lateral_interface import N_HZ

pytestmark = pytest.mark.integration

ROOT = Path(__file__).resolve().parents[1]

#: a control clipped far inside what the identification runs ask for: not a linear loop
CLIPPED = {"controller.limit_enabled": "1", "controller.u_max": "0.001"}


@pytest.fixture(scope="module")
def fmus(built_fmus):
    return built_fmus["DroneFlyLateral"], built_fmus["StateFeedback"]


def _timing(d: int, loop) -> dict[str, float]:
    """The controller's settings for d whole samples of delay, sampled once per wing beat,
    and the design's integral gains (SI: seconds)."""
    out = {"controller.sensing_delay": d / N_HZ, "controller.sample_period": 1.0 / N_HZ}
    for i, j in zip(*np.nonzero(loop.KI)):
        out[f"controller.{integral_gain_name(int(i), int(j))}"] = float(loop.KI[i, j])
    return out


@pytest.mark.parametrize("name", DESIGNS)
def test_cosim_flips_the_verdict_at_the_sampled_margin(fmus, name):
    """cosimulate with the controller delayed d = floor(margin) and d + 1 whole samples
    (sampled once per wing beat, step 1 wing beat): the verdict identified from the runs is
    model (b)'s at both (kept at d, lost at d + 1), its dominant rate model (b)'s within
    RATE_TOL_PER_WINGBEAT (a simple eigenvalue of a fit with residual ~1e-15), and the run's
    cross-checks pass. (A 4-state map fitted to the 4 (d + 1)-state loop would give the wrong
    verdict: stabilising at d = 6: 'unstable', +0.01085.)"""
    loop = design(name)
    m = sampled_margin(loop)
    verdicts = []
    for d in (m.whole, m.whole + 1):
        r = cosimulate(*fmus, gains=loop.K, step_wingbeats=1.0, stop_wingbeats=40.0,
                       out_dir=None, plot=False, set_values=_timing(d, loop))
        exact = sampled_rates(loop, 1.0, float(d))
        assert r.check_failures == [], (name, d, r.check_failures)
        assert r.model_b == (1.0, float(d))
        assert r.loop_states == 4 * (d + 1) + len(loop.integrated)
        assert r.verdict == classify(exact), (name, d, r.verdict)
        assert abs(r.identification.dominant_growth_rate - float(np.max(exact.real))) \
            <= RATE_TOL_PER_WINGBEAT, (name, d)
        verdicts.append(r.verdict)
    assert verdicts[0] in ("stable", "neutral") and verdicts[1] == "unstable", (name, verdicts)


def test_cli_cosim_at_six_and_seven_samples_matches_the_sweep(fmus, tmp_path, capsys):
    """The issue's case through the CLI: the stabilising gains, sampled once per wing beat,
    6 and 7 wing beats of delay: stable (-0.00888 per wing beat) then unstable (+0.00872), as
    `dronefly sweep --delays 6,7 --sample-periods 1` says (its stability and
    stability_identified columns), exit 0."""
    from dronefly.harness.sweep.cases import SweepSpec
    from dronefly.harness.sweep.run import run_sweep

    rates = {}
    for d in (6, 7):
        argv = ["cosim", "--plant", str(fmus[0]), "--controller", str(fmus[1]),
                "--gains", "stabilising", "--step", "1", "--stop", "40",
                "--set", f"controller.sensing_delay={d / N_HZ!r}",
                "--set", f"controller.sample_period={1 / N_HZ!r}",
                "--json", "--no-plot", "--out", str(tmp_path / "cosim")]
        assert main(argv) == 0
        out = json.loads(capsys.readouterr().out)
        assert out["check_failures"] == []
        rates[d] = (out["verdict"], out["dominant_growth_rate_per_wingbeat"])
    spec = SweepSpec.from_text(disturbances="directions", slices="dgamma:dv", grid=2, lhs=1,
                               directions="+dgamma", amplitudes=1, gains="stabilising",
                               steps="1", scales="1", stop="20", master="gauss-seidel",
                               seed=0, extent=1.0, delays="6,7", sample_periods="1")
    res = run_sweep(spec, tmp_path / "sweep", plant=fmus[0], controller=fmus[1], workers=1,
                    plot=False, progress_bar=False)
    sweep = {round(g["delay_wb"]): g for g in res.summary["delay_groups"]}
    for d, verdict in ((6, "stable"), (7, "unstable")):
        assert rates[d][0] == verdict == sweep[d]["stability"] == sweep[d]["stability_identified"]
        # both are model (b) of the same loop: the dominant rates agree to the fit's rounding
        assert abs(rates[d][1] - sweep[d]["stability_rate"]) <= RATE_TOL_PER_WINGBEAT
    # docs/latency.md's numbers (its `dronefly cosim` example), to the 5 decimals it prints
    import re

    text = " ".join((ROOT / "docs" / "latency.md").read_text(encoding="utf-8").split())
    m = re.search(r"says `stable` \(([-+0-9.]+) per wing beat\) then `unstable` \(([-+0-9.]+)\)",
                  text)
    assert m
    assert math.isclose(rates[6][1], float(m.group(1)), abs_tol=5e-6)
    assert math.isclose(rates[7][1], float(m.group(2)), abs_tol=5e-6)


def test_sample_instants_off_the_grid_are_refused(fmus, tmp_path, capsys):
    """A sample period that is not a whole number of steps (0.0060976 s = 1.0000064 wing
    beats at a step of 1 wing beat: the instants drift off the grid) is refused in one line
    naming the value, exit 2, nothing written."""
    argv = ["cosim", "--plant", str(fmus[0]), "--controller", str(fmus[1]), "--gains",
            "stabilising", "--step", "1", "--set", "controller.sensing_delay=0.036585",
            "--set", "controller.sample_period=0.0060976", "--no-plot", "--out",
            str(tmp_path / "out")]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and "0.0060976" in err and "Traceback" not in err
    assert not (tmp_path / "out").exists()


# --- every verdict-producing path with a deliberately mismatched case -----------------------
def test_cosim_with_a_clipped_control_fails_its_cross_check(fmus, tmp_path, capsys):
    """cosim: the clipped loop's identification leaves a fit residual far above rounding and
    its trajectory leaves the linear one: 'cross-check failed', exit 1, outputs kept."""
    argv = ["cosim", "--plant", str(fmus[0]), "--controller", str(fmus[1]), "--stop", "30",
            *[a for k, v in CLIPPED.items() for a in ("--set", f"{k}={v}")],
            "--no-plot", "--out", str(tmp_path)]
    assert main(argv) == 1
    cap = capsys.readouterr()
    assert "cross-check failed" in cap.err
    assert "CROSS-CHECK FAILED" in cap.out
    assert list(tmp_path.glob("*.csv")) and list(tmp_path.glob("*.json"))


def test_cosim_system_with_a_clipped_control_fails_its_cross_check(built_fmus, tmp_path,
                                                                   capsys):
    """cosim --system: the same clipped controller inside the hover system: exit 1."""
    ssp = built_fmus["DroneFlyHover.ssp"]
    argv = ["cosim", "--system", str(ssp), "--stop", "20", "--no-plot", "--out", str(tmp_path),
            "--set", "lateral_controller.limit_enabled=1",
            "--set", "lateral_controller.u_max=0.001"]
    assert main(argv) == 1
    assert "cross-check failed" in capsys.readouterr().err


def test_demo_with_a_clipped_control_fails_its_cross_check(fmus, tmp_path, capsys):
    """demo: the same clipped controller for both runs. The open loop (no control) passes,
    the Eq. (27) loop is marked in the table and the command exits 1, outputs kept."""
    argv = ["demo", "--no-plot", "--out", str(tmp_path / "cosim"), "--build",
            str(fmus[0].parent), *[a for k, v in CLIPPED.items() for a in ("--set", f"{k}={v}")]]
    assert main(argv) == 1
    cap = capsys.readouterr()
    assert "cross-check failed (paper)" in cap.err and "(open)" not in cap.err
    assert "cross-check failed" in next(ln for ln in cap.out.splitlines()
                                        if ln.startswith("paper "))
    assert len(list((tmp_path / "cosim").glob("*.csv"))) == 2


# --- point 2: a plant and a controller that disagree on their scales ------------------------
def _sampled_rates_oracle(K: np.ndarray, h: float) -> np.ndarray:
    """log(eig(Phi + Gamma K)) / h of the model's A, B (scipy's expm of the augmented
    matrix, not the harness's discretisation), per wing beat, sorted by real part."""
    from scipy.linalg import expm

    from dronefly.models import lateral_dynamics

    A, B = lateral_dynamics.system_matrices(lateral_dynamics.default_parameters())
    E = expm(np.block([[A, B], [np.zeros((3, 7))]]) * h)
    mu = np.linalg.eigvals(E[:4, :4] + E[:4, 4:] @ K)
    return np.sort_complex(np.log(mu.astype(complex)) / h)


def test_plant_and_controller_scales_must_agree_unless_intended(fmus, tmp_path, capsys):
    """--set plant.n=200 with the controller at 164 Hz: refused in one line naming both
    values (exit 2, nothing written), in cosim and in sweep. With --allow-scale-mismatch the
    run goes ahead, and its model is the loop the FMUs run: the controller reads x+ scaled by
    n_p / n_c on the rates, so the identified rates are those of Phi + Gamma K diag(1, r, r, 1),
    r = 200 / 164, within 1e-9 (the fit's rounding times the eigenvalues' condition numbers,
    < 1e3), and the cross-checks pass."""
    base = ["--plant", str(fmus[0]), "--controller", str(fmus[1]), "--no-plot", "--stop", "30"]
    assert main(["cosim", *base, "--set", "plant.n=200", "--out", str(tmp_path / "a")]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1
    assert "plant.n = 200.0 Hz" in err and "controller.n = 164.0 Hz" in err
    assert not (tmp_path / "a").exists()
    assert main(["cosim", *base, "--set", "controller.U=2.0", "--out", str(tmp_path / "a")]) == 2
    assert "controller.U = 2.0 m/s" in capsys.readouterr().err
    assert main(["sweep", "--plant", str(fmus[0]), "--controller", str(fmus[1]), "--workers",
                 "1", "--no-plot", "--no-progress", "--set", "plant.n=200",
                 "--out", str(tmp_path / "s")]) == 2
    assert "controller.n = 164.0 Hz" in capsys.readouterr().err
    assert not (tmp_path / "s").exists()

    assert main(["cosim", *base, "--set", "plant.n=200", "--allow-scale-mismatch", "--json",
                 "--out", str(tmp_path / "b")]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["check_failures"] == []
    r = 200.0 / N_HZ
    K = np.array(out["gains"]) * np.array([1.0, r, r, 1.0])
    got = np.sort_complex(np.array([complex(*e) for e in out["eigenvalues_per_wingbeat"]]))
    np.testing.assert_allclose(got, _sampled_rates_oracle(K, 0.1), rtol=0, atol=1e-9)


# --- point 3: an initial state given with --set ---------------------------------------------
def test_set_plant_start_takes_effect_or_the_conflict_is_refused(fmus, tmp_path, capsys):
    """--set plant.delta_gamma_start=0.3 starts the run at 0.3 rad (the CSV's first row, read
    as a number); with --x0 as well the two are refused in one line naming both (exit 2,
    nothing written); the sweep, which sets every case's initial state, refuses it too."""
    import csv

    base = ["--plant", str(fmus[0]), "--controller", str(fmus[1]), "--no-plot", "--stop", "5"]
    assert main(["cosim", *base, "--set", "plant.delta_gamma_start=0.3", "--json",
                 "--out", str(tmp_path / "a")]) == 0
    out = json.loads(capsys.readouterr().out)
    with open(out["csv"], newline="") as f:
        rows = list(csv.DictReader(f))
    assert float(rows[0]["delta_gamma"]) == 0.3
    assert [float(rows[0][s]) for s in ("delta_v", "delta_p", "delta_r")] == [0.0, 0.0, 0.0]
    assert out["check_failures"] == []  # the exact solution is taken from the same x0

    assert main(["cosim", *base, "--set", "plant.delta_gamma_start=0.3", "--x0=0,0,0,0.1",
                 "--out", str(tmp_path / "b")]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1
    assert "plant.delta_gamma_start = 0.3" in err and "--x0" in err
    assert not (tmp_path / "b").exists()
    assert main(["sweep", "--plant", str(fmus[0]), "--controller", str(fmus[1]), "--workers",
                 "1", "--no-plot", "--no-progress", "--set", "plant.delta_gamma_start=0.3",
                 "--out", str(tmp_path / "s")]) == 2
    assert "delta_gamma_start" in capsys.readouterr().err
    assert not (tmp_path / "s").exists()


# --- point 4: files a user did not ask to change ---------------------------------------------
def test_cosim_builds_only_what_is_missing_and_leaves_a_user_file_alone(tmp_path, capsys):
    """cosim with the default FMUs: the first run builds both into --build and says so; a
    second run finds them up to date (same bytes, same modification times, nothing said); an
    FMU built from other sources (its package hash) is rebuilt; a file the build did not write
    at an FMU's path is left alone with one line naming it (exit 2), as in `dronefly build`."""
    import zipfile

    build = tmp_path / "build"
    argv = ["cosim", "--build", str(build), "--stop", "1", "--no-plot", "--out",
            str(tmp_path / "out")]
    assert main(argv) == 0
    out = capsys.readouterr().out
    fmus = [build / "DroneFlyLateral.fmu", build / "StateFeedback.fmu"]
    assert all(f"built {p}" in out for p in fmus)
    before = [(p.read_bytes(), p.stat().st_mtime_ns) for p in fmus]
    assert main(argv) == 0
    assert "built" not in capsys.readouterr().out
    assert [(p.read_bytes(), p.stat().st_mtime_ns) for p in fmus] == before

    # the same FMU as from older sources: another package hash in slavemodule.txt
    stale = fmus[1]
    with zipfile.ZipFile(stale) as z:
        members = {n: z.read(n) for n in z.namelist()}
    members["resources/slavemodule.txt"] = b"dronefly_statefeedback_0000000000000000_slave"
    with zipfile.ZipFile(stale, "w") as z:
        for n, data in members.items():
            z.writestr(n, data)
    assert main(argv) == 0
    assert f"built {stale}" in capsys.readouterr().out
    assert stale.read_bytes() == before[1][0]

    stale.write_text("my notes\n", encoding="utf-8")
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and str(stale) in err and "left alone" in err
    assert stale.read_text(encoding="utf-8") == "my notes\n"
    assert main(["build", "--out", str(build)]) == 2
    assert str(stale) in capsys.readouterr().err
    assert stale.read_text(encoding="utf-8") == "my notes\n"

    # simulate: the same rule for its plant FMU
    sim = tmp_path / "sim"
    for expect in (True, False):
        assert main(["simulate", "--stop", "1", "--out", str(sim)]) == 0
        assert (f"built {sim / 'DroneFlyLateral.fmu'}" in capsys.readouterr().out) is expect


# --- point 10: the core install -------------------------------------------------------------
#: every optional package of the extras (pyproject.toml), as if not installed
OPTIONAL = ("matplotlib", "tqdm", "threadpoolctl", "distributed", "dask", "libcosimpy")


@pytest.fixture
def core_install(monkeypatch):
    """The optional packages blocked (``import`` raises ImportError, as when not installed)."""
    import sys

    for m in OPTIONAL:
        monkeypatch.setitem(sys.modules, m, None)


def test_every_command_runs_on_the_core_install(core_install, fmus, tmp_path, capsys):
    """With no extra installed, each command runs with its optional parts turned off
    (demo and cosim --no-plot, sweep --workers 1 --no-plot --no-progress), and with them on
    it runs without them, one line naming the extra for each part skipped."""
    plant, ctrl = (str(p) for p in fmus)
    build = str(fmus[0].parent)
    runs = [
        ["build", "--out", str(tmp_path / "build")],
        ["check", "--no-fuzz", plant],
        ["simulate", "--stop", "2", "--out", str(tmp_path / "sim")],
        ["cosim", "--plant", plant, "--controller", ctrl, "--stop", "2", "--no-plot",
         "--out", str(tmp_path / "cosim")],
        ["demo", "--no-plot", "--build", build, "--out", str(tmp_path / "demo")],
        ["analyze", "--out", str(tmp_path / "analysis.txt")],
        ["sweep", "--plant", plant, "--controller", ctrl, "--workers", "1", "--no-plot",
         "--no-progress", "--disturbances", "directions", "--directions", "+dgamma",
         "--amplitudes", "1", "--gains", "paper", "--steps", "1", "--stop", "5",
         "--out", str(tmp_path / "sweep")],
    ]
    for argv in runs:
        assert main(argv) == 0, (argv, capsys.readouterr().err)
        capsys.readouterr()
    for argv, extra, what in (
            (["demo", "--build", build, "--out", str(tmp_path / "d2")], "plot", "plots"),
            (runs[-1][:5] + ["--workers", "2", *runs[-1][7:]], "sweep",
             "one BLAS thread per worker process")):
        assert main(argv) == 0
        err = [line for line in capsys.readouterr().err.splitlines() if "skipped" in line]
        assert len(err) == 1 and f"dronefly-fmu[{extra}]" in err[0], err
        assert err[0].startswith(f"dronefly {argv[0]}: {what} skipped: ")


# --- point 5: setuptools' build tree and a checkout named dronefly ---------------------------
def test_setuptools_builds_apart_from_the_fmus():
    """`pip install .` builds with setuptools in the checkout: its build/lib and
    build/bdist.* (as setuptools itself resolves them from setup.cfg, where the project sets
    its build folder; pyproject.toml sets none) lie outside build/, where the FMUs are
    built."""
    import subprocess
    import sys

    code = ("from setuptools.dist import Distribution\n"
            "d = Distribution({'name': 'x'}); d.parse_config_files(['setup.cfg'])\n"
            "for c, a in (('build', 'build_lib'), ('build', 'build_temp'), ('bdist', 'bdist_base')):\n"
            "    cmd = d.get_command_obj(c); cmd.ensure_finalized(); print(getattr(cmd, a))\n")
    r = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True,
                       timeout=60)
    assert r.returncode == 0, r.stderr
    dirs = [(ROOT / line).resolve() for line in r.stdout.split()]
    assert len(dirs) == 3
    for d in dirs:
        assert not d.is_relative_to(ROOT / "build"), d


def test_the_installed_package_holds_every_module_of_the_checkout():
    """A wheel installs the packages pyproject.toml lists (the root folder is ``dronefly``):
    every folder of the package that holds an ``__init__.py`` is listed, so what an editable
    install finds by path a plain ``pip install`` installs too (and the data files beside
    the FMUs' slaves)."""
    import tomllib

    config = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]
    assert config["package-dir"] == {"dronefly": "."}
    skip = ("tests", "docs", "benchmarks", "build")
    folders = {p.parent.relative_to(ROOT) for p in ROOT.rglob("__init__.py")
               if not p.relative_to(ROOT).parts[0].startswith(".")
               and p.relative_to(ROOT).parts[0] not in skip}
    assert set(config["packages"]) == {".".join(("dronefly", *f.parts)) for f in folders}
    for pkg, patterns in config["package-data"].items():  # the README and reference files
        folder = ROOT / Path(*pkg.split(".")[1:])        # of each FMU folder, check's schema
        assert any(list(folder.glob(p)) for p in patterns), pkg


def test_a_checkout_named_dronefly_is_the_package(tmp_path):
    """Python started in the folder that holds a checkout named dronefly imports the checkout
    as the package: the checkout's root folder is the package, so that is the same code (no
    folder of the checkout, build/ with its FMUs included, passes for a module)."""
    import subprocess
    import sys

    (tmp_path / "dronefly").symlink_to(ROOT, target_is_directory=True)
    code = ("import dronefly.harness.builder.build as b, dronefly.cli.app as m; "
            "print(b.__file__); print(m.__file__)")
    r = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, capture_output=True,
                       text=True, timeout=60,
                       env={k: v for k, v in __import__("os").environ.items()
                            if k != "PYTHONPATH"})
    assert r.returncode == 0, r.stderr
    assert r.stdout.split() == [str(tmp_path / "dronefly" / "harness" / "builder" / "build.py"),
                                str(tmp_path / "dronefly" / "cli" / "app.py")]


# --- point 8: analyze --targets puts the design first ---------------------------------------
def test_analyze_targets_prints_the_design_first(capsys):
    """With --targets the designed gains are the first line of the text and the first key of
    the JSON; they place the targets: eig(A1 + b k) with the model's A1, b (Table 1) equal
    the targets to 1e-9 (distinct, well-separated targets: the eigenvalues of the closed
    loop move by about cond(V) * 1e-15 * |k|, cond(V) < 1e3 here)."""
    from dronefly.models import lateral_dynamics

    targets = "--targets=-0.2,-0.089+0.057j,-0.089-0.057j,-0.51"
    assert main(["analyze", targets]) == 0
    first = capsys.readouterr().out.splitlines()[0]
    assert first.startswith("Design for the given targets with delta_Phi_a: k = ")
    assert main(["analyze", targets, "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert next(iter(out)) == "custom_design"
    k = np.array(out["custom_design"]["gains"])
    # the printed line holds the same gains (6 decimals)
    printed = [float(v) for v in first.split("k = (")[1].rstrip(")").split(",")]
    np.testing.assert_allclose(printed, k, rtol=0, atol=5e-7)
    A, B = lateral_dynamics.system_matrices(lateral_dynamics.default_parameters())
    got = np.sort_complex(np.linalg.eigvals(A + np.outer(B[:, 0], k)))
    want = np.sort_complex(np.array([-0.2, -0.089 + 0.057j, -0.089 - 0.057j, -0.51]))
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-9)


# --- point 6: identified from runs vs computed from matrices --------------------------------
def test_cosim_says_which_eigenvalues_are_identified_and_which_computed(fmus, capsys):
    """The README's design (Ackermann, targets -0.1 .. -0.4) co-simulated at a step of 0.1
    wing beats: the runs identify the exact sampled-data loop, -0.1002, -0.1942, -0.3385,
    -0.3716 (scipy's expm of the model's A, B with the zero-order hold; 1e-9: the fit's
    rounding, 5e-14 found), not eig(A + B K) = the targets, which the output labels as
    computed from the matrices."""
    from dronefly.harness.paper.analysis import ackermann_gains, lateral_system

    A, B = lateral_system()
    K = np.zeros((3, 4))
    K[0] = ackermann_gains(A, B, [-0.1, -0.2, -0.3, -0.4], u="delta_Phi_a")
    r = cosimulate(*fmus, gains=K, stop_wingbeats=30, out_dir=None, plot=False)
    ident = np.sort(r.identified_eigenvalues.real)
    np.testing.assert_allclose(ident, np.sort(_sampled_rates_oracle(K, 0.1).real), atol=1e-9)
    np.testing.assert_allclose(ident, [-0.3716, -0.3385, -0.1942, -0.1002], atol=5e-5)
    assert np.max(np.abs(ident - [-0.4, -0.3, -0.2, -0.1])) > 1e-3  # the hold shows
    text = r.summary()
    assert "identified from the co-simulated runs" in text
    assert "computed from the plant FMU's A1, B1 and K" in text
    assert "identified from the co-simulated runs" in r.to_json()["eigenvalues_source"]


# --- point 7: the altitude lost, and with which controllers ---------------------------------
def test_altitude_lost_says_with_which_controllers():
    """README and docs/validity.md: the 0.22 rad roll's sink over 100 wing beats in the
    nonlinear plant, with both controllers (4.753 mm) and with the lateral one alone
    (9.762 mm), each quoted to its printed rounding (0.05 mm)."""
    import re

    from dronefly.harness.validity.terms import term_errors

    both = 1e3 * term_errors("+dgamma").altitude_lost_m["all"]
    alone = 1e3 * term_errors("+dgamma", longitudinal_control=False).altitude_lost_m["all"]
    assert alone > 1.5 * both  # the longitudinal controller recovers part of the sink
    for doc, pattern in (
            ("README.md", r"costs ([0-9.]+) mm of altitude in 100 wing beats with both "
                          r"controllers flying .*?, ([0-9.]+) mm with the lateral controller "
                          r"alone"),
            ("docs/validity.md", r"it loses ([0-9.]+) mm in 100 wing beats \(0\.61 s\) with "
                                 r"both controllers flying .*?, ([0-9.]+) mm with the lateral "
                                 r"controller alone")):
        text = " ".join((ROOT / doc).read_text(encoding="utf-8").split())
        m = re.search(pattern, text)
        assert m, doc
        assert abs(float(m.group(1)) - both) <= 0.05 and abs(float(m.group(2)) - alone) <= 0.05


# --- point 9: docs/latency.md names every design --------------------------------------------
def test_latency_doc_names_every_design():
    """docs/latency.md's section on the designs names each of DESIGNS as design("name"), with
    its label (the design's own, as tables print it) and nothing that is not a design."""
    import re

    from dronefly.harness.latency.designs import designs

    text = (ROOT / "docs" / "latency.md").read_text(encoding="utf-8")
    section = text.split("## The designs", 1)[1].split("\n## ", 1)[0]
    named = re.findall(r'`design\("([a-z0-9_]+)"\)`', section)
    assert sorted(named) == sorted(DESIGNS) and len(named) == len(set(named))
    for name, loop in designs().items():
        bullet = next(b for b in section.split("\n- ") if b.startswith(f'`design("{name}")`'))
        words = {"eq27": "as printed", "eq27_exact": "exactly", "stabilising": "-0.1",
                 "lqr": "Bryson", "pi": "PI"}[name]
        assert words in bullet and words in loop.name, (name, loop.name)


def test_jacobi_with_a_delay_line_is_model_b_and_its_lag_with_integral_action_is_refused(fmus):
    """Jacobi with 6 samples of sensing delay, sampled once per wing beat: the verdict and
    rate of model (b) (the master's lag is inside the delay), cross-checks passed. Jacobi
    without sensing delay but with integral gains is not model (b) (its lag delays the sensed
    state, not its integral: the trajectory check would fail by 6e-4): refused before any run."""
    from dronefly.harness.cosim.master import CoSimError

    loop = design("stabilising")
    r = cosimulate(*fmus, gains=loop.K, master="jacobi", step_wingbeats=1.0,
                   stop_wingbeats=40.0, out_dir=None, plot=False, set_values=_timing(6, loop))
    exact = sampled_rates(loop, 1.0, 6.0)
    assert r.check_failures == [] and r.verdict == classify(exact) == "stable"
    assert abs(r.identification.dominant_growth_rate - float(np.max(exact.real))) \
        <= RATE_TOL_PER_WINGBEAT
    with pytest.raises(CoSimError, match="Jacobi master and no sensing delay"):
        cosimulate(*fmus, gains=loop.K, master="jacobi", stop_wingbeats=5.0, out_dir=None,
                   plot=False, set_values={"controller.KI[1,4]": -0.001})


def test_system_instances_must_agree_on_their_scales(built_fmus, tmp_path, capsys):
    """cosim --system: an instance's U set apart from the others' (each reads the states with
    its own) is refused in one line naming every value, exit 2, nothing written."""
    argv = ["cosim", "--system", str(built_fmus["DroneFlyHover.ssp"]), "--stop", "5",
            "--no-plot", "--out", str(tmp_path / "out"), "--set", "lateral.U=2.0"]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1
    assert "lateral.U = 2.0" in err and "lateral_controller.U = 3.77" in err
    assert not (tmp_path / "out").exists()


def test_sweep_with_a_clipped_control_fails_its_cross_check(fmus, tmp_path, capsys):
    """sweep with delay axes: the clipped controller's identified verdict disagrees with the
    loop's model (linear); the sweep says 'cross-check failed' and exits 1, rows kept."""
    argv = ["sweep", "--plant", str(fmus[0]), "--controller", str(fmus[1]), "--workers", "1",
            "--no-plot", "--no-progress", "--disturbances", "directions", "--directions",
            "+dgamma", "--amplitudes", "1", "--gains", "stabilising", "--steps", "1", "--stop",
            "20", "--delays", "1", "--sample-periods", "1", "--out", str(tmp_path),
            *[a for k, v in CLIPPED.items() for a in ("--set", f"{k}={v}")]]
    assert main(argv) == 1
    assert "cross-check failed" in capsys.readouterr().err
    assert len((tmp_path / "sweep.csv").read_text().splitlines()) == 2
