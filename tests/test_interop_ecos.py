"""The third importer: the closed-loop SSP co-simulated by Ecos (ecospy 0.7.2).

Ecos runs in a child process (:mod:`dronefly.harness.interop.ecos`). Its fixed-step master is
Jacobi with the controller fed x_0 before the first step, so its trajectory must equal
``Loop.run(master="jacobi")`` (default u_source0: the plant's initial outputs) to rounding, and
differ from Gauss-Seidel; its verdict of the paper's gains is neutral. FMI 3.0: Ecos runs
build/fmi3/DroneFlyHover.ssp as our Jacobi master does, and cannot bind the FMI 3.0 closed loop's
gains (it takes an array for a scalar).

On Linux x86_64, where the test extra installs ecospy and tbb, an Ecos that cannot be loaded
fails every test with the reason, unless DRONEFLY_ALLOW_NO_ECOS=1 lets them skip; elsewhere
they skip with the reason.
"""

from __future__ import annotations

import ctypes.util
import json
import os
import platform
import subprocess
import sys

import numpy as np
import pytest
from numpy.testing import assert_allclose

from dronefly.models.feedback import default_gains
from dronefly.harness.cosim.fmu import FMU
from dronefly.harness.cosim.master import CoSimError, Loop
from dronefly.harness.cosim.identification import TOL_PER_WINGBEAT
from dronefly.harness.interop.ecos import (ecos_available, ecos_env, ecos_verdict, run_ecos,
    tbb_library_dir)
from dronefly.harness.interop.ssp import ssp_parameter_set
from dronefly.harness.paper import printed as pv
from dronefly.models.lateral_interface import scale_vector

pytestmark = pytest.mark.integration

STATES = ("delta_v", "delta_p", "delta_r", "delta_gamma")
CONTROLS = ("delta_Phi_a", "delta_alpha_1a", "delta_alpha_2a")
H = 0.1 / 164.0  # 0.1 wing beat, the SSP's step
X0 = np.array([0.02, 0.05, -0.03, 0.1])  # non-dimensional initial state, all states moving
N = 3000  # 300 wing beats


#: set to 1 to let the Ecos tests skip where ecospy should work but does not
ALLOW_NO_ECOS = "DRONEFLY_ALLOW_NO_ECOS"


def ecos_expected() -> bool:
    """Whether the test extra installs ecospy and tbb here (pyproject: Linux x86_64)."""
    return sys.platform.startswith("linux") and platform.machine() in ("x86_64", "AMD64")


def require_ecos(why: str | None) -> None:
    """Nothing if Ecos works (``why`` is None); else fail (Linux x86_64, unless
    DRONEFLY_ALLOW_NO_ECOS=1) or skip, with the reason."""
    if why and ecos_expected() and os.environ.get(ALLOW_NO_ECOS) != "1":
        pytest.fail(f"Ecos is unavailable on Linux x86_64, where the test extra installs ecospy "
                    f"and tbb: {why} (set {ALLOW_NO_ECOS}=1 to skip the Ecos tests)",
                    pytrace=False)
    if why:
        pytest.skip(why)


@pytest.fixture(scope="module")
def ecos():
    require_ecos(ecos_available())


@pytest.fixture(scope="module")
def ssp(built_fmus):
    return built_fmus["DroneFlyClosedLoop.ssp"]


@pytest.fixture(scope="module")
def bound(ssp):
    """The SSP's parameter bindings, by component: {"plant": {...}, "controller": {...}}."""
    out: dict[str, dict[str, float]] = {"plant": {}, "controller": {}}
    for p in ssp_parameter_set(ssp).parameters:
        comp, name = p.name.split(".", 1)
        out[comp][name] = float(p.value)
    return out


@pytest.fixture(scope="module")
def loop(built_fmus):
    with FMU(built_fmus["DroneFlyLateral"]) as p, FMU(built_fmus["StateFeedback"]) as c:
        yield Loop(p, c)


