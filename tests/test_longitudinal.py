"""The longitudinal motion of Sect. 3.5: plant model, FMUs and designs against the paper and
independent oracles.

Oracles: the paper's text itself (A, B of Sect. 3.5, Eq. 31 and the Sect. 2.4 flight data are
parsed from the Markdown of the paper), numpy's eigenvalues, scipy's ``solve_ivp`` (DOP853), an
Ackermann formula written here, python-control, and a numeric minimisation written here. No
number is a snapshot of this project's own output.
"""

from __future__ import annotations

import itertools
import math
import re
from pathlib import Path

import numpy as np
import pytest
from numpy.testing import assert_allclose

from dronefly.models import feedback as L
from dronefly.core.errors import DroneflyError
from dronefly.harness.paper import longitudinal as lon
from dronefly.models.longitudinal_interface import CONTROL_NAMES, IY_PLUS, LONGITUDINAL, STATE_NAMES
from dronefly.models import longitudinal_dynamics

from fmu_helpers import model_description, set_values, start
from shared_files import need_shared

pytestmark = pytest.mark.numeric  # also run under a second BLAS kernel (.ci/run)

ROOT = Path(__file__).resolve().parents[1]
PAPER = ROOT.parent / "shared" / "paper" / "zhang-sun-lateral-stabilization-control.md"
DOC = ROOT / "docs" / "longitudinal.md"
STATES, CONTROLS = list(STATE_NAMES), list(CONTROL_NAMES)
GAINS = [L.gain_name(i, j) for i in range(4) for j in range(4)]
PHIBAR, ALPHA2 = CONTROLS.index("delta_phibar"), CONTROLS.index("delta_alpha_2")


# --- the paper's text ---------------------------------------------------------------------------
@pytest.fixture(scope="module")
def paper() -> str:
    need_shared(PAPER, "the paper's text")
    return PAPER.read_text(encoding="utf-8")


def _section(text: str, start: str, end: str) -> str:
    return text[text.index(start):text.index(end)]


def _printed_matrix(section: str, label: str) -> list[list[str]]:
    """The entries, as printed, of ``label=\\left[\\begin{array}...\\end{array}\\right]``."""
    m = re.search(re.escape(label) + r"=\\left\[\\begin\{array\}\{c+\}(.*?)\\end\{array\}",
                  section, re.S)
    assert m, label
    rows = [r for r in m.group(1).split("\\\\") if r.strip()]
    return [[t.strip() for t in r.split("&")] for r in rows]


def _half_unit(token: str) -> float:
    return 0.5 * 10.0 ** -len(token.split(".")[1]) if "." in token else 0.0


@pytest.fixture(scope="module")
def printed(paper):
    """Sect. 3.5's A, B and Eq. (31)'s A_nn as printed (strings)."""
    s = _section(paper, "### 3.5 The longitudinal motion", "### 3.6")
    return {"A": _printed_matrix(s, r"\boldsymbol{A}"), "B": _printed_matrix(s, r"\boldsymbol{B}"),
            "A_nn": _printed_matrix(s, r"\boldsymbol{A}_{\mathrm{nn}}")}


@pytest.fixture(scope="module")
def AB():
    """A and B of Sect. 3.5 as numbers: parsed from the paper where its text is beside the
    checkout (the oracle's matrices), else the project's transcription of them
    (``A_SECT35``, ``B_SECT35``), which test_model_matrices_are_the_printed_ones checks against
    the text wherever it is present. Only the tests that read the text itself skip without it."""
    if not PAPER.is_file():
        return np.array(longitudinal_dynamics.A_SECT35, dtype=float), np.array(longitudinal_dynamics.B_SECT35, dtype=float)
    s = _section(PAPER.read_text(encoding="utf-8"), "### 3.5 The longitudinal motion", "### 3.6")
    return tuple(np.array([[float(t) for t in r] for r in _printed_matrix(s, label)])
                 for label in (r"\boldsymbol{A}", r"\boldsymbol{B}"))


@pytest.fixture(scope="module")
def designs():
    return {(d.targets, d.inputs): d for d in lon.designs()}


def _sorted(ev):
    ev = np.asarray(ev, dtype=complex)
    return ev[np.lexsort((-ev.imag, -ev.real))]


# --- model ---------------------------------------------------------------------------------------
def test_model_matrices_are_the_printed_ones(printed, AB):
    """A and B of the model (derivatives recovered with m+, Iy+, then rebuilt) equal Sect. 3.5's
    printed matrices; every printed entry has at most 4 decimals."""
    A, B = longitudinal_dynamics.system_matrices(longitudinal_dynamics.default_parameters())
    assert A.shape == B.shape == (4, 4)
    for name, ours, theirs in (("A", A, printed["A"]), ("B", B, printed["B"])):
        for i, j in itertools.product(range(4), range(4)):
            token = theirs[i][j]
            assert _half_unit(token) in (0.0, 5e-5), (name, i, j, token)
            assert abs(ours[i, j] - float(token)) <= 1e-15, (name, i, j, token, ours[i, j])
    assert_allclose(np.array(longitudinal_dynamics.A_SECT35), AB[0], rtol=0, atol=0)
    assert_allclose(np.array(longitudinal_dynamics.B_SECT35), AB[1], rtol=0, atol=0)


