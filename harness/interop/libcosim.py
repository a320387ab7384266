"""A second, independent FMI importer: the closed loop co-simulated by libcosim (libcosimpy).

libcosim (Open Simulation Platform) loads FMUs through FMI Library, not FMPy, and runs them
with its own fixed-step master. :func:`run_libcosim` connects plant and controller by name
(every controller input from the plant output of that name, every plant input from the
controller output of that name), runs ``n_steps`` steps and returns the time series;
:func:`libcosim_verdict` runs it from the unit initial states and classifies neutral stability
with :func:`harness.cosim.identification.identify`.

libcosim's fixed-step master, measured (``tests/test_interop.py``)
-------------------------------------------------------------------
It is a Jacobi master. In every step each slave first receives the input values transferred
at the end of the previous step, steps, and its outputs are read; only then are the outputs
transferred to the connected inputs. So the plant's input over step k is the controller's
output read after step k-1, u_k = K x_(k-1). Before the first step the plant's initial
values the controller holds are those libcosim transferred in initialization mode, i.e. the
plant's outputs read *before* fmi2ExitInitializationMode: u_0 = K x_(-1). (Initial values
set on the controller's connected inputs are overwritten by that transfer.) Our plant
publishes x_0 only at fmi2ExitInitializationMode, so x_(-1) = 0 and u_0 = 0, u_1 = K x_0.
:func:`run_libcosim` records x_(-1) from libcosim's own observer (the controller's inputs at
step 0, ``InteropRun.controller_inputs0``). The loop is then exactly
``harness.cosim.master.Loop.run(..., master="jacobi", u_source0=x_(-1))``; the two agree to
rounding (~1e-15 relative).

Time in libcosim is an integer number of nanoseconds, so the step is rounded to whole
nanoseconds (:func:`step_ns`): 0.1 wing beat at 164 Hz is 609 756 ns = 0.099999984 wing beats.
Compare with the harness at that step, not at 1/1640 s.

libcosimpy 0.0.6 quirk: ``CosimObserver.time_series_real_samples`` trims as many samples as it
finds step number 0 in the buffer, so a request from step 0 always loses the last sample.
:func:`run_libcosim` reads samples 0..N-1 and then sample N on its own.
"""

from __future__ import annotations

import ctypes.util
import math
import os
import sys
import sysconfig
from dataclasses import dataclass, field
from pathlib import Path
from typing import Mapping, Sequence

import fmpy
import numpy as np

from ..builder.closedloop import plant_md_scales
from ...core.extras import optional
from ...models.lateral_interface import STATE_NAMES
from ..cosim.master import CoSimError
from ..cosim.identification import Verdict, unit_start_values, verdict_of

__all__ = ["InteropRun", "c_host_env", "libcosim_available", "libcosim_verdict", "libpython_path",
           "run_libcosim", "step_ns"]


def libcosim_available() -> str | None:
    """None if libcosimpy can be used here, else why not."""
    try:
        optional("libcosimpy.CosimExecution")
        optional("libcosimpy._internal", "libcosimc")()
    except Exception as e:  # ImportError, OSError from the shared library
        return f"libcosimpy unavailable: {e!r}"
    return None


def step_ns(step_wingbeats: float, n_hz: float) -> int:
    """The communication step in whole nanoseconds (libcosim's time unit)."""
    ns = int(round(step_wingbeats / n_hz * 1e9))
    if ns < 1:
        raise CoSimError(f"step = {step_wingbeats!r} wing beats is under 1 ns at n = {n_hz} Hz")
    return ns


@dataclass
class InteropRun:
    """Signals recorded by libcosim's time-series observer at t_k = k * step (k = 0..N)."""

    names: list[str]
    time: np.ndarray  # s
    signals: np.ndarray  # (N + 1, len(names))
    step_ns: int
    complete: bool = True
    error: str = ""
    controller_inputs0: dict[str, float] = field(default_factory=dict)  # x_(-1), dimensional

    def column(self, name: str) -> np.ndarray:
        return self.signals[:, self.names.index(name)]

    def states(self, names: Sequence[str] = STATE_NAMES) -> np.ndarray:
        return np.column_stack([self.column(n) for n in names])


def _variables(execution, index: int) -> dict[str, tuple[int, int]]:
    """name -> (value reference, causality) of one slave."""
    return {v.name.decode(): (v.reference, v.causality) for v in execution.slave_variables(index)}


