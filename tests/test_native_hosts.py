"""Native FMUs in hosts that are not Python: the C host of tests/c_host, on Linux and under Wine.

The C host (``tests/c_host/fmi2_host.c``) is compiled here with the project's toolchain
(``zig cc``, harness/builder/toolchain.py) for linux64 and, cross-compiled, for win64. It runs in a
process started with no ``LD_PRELOAD``, ``PYTHONHOME`` or ``PYTHONPATH``; it copies its own
``/proc/self/maps`` after loading and initializing both FMUs, and the test reads there which
libraries the process holds: the FMUs' binaries and no libpython. A second test preloads
libpython and sees it there, so the check can see what it looks for.

- A Reference-FMU (VanDerPol, the Modelica Association's C) proves the path against FMPy.
- The native FMI 2.0 closed loop (``DroneFlyLateral`` + ``StateFeedback``, built by
  harness/builder/native.py) equals the pythonfmu loop of ``dronefly cosim`` (the Gauss-Seidel master of
  ``harness.cosim.master.Loop``) to 1e-12 over 300 steps, on Linux and, with the win64 binaries
  and the Windows build of the host, under Wine.

Wine is Debian's ``wine64`` (.ci/setup-c-host.sh installs it). Where Debian's packages are there
(``apt-get`` on Linux x86_64), a missing Wine fails the Wine test; ``DRONEFLY_ALLOW_NO_WINE=1``
turns that into a skip.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest

from dronefly.harness.builder import native
from dronefly.harness.builder.toolchain import find_toolchain, fmi_include_dir, host_platform, \
    missing_reason
from dronefly.harness.cosim.fmu import FMU
from dronefly.harness.cosim.master import Loop
from dronefly.harness.interop.libcosim import libpython_path
from dronefly.models.lateral_interface import scale_vector

pytestmark = [pytest.mark.integration,
              pytest.mark.skipif(not (sys.platform.startswith("linux")
                                      and host_platform("2.0") == "linux64"),
                                 reason="linux64 binaries, /proc/self/maps and Wine: Linux x86_64")]

REPO = Path(__file__).resolve().parents[1]
HOST_C = REPO / "tests" / "c_host" / "fmi2_host.c"
REFERENCE = REPO.parent / "shared" / "reference-fmus" / "fmi2"
ALLOW_NO_WINE = "DRONEFLY_ALLOW_NO_WINE"

STATES = ("delta_v", "delta_p", "delta_r", "delta_gamma")
CONTROLS = ("delta_Phi_a", "delta_alpha_1a", "delta_alpha_2a")
H = 0.1 / 164.0  # 0.1 wing beat, s
N_STEPS = 300
X0 = np.array([0.02, 0.05, -0.03, 0.1])  # non-dimensional initial state
#: the same loop, the same arithmetic up to the order of a few sums and the matrix exponential
#: (C at initialization against scipy's expm): round-off, a few 1e-16 per step, grows by at most
#: the loop's neutral mode over 300 steps; 1e-12 of each signal's peak leaves room for that
TOL_LOOP = 1e-12


def _clean_env() -> dict[str, str]:
    """The environment of a host that has nothing of Python: no preload, home or path."""
    return {k: v for k, v in os.environ.items()
            if k not in ("LD_PRELOAD", "PYTHONHOME", "PYTHONPATH")}


def _rows(text: str, width: int) -> np.ndarray:
    rows = np.array([[float(x) for x in line.split(",")] for line in text.splitlines() if line])
    assert rows.ndim == 2 and rows.shape[1] == width, text[:500]
    return rows


def _rel_dev(a: np.ndarray, b: np.ndarray) -> float:
    """max |a - b| per column, relative to that column's peak |b|."""
    peak = np.maximum(np.abs(b).max(axis=0), 1e-300)
    return float(np.max(np.abs(a - b) / peak))


def _libraries(maps: Path) -> set[str]:
    """The files mapped into the host process (the path column of /proc/self/maps)."""
    out = set()
    for line in maps.read_text().splitlines():
        parts = line.split(maxsplit=5)
        if len(parts) == 6 and parts[5].startswith("/"):
            out.add(parts[5])
    return out


def _has_libpython(libs: set[str]) -> bool:
    return any(Path(p).name.startswith("libpython") for p in libs)


@pytest.fixture(scope="module")
def zig():
    tc = find_toolchain("win64")
    assert tc is not None and tc.kind == "zig", f"zig cc is in the test extra: {missing_reason('win64')}"
    return tc