def test_model_equations_structure(AB):
    """dtheta' = dq+, A[1,4] = -g+ (Sect. 2.1's 0.0158), no control in the dtheta row."""
    A, B = AB
    p = longitudinal_dynamics.default_parameters()
    assert A[3].tolist() == [0.0, 0.0, 1.0, 0.0] and B[3].tolist() == [0.0] * 4
    assert A[0, 3] == -p.g_plus == -0.0158
    assert p.m_plus == 92.7
    # the derivatives are the printed rows times m+ (x, z) and Iy+ (pitch)
    d = longitudinal_dynamics.derive_derivatives()
    assert d["Mq_plus"] == pytest.approx(A[2, 2] * IY_PLUS, rel=1e-15)
    assert d["Z_alpha_1_plus"] == pytest.approx(B[1, 1] * 92.7, rel=1e-15)


def _inertia_scale() -> float:
    """0.5 rho U^2 S_t c t_w^2 [kg m^2] of Sect. 2.1 from Sect. 2.4's data (rho = 1.25 kg/m^3,
    U = 2 Phi n r2, S_t two wings of 33.34 mm^2, c = 2.98 mm, t_w = 1/n)."""
    return 0.5 * 1.25 * _reference_U()**2 * 2 * 33.34e-6 * 2.98e-3 / 164.0**2


def test_iy_plus_is_iy_in_the_paper_s_nondimensionalisation(paper):
    """Iy+ = Iy Ix+ / Ix with Ix, Iy of Sect. 2.4 and the printed Ix+ (Sect. 2.1).

    Independently, from the Sect. 2.4 flight data: I+ = I / (0.5 rho U^2 S_t c t_w^2). The printed
    Ix+ and Iz+ are the same factor (1.0014) above that, within their print rounding, so Iy+ is
    Iy's raw value times that factor."""
    s24 = _section(paper, "### 2.4 Flight data", "## 3 Results")
    mg_mm2 = {ax: float(re.search(rf"I_{{{ax}}}=(-?[0-9.]+) \\mathrm{{mg}}", s24).group(1))
              for ax in ("x", "y", "z")}
    s21 = _section(paper, "The nondimensional forms are", "Note that the equations of motion")
    ix_plus = re.search(r"I_\{x\}\^\{\+\}=([0-9.]+)", s21).group(1)
    iz_plus = re.search(r"I_\{z\}\^\{\+\}=([0-9.]+)", s21).group(1)
    assert IY_PLUS == pytest.approx(mg_mm2["y"] / mg_mm2["x"] * float(ix_plus), rel=1e-15)
    assert abs(IY_PLUS - 19.895) <= 5e-4  # the value docs/longitudinal.md prints, to its digits
    raw = {k: v * 1e-12 / _inertia_scale() for k, v in mg_mm2.items()}
    fx = float(ix_plus) / raw["x"]
    fz = float(iz_plus) / raw["z"]
    # both printed inertias sit the same factor above the raw ones, within their rounding
    assert abs(fx - fz) <= (_half_unit(ix_plus) / raw["x"] + _half_unit(iz_plus) / raw["z"])
    assert 1.001 < fx < 1.002
    assert IY_PLUS == pytest.approx(raw["y"] * fx, rel=1e-12)
    lo, hi = sorted((raw["y"] * (float(iz_plus) - 0.005) / raw["z"],
                     raw["y"] * (float(iz_plus) + 0.005) / raw["z"]))
    assert lo <= IY_PLUS <= hi, "Iz+'s factor gives the same Iy+ within Iz+'s rounding"


def test_eigenvalues_against_eq31(printed, AB):
    """eig(A) of the model against the eigenvalues Eq. (31) prints (sigma +/- i omega, the fast
    and the slow subsidence), within the printed rounding propagated from A's 4 decimals."""
    Ann = printed["A_nn"]
    want = {"sigma": float(Ann[0][0]), "omega": abs(float(Ann[1][0])), "fast": float(Ann[2][2]),
            "slow": float(Ann[3][3])}
    assert float(Ann[1][1]) == want["sigma"] and abs(float(Ann[0][1])) == want["omega"]

    def quantities(A):
        w = np.linalg.eigvals(A)
        pair = w[np.argmax(w.imag)]
        real = np.sort(w[np.abs(w.imag) < 1e-14].real)
        return {"sigma": pair.real, "omega": pair.imag, "fast": real[0], "slow": real[1]}

    A_model, _ = longitudinal_dynamics.system_matrices(longitudinal_dynamics.default_parameters())
    got = quantities(A_model)
    A = AB[0]
    spread = dict.fromkeys(got, 0.0)
    for i, j in itertools.product(range(4), range(4)):
        h = _half_unit(printed["A"][i][j])
        if h == 0.0:  # structural 0 and 1 (not rounded)
            continue
        d = np.zeros((4, 4))
        d[i, j] = h
        up, dn = quantities(A + d), quantities(A - d)
        for k in spread:
            spread[k] += abs(up[k] - dn[k]) / 2
    tokens = {"sigma": Ann[0][0], "omega": Ann[1][0], "fast": Ann[2][2], "slow": Ann[3][3]}
    for k, v in want.items():
        assert abs(got[k] - v) <= spread[k] + _half_unit(tokens[k]), (k, got[k], v, spread[k])
    assert got["sigma"] > 0 and got["fast"] < got["slow"] < 0  # the modes of Sect. 3.5's text


