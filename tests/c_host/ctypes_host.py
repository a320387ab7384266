"""A minimal FMI host in Python's standard library alone (ctypes): no fmpy, no numpy.

Loads the binary of one extracted FMU into this process (which keeps it loaded until exit),
instantiates it, runs a few steps with logging on, prints what happened, and exits with
``sys.exit(0)``: a crash at process exit shows as another exit code.

    python ctypes_host.py FMU_DIR MODEL_ID TOKEN FMI STEPS [--step H] [--set VR=VALUE]...
                          [--output VR]... [--modules] [+ FMU_DIR MODEL_ID ...]...

Several FMUs, separated by ``+``, run one after the other in the same process (and
interpreter); the lines of the k-th start with ``fmu k``.

FMI is 2 or 3; STEPS steps of H seconds (default 0.001) from t = 0; ``--set`` sets a Float64
(FMI 2.0: Real) in initialization mode; each ``--output`` (default 0) is read after the steps.
Output lines: ``log: <message>`` for each logged message, ``instance: NULL`` or ``instance:
ok``, ``status <call> <int>`` for each call after instantiation, ``output <repr>`` for each
output after the steps, and with ``--modules`` one line
``modules: <name> ...`` listing the top-level modules in ``sys.modules`` that are not in the
standard library (``sys.stdlib_module_names``), besides the FMU's own.
"""

import ctypes
import os
import sys


def _log(message):
    text = message.decode("utf-8", "replace") if message else ""
    for line in text.splitlines() or [""]:
        print(f"log: {line}", flush=True)


LOG2 = ctypes.CFUNCTYPE(None, ctypes.c_void_p, ctypes.c_char_p, ctypes.c_int, ctypes.c_char_p,
                        ctypes.c_char_p)
LOG3 = ctypes.CFUNCTYPE(None, ctypes.c_void_p, ctypes.c_int, ctypes.c_char_p, ctypes.c_char_p)
_logger2 = LOG2(lambda env, inst, status, cat, msg: _log(msg))
_logger3 = LOG3(lambda env, status, cat, msg: _log(msg))


class Callbacks2(ctypes.Structure):
    _fields_ = [("logger", LOG2), ("allocateMemory", ctypes.c_void_p),
                ("freeMemory", ctypes.c_void_p), ("stepFinished", ctypes.c_void_p),
                ("componentEnvironment", ctypes.c_void_p)]


def options(argv):
    """(step, {vr: value} to set, output vrs) from one FMU's options."""
    step, values, out = 0.001, {}, []
    for i, a in enumerate(argv):
        if a == "--step":
            step = float(argv[i + 1])
        elif a == "--set":
            vr, _, value = argv[i + 1].partition("=")
            values[int(vr)] = float(value)
        elif a == "--output":
            out.append(int(argv[i + 1]))
    return step, values, out or [0]


def run2(lib, folder, token, steps):
    libc = ctypes.CDLL(None)
    cb = Callbacks2(_logger2, ctypes.cast(libc.calloc, ctypes.c_void_p),
                    ctypes.cast(libc.free, ctypes.c_void_p), None, None)
    lib.fmi2Instantiate.restype = ctypes.c_void_p
    lib.fmi2Instantiate.argtypes = [ctypes.c_char_p, ctypes.c_int, ctypes.c_char_p,
                                    ctypes.c_char_p, ctypes.POINTER(Callbacks2), ctypes.c_int,
                                    ctypes.c_int]
    uri = "file://" + os.path.join(folder, "resources")
    c = lib.fmi2Instantiate(b"host", 1, token.encode(), uri.encode(), ctypes.byref(cb), 0, 1)
    if not c:
        print("instance: NULL", flush=True)
        return
    print("instance: ok", flush=True)
    c = ctypes.c_void_p(c)
    lib.fmi2SetupExperiment.argtypes = [ctypes.c_void_p, ctypes.c_int, ctypes.c_double,
                                        ctypes.c_double, ctypes.c_double, ctypes.c_int,
                                        ctypes.c_double]
    lib.fmi2DoStep.argtypes = [ctypes.c_void_p, ctypes.c_double, ctypes.c_double, ctypes.c_int]
    print("status setupExperiment", lib.fmi2SetupExperiment(c, 0, 0.0, 0.0, 0, 0, 0.0))
    print("status enterInitializationMode", lib.fmi2EnterInitializationMode(c))
    h, values, out = options(OPTIONS[0])
    for vr, x in values.items():
        print("status setReal", lib.fmi2SetReal(c, (ctypes.c_uint * 1)(vr), 1,
                                                (ctypes.c_double * 1)(x)))
    print("status exitInitializationMode", lib.fmi2ExitInitializationMode(c))
    for k in range(steps):
        print("status doStep", lib.fmi2DoStep(c, k * h, h, 1))
    for o in out:
        vr, value = (ctypes.c_uint * 1)(o), (ctypes.c_double * 1)()
        print("status getReal", lib.fmi2GetReal(c, vr, 1, value))
        print(f"output {value[0]!r}")
    print("status terminate", lib.fmi2Terminate(c))
    lib.fmi2FreeInstance(c)