def _max_abs_rel(a: np.ndarray, b: np.ndarray) -> tuple[float, float]:
    """max |a - b| and the same per column relative to that column's peak |b|."""
    d = np.abs(a - b)
    return float(d.max()), float(np.max(d / np.maximum(np.abs(b).max(axis=0), 1e-300)))


def test_ecos_is_the_jacobi_loop(ecos, ssp, bound, loop):
    """Ecos' trajectory (x_k, and the control applied over step k) from a state with every
    component nonzero, with the SSP's gains, equals our Jacobi master's to rounding: measured
    0.0 (the same arithmetic in the same order) over 3000 steps; tolerance 1e-12. Ecos
    accumulates its time (t_k = t_(k-1) + h). Against Gauss-Seidel the one-step delay shows."""
    start = {f"{s}_start": float(v) for s, v in zip(STATES, X0 * np.array(scale_vector()))}
    r = run_ecos(ssp, n_steps=N, overrides={f"plant.{k}": v for k, v in start.items()})
    assert r.complete, r.error
    assert r.names == [*STATES, *CONTROLS]
    assert_allclose(r.time, np.arange(N + 1) * H, rtol=0, atol=1e-12)
    ja = loop.run(H, N, master="jacobi", plant_start=start, controller_params=bound["controller"])
    dev, rel = _max_abs_rel(r.signals, ja.signals)
    assert dev <= 1e-12 and rel <= 1e-12, f"Ecos vs Jacobi master: {dev:.2e} ({rel:.2e} rel.)"
    gs = loop.run(H, N, master="gauss-seidel", plant_start=start,
                  controller_params=bound["controller"])
    assert _max_abs_rel(r.signals, gs.signals)[1] > 1e-4, "Ecos is not Gauss-Seidel"


def test_ecos_applies_every_binding_of_the_ssp(ecos, ssp, bound, loop):
    """With nothing overridden, Ecos runs the SSP's own values (x+_0 = (0, 0, 0, 0.1), Eq. 27
    gains), although it keys SSP parameter sets by SSV name (``plant``, ``controller``) and
    applies one per init: run_ecos sets all of them. delta_gamma at 300 wing beats: 0.010684."""
    r = run_ecos(ssp, n_steps=N)
    assert r.complete, r.error
    assert r.column("delta_gamma")[0] == bound["plant"]["delta_gamma_start"] == 0.1
    ja = loop.run(H, N, master="jacobi", plant_start=bound["plant"],
                  controller_params=bound["controller"])
    assert _max_abs_rel(r.signals, ja.signals)[0] <= 1e-12
    assert abs(r.column("delta_gamma")[-1] - 0.010684) < 1e-6


def test_ecos_verdicts(ecos, ssp):
    """Neutral with the paper's gains (the same rate as the other importers), unstable open
    loop at the plant's divergent rate (Eq. 19)."""
    v = ecos_verdict(ssp)
    ident = v.identification
    assert v.verdict == "neutral"
    assert abs(ident.dominant_growth_rate) <= TOL_PER_WINGBEAT
    assert abs(ident.dominant_growth_rate - 7.7e-5) < 1e-6
    assert_allclose(ident.eigenvalues[:4], list(pv.eq27_targets()), atol=1e-3)
    assert ident.fit_residual < 1e-10
    zero = {f"controller.K[{i},{j}]": 0.0 for i in range(1, 4) for j in range(1, 5)}
    open_loop = ecos_verdict(ssp, overrides=zero)
    assert open_loop.verdict == "unstable"
    assert_allclose(open_loop.identification.dominant_growth_rate, float(pv.EQ19_A_LNN[0][0]),
                    atol=1e-3)


