"""Interoperability: a second importer (libcosim), the SSP, the container FMU, a C host.

Every run here gives a trajectory that is compared with ``harness.cosim.master.Loop`` under the
same master algorithm, and a verdict classified by ``harness.cosim.identification.identify``.
"""

from __future__ import annotations

import json
import os
import platform
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest
from numpy.testing import assert_allclose
from shared_files import provided_on_ci

from dronefly.harness.paper import printed as pv
from dronefly.models.lateral_interface import scale_vector
from dronefly.harness.builder.closedloop import CLOSED_LOOP, fix_connection_types, write_container
from dronefly.harness.interop.container import container_verdict, run_container
from dronefly.harness.interop.ssp import run_ssp, ssp_parameter_set, ssp_verdict
from dronefly.harness.cosim.fmu import FMU
from dronefly.harness.interop.libcosim import (c_host_env, libcosim_available, libcosim_verdict,
    libpython_path, run_libcosim, step_ns)
from dronefly.harness.cosim.master import Loop
from dronefly.harness.cosim.identification import TOL_PER_WINGBEAT

pytestmark = pytest.mark.integration

STATES = ("delta_v", "delta_p", "delta_r", "delta_gamma")
CONTROLS = ("delta_Phi_a", "delta_alpha_1a", "delta_alpha_2a")
N_HZ = 164.0
H = 0.1 / N_HZ  # 0.1 wing beat
#: non-dimensional -> dimensional state (U, n, n, 1), U as the plant FMU's default
SCALE = np.array(scale_vector())
X0 = np.array([0.02, 0.05, -0.03, 0.1])  # non-dimensional initial state for the comparisons
PAPER_TARGETS = list(pv.eq27_targets())


def _start(x: np.ndarray) -> dict[str, float]:
    return {f"{s}_start": float(v) for s, v in zip(STATES, x * SCALE)}


def _rel_dev(a: np.ndarray, b: np.ndarray) -> float:
    """max |a - b| per column, relative to that column's peak |b|."""
    peak = np.maximum(np.abs(b).max(axis=0), 1e-300)
    return float(np.max(np.abs(a - b) / peak))


@pytest.fixture(scope="module")
def fmus(built_fmus):
    return built_fmus["DroneFlyLateral"], built_fmus["StateFeedback"]


@pytest.fixture(scope="module")
def ssp(built_fmus):
    path = built_fmus["DroneFlyLateral"].with_name(f"{CLOSED_LOOP}.ssp")
    assert path.is_file(), "build_all writes the SSP next to the FMUs"
    return path


@pytest.fixture(scope="module")
def container(built_fmus):
    path = built_fmus["DroneFlyLateral"].with_name(f"{CLOSED_LOOP}.fmu")
    assert path.is_file(), "build_all writes the container FMU next to the FMUs"
    return path


@pytest.fixture(scope="module")
def harness_loop(fmus):
    with FMU(fmus[0]) as p, FMU(fmus[1]) as c:
        yield Loop(p, c)


# -----------------------------------------------------------------------------
# libcosim: the second importer
@pytest.fixture(scope="module")
def libcosim():
    why = libcosim_available()
    if why:
        if sys.platform.startswith("linux") and platform.machine() in ("x86_64", "AMD64") \
                or sys.platform == "win32":
            pytest.fail(f"{why}: libcosimpy has wheels for this platform and the test extra "
                        "installs it")
        pytest.skip(f"{why} (no libcosimpy wheel for {sys.platform}/{platform.machine()})")


