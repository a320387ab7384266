"""Value access of :class:`dronefly.fmi.SlaveBase`: fmi2Get/fmi2Set of every type.

Functions of the slave (``self``), bound as methods in ``SlaveBase``. A getter
cannot fail in pythonfmu 0.7.0 (an exception would be fmi2Fatal): reads of
unknown value references or of a type the FMU does not have are logged with
status fmi2Error and answered with NaN / false / 0 / "". A value that may not
be set is logged at once and kept for the next doStep, which is refused.

Shipped inside every FMU with the rest of :mod:`dronefly.fmi`; imports only the standard library
and pythonfmu.
"""

from __future__ import annotations

import math
from typing import Any

from pythonfmu.enums import Fmi2Status

__all__ = ["get_boolean", "get_integer", "get_real", "get_string", "set_boolean", "set_integer",
           "set_real", "set_rows", "set_string"]

_NONE: frozenset[int] = frozenset()  # the settable rows of a type the FMU does not have


def _vr_text(vr: int) -> str:
    return f"valueReference {vr & 0xFFFFFFFF}"  # the wrapper passes the unsigned reference as int


def _reject(self: Any, vr: int, value: Any, why: str, kind: str) -> None:
    name = self.VARIABLES[vr].name if 0 <= vr < self._n_vars else _vr_text(vr)
    msg = f"{self.FMI}Set{self.TYPE_NAMES[kind]}: {name} = {value!r} rejected: {why}"
    self._pending.append(msg)
    self._report(msg, Fmi2Status.error)


def _read(self: Any, vrs: list[int], kind: str, convert: Any, fallback: Any) -> list[Any]:
    """Values of ``vrs`` as ``kind``; wrong ones logged and answered with ``fallback``."""
    try:
        if self._mode == "instantiated":
            self._in_state("Get", f"{self.FMI}Get{self.TYPE_NAMES[kind]}")
        if self._stale:
            self._update_if_stale()
        r, types, n = self._real, self._types, self._n_vars
        # the wrapper passes value references as C int: 2**32 - 1 arrives as -1
        if vrs and (min(vrs) < 0 or max(vrs) >= n or any(types[i] != kind for i in vrs)):
            _bad_get(self, vrs, kind)
            return [convert(r[i]) if 0 <= i < n and types[i] == kind else fallback for i in vrs]
        return [convert(r[i]) for i in vrs]
    except BaseException as e:  # a getter cannot fail: log, answer the fallback
        self._report(f"{self.FMI}Get{self.TYPE_NAMES[kind]} failed: {e!r}", Fmi2Status.error)
        return [fallback for _ in vrs]


def get_real(self: Any, vrs: list[int]) -> list[float]:
    try:  # the hot path of every co-simulation step: no per-element checks
        if self._stale:  # a direct-feedthrough FMU after a set: recompute the outputs once
            self._update_if_stale()
        if vrs == self._get_vrs and self._mode != "instantiated":
            return self._real[self._get_rows]  # the rows of the last such read: one slice
        r = self._real
        if self._mode == "instantiated" or min(vrs) < 0:
            raise IndexError  # (a reference >= 2**31 arrives negative and would wrap around)
        out = [r[i] for i in vrs]  # an index past the end raises; PyFloat_AsDouble converts
        rows = _real_block(self, vrs)
        if rows is not None:  # consecutive Real rows: the next read of them is a slice
            self._get_vrs, self._get_rows = list(vrs), rows
        return out
    except BaseException:  # also min() of no references: answered (empty) by _read
        return _read(self, vrs, "Real", float, math.nan)


def _real_block(self: Any, vrs: list[int]) -> slice | None:
    """``vrs`` as one slice of the value table if they are consecutive Real rows, in order."""
    return _block_of(self, vrs, "Real")


def _block_of(self: Any, vrs: list[int], kind: str) -> slice | None:
    """``vrs`` as one slice of the value table if they are consecutive rows of type ``kind``,
    in order."""
    first, n = vrs[0], len(vrs)
    if first < 0 or vrs != list(range(first, first + n)) or not all(
            t == kind for t in self._types[first:first + n]) or first + n > self._n_vars:
        return None
    return slice(first, first + n)


