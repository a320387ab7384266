"""A third importer: the closed-loop SSP co-simulated by Ecos (ecospy), in a child process.

Ecos (ecospy 0.7.2) is a C++ co-simulation engine (fmi4c, SSP 1.0, a CLI, proxyfmu) with a
ctypes binding. Its ``libecosc.so`` needs ``libtbb.so.12``, which the PyPI package ``tbb``
installs off the library path, so :func:`run_ecos` runs ecospy in a child process of this
interpreter with that folder on ``LD_LIBRARY_PATH`` (:func:`ecos_env`). A crash in Ecos or an
FMU ends the child only; Ecos leaks an unzipped copy of the SSP per simulation into ``TMPDIR``
(the child's is private and removed).

Why Ecos crashed on our SSP (measured, docs/interop.md): pythonfmu runs the FMU's Python code
in the host's interpreter, so the FMUs' imports (numpy, scipy) must be importable by the
Python that runs ecospy. Where they are not, pythonfmu's ``fmi2Instantiate`` returns NULL;
fmi4c (inside Ecos) wraps that NULL in a non-NULL instance handle, so Ecos' check passes, and
``init()`` calls ``fmi2SetupExperiment(NULL, ...)``: SIGSEGV. Threads are not the cause: Ecos
steps the FMUs on TBB worker threads, and pythonfmu takes the GIL (``PyGILState_Ensure``)
around each call while ctypes has released it.

Ecos' fixed-step master, measured (``tests/test_interop_ecos.py``)
------------------------------------------------------------------
Jacobi. Each step every instance gets its inputs, steps and its outputs are read (the instances
in parallel), then all connections are transferred. In initialization mode Ecos transfers the
connections (once per instance) before fmi2ExitInitializationMode, when our plant already
serves x_0 (its start values): the controller sees x_(-1) = x_0, so u_0 = u_1 = K x_0 and
u_k = K x_(k-1), exactly ``Loop.run(..., master="jacobi")`` with its default u_source0 (the
plant's initial outputs); measured: equal to the last bit over 3000 steps. Time is a double
that Ecos accumulates (t_k = t_(k-1) + h, 1.5e-13 s from k h after 3000 steps).

Ecos keys SSP parameter sets by the SSV's ``name`` and applies one per ``init``; ours are two
(``plant``, ``controller``), so :func:`run_ecos` sets every binding before ``init`` itself.
"""

from __future__ import annotations

import functools
import importlib.util
import json
import os
import platform
import signal
import subprocess
import sys
import tempfile
from importlib import metadata
from pathlib import Path
from typing import Mapping

import numpy as np

from ...models.lateral_interface import STATE_NAMES
from ..cosim.master import CoSimError
from ..cosim.identification import Verdict, unit_start_values, verdict_of
from .libcosim import InteropRun
from .ssp import PLANT_INSTANCE, ClosedLoopSSP

__all__ = ["ecos_available", "ecos_env", "ecos_verdict", "run_ecos", "tbb_library_dir"]


#: The child: only ecospy and the standard library (no numpy), so it also shows the failure
#: mode of a host that cannot import the FMUs' dependencies. Stages go to stderr.
_CHILD = r"""
import json, sys
job = json.load(open(sys.argv[1]))
from ecospy import EcosLib, EcosSimulation
EcosLib.set_log_level("warn")
out = {"version": repr(EcosLib.version()), "runs": []}
for run in job["runs"]:
    res = {"time": [], "values": [], "error": ""}
    out["runs"].append(res)
    try:
        sim = EcosSimulation(step_size=job["step"], ssp_path=job["ssp"])
        print("stage: created", file=sys.stderr, flush=True)
        for name, value in run.items():
            sim.set_real(name, value)
        if not sim.init():
            raise RuntimeError("init: " + EcosLib.get_last_error())
        print("stage: initialized", file=sys.stderr, flush=True)
        for k in range(job["n"] + 1):
            if k:
                sim.step(1)
            res["time"].append(sim.get_time())
            res["values"].append([sim.get_real(r) for r in job["record"]])
        print("stage: stepped", file=sys.stderr, flush=True)
        sim.terminate()
        print("stage: terminated", file=sys.stderr, flush=True)
        sim.free()
        print("stage: freed", file=sys.stderr, flush=True)
    except Exception as e:
        res["error"] = f"{type(e).__name__}: {e}"
with open(sys.argv[2], "w") as f:
    json.dump(out, f)
print("stage: written", file=sys.stderr, flush=True)
# Everything is freed and written: leave without the interpreter's and the libraries' exit
# handlers, where the process otherwise crashes now and then (SIGSEGV after "written", about
# 1 run in 50 on a loaded machine: pythonfmu3's FMI 3.0 binary after Ecos has unloaded it).
sys.stdout.flush()
import os
os._exit(0)
"""