def test_ecos_runs_the_fmus_where_the_host_cannot_import_numpy_or_scipy(ecos, ssp, tmp_path):
    """pythonfmu runs the FMU's code in the host's interpreter; an FMU that imported numpy
    would fail to instantiate where numpy cannot be imported (a fresh venv with only ecospy and
    tbb; here: numpy and scipy hidden on PYTHONPATH), and fmi4c wraps the NULL in a non-NULL
    handle and passes it to fmi2SetupExperiment: SIGSEGV. The FMUs need only the standard
    library, and the closed loop runs."""
    for name in ("numpy", "scipy"):
        hide = tmp_path / "hide" / name
        hide.mkdir(parents=True)
        (hide / "__init__.py").write_text(f"raise ImportError('{name} hidden for this test')\n")
    env = dict(os.environ, PYTHONPATH=str(tmp_path / "hide"))
    r = run_ecos(ssp, n_steps=10, env=env)
    assert r.complete, r.error


def test_ecospy_needs_tbb_on_the_library_path(ecos):
    """ecospy's libecosc.so needs libtbb.so.12, which the PyPI package tbb installs where the
    loader does not look; ecos_env puts that folder on LD_LIBRARY_PATH."""
    lib = tbb_library_dir()
    if lib is None or ctypes.util.find_library("tbb"):
        pytest.skip("libtbb comes from the system here, not from the tbb package")
    code = "import ecospy"
    env = {k: v for k, v in os.environ.items() if k != "LD_LIBRARY_PATH"}
    r = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True)
    assert r.returncode != 0 and "libtbb.so.12: cannot open shared object file" in r.stderr
    r = subprocess.run([sys.executable, "-c", code], env=ecos_env(env), capture_output=True,
                       text=True)
    assert r.returncode == 0, r.stderr
    assert ecos_env(env)["LD_LIBRARY_PATH"].split(os.pathsep)[0] == lib


def test_an_unavailable_ecos_fails_unless_allowed(monkeypatch):
    """The fixture's rule: on Linux x86_64 a broken install is a failure naming the reason;
    DRONEFLY_ALLOW_NO_ECOS=1 turns it into a skip; a working Ecos passes."""
    if not ecos_expected():
        pytest.skip("the rule is for Linux x86_64")
    why = "ecospy cannot be loaded: libtbb.so.12: cannot open shared object file"
    monkeypatch.delenv(ALLOW_NO_ECOS, raising=False)
    with pytest.raises(pytest.fail.Exception, match=r"unavailable on Linux x86_64.*libtbb"):
        require_ecos(why)
    monkeypatch.setenv(ALLOW_NO_ECOS, "1")
    with pytest.raises(pytest.skip.Exception, match="libtbb"):
        require_ecos(why)
    require_ecos(None)


# -- FMI 3.0 ---------------------------------------------------------------------------------


def test_ecos_runs_the_fmi3_hover_system_as_our_jacobi_master(ecos, built_fmus3):
    """build/fmi3/DroneFlyHover.ssp (four FMI 3.0 FMUs): with every binding set (run_ecos) both
    axes' states over 60 wing beats equal our Jacobi master's; measured 0.0, tolerance 1e-12.
    The SSV values are not the FMUs' defaults (0.1 rad roll and pitch; defaults 0)."""
    from dronefly.harness.stability.system_verdicts import cosimulate_system

    ssp = built_fmus3["DroneFlyHover.ssp"]
    ours = cosimulate_system(ssp, master="jacobi", stop_wingbeats=60, verdicts=False,
                             out_dir=None, plot=False).run
    for axis, angle in (("lateral", "delta_gamma"), ("longitudinal", "delta_theta")):
        r = run_ecos(ssp, n_steps=600, plant=axis)
        assert r.complete, r.error
        assert r.column(angle)[0] == 0.1
        states = [n for n in r.names if f"{axis}.{n}" in ours.names]
        assert len(states) == 4
        want = np.column_stack([ours.signals[:, ours.names.index(f"{axis}.{n}")] for n in states])
        assert np.max(np.abs(r.states(states) - want)) <= 1e-12, axis
        assert np.max(np.abs(want[-1])) > 1e-3  # the loop moved


