"""harness/builder/toolchain.py: the C toolchain of the native FMUs and the C hosts.

One tiny C file is built for every FMI platform with ``zig cc`` (the ``ziglang`` package of the
test extra: a missing one fails these tests, it does not skip them), and each binary's header is
read twice: by the project's :func:`binary_platform` and by ``file(1)``, an independent reader
(.ci/setup-c-host.sh installs it). The Linux x86_64 library is loaded and called here; the
Windows DLL runs under Wine in tests/test_native_hosts.py.
"""

from __future__ import annotations

import ctypes
import os
import shutil
import subprocess
import sys

import pytest

from dronefly.harness.builder import toolchain as tcmod
from dronefly.harness.builder.toolchain import (FMI2_PLATFORMS, FMI3_PLATFORMS, PLATFORMS, ToolchainError,
                                        binary_platform, find_toolchain, fmi_include_dir,
                                        host_platform, missing_reason)
from dronefly.core.errors import DroneflyError

LINUX_X86 = sys.platform.startswith("linux") and host_platform("2.0") == "linux64"

#: exported through the FMI header's own macro, as the native FMUs do; ``hidden`` is not
SOURCE = r"""
#include <math.h>
#include "fmi2Functions.h"
static double hidden(double x) { return sqrt(x) + SCALE; }
FMI2_Export double dronefly_probe(double x) { return hidden(x); }
double not_exported(double x) { return x; }
"""

#: what file(1) prints for each format and architecture
FILE_SAYS = {("ELF", "x86_64"): "ELF 64-bit LSB shared object, x86-64",
             ("ELF", "aarch64"): "ELF 64-bit LSB shared object, ARM aarch64",
             ("PE", "x86_64"): "PE32+ executable (DLL)",
             ("Mach-O", "x86_64"): "Mach-O 64-bit x86_64 dynamically linked shared library",
             ("Mach-O", "aarch64"): "Mach-O 64-bit arm64 dynamically linked shared library"}


@pytest.fixture(autouse=True)
def fresh_cache(tmp_path, monkeypatch):
    """Each test compiles for real: its own, empty binary cache."""
    monkeypatch.setenv("DRONEFLY_CACHE_DIR", str(tmp_path / "cache"))
    return tmp_path / "cache"


@pytest.fixture(scope="module")
def zig():
    tc = find_toolchain("win64")
    assert tc is not None and tc.kind == "zig", (
        f"zig cc is part of the test extra: {missing_reason('win64')}")
    return tc


@pytest.fixture(scope="module")
def probe_c(tmp_path_factory):
    src = tmp_path_factory.mktemp("probe") / "probe.c"
    src.write_text(SOURCE)
    return src


def test_the_platform_names_are_the_standards():
    """FMI 2.0 section 2.1.2 and FMI 3.0 section 2.5.1.1 name the binaries' folders."""
    assert FMI2_PLATFORMS == ("linux64", "win64", "darwin64")
    assert set(FMI3_PLATFORMS) == {"x86_64-linux", "aarch64-linux", "x86_64-windows",
                                   "x86_64-darwin", "aarch64-darwin"}


@pytest.mark.parametrize("platform", list(PLATFORMS))
def test_zig_builds_a_shared_library_for_every_platform(zig, probe_c, tmp_path, platform):
    p = PLATFORMS[platform]
    out = zig.compile([probe_c], tmp_path / "lib" / f"probe{p.suffix}", platform,
                      include_dirs=[fmi_include_dir()], defines={"SCALE": "1.0"})
    # nothing but the library: no import library or .pdb beside the DLL
    assert sorted(x.name for x in out.parent.iterdir()) == [out.name]
    assert binary_platform(out) == (p.fmt, p.arch, True)
    file_cmd = shutil.which("file")
    assert file_cmd, "file(1) is the independent reader of the header (.ci/setup-c-host.sh)"
    said = subprocess.run([file_cmd, "-b", str(out)], capture_output=True, text=True).stdout
    assert said.startswith(FILE_SAYS[p.fmt, p.arch]), said
    if platform == "aarch64-darwin":  # macOS on arm64 loads no unsigned code
        assert _LC_CODE_SIGNATURE in _macho_load_commands(out.read_bytes())


_LC_CODE_SIGNATURE = 0x1D


def _macho_load_commands(data: bytes) -> list[int]:
    """The load command types of a 64-bit little-endian Mach-O file (mach-o/loader.h)."""
    import struct

    ncmds, = struct.unpack_from("<I", data, 16)
    off, cmds = 32, []
    for _ in range(ncmds):
        cmd, size = struct.unpack_from("<II", data, off)
        cmds.append(cmd)
        off += size
    return cmds


@pytest.mark.skipif(not LINUX_X86, reason="loads the linux64 library into this process: "
                                          "Linux x86_64 only")
