"""docs/interop.md's numbers are those of the artefacts and of independent computations.

The document's blocks run verbatim (tests/test_docs.py) and the importers' trajectories are
compared with our masters (tests/test_interop.py, tests/test_interop_ecos.py). This file checks
the prose: the closed-loop SSP's row against the SSP as fmpy and ElementTree read it, and each
number the text quotes of the closed loop against a recursion written here from the paper's
matrices with scipy's ``expm``, not through any master or FMU.
"""

from __future__ import annotations

import math
import re
import xml.etree.ElementTree as ET
import zipfile
from pathlib import Path

import numpy as np
import pytest
from docnumbers import NumericText
from fmpy.ssp.ssd import get_connections, read_ssd
from scipy.linalg import expm

from dronefly.harness.builder.closedloop import CLOSED_LOOP
from dronefly.harness.cosim.identification import TOL_PER_WINGBEAT
from dronefly.harness.interop.libcosim import step_ns
from dronefly.harness.interop.ssp import ssp_parameter_set
from dronefly.harness.paper.analysis import lateral_system
from dronefly.harness.paper.printed import EQ27_GAINS

DOC = Path(__file__).resolve().parents[1] / "docs" / "interop.md"
PLAIN = " ".join(DOC.read_text(encoding="utf-8").split())  # for text quoted exactly
TEXT = NumericText(PLAIN)  # numbers to a unit of their last digit (tests/docnumbers.py)
N_HZ = 164.0  # the plant's default wing-beat frequency (Sect. 2.1 of the paper)
H_WB = 0.1  # the documents' communication step, wing beats
X0 = np.array([0.0, 0.0, 0.0, 0.1])  # x+_0 of the SSP: delta_gamma 0.1 rad, the rest 0

pytestmark = pytest.mark.numeric  # expm and the eigenvalues go through the BLAS kernel


@pytest.fixture(scope="module")
def ssp(built_fmus) -> Path:
    return built_fmus["DroneFlyLateral"].with_name(f"{CLOSED_LOOP}.ssp")


def _sampled_loop() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Phi = exp(A h), Gamma = int_0^h exp(A s) ds B (the control held over the step) for the
    paper's non-dimensional A, B (time in wing beats), and the printed Eq. (27) gains."""
    A, B = lateral_system()
    n, m = B.shape
    M = np.zeros((n + m, n + m))
    M[:n, :n], M[:n, n:] = A * H_WB, B * H_WB
    E = expm(M)
    K = np.zeros((m, n))
    K[0] = [float(k) for k in EQ27_GAINS]
    return E[:n, :n], E[:n, n:], K


def _jacobi(steps: int) -> np.ndarray:
    """x_steps of the Jacobi loop the doc describes for libcosim and Ecos: u_k = K x_(k-1),
    with x_(-1) = x_0 (the controller saw the plant's initial outputs)."""
    Phi, Gamma, K = _sampled_loop()
    x, previous = X0.copy(), X0.copy()
    for _ in range(steps):
        x, previous = Phi @ x + Gamma @ (K @ previous), x
    return x


def test_the_closed_loop_ssp_is_as_its_row_says(ssp):
    """Row of DroneFlyClosedLoop.ssp: "their 7 connections, parameter values (x+_0 = (0, 0, 0,
    0.1), Eq. (27) gains), default experiment 0 to 300 wing beats"."""
    connections = len(get_connections(read_ssd(str(ssp)).system))  # fmpy's reader
    params = {p.name: float(p.value) for p in ssp_parameter_set(ssp).parameters}
    x0 = [params[f"plant.{s}_start"] for s in ("delta_v", "delta_p", "delta_r", "delta_gamma")]
    gains = [params[f"controller.K[1,{j}]"] for j in range(1, 5)]
    with zipfile.ZipFile(ssp) as z:  # ElementTree: a reader that is neither ours nor fmpy's
        root = ET.fromstring(z.read("SystemStructure.ssd"))
    experiment = next(e for e in root.iter() if e.tag.endswith("}DefaultExperiment"))
    start_s, stop_s = (float(experiment.get(a, "0")) for a in ("startTime", "stopTime"))
    assert x0 == list(X0) and gains == [float(k) for k in EQ27_GAINS]
    row = (f"their {connections} connections, parameter values (x+_0 = (0, 0, 0, {x0[3]}), "
           f"Eq. (27) gains), default experiment {start_s:g} to {stop_s * N_HZ:.0f} wing beats")
    assert row in TEXT, row