#: probes of Ecos with FMI 3.0 FMUs, in a child process (ecospy needs tbb's LD_LIBRARY_PATH)
_PROBE = r"""
import json, sys
from ecospy import EcosLib, EcosSimulation
EcosLib.set_log_level("error")
loop, hover = sys.argv[1:3]
out = {}
sim = EcosSimulation(step_size=0.1 / 164, ssp_path=loop)
try:
    sim.set_real("controller::K[1,1]", -0.3192)
except Exception as e:
    out["set_element"] = str(e)
sim.init(parameter_set="plant")
out["K"] = sim.get_real("controller::K")
sim.step(3000)
out["delta_gamma"] = sim.get_real("plant::delta_gamma")
sim.terminate(); sim.free()
sim = EcosSimulation(step_size=0.1 / 164, ssp_path=loop)
try:
    sim.get_real("controller::K")  # before init: not yet readable
except Exception as e:
    out["K_before_init"] = str(e)
sim.init(parameter_set="plant")
out["delta_Phi_a_after"] = sim.get_real("controller::delta_Phi_a")
sim.terminate(); sim.free()
sim = EcosSimulation(step_size=0.1 / 164, ssp_path=loop)
EcosLib.set_log_level("warn")  # shows the bindings it skips
sim.init(parameter_set="controller")
EcosLib.set_log_level("error")
sim.terminate(); sim.free()
sim = EcosSimulation(step_size=0.1 / 164, ssp_path=hover)
sim.init(parameter_set="lateral")
out["hover_lateral_set"] = [sim.get_real("lateral::delta_gamma"),
                            sim.get_real("longitudinal::delta_theta")]
sim.terminate(); sim.free()
for tag, path in zip(("Float64", "Real"), sys.argv[3:5]):  # SSP 2.0 array parameters
    try:
        sim = EcosSimulation(step_size=0.1 / 164, ssp_path=path)
    except Exception as e:
        out[tag] = str(e)
        continue
    EcosLib.set_log_level("debug")  # shows the FMUs' messages
    out[tag] = sim.init(parameter_set="controller")
    sim.step(1)
    EcosLib.set_log_level("error")
    sim.terminate(); sim.free()
print(json.dumps(out))
"""


def _ssp2_gains(ssp, out, tag):
    """A copy of the closed-loop SSP whose controller.ssv binds the array K as SSP 2.0 writes
    it: one Parameter, ``ssv:<tag>`` with 12 values row-major, two ``ssc:Dimension``."""
    import zipfile

    ssv = ('<?xml version="1.0" encoding="utf-8"?>\n<ssv:ParameterSet xmlns:ssv="http://'
           'ssp-standard.org/SSP1/SystemStructureParameterValues" xmlns:ssc="http://ssp-standard'
           '.org/SSP1/SystemStructureCommon" version="2.0" name="controller"><ssv:Parameters>'
           f'<ssv:Parameter name="K"><ssv:{tag} value="'
           + " ".join(repr(k) for row in default_gains() for k in row)
           + '"/><ssc:Dimension size="3"/><ssc:Dimension size="4"/></ssv:Parameter>'
           '</ssv:Parameters></ssv:ParameterSet>\n')
    with zipfile.ZipFile(ssp) as zi, zipfile.ZipFile(out, "w") as zo:
        for name in zi.namelist():
            zo.writestr(name, ssv if name == "resources/controller.ssv" else zi.read(name))
    return out