def tbb_library_dir() -> str | None:
    """The folder holding ``libtbb.so.12`` of the PyPI package ``tbb``, or None (pip puts it
    into ``<prefix>/lib`` or ``~/.local/lib``, where the loader does not look)."""

    try:
        files = metadata.distribution("tbb").files or []
    except metadata.PackageNotFoundError:
        return None
    for f in files:
        if f.name == "libtbb.so.12":
            path = Path(f.locate()).resolve()
            if path.is_file():
                return str(path.parent)
    return None


def ecos_env(base: Mapping[str, str] | None = None) -> dict[str, str]:
    """``base`` (default: ``os.environ``) with :func:`tbb_library_dir` first on
    ``LD_LIBRARY_PATH``, the environment a process needs to load ecospy's ``libecosc.so``."""
    env = dict(os.environ if base is None else base)
    lib = tbb_library_dir()
    if lib:
        old = env.get("LD_LIBRARY_PATH")
        env["LD_LIBRARY_PATH"] = os.pathsep.join([lib] + ([old] if old else []))
    return env


@functools.lru_cache(maxsize=1)
def ecos_available() -> str | None:
    """None if ecospy runs here (probed once, in a child process), else why not."""

    if not (sys.platform.startswith("linux") and platform.machine() in ("x86_64", "AMD64")):
        return f"the Ecos route is for Linux x86_64 (ecospy's binaries), not " \
               f"{sys.platform}/{platform.machine()}"
    if importlib.util.find_spec("ecospy") is None:
        return "ecospy is not installed (pip install ecospy tbb)"
    r = subprocess.run([sys.executable, "-c", "from ecospy import EcosLib; print(EcosLib.version())"],
                       env=ecos_env(), capture_output=True, text=True, timeout=120)
    if r.returncode != 0:
        why = (r.stderr.strip().splitlines() or [f"exit code {r.returncode}"])[-1]
        hint = "" if tbb_library_dir() else " (no libtbb.so.12 found: pip install tbb)"
        return f"ecospy cannot be loaded: {why}{hint}"
    return None


def _plant_connectors(read: ClosedLoopSSP, plant: str) -> tuple[list[str], list[str]]:
    """The plant's output and input names, in the order of its FMU's model description (the
    order of the connectors that the project's SSP writer declares)."""
    variables = read.md(plant).modelVariables
    return ([v.name for v in variables if v.causality == "output"],
            [v.name for v in variables if v.causality == "input"])


def _run_jobs(ssp: Path, step_s: float, n_steps: int, record: list[str],
              runs: list[dict[str, float]], env: Mapping[str, str] | None) -> dict:
    """Run the SSP once per entry of ``runs`` (values set before init) in one child."""
    why = ecos_available()
    if why:
        raise CoSimError(why)
    with tempfile.TemporaryDirectory(prefix="dronefly_ecos_") as tmp:
        job, out = Path(tmp, "job.json"), Path(tmp, "out.json")
        job.write_text(json.dumps({"ssp": str(ssp), "step": step_s, "n": n_steps,
                                   "record": record, "runs": runs}))
        child_env = {**ecos_env(env), "TMPDIR": tmp}  # Ecos leaves a copy of the SSP there
        r = subprocess.run([sys.executable, "-c", _CHILD, str(job), str(out)], env=child_env,
                           capture_output=True, text=True, timeout=600)
        if r.returncode != 0:
            stages = [ln for ln in r.stderr.splitlines() if ln.startswith("stage: ")]
            where = stages[-1][7:] if stages else "not created"
            sig = f"signal {signal.Signals(-r.returncode).name}" if r.returncode < 0 \
                else f"exit code {r.returncode}"
            hint = (" (an FMU failed to instantiate and Ecos went on with its NULL instance: "
                    "can this Python import the FMUs' dependencies?)"
                    if r.returncode == -signal.SIGSEGV and where == "created" else "")
            raise CoSimError(f"Ecos child process ended with {sig}; last stage: {where}{hint}\n"
                             + r.stderr[-1500:])
        return json.loads(out.read_text())