# --- the plant FMU ---------------------------------------------------------------------------------
def _reference_U() -> float:
    """U = 2 Phi n r2 from Sect. 2.4's data (Phi = 107.1 deg, n = 164 Hz, r2 = 0.55 R, R = 11.2 mm)."""
    return 2 * math.radians(107.1) * 164.0 * 0.55 * 11.2e-3


def _get(inst, names):
    return np.array(inst.slave.getReal(inst.vrs(list(names))))


@pytest.mark.integration
@pytest.mark.parametrize("name", ["DroneFlyLongitudinal", "StateFeedbackLongitudinal"])
def test_fmpy_validate_reports_no_problems(built_fmus, name):
    from fmpy.validation import validate_fmu

    assert validate_fmu(str(built_fmus[name])) == []


@pytest.mark.integration
def test_fmu_matrices_and_scales(longitudinal_plant, AB):
    with longitudinal_plant.instantiate() as inst:
        start(inst)
        A = _get(inst, [f"A[{i},{j}]" for i in range(1, 5) for j in range(1, 5)]).reshape(4, 4)
        B = _get(inst, [f"B[{i},{j}]" for i in range(1, 5) for j in range(1, 5)]).reshape(4, 4)
        n, U = _get(inst, ["n", "U"])
    assert_allclose(A, AB[0], rtol=0, atol=1e-15)
    assert_allclose(B, AB[1], rtol=0, atol=1e-15)
    assert n == 164.0 and U == pytest.approx(_reference_U(), rel=1e-14)


@pytest.mark.integration
def test_fmu_trajectory_against_solve_ivp(longitudinal_plant, AB):
    """Non-zero initial state, inputs held piecewise constant over the communication steps
    (changed three times): the FMU's outputs against DOP853 (rtol 1e-12) on the dimensional
    equations dx/dt = n S A S^-1 x + n S B u, S = diag(U, U, n, 1), with A, B from the paper."""
    from scipy.integrate import solve_ivp

    A, B = AB
    n, U = 164.0, _reference_U()
    S = np.diag([U, U, n, 1.0])
    Ad, Bd = n * S @ A @ np.linalg.inv(S), n * S @ B
    x0 = np.array([0.05, -0.03, 2.0, 0.1])  # m/s, m/s, rad/s, rad
    segments = [  # (wing beats, held controls [rad]) in B's column order
        (8.0, [0.01, -0.02, 0.005, -0.003]),
        (12.0, [0.0, 0.0, -0.02, 0.0]),
        (5.0, [-0.015, 0.01, 0.0, 0.004]),
        (15.0, [0.0, 0.0, 0.0, 0.0])]
    h_wb = 0.5
    times, fmu_x, ref_x = [0.0], [x0], [x0]
    with longitudinal_plant.instantiate() as inst:
        start(inst, {f"{s}_start": v for s, v in zip(STATES, x0)})
        assert_allclose(_get(inst, STATES), x0, rtol=0, atol=0)
        t, x = 0.0, x0
        for length, u in segments:
            inst.slave.setReal(inst.vrs(CONTROLS), u)
            steps = round(length / h_wb)
            t_eval = t + h_wb / n * np.arange(1, steps + 1)
            sol = solve_ivp(lambda _t, y, u=np.array(u): Ad @ y + Bd @ u, (t, t_eval[-1]), x,
                            method="DOP853", rtol=1e-12, atol=1e-15, t_eval=t_eval)
            assert sol.success
            for k, tk in enumerate(t_eval):
                inst.slave.doStep(currentCommunicationPoint=t + k * h_wb / n,
                                  communicationStepSize=h_wb / n)
                fmu_x.append(_get(inst, STATES))
                times.append(tk)
            ref_x += list(sol.y.T)
            t, x = t_eval[-1], sol.y[:, -1]
        assert not [m for m in inst.messages if m.status > 0]
    fmu_x, ref_x = np.array(fmu_x), np.array(ref_x)
    peak = np.abs(ref_x).max(axis=0)
    assert_allclose(fmu_x / peak, ref_x / peak, rtol=0, atol=1e-9)
    assert np.abs(ref_x[-1] - ref_x[0]).max() > 0.1 * peak.min()  # the states really moved