def test_libcosim_equals_the_jacobi_harness(libcosim, fmus, harness_loop):
    """libcosim's fixed-step master is Jacobi: the plant's input over step k is the controller
    output read after step k-1 (u_k = K x_(k-1)), and before the first step the controller holds
    what libcosim transferred in initialization mode (recorded as ``controller_inputs0``; 0 for
    our plant, whose outputs take x_0 at fmi2ExitInitializationMode). That is exactly
    ``Loop.run(master="jacobi", u_source0=x_(-1))`` at the same step (libcosim's time is in whole
    nanoseconds: 609 756 ns), so the two agree to rounding: measured 5e-14 relative over 3000
    steps (300 wing beats); tolerance 1e-9. Against the Gauss-Seidel harness the one-step delay
    shows at the 1e-3 level.
    """
    h = step_ns(0.1, N_HZ)
    n = 3000
    r = run_libcosim(*fmus, step_ns=h, n_steps=n, plant_start=_start(X0))
    assert r.complete, r.error
    assert r.names == [*STATES, *CONTROLS]
    assert_allclose(r.time, np.arange(n + 1) * h * 1e-9, rtol=0, atol=1e-15)
    x_prev = [r.controller_inputs0[s] for s in STATES]
    ja = harness_loop.run(h * 1e-9, n, master="jacobi", plant_start=_start(X0), u_source0=x_prev)
    dev = _rel_dev(r.signals, ja.signals)
    assert dev <= 1e-9, f"libcosim vs Jacobi harness: {dev:.2e}"
    gs = harness_loop.run(h * 1e-9, n, master="gauss-seidel", plant_start=_start(X0))
    assert _rel_dev(r.signals, gs.signals) > 1e-4, "libcosim is not Gauss-Seidel"


def test_libcosim_verdicts(libcosim, fmus):
    v = libcosim_verdict(*fmus)
    ident, h_wb = v.identification, v.step_wb
    assert abs(h_wb - 0.1) < 1e-6
    assert ident.verdict == "neutral"
    assert abs(ident.dominant_growth_rate) <= TOL_PER_WINGBEAT
    assert_allclose(ident.eigenvalues[:4], PAPER_TARGETS, atol=1e-3)
    assert ident.fit_residual < 1e-10
    zero = {f"K[{i},{j}]": 0.0 for i in range(1, 4) for j in range(1, 5)}
    open_loop = libcosim_verdict(*fmus, gains=zero).identification
    assert open_loop.verdict == "unstable"
    assert_allclose(open_loop.dominant_growth_rate, float(pv.EQ19_A_LNN[0][0]), atol=1e-3)


def test_libcosim_runs_the_ssp(libcosim, fmus, ssp):
    """libcosim loads the SSP itself (component parameter bindings applied) and gives the
    same trajectory as the loop it builds from the two FMUs."""
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimObserver import CosimObserver

    h = step_ns(0.1, N_HZ)
    n = 200
    ex = CosimExecution.from_ssp_file(str(ssp), h)
    obs = CosimObserver.create_last_value()
    ex.add_observer(obs)
    assert ex.step(n)
    infos = {i.name.decode(): i.index for i in ex.slave_infos()}
    pv = {v.name.decode(): v.reference for v in ex.slave_variables(infos["plant"])}
    last = obs.last_real_values(infos["plant"], [pv[s] for s in STATES])
    params = {p.name.split(".", 1)[1]: float(p.value) for p in ssp_parameter_set(ssp).parameters
              if p.name.startswith("plant.")}
    direct = run_libcosim(*fmus, step_ns=h, n_steps=n, plant_start=params)
    assert_allclose(last, direct.states()[-1], rtol=1e-12, atol=0)
    assert params["delta_gamma_start"] == 0.1
    assert abs(last[3]) > 1e-3  # the bound initial state was applied (else all would stay 0)


# -----------------------------------------------------------------------------
# SSP
def test_ssp_content(ssp):
    from fmpy.ssp.ssd import find_components, get_connections, read_ssd

    from dronefly.models.feedback import default_gains

    ssd = read_ssd(str(ssp))  # schema-validated by fmpy
    assert [c.name for c in find_components(ssd.system)] == ["plant", "controller"]
    cons = {(a.parent.name, a.name, b.parent.name, b.name)
            for a, b in get_connections(ssd.system)}
    assert cons == {("plant", s, "controller", s) for s in STATES} | {
        ("controller", u, "plant", u) for u in CONTROLS}
    params = {p.name: float(p.value) for p in ssp_parameter_set(ssp).parameters}
    assert params["plant.delta_gamma_start"] == 0.1
    assert [params[f"controller.K[1,{j}]"] for j in range(1, 5)] == list(default_gains()[0])
    names = zipfile.ZipFile(ssp).namelist()
    assert {"resources/DroneFlyLateral.fmu", "resources/StateFeedback.fmu",
            "resources/plant.ssv", "resources/controller.ssv"} <= set(names)