def test_ecos_takes_an_fmi3_array_for_a_scalar(ecos, built_fmus3, bound, loop, tmp_path):
    """What Ecos 0.7.2 (fmi4c) does with the FMI 3.0 array K of build/fmi3/DroneFlyClosedLoop.ssp:

    - the elements K[i,j] are no variables to it (set_real: "No real property ... found!");
      the SSP's controller.ssv binds no K (SSP 1.0 binds scalars; the FMU's start values are
      the gains), so run_ecos runs the SSP;
    - it registers K as one Float64, its first element (K[1,1] = -0.3192);
    - with only the plant's set applied (init(parameter_set="plant")) the controller runs its
      defaults, which are the SSV's gains: delta_gamma after 3000 steps is our Jacobi
      master's with the FMI 2.0 FMUs and the SSP's values (0.010684);
    - after a read of K before init, it reads the controller's values in one fmi3GetFloat64
      call that includes K, one value per variable: the 11 further values of K shift the rest,
      and delta_Phi_a reads K[1,2] = -0.2879;
    - it applies one SSV set per init (hover: the lateral set, not the longitudinal one);
    - K bound as an SSP 2.0 array parameter: ``ssv:Float64`` is no SSP 1.0 element to it
      (the SSP is not loaded); ``ssv:Real`` with 12 values: it sets K with one value, which
      the FMU refuses (logged; the step after is refused), and Ecos goes on. fmpy's read_ssd
      refuses both (SSP 1.0 schema).
    """
    from fmpy.ssp.ssd import read_ssd

    loop3, hover = built_fmus3["DroneFlyClosedLoop.ssp"], built_fmus3["DroneFlyHover.ssp"]
    r = run_ecos(loop3, n_steps=10)
    assert r.complete, r.error
    ssp2 = [_ssp2_gains(loop3, tmp_path / f"{tag}.ssp", tag) for tag in ("Float64", "Real")]
    for path, why in zip(ssp2, ("Float64': This element is not expected",
                                "is not a valid value of the atomic type 'xs:double'")):
        with pytest.raises(Exception, match=r"(?s)The value '2.0' is not accepted.*" + why):
            read_ssd(str(path))
    p = subprocess.run([sys.executable, "-c", _PROBE, str(loop3), str(hover), *map(str, ssp2)],
                       env={**ecos_env(), "TMPDIR": str(tmp_path)}, capture_output=True,
                       text=True, timeout=300)
    out, log = json.loads(p.stdout.strip().splitlines()[-1]), p.stdout + p.stderr
    assert "No real property controller::K[1,1] found!" in out["set_element"]
    assert "No variable named 'K[1,1]'" not in log  # the SSV binds only what the FMU has
    assert out["K"] == default_gains()[0][0] == -0.3192
    ja = loop.run(H, N, master="jacobi", plant_start=bound["plant"],
                  controller_params=bound["controller"])
    # the same arithmetic in the same order (0.0 apart when measured); 1e-12 allows for a
    # libm or BLAS of another machine under either side
    assert abs(out["delta_gamma"] - ja.column("delta_gamma")[-1]) < 1e-12
    assert out["delta_Phi_a_after"] == default_gains()[0][1] == -0.2879
    assert out["hover_lateral_set"] == [0.1, 0.0]
    assert out["Float64"] == "Unknown XML node in ssv:Parameter encountered!"
    assert out["Real"] is True
    assert "fmi3SetFloat64: K = -0.3192 rejected: 12 values needed, 1 given" in log
    assert "step refused at t = 0.0 s: fmi3SetFloat64: K = -0.3192 rejected" in log


def test_ecos_verdict_of_a_loop_it_does_not_model_is_refused(ecos, built_fmus, tmp_path):
    """The closed-loop SSP with StateFeedbackDelayed (one wing beat of sensing delay): the
    8-state Jacobi map has no state for the delay line; its fit's residual is far above
    rounding, so ecos_verdict raises CrossCheckError instead of giving a verdict."""
    from dronefly.core.errors import CrossCheckError
    from dronefly.harness.builder.closedloop import write_ssp

    delayed = write_ssp(built_fmus["DroneFlyLateral"], built_fmus["StateFeedbackDelayed"],
                        tmp_path)
    with pytest.raises(CrossCheckError, match="Ecos .*fit residual"):
        ecos_verdict(delayed)