def get_boolean(self: Any, vrs: list[int]) -> list[bool]:
    try:  # the hot path: the consecutive Boolean rows of the last such read, as fmi2GetReal
        if vrs == self._get_bool_vrs and self._mode != "instantiated":
            if self._stale:
                self._update_if_stale()
            return list(map(bool, self._real[self._get_bool_rows]))
    except BaseException:  # (answered and logged by _read)
        pass
    out = _read(self, vrs, "Boolean", bool, False)
    try:
        if vrs and self._mode != "instantiated":
            rows = _block_of(self, vrs, "Boolean")
            if rows is not None:
                self._get_bool_vrs, self._get_bool_rows = list(vrs), rows
    except BaseException:  # (a getter cannot fail)
        pass
    return out


def get_integer(self: Any, vrs: list[int]) -> list[int]:
    return _read(self, vrs, "Integer", int, 0)


def get_string(self: Any, vrs: list[int]) -> list[str]:
    return _read(self, vrs, "String", str, "")


def set_real(self: Any, vrs: list[int], values: list[float]) -> None:
    try:  # the hot path of every co-simulation step: inputs only, each settable now
        if vrs == self._set_vrs and self._mode == self._set_mode and len(values) == len(vrs):
            self._real[self._set_rows] = values  # the inputs of the last such set: one slice
            if self.DIRECT_FEEDTHROUGH or not self._initialized:
                self._stale = True
            return
        mode = self._mode
        if self._input_rows[mode].issuperset(vrs):
            r = self._real
            for i, x in zip(vrs, values):
                r[i] = x
            if self.DIRECT_FEEDTHROUGH or not self._initialized:
                self._stale = True
            if len(values) == len(vrs):  # consecutive inputs: the next set of them in this
                rows = _real_block(self, vrs)  # state is a slice
                if rows is not None:
                    self._set_vrs, self._set_mode, self._set_rows = list(vrs), mode, rows
            return
    except BaseException:  # (the general path below says what is wrong)
        pass
    set_rows(self, vrs, values, "Real")


def set_boolean(self: Any, vrs: list[int], values: list[bool]) -> None:
    set_rows(self, vrs, values, "Boolean")


def set_integer(self: Any, vrs: list[int], values: list[int]) -> None:
    set_rows(self, vrs, values, "Integer")


def set_string(self: Any, vrs: list[int], values: list[str]) -> None:
    set_rows(self, vrs, values, "String")


def set_rows(self: Any, vrs: list[int], values: list[Any], kind: str) -> None:
    """Set scalar rows ``vrs`` of type ``kind``; a row that may not be set is logged (status
    Error) and kept for the next doStep."""
    try:
        ok = self._settable.get((self._mode, kind), _NONE)
        r = self._real
        if kind != "Boolean" and ok.issuperset(vrs):  # the hot path: every row may be set
            for i, x in zip(vrs, values):
                r[i] = x
        else:
            boolean = kind == "Boolean"
            for i, x in zip(vrs, values):
                if i in ok:
                    r[i] = bool(x) if boolean else x
                else:
                    _reject(self, i, x, _why_not_settable(self, i, kind), kind)
        # outputs follow sets only before initialization ends or with direct feedthrough
        if self.DIRECT_FEEDTHROUGH or not self._initialized:
            self._stale = True
        if not self._dirty and not self._param_vrs.isdisjoint(vrs):
            self._dirty = True
    except BaseException as e:  # never let an exception reach the wrapper
        msg = f"{self.FMI}Set{self.TYPE_NAMES[kind]} failed: {e!r}"
        self._pending.append(msg)
        self._report(msg, Fmi2Status.error)


def _why_not_settable(self: Any, vr: int, kind: str) -> str:
    if not 0 <= vr < self._n_vars:
        return "no such variable"
    if self._types[vr] != kind:
        names = self.TYPE_NAMES
        got = names[self._types[vr]]
        return f"is {'an' if got[:1] in 'AEIOU' else 'a'} {got} variable, not {names[kind]}"
    return f"not settable in state {self._mode!r}"


def _bad_get(self: Any, vrs: list[int], kind: str) -> None:
    """Log reads of unknown or wrongly typed variables (a getter cannot fail)."""
    for i in vrs:
        if not (0 <= i < self._n_vars) or self._types[i] != kind:
            names = self.TYPE_NAMES
            what = (_vr_text(i) if not 0 <= i < self._n_vars
                    else f"{self.VARIABLES[i].name} (a {names[self._types[i]]} variable)")
            self._report(f"{self.FMI}Get{names[kind]} of {what}: not a {names[kind]} variable "
                         "of this FMU", Fmi2Status.error)