@pytest.mark.parametrize("kind", ["zig", "host"])
def test_the_linux_library_exports_the_fmi_declared_symbol_only(probe_c, tmp_path, kind):
    tc = tcmod._zig() if kind == "zig" else tcmod._host_cc()
    assert tc is not None, f"no {kind} toolchain"
    out = tc.compile([probe_c], tmp_path / "probe.so", "linux64",
                     include_dirs=[fmi_include_dir()], defines={"SCALE": "1.0"})
    lib = ctypes.CDLL(str(out))
    lib.dronefly_probe.restype = ctypes.c_double
    lib.dronefly_probe.argtypes = [ctypes.c_double]
    assert lib.dronefly_probe(16.0) == 5.0  # sqrt(16) + SCALE: exact in binary
    with pytest.raises(AttributeError):
        lib.not_exported  # noqa: B018  (hidden by -fvisibility=hidden)


def test_warnings_are_errors(zig, tmp_path):
    src = tmp_path / "warn.c"
    src.write_text("int f(int x) { int unused; return x; }\n")
    with pytest.raises(ToolchainError, match=r"unused.*zig compiler for x86_64-windows failed"
                                             r"|zig compiler for x86_64-windows failed.*unused"):
        zig.compile([src], tmp_path / "warn.dll", "x86_64-windows")
    assert not (tmp_path / "warn.dll").exists()


def test_an_unknown_platform_is_refused_naming_it(zig, probe_c, tmp_path):
    with pytest.raises(ToolchainError, match="platform = 'win32'"):
        zig.compile([probe_c], tmp_path / "x.dll", "win32")
    with pytest.raises(DroneflyError, match="platform = 'linux32'"):
        find_toolchain("linux32")


@pytest.mark.skipif(not LINUX_X86, reason="the host compiler's own platform is linux64 here")
def test_the_host_compiler_builds_for_its_own_platform_only(probe_c, tmp_path, monkeypatch):
    monkeypatch.setattr(tcmod, "_zig", lambda: None)
    monkeypatch.setattr(tcmod, "_ziglang_installed", lambda: False)
    tc = find_toolchain("linux64")
    assert tc is not None and tc.kind == "host"
    assert find_toolchain("win64") is None
    assert missing_reason("win64") == (
        "no C toolchain for win64: the 'ziglang' package is missing (pip install "
        f"'dronefly-fmu[native]') and the host compiler {tc.command[0]} builds for linux64 only")
    with pytest.raises(ToolchainError, match="platform = 'win64'.*ziglang"):
        tc.compile([probe_c], tmp_path / "x.dll", "win64")


def test_no_toolchain_at_all_is_one_line_naming_both(monkeypatch):
    monkeypatch.setattr(tcmod, "_zig", lambda: None)
    monkeypatch.setattr(tcmod, "_host_cc", lambda: None)
    monkeypatch.setattr(tcmod, "_ziglang_installed", lambda: True)
    assert find_toolchain("linux64") is None
    why = missing_reason("linux64")
    assert why is not None and "\n" not in why
    assert why == ("no C toolchain for linux64: the 'ziglang' package is installed but "
                   "`python -m ziglang version` failed and no gcc, cc or clang on PATH")


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="sanitizer builds: Linux gcc")
def test_the_sanitizer_build_catches_undefined_behaviour(tmp_path):
    """A signed overflow that an unsanitized build runs silently ends the sanitized one."""
    tc = find_toolchain(sanitize=True)
    assert tc is not None, missing_reason(sanitize=True)
    assert find_toolchain("win64", sanitize=True) is None
    src = tmp_path / "ub.c"
    src.write_text("#include <limits.h>\n#include <stdlib.h>\n"
                   "int main(int argc, char **argv) { (void)argv;\n"
                   "  int x = INT_MAX - 1 + argc; return (x + 1) == 0 ? 0 : 3; }\n")
    host = host_platform()
    plain = tc.compile([src], tmp_path / "plain", host, shared=False, optimize="-O0")
    assert subprocess.run([str(plain)]).returncode in (0, 3)
    san = tc.compile([src], tmp_path / "san", host, shared=False, sanitize=True, optimize="-O0")
    r = subprocess.run([str(san)], capture_output=True, text=True)
    assert r.returncode != 0 and "signed integer overflow" in r.stderr, r.stderr
    with pytest.raises(ToolchainError, match="sanitize = True"):
        tcmod._zig().compile([src], tmp_path / "z", host, shared=False, sanitize=True)


def _cpu_has_fma() -> bool:
    try:
        with open("/proc/cpuinfo") as f:
            return " fma " in f.read().replace("\n", " ")
    except OSError:
        return False


@pytest.mark.skipif(not (LINUX_X86 and _cpu_has_fma()),
                    reason="runs Haswell code here: needs an x86_64 Linux CPU with FMA")