@pytest.mark.integration
def test_plant_outputs_do_not_depend_on_inputs(longitudinal_plant):
    """ModelStructure says no direct feedthrough: setting an input changes no output until doStep."""
    with longitudinal_plant.instantiate() as inst:
        start(inst, {"delta_theta_start": 0.1})
        before = _get(inst, STATES)
        inst.slave.setReal(inst.vrs(CONTROLS), [0.1, -0.1, 0.2, -0.2])
        assert_allclose(_get(inst, STATES), before, rtol=0, atol=0)
        inst.slave.doStep(currentCommunicationPoint=0.0, communicationStepSize=1 / 164.0)
        assert np.all(_get(inst, STATES)[:3] != before[:3])


def _indices(root):
    svs = root.find("ModelVariables").findall("ScalarVariable")
    return svs, {sv.get("name"): i + 1 for i, sv in enumerate(svs)}


def _deps(root, part):
    return {int(u.get("index")): set(map(int, u.get("dependencies").split()))
            for u in root.find(f"ModelStructure/{part}")}


EXPECTED_UNITS = {"delta_u": "m/s", "delta_w": "m/s", "delta_q": "rad/s", "delta_theta": "rad",
                  **{c: "rad" for c in CONTROLS}, "n": "Hz", "U": "m/s",
                  "sensing_delay": "s", "sample_period": "s"}


@pytest.mark.integration
@pytest.mark.parametrize("name", ["DroneFlyLongitudinal", "StateFeedbackLongitudinal"])
def test_every_variable_has_a_description_and_a_unit(built_fmus, name):
    root = model_description(built_fmus[name])
    units = {u.get("name") for u in root.find("UnitDefinitions")}
    svs, idx = _indices(root)
    for sv in svs:
        v, real = sv.get("name"), sv.find("Real")
        assert len(sv.get("description") or "") > 10, v
        if real is None:  # Booleans (saturated, limit_enabled) have no unit
            assert sv.find("Boolean") is not None, v
            continue
        assert real.get("unit") in units, v
        base = v.removesuffix("_start")
        if base in EXPECTED_UNITS:
            assert real.get("unit") == EXPECTED_UNITS[base], v
        elif v != "u_max":
            assert real.get("unit") == "1", v  # non-dimensional parameters, gains, A, B
        if real.get("unit") in ("rad", "rad/s"):
            assert real.get("displayUnit") in ("deg", "deg/s"), v
    assert set(STATES) <= set(idx) and set(CONTROLS) <= set(idx)


def _observed_dependencies(fmu, knowns, unknowns, base, delta):
    """Which knowns change which unknowns, in initialization mode, by setting each known in turn."""
    seen = {u: set() for u in unknowns}
    with fmu.instantiate() as inst:
        s = inst.slave
        s.setupExperiment(startTime=0.0)
        s.enterInitializationMode()
        set_values(inst, base)
        ref = _get(inst, unknowns)
        for k in knowns:
            v0 = s.getReal([fmu.vr(k)])[0]
            s.setReal([fmu.vr(k)], [delta(k, v0)])
            for u, a, b in zip(unknowns, ref, _get(inst, unknowns)):
                if a != b:
                    seen[u].add(k)
            s.setReal([fmu.vr(k)], [v0])
        assert_allclose(_get(inst, unknowns), ref, rtol=0, atol=0)
        assert not [m for m in inst.messages if m.status > 0]
    return seen


@pytest.mark.integration
def test_plant_model_structure_is_truthful(built_fmus, longitudinal_plant):
    """Outputs: no dependencies (no feedthrough). InitialUnknowns: the outputs and the calculated
    A, B; each declared dependency set is exactly what changes the value (perturbation)."""
    root = model_description(built_fmus["DroneFlyLongitudinal"])
    svs, idx = _indices(root)
    name = {i: n for n, i in idx.items()}
    outputs = _deps(root, "Outputs")
    assert sorted(outputs) == [idx[s] for s in STATES] and all(d == set() for d in outputs.values())
    initial = _deps(root, "InitialUnknowns")
    calculated = [sv.get("name") for sv in svs if sv.get("causality") == "calculatedParameter"]
    assert len(calculated) == 32
    assert sorted(initial) == sorted(idx[n] for n in STATES + calculated)
    knowns = [sv.get("name") for sv in svs if sv.get("causality") in ("parameter", "input")]
    unknowns = STATES + calculated
    base = {f"{s}_start": 0.1 for s in STATES} | {  # the two derivatives printed as 0
        "X_Phi_plus": 0.3, "Z_phibar_plus": -0.2}
    seen = _observed_dependencies(longitudinal_plant, knowns, unknowns, base,
                                  lambda k, v: 1.5 * v if v else 0.37)
    for u in unknowns:
        declared = {name[i] for i in initial[idx[u]]}
        assert seen[u] == declared, (u, seen[u], declared)