def test_ssp_run_is_the_delayed_loop(ssp, harness_loop):
    """fmpy's SSP master (fmpy/ssp/simulation.py): connectors start at 0; each step sets inputs
    from connectors, steps, reads outputs, then applies all connections. So u_0 = u_1 = 0 and
    u_k = K x_(k-1) after that, and the row stamped t_j holds x_(j+1): from x_1 on this is the
    Jacobi harness started at x_1 with a zero previous state. Same arithmetic, so 1e-12."""
    res = run_ssp(ssp)  # the SSP's own parameters and default experiment
    assert len(res) == 3000
    xs = np.column_stack([res[f"plant.{s}"] for s in STATES])
    ja = harness_loop.run(H, len(xs) - 1, master="jacobi",
                          plant_start=dict(zip((f"{s}_start" for s in STATES), xs[0])),
                          u_source0=[0.0] * 4)
    assert _rel_dev(xs, ja.signals[:, :4]) <= 1e-12


def test_ssp_verdict_is_neutral(ssp):
    ident = ssp_verdict(ssp).identification
    assert ident.verdict == "neutral"
    assert_allclose(ident.eigenvalues[:4], PAPER_TARGETS, atol=1e-3)
    assert ident.fit_residual < 1e-10


# -----------------------------------------------------------------------------
# container FMU
def _fmpy_cli(*args: str, cwd: Path) -> subprocess.CompletedProcess:
    exe = shutil.which("fmpy", path=str(Path(sys.executable).parent))
    cmd = [exe] if exe else [sys.executable, "-c", "from fmpy.cli import main; main()"]
    return subprocess.run([*cmd, *args], cwd=cwd, capture_output=True, text=True, timeout=120)


def test_container_passes_fmpy_validate(container, tmp_path):
    r = _fmpy_cli("validate", str(container), cwd=tmp_path)
    assert r.returncode == 0, r.stdout + r.stderr
    assert "No problems found" in r.stdout


def test_container_fmpy_simulate_cli(container, tmp_path):
    out = tmp_path / "closed_loop.csv"
    r = _fmpy_cli("simulate", str(container), "--output-interval", repr(H),
                  "--output-file", str(out), cwd=tmp_path)
    assert r.returncode == 0, r.stdout + r.stderr
    from fmpy.util import read_csv

    data = read_csv(str(out))
    assert len(data) == 3001 and data["time"][-1] == pytest.approx(300 / N_HZ)
    assert data["delta_gamma"][0] == 0.1
    # neutral: the state neither decays to 0 nor grows; it settles on the neutral mode
    tail = np.column_stack([data[s] for s in STATES])[-100:]
    assert np.all(np.abs(tail[:, 3]) > 1e-3) and np.ptp(tail, axis=0).max() < 1e-3


def test_container_is_the_gauss_seidel_loop(container, harness_loop):
    """Measured: the container resolves its connections in initialization (the plant's outputs
    already hold x_0 there, so u_0 = K x_0) and after every step (plant -> controller ->
    plant; the controller is direct feedthrough): u_k = K x_k, the Gauss-Seidel harness."""
    res = run_container(container, start_values=_start(X0))
    sig = np.column_stack([res[n] for n in (*STATES, *CONTROLS)])
    assert_allclose(sig[0, :4], X0 * SCALE)
    gs = harness_loop.run(H, len(sig) - 1, master="gauss-seidel", plant_start=_start(X0))
    assert _rel_dev(sig, gs.signals) <= 1e-12


