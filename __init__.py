"""Not a module: the root of a dronefly-fmu checkout.

Python imports this file only when it runs from the folder that holds a checkout named
``dronefly``: the checkout then shadows the installed package ``dronefly`` (its ``build/``
folder of FMUs would pass for ``dronefly.build``, its ``harness/`` for ``dronefly.harness``).
Raising here says so in one line, instead of an error about a name deep inside an import.
"""

import os as _os

_here = _os.path.dirname(_os.path.abspath(__file__))
if __name__ == "dronefly":
    raise ImportError(
        f"{_here} is a dronefly-fmu checkout, not the package: Python, started in "
        f"{_os.path.dirname(_here)}, imports it as 'dronefly' in place of the installed "
        "package; run from another folder (the checkout itself, for one) or rename the checkout")
