"""Shared fixtures: the project's FMUs, built once per test session into a temporary folder.

The header names the BLAS kernels numpy and scipy run; with ``OPENBLAS_CORETYPE`` set, the
session stops unless every OpenBLAS took that kernel (a second-kernel run that silently ran
the first would prove nothing).
"""

from __future__ import annotations

import atexit
import contextlib
import os
import shutil
import signal
import sys
import tempfile
from pathlib import Path
from typing import Any, Callable, Iterator

import pytest

# The suite starts hundreds of Python processes (the CLI of the documents' blocks, the checking
# and fuzz children, sweep workers) that import the package: they share one bytecode cache,
# outside the checkout, also where the machine sets PYTHONDONTWRITEBYTECODE (the pytest-xdist
# workers inherit it from the first process that loads this file). The cache is kept between
# sessions (``dronefly-fmu/pycache`` in ``$XDG_CACHE_HOME``, default ``~/.cache``): compiling
# numpy, scipy, fmpy and the package anew costs each worker about 10 s of CPU. Python checks a
# cached file against its source's modification time (whole seconds) and size; a tool that
# rewrites sources faster than that (mutation/run.py) sets ``DRONEFLY_TEST_PYCACHE=session``:
# a fresh cache for the session, removed at its end.
# Two workers on two cores, and each process's OpenBLAS would start a thread per core that
# spins between calls: one BLAS thread per process (the workers and every process they start
# inherit it; the suite's matrices are small). 5 % less CPU for the suite, measured.
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

if "PYTHONPYCACHEPREFIX" not in os.environ:
    if os.environ.get("DRONEFLY_TEST_PYCACHE") == "session":
        _PYCACHE = tempfile.mkdtemp(prefix="dronefly_pycache_")
        atexit.register(shutil.rmtree, _PYCACHE, True)
    else:
        _PYCACHE = str(Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache")
                       / "dronefly-fmu" / "pycache")
    os.environ["PYTHONPYCACHEPREFIX"] = _PYCACHE
    os.environ.pop("PYTHONDONTWRITEBYTECODE", None)
    sys.pycache_prefix, sys.dont_write_bytecode = _PYCACHE, False  # this process's imports too


def _blas_kernels() -> list[str]:
    import numpy  # noqa: F401  (loads the BLAS libraries threadpoolctl reports)
    import scipy.linalg  # noqa: F401
    try:
        from threadpoolctl import threadpool_info
    except ImportError:  # not in the test extra's environment: nothing to report
        return []

    return [f"{i['internal_api']} {i['version']} {i.get('architecture')} ({Path(i['filepath']).name})"
            for i in threadpool_info() if i["user_api"] == "blas"]


def pytest_report_header(config: pytest.Config) -> str:
    return "BLAS: " + "; ".join(_blas_kernels())


#: the kernel OpenBLAS reports for a forced core type whose kernels are another's (scipy-openblas
#: 0.3.30/0.3.31: Prescott runs the Katmai kernels, Zen the Haswell ones)
_KERNEL_OF = {"prescott": "katmai", "core2": "katmai", "zen": "haswell", "cooperlake": "skylakex"}


#: the files of the longest tests (tens of seconds each on 2 cores; ``pytest --durations``),
#: run first, each file's tests together and in their order (a module's fixtures are made
#: once): the pytest-xdist workers then end together instead of one finishing a long test
#: alone. A file missing from this list only runs later.
LONGEST_FIRST = ("test_core_install.py", "test_native.py", "test_validity.py",
                 "test_reliability.py", "test_interrupt.py", "test_figures.py",
                 "test_flapping_docs.py", "test_flapping_master.py", "test_cosim_verdicts.py",
                 "test_doc_claims.py", "test_validity_halves.py", "test_flapping.py")


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    rank = {name: k for k, name in enumerate(LONGEST_FIRST)}
    items.sort(key=lambda item: rank.get(item.path.name, len(LONGEST_FIRST)))  # stable


def pytest_configure(config: pytest.Config) -> None:
    want = os.environ.get("OPENBLAS_CORETYPE", "").strip().lower()
    if not want:
        return
    kernel = _KERNEL_OF.get(want, want)
    got = _blas_kernels()
    if not got or any(f" {kernel} (" not in k.lower() for k in got if k.startswith("openblas")):
        raise pytest.UsageError(f"OPENBLAS_CORETYPE={os.environ['OPENBLAS_CORETYPE']} did not take "
                                f"effect: {'; '.join(got)}")


@pytest.fixture
def sigint_as_in_a_terminal():
    """SIGINT handled as in a process started from a terminal (KeyboardInterrupt), for the tests
    of Ctrl-C: a test run started in the background of a non-interactive shell inherits SIGINT
    ignored, and an ignored SIGINT rightly stays ignored by the code under test."""
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    yield
    signal.signal(signal.SIGINT, previous)


@pytest.fixture(scope="session")
def built_fmus(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """Every artefact of ``dronefly build``, freshly built: FMUs by model name
    (``"DroneFlyLateral"``), other files by file name (``"DroneFlyClosedLoop.ssp"``)."""
    from dronefly.harness.builder.build import build_all

    out = tmp_path_factory.mktemp("fmus")
    return {(p.stem if p.suffix == ".fmu" else p.name): p for p in build_all(out)}


@pytest.fixture(scope="session")
def built_fmus3(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """The FMI 3.0 artefacts of ``dronefly build`` (``build/fmi3/``), freshly built: FMUs by
    model name, the hover system SSPs by file name."""
    from dronefly.harness.builder.build import build_all

    out = tmp_path_factory.mktemp("fmus3")
    return {(p.stem if p.suffix == ".fmu" else p.name): p for p in build_all(out, fmi=3)}


@pytest.fixture(scope="session")
def opened_fmus(built_fmus) -> Iterator[Callable[[str], Any]]:
    """The built FMUs by model name, each read and extracted once, on first use."""
    from dronefly.harness.cosim.fmu import FMU

    with contextlib.ExitStack() as stack:
        cache: dict[str, Any] = {}

        def get(name: str) -> Any:
            if name not in cache:
                cache[name] = stack.enter_context(FMU(built_fmus[name]))
            return cache[name]

        yield get


def _opened(model: str) -> Any:
    """A session fixture: the built FMU ``model``, read and extracted once."""

    @pytest.fixture(scope="session")
    def fixture(opened_fmus):
        return opened_fmus(model)

    fixture.__doc__ = f"The built {model}, read and extracted once."
    return fixture


plant = _opened("DroneFlyLateral")
controller = _opened("StateFeedback")
longitudinal_plant = _opened("DroneFlyLongitudinal")
longitudinal_controller = _opened("StateFeedbackLongitudinal")


@pytest.fixture(scope="session")
def core_env(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The ``bin`` folder of a virtual environment with only the core install of dronefly-fmu
    (no extra: tests/core_install.py); its optional packages are checked to be absent."""
    import subprocess

    from core_install import OPTIONAL_MODULES, make_core_env

    bin_dir = make_core_env(tmp_path_factory.mktemp("core_env") / "venv")
    code = ("import importlib.util, sys\n"
            f"found = [m for m in {OPTIONAL_MODULES!r} if importlib.util.find_spec(m)]\n"
            "import dronefly.cli, numpy, scipy, fmpy, pythonfmu\n"
            "sys.exit(f'optional packages found: {found}' if found else 0)\n")
    r = subprocess.run([str(bin_dir / "python"), "-c", code], capture_output=True, text=True,
                       timeout=120)
    assert r.returncode == 0, r.stderr[-2000:]
    return bin_dir
