"""The entry module of an FMU: what the wrapper imports first, what it does when the FMU's
Python side cannot start, and what the FMU says its host needs (:data:`HOST_REQUIREMENT` in the
model description, :func:`host_documentation` in ``documentation/``).

pythonfmu's and pythonfmu3's wrappers import the module named in ``resources/slavemodule.txt``
and take a slave class from it. If that import raised, pythonfmu 0.7.0 would log the error only
with debug logging on, and pythonfmu3 0.3.4 would print a traceback and then dereference a null
pointer (the host crashes). So the entry never raises: when the FMU's package cannot be imported
(an import error, a syntax error of an unsupported Python version, anything), it defines a
stand-in slave class whose constructor

- writes one line to the host's standard error naming the model, the Python version and the
  cause, and what the FMU needs (every logging setting: the importer may have logging off);
- registers the release of the wrapper's interpreter guard at exit (the FMU's ``fmi/host.py``,
  loaded by path: the package itself may be what fails), as a started FMU does, so that the
  host still exits cleanly;
- raises ``ImportError`` with the same line: the wrapper's instantiate function logs it (FMI 2.0:
  with logging on; FMI 3.0: always) and returns NULL.

The stand-in uses only the standard library and runs on any CPython 3.
"""

from __future__ import annotations

import html
from string import Template

__all__ = ["HOST_REQUIREMENT", "NEWEST_TESTED_PYTHON", "OLDEST_PYTHON", "entry2", "entry3",
           "host_documentation"]

#: the oldest CPython the FMUs start in (pythonfmu 0.7.0's facade imports typing.Literal);
#: tests/test_host_requirements.py runs every CPython 3 of the machine and checks both bounds
OLDEST_PYTHON = (3, 8)
#: the newest CPython the tests ran the FMUs in
NEWEST_TESTED_PYTHON = (3, 13)
_RANGE = "%d.%d to %d.%d" % (*OLDEST_PYTHON, *NEWEST_TESTED_PYTHON)

#: appended to every FMU's modelDescription description
HOST_REQUIREMENT = (f"Host requirements: a CPython 3 interpreter ({_RANGE} tested) with its "
                    "standard library only, no packages; see documentation/index.html")

_HOST_ITEMS = (
    f"A CPython 3 interpreter, {_RANGE} (tested on Linux x86_64), with its standard library "
    "only. The FMU ships all the Python code it runs in resources/ (the model, the slave base, "
    "pythonfmu's Python facade) and imports no package: no numpy, scipy or fmpy.",
    "How the FMU finds its interpreter: its binary (pythonfmu's or pythonfmu3's) does not link "
    "a Python library; it uses the interpreter loaded in the host process. In a Python host "
    "(FMPy, a script using ctypes) that is the host's own interpreter. A host that is not "
    "written in Python (Dymola, Simulink, OMSimulator, a C program) must load one: on Linux "
    "preload the shared libpython (LD_PRELOAD=/path/to/libpython3.X.so.1.0, and PYTHONHOME "
    "when the interpreter is not installed in its configured prefix); the binary starts it on "
    "the first instantiation. On Windows python3.dll of a CPython 3 installation must be on "
    "the DLL search path (PATH); not tested here.",
    "When the Python side cannot start (an interpreter older than "
    "%d.%d, an import that fails), instantiation writes one line to the host's standard error "
    "naming the model, the Python version and the cause, logs the same through the FMI logger "
    "(FMI 2.0: with logging on), and returns NULL; the host can still exit cleanly."
    % OLDEST_PYTHON,
)


def host_documentation(model: str, readme: bytes) -> dict[str, bytes]:
    """``documentation/index.html`` (the FMI entry point) and ``documentation/README.md`` of an
    FMU: what the host needs, then the model's README (``readme``, Markdown)."""
    md = "\n".join(["", "## What the host needs", "", *(f"- {item}" for item in _HOST_ITEMS), ""])
    page = "\n".join([
        "<!DOCTYPE html>", '<html lang="en">', '<head><meta charset="utf-8">',
        f"<title>{html.escape(model)}</title></head>", "<body>",
        f"<h1>{html.escape(model)}</h1>", "<h2>What the host needs</h2>", "<ul>",
        *(f"<li>{html.escape(item)}</li>" for item in _HOST_ITEMS), "</ul>",
        '<p>The model, its variables and its reference result: <a href="README.md">README.md'
        "</a>.</p>", "</body>", "</html>", ""])
    return {"documentation/index.html": page.encode(),
            "documentation/README.md": readme.rstrip(b"\n") + b"\n" + md.encode()}

