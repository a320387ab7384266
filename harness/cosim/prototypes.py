"""FMPy's FMU classes, with the prototypes of their FMI functions worked out once per class.

FMPy (0.3.2x) works out the C prototype of every FMI function (about 70 of them) from its
Python method's signature with :mod:`inspect` each time an ``FMU2Slave``, ``FMU2Model``,
``FMU3Slave`` or ``FMU3Model`` is made: about 5 ms, fifty times the FMU's own
``fmi2Instantiate``, paid by every instance the checks, the fuzz and the co-simulations make.
The prototypes depend on the class only. The classes here are FMPy's, less that repetition:
the first object of a class loads its functions as FMPy does, and records each one's argument
names, argument types and result type; every later object gives the functions of its own
library the recorded prototypes. Where FMPy loads its functions another way (a version
without ``_loadFunctions``), they are FMPy's classes unchanged.
"""

from __future__ import annotations

from typing import Any

from fmpy.fmi2 import FMU2Model as _FMPyModel2
from fmpy.fmi2 import FMU2Slave as _FMPySlave2
from fmpy.fmi3 import FMU3Model as _FMPyModel3
from fmpy.fmi3 import FMU3Slave as _FMPySlave3

__all__ = ["FMU2Model", "FMU2Slave", "FMU3Model", "FMU3Slave"]

#: per class, the functions FMPy loaded: (name, argument names, argument types, result type)
_PROTOTYPES: dict[type, list[tuple[str, Any, Any, Any]]] = {}


class _Prototyped:
    """The mixin: ``_loadFunctions`` from the recorded prototypes after the first object."""

    dll: Any
    _functions: dict[str, Any]

    def _loadFunctions(self) -> None:
        recorded = _PROTOTYPES.get(type(self))
        if recorded is None:
            super()._loadFunctions()  # type: ignore[misc]
            _PROTOTYPES[type(self)] = [(name, f.argnames, f.argtypes, f.restype)
                                       for name, f in self._functions.items()]
            return
        for name, argnames, argtypes, restype in recorded:
            f = getattr(self.dll, name)  # AttributeError where it is missing, as in FMPy
            f.argnames, f.argtypes, f.restype = argnames, argtypes, restype
            self._functions[name] = f


class FMU2Slave(_Prototyped, _FMPySlave2):
    """FMPy's ``FMU2Slave`` (module docstring)."""


class FMU2Model(_Prototyped, _FMPyModel2):
    """FMPy's ``FMU2Model`` (module docstring)."""


class FMU3Slave(_Prototyped, _FMPySlave3):
    """FMPy's ``FMU3Slave`` (module docstring)."""


class FMU3Model(_Prototyped, _FMPyModel3):
    """FMPy's ``FMU3Model`` (module docstring)."""
