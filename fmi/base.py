"""FMI 2.0 co-simulation slave base shared by the project's FMUs.

pythonfmu 0.7.0 provides the C wrapper and :class:`pythonfmu.Fmi2Slave`; this
module replaces the parts that the FMI 2.0 standard and our users need and
pythonfmu does not give: a declarative variable table with units, display
units and ModelStructure dependencies; a model description that passes
``fmpy validate`` (generated from it by :mod:`dronefly.harness.builder.modeldescription`, which
the FMUs do not ship); value storage by value reference; full-state get/set and
serialisation (:mod:`.state`); the FMI 2.0 co-simulation state machine;
and error containment (no Python exception ever reaches the wrapper, where it
would become fmi2Fatal).

pythonfmu 0.7.0 lets a Python slave return a non-OK status only from doStep
(False = fmi2Discard); every other call returns fmi2OK unless an exception
escapes, which is fmi2Fatal and corrupts the instance. So a call that the
standard answers with fmi2Error (a call in the wrong state, an unknown value
reference, a value that may not be set) is logged at once with status
fmi2Error, changes nothing, and the next doStep is refused with the same
message (the standard's error state allows no doStep). ``docs/fmi-limits.md``
lists these calls.

Every logged message passes through :meth:`SlaveBase._report`, which escapes
``%`` (the importer's logger treats the message as a printf format) and any
character that is not UTF-8.

The FMI 3.0 FMUs run the same class behind :class:`~dronefly.fmi.base3.Fmi3Side`, which
changes only the FMI-facing names and statuses (class attributes ``FMI``, ``FMI_TEXT``,
``TYPE_NAMES``, ``STATE_API``, ``ILLEGAL_STATUS``, ``PRINTF_LOGGER``).

Each FMU ships its own copy of this module inside a content-addressed package,
so it must import nothing from the project but relative siblings.
"""

from __future__ import annotations

import math
from typing import Any, ClassVar, Iterable, Sequence

from pythonfmu import Fmi2Slave
from pythonfmu.enums import Fmi2Status

from .calls import (MODES, do_step_status, enter, exit_initialization_mode, in_state, refuse,
    setup_experiment, step_refused)
from .host import finalize_at_exit, inside_fmpy_container, leave_sys_path
from .state import get_fmu_state, set_fmu_state, snapshot, state_from_bytes, state_to_bytes
from .access import (get_boolean, get_integer, get_real, get_string, set_boolean, set_integer,
    set_real, set_string)
from .vars import UNITS, Var

__all__ = ["UNITS", "SlaveBase", "Var"]



