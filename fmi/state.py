"""FMU states of :class:`dronefly.fmi.SlaveBase`: handles, serialisation, refusal.

pythonfmu 0.7.0 hands the host the Python object that ``_get_fmu_state``
returns and passes it back to ``_set_fmu_state``; serialisation calls two
static methods on the slave class. Any exception there becomes fmi2Fatal and
leaves the instance unusable, so nothing in this module raises:

- A state is a :class:`StateHandle` naming the FMU and build it belongs to
  (``fmu_id``: model name and content-addressed package). A state of another
  FMU or another build is refused by ``fmi2SetFMUstate``, which logs why and
  leaves the instance unchanged.
- Serialised bytes carry a header (magic, format version, FMU id, payload
  length, SHA-256 of the payload) checked before the payload is parsed.
  Empty, truncated, corrupt or foreign bytes deserialise to a *rejected*
  handle holding the reason, which ``fmi2SetFMUstate`` then refuses (the one
  legal way left: pythonfmu offers no non-Fatal failure of
  ``fmi2DeSerializeFMUstate`` itself).
- A handle the host frees with ``fmi2FreeFMUstate`` is kept alive, emptied,
  as a tombstone (the last :data:`TOMBSTONES` = 256 of them, about 25 kB), so that a host that
  passes a freed state again gets a refusal instead of a use-after-free.

Shipped inside every FMU with the rest of :mod:`dronefly.fmi`; imports only the standard library.
"""

from __future__ import annotations

import hashlib
import json
import math
from collections import deque
from typing import Any

from pythonfmu.enums import Fmi2Status

__all__ = ["FORMAT", "MAGIC", "TOMBSTONES", "StateHandle", "foreign", "get_fmu_state", "set_fmu_state",
           "snapshot", "state_from_bytes", "state_to_bytes"]

MAGIC = b"DRONEFLY-FMU-STATE"
FORMAT = 1
#: freed handles kept alive so that their reuse is detected (about 100 bytes each)
TOMBSTONES = 256
_MAX_HEADER = 4096

_freed: deque["StateHandle"] = deque(maxlen=TOMBSTONES)


class StateHandle:
    """One FMU state: ``payload`` (a dict) or ``rejected`` (why it cannot be used)."""

    __slots__ = ("fmu_id", "payload", "rejected", "freed", "__weakref__")

    def __init__(self, fmu_id: str, payload: dict[str, Any] | None,
                 rejected: str | None = None) -> None:
        self.fmu_id = fmu_id
        self.payload = payload
        self.rejected = rejected
        self.freed = False

    def problem(self, fmu_id: str, free_call: str = "fmi2FreeFMUstate") -> str | None:
        """Why this state cannot be restored into FMU ``fmu_id`` (None: it can); ``free_call``
        names the FMI function that frees a state."""
        if self.freed:
            return f"the state was freed ({free_call}) before it was used"
        if self.rejected is not None:
            return self.rejected
        if self.fmu_id != fmu_id:
            return f"the state belongs to FMU {self.fmu_id!r}, not to {fmu_id!r}"
        if not isinstance(self.payload, dict):
            return "the state holds no data"
        return None

    def __del__(self) -> None:
        # The host freed its last reference. Keep the object alive, empty, so that a stale
        # pointer still points at a StateHandle that says it was freed.
        try:
            self.freed = True
            self.payload = None
            _freed.append(self)
        except Exception:  # pragma: no cover - interpreter shutdown
            pass


def foreign(obj: Any) -> str:
    """Why an object that is no StateHandle of this FMU's code cannot be restored."""
    name = type(obj).__name__
    if name == "StateHandle":
        return "the state was made by another FMU (its code is not this FMU's)"
    return f"not an FMU state of this FMU (a {name})"


def state_to_bytes(state: Any, fmu_id: str) -> bytes:
    """Header and JSON payload; ``b""`` for a state that cannot be serialised."""
    try:
        if not isinstance(state, StateHandle) or state.problem(fmu_id) is not None:
            return b""
        # repr-exact floats; NaN/Inf inputs survive as JSON extensions
        payload = json.dumps(state.payload, separators=(",", ":")).encode("utf-8")
        header = json.dumps({"format": FORMAT, "fmu": fmu_id, "length": len(payload),
                             "sha256": hashlib.sha256(payload).hexdigest()}).encode("utf-8")
        return MAGIC + b"\n" + header + b"\n" + payload
    except BaseException:
        return b""


def state_from_bytes(data: Any, fmu_id: str) -> StateHandle:
    """A handle for serialised bytes; a rejected handle (with the reason) if they are not
    a complete, intact state of this FMU."""
    try:
        return StateHandle(fmu_id, _parse(bytes(data), fmu_id))
    except _Rejected as e:
        return StateHandle(fmu_id, None, rejected=f"serialized state refused: {e}")
    except BaseException as e:  # never let anything reach the wrapper
        return StateHandle(fmu_id, None, rejected=f"serialized state refused: {e!r}")


