"""The cases of ``dronefly sweep``: what is swept, and how each case is named.

Sect. 3.6 of the paper bounds the validity of the linear analysis by
|dv+|, |dp+|, |dr+| <= 0.15, |dgamma| <= 0.22 (the *validity box*) and
|control| <= 0.4 rad. A sweep is the product of four dimensions:

initial disturbance x+(0)
    ``grid``: an N x N grid over a two-dimensional slice of the box (the other two
    components zero); ``lhs``: a Latin hypercube over the whole box; ``directions``:
    a direction (a state axis, or the unstable open-loop eigenvector ``mode1``)
    times an amplitude a in (0, 1], in units of the box (a = 1 touches its face).
gain set
    ``paper`` (Eq. 27, neutral), ``stabilising`` (lambda_1 moved to
    ``STABILISING_LAMBDA1`` with delta_Phi_a alone), ``open`` (no control).
communication step
    How often the insect senses and acts, in wing beats (meaningful: 0.1 to 3).
sensing delay and sample period
    The controller's ``sensing_delay`` and ``sample_period``, in wing beats (0 and 0, the
    default, set nothing: the controller's defaults); see :mod:`harness.sweep.delays`.
bound scale
    A factor on the bounds checked; the initial disturbances stay in the nominal box.

Every case has a deterministic number (its position in that product) and a
``key``: a hash of everything that determines its result, used to resume.
"""

from __future__ import annotations

import hashlib
import itertools
import math
from dataclasses import dataclass, field
from typing import Any, Mapping

import numpy as np

from ...core.errors import DroneflyError
from ...models.feedback import U_MAX_LINEAR_RANGE
from ...models.lateral_interface import STATE_BOUNDS_SECT36, eigen_order
from ..paper.gains import GAIN_SETS, STABILISING_LAMBDA1, gain_matrix, parse_gains
from ...models import lateral_dynamics
from ..cosim.master import MASTERS, MAX_STEPS
from .parse import (AXES, SweepInputError, one_line, parse_floats, parse_int, parse_names,
    parse_slices)

__all__ = ["MAX_CASES", "AXES", "one_line", "Case", "DEFAULT_DIRECTIONS", "DISTURBANCES", "GAIN_SETS",
           "STABILISING_LAMBDA1", "STATE_BOUNDS_SECT36", "SweepInputError", "SweepSpec",
           "direction_vector",
           "gain_matrix", "parse_floats", "parse_int", "parse_names", "parse_slices"]

#: Cases per sweep at most (rows of sweep.csv, about 1 kB each, and their results in memory).
MAX_CASES = 200_000

DISTURBANCES: tuple[str, ...] = ("grid", "lhs", "directions")
DEFAULT_DIRECTIONS: tuple[str, ...] = tuple(f"{s}{a}" for a in (*AXES, "mode1") for s in "+-")


def _mode1_direction() -> np.ndarray:
    """Unstable open-loop eigenvector in box units (max component 1, dgamma > 0)."""
    A, _ = lateral_dynamics.system_matrices(lateral_dynamics.default_parameters())
    w, V = np.linalg.eig(A)
    v = np.real(V[:, eigen_order(w)[0]]) / np.array(STATE_BOUNDS_SECT36)
    v = v / np.max(np.abs(v))
    return v if v[3] >= 0 else -v


def direction_vector(name: str) -> np.ndarray:
    """A direction of ``DEFAULT_DIRECTIONS`` (``+dv``, ``-mode1``, ...) in box units."""
    sign = 1.0 if name[0] == "+" else -1.0
    if name[1:] == "mode1":
        return sign * _mode1_direction()
    d = np.zeros(4)
    d[AXES.index(name[1:])] = sign
    return d


@dataclass(frozen=True)
class Case:
    """One closed-loop run. ``x0`` is non-dimensional (dv+, dp+, dr+, dgamma)."""

    case: int
    family: str  # grid | lhs | direction | custom
    label: str  # the slice "X:Y", the direction "+dp", or ""
    amplitude: float  # direction cases: box units; NaN otherwise
    x0: tuple[float, float, float, float]
    gains: str
    K: tuple[tuple[float, ...], ...]
    step_wb: float
    scale: float
    stop_wb: float
    master: str = "gauss-seidel"
    #: ``--set`` values (name, value) of the plant and of the controller, in their units
    plant_values: tuple[tuple[str, Any], ...] = ()
    controller_values: tuple[tuple[str, Any], ...] = ()
    #: the controller's sensing_delay and sample_period, wing beats (0: not set)
    delay_wb: float = 0.0
    sample_period_wb: float = 0.0
    key: str = field(init=False)

    def __post_init__(self) -> None:
        timing = (float(self.delay_wb), float(self.sample_period_wb))
        ident = repr((tuple(map(float, self.x0)), tuple(tuple(map(float, r)) for r in self.K),
                      float(self.step_wb), float(self.scale), self.n_steps, self.master)
                     + ((self.plant_values, self.controller_values)
                        if self.plant_values or self.controller_values else ())
                     + ((timing,) if any(timing) else ()))
        object.__setattr__(self, "key", hashlib.sha1(ident.encode()).hexdigest()[:16])

    @property
    def n_steps(self) -> int:
        """Communication steps: stop / step, rounded (at least 1)."""
        return max(1, int(round(self.stop_wb / self.step_wb)))