def test_container_verdict_is_neutral(container):
    ident = container_verdict(container).identification
    assert ident.verdict == "neutral"
    assert_allclose(ident.eigenvalues[:4], PAPER_TARGETS, atol=1e-3)
    assert ident.fit_residual < 1e-10


def test_fix_connection_types_only_renames_connection_types():
    cfg = {"variables": [{"variableType": "Real"}],
           "connections": [{"variableType": "Real"}, {"variableType": "Integer"},
                            {"variableType": "Float64"}, {"variableType": "Boolean"}]}
    fix_connection_types(cfg)
    assert [c["variableType"] for c in cfg["connections"]] == ["Float64", "Int32", "Float64",
                                                              "Boolean"]
    assert cfg["variables"] == [{"variableType": "Real"}]


def test_fmpy_container_workaround_is_needed_and_works(fmus, container, tmp_path,
                                                       monkeypatch):
    """fmpy 0.3.32 writes FMI 2 connection types ("Real") that its container binary rejects;
    with the types renamed the same container runs. If fmpy fixes its writer, the raw
    container must run too and the fix is a no-op (then the workaround can go). The run that
    fails leaves no extracted FMU in the temporary folder."""
    import tempfile

    raw = write_container(*fmus, tmp_path, fix=False, name="Raw")
    types = {c["variableType"] for c in json.loads(
        zipfile.ZipFile(raw).read("resources/container.json"))["connections"]}
    ours = json.loads(zipfile.ZipFile(container).read("resources/container.json"))
    assert {c["variableType"] for c in ours["connections"]} == {"Float64"}
    if types == {"Real"}:
        scratch = tmp_path / "scratch"
        scratch.mkdir()
        monkeypatch.setattr(tempfile, "tempdir", str(scratch))
        with pytest.raises(Exception, match="instantiate"):
            run_container(raw, stop_s=5 * H)
        assert list(scratch.iterdir()) == []
        monkeypatch.undo()
    else:
        assert types == {"Float64"}
        run_container(raw, stop_s=5 * H)
    assert len(run_container(container, stop_s=5 * H)) == 6


def test_closed_loop_artefacts_are_reproducible(fmus, ssp, container, tmp_path):
    from dronefly.harness.builder.build import build_closed_loop

    again = build_closed_loop(tmp_path, *fmus)
    assert [p.read_bytes() for p in again] == [ssp.read_bytes(), container.read_bytes()]