def run_ecos(ssp: str | Path, *, n_steps: int, step_s: float | None = None,
             overrides: Mapping[str, float] | None = None, plant: str = PLANT_INSTANCE,
             env: Mapping[str, str] | None = None) -> InteropRun:
    """Co-simulate the SSP with Ecos' fixed-step master and record the plant's signals.

    Parameters
    ----------
    ssp : path
        An SSP 1.0 file such as ``DroneFlyClosedLoop.ssp``.
    n_steps : int
        Number of communication steps from t = 0.
    step_s : float, optional
        Communication step in seconds; default 0.1 wing beat of the plant's n.
    overrides : mapping, optional
        ``component.variable`` -> value, replacing or adding to the SSP's bindings
        (e.g. ``plant.delta_v_start``).
    plant : str
        The component whose outputs (states) and inputs (controls) are recorded.
    env : mapping, optional
        Base environment of the child process (default ``os.environ``).

    Returns
    -------
    InteropRun
        As :func:`dronefly.harness.interop.libcosim.run_libcosim` returns it: ``names`` are the
        plant's outputs then inputs, row k holds x_k and the control applied over step k, at
        Ecos' time t_k. ``step_ns`` is the step rounded to whole ns (Ecos uses the double).

    Raises
    ------
    CoSimError
        Ecos unavailable, a bad argument, or the child process crashed (the message says in
        which stage; an error Ecos reports is returned as ``complete=False`` instead).
    """
    ssp = Path(ssp).resolve()
    if not ssp.is_file():
        raise CoSimError(f"SSP {str(ssp)!r} does not exist")
    if n_steps < 1:
        raise CoSimError(f"n_steps = {n_steps!r} must be >= 1")
    read = ClosedLoopSSP(ssp)
    if step_s is None:
        step_s = read.plant(plant)[2]
    if not (np.isfinite(step_s) and step_s > 0):
        raise CoSimError(f"step = {step_s!r} s must be finite and > 0")
    return _runs(read, float(step_s), n_steps, [overrides or {}], plant, env)[0]


def _runs(read: ClosedLoopSSP, step_s: float, n_steps: int,
          overrides: list[Mapping[str, float]], plant: str,
          env: Mapping[str, str] | None) -> list[InteropRun]:
    outputs, inputs = _plant_connectors(read, plant)
    names = [*outputs, *inputs]
    bound = {p.name: float(p.value) for p in read.parameter_set().parameters}
    runs = []
    for o in overrides:
        values = {**bound, **{k: float(v) for k, v in o.items()}}
        runs.append({k.replace(".", "::", 1): v for k, v in values.items()})
    out = _run_jobs(read.path, step_s, n_steps, [f"{plant}::{n}" for n in names], runs, env)
    result = []
    for res in out["runs"]:
        n = len(res["values"])
        signals = np.asarray(res["values"], dtype=float).reshape(n, len(names))
        result.append(InteropRun(names, np.asarray(res["time"], dtype=float), signals,
                                 int(round(step_s * 1e9)), complete=not res["error"]
                                 and n == n_steps + 1, error=res["error"]))
    return result


def ecos_verdict(ssp: str | Path, n_steps: int = 20, *,
                 overrides: Mapping[str, float] | None = None,
                 env: Mapping[str, str] | None = None) -> Verdict:
    """Identify and classify the loop as Ecos runs the SSP (its gains, 0.1 wing beat).

    One run per unit initial state x+_0 = e_i, all in one child process. Each run is
    [x_(-1); x_0; x_1; ...] with x_(-1) = x_0 (see the module text), the delayed (Jacobi) form
    of :func:`dronefly.harness.cosim.identification.identify`; u_0 = u_1 (= K x_0) is checked.

    Parameters
    ----------
    ssp : path
        The closed-loop SSP (components ``plant`` and ``controller``).
    n_steps : int
        Steps per identification run.
    overrides, env : mapping, optional
        As in :func:`run_ecos` (e.g. the gains ``controller.K[i,j]``).

    Returns
    -------
    Verdict
        The identification and the non-dimensional runs it used.

    Raises
    ------
    CrossCheckError
        The fit's residual exceeds :data:`~dronefly.harness.cosim.identification.FIT_RESIDUAL_TOL`.
    """
    ssp = Path(ssp).resolve()
    read = ClosedLoopSSP(ssp)
    n_hz, scale, step = read.plant()
    starts = [{**(overrides or {}), **start}
              for start in unit_start_values(scale, prefix=f"{PLANT_INSTANCE}.")]
    runs = []
    for r in _runs(read, step, n_steps, starts, PLANT_INSTANCE, env):
        if not r.complete:
            raise CoSimError(f"Ecos identification run failed: {r.error}")
        u0, u1 = r.signals[:2, len(STATE_NAMES):]
        if np.any(u0 != u1):
            raise CoSimError(f"Ecos fed the plant u_0 = {u0.tolist()} != u_1 = {u1.tolist()}: "
                             "the controller did not see x_0 before the first step")
        xs = r.states() / scale
        runs.append(np.vstack([xs[:1], xs]))
    return verdict_of(runs, step * n_hz, delay=True, where=f"Ecos {ssp}")