@pytest.fixture(scope="module")
def hosts(zig, tmp_path_factory):
    """The C host for linux64 and for win64, both built by zig cc."""
    out = tmp_path_factory.mktemp("hosts")
    inc = [fmi_include_dir()]
    linux = zig.compile([HOST_C], out / "fmi2_host", "linux64", shared=False, include_dirs=inc,
                        defines={"_POSIX_C_SOURCE": "200809L"}, libs=["dl"])
    win = zig.compile([HOST_C], out / "fmi2_host.exe", "win64", shared=False, include_dirs=inc)
    return {"linux64": linux, "win64": win}


@pytest.fixture(scope="module")
def native_pair(zig, tmp_path_factory):
    """The native FMI 2.0 plant and controller with linux64 and win64 binaries, extracted:
    {name: (folder, model identifier, GUID, {variable: value reference})}."""
    import fmpy

    out = tmp_path_factory.mktemp("native")
    pair = {}
    for name in ("DroneFlyLateral", "StateFeedback"):
        fmu, platforms = native.build_native(name, out, 2, zig, ("linux64", "win64"))
        assert platforms == ("linux64", "win64")
        d = out / name
        with zipfile.ZipFile(fmu) as z:
            z.extractall(d)
        md = fmpy.read_model_description(str(fmu))
        pair[name] = (d, md.coSimulation.modelIdentifier, md.guid,
                      {v.name: v.valueReference for v in md.modelVariables})
    return pair


def _loop_args(pair, x0: np.ndarray, dir_of=str) -> list[str]:
    (pd, pid, pg, pv), (cd, cid, cg, cv) = pair["DroneFlyLateral"], pair["StateFeedback"]
    start = {f"{s}_start": float(v) for s, v in zip(STATES, x0 * np.array(scale_vector()))}
    return [str(N_STEPS), repr(H), dir_of(pd), pid, pg, dir_of(cd), cid, cg,
            ",".join(str(pv[s]) for s in STATES), ",".join(str(cv[s]) for s in STATES),
            ",".join(str(cv[u]) for u in CONTROLS), ",".join(str(pv[u]) for u in CONTROLS),
            ",".join(f"{pv[k]}={v!r}" for k, v in start.items())]


@pytest.fixture(scope="module")
def pythonfmu_loop(built_fmus):
    """The closed loop of ``dronefly cosim``: the pythonfmu FMUs, Gauss-Seidel."""
    with FMU(built_fmus["DroneFlyLateral"]) as p, FMU(built_fmus["StateFeedback"]) as c:
        start = {f"{s}_start": float(v) for s, v in zip(STATES, X0 * np.array(scale_vector()))}
        yield Loop(p, c).run(H, N_STEPS, master="gauss-seidel", plant_start=start)


# -----------------------------------------------------------------------------------------
# the path, proved with a Reference-FMU
def test_a_reference_fmu_runs_in_the_c_host_without_libpython(hosts, tmp_path):
    """VanDerPol (plant, no inputs) feeding Feedthrough (controller): the C host's x0, x1
    equal FMPy's run of the same binary at the same communication points (same calls, same
    floating-point operations: equal to the last bit, 1e-15 for the time accumulated
    differently)."""
    import fmpy

    dirs = {}
    for name in ("VanDerPol", "Feedthrough"):
        dirs[name] = tmp_path / name
        with zipfile.ZipFile(REFERENCE / f"{name}.fmu") as z:
            z.extractall(dirs[name])
    guid = {n: fmpy.read_model_description(str(REFERENCE / f"{n}.fmu")).guid for n in dirs}
    maps = tmp_path / "maps.txt"
    h, n = 0.01, 200
    r = subprocess.run([str(hosts["linux64"]), "-m", str(maps), str(n), repr(h),
                        str(dirs["VanDerPol"]), "VanDerPol", guid["VanDerPol"],
                        str(dirs["Feedthrough"]), "Feedthrough", guid["Feedthrough"],
                        "1,3", "7,9", "", ""],
                       env=_clean_env(), capture_output=True, text=True, timeout=60)
    assert r.returncode == 0, r.stderr
    rows = _rows(r.stdout, 3)
    libs = _libraries(maps)
    assert any(p.endswith("/binaries/linux64/VanDerPol.so") for p in libs), sorted(libs)
    assert not _has_libpython(libs), sorted(libs)
    ref = fmpy.simulate_fmu(str(REFERENCE / "VanDerPol.fmu"), fmi_type="CoSimulation",
                            stop_time=n * h, output_interval=h, output=["x0", "x1"])
    assert len(ref) == n + 1
    np.testing.assert_allclose(rows[:, 0], ref["time"], rtol=0, atol=1e-15 * n * h)
    assert np.array_equal(rows[:, 1:], np.column_stack([ref["x0"], ref["x1"]]))