# -----------------------------------------------------------------------------
# a C host (no Python in the process until libpython is preloaded)
@pytest.fixture(scope="module")
def c_host(tmp_path_factory, fmus):
    if not sys.platform.startswith("linux"):
        pytest.skip("the C host test uses dlopen and linux64 binaries")
    cc = shutil.which(os.environ.get("CC", "gcc")) or shutil.which("cc")
    if cc is None:
        provided_on_ci("no C compiler (.ci/setup-c-host.sh installs gcc)")
    if libpython_path() is None:
        provided_on_ci("this Python has no shared libpython (Py_ENABLE_SHARED = 0) and none of "
                       "the same version is installed; .ci/setup-c-host.sh installs Debian's")
    import fmpy

    inc = Path(fmpy.__file__).parent / "c-code"
    out = tmp_path_factory.mktemp("c_host")
    exe = out / "fmi2_host"
    src = Path(__file__).parent / "c_host" / "fmi2_host.c"
    r = subprocess.run([cc, "-std=c99", "-D_POSIX_C_SOURCE=200809L", "-O1", "-Wall", "-Werror",
                        f"-I{inc}", "-o", str(exe), str(src), "-ldl"],
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    args = [str(exe), "300", repr(H)]
    for path in fmus:
        d = out / path.stem
        with zipfile.ZipFile(path) as z:
            z.extractall(d)
        md = fmpy.read_model_description(str(path))
        args += [str(d), md.coSimulation.modelIdentifier, md.guid]
    pv = {v.name: v.valueReference for v in fmpy.read_model_description(str(fmus[0])).modelVariables}
    cv = {v.name: v.valueReference for v in fmpy.read_model_description(str(fmus[1])).modelVariables}
    args += [",".join(str(pv[s]) for s in STATES), ",".join(str(cv[s]) for s in STATES),
             ",".join(str(cv[u]) for u in CONTROLS), ",".join(str(pv[u]) for u in CONTROLS),
             ",".join(f"{pv[k]}={v!r}" for k, v in _start(X0).items())]
    return args


def test_c_host_without_libpython_fails_with_undefined_symbol(c_host):
    env = {k: v for k, v in os.environ.items() if k not in ("LD_PRELOAD", "PYTHONHOME")}
    r = subprocess.run(c_host, env=env, capture_output=True, text=True, timeout=60)
    assert r.returncode == 2, r.stderr
    assert "undefined symbol: _Py" in r.stderr, r.stderr


def test_c_host_with_libpython_preloaded_runs_the_loop(c_host, harness_loop):
    """With LD_PRELOAD=<libpython>, PYTHONHOME and PYTHONPATH (``c_host_env``) the C host runs
    both FMUs in one process; its Gauss-Seidel loop equals the harness's (same calls, same
    arithmetic; printed with 17 digits): tolerance 1e-12 relative."""
    r = subprocess.run(c_host, env=c_host_env(), capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    rows = np.array([[float(x) for x in line.split(",")] for line in r.stdout.splitlines()])
    assert rows.shape == (301, 8)
    gs = harness_loop.run(H, 300, master="gauss-seidel", plant_start=_start(X0))
    assert_allclose(rows[:, 0], gs.time, rtol=1e-15)
    assert _rel_dev(rows[:, 1:], gs.signals) <= 1e-12


def test_container_declares_only_platforms_all_its_fmus_have(container, fmus):
    """The container's binaries are exactly the platforms of the container binary that every
    nested FMU also ships (the nested FMUs have no darwin64 binary)."""
    import zipfile as zf

    def platforms(path):
        with zf.ZipFile(path) as z:
            return {n.split("/")[1] for n in z.namelist()
                    if n.startswith("binaries/") and n.count("/") >= 2 and not n.endswith("/")}

    nested = set.intersection(*(platforms(f) for f in fmus))
    assert platforms(container) == nested == {"linux64", "win64"}


# -----------------------------------------------------------------------------
# a verdict the identification's own fit contradicts is an error
@pytest.fixture(scope="module")
def delayed_pair(built_fmus, tmp_path_factory):
    """The plant with StateFeedbackDelayed (one wing beat of sensing delay, ten steps of 0.1):
    a loop with a delay line that the importers' 4- and 8-state maps have no state for."""
    out = tmp_path_factory.mktemp("delayed_loop")
    from dronefly.harness.builder.closedloop import write_container
    from dronefly.harness.builder.closedloop import write_ssp

    plant, ctrl = built_fmus["DroneFlyLateral"], built_fmus["StateFeedbackDelayed"]
    return plant, ctrl, write_ssp(plant, ctrl, out), write_container(plant, ctrl, out)


def test_importer_verdicts_of_a_loop_they_do_not_model_are_refused(delayed_pair):
    """fmpy's SSP run and the container FMU of the delayed loop: the fit of the map without
    delay states leaves a residual far above rounding (O(1e-2) and more, against 1e-15 for the
    loop it models): CrossCheckError naming the importer, never a verdict."""
    from dronefly.core.errors import CrossCheckError

    _, _, ssp_path, container_path = delayed_pair
    with pytest.raises(CrossCheckError, match="fmpy SSP .*fit residual"):
        ssp_verdict(ssp_path)
    with pytest.raises(CrossCheckError, match="container .*fit residual"):
        container_verdict(container_path)


def test_libcosim_verdict_of_a_loop_it_does_not_model_is_refused(libcosim, delayed_pair):
    from dronefly.core.errors import CrossCheckError

    plant, ctrl, _, _ = delayed_pair
    with pytest.raises(CrossCheckError, match="libcosim .*fit residual"):
        libcosim_verdict(plant, ctrl)