def run3(lib, folder, token, steps):
    lib.fmi3InstantiateCoSimulation.restype = ctypes.c_void_p
    lib.fmi3InstantiateCoSimulation.argtypes = [
        ctypes.c_char_p, ctypes.c_char_p, ctypes.c_char_p, ctypes.c_bool, ctypes.c_bool,
        ctypes.c_bool, ctypes.c_bool, ctypes.c_void_p, ctypes.c_size_t, ctypes.c_void_p,
        LOG3, ctypes.c_void_p]
    resources = os.path.join(folder, "resources") + os.sep
    c = lib.fmi3InstantiateCoSimulation(b"host", token.encode(), resources.encode(), False,
                                        True, False, False, None, 0, None, _logger3, None)
    if not c:
        print("instance: NULL", flush=True)
        return
    print("instance: ok", flush=True)
    c = ctypes.c_void_p(c)
    lib.fmi3EnterInitializationMode.argtypes = [ctypes.c_void_p, ctypes.c_bool,
                                                ctypes.c_double, ctypes.c_double,
                                                ctypes.c_bool, ctypes.c_double]
    print("status enterInitializationMode",
          lib.fmi3EnterInitializationMode(c, False, 0.0, 0.0, False, 0.0))
    h, values, out = options(OPTIONS[0])
    lib.fmi3SetFloat64.argtypes = [ctypes.c_void_p, ctypes.c_void_p, ctypes.c_size_t,
                                   ctypes.c_void_p, ctypes.c_size_t]
    for vr, x in values.items():
        print("status setFloat64", lib.fmi3SetFloat64(c, (ctypes.c_uint * 1)(vr), 1,
                                                      (ctypes.c_double * 1)(x), 1))
    lib.fmi3ExitInitializationMode.argtypes = [ctypes.c_void_p]
    print("status exitInitializationMode", lib.fmi3ExitInitializationMode(c))
    lib.fmi3DoStep.argtypes = [ctypes.c_void_p, ctypes.c_double, ctypes.c_double, ctypes.c_bool,
                               ctypes.POINTER(ctypes.c_bool), ctypes.POINTER(ctypes.c_bool),
                               ctypes.POINTER(ctypes.c_bool), ctypes.POINTER(ctypes.c_double)]
    flags = [ctypes.c_bool() for _ in range(3)]
    last = ctypes.c_double()
    for k in range(steps):
        print("status doStep", lib.fmi3DoStep(c, k * h, h, True, *map(ctypes.byref, flags),
                                             ctypes.byref(last)))
    lib.fmi3GetFloat64.argtypes = [ctypes.c_void_p, ctypes.c_void_p, ctypes.c_size_t,
                                   ctypes.c_void_p, ctypes.c_size_t]
    for o in out:
        vr, value = (ctypes.c_uint * 1)(o), (ctypes.c_double * 1)()
        print("status getFloat64", lib.fmi3GetFloat64(c, vr, 1, value, 1))
        print(f"output {value[0]!r}")
    lib.fmi3Terminate.argtypes = [ctypes.c_void_p]
    print("status terminate", lib.fmi3Terminate(c))
    lib.fmi3FreeInstance.argtypes = [ctypes.c_void_p]
    lib.fmi3FreeInstance(c)


def foreign_modules():
    """Top-level modules loaded that are neither standard library nor the FMU's own."""
    std = set(getattr(sys, "stdlib_module_names", ())) | set(sys.builtin_module_names)
    tops = {name.partition(".")[0] for name in sys.modules}
    own = ("dronefly_", "dronefly3_", "pythonfmu")  # the FMU's package and entry, its wrapper
    return sorted(t for t in tops if t not in std and not t.startswith(own) and t != "__main__")


#: the options of the FMU being run (set by main)
OPTIONS = [[]]


def main():
    args = [a for a in sys.argv[1:] if a != "--modules"]
    groups, current = [], []
    for a in args:
        if a == "+":
            groups.append(current)
            current = []
        else:
            current.append(a)
    groups.append(current)
    for k, group in enumerate(groups):
        print(f"fmu {k}", flush=True)
        folder, model, token, fmi, steps = group[:5]
        OPTIONS[0] = group[5:]
        folder = os.path.abspath(folder)
        platform = "linux64" if fmi == "2" else "x86_64-linux"
        lib = ctypes.CDLL(os.path.join(folder, "binaries", platform, f"{model}.so"))
        (run2 if fmi == "2" else run3)(lib, folder, token, int(steps))
    if "--modules" in sys.argv:
        print("modules:", *foreign_modules())
    print(f"python {sys.version_info[0]}.{sys.version_info[1]}.{sys.version_info[2]}",
          flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
