"""Co-simulation slave base shared by the project's FMUs (shipped inside each FMU).

One implementation, two FMI wrappers: :class:`SlaveBase` is the FMI 2.0 slave (pythonfmu
0.7.0); :func:`.base3.fmi3_class` makes any subclass an FMI 3.0 slave (pythonfmu3).

- :mod:`.base`: :class:`SlaveBase`, storage, hooks and the FMI 2.0 binding;
- :mod:`.calls`: the lifecycle, doStep and the call-sequence table (both versions);
- :mod:`.base3`, :mod:`.table3`: the FMI 3.0 side (arrays, ``time``, statuses);
- :mod:`.vars`: the variable table (:class:`Var`) and the unit definitions (``UNITS``);
- :mod:`.access`: fmi2Get/fmi2Set of every type;
- :mod:`.state`: FMU states, their serialisation and refusal;
- :mod:`.host`: what the host process needs (``sys.path``, exit, FMPy's container).
"""

from .base import SlaveBase
from .vars import UNITS, Var

__all__ = ["UNITS", "SlaveBase", "Var"]