class SlaveBase(Fmi2Slave):
    """Variable storage, model description and error containment.

    Subclasses define ``MODEL_NAME``, ``MODEL_DESCRIPTION``, ``VARIABLES``,
    ``DEFAULT_EXPERIMENT`` (start, stop, step in s) and implement
    :meth:`_refresh` (validate and rebuild after parameters or inputs
    changed; raise ``ValueError`` naming the bad value) and :meth:`_advance`
    (one communication step; validates the inputs, which change every step).
    An FMU with direct feedthrough also implements :meth:`_update_outputs`,
    which fmi2GetReal/fmi2GetBoolean call after any value was set.
    Boolean variables are stored in the same value-reference table.
    """

    MODEL_NAME: ClassVar[str]
    MODEL_DESCRIPTION: ClassVar[str]
    VARIABLES: ClassVar[tuple[Var, ...]]
    DEFAULT_EXPERIMENT: ClassVar[tuple[float, float, float]]
    GENERATION_TOOL: ClassVar[str] = "dronefly-fmu (pythonfmu 0.7.0 wrapper)"
    UNITS: ClassVar[dict[str, tuple[dict[str, int], dict[str, float]]]] = UNITS
    #: outputs depend on inputs within a time instant (Modelica block semantics)
    DIRECT_FEEDTHROUGH: ClassVar[bool] = False
    MODES: ClassVar[tuple[str, ...]] = MODES
    #: the FMI version's names in messages (prefix of the calls, standard, type names,
    #: "FMUstate"/"FMUState"), the status of a step refused for an illegal call, and
    #: whether the importer's logger reads messages as printf formats
    FMI: ClassVar[str] = "fmi2"
    FMI_TEXT: ClassVar[str] = "FMI 2.0"
    TYPE_NAMES: ClassVar[dict[str, str]] = {k: k for k in ("Real", "Boolean", "Integer", "String")}
    STATE_API: ClassVar[str] = "FMUstate"
    ILLEGAL_STATUS: ClassVar[Fmi2Status] = Fmi2Status.discard
    PRINTF_LOGGER: ClassVar[bool] = True
    log_categories = {
        "logStatusWarning": "Messages with status fmi2Warning.",
        "logStatusDiscard": "Messages with status fmi2Discard (refused steps).",
        "logStatusError": "Messages with status fmi2Error (rejected values).",
    }

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self.modelName = self.MODEL_NAME
        # the variable table's lookups, made once per class and shared by its instances
        (self._vr, start, self._types, self._settable, self._param_vrs, self._input_rows,
         self._n_vars) = self._class_tables()
        self._real: list[Any] = list(start)
        self._mode = "instantiated"
        self._time = 0.0
        self._stop_time: float | None = None
        self._pending: list[str] = []
        self._dirty = True
        self._stale = True  # a value was set since the last _update_outputs
        self._initialized = False
        # the value references of the last fmi2GetReal of consecutive Real rows and those rows,
        # and of the last fmi2SetReal of consecutive inputs, its state and rows (.values)
        self._get_vrs: list[int] | None = None
        self._get_rows = slice(0, 0)
        self._get_bool_vrs: list[int] | None = None  # the same for fmi2GetBoolean
        self._get_bool_rows = slice(0, 0)
        self._set_vrs: list[int] | None = None
        self._set_mode = ""
        self._set_rows = slice(0, 0)
        self._fmu_id = self._class_fmu_id()
        # The wrapper puts the resources folder at the front of sys.path on every
        # instantiation; the FMU's package is imported by then, so take it out again.
        leave_sys_path(self.resources)
        self._mute = inside_fmpy_container(self.resources)
        finalize_at_exit(self.resources, self.MODEL_NAME)

    # -- subclass hooks ---------------------------------------------------
    def _refresh(self) -> None:  # pragma: no cover - abstract
        raise NotImplementedError

    def _advance(self, t: float, h: float) -> None:  # pragma: no cover - abstract
        raise NotImplementedError

    def _initialize(self) -> None:
        """Compute initial unknowns on leaving initialization mode."""
        self._refresh()

    def _update_outputs(self) -> None:
        """Recompute direct-feedthrough outputs from the current inputs and parameters.

        Called lazily by fmi2GetReal/fmi2GetBoolean when a value was set since
        the last call. Raise ``ValueError`` naming the bad value to keep the
        last outputs; the message is logged with status fmi2Error. The default
        does nothing: outputs change only in doStep.
        """

    def _extra_state(self) -> dict[str, Any]:
        return {}

    def _restore_extra_state(self, state: dict[str, Any]) -> None:
        pass

    # -- helpers ------------------------------------------------------------
    @staticmethod
    def _may_set(v: Var, mode: str) -> bool:
        if v.causality == "input":
            return mode != "terminated"
        if v.causality == "parameter":
            if v.variability == "tunable":
                return mode != "terminated"
            return mode in ("instantiated", "initialization")
        return False

    def _value(self, name: str) -> Any:
        return self._real[self._vr[name]]

    def _values(self, names: Iterable[str]) -> list[Any]:
        r, vr = self._real, self._vr
        return [r[vr[n]] for n in names]

    def _set_values(self, names: Iterable[str], values: Iterable[Any]) -> None:
        r, vr = self._real, self._vr
        for n, x in zip(names, values):
            r[vr[n]] = x

    def _report(self, msg: str, status: Fmi2Status) -> None:
        """Log ``msg``: ``%`` escaped for a printf-style logger, valid UTF-8 guaranteed."""
        if self._mute:
            return
        text = f"{self.instance_name}: {msg}"
        if self.PRINTF_LOGGER:
            text = text.replace("%", "%%")
        self.log(text.encode("utf-8", "backslashreplace").decode("utf-8"), status)

    def _update_if_stale(self) -> None:
        self._stale = False
        try:
            self._update_outputs()
        except BaseException as e:  # getters cannot fail: keep the outputs, say why
            self._report(f"outputs keep their last valid values: {e}", Fmi2Status.error)

    @staticmethod
    def _check_finite(names: Sequence[str], values: Sequence[float]) -> None:
        for n, x in zip(names, values):
            if not math.isfinite(x):
                raise ValueError(f"{n} = {x!r} is not finite")

    # -- FMI calls: functions of .calls, bound here as methods ----------------
    _in_state = in_state
    _refuse = refuse
    _enter = enter
    setup_experiment = setup_experiment
    exit_initialization_mode = exit_initialization_mode

    def enter_initialization_mode(self) -> None:
        self._enter("EnterInitializationMode", "initialization")

    def terminate(self) -> None:
        self._enter("Terminate", "terminated")

    def do_step(self, current_time: float, step_size: float) -> bool:
        # the hot path: every check of do_step_status passes (stepping, nothing pending,
        # initialized, no parameter set, the clock continued exactly, a finite step > 0 that
        # ends at the stop time at the latest); anything else takes do_step_status, which
        # says why it refuses (or accepts a step past the stop time within its tolerance)
        if (self._mode == "stepping" and not self._pending and not self._dirty
                and current_time == self._time and self._initialized):
            end = current_time + step_size
            stop = self._stop_time
            if step_size > 0.0 and end - end == 0.0 and (stop is None or end <= stop):
                try:
                    self._advance(current_time, step_size)
                except BaseException as e:  # never let an exception reach the wrapper
                    return step_refused(self, e, current_time) == 0
                self._time = end
                return True
        return do_step_status(self, current_time, step_size) == 0

    # value access and FMU state: functions of .values and .state, bound
    # here as methods (mixin classes would lengthen the MRO, and pythonfmu's findClass leaks
    # memory per MRO entry on every instantiation)
    get_real = get_real
    get_boolean = get_boolean
    get_integer = get_integer
    get_string = get_string
    set_real = set_real
    set_boolean = set_boolean
    set_integer = set_integer
    set_string = set_string
    _get_fmu_state = get_fmu_state
    _set_fmu_state = set_fmu_state
    _snapshot = snapshot

    @classmethod
    def _class_tables(cls) -> tuple[Any, ...]:
        """What every instance looks up in ``VARIABLES``, made once per class (an instance
        never changes them): name -> value reference, the start values, the types, per state
        and type the rows that may be set, the parameters' rows, per state the Real inputs
        that may be set (no parameter: a set changes no model), and the number of variables."""
        tables = cls.__dict__.get("_TABLES")
        if tables is None:
            vars_ = cls.VARIABLES
            settable = {
                (mode, kind): frozenset(i for i, v in enumerate(vars_)
                                        if v.type == kind and cls._may_set(v, mode))
                for mode in MODES for kind in ("Real", "Boolean", "Integer")
            }
            tables = (
                {v.name: i for i, v in enumerate(vars_)},
                tuple(v.start if v.start is not None else 0.0 for v in vars_),
                tuple(v.type for v in vars_),
                settable,
                frozenset(i for i, v in enumerate(vars_) if v.causality == "parameter"),
                {mode: frozenset(i for i in settable[mode, "Real"]
                                 if vars_[i].causality == "input") for mode in MODES},
                len(vars_),
            )
            cls._TABLES = tables
        return tables

    @classmethod
    def _class_fmu_id(cls) -> str:
        """Model name and content-addressed package: which FMU and build a state belongs to."""
        fmu_id = cls.__dict__.get("_FMU_ID")
        if fmu_id is None:  # one string per class, shared by all its instances and states
            fmu_id = f"{cls.MODEL_NAME}@{cls.__module__.split('.')[0]}"
            cls._FMU_ID = fmu_id
        return fmu_id

    @classmethod
    def _fmu_state_to_bytes(cls, state: Any) -> bytes:
        return state_to_bytes(state, cls._class_fmu_id())

    @classmethod
    def _fmu_state_from_bytes(cls, data: bytes) -> Any:
        return state_from_bytes(data, cls._class_fmu_id())
