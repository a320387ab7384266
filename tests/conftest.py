"""Shared fixtures: the project's FMUs, built once per test session into a temporary folder."""

from __future__ import annotations

from pathlib import Path

import pytest


@pytest.fixture(scope="session")
def built_fmus(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """Every artefact of ``dronefly build``, freshly built: FMUs by model name
    (``"DroneFlyLateral"``), other files by file name (``"DroneFlyClosedLoop.ssp"``)."""
    from dronefly.build import build_all

    out = tmp_path_factory.mktemp("fmus")
    return {(p.stem if p.suffix == ".fmu" else p.name): p for p in build_all(out)}


@pytest.fixture(scope="session")
def built_fmus3(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """The FMI 3.0 artefacts of ``dronefly build`` (``build/fmi3/``), freshly built: FMUs by
    model name, the hover system SSPs by file name."""
    from dronefly.build3 import build_all3

    out = tmp_path_factory.mktemp("fmus3")
    return {(p.stem if p.suffix == ".fmu" else p.name): p for p in build_all3(out)}


@pytest.fixture(scope="session")
def plant(built_fmus):
    """The built DroneFlyLateral, read and extracted once."""
    from dronefly.harness.cosim.fmu import FMU

    with FMU(built_fmus["DroneFlyLateral"]) as fmu:
        yield fmu


@pytest.fixture(scope="session")
def controller(built_fmus):
    """The built StateFeedback, read and extracted once."""
    from dronefly.harness.cosim.fmu import FMU

    with FMU(built_fmus["StateFeedback"]) as fmu:
        yield fmu