def run_libcosim(plant: str | Path, controller: str | Path, *, step_ns: int, n_steps: int,
                 plant_start: Mapping[str, float] | None = None,
                 controller_params: Mapping[str, float] | None = None,
                 log_level: str = "WARNING") -> InteropRun:
    """Co-simulate plant and controller in libcosim with its fixed-step master.

    Parameters
    ----------
    plant, controller : path
        FMI 2.0 co-simulation FMUs, connected by variable name.
    step_ns : int
        Communication step in nanoseconds (see :func:`step_ns`).
    n_steps : int
        Number of steps from t = 0.
    plant_start, controller_params : mapping
        Initial values (libcosim sets them in initialization mode).
    log_level : str
        libcosim's (process-wide) console log level; its default, DEBUG, logs every FMI call.

    Raises
    ------
    CoSimError
        libcosimpy missing, an FMU cannot be loaded, or a variable has no partner.
    """
    why = libcosim_available()
    if why:
        raise CoSimError(why)
    get_last_error_message = optional("libcosimpy._internal", "get_last_error_message")
    CosimVariableCausality, CosimVariableType = optional(
        "libcosimpy.CosimEnums", "CosimVariableCausality", "CosimVariableType")
    CosimExecution = optional("libcosimpy.CosimExecution", "CosimExecution")
    CosimLogLevel, log_output_level = optional("libcosimpy.CosimLogging", "CosimLogLevel",
                                               "log_output_level")
    CosimObserver = optional("libcosimpy.CosimObserver", "CosimObserver")
    CosimLocalSlave = optional("libcosimpy.CosimSlave", "CosimLocalSlave")

    if int(step_ns) != step_ns or step_ns < 1:
        raise CoSimError(f"step_ns = {step_ns!r} ns must be a positive integer")
    if n_steps < 1:
        raise CoSimError(f"n_steps = {n_steps!r} must be >= 1")
    for label, path in (("plant", plant), ("controller", controller)):
        if not Path(path).is_file():
            raise CoSimError(f"{label} FMU {str(path)!r} does not exist")
    log_output_level(CosimLogLevel[log_level])

    ex = CosimExecution.from_step_size(int(step_ns))
    slaves = []  # keep the slave objects alive as long as the execution
    idx = {}
    for role, path in (("plant", plant), ("controller", controller)):
        slave = CosimLocalSlave(str(Path(path).resolve()), role)
        slaves.append(slave)
        i = ex.add_local_slave(slave)
        if i < 0:
            raise CoSimError(f"libcosim cannot load the {role} FMU {str(path)!r}: "
                             f"{get_last_error_message()}")
        idx[role] = i
    pv, cv = _variables(ex, idx["plant"]), _variables(ex, idx["controller"])
    out_, in_ = CosimVariableCausality.OUTPUT.value, CosimVariableCausality.INPUT.value
    states = [n for n, (_, c) in pv.items() if c == out_]
    controls = [n for n, (_, c) in pv.items() if c == in_]
    for n, (_, c) in cv.items():
        if c == in_ and pv.get(n, (0, None))[1] != out_:
            raise CoSimError(f"controller input {n!r} has no plant output of that name ({plant})")
    for n in controls:
        if cv.get(n, (0, None))[1] != out_:
            raise CoSimError(f"plant input {n!r} has no controller output of that name "
                             f"({controller})")
    p, c = idx["plant"], idx["controller"]
    for n, (vr, cz) in cv.items():
        if cz == in_:
            ex.connect_real_variables(p, pv[n][0], c, vr)
    for n in controls:
        ex.connect_real_variables(c, cv[n][0], p, pv[n][0])
    for slave_index, table, values in ((p, pv, plant_start), (c, cv, controller_params)):
        for name, value in (values or {}).items():
            if name not in table:
                raise CoSimError(f"no variable {name!r} in slave {slave_index}")
            ex.real_initial_value(slave_index, table[name][0], float(value))

    obs = CosimObserver.create_time_series()
    ex.add_observer(obs)
    sensed = [n for n, (_, cz) in cv.items() if cz == in_]
    series = [(p, pv[n][0], n) for n in states] + [(c, cv[n][0], n) for n in controls]
    for n in sensed:
        obs.start_time_series(c, cv[n][0], CosimVariableType.REAL)
    for s, vr, _ in series:
        obs.start_time_series(s, vr, CosimVariableType.REAL)
    ok = ex.step(n_steps)
    error = "" if ok else get_last_error_message()
    steps_done = int(round(ex.status().current_time / step_ns))
    cols, times = [], None
    for s, vr, _ in series:
        t0, _, v0 = obs.time_series_real_samples(s, vr, 0, steps_done + 1)  # loses the last
        t1, _, v1 = obs.time_series_real_samples(s, vr, steps_done, 1)
        cols.append(list(v0)[:steps_done] + list(v1))
        if times is None:
            times = list(t0)[:steps_done] + list(t1)
    n = min(len(col) for col in cols)
    signals = np.column_stack([np.asarray(col[:n], dtype=float) for col in cols])
    time = np.asarray(times[:n], dtype=np.int64) * 1e-9
    inputs0 = {}
    for name in sensed:
        _, _, v = obs.time_series_real_samples(c, cv[name][0], 0, 2)  # step 0 (and 1)
        inputs0[name] = float(v[0]) if v else math.nan
    del obs, ex, slaves
    return InteropRun([*states, *controls], time, signals, int(step_ns), complete=ok,
                      error=error, controller_inputs0=inputs0)


