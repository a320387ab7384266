"""FMI 2.0 co-simulation slave base shared by the project's FMUs (shipped inside each FMU).

- :mod:`.base`: :class:`SlaveBase`, the lifecycle, doStep and the FMI 2.0 call-sequence table;
- :mod:`.vars`: the variable table (:class:`Var`) and the unit definitions (``UNITS``);
- :mod:`.values`: fmi2Get/fmi2Set of every type;
- :mod:`.state`: FMU states, their serialisation and refusal;
- :mod:`.host`: what the host process needs (``sys.path``, exit, FMPy's container).
"""

from .base import SlaveBase
from .vars import UNITS, Var

__all__ = ["UNITS", "SlaveBase", "Var"]
