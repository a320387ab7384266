"""Benchmark: the native (C) FMUs against the pythonfmu FMUs, with the anchors in the same run.

Measures, interleaved repeat by repeat (the machine is shared and noisy):

  step     microseconds per closed-loop step of DroneFlyLateral + StateFeedback through FMPy
           and our master (``harness.cosim.master.Loop``, instances reused, CPU time of this
           thread): the native pair, the pythonfmu pair, and the do-nothing pythonfmu FMUs of
           ``null_fmus/`` through the same master (the floor of any pythonfmu pair)
  chost    steps per second of the native closed loop in the C host of tests/c_host (no Python
           in the process; the loop alone, wall time, printed by the host's ``-t``) against the
           physical limit: the 4 x 7 product of the plant and the 3 x 4 law and nothing else
           (``native_limit.c``), both built by zig cc (harness/builder/toolchain.py)
  simulate ``fmpy.simulate_fmu`` of the lateral plant alone over its default experiment
           (300 steps of 0.1 wing beat), native against pythonfmu, wall time (target: the
           native plant at least 3 times faster), against the floor of simulate_fmu itself
           (the native FMU with fmi2DoStep and fmi2GetReal made free: pythonfmu/floor bounds
           the ratio any FMU can reach), and what one fmi2GetReal and one fmi2DoStep cost
           through FMPy's FMU2Slave: FMPy's own cost per call is most of it
  memory   the growth of the process's resident memory over ``--cycles`` (default 10,000)
           fmi2Instantiate/fmi2FreeInstance cycles of the lateral plant through FMPy in a fresh
           process, after 100 cycles of warm-up: native (target < 1 MB) and pythonfmu
  sweep    ``dronefly sweep`` (1 worker) on the native pair against the pythonfmu pair, on a
           subset of the default cases with the same mix of steps and gains (the default
           8,538 cases take minutes per pair here); the time of all 8,538 is the subset's
           time scaled by the number of cases (``--sweep-grid``, ``--sweep-amplitudes``)

Prints medians and the ratios, with the date and the machine. Exits 1 when ``simulate`` misses
its target of 3 or ``memory`` its 1 MB.
Usage: python benchmarks/native_bench.py [--steps N] [--repeats R] [--cycles N]
       [--only step,chost,simulate,memory,sweep]
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import platform
import re
import statistics
import subprocess
import sys
import tempfile
import time
import zipfile
from datetime import datetime, timezone
from pathlib import Path

HERE = Path(__file__).resolve().parent
REPO = HERE.parent
H = 0.1 / 164.0
STATES = ["delta_v", "delta_p", "delta_r", "delta_gamma"]
CONTROLS = ["delta_Phi_a", "delta_alpha_1a", "delta_alpha_2a"]
#: the default sweep's number of cases (``dronefly sweep`` with no options)
DEFAULT_SWEEP_CASES = 8538
TARGET_SIMULATE = 3.0
TARGET_MEMORY_MB = 1.0


def _machine() -> str:
    cpu = ""
    with contextlib.suppress(OSError):
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    return f"{platform.system()} {platform.machine()}, {os.cpu_count()} cores, {cpu}"


def _build(out: Path) -> dict[str, Path]:
    """The pythonfmu pair, the do-nothing pair and the native pair (FMI 2.0)."""
    from pythonfmu import FmuBuilder

    from dronefly.harness.builder import native
    from dronefly.harness.builder.build import build_fmu

    fmus = {name: build_fmu(name, out) for name in ("DroneFlyLateral", "StateFeedback")}
    for name in ("NullPlant", "NullController"):
        fmus[name] = Path(FmuBuilder.build_FMU(HERE / "null_fmus" / f"{name}.py", dest=out))
    for name in ("DroneFlyLateral", "StateFeedback"):
        path, platforms = native.build_native(name, out / "native", 2, True, ("linux64",))
        if not platforms:
            sys.exit(f"native_bench: no C compiler: {name} is a source-code FMU")
        fmus[f"native:{name}"] = path
    return fmus


def _time_loop(loop, p, c, steps: int) -> float:
    t0 = time.thread_time()
    run = loop.run(H, steps, instances=(p, c))
    elapsed = (time.thread_time() - t0) / steps * 1e6
    assert run.complete, run.failure
    return elapsed


def bench_step(fmus: dict[str, Path], steps: int, repeats: int) -> dict[str, list[float]]:
    from dronefly.harness.cosim.fmu import FMU
    from dronefly.harness.cosim.master import Loop

    pairs = {"native": ("native:DroneFlyLateral", "native:StateFeedback"),
             "pythonfmu": ("DroneFlyLateral", "StateFeedback"),
             "floor": ("NullPlant", "NullController")}
    times: dict[str, list[float]] = {k: [] for k in pairs}
    with contextlib.ExitStack() as stack:
        runs = {}
        for key, (pn, cn) in pairs.items():
            P, C = stack.enter_context(FMU(fmus[pn])), stack.enter_context(FMU(fmus[cn]))
            p = stack.enter_context(P.instantiate(logging=False))
            c = stack.enter_context(C.instantiate(logging=False))
            runs[key] = (Loop(P, C), p, c)
            _time_loop(*runs[key], 10)  # warm up
        for r in range(repeats):
            for key in (list(runs) if r % 2 == 0 else list(runs)[::-1]):
                times[key].append(_time_loop(*runs[key], steps))
    return times


def _compile_c(out: Path) -> tuple[Path, Path]:
    from dronefly.harness.builder.toolchain import find_toolchain, fmi_include_dir, missing_reason

    tc = find_toolchain("linux64")
    if tc is None:
        sys.exit(f"native_bench: {missing_reason('linux64')}")
    host = tc.compile([REPO / "tests" / "c_host" / "fmi2_host.c"], out / "fmi2_host", "linux64",
                      shared=False, include_dirs=[fmi_include_dir()],
                      defines={"_POSIX_C_SOURCE": "200809L"}, libs=["dl"])
    limit = tc.compile([HERE / "native_limit.c"], out / "native_limit", "linux64", shared=False)
    return host, limit


def _host_args(fmus: dict[str, Path], out: Path, steps: int) -> list[str]:
    import fmpy

    args = [str(steps), repr(H)]
    mds = []
    for name in ("DroneFlyLateral", "StateFeedback"):
        path = fmus[f"native:{name}"]
        d = out / f"x_{name}"
        with zipfile.ZipFile(path) as z:
            z.extractall(d)
        md = fmpy.read_model_description(str(path))
        mds.append({v.name: v.valueReference for v in md.modelVariables})
        args += [str(d), md.coSimulation.modelIdentifier, md.guid]
    pv, cv = mds
    return args + [",".join(str(pv[s]) for s in STATES), ",".join(str(cv[s]) for s in STATES),
                   ",".join(str(cv[u]) for u in CONTROLS), ",".join(str(pv[u]) for u in CONTROLS),
                   f"{pv['delta_gamma_start']}=0.1"]


def bench_chost(fmus: dict[str, Path], out: Path, steps: int, repeats: int) -> dict[str, list[float]]:
    host, limit = _compile_c(out)
    env = {k: v for k, v in os.environ.items() if k not in ("LD_PRELOAD", "PYTHONHOME",
                                                             "PYTHONPATH")}
    args = _host_args(fmus, out, steps)
    rate: dict[str, list[float]] = {"chost": [], "limit": []}
    pattern = re.compile(r"loop_s=(\S+) steps=(\d+)")
    for r in range(repeats):
        for key in (("chost", "limit") if r % 2 == 0 else ("limit", "chost")):
            cmd = [str(host), "-q", "-t", *args] if key == "chost" else [str(limit), str(steps * 20)]
            res = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=600,
                                 check=True)
            m = pattern.search(res.stderr if key == "chost" else res.stdout)
            assert m, res.stderr
            rate[key].append(int(m.group(2)) / float(m.group(1)))
    return rate


def _extract(fmu: Path, name: str) -> str:
    """The FMU extracted into ``name`` beside it (in the benchmark's temporary folder, removed
    with it)."""
    import fmpy

    return fmpy.extract(str(fmu), str(Path(fmu).parent / name))


def bench_calls(fmus: dict[str, Path], calls: int, repeats: int) -> dict[str, list[float]]:
    """Microseconds of one fmi2GetReal (the 4 outputs) and one fmi2DoStep of the lateral plant
    through FMPy's FMU2Slave: what a step of ``simulate_fmu`` costs beside FMPy's own loop."""
    import fmpy
    from fmpy.fmi2 import FMU2Slave

    out: dict[str, list[float]] = {}
    slaves = {}
    for key, name in (("native", "native:DroneFlyLateral"), ("pythonfmu", "DroneFlyLateral")):
        md = fmpy.read_model_description(str(fmus[name]))
        s = FMU2Slave(guid=md.guid, unzipDirectory=_extract(fmus[name], f"calls_{key}"),
                      modelIdentifier=md.coSimulation.modelIdentifier, instanceName=key)
        s.instantiate()
        s.setupExperiment(startTime=0.0)
        s.enterInitializationMode()
        s.exitInitializationMode()
        slaves[key] = (s, [v.valueReference for v in md.modelVariables
                           if v.causality == "output"], [0.0])
    for r in range(repeats):
        for key in (list(slaves) if r % 2 == 0 else list(slaves)[::-1]):
            s, vrs, t = slaves[key]
            t0 = time.perf_counter()
            for _ in range(calls):
                s.getReal(vrs)
            t1 = time.perf_counter()
            for _ in range(calls):
                s.doStep(t[0], H)
                t[0] += H
            t2 = time.perf_counter()
            out.setdefault(f"{key}:get", []).append((t1 - t0) / calls * 1e6)
            out.setdefault(f"{key}:step", []).append((t2 - t1) / calls * 1e6)
    for s, _, _ in slaves.values():
        s.terminate()
        s.freeInstance()
    return out


@contextlib.contextmanager
def _free_calls():
    """FMPy's FMU2Slave with fmi2DoStep and fmi2GetReal costing nothing (the methods return
    at once, no call into the FMU): ``simulate_fmu`` of any FMU, native or not, costs at least
    what it costs then (FMPy's own loop, recorder and set-up, and the native FMU's
    instantiate, initialize, terminate and free, microseconds in C)."""
    from fmpy.fmi2 import FMU2Slave

    step, get = FMU2Slave.doStep, FMU2Slave.getReal
    FMU2Slave.doStep = lambda self, *a, **k: 0  # fmi2OK
    FMU2Slave.getReal = lambda self, vr: [0.0] * len(vr)
    try:
        yield
    finally:
        FMU2Slave.doStep, FMU2Slave.getReal = step, get


def bench_simulate(fmus: dict[str, Path], repeats: int) -> dict[str, list[float]]:
    """Wall seconds of ``fmpy.simulate_fmu`` of the lateral plant over its default experiment:
    native, pythonfmu, and ``floor``: the native FMU with fmi2DoStep and fmi2GetReal free
    (:func:`_free_calls`), the least any FMU can cost in ``simulate_fmu``."""
    import fmpy

    times: dict[str, list[float]] = {"native": [], "pythonfmu": [], "floor": []}
    paths = {"native": fmus["native:DroneFlyLateral"], "pythonfmu": fmus["DroneFlyLateral"]}
    dirs = {k: _extract(p, f"simulate_{k}") for k, p in paths.items()}
    mds = {k: fmpy.read_model_description(str(p)) for k, p in paths.items()}

    def run(key: str) -> float:
        t0 = time.perf_counter()
        res = fmpy.simulate_fmu(dirs[key], model_description=mds[key])
        dt = time.perf_counter() - t0
        assert len(res) == 301, len(res)
        return dt

    for key in paths:  # warm up: the first load of each binary and of pythonfmu's interpreter
        run(key)
    for r in range(repeats):
        for key in (["native", "pythonfmu", "floor"] if r % 2 == 0
                    else ["floor", "pythonfmu", "native"]):
            if key == "floor":
                with _free_calls():
                    times[key].append(run("native"))
            else:
                times[key].append(run(key))
    return times


_MEMORY_CHILD = r"""
import json, sys
from fmpy import read_model_description, extract
from fmpy.fmi2 import FMU2Slave
path, cycles = sys.argv[1], int(sys.argv[2])
def rss_kb():
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * 4096 // 1024
md = read_model_description(path)
folder = extract(path, path + ".extracted")  # beside the FMU, in the benchmark's folder
fmu = FMU2Slave(guid=md.guid, unzipDirectory=folder,
                modelIdentifier=md.coSimulation.modelIdentifier, instanceName="m")