def test_the_step_in_whole_nanoseconds():
    """libcosim's time is in ns: 0.1 wing beat at 164 Hz is 609 756.1 ns, rounded."""
    ns = step_ns(H_WB, N_HZ)
    assert ns == round(H_WB / N_HZ * 1e9) == 609756
    assert f"step {ns // 1000} {ns % 1000} ns" in TEXT
    assert f"0.1 wing beat = {ns} ns" in PLAIN


def test_the_jacobi_loops_delta_gamma_after_3000_steps():
    """The value the doc quotes for Ecos (in-process, proxyfmu, the FMI 3.0 SSP) and asserts
    for libcosim and Ecos' blocks. The 3000 steps of a loop whose slowest mode is neutral
    (|lambda| h ~ 1e-5) carry the round-off of each step, a few ulps, without growth: 1e-16
    relative per step, 3e-13 after 3000 at the worst, so 12 digits hold (the doc prints 12
    and says the last bits differ between machines)."""
    value = _jacobi(3000)[3]
    quoted = f"{value:.12g}"
    assert f"in-process, {quoted}..." in TEXT, quoted
    assert f"steps {quoted}, as from the FMI 2.0 SSP" in TEXT, quoted
    # the blocks' asserts: abs(... - 0.010684) < 1e-6
    assert len(re.findall(rf"- {value:.6f}\) < 1e-6", DOC.read_text(encoding="utf-8"))) == 2


def test_the_neutral_rate_and_its_tolerance():
    """"dominant rate 7.7e-5 per wing beat, tolerance 1e-3": the largest root of the Jacobi
    loop's transition over (x_k, x_(k-1)), as a rate per wing beat (ln|z| / h); an eigenvalue
    of a well-separated spectrum, exact to 1e-12 of itself, printed to 2 digits."""
    Phi, Gamma, K = _sampled_loop()
    n = len(Phi)
    T = np.block([[Phi, Gamma @ K], [np.eye(n), np.zeros((n, n))]])
    rate = max(math.log(abs(z)) for z in np.linalg.eigvals(T)) / H_WB
    assert 0 < rate < TOL_PER_WINGBEAT  # neutral
    quoted = f"dominant rate {rate:.1e} per wing beat, tolerance {TOL_PER_WINGBEAT:.0e}"
    assert quoted.replace("e-05", "e-5").replace("e-03", "e-3") in TEXT, quoted


def test_ecos_time_is_an_accumulated_double():
    """"time accumulated, 1.5e-13 s off k h": t_k = t_(k-1) + h in doubles, 3000 steps of
    h = 0.1 / 164 s, against 3000 h (IEEE 754 addition: the same on every machine)."""
    h = H_WB / N_HZ
    t = 0.0
    for _ in range(3000):
        t += h
    assert f"{abs(t - 3000 * h):.1e} s off k h" in TEXT


def test_the_gains_ecos_reads_in_place_of_an_array():
    """Ecos reads the FMI 3.0 array K as its first element, K[1,1], and shifted outputs show
    K[1,2]: the printed Eq. (27) gains, as printed (the SSP and the FMUs' start values hold
    exactly these decimals)."""
    assert f"`controller::K` = K[1,1] = {EQ27_GAINS[0]}" in PLAIN
    assert f"`delta_Phi_a` reads K[1,2] = {EQ27_GAINS[1]}" in PLAIN