class _Rejected(Exception):
    pass


def _parse(data: bytes, fmu_id: str) -> dict[str, Any]:
    if not data:
        raise _Rejected("0 bytes")
    if not data.startswith(MAGIC + b"\n"):
        raise _Rejected(f"{len(data)} bytes without the {MAGIC.decode()} header")
    rest = data[len(MAGIC) + 1:]
    end = rest.find(b"\n", 0, _MAX_HEADER)
    if end < 0:
        raise _Rejected("the header is truncated")
    try:
        header = json.loads(rest[:end].decode("utf-8"))
    except (UnicodeDecodeError, ValueError):
        raise _Rejected("the header is not readable") from None
    if not isinstance(header, dict):
        raise _Rejected("the header is not readable")
    if header.get("format") != FORMAT:
        raise _Rejected(f"format {header.get('format')!r}, this FMU reads format {FORMAT}")
    if header.get("fmu") != fmu_id:
        raise _Rejected(f"it was saved by FMU {header.get('fmu')!r}, not by {fmu_id!r}")
    payload = rest[end + 1:]
    if header.get("length") != len(payload):
        raise _Rejected(f"{len(payload)} payload bytes, the header says {header.get('length')!r}")
    if hashlib.sha256(payload).hexdigest() != header.get("sha256"):
        raise _Rejected("the checksum does not match (corrupt bytes)")
    try:
        state = json.loads(payload.decode("utf-8"))
    except (UnicodeDecodeError, ValueError):
        raise _Rejected("the payload is not readable") from None
    if not isinstance(state, dict):
        raise _Rejected("the payload is not a state")
    return state


# -- the slave's side: functions of a SlaveBase (self), bound as its methods --------------
def snapshot(self: Any) -> dict[str, Any]:
    return {
        "real": list(self._real),
        "mode": self._mode,
        "time": self._time,
        "stop_time": self._stop_time,
        "pending": list(self._pending),
        "initialized": self._initialized,
        "extra": self._extra_state(),
    }


def get_fmu_state(self: Any) -> Any:
    try:
        return StateHandle(self._fmu_id, snapshot(self))
    except BaseException as e:
        self._report(f"{self.FMI}Get{self.STATE_API} failed: {e!r}", Fmi2Status.error)
        return StateHandle(self._fmu_id, None, rejected=f"not saved: {e!r}")


def set_fmu_state(self: Any, state: Any) -> None:
    try:
        why = (state.problem(self._fmu_id, f"{self.FMI}Free{self.STATE_API}")
               if isinstance(state, StateHandle) else foreign(state))
        if why is None:
            why = _check_payload(self, state.payload)
        if why is not None:
            self._report(f"{self.FMI}Set{self.STATE_API} refused, the instance is unchanged: "
                         f"{why}", Fmi2Status.error)
            return
        before = snapshot(self)
        try:
            _restore(self, state.payload)
        except BaseException as e:
            _restore(self, before)
            self._report(f"{self.FMI}Set{self.STATE_API} refused, the instance is unchanged: "
                         f"{e}", Fmi2Status.error)
    except BaseException as e:  # never let an exception reach the wrapper
        self._report(f"{self.FMI}Set{self.STATE_API} failed: {e!r}", Fmi2Status.error)


def _check_payload(self: Any, p: Any) -> str | None:
    """Why a state payload does not fit this FMU (None if it does)."""
    real = p.get("real")
    if not isinstance(real, list) or len(real) != self._n_vars:
        return f"it holds {len(real) if isinstance(real, list) else 'no'} values, this FMU " \
               f"has {self._n_vars} variables"
    if p.get("mode") not in self.MODES or not isinstance(p.get("pending"), list):
        return f"unknown mode {p.get('mode')!r}"
    t = p.get("time")
    if not (isinstance(t, (int, float)) and math.isfinite(t)):
        return f"time = {t!r} is not a finite number"
    return None


def _restore(self: Any, p: dict[str, Any]) -> None:
    self._real = [bool(x) if kind == "Boolean" else int(x) if kind == "Integer" else float(x)
                  for x, kind in zip(p["real"], self._types)]
    self._mode = p["mode"]
    self._time = float(p["time"])
    self._stop_time = None if p["stop_time"] is None else float(p["stop_time"])
    self._pending = [str(m) for m in p["pending"]]
    self._restore_extra_state(p["extra"])
    self._initialized = bool(p["initialized"])
    self._dirty = True  # the next doStep rebuilds from the restored values
    self._stale = True