@pytest.mark.integration
def test_controller_model_structure_is_truthful(built_fmus, longitudinal_controller):
    """Outputs u depend on the state inputs x (direct feedthrough); InitialUnknowns also on the
    gains of their row, n, U and the limit: exactly what changes them (perturbation, with and
    without an active limit)."""
    root = model_description(built_fmus["StateFeedbackLongitudinal"])
    svs, idx = _indices(root)
    name = {i: n for n, i in idx.items()}
    outputs = _deps(root, "Outputs")
    assert sorted(outputs) == sorted(idx[n] for n in CONTROLS + ["saturated"])
    assert all(d == {idx[s] for s in STATES} for d in outputs.values())
    initial = _deps(root, "InitialUnknowns")
    assert set(initial) == set(outputs)
    rng = np.random.default_rng(7)
    K = rng.uniform(0.5, 2.0, (4, 4)) * rng.choice([-1, 1], (4, 4))
    x = LONGITUDINAL.to_dimensional([0.03, -0.02, 0.04, 0.05], _reference_U(), 164.0)
    base = dict(zip(GAINS, K.ravel())) | dict(zip(STATES, x))
    u = K @ np.array([0.03, -0.02, 0.04, 0.05])
    knowns = [n for n in idx if n not in CONTROLS + ["saturated", "limit_enabled"]]
    # a zero known (KI[i,j], sensing_delay, sample_period) is set to 0.01 instead
    free = _observed_dependencies(longitudinal_controller, knowns, CONTROLS, base,
                                  lambda k, v: 1.25 * v if v else 0.01)
    limited = _observed_dependencies(
        longitudinal_controller, ["u_max"], CONTROLS,
        base | {"limit_enabled": True, "u_max": 0.5 * np.abs(u).min()}, lambda k, v: 1.25 * v)
    for i, c in enumerate(CONTROLS):
        declared = {name[j] for j in initial[idx[c]]}
        observed = free[c] | limited[c]
        assert observed == declared - {"limit_enabled"}, (c, observed, declared)
        assert {L.gain_name(i, j) for j in range(4)} | set(STATES) | {"n", "U",
                                                                     "sensing_delay"} == free[c]
        assert "limit_enabled" in declared
    with longitudinal_controller.instantiate() as inst:  # outputs follow the inputs without doStep
        start(inst, {k: v for k, v in base.items() if k in GAINS})
        for xp in rng.normal(0.0, 0.1, (3, 4)):
            inst.slave.setReal(inst.vrs(STATES), list(LONGITUDINAL.to_dimensional(
                xp, _reference_U(), 164.0)))
            assert_allclose(_get(inst, CONTROLS), K @ xp, rtol=1e-12, atol=1e-300)


@pytest.mark.integration
def test_controller_computes_K_x_plus_in_si(longitudinal_controller):
    """Default gains = design (b) in the delta_phibar row; u = K x+ with x+ = (du/U, dw/U, dq/n,
    dtheta) computed here, and equal to the FeedbackLaw on the same numbers."""
    U, n = _reference_U(), 164.0
    rng = np.random.default_rng(3)
    xs = rng.normal(0.0, 1.0, (6, 4)) * [0.1 * U, 0.1 * U, 0.1 * n, 0.1]
    with longitudinal_controller.instantiate() as inst:
        start(inst)
        K0 = _get(inst, GAINS).reshape(4, 4)
        assert_allclose(K0, np.array(L.default_longitudinal_gains()), rtol=0, atol=0)
        assert np.count_nonzero(K0) == 4 and np.count_nonzero(K0[PHIBAR]) == 4
        assert _get(inst, ["n"])[0] == n and _get(inst, ["U"])[0] == pytest.approx(U, rel=1e-14)
        K = rng.uniform(-2.0, 2.0, (4, 4))
        for gains in (K0, K):
            inst.slave.setReal(inst.vrs(GAINS), gains.ravel().tolist())
            law = L.FeedbackLaw(tuple(map(tuple, gains)), axis=LONGITUDINAL)
            for x in xs:
                inst.slave.setReal(inst.vrs(STATES), x.tolist())
                u = _get(inst, CONTROLS)
                xp = x / np.array([U, U, n, 1.0])
                assert_allclose(u, gains @ xp, rtol=1e-12, atol=1e-15)
                assert_allclose(u, law.evaluate(x.tolist())[0], rtol=1e-13, atol=1e-16)
        assert not [m for m in inst.messages if m.status > 0]


def _discarded(inst, t, h):
    from fmpy.fmi1 import FMICallException

    with pytest.raises(FMICallException) as e:
        inst.slave.doStep(currentCommunicationPoint=t, communicationStepSize=h)
    assert e.value.status == 2, "fmi2Discard"
    return inst.messages[-1].message


H = 0.1 / 164.0


@pytest.mark.integration
@pytest.mark.parametrize("bad, fragment", [
    ({"delta_phibar": math.nan}, "delta_phibar = nan"),
    ({"delta_alpha_2": -math.inf}, "delta_alpha_2 = -inf"),
    ({"Iy_plus": math.nan}, "Iy_plus = nan"),
    ({"Iy_plus": 0.0}, "Iy_plus = 0.0"),
    ({"M_phibar_plus": math.inf}, "M_phibar_plus = inf"),
    ({"m_plus": 5e-324}, "is not finite"),  # A = X / m+ overflows
])
def test_plant_bad_value_is_discarded_and_the_instance_recovers(longitudinal_plant, bad, fragment):
    with longitudinal_plant.instantiate() as inst:
        start(inst, {"delta_theta_start": 0.1})
        inst.slave.doStep(currentCommunicationPoint=0.0, communicationStepSize=H)
        before = _get(inst, STATES)
        good = {k: inst.slave.getReal([longitudinal_plant.vr(k)])[0] for k in bad}
        set_values(inst, bad)
        msg = _discarded(inst, H, H)
        assert fragment in msg, msg
        assert_allclose(_get(inst, STATES), before, rtol=0, atol=0, err_msg="state unchanged")
        set_values(inst, good)
        inst.slave.doStep(currentCommunicationPoint=H, communicationStepSize=H)
        after = _get(inst, STATES)
        assert np.all(np.isfinite(after)) and not np.array_equal(after, before)


