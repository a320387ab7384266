"""What a plant and its controller must agree on, for either axis of motion.

Zhang & Sun split the disturbed motion into a lateral part (Sect. 2-3.4) and a
longitudinal part (Sect. 3.5); each is a 4-state linear system with its own
state, controls and non-dimensionalisation. An :class:`Axis` holds those for
one of them: the variable names, SI units with display units, descriptions,
and which reference scale (U [m/s], n [Hz] or none) makes each state
component non-dimensional. :mod:`dronefly.models.lateral_interface` and
:mod:`dronefly.models.longitudinal_interface` define the two instances.

Pure Python (no numpy): the FMUs ship this module.
"""

from __future__ import annotations

import math
import operator
from dataclasses import dataclass
from typing import Callable, Iterable, Sequence

from ..core.errors import DroneflyError

__all__ = ["Axis", "dot"]

#: a . b of two equal-length float sequences: the products K x+ and [Phi Gamma] [x; u] of the
#: FMUs' steps (math.sumprod from Python 3.12, one C loop; before, sum over map)
dot: Callable[[Iterable[float], Iterable[float]], float] = getattr(
    math, "sumprod", lambda a, b: sum(map(operator.mul, a, b)))

_SCALE_TEXT = {"U": "/U", "n": "/n", "1": ""}


@dataclass(frozen=True)
class Axis:
    """One axis of motion: its state x, control u and non-dimensional state x+.

    Attributes
    ----------
    name : str
        ``"lateral"`` or ``"longitudinal"``.
    state_names, control_names : tuple of str
        FMI variable names, in the order of the columns of A and of B.
    state_units : tuple of (unit, display unit or None)
        SI unit of each state.
    control_unit : (unit, display unit)
        Unit of every control (rad, displayed in deg).
    state_descriptions, control_descriptions : tuple of str
        One line each.
    scales : tuple of str
        Per state component: ``"U"``, ``"n"`` or ``"1"``; x+_i = x_i / scale_i.
    """

    name: str
    state_names: tuple[str, ...]
    control_names: tuple[str, ...]
    state_units: tuple[tuple[str, str | None], ...]
    control_unit: tuple[str, str]
    state_descriptions: tuple[str, ...]
    control_descriptions: tuple[str, ...]
    scales: tuple[str, ...]

    def __post_init__(self) -> None:
        n = len(self.state_names)
        for label, seq in (("state_units", self.state_units),
                           ("state_descriptions", self.state_descriptions),
                           ("scales", self.scales)):
            if len(seq) != n:
                raise DroneflyError(f"axis {self.name!r}: {label} has {len(seq)} entries, "
                                    f"expected {n}")
        if len(self.control_descriptions) != len(self.control_names):
            raise DroneflyError(f"axis {self.name!r}: one description per control expected")

    @property
    def nondimensional(self) -> tuple[str, ...]:
        """How each component of x+ is formed, e.g. ``"x+1 = delta_v/U"``."""
        return tuple(f"x+{i + 1} = {name}{_SCALE_TEXT[s]}"
                     for i, (name, s) in enumerate(zip(self.state_names, self.scales)))

    def scale_vector(self, u_m_per_s: float, n_hz: float) -> tuple[float, ...]:
        """The dimensional state is x = x+ * scale (element-wise)."""
        table = {"U": float(u_m_per_s), "n": float(n_hz), "1": 1.0}
        return tuple(table[s] for s in self.scales)

    def to_nondimensional(self, x: Sequence[float], u_m_per_s: float,
                          n_hz: float) -> tuple[float, ...]:
        """Dimensional state (SI) -> x+."""
        return tuple(v / s for v, s in zip(x, self.scale_vector(u_m_per_s, n_hz)))

    def to_dimensional(self, x_plus: Sequence[float], u_m_per_s: float,
                       n_hz: float) -> tuple[float, ...]:
        """x+ -> dimensional state (SI)."""
        return tuple(v * s for v, s in zip(x_plus, self.scale_vector(u_m_per_s, n_hz)))
