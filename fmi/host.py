"""What the host process needs from an FMU of :class:`dronefly.fmi.SlaveBase`.

pythonfmu 0.7.0 runs every FMU of a process in one interpreter and leaves three things for
the FMU to repair: the resources folder it puts on ``sys.path`` at every instantiation,
the double release of its interpreter guard at process exit, and (nested in FMPy's
container) a logger that points into freed memory. Shipped inside every FMU.
"""

from __future__ import annotations

import atexit
import ctypes
import os
import os.path
import platform
import posixpath
import sys
import threading

__all__ = ["PYTHONFMU_BESIDE_SHIM", "binary_folder3", "finalize_at_exit", "guarded_libraries",
           "inside_fmpy_container", "leave_sys_path", "loaded_libraries", "platform_tuple",
           "release_interpreter_guard"]


def leave_sys_path(resources: str | None) -> None:
    """Remove the resources folder that the wrapper put at the front of ``sys.path``.

    The FMU's package is imported by the time the slave is created; without this,
    ``sys.path`` grows by one entry per instantiation.
    """
    while resources is not None and resources in sys.path:
        sys.path.remove(resources)


_FINALIZE: set[str] = set()
_FINALIZE_ASKED: set[tuple[str, str, str]] = set()


def finalize_at_exit(resources: str | None, model: str, folder: str = "linux64") -> None:
    """Release pythonfmu's interpreter guard of this FMU's binary before the process exits.

    pythonfmu 0.7.0 keeps a static ``std::shared_ptr<PyState>`` and also resets it from an
    ELF destructor (``finalizePythonInterpreter``). A library still loaded at exit has the
    static destroyed first, then the destructor assigns to the destroyed pointer: a double
    free, seen as "corrupted double-linked list" (valgrind: invalid read in
    finalizePythonInterpreter). Calling the exported ``finalizePythonInterpreter`` from a
    Python exit handler, while everything is alive, leaves both later steps nothing to free.
    Only in a Python host on Linux (the exit handler runs on the process's main thread):
    where pythonfmu started the interpreter itself (a C host), Python exits inside that
    very destructor, and calling it again there would be the bug itself.

    Parameters
    ----------
    resources : str or None
        The FMU's resources folder, as the wrapper passes it.
    model : str
        The model identifier: the library is ``binaries/<folder>/<model>.so``.
    folder : str
        The platform folder under ``binaries``: ``linux64`` (FMI 2.0), or the FMI 3.0
        platform tuple of the loaded library (:func:`binary_folder3`).
    """

    if not resources or not sys.platform.startswith("linux"):
        return
    key = (resources, model, folder)
    if key in _FINALIZE_ASKED:  # (every instantiation asks again: answered once)
        return
    _FINALIZE_ASKED.add(key)
    lib = os.path.join(os.path.dirname(os.path.abspath(resources)), "binaries", folder,
                       f"{model}.so")
    if lib in _FINALIZE:
        return
    _FINALIZE.add(lib)

    atexit.register(_at_exit, lib)


def guarded_libraries() -> tuple[str, ...]:
    """The FMU libraries (``binaries/<folder>/<model>.so``) whose guard is released at exit."""
    return tuple(sorted(_FINALIZE))


#: FMI 3.0 platform tuple architectures (the standard's "Platform Tuple Definitions") of
#: ``platform.machine()``
_ARCH3 = {"x86_64": "x86_64", "amd64": "x86_64", "x64": "x86_64", "aarch64": "aarch64",
          "arm64": "aarch64", "armv8l": "aarch32", "armv7l": "aarch32", "armv7": "aarch32",
          "arm": "aarch32", "i386": "x86", "i486": "x86", "i586": "x86", "i686": "x86",
          "x86": "x86", "riscv64": "riscv64", "riscv32": "riscv32", "ppc64": "ppc64",
          "ppc64le": "ppc64", "ppc": "ppc32", "powerpc": "ppc32"}


def platform_tuple(machine: str, system: str) -> str:
    """The FMI 3.0 platform tuple ``<arch>-<sys>`` (the folder under ``binaries``) of a machine.

    Parameters
    ----------
    machine, system : str
        As ``platform.machine()`` and ``platform.system()`` name them (``"x86_64"``,
        ``"aarch64"``, ``"AMD64"``, ``"arm64"``; ``"Linux"``, ``"Windows"``, ``"Darwin"``).
        An unknown machine is kept as it is named, in lower case.
    """
    arch = machine.lower()
    return f"{_ARCH3.get(arch, arch)}-{system.lower()}"


_FOLDER3: dict[tuple[str, str], str] = {}