@pytest.mark.integration
@pytest.mark.parametrize("bad, fragment", [
    ({"delta_q": math.nan}, "delta_q = nan"),
    ({"K[3,2]": math.nan}, "K[3,2] = nan"),
    ({"U": 0.0}, "U = 0.0"),
])
def test_controller_bad_value_is_discarded_and_the_instance_recovers(longitudinal_controller, bad,
                                                                    fragment):
    x = [0.01, -0.02, 0.5, 0.05]
    U = _reference_U()
    want = np.array(L.default_longitudinal_gains()) @ (np.array(x) / [U, U, 164.0, 1.0])
    with longitudinal_controller.instantiate() as inst:
        start(inst, dict(zip(STATES, x)))
        inst.slave.doStep(currentCommunicationPoint=0.0, communicationStepSize=H)
        before = _get(inst, CONTROLS)
        assert_allclose(before, want, rtol=1e-12)
        good = {k: inst.slave.getReal([longitudinal_controller.vr(k)])[0] for k in bad}
        set_values(inst, bad)
        msg = _discarded(inst, H, H)
        assert fragment in msg, msg
        assert_allclose(_get(inst, CONTROLS), before, rtol=0, atol=0)
        set_values(inst, good)
        inst.slave.doStep(currentCommunicationPoint=H, communicationStepSize=H)
        assert_allclose(_get(inst, CONTROLS), want, rtol=1e-12)


# --- designs -------------------------------------------------------------------------------------
def _ackermann(A: np.ndarray, b: np.ndarray, poles) -> np.ndarray:
    """k with eig(A + b k) = poles: k = -e_n^T C^-1 p(A), C = [b, A b, ..., A^(n-1) b]."""
    n = len(A)
    C = np.column_stack([np.linalg.matrix_power(A, i) @ b for i in range(n)])
    p = np.real(np.poly(poles))
    pA = sum(c * np.linalg.matrix_power(A, n - i) for i, c in enumerate(p))
    return -np.linalg.solve(C.T, np.eye(n)[-1]) @ pA


def _targets(A: np.ndarray, kind: str) -> np.ndarray:
    w = np.linalg.eigvals(A)
    pair = w[np.argmax(w.imag)]
    rest = [z for z in w if abs(z.imag) < 1e-14]
    moved = complex(0.0 if kind == "neutral" else -pair.real, pair.imag)
    return _sorted([moved, moved.conjugate(), *rest])


def test_four_designs_place_the_targets(designs, AB):
    A, B = AB
    assert set(designs) == {(k, i) for k in ("neutral", "mirror")
                            for i in (("delta_phibar",), ("delta_phibar", "delta_alpha_2"))}
    for (kind, inputs), d in designs.items():
        t = _targets(A, kind)
        assert_allclose(_sorted(d.target_eigenvalues), t, rtol=0, atol=1e-14)
        ev = _sorted(np.linalg.eigvals(A + B @ d.K))
        assert_allclose(ev, t, rtol=0, atol=1e-10, err_msg=f"{kind} {inputs}")
        assert_allclose(_sorted(d.eigenvalues), ev, rtol=0, atol=1e-12)
        unused = [i for i, c in enumerate(CONTROLS) if c not in inputs]
        assert not d.K[unused].any()
        if kind == "neutral":
            pair = ev[np.abs(ev.imag) > 1e-6]
            assert len(pair) == 2 and np.abs(pair.real).max() < 1e-10
        assert np.max(np.abs(d.place_poles_K - d.K)) < 1e-9 * np.abs(d.K).max()


def test_design_b_gains_are_the_controller_default(designs):
    K = designs[("mirror", ("delta_phibar",))].K
    assert_allclose(K[PHIBAR], L.LONGITUDINAL_GAINS_DESIGN_B, rtol=0, atol=1e-12)
    assert_allclose(np.array(L.default_longitudinal_gains()), K, rtol=0, atol=1e-12)


def test_single_input_designs_equal_ackermann_and_python_control(designs, AB):
    A, B = AB
    for kind in ("neutral", "mirror"):
        d = designs[(kind, ("delta_phibar",))]
        k = _ackermann(A, B[:, PHIBAR], _targets(A, kind))
        assert_allclose(d.K[PHIBAR], k, rtol=1e-9, atol=1e-12)
    import control  # the test extra installs it: a broken install fails
    for kind in ("neutral", "mirror"):
        k = -np.asarray(control.acker(A, B[:, [PHIBAR]], _targets(A, kind))).ravel()
        assert_allclose(designs[(kind, ("delta_phibar",))].K[PHIBAR], k, rtol=1e-8, atol=1e-12)