def libcosim_verdict(plant: str | Path, controller: str | Path, *,
                     gains: Mapping[str, float] | None = None, step_wingbeats: float = 0.1,
                     n_steps: int = 20) -> Verdict:
    """Identify the closed loop as co-simulated by libcosim and classify it.

    One run per unit initial state x_0 = e_i; x_(-1) is what libcosim fed the controller
    before the first step, read from its observer (0 for our plant, see the module text).
    Four such runs of 20 steps fix the 8 x 8 Jacobi transition matrix (the trajectories span
    the stacked state space after one step). The verdict's ``step_wb`` is the step in wing
    beats actually used (whole nanoseconds).

    Raises
    ------
    CrossCheckError
        The fit's residual exceeds :data:`~dronefly.harness.cosim.identification.FIT_RESIDUAL_TOL`
        (the runs are not the loop identified, e.g. a controller with a sensing delay).
    """
    md = fmpy.read_model_description(str(plant))
    n_hz, scale = plant_md_scales(md)
    h = step_ns(step_wingbeats, n_hz)
    h_wb = h * 1e-9 * n_hz
    runs = []
    for start in unit_start_values(scale):
        r = run_libcosim(plant, controller, step_ns=h, n_steps=n_steps, plant_start=start,
                         controller_params=gains)
        if not r.complete:
            raise CoSimError(f"libcosim identification run failed: {r.error}")
        x_prev = np.array([r.controller_inputs0[s] for s in STATE_NAMES]) / scale
        runs.append(np.vstack([x_prev, r.states() / scale]))
    v = verdict_of(runs, h_wb, delay=True, where=f"libcosim {plant} + {controller}")
    if not math.isfinite(v.identification.dominant_growth_rate):
        raise CoSimError("libcosim identification gave no finite growth rate")
    return v


# -----------------------------------------------------------------------------
# hosts that are not Python
def libpython_path() -> str | None:
    """The shared libpython to preload in a non-Python FMI host, or None if there is none.

    pythonfmu's binary leaves the Python C API symbols (``_Py_NoneStruct``, ...) undefined and
    expects the host process to provide them: a Python host does, a C/C++ host must preload
    libpython. The interpreter's own library comes first (``LIBDIR``/``INSTSONAME``, also under
    ``MULTIARCH`` on Debian); failing that, the system's libpython of the same major.minor
    version (same ABI). None means the interpreter is statically linked
    (``Py_ENABLE_SHARED = 0``) and no such library is installed (Debian: ``libpython3.X``).
    """

    libdir = sysconfig.get_config_var("LIBDIR") or ""
    multiarch = sysconfig.get_config_var("MULTIARCH") or ""
    for so in (sysconfig.get_config_var("INSTSONAME"), sysconfig.get_config_var("LDLIBRARY")):
        if so and ".so" in so:
            for cand in (os.path.join(libdir, so), os.path.join(libdir, multiarch, so)):
                if os.path.isfile(cand):
                    return cand
    found = ctypes.util.find_library(f"python{sys.version_info[0]}.{sys.version_info[1]}")
    if found:
        for d in (libdir, os.path.join("/usr/lib", multiarch), "/usr/lib", "/usr/local/lib"):
            cand = os.path.join(d, found)
            if os.path.isfile(cand):
                return cand
    return None


def c_host_env(base: Mapping[str, str] | None = None) -> dict[str, str]:
    """Environment for running our pythonfmu FMUs in a C/C++ host.

    ``LD_PRELOAD`` = :func:`libpython_path`, ``PYTHONHOME`` = this interpreter's base prefix
    (its standard library), ``PYTHONPATH`` = this environment's site-packages (numpy, scipy,
    which the FMUs import). Raises :class:`CoSimError` if there is no shared libpython.
    """

    lib = libpython_path()
    if lib is None:
        raise CoSimError("no shared libpython for this interpreter (Py_ENABLE_SHARED = "
                         f"{sysconfig.get_config_var('Py_ENABLE_SHARED')}); pythonfmu FMUs "
                         "cannot run in a non-Python host without one")
    env = dict(os.environ if base is None else base)
    paths = [sysconfig.get_paths()["purelib"], sysconfig.get_paths()["platlib"]]
    old = env.get("PYTHONPATH")
    env.update(LD_PRELOAD=lib, PYTHONHOME=sys.base_prefix,
               PYTHONPATH=os.pathsep.join(dict.fromkeys(paths + ([old] if old else []))))
    return env