@dataclass(frozen=True)
class SweepSpec:
    """What a sweep covers; every field has the ``dronefly sweep`` default.

    Attributes
    ----------
    disturbances : subset of ``DISTURBANCES``
    slices : ((x axis, y axis), ...)
        Slices of the box covered by ``grid``.
    grid_points : int
        Points per axis of each grid (odd keeps the origin), >= 2.
    lhs_points : int
        Latin-hypercube samples over the box (seeded by ``seed``), >= 1.
    directions : names like ``+dv`` or ``-mode1``
    amplitudes : int
        Amplitudes 1/N, 2/N, ..., 1 (box units) per direction, >= 1.
    gains : subset of ``GAIN_SETS``
    steps_wb : communication steps, wing beats, each > 0 and <= ``stop_wb``
    delays_wb : the controller's ``sensing_delay`` per case, wing beats, each >= 0
    sample_periods_wb : its ``sample_period``, wing beats, each >= 0 (0: every step)
    scales : factors on the bounds checked, each > 0
    stop_wb : float
        Simulated time, wing beats.
    master : {'gauss-seidel', 'jacobi'}
    seed : int
    extent : float
        The grid, the Latin hypercube and the direction amplitudes cover ``extent`` times
        the box (> 0; the bounds checked stay the box times ``scales``).
    """

    disturbances: tuple[str, ...] = ("grid", "directions")
    slices: tuple[tuple[str, str], ...] = (("dgamma", "dv"), ("dgamma", "dp"), ("dr", "dp"))
    grid_points: int = 21
    lhs_points: int = 200
    directions: tuple[str, ...] = DEFAULT_DIRECTIONS
    amplitudes: int = 10
    gains: tuple[str, ...] = ("paper", "stabilising")
    steps_wb: tuple[float, ...] = (0.1, 1.0, 3.0)
    scales: tuple[float, ...] = (1.0,)
    stop_wb: float = 200.0
    master: str = "gauss-seidel"
    seed: int = 0
    #: the disturbances cover ``extent`` times the box (grid, Latin hypercube, amplitudes)
    extent: float = 1.0
    #: the controller's sensing delays and sample periods, wing beats (each >= 0; 0: not set)
    delays_wb: tuple[float, ...] = (0.0,)
    sample_periods_wb: tuple[float, ...] = (0.0,)

    @classmethod
    def from_text(cls, *, disturbances: str, slices: str, grid: str, lhs: str, directions: str,
                  amplitudes: str, gains: str, steps: str, scales: str, stop: str, master: str,
                  seed: str, extent: float = 1.0, delays: str = "0",
                  sample_periods: str = "0") -> "SweepSpec":
        """A validated spec from command-line strings (comma-separated lists)."""
        spec = cls(parse_names(disturbances, "disturbances", DISTURBANCES), parse_slices(slices),
                   parse_int(grid, "grid", 2), parse_int(lhs, "lhs", 1),
                   parse_names(directions, "directions", DEFAULT_DIRECTIONS),
                   parse_int(amplitudes, "amplitudes", 1), parse_names(gains, "gains", GAIN_SETS),
                   parse_floats(steps, "steps"), parse_floats(scales, "scales"),
                   parse_floats(stop, "stop")[0], master, parse_int(seed, "seed", 0),
                   parse_floats([extent] if isinstance(extent, (int, float)) else extent,
                                "extent")[0],
                   parse_floats(delays, "delays"), parse_floats(sample_periods, "sample-periods"))
        spec.validate()
        return spec

    def validate(self) -> None:
        """Raise :class:`SweepInputError` naming the first bad value."""
        parse_names(self.disturbances, "disturbances", DISTURBANCES)
        parse_names(self.gains, "gains", GAIN_SETS)
        if not (isinstance(self.extent, (int, float)) and math.isfinite(self.extent)
                and self.extent > 0):
            raise SweepInputError(f"extent = {self.extent!r} must be finite and > 0")
        parse_names(self.directions, "directions", DEFAULT_DIRECTIONS)
        parse_slices(self.slices)
        if self.master not in MASTERS:
            raise SweepInputError(f"master = {self.master!r}; choose from {', '.join(MASTERS)}")
        for name, v, lo in (("grid_points", self.grid_points, 2), ("lhs_points", self.lhs_points, 1),
                            ("amplitudes", self.amplitudes, 1), ("seed", self.seed, 0)):
            if not isinstance(v, (int, np.integer)) or isinstance(v, bool) or v < lo:
                raise SweepInputError(f"{name} = {v!r} must be an integer >= {lo}")
        stop = parse_floats([self.stop_wb], "stop")[0]
        if stop <= 0:
            raise SweepInputError(f"stop = {self.stop_wb!r} wing beats must be > 0")
        for h in parse_floats(self.steps_wb, "steps"):
            if not 0 < h <= stop:
                raise SweepInputError(f"step = {h!r} wing beats must be > 0 and <= stop ({stop:g})")
            if stop / h > MAX_STEPS:
                raise SweepInputError(f"stop / step = {stop!r} / {h!r} exceeds {MAX_STEPS} "
                                      "communication steps per case")
        for s in parse_floats(self.scales, "scales"):
            if s <= 0:
                raise SweepInputError(f"scale = {s!r} must be > 0")
        for name, values in (("delay", self.delays_wb), ("sample period", self.sample_periods_wb)):
            for v in parse_floats(values, name):
                if v < 0:
                    raise SweepInputError(f"{name} = {v!r} wing beats must be >= 0")
        n = self.case_count()
        if n > MAX_CASES:
            raise SweepInputError(
                f"{n} cases (grid {self.grid_points} x {self.grid_points} per slice, lhs "
                f"{self.lhs_points}, directions x amplitudes, times gains, steps and scales) exceed "
                f"the limit of {MAX_CASES}: one row of sweep.csv each (about 1 kB) and their "
                "results are held in memory; split the sweep")

    def case_count(self) -> int:
        """The number of cases, counted before any is made (no allocation)."""
        per = 0
        if "grid" in self.disturbances:
            per += len(tuple(self.slices)) * int(self.grid_points) ** 2
        if "lhs" in self.disturbances:
            per += int(self.lhs_points)
        if "directions" in self.disturbances:
            per += len(tuple(self.directions)) * int(self.amplitudes)
        return (per * len(tuple(self.gains)) * len(tuple(self.steps_wb)) * len(tuple(self.scales))
                * len(tuple(self.delays_wb)) * len(tuple(self.sample_periods_wb)))

    def initial_states(self) -> list[tuple[str, str, float, np.ndarray]]:
        """(family, label, amplitude, x+(0)) of every disturbance, in a fixed order."""
        box = np.array(STATE_BOUNDS_SECT36)
        out: list[tuple[str, str, float, np.ndarray]] = []
        if "grid" in self.disturbances:
            g = np.linspace(-self.extent, self.extent, self.grid_points)
            for ax, ay in self.slices:
                i, j = AXES.index(ax), AXES.index(ay)
                for b in g:  # rows: y
                    for a in g:  # columns: x
                        x = np.zeros(4)
                        x[i], x[j] = a * box[i], b * box[j]
                        out.append(("grid", f"{ax}:{ay}", math.nan, x))
        if "lhs" in self.disturbances:
            rng = np.random.default_rng(self.seed)
            n = self.lhs_points
            u = np.column_stack([(rng.permutation(n) + rng.random(n)) / n for _ in range(4)])
            for row in u:
                out.append(("lhs", "", math.nan, (2.0 * row - 1.0) * box * self.extent))
        if "directions" in self.disturbances:
            for name in self.directions:
                d = direction_vector(name)
                for k in range(1, self.amplitudes + 1):
                    a = k / self.amplitudes * self.extent
                    out.append(("direction", name, a, a * d * box))
        return out

    def cases(self, values: Mapping[str, Mapping[str, Any]] | None = None) -> list[Case]:
        """Every case, numbered: gain set x step x delay x sample period x scale x disturbance.

        ``values``: ``--set`` values by instance (``plant``, ``controller``), as resolved by
        :func:`dronefly.harness.cosim.params.resolve_assignments`.
        """
        self.validate()
        x0s = self.initial_states()
        pv = tuple(sorted((values or {}).get("plant", {}).items()))
        cv = tuple(sorted((values or {}).get("controller", {}).items()))
        out: list[Case] = []
        for g in self.gains:
            try:
                K = tuple(tuple(float(v) for v in row) for row in parse_gains(g))
            except DroneflyError as e:
                raise SweepInputError(str(e)) from e
            for h, d, T, s in itertools.product(self.steps_wb, self.delays_wb,
                                                self.sample_periods_wb, self.scales):
                for family, label, amp, x in x0s:
                    out.append(Case(len(out), family, label, amp, tuple(float(v) for v in x), g,
                                    K, float(h), float(s), float(self.stop_wb), self.master, pv,
                                    cv, float(d), float(T)))
        return out


#: The control bound of Sect. 3.1/3.6, rad (re-exported for the sweep).
CONTROL_BOUND: float = U_MAX_LINEAR_RANGE