def test_two_input_design_is_the_least_rank_one_gain(designs, AB):
    """K = w k^T over (delta_phibar, delta_alpha_2), |w| = 1: its Frobenius norm |k| is the least
    over all directions w (found here by a grid of 0.05 deg and golden-section refinement, each k
    by the Ackermann formula above)."""
    A, B = AB
    cols = [PHIBAR, ALPHA2]
    for kind in ("neutral", "mirror"):
        d = designs[(kind, ("delta_phibar", "delta_alpha_2"))]
        t = _targets(A, kind)
        assert np.linalg.matrix_rank(d.K, tol=1e-12) == 1
        assert np.linalg.norm(d.direction) == pytest.approx(1.0, abs=1e-14)
        assert_allclose(d.K[cols], np.outer(d.direction, d.K[cols].T @ d.direction), atol=1e-14)

        def norm(theta: float) -> float:
            return float(np.linalg.norm(_ackermann(A, B[:, cols] @ [np.cos(theta), np.sin(theta)], t)))

        grid = np.linspace(0.0, np.pi, 3601)[:-1]
        values = [norm(th) for th in grid]
        a, b = grid[int(np.argmin(values))] - np.pi / 3600, grid[int(np.argmin(values))] + np.pi / 3600
        g = (math.sqrt(5) - 1) / 2
        for _ in range(60):
            c1, c2 = b - g * (b - a), a + g * (b - a)
            a, b = (a, c2) if norm(c1) < norm(c2) else (c1, b)
        best_theta = (a + b) / 2
        best = norm(best_theta)
        ours = np.linalg.norm(d.K)
        assert ours <= best * (1 + 1e-9), (kind, ours, best)
        assert ours >= best * (1 - 1e-9)
        w_best = np.array([np.cos(best_theta), np.sin(best_theta)])
        assert abs(abs(w_best @ d.direction) - 1.0) < 1e-6
        single = designs[(kind, ("delta_phibar",))]
        assert ours < np.linalg.norm(single.K)  # two inputs need less gain than one


def test_peak_controls_against_solve_ivp(designs, AB):
    """peak_controls (matrix exponential on a 0.05 wing-beat grid) against a DOP853 solution of
    the closed loop sampled 10 times finer: the grid peak is at most the fine one, and close."""
    from scipy.integrate import solve_ivp

    A, B = AB
    d = designs[("mirror", ("delta_phibar",))]
    t = np.linspace(0.0, 300.0, 60001)
    for j in range(4):
        sol = solve_ivp(lambda _t, x: (A + B @ d.K) @ x, (0.0, 300.0), np.eye(4)[j],
                        method="DOP853", rtol=1e-11, atol=1e-14, t_eval=t)
        fine = np.abs(d.K @ sol.y).max()
        assert d.peak_control_rad[j] <= fine * (1 + 1e-8)
        assert d.peak_control_rad[j] >= fine * (1 - 1e-4), (j, d.peak_control_rad[j], fine)


@pytest.mark.parametrize("kind, inputs, needle", [
    ("bogus", ["delta_phibar"], "'bogus'"),
    ("mirror", ["delta_phibar", "delta_bogus"], "'delta_bogus'"),
    ("mirror", [], "[]"),
    ("mirror", ["delta_Phi", "delta_phibar", "delta_alpha_2"], "'delta_Phi'"),
    ("mirror", ["delta_phibar", "delta_phibar"], "'delta_phibar', 'delta_phibar'"),
])
def test_bad_design_inputs_are_refused_naming_the_value(kind, inputs, needle):
    with pytest.raises(DroneflyError) as e:
        lon.design(kind, inputs)
    assert needle in str(e.value), str(e.value)


def test_a_single_input_name_is_one_input():
    """A str is a Sequence[str]: design("mirror", "delta_phibar") is the delta_phibar design."""
    assert_allclose(lon.design("mirror", "delta_phibar").K[PHIBAR], L.LONGITUDINAL_GAINS_DESIGN_B,
                    rtol=0, atol=1e-12)


# --- docs/longitudinal.md -------------------------------------------------------------------------
def _table(text: str, header: str) -> list[list[str]]:
    """The body rows of the Markdown table whose header line starts with ``header``."""
    lines = text.splitlines()
    i = next(k for k, ln in enumerate(lines) if ln.startswith(header))
    rows = []
    for ln in lines[i + 2:]:
        if not ln.startswith("|"):
            break
        rows.append([c.strip() for c in ln.strip("|").split("|")])
    return rows


def _key(design: str, inputs: str) -> tuple[str, tuple[str, ...]]:
    kind = {"(a) neutral": "neutral", "(b) mirror": "mirror"}[design]
    return kind, tuple(s.strip() for s in inputs.split("+"))


def _close(token: str, value: float) -> None:
    """``token`` is ``value`` to the digits printed (half a unit of the last one)."""
    assert abs(float(token) - value) <= _half_unit(token) + 1e-12, (token, value)