def binary_folder3(resources: str | None, model: str) -> str:
    """The folder under ``binaries`` of this FMI 3.0 FMU's loaded library ``<model>.so``.

    The library the host loaded from the FMU beside ``resources`` (the loader's names
    normalised as in :func:`release_interpreter_guard`); if none is found, the platform tuple
    of this machine (:func:`platform_tuple`), where an FMI 3.0 host looks for it. Looked up
    once per FMU and model.
    """

    key = (str(resources), model)
    if key not in _FOLDER3:
        folder = platform_tuple(platform.machine(), platform.system())
        if resources:
            root = _same_file_key(os.path.join(os.path.dirname(os.path.abspath(resources)),
                                               "binaries"))
            for path in loaded_libraries():
                where, name = posixpath.split(path)
                if name == f"{model}.so" and posixpath.dirname(where) == root:
                    folder = posixpath.basename(where)
                    break
        _FOLDER3[key] = folder
    return _FOLDER3[key]


#: Nested in a container built by dronefly, ``<model>.so`` is a forwarding shim and pythonfmu's
#: library sits beside it under this name (see ``harness/builder/nestedshim.py``). The shim
#: may be unloaded (the container frees its components) while pythonfmu's library stays
#: loaded, so the guard is released through pythonfmu's library itself whenever it is there.
PYTHONFMU_BESIDE_SHIM = ".pythonfmu.so"


def _at_exit(lib: str) -> None:
    native_id = getattr(threading, "get_native_id", None)  # Python 3.8+
    if native_id is None or native_id() != os.getpid():  # not the main thread: a C host's shutdown
        return
    release_interpreter_guard(lib)


def release_interpreter_guard(lib: str) -> str | None:
    """Call ``finalizePythonInterpreter`` of the pythonfmu library behind ``lib`` if loaded.

    Parameters
    ----------
    lib : str
        Path of the FMU's ``binaries/<folder>/<model>.so`` (pythonfmu's library, or dronefly's
        shim with pythonfmu's library beside it as ``<model>.pythonfmu.so``), in any spelling
        of the path (the resources folder may come as ``//tmp/...``).

    Returns
    -------
    str or None
        The loader's name of the library whose guard was released, or ``None`` if neither is
        loaded. Releasing twice is harmless (the guard is then empty).
    """

    loaded = loaded_libraries()
    for path in (lib[:-len(".so")] + PYTHONFMU_BESIDE_SHIM, lib):
        for name in loaded.get(_same_file_key(path), ()):
            try:
                handle = ctypes.CDLL(name, mode=os.RTLD_NOLOAD | os.RTLD_NOW)  # only if loaded
                handle.finalizePythonInterpreter()
                return name
            except (OSError, AttributeError):
                continue
    return None


def _same_file_key(path: str) -> str:
    """``path`` normalised as the loader's names are compared here: one leading slash, no
    ``.``/``..``, no doubled separators. The file itself may be gone (hosts that unpack FMUs
    into a temporary folder delete it while the library is still mapped), so no ``stat``."""

    return posixpath.normpath("/" + path.lstrip("/")) if path.startswith("/") \
        else posixpath.normpath(path)


def loaded_libraries() -> dict[str, list[str]]:
    """The shared objects loaded in this process, as ``dl_iterate_phdr`` lists them.

    Returns
    -------
    dict
        Normalised path -> the loader's own names for it (what ``dlopen`` with
        ``RTLD_NOLOAD`` matches without touching the file system).
    """

    class _Info(ctypes.Structure):  # the leading fields of struct dl_phdr_info
        _fields_ = [("addr", ctypes.c_void_p), ("name", ctypes.c_char_p)]

    found: dict[str, list[str]] = {}

    def visit(info, _size, _data) -> int:
        name = info.contents.name
        if name:
            text = os.fsdecode(name)
            found.setdefault(_same_file_key(text), []).append(text)
        return 0

    callback = ctypes.CFUNCTYPE(ctypes.c_int, ctypes.POINTER(_Info), ctypes.c_size_t,
                                ctypes.c_void_p)(visit)
    try:
        ctypes.CDLL(None).dl_iterate_phdr(callback, None)
    except (OSError, AttributeError):  # not glibc/ELF: nothing found, nothing released
        return {}
    return found


def inside_fmpy_container(resources: str | None) -> bool:
    """Whether this FMU runs nested in an FMPy container FMU (``resources/container.json``).

    FMPy 0.3.32's container (its fmi-rs importer) gives a nested FMU's fmi2Instantiate a
    pointer to a callbacks struct on its stack; pythonfmu 0.7.0 keeps that pointer and calls
    its logger through it later, i.e. through freed stack memory: the host crashes on the
    first message. Nested there, the FMU therefore logs nothing; the container still reports
    each refused call with its status in its own log ("[plant] fmi2DoStep(...) ->
    fmi2Discard"). See docs/interop.md.
    """
    if not resources:
        return False
    nested = _NESTED.get(resources)
    if nested is None:  # once per resources folder and process (a container does not move)
        outer = os.path.dirname(os.path.dirname(os.path.abspath(resources)))
        nested = _NESTED[resources] = (os.path.basename(outer) == "resources" and os.path.isfile(
            os.path.join(outer, "container.json")))
    return nested


_NESTED: dict[str, bool] = {}