def test_the_library_check_sees_a_preloaded_libpython(hosts, tmp_path):
    """The same run with libpython preloaded: the maps show it (the check above can fail)."""
    lib = libpython_path()
    if lib is None:
        pytest.skip("this Python has no shared libpython (Py_ENABLE_SHARED = 0) and none of its "
                    "version is installed; .ci/setup-c-host.sh installs Debian's")
    maps = tmp_path / "maps.txt"
    d = tmp_path / "Feedthrough"
    with zipfile.ZipFile(REFERENCE / "Feedthrough.fmu") as z:
        z.extractall(d)
    import fmpy

    guid = fmpy.read_model_description(str(REFERENCE / "Feedthrough.fmu")).guid
    r = subprocess.run([str(hosts["linux64"]), "-q", "-m", str(maps), "2", "0.1",
                        str(d), "Feedthrough", guid, str(d), "Feedthrough", guid,
                        "8", "7", "", ""],
                       env={**_clean_env(), "LD_PRELOAD": lib}, capture_output=True, text=True,
                       timeout=60)
    assert r.returncode == 0, r.stderr
    assert _has_libpython(_libraries(maps))


# -----------------------------------------------------------------------------------------
# the native closed loop
def test_the_native_loop_in_the_c_host_equals_the_pythonfmu_loop(hosts, native_pair,
                                                                   pythonfmu_loop, tmp_path):
    maps = tmp_path / "maps.txt"
    r = subprocess.run([str(hosts["linux64"]), "-m", str(maps), *_loop_args(native_pair, X0)],
                       env=_clean_env(), capture_output=True, text=True, timeout=60)
    assert r.returncode == 0, r.stderr
    libs = _libraries(maps)
    for name in ("DroneFlyLateral", "StateFeedback"):
        assert any(p.endswith(f"/binaries/linux64/{name}.so") for p in libs), sorted(libs)
    assert not _has_libpython(libs), sorted(libs)
    rows = _rows(r.stdout, 8)
    assert rows.shape[0] == N_STEPS + 1
    np.testing.assert_allclose(rows[:, 0], pythonfmu_loop.time, rtol=1e-15)
    assert _rel_dev(rows[:, 1:], pythonfmu_loop.signals) <= TOL_LOOP
    assert abs(rows[-1, 4]) > 1e-3  # the loop moved: delta_gamma is not trivially zero


def _wine() -> list[str] | None:
    for name in ("wine64", "wine"):
        exe = shutil.which(name)
        if exe:
            return [exe]
    for path in ("/usr/lib/wine/wine64", "/usr/lib/x86_64-linux-gnu/wine/wine64"):
        if os.access(path, os.X_OK):
            return [path]
    return None


@pytest.fixture(scope="module")
def wine(tmp_path_factory):
    cmd = _wine()
    if cmd is None:
        why = "Wine is missing: .ci/setup-c-host.sh installs Debian's wine64"
        if os.environ.get(ALLOW_NO_WINE) == "1" or shutil.which("apt-get") is None:
            pytest.skip(why + (" (no apt-get: not a Debian machine)"
                               if shutil.which("apt-get") is None else f" ({ALLOW_NO_WINE}=1)"))
        pytest.fail(why)
    prefix = Path(os.environ.get("WINEPREFIX") or Path.home() / ".cache" / "dronefly-wine")
    env = {**_clean_env(), "WINEPREFIX": str(prefix), "WINEDEBUG": "-all"}
    return cmd, env


def test_the_windows_host_runs_the_win64_binaries_under_wine(hosts, native_pair, wine,
                                                              pythonfmu_loop):
    cmd, env = wine
    r = subprocess.run([*cmd, str(hosts["win64"]),
                        *_loop_args(native_pair, X0, dir_of=lambda d: "Z:" + str(d))],
                       env=env, capture_output=True, text=True, timeout=180)
    assert r.returncode == 0, r.stderr[-2000:]
    rows = _rows(r.stdout, 8)
    assert rows.shape[0] == N_STEPS + 1
    np.testing.assert_allclose(rows[:, 0], pythonfmu_loop.time, rtol=1e-15)
    assert _rel_dev(rows[:, 1:], pythonfmu_loop.signals) <= TOL_LOOP