def _eigenvalues(cell: str) -> list[complex]:
    out = []
    for part in cell.split(","):
        m = re.fullmatch(r"\s*(-?[0-9.]+)(?: ± ([0-9.]+)i)?\s*", part)
        assert m, part
        out.append((m.group(1), m.group(2)))
    return out


def test_doc_numbers_are_the_designs(designs):
    """Every number of docs/longitudinal.md's three tables against designs(), to its digits."""
    text = DOC.read_text(encoding="utf-8")
    gains = _table(text, "| design | inputs | row |")
    assert len(gains) == 6
    for design, inputs, row, *ks in gains:
        d = designs[_key(design, inputs)]
        for token, k in zip(ks, d.K[CONTROLS.index(row)], strict=True):
            _close(token, k)
    covered = {(_key(r[0], r[1]), r[2]) for r in gains}
    nonzero = {(key, CONTROLS[i]) for key, d in designs.items() for i in range(4) if d.K[i].any()}
    assert covered == nonzero
    eig = _table(text, "| design | inputs | closed-loop eigenvalues |")
    assert len(eig) == 4
    for design, inputs, cell, norm, pp, knv in eig:
        d = designs[_key(design, inputs)]
        got = [z for z in d.eigenvalues if z.imag >= 0]  # one of each pair
        printed = _eigenvalues(cell)
        assert len(printed) == len(got) == 3
        for (re_, im), z in zip(printed, sorted(got, key=lambda z: (-abs(z.imag), -z.real))):
            _close(re_, z.real)
            _close(im or "0", z.imag)
        _close(norm, np.linalg.norm(d.K))
        assert pp.startswith("< ") and np.abs(d.place_poles_K - d.K).max() < float(pp[2:])
        if d.knv_K is None:
            assert knv == "-"
        else:
            _close(knv, np.linalg.norm(d.knv_K))
    peaks = _table(text, "| design | inputs | du+ = 1 |")
    assert {_key(r[0], r[1]) for r in peaks} == set(designs) == {_key(r[0], r[1]) for r in eig}
    for design, inputs, *ps in peaks:
        for token, p in zip(ps, designs[_key(design, inputs)].peak_control_rad, strict=True):
            _close(token, p)


def test_doc_numbers_of_the_text(designs, AB):
    """The prose: open-loop eigenvalues, Iy+, the two-input ratios, gain savings, KNV factors."""
    text = " ".join(DOC.read_text(encoding="utf-8").split())
    A, B = AB
    w = np.linalg.eigvals(A)
    pair = w[np.argmax(w.imag)]
    m = re.search(r"per wing beat: (\S+) ± (\S+)i \(unstable oscillation, doubling in about (\d+) "
                  r"wing beats\), (\S+) \(slow subsidence\) and (\S+) \(fast", text)
    _close(m.group(1), pair.real)
    _close(m.group(2), pair.imag)
    assert round(math.log(2) / pair.real) == int(m.group(3))
    real = sorted(z.real for z in w if abs(z.imag) < 1e-14)
    _close(m.group(4), real[1])
    _close(m.group(5), real[0])
    _close(re.search(r"x 10\.00 = ([0-9.]+)", text).group(1), IY_PLUS)
    _close(re.search(r"give Ix\+ = ([0-9.]+)", text).group(1), 657.7e-12 / _inertia_scale())
    _close(re.search(r"the raw value would be ([0-9.]+)", text).group(1), 1308.5e-12 / _inertia_scale())
    _close(re.search(r"both ([0-9.]+) times their raw values", text).group(1),
           10.00 / (657.7e-12 / _inertia_scale()))
    m = re.search(r"`delta_alpha_2` is (\S+) \(a\) or (\S+) \(b\) times", text)
    for token, kind in zip(m.groups(), ("neutral", "mirror")):
        K = designs[(kind, ("delta_phibar", "delta_alpha_2"))].K
        _close(token, K[ALPHA2, 0] / K[PHIBAR, 0])
    for kind in ("neutral", "mirror"):  # "saves only about 1 % of the gain"
        one = np.linalg.norm(designs[(kind, ("delta_phibar",))].K)
        two = np.linalg.norm(designs[(kind, ("delta_phibar", "delta_alpha_2"))].K)
        assert 0.005 < 1 - two / one < 0.015
    m = re.search(r"about ([0-9.]+) to ([0-9.]+) times larger", text)
    factors = sorted(np.linalg.norm(d.knv_K) / np.linalg.norm(d.K) for d in designs.values()
                     if d.knv_K is not None)
    assert float(m.group(1)) == round(factors[0], 1) and float(m.group(2)) == round(factors[1])
    m = re.search(r"0\.1 rad \(6 degrees\) needs at most ([0-9.]+) rad", text)
    _close(m.group(1), 0.1 * designs[("mirror", ("delta_phibar",))].peak_control_rad[3])
    assert "B[3,3] = -0.1556 against B[3,4] = 0.0247" in text and round(B[2, 2] / B[2, 3]) == -6