# the library stays loaded; each cycle is fmi2Instantiate ... fmi2FreeInstance
def cycle():
    fmu.instantiate()
    fmu.setupExperiment(startTime=0.0)
    fmu.enterInitializationMode()
    fmu.exitInitializationMode()
    fmu.terminate()
    fmu.fmi2FreeInstance(fmu.component)  # the FMI call alone: fmpy's freeInstance also unloads
for _ in range(100):
    cycle()
before = rss_kb()
for _ in range(cycles):
    cycle()
print(json.dumps({"before_kb": before, "after_kb": rss_kb()}))
"""


def bench_memory(fmus: dict[str, Path], cycles: int) -> dict[str, dict[str, float]]:
    out = {}
    for key, name in (("native", "native:DroneFlyLateral"), ("pythonfmu", "DroneFlyLateral")):
        t0 = time.perf_counter()
        r = subprocess.run([sys.executable, "-c", _MEMORY_CHILD, str(fmus[name]), str(cycles)],
                           capture_output=True, text=True, timeout=3600, check=True)
        m = json.loads(r.stdout.strip().splitlines()[-1])
        grow_kb = m["after_kb"] - m["before_kb"]
        out[key] = {"growth_mb": grow_kb / 1024, "per_cycle_kb": grow_kb / cycles,
                    "seconds": time.perf_counter() - t0}
    return out


def bench_sweep(fmus: dict[str, Path], out: Path, grid: int, amplitudes: int,
                repeats: int) -> dict[str, object]:
    exe = Path(sys.executable).with_name("dronefly")
    common = ["sweep", "--workers", "1", "--no-plot", "--no-progress", "--json",
              "--grid", str(grid), "--amplitudes", str(amplitudes)]
    pairs = {"native": ["--plant", str(fmus["native:DroneFlyLateral"]),
                        "--controller", str(fmus["native:StateFeedback"])],
             "pythonfmu": ["--plant", str(fmus["DroneFlyLateral"]),
                           "--controller", str(fmus["StateFeedback"])]}
    times: dict[str, list[float]] = {k: [] for k in pairs}
    cases = {}
    for r in range(repeats):
        for key in (list(pairs) if r % 2 == 0 else list(pairs)[::-1]):
            folder = out / f"sweep_{key}_{r}"
            t0 = time.perf_counter()
            res = subprocess.run([str(exe), *common, "--out", str(folder), *pairs[key]],
                                 capture_output=True, text=True, timeout=3600)
            times[key].append(time.perf_counter() - t0)
            if res.returncode not in (0, 1):
                sys.exit(f"native_bench: sweep on {key} exited {res.returncode}: "
                         f"{res.stderr.strip()[-500:]}")
            with open(folder / "sweep.csv") as f:
                cases[key] = sum(1 for _ in f) - 1
    return {"times": times, "cases": cases}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--steps", type=int, default=2000)
    ap.add_argument("--repeats", type=int, default=7)
    ap.add_argument("--cycles", type=int, default=10000)
    ap.add_argument("--sweep-grid", type=int, default=5)
    ap.add_argument("--sweep-amplitudes", type=int, default=3)
    ap.add_argument("--sweep-repeats", type=int, default=1)
    ap.add_argument("--only", default="step,chost,simulate,memory,sweep")
    args = ap.parse_args(argv)
    only = set(args.only.split(","))
    unknown = only - {"step", "chost", "simulate", "memory", "sweep"}
    if unknown:
        ap.error(f"--only: unknown part(s) {', '.join(sorted(unknown))}")
    start = datetime.now(timezone.utc)
    print(f"native_bench {start:%Y-%m-%d %H:%M} UTC; {_machine()}; Python "
          f"{sys.version.split()[0]}")
    ok = True
    med = statistics.median
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp)
        fmus = _build(out)
        if "step" in only:
            t = bench_step(fmus, args.steps, args.repeats)
            print(f"closed-loop step through FMPy and Loop, CPU us/step, median of {args.repeats}"
                  f" x {args.steps} steps:")
            for k in ("native", "pythonfmu", "floor"):
                print(f"  {k:10s} {med(t[k]):8.2f}  (min {min(t[k]):.2f}, max {max(t[k]):.2f})")
            print(f"  native/floor {med(t['native']) / med(t['floor']):.3f}, pythonfmu/floor "
                  f"{med(t['pythonfmu']) / med(t['floor']):.3f}, pythonfmu/native "
                  f"{med(t['pythonfmu']) / med(t['native']):.2f}")
        if "chost" in only:
            n = 50 * args.steps
            rate = bench_chost(fmus, out, n, args.repeats)
            print(f"native closed loop in the C host, steps/s (median of {args.repeats} runs of "
                  f"{n} steps; the limit {20 * n} steps):")
            print(f"  C host   {med(rate['chost']):14,.0f}  ({1e9 / med(rate['chost']):.1f} ns/step)")
            print(f"  limit    {med(rate['limit']):14,.0f}  ({1e9 / med(rate['limit']):.1f} ns/step)")
            print(f"  C host/limit {med(rate['chost']) / med(rate['limit']):.3f}")
        if "simulate" in only:
            t = bench_simulate(fmus, args.repeats)
            ratio = med(t["pythonfmu"]) / med(t["native"])
            print(f"fmpy.simulate_fmu of DroneFlyLateral (300 steps), wall ms, median of "
                  f"{args.repeats}: native {1e3 * med(t['native']):.2f}, pythonfmu "
                  f"{1e3 * med(t['pythonfmu']):.2f}; pythonfmu/native {ratio:.2f} "
                  f"(target >= {TARGET_SIMULATE:g})")
            bound = med(t["pythonfmu"]) / med(t["floor"])
            print(f"  floor (fmi2DoStep and fmi2GetReal free: FMPy's own cost) "
                  f"{1e3 * med(t['floor']):.2f}; pythonfmu/floor {bound:.2f}: the largest ratio "
                  "any FMU can reach through simulate_fmu")
            ok &= ratio >= TARGET_SIMULATE
            c = bench_calls(fmus, 3000, args.repeats)
            print("  through FMPy's FMU2Slave, us per call (median of "
                  f"{args.repeats} x 3000): fmi2GetReal native {med(c['native:get']):.2f}, "
                  f"pythonfmu {med(c['pythonfmu:get']):.2f}; fmi2DoStep native "
                  f"{med(c['native:step']):.2f}, pythonfmu {med(c['pythonfmu:step']):.2f}")
        if "memory" in only:
            m = bench_memory(fmus, args.cycles)
            print(f"resident memory over {args.cycles} instantiate/free cycles of DroneFlyLateral:")
            for k in ("native", "pythonfmu"):
                print(f"  {k:10s} +{m[k]['growth_mb']:.3f} MB ({m[k]['per_cycle_kb']:.3f} kB per "
                      f"cycle; {m[k]['seconds']:.0f} s)")
            ok &= m["native"]["growth_mb"] < TARGET_MEMORY_MB
        if "sweep" in only:
            s = bench_sweep(fmus, out, args.sweep_grid, args.sweep_amplitudes, args.sweep_repeats)
            t, cases = s["times"], s["cases"]
            assert cases["native"] == cases["pythonfmu"], cases
            scale = DEFAULT_SWEEP_CASES / cases["native"]
            print(f"dronefly sweep, 1 worker, --grid {args.sweep_grid} --amplitudes "
                  f"{args.sweep_amplitudes}: {cases['native']} cases, wall s (median of "
                  f"{args.sweep_repeats}), and scaled to the default {DEFAULT_SWEEP_CASES} cases:")
            for k in ("native", "pythonfmu"):
                print(f"  {k:10s} {med(t[k]):8.1f} s  -> {med(t[k]) * scale:8.0f} s "
                      f"({cases[k] / med(t[k]):.1f} cases/s)")
            print(f"  pythonfmu/native {med(t['pythonfmu']) / med(t['native']):.2f}")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