#: defines _cannot_start(resources, error, fmi); $pkg and $model are substituted
_CANNOT_START = Template('''\
def _cannot_start(resources, error, fmi):
    """Report why this FMU's Python side cannot start (one line), then raise ImportError."""
    import sys
    cause = " ".join(("%s: %s" % (type(error).__name__, error)).split())
    why = ("$model: the FMU's Python side cannot start in Python %s: %s. It needs CPython 3 "
           "with its standard library only, no packages (documentation/README.md in the FMU)"
           % (sys.version.split()[0], cause))
    try:
        sys.stderr.write(why + "\\n")
        sys.stderr.flush()
    except BaseException:
        pass
    try:  # release the wrapper's interpreter guard at exit, as a started FMU does
        import importlib.util
        import os
        spec = importlib.util.spec_from_file_location(
            "${pkg}_host_at_start", os.path.join(resources, "$pkg", "fmi", "host.py"))
        host = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(host)
        host.finalize_at_exit(resources, "$model", "linux64" if fmi == 2
                              else host.binary_folder3(resources, "$model"))
    except BaseException:
        pass
    raise ImportError(why)


''')

_ENTRY2 = Template('''\
# Entry module named in resources/slavemodule.txt; the pythonfmu wrapper imports it and then
# evaluates this file once more in the module's namespace on every fmi2Instantiate.
# pythonfmu 0.7.0's findClass releases one reference to this module's globals per load that it
# never took (Py_DECREF of the borrowed PyModule_GetDict result). Each evaluation takes that
# reference first, as a bare reference count that nothing ever releases: no container holds
# it, so the dictionary is freed exactly once when the interpreter ends. (Holding it in a
# list inside the dictionary itself made the count too low at teardown: the list released
# references that findClass had already released, a double free at process exit.)
import ctypes as _ctypes
_ctypes.pythonapi.Py_IncRef(_ctypes.py_object(globals()))
del _ctypes


${cannot_start}try:
    from $pkg.$module import $cls  # noqa: E402,F401
except BaseException as _error:  # refuse every instantiation, saying why
    _START_ERROR = _error

    class Fmi2Slave:
        """Stand-in for the slave base: the wrapper takes the class derived from Fmi2Slave."""

        def __init__(self, **kwargs):
            _cannot_start(kwargs.get("resources"), _START_ERROR, 2)

    class $cls(Fmi2Slave):
        """$cls, whose Python side could not start."""
''')

_ENTRY3 = Template('''\
# Entry module named in resources/slavemodule.txt. pythonfmu3's wrapper imports it and takes
# the class defined on a line "class <Name>(...Fmi3Slave...):" in this file.
${cannot_start}try:
    from $pkg.fmi.base3 import fmi3_class
    from $pkg.$module import $cls as _Model

    Fmi3Slave = fmi3_class(_Model)
except BaseException as _error:  # refuse every instantiation, saying why
    _START_ERROR = _error

    class Fmi3Slave:  # noqa: F811
        """Stand-in for the slave base: the Python side could not start."""

        def __init__(self, **kwargs):
            _cannot_start(kwargs.get("resources"), _START_ERROR, 3)


class $cls(Fmi3Slave):
    """The FMI 3.0 Co-Simulation slave of $cls."""
''')


def _entry(template: Template, pkg: str, module: str, cls: str, model: str) -> str:
    cannot_start = _CANNOT_START.substitute(pkg=pkg, model=model)
    return template.substitute(pkg=pkg, module=module, cls=cls, cannot_start=cannot_start)


def entry2(pkg: str, module: str, cls: str, model: str) -> str:
    """The FMI 2.0 (pythonfmu) entry module's source.

    Parameters
    ----------
    pkg : str
        The FMU's content-addressed package (``dronefly_<name>_<hash>``).
    module, cls : str
        The slave class: ``cls`` of ``pkg.module``.
    model : str
        The model identifier (``binaries/<platform>/<model>.so``).
    """
    return _entry(_ENTRY2, pkg, module, cls, model)


def entry3(pkg: str, module: str, cls: str, model: str) -> str:
    """The FMI 3.0 (pythonfmu3) entry module's source (parameters as :func:`entry2`)."""
    return _entry(_ENTRY3, pkg, module, cls, model)
