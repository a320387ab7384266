"""``dronefly build``'s FMI 3.0 half: every FMU of the project as an FMI 3.0 Co-Simulation FMU
(pythonfmu3) in ``build/fmi3/``, with the closed-loop and hover systems referencing them
(docs/fmi3.md).

:func:`dronefly.builder.build.build_fmu` with ``fmi=3`` builds one; :mod:`dronefly.builder.package3` holds what
an FMI 3.0 package adds.
"""

from __future__ import annotations

from pathlib import Path

from ..harness.cosim.ssp import HOVER, HOVER_6DOF, hover_system, write_system_ssp
from .build import FMUS, BuildError, build_fmu
from .closedloop import CLOSED_LOOP, CONTROLLER, PLANT, write_ssp

__all__ = ["FMI3_OUT", "build_all3"]

#: where ``dronefly build`` writes the FMI 3.0 FMUs, below its output folder
FMI3_OUT = "fmi3"


def build_all3(out_dir: str | Path = Path("build") / FMI3_OUT) -> list[Path]:
    """Every FMU of the project as an FMI 3.0 Co-Simulation FMU (pythonfmu3) in ``out_dir``,
    with the systems referencing them: ``DroneFlyClosedLoop.ssp`` (the lateral plant and its
    controller) and the hover systems ``DroneFlyHover.ssp`` and ``DroneFlyHover6DOF.ssp``.
    No container FMU (why: docs/fmi-limits.md)."""

    fmus = {name: build_fmu(name, out_dir, fmi=3) for name in FMUS}
    try:
        systems = [write_ssp(fmus[PLANT], fmus[CONTROLLER], out_dir)]
    except (OSError, ValueError) as e:
        raise BuildError(f"cannot build the FMI 3.0 {CLOSED_LOOP}.ssp: {e}") from e
    for name, nonlinear in ((HOVER, False), (HOVER_6DOF, True)):
        try:
            systems.append(write_system_ssp(
                hover_system(fmus, nonlinear=nonlinear), Path(out_dir) / f"{name}.ssp",
                description="The hovering model drone fly (Zhang & Sun), FMI 3.0 FMUs"))
        except (OSError, ValueError) as e:
            raise BuildError(f"cannot build the FMI 3.0 {name}.ssp: {e}") from e
    return [*fmus.values(), *systems]