def test_a_times_b_plus_c_is_not_fused(zig, tmp_path):
    """clang fuses ``a * b + c`` into one rounding by default where the CPU has FMA; numpy and
    the pythonfmu FMUs round twice. With a = 1 + 2^-30, b = 1 - 2^-30, c = -1: a b = 1 - 2^-60
    rounds to 1, so two roundings give 0 exactly and one rounding gives -2^-60."""
    src = tmp_path / "fma.c"
    src.write_text('#include "fmi2Functions.h"\n'
                   "FMI2_Export double f(double a, double b, double c) { return a * b + c; }\n")
    out = zig.compile([src], tmp_path / "fma.so", "linux64", include_dirs=[fmi_include_dir()],
                      extra_flags=["-mcpu=haswell"])
    lib = ctypes.CDLL(str(out))
    lib.f.restype = ctypes.c_double
    lib.f.argtypes = [ctypes.c_double] * 3
    assert lib.f(1 + 2**-30, 1 - 2**-30, -1.0) == 0.0


def test_a_binary_is_compiled_once_per_inputs_and_anew_when_a_byte_changes(
        zig, probe_c, tmp_path, fresh_cache, monkeypatch):
    """The cache gives back the binary of the same inputs without the compiler, and any changed
    byte (a define, a source, a header of an include folder) compiles anew; ``0`` turns it off."""
    inc = tmp_path / "inc"
    shutil.copytree(fmi_include_dir(), inc)
    first = zig.compile([probe_c], tmp_path / "a.so", "linux64", include_dirs=[inc],
                        defines={"SCALE": "1.0"})
    assert len(list(fresh_cache.iterdir())) == 1
    calls = []

    def compiler(cmd, *args, **kwargs):
        calls.append(cmd)
        return real(cmd, *args, **kwargs)

    real = subprocess.run
    monkeypatch.setattr(tcmod.subprocess, "run", compiler)
    again = zig.compile([probe_c], tmp_path / "b.so", "linux64", include_dirs=[inc],
                        defines={"SCALE": "1.0"})
    assert calls == [] and again.read_bytes() == first.read_bytes()
    zig.compile([probe_c], tmp_path / "c.so", "linux64", include_dirs=[inc],
                defines={"SCALE": "2.0"})
    assert len(calls) == 1
    (inc / "fmi2Functions.h").write_text((inc / "fmi2Functions.h").read_text() + "\n")
    zig.compile([probe_c], tmp_path / "d.so", "linux64", include_dirs=[inc],
                defines={"SCALE": "1.0"})
    assert len(calls) == 2
    probe_c.write_text(probe_c.read_text() + "\n")
    try:
        zig.compile([probe_c], tmp_path / "e.so", "linux64", include_dirs=[inc],
                    defines={"SCALE": "1.0"})
    finally:
        probe_c.write_text(SOURCE)
    assert len(calls) == 3
    monkeypatch.setenv("DRONEFLY_CACHE_DIR", "0")
    zig.compile([probe_c], tmp_path / "f.so", "linux64", include_dirs=[inc],
                defines={"SCALE": "1.0"})
    assert len(calls) == 4 and len(list(fresh_cache.iterdir())) == 4
    # an executable from the cache is still one (the C hosts of the tests run so)
    monkeypatch.setenv("DRONEFLY_CACHE_DIR", str(fresh_cache))
    exe_src = tmp_path / "main.c"
    exe_src.write_text("int main(void) { return 7; }\n")
    for k in range(2):
        exe = zig.compile([exe_src], tmp_path / f"exe{k}", "linux64", shared=False)
        if LINUX_X86:
            assert subprocess.run([str(exe)]).returncode == 7
        assert os.access(exe, os.X_OK)


@pytest.mark.skipif(not LINUX_X86, reason="the nested-FMU shim is built for linux64 (x86_64) only")
def test_the_nested_fmu_shim_is_compiled_once_per_compiler_and_source(tmp_path, monkeypatch):
    """harness/builder/nestedshim.py: the first build compiles the shim into the cache, the
    next takes the same bytes from it without compiling; another source compiles anew."""
    from dronefly.harness.builder import nestedshim

    if nestedshim._compiler() is None:
        pytest.skip("no C compiler (cc, gcc or clang) on this machine")
    monkeypatch.setenv("DRONEFLY_CACHE_DIR", str(tmp_path / "cache"))
    compiled = []
    run = subprocess.run

    def counting(cmd, *a, **kw):
        if "-shared" in cmd:
            compiled.append(cmd)
        return run(cmd, *a, **kw)

    monkeypatch.setattr(nestedshim.subprocess, "run", counting)
    builds = []
    for source in (nestedshim.SHIM_SOURCE, nestedshim.SHIM_SOURCE,
                   nestedshim.SHIM_SOURCE + "\n/* another source */\n"):
        monkeypatch.setattr(nestedshim, "SHIM_SOURCE", source)
        nestedshim.shim_library.cache_clear()
        builds.append(nestedshim.shim_library())
    nestedshim.shim_library.cache_clear()
    assert len(compiled) == 2  # the first and the third
    assert builds[0] == builds[1] and builds[0][:4] == b"\x7fELF"
    assert len(list((tmp_path / "cache").iterdir())) == 2
