"""``dronefly cosim``: co-simulate plant and controller FMUs and check neutral stability.

:func:`cosimulate` is the Python API of the command: one call returns a
:class:`CosimResult` with the time series, the eigenvalues identified from the
co-simulation, the verdict and the cross-checks.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np

from ..builder.build import project_fmus
from ...core.files import run_name, write_run_files
from ...core.text import complex_text
from ...models.feedback import default_gains, gain_name
from ...models.lateral_interface import STATE_NAMES, sort_eigenvalues
from ..cosim.calculated import plant_matrices
from ..cosim.fmu import FMU, column_units
from ..cosim.master import MASTERS, CoSimError, Loop, LoopRun, step_count
from ..cosim.pair import PairError, PairLayout, pair_layout
from ..cosim.params import resolve_assignments, scale_ratios
from ..cosim.identification import (FIT_RESIDUAL_TOL, RATE_TOL_PER_WINGBEAT, TOL_PER_WINGBEAT,
                               TRAJECTORY_TOL, Identification, classify, cross_check_failures,
                               identify, rates_from_transition, relative_deviation,
                               sampled_closed_loop)
from ..latency.grid import GridTiming
from ..latency.identify import identify_delayed
from ..latency.loop import FeedbackLoop, LatencyInputError
from ..latency.sampled import delay_split
from ..paper.gains import as_gain_matrix
from .plot import plot_loop

__all__ = ["DEFAULT_X0", "FIT_RESIDUAL_TOL", "RATE_TOL_PER_WINGBEAT", "TRAJECTORY_TOL", "CosimResult",
           "cosimulate", "parse_x0"]

_ID_STEPS = 20  # steps per identification run
#: The initial state x+ (dv+, dp+, dr+, dgamma) when none is given: a 0.1 rad roll.
DEFAULT_X0 = (0.0, 0.0, 0.0, 0.1)



def parse_x0(text: str | Sequence[float]) -> np.ndarray:
    """Non-dimensional initial state x+ from ``a,b,c,...``: one finite number per state of
    the plant (the lateral plant's dv+, dp+, dr+, dgamma; checked against the plant when the
    pair is known)."""
    try:
        x = [float(p) for p in (text.split(",") if isinstance(text, str) else text)]
    except ValueError:
        raise CoSimError(f"x0 = {text!r}: expected one number per state, e.g. "
                         "dv+,dp+,dr+,dgamma") from None
    if not x or not all(math.isfinite(v) for v in x):
        raise CoSimError(f"x0 = {text!r}: expected finite numbers, one per state, e.g. "
                         "dv+,dp+,dr+,dgamma")
    return np.array(x)


@dataclass
class CosimResult:
    """Everything one co-simulation established."""

    run: LoopRun
    gains: np.ndarray  # 3x4
    master: str
    step_wingbeats: float
    stop_wingbeats: float
    #: identified from the co-simulated runs (their fitted transition matrix)
    identification: Identification
    #: computed from the plant FMU's A1, B1 and K: eig(A1 + B1 K) per wing beat, the continuous
    #: loop (the runs hold the control over each step, so they identify sampled_eigenvalues)
    continuous_eigenvalues: np.ndarray
    #: computed from A1, B1 and K: the exact sampled-data loop at the run's step (zero-order
    #: hold; with a delay line, model (b)), log(mu) / step per wing beat
    sampled_eigenvalues: np.ndarray
    trajectory_error: float  # max relative deviation from the exact sampled-data solution
    csv: Path | None = None
    plot: Path | None = None
    extra: dict[str, Any] = field(default_factory=dict)
    #: the failed cross-checks, one sentence each (empty: all passed)
    check_failures: list[str] = field(default_factory=list)
    #: the states of the loop identified: 4, 8 (Jacobi), or 4 (D + 1) + q with D delayed
    #: samples and q integrals (model (b))
    loop_states: int = 4
    #: sample period and delay of model (b), wing beats (None: no delay, sampling or
    #: integral action in the controller)
    model_b: tuple[float, float] | None = None

    @property
    def verdict(self) -> str:
        """The verdict of the loop identified from the runs."""
        return self.identification.verdict

    @property
    def identified_eigenvalues(self) -> np.ndarray:
        """Eigenvalues per wing beat identified from the co-simulated runs (sorted)."""
        return self.identification.eigenvalues

    def to_json(self) -> dict[str, Any]:
        ev = self.identification.eigenvalues
        return {
            "verdict": self.verdict,
            "complete": self.run.complete,
            "failure": None if self.run.complete else str(self.run.failure),
            "master": self.master,
            "gains": self.gains.tolist(),
            "eigenvalues_per_wingbeat": [[float(e.real), float(e.imag)] for e in ev],
            "eigenvalues_source": "identified from the co-simulated runs; "
                                  "sampled_data_eigenvalues_per_wingbeat and "
                                  "continuous_eigenvalues_per_wingbeat are computed from the "
                                  "plant FMU's A1, B1 and the gains",
            "dominant_growth_rate_per_wingbeat": self.identification.dominant_growth_rate,
            "tolerance_per_wingbeat": TOL_PER_WINGBEAT,
            "continuous_eigenvalues_per_wingbeat":
                [[float(e.real), float(e.imag)] for e in self.continuous_eigenvalues],
            "sampled_data_eigenvalues_per_wingbeat":
                [[float(e.real), float(e.imag)] for e in self.sampled_eigenvalues],
            "identification_fit_residual": self.identification.fit_residual,
            "trajectory_max_rel_error": self.trajectory_error,
            "loop_states": self.loop_states,
            "model_b_sample_period_wb": None if self.model_b is None else self.model_b[0],
            "model_b_delay_wb": None if self.model_b is None else self.model_b[1],
            "check_failures": list(self.check_failures),
            "step_wingbeats": self.step_wingbeats,
            "stop_wingbeats": self.stop_wingbeats,
            "csv": None if self.csv is None else str(self.csv),
            "plot": None if self.plot is None else str(self.plot),
            "recorded": list(self.run.names),
            "built": list(self.extra.get("built", ())),
            "units": dict(self.extra.get("units", {})),
        }

    def summary(self) -> str:
        shown = self.identification.eigenvalues[:_SHOWN]
        ev = ", ".join(complex_text(e) for e in shown)
        rest = len(self.identification.eigenvalues) - len(shown)
        if rest > 0:
            ev += f", ... ({rest} more)"
        where = ("" if self.model_b is None else
                 f" (a loop of {self.loop_states} states: sampled every "
                 f"{self.model_b[0]:g} wing beats, delayed {self.model_b[1]:g})")
        sampled = self.sampled_eigenvalues[:_SHOWN]
        lines = [
            f"verdict: {self.verdict} (dominant rate "
            f"{self.identification.dominant_growth_rate:+.5f} per wing beat, tolerance "
            f"{TOL_PER_WINGBEAT:g})",
            f"identified from the co-simulated runs, per wing beat{where}: {ev}",
            "computed from the plant FMU's A1, B1 and K, per wing beat: the exact sampled-data "
            f"loop at this step (the control held over each step, what the runs are checked "
            f"against): {', '.join(complex_text(e) for e in sampled)}"
            + (", ..." if len(self.sampled_eigenvalues) > len(sampled) else "")
            + f"; eig(A1 + B1 K) of the continuous loop (no hold): "
            f"{', '.join(complex_text(e) for e in self.continuous_eigenvalues)}",
            f"{self.master} master, step {self.step_wingbeats:g} wing beats, "
            f"{len(self.run.time) - 1} steps to {self.stop_wingbeats:g} wing beats; max deviation "
            f"from the exact sampled-data solution {self.trajectory_error:.1e}",
        ]
        requested = self.extra.get("requested_stop_wb")
        if requested is not None and not math.isclose(requested, self.stop_wingbeats,
                                                      rel_tol=1e-9):
            lines.append(f"note: the requested stop {requested:g} wing beats is not a whole "
                         f"number of steps; the run stops at {self.stop_wingbeats:g}")
        for path in self.extra.get("built", ()):
            lines.append(f"built {path} (missing or out of date with the sources)")
        if not self.run.complete:
            lines.append(f"INCOMPLETE: {self.run.failure}")
        lines += [f"CROSS-CHECK FAILED: {f}" for f in self.check_failures]
        if self.csv:
            lines.append(f"csv: {self.csv}")
        if self.plot:
            lines.append(f"plot: {self.plot}")
        return "\n".join(lines)


_SHOWN = 8  # identified eigenvalues the summary lists (the JSON has all)


def _read_plant_matrices(loop: Loop, values: Mapping[str, Any]) -> tuple[np.ndarray, np.ndarray]:
    """A1 and B1 as the plant FMU computes them (calculated parameters) with ``values`` set."""
    matrices = plant_matrices(loop.plant, len(loop.states), len(loop.controls), values)
    if matrices is None:
        raise CoSimError(f"the plant FMU {str(loop.plant.path)!r} does not expose its A and B "
                         "as calculated parameters A[i,j], B[i,j]")
    return matrices


def cosimulate(plant: str | Path | None = None, controller: str | Path | None = None, *,
               gains: str | np.ndarray | None = None, x0: str | Sequence[float] | None = None,
               step_wingbeats: float = 0.1, stop_wingbeats: float = 300.0,
               master: str = "gauss-seidel", out_dir: str | Path | None = "build/cosim",
               plot: bool = True, name: str | None = None,
               set_values: Mapping[str, Any] | None = None,
               record: Sequence[str] = (), build_dir: str | Path = "build",
               allow_scale_mismatch: bool = False) -> CosimResult:
    """Co-simulate the loop, identify its eigenvalues and classify its stability.

    Parameters
    ----------
    plant, controller : path, optional
        FMUs with the DroneFlyLateral / StateFeedback interface (default: the
        project's, built into ``build/`` on demand).
    gains : str or (3, 4) array_like, optional
        Non-dimensional gains u = K x+ of the lateral pair (rows: delta_Phi_a, delta_alpha_1a,
        delta_alpha_2a; columns: dv+, dp+, dr+, dgamma): a named set ``paper`` (Eq. 27),
        ``stabilising`` or ``open``, an inline matrix, a ``.csv``/``.json`` file (see
        :func:`~dronefly.harness.paper.gains.parse_gains`) or an array. None (default):
        ``paper`` for a pair whose plant has the lateral states; for any other pair the
        controller's own ``K[i,j]`` (with ``set_values``). ``open`` (all zeros) fits any
        pair; another matrix of the wrong shape is refused.
    x0 : str or sequence, optional
        Non-dimensional initial state x+, one value per state of the plant (the pair's
        states: :func:`~dronefly.harness.cosim.pair.pair_layout`). Default: 0.1 rad in the
        plant's first angle (for the lateral plant :data:`DEFAULT_X0`, a 0.1 rad roll), with
        the states whose ``plant.<state>_start`` [SI] ``set_values`` gives taken from there;
        giving both is refused.
    step_wingbeats, stop_wingbeats : float
        Communication step and stop time in wing beats.
    master : {'gauss-seidel', 'jacobi'}
    out_dir : path or None
        Where the CSV (and PNG) go; None writes nothing.
    set_values : mapping, optional
        ``{"plant.Lv_plus": 0.2, "controller.limit_enabled": "1", ...}``: parameter (or
        input) values in each FMU's unit, set in initialization mode; a bare name that only
        one FMU has is enough. Numbers, booleans or text (as ``--set`` gives them), converted
        to each variable's declared type before anything runs
        (:func:`~dronefly.harness.cosim.params.resolve_assignments`).
    record : sequence of str
        More variables to record after the states and controls, ``plant.NAME`` or
        ``controller.NAME``: any Real, Integer or Boolean variable of any causality (e.g.
        ``plant.n``, ``controller.K[1,1]``, ``controller.saturated``, ``plant.delta_Phi_a``),
        in the run's CSV and its JSON's ``recorded``; Booleans as 0 and 1 (a str is one
        name).
    build_dir : path
        Where the project's FMUs are built when ``plant`` or ``controller`` is not given.
    allow_scale_mismatch : bool
        Accept a plant and a controller whose ``n`` or ``U`` differ (the controller then reads
        the plant's x+ scaled by their ratios; the model and the cross-checks use the gains
        as the plant sees them). Otherwise such a pair is refused.

    Raises
    ------
    PairError
        A pair whose loop cannot be identified (its states, controls or gains; the reason
        named), gains or x0 of another shape than the pair's.
    ParameterError
        The plant's and the controller's ``n`` or ``U`` differ (without
        ``allow_scale_mismatch``), a ``set_values`` name or value that cannot be used.
    CoSimError
        A bad step, stop, master or x0, or x0 together with a ``plant.<state>_start``;
        sample instants off the communication grid.
    """
    K = None if gains is None else as_gain_matrix(gains)
    x0v = None if x0 is None else parse_x0(x0)
    step_count(stop_wingbeats, step_wingbeats)  # validates before anything is built
    if master not in MASTERS:
        raise CoSimError(f"master = {master!r}; choose one of {', '.join(MASTERS)}")

    built: list[Path] = []
    plant_given, controller_given = plant is not None, controller is not None
    plant, controller = project_fmus(plant, controller, build_dir, built=built)
    record = (record,) if isinstance(record, str) else tuple(record)
    given_fmus = plant_given or controller_given
    with FMU(plant) as pf, FMU(controller) as cf:
        loop = Loop(pf, cf)
        values = resolve_assignments(dict(set_values or {}), {
            "plant": pf.model_description, "controller": cf.model_description})
        # what differs from the defaults names the files (the gains: _default_name)
        inputs = {k: v for k, v in (
            ("x0", None if x0v is None else x0v.tolist()),
            ("step_wb", None if step_wingbeats == 0.1 else step_wingbeats),
            ("stop_wb", None if stop_wingbeats == 300.0 else stop_wingbeats),
            ("set", {k: repr(v) for k, v in sorted(dict(set_values or {}).items())} or None),
            ("record", list(record) or None),
            ("fmus", [pf.model_description.guid, cf.model_description.guid]
             if given_fmus else None)) if v is not None}
        result = _cosimulate(loop, K, x0v, step_wingbeats, stop_wingbeats, master, out_dir,
                             plot, name, values, record,
                             allow_scale_mismatch, [str(p) for p in built], inputs)
    result.extra["requested_stop_wb"] = stop_wingbeats
    return result


def _controller_timing(cf: FMU, ctrl_values: Mapping[str, Any], n_hz: float,
                       layout: PairLayout) -> tuple[float, float, np.ndarray]:
    """(sensing delay, sample period) in wing beats and the integral gains KI (controls x
    states) the controller runs with: its start values with ``ctrl_values`` set (0 where it
    has none)."""

    start = {**cf.start_values(), **ctrl_values}

    def value(name: str) -> float:
        v = start.get(name)
        return 0.0 if v is None else float(v)

    KI = np.array([[value(name) for name in row] for row in layout.gain_names("KI")])
    return value("sensing_delay") * n_hz, value("sample_period") * n_hz, KI


def _initial_state(x0: np.ndarray | None, plant_values: Mapping[str, Any],
                   scale: np.ndarray, layout: PairLayout) -> np.ndarray:
    """x0, or the layout's default x0 with the states ``plant_values`` starts
    (``<state>_start``, SI) taken from there; both given: refused."""
    given = {i: f"{s}_start" for i, s in enumerate(layout.states)
             if f"{s}_start" in plant_values}
    if x0 is not None and len(x0) != len(layout.states):
        raise PairError(f"x0 = {','.join(f'{v:g}' for v in x0)} (--x0) has {len(x0)} values; "
                        f"the plant has {len(layout.states)} states "
                        f"({', '.join(layout.states)}, as x+)")
    if given and x0 is not None:
        name = next(iter(given.values()))
        raise CoSimError(f"x0 = {','.join(f'{v:g}' for v in x0)} (--x0) and plant.{name} = "
                         f"{plant_values[name]!r} both set the initial state: give one of them")
    if x0 is not None:
        return x0
    out = layout.default_x0()
    for i, name in given.items():
        out[i] = float(plant_values[name]) / scale[i]
    return out


def _gains(K: np.ndarray | None, layout: PairLayout, cf: FMU,
           ctrl_values: Mapping[str, Any]) -> np.ndarray:
    """The loop's gains: ``K`` checked against the pair's shape, or by default the paper's
    (a lateral pair) or the controller's own K (any other pair)."""
    lateral = layout.states == tuple(STATE_NAMES)
    if K is None:
        if lateral and layout.shape == np.shape(default_gains()):
            return np.array(default_gains(), dtype=float)
        start = {**cf.start_values(), **ctrl_values}
        return np.array([[float(start.get(n) or 0.0) for n in row]
                         for row in layout.gain_names()])
    if K.shape == layout.shape:
        return K
    if not K.any():  # open: no control, whatever the shape
        return np.zeros(layout.shape)
    raise PairError(f"--gains is a {K.shape[0]}x{K.shape[1]} matrix (the lateral design); "
                    f"this pair has {layout.shape[0]} controls x {layout.shape[1]} states "
                    f"({', '.join(layout.controls)} on {', '.join(layout.states)}): omit "
                    "--gains to run the controller's own K, set its elements with --set "
                    "controller.K[i,j]=VALUE, or give --gains open")


def _cosimulate(loop: Loop, K: np.ndarray | None, x0: np.ndarray | None, step_wb: float, stop_wb: float,
                master: str, out_dir: str | Path | None, plot: bool,
                name: str | None, values: Mapping[str, Mapping[str, Any]],
                record: Sequence[str] = (), allow_scale_mismatch: bool = False,
                built: Sequence[str] = (), inputs: Mapping[str, Any] | None = None
                ) -> CosimResult:
    pf, cf = loop.plant, loop.controller
    layout = pair_layout(pf, cf)  # refused here, with the reason, if it cannot be identified
    states, ns = list(layout.states), len(layout.states)
    plant_values, ctrl_values = dict(values.get("plant", {})), dict(values.get("controller", {}))
    K = _gains(K, layout, cf, ctrl_values)
    scale = layout.scale_vector({**pf.start_values(), **plant_values})
    ratio = scale_ratios({**pf.start_values(), **plant_values},
                         {**cf.start_values(), **ctrl_values},
                         allow_mismatch=allow_scale_mismatch, scales=layout.scales)
    x0 = _initial_state(x0, plant_values, scale, layout)
    n = float(layout.scale_vector({**pf.start_values(), **plant_values}, ("n",))[0])  # Hz
    h = step_wb / n
    n_steps = step_count(stop_wb, step_wb)
    stop_wb = round(n_steps * step_wb, 12)  # what is run and reported: whole steps, never past
    gains = {**ctrl_values,
             **{gain_name(i, j): float(K[i, j]) for i in range(K.shape[0]) for j in range(K.shape[1])}}
    jacobi = master == "jacobi"
    tau_wb, period_wb, KI = _controller_timing(cf, ctrl_values, n, layout)
    Km = K  # the gains as the plant sees them: u = Km x+ in the plant's scales
    n_ratio = 1.0 if ratio is None else float(
        ratio[layout.scales.index("n")] if "n" in layout.scales else 1.0)
    if ratio is not None:
        # the controller's x+ is ratio * the plant's, its integral runs over its own wing
        # beats (n_c / n_p = 1 / ratio[1] of the plant's)
        Km, KI = K * ratio, KI * ratio / n_ratio
    timing = None
    if tau_wb or period_wb or KI.any():
        timing = GridTiming(step_wb, tau_wb, period_wb, jacobi)
        if jacobi and timing.tau_eff == 0.0 and (KI.any() or timing.model_b() is None):
            # the master's one-step lag delays the sensed state but not the integral of it:
            # not model (b), whose delay delays both
            raise CoSimError(
                "with the Jacobi master and no sensing delay the controller sees every sample "
                "one step late; cosim identifies that loop only without integral gains (KI) "
                "and sampling at every step: give controller.sensing_delay of at least one "
                f"step ({step_wb / float(n)!r} s) or use --master gauss-seidel")
        if timing.model_b() is None:
            raise CoSimError(
                f"controller.sample_period = {float(period_wb / n)!r} s is {period_wb:.9g} wing "
                f"beats, not a whole number of steps of {step_wb:g} wing beats: its sample "
                "instants drift off the communication grid and cosim identifies only loops "
                f"whose instants are on it (one wing beat is {1.0 / float(n)!r} s)")

    def start(x: np.ndarray) -> dict[str, float]:
        return {**plant_values, **{f"{s}_start": float(v) for s, v in zip(states, x * scale)}}

    A, B = _read_plant_matrices(loop, plant_values)
    with pf.instantiate() as p, cf.instantiate() as c:
        # with a delay line (model (b)) the controller starts at the equilibrium: under the
        # Jacobi master it is fed x = 0 before the first step, as model (b) has it
        feed0 = [0.0] * ns if jacobi and timing is not None else None
        run = loop.run(h, n_steps, master=master, plant_start=start(x0),
                       controller_params=gains, instances=(p, c), record=record,
                       u_source0=feed0)
        if timing is None:
            ident, F, exact_rates = _identify_plain(loop, p, c, start, gains, h, step_wb,
                                                    n_steps, scale, jacobi, A, B, Km, states)
        else:
            ident, F, exact_rates, _ = _identify_model_b(loop, p, c, start, gains, h,
                                                         timing, scale, A, B, Km, KI, states)
        open_run = None
        if plot and out_dir is not None and K.any():  # the open loop, for comparison
            zero = {**gains, **{gain_name(i, j): 0.0 for i in range(K.shape[0])
                                for j in range(K.shape[1])}}
            open_run = loop.run(h, n_steps, master=master, plant_start=start(x0),
                                controller_params=zero, instances=(p, c), u_source0=feed0)
    cont = np.array(sort_eigenvalues(np.linalg.eigvals(A + B @ Km)), dtype=complex)
    xs = np.column_stack([run.column(s) for s in states]) / scale
    z = np.zeros(len(F))
    z[:ns] = x0
    if jacobi and timing is None:
        z[ns:2 * ns] = x0  # the Jacobi master feeds the controller x0 before the first step
    every = 1 if timing is None else int(round(timing.Ts / step_wb))
    xs = xs[::every]
    ref = np.empty_like(xs)
    for k in range(len(xs)):
        ref[k] = z[:ns]
        z = F @ z
    err = relative_deviation(xs, ref)
    exact_dominant = float(np.max(exact_rates.real))
    what = ("the exact sampled-data loop" if timing is None else
            "model (b), the exact sampled-data loop with the delay line")
    failures = cross_check_failures(ident.dominant_growth_rate, exact_dominant, ident.fit_residual, err,
                      ident.verdict, classify(exact_rates), what)
    result = CosimResult(run, K, master, step_wb, stop_wb, ident, cont, exact_rates, err,
                         check_failures=failures, loop_states=len(F),
                         model_b=None if timing is None else timing.model_b())
    result.extra["scale"] = scale.tolist()
    result.extra["built"] = list(built)
    result.extra["controls"] = list(loop.controls)  # what the plot draws as controls
    result.extra["states"] = states
    # the unit of every CSV column, as the FMUs declare it (the JSON's "units")
    result.extra["units"] = column_units(run.names, {"plant": pf, "controller": cf}, "plant")
    result.extra["state_units"] = list(layout.units)
    if open_run is not None:
        result.extra["open_loop"] = open_run
    if out_dir is not None:
        write_run_files(result, out_dir, name or _default_name(K, master, inputs or {}),
                        plot_loop if plot else None)
    return result


def _identify_plain(loop: Loop, p: Any, c: Any, start: Any, gains: Mapping[str, float],
                    h: float, step_wb: float, n_steps: int, scale: np.ndarray, jacobi: bool,
                    A: np.ndarray, B: np.ndarray, K: np.ndarray, states: Sequence[str]
                    ) -> tuple[Identification, np.ndarray, np.ndarray]:
    """The loop without delay line: F fitted from runs from the unit states, the exact F
    (zero-order hold at the step) and its rates per wing beat."""
    id_runs = []
    eye = np.eye(len(states))
    units = [(e, e) for e in eye]
    if jacobi:
        units = [(e, e) for e in eye] + [(np.zeros(len(states)), e) for e in eye]
    for x_now, x_prev in units:
        r = loop.run(h, min(_ID_STEPS, n_steps), master="jacobi" if jacobi else "gauss-seidel",
                     plant_start=start(x_now), controller_params=gains,
                     u_source0=list(x_prev * scale), instances=(p, c))
        if not r.complete:
            raise CoSimError(f"identification run failed: {r.failure}")
        xs = np.column_stack([r.column(s) for s in states]) / scale
        id_runs.append(np.vstack([x_prev, xs]) if jacobi else xs)
    ident = identify(id_runs, step_wb, delay=jacobi)
    F = sampled_closed_loop(A, B, K, step_wb, jacobi)
    return ident, F, rates_from_transition(F, step_wb)


def _identify_model_b(loop: Loop, p: Any, c: Any, start: Any, gains: Mapping[str, float],
                      h: float, timing: Any, scale: np.ndarray, A: np.ndarray, B: np.ndarray,
                      K: np.ndarray, KI: np.ndarray, states: Sequence[str]
                      ) -> tuple[Identification, np.ndarray, np.ndarray, Any]:
    """The loop with its delay line and integral (model (b)): M fitted from runs from the unit
    states (the controller's line at the equilibrium), the exact M and its rates per wing beat."""

    Ts, tau = timing.model_b()
    d, _ = delay_split(tau, Ts)
    m = int(round(Ts / timing.h))
    samples = 2 * (d + 2) + 10  # pairs enough to span the 4 (d + 2) + q augmented states
    fl = FeedbackLoop(A, B, K, KI)
    runs = []
    for e in np.eye(len(states)):
        r = loop.run(h, samples * m, master="jacobi" if timing.jacobi else "gauss-seidel",
                     plant_start=start(e), controller_params=gains, instances=(p, c),
                     u_source0=[0.0] * len(states) if timing.jacobi else None)
        if not r.complete:
            raise CoSimError(f"identification run failed: {r.failure}")
        runs.append(np.column_stack([r.column(s) for s in states])[::m] / scale)
    try:
        fit = identify_delayed(runs, fl, Ts, tau)
    except LatencyInputError as e:
        raise CoSimError(f"cannot identify the delayed loop: {e}") from e
    rates = rates_from_transition(fit.transition, Ts)
    ident = Identification(fit.transition, rates, float(np.max(rates.real)), classify(rates),
                           fit.fit_residual)
    return ident, fit.exact, rates_from_transition(fit.exact, Ts), fit


def _default_name(K: np.ndarray, master: str, inputs: Mapping[str, Any]) -> str:
    """``cosim_<gains>_<master>``, with a digest of every other input that differs from the
    defaults (:func:`~dronefly.core.files.run_name`): two runs with different inputs never
    share a name."""
    inputs = dict(inputs)
    if not K.any():
        tag = "open"
    elif np.array_equal(K, np.array(default_gains())):
        tag = "paper"
    else:
        tag = "custom"
        inputs["gains"] = K.tolist()
    return run_name(f"cosim_{tag}_{master}", inputs)

