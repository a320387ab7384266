"""The C toolchain that builds the native FMUs' binaries and the C hosts of the tests.

One compiler for every platform: ``zig cc`` from the PyPI package ``ziglang`` (the ``native``
extra; ``python -m ziglang cc``), a clang with the C libraries of Linux (glibc, pinned to 2.17
so that the binary loads on old distributions), Windows (mingw-w64) and macOS inside one wheel.
It cross-compiles from any machine to every platform the FMI standards name. Without it, the
host's own C compiler (``$CC``, ``gcc``, ``cc`` or ``clang``) builds for the host platform only;
it is also the one that builds with ``-fsanitize=address,undefined`` (zig ships no sanitizer
runtime for shared libraries). docs/interop.md says why zig and not mingw-w64, osxcross or
FMPy's CMake build.

A binary is compiled with warnings as errors (``-Wall -Wextra -Werror``), C99, ``-O2``, no
contraction of ``a * b + c`` into a fused multiply-add (``-ffp-contract=off``: clang contracts by
default, gcc does not, and numpy does not: the same floats from every compiler), and symbols
hidden by default (``-fvisibility=hidden``): a shared library exports exactly what its
headers declare exported. The FMI headers do that for every FMI function (``FMI2_Export`` and
``FMI3_Export``: default visibility, or ``__declspec(dllexport)`` on Windows), so a C file that
includes ``fmi2Functions.h`` or ``fmi3Functions.h`` and defines the functions exports them and
nothing else. :func:`fmi_include_dir` is where fmpy keeps those headers.

Compiled binaries are kept in a cache addressed by everything that decides their bytes: the
compiler and its version, the platform, every flag, the contents of the sources and of every
header in the include folders (:func:`cache_dir`; ``DRONEFLY_CACHE_DIR`` moves it, ``0`` turns it
off). A build whose inputs have not changed copies the binary instead of compiling it again, as
ccache does; any change of a byte of its inputs compiles it anew.
"""

from __future__ import annotations

import functools
import hashlib
import importlib.util
import os
import platform as _pyplatform
import shutil
import struct
import subprocess
import sys
import tempfile
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

from ...core.errors import DroneflyError

__all__ = ["FMI2_PLATFORMS", "FMI3_PLATFORMS", "PLATFORMS", "Platform", "Toolchain",
           "ToolchainError", "binary_platform", "cache_dir", "cached_binary", "find_toolchain",
           "fmi_include_dir", "host_platform", "keep_binary", "missing_reason"]


class ToolchainError(DroneflyError):
    """A C build could not be made: unknown platform, a toolchain that cannot build for it,
    or the compiler's own error (its first lines in the message)."""


@dataclass(frozen=True)
class Platform:
    """A platform as the FMI standard names it, and how to build for it.

    Attributes
    ----------
    name : str
        The folder below ``binaries/`` (FMI 2.0: ``linux64``; FMI 3.0: ``x86_64-linux``).
    fmi_version : str
        ``"2.0"`` or ``"3.0"``.
    zig_target : str
        ``zig cc -target`` for it.
    fmt : str
        The binary format: ``"ELF"``, ``"PE"`` or ``"Mach-O"``.
    arch : str
        ``"x86_64"`` or ``"aarch64"``.
    suffix : str
        The shared library's file suffix (``.so``, ``.dll``, ``.dylib``).
    """

    name: str
    fmi_version: str
    zig_target: str
    fmt: str
    arch: str
    suffix: str

    @property
    def os(self) -> str:
        """``"linux"``, ``"windows"`` or ``"darwin"``."""
        return {"ELF": "linux", "PE": "windows", "Mach-O": "darwin"}[self.fmt]

    @property
    def exe_suffix(self) -> str:
        """An executable's file suffix: ``.exe`` on Windows, none elsewhere."""
        return ".exe" if self.fmt == "PE" else ""


#: glibc 2.17 (2012): the oldest that zig links against, so the .so loads on any current Linux
_LINUX = {"x86_64": "x86_64-linux-gnu.2.17", "aarch64": "aarch64-linux-gnu.2.17"}


def _platforms() -> dict[str, Platform]:
    rows = [("linux64", "2.0", _LINUX["x86_64"], "ELF", "x86_64", ".so"),
            ("win64", "2.0", "x86_64-windows-gnu", "PE", "x86_64", ".dll"),
            ("darwin64", "2.0", "x86_64-macos", "Mach-O", "x86_64", ".dylib"),
            ("x86_64-linux", "3.0", _LINUX["x86_64"], "ELF", "x86_64", ".so"),
            ("aarch64-linux", "3.0", _LINUX["aarch64"], "ELF", "aarch64", ".so"),
            ("x86_64-windows", "3.0", "x86_64-windows-gnu", "PE", "x86_64", ".dll"),
            ("x86_64-darwin", "3.0", "x86_64-macos", "Mach-O", "x86_64", ".dylib"),
            ("aarch64-darwin", "3.0", "aarch64-macos", "Mach-O", "aarch64", ".dylib")]
    return {r[0]: Platform(*r) for r in rows}


#: every platform a native FMU can be built for, by its FMI name
PLATFORMS: dict[str, Platform] = _platforms()
#: the FMI 2.0 platform names (the standard has no aarch64 name)
FMI2_PLATFORMS: tuple[str, ...] = tuple(n for n, p in PLATFORMS.items() if p.fmi_version == "2.0")
#: the FMI 3.0 platform tuples
FMI3_PLATFORMS: tuple[str, ...] = tuple(n for n, p in PLATFORMS.items() if p.fmi_version == "3.0")

#: the host's machine name as Python reports it -> the FMI architecture
_ARCH = {"x86_64": "x86_64", "amd64": "x86_64", "aarch64": "aarch64", "arm64": "aarch64"}
_OS = {"linux": "linux", "win32": "windows", "darwin": "darwin"}
_FMI2_NAME = {("x86_64", "linux"): "linux64", ("x86_64", "windows"): "win64",
              ("x86_64", "darwin"): "darwin64"}


def host_platform(fmi_version: str = "3.0") -> str | None:
    """The FMI platform name of this machine, or None where the standard names none.

    Parameters
    ----------
    fmi_version : str
        ``"2.0"`` (``linux64``, ``win64``, ``darwin64``) or ``"3.0"`` (``x86_64-linux``, ...).

    Returns
    -------
    str or None
        None for an FMI 2.0 name on aarch64 (FMI 2.0 has none) or an unknown OS or machine.
    """
    if fmi_version not in ("2.0", "3.0"):
        raise ToolchainError(f"fmi_version = {fmi_version!r}: must be '2.0' or '3.0'")
    arch = _ARCH.get(_pyplatform.machine().lower())
    osname = next((v for k, v in _OS.items() if sys.platform.startswith(k)), None)
    if arch is None or osname is None:
        return None
    if fmi_version == "2.0":
        return _FMI2_NAME.get((arch, osname))
    return f"{arch}-{osname}"


def _platform(name: str) -> Platform:
    try:
        return PLATFORMS[name]
    except KeyError:
        raise ToolchainError(f"platform = {name!r}: not one of {', '.join(PLATFORMS)}") from None


def fmi_include_dir() -> Path:
    """The folder of the FMI 2.0 and 3.0 headers (``fmi2Functions.h``, ``fmi3Functions.h``,
    ...) that the fmpy package ships: the headers the native FMUs and the C hosts compile with.

    Returns
    -------
    pathlib.Path
    """
    spec = importlib.util.find_spec("fmpy")
    if spec is None or spec.origin is None:
        raise ToolchainError("fmpy is not installed: its c-code/ folder holds the FMI headers")
    inc = Path(spec.origin).parent / "c-code"
    if not (inc / "fmi2Functions.h").is_file() or not (inc / "fmi3Functions.h").is_file():
        raise ToolchainError(f"fmpy's FMI headers are missing from {inc}")
    return inc


@dataclass(frozen=True)
class Toolchain:
    """A C compiler and the platforms it builds for.

    Attributes
    ----------
    kind : str
        ``"zig"`` (``zig cc``, every platform of :data:`PLATFORMS`) or ``"host"`` (the machine's
        own C compiler, its own platform only).
    command : tuple of str
        The compiler's command line before the flags (``python -m ziglang cc`` or ``gcc``).
    version : str
        The compiler's version line.
    """

    kind: str
    command: tuple[str, ...]
    version: str

    def can_build(self, platform: str) -> bool:
        """Whether this toolchain builds for ``platform`` (an FMI platform name)."""
        p = _platform(platform)
        if self.kind == "zig":
            return True
        host = host_platform(p.fmi_version)
        return host == platform

    def can_sanitize(self) -> bool:
        """Whether it builds with ``-fsanitize=address,undefined`` (the host's gcc or clang on
        Linux; zig ships no sanitizer runtime for shared libraries)."""
        return self.kind == "host" and sys.platform.startswith("linux")

    def compile(self, sources: Sequence[str | os.PathLike[str]], out: str | os.PathLike[str],
                platform: str, *, shared: bool = True,
                include_dirs: Iterable[str | os.PathLike[str]] = (),
                defines: Mapping[str, str | None] | None = None, sanitize: bool = False,
                optimize: str = "-O2", extra_flags: Sequence[str] = (),
                libs: Sequence[str] = (), timeout_s: float = 900.0) -> Path:
        """Compile C sources into a shared library (or an executable) for one platform.

        Parameters
        ----------
        sources : sequence of path
            The C files.
        out : path
            The file to write (its folder is created). Nothing else is left beside it: zig's
            import library and debug database of a Windows DLL are dropped.
        platform : str
            An FMI platform name of :data:`PLATFORMS`.
        shared : bool
            A shared library (default) or an executable.
        include_dirs : iterable of path
            ``-I`` folders.
        defines : mapping of str to str or None
            ``-D`` macros (None: defined without a value).
        sanitize : bool
            Build with ``-fsanitize=address,undefined`` (no recovery from undefined behaviour);
            :meth:`can_sanitize` must hold.
        optimize : str
            The optimisation flag.
        extra_flags : sequence of str
            More compiler flags.
        libs : sequence of str
            Libraries to link, without ``-l`` (``m`` is always linked except on Windows).
        timeout_s : float
            The compiler's time limit, s (zig's first build for a platform compiles that
            platform's C library into its cache: minutes).

        Returns
        -------
        pathlib.Path
            ``out``.

        Raises
        ------
        ToolchainError
            The platform is unknown or not buildable by this toolchain, sanitizers are asked of
            one that has none, or the compiler failed (its first error lines in the message).
        """
        p = _platform(platform)
        if not self.can_build(platform):
            raise ToolchainError(f"platform = {platform!r}: the host compiler {self.command[0]} "
                                 f"builds for {host_platform(p.fmi_version)} only; install the "
                                 "'ziglang' package (pip install 'dronefly-fmu[native]') to "
                                 "cross-compile")
        if sanitize and not self.can_sanitize():
            raise ToolchainError(f"sanitize = True: {self.kind} toolchain {self.command[0]} has "
                                 "no sanitizer runtime; use the host's gcc or clang on Linux")
        srcs = [Path(s).resolve() for s in sources]
        missing = [str(s) for s in srcs if not s.is_file()]
        if missing:
            raise ToolchainError(f"sources = {missing}: no such file")
        out = Path(out).resolve()
        out.parent.mkdir(parents=True, exist_ok=True)
        flags = ["-std=c99", optimize, "-Wall", "-Wextra", "-Werror", "-fvisibility=hidden",
                 "-ffp-contract=off"]
        if self.kind == "zig":
            flags = ["-target", p.zig_target, *flags, "-g0"]
        if shared:
            flags += ["-shared"] + ([] if p.fmt == "PE" else ["-fPIC"])
        if sanitize:
            flags += ["-fsanitize=address,undefined", "-fno-sanitize-recover=undefined",
                      "-fno-omit-frame-pointer", "-g"]
        flags += [f"-I{Path(d).resolve()}" for d in include_dirs]
        for k, v in (defines or {}).items():
            flags.append(f"-D{k}" if v is None else f"-D{k}={v}")
        flags += list(extra_flags)
        link = [f"-l{lib}" for lib in libs] + ([] if p.fmt == "PE" else ["-lm"])
        cached = _cached(self, platform, flags, srcs, include_dirs, link, out.suffix)
        if cached is not None and cached.is_file():
            shutil.copy(cached, out)  # the bytes and the mode (an executable stays one)
            return out
        with tempfile.TemporaryDirectory(prefix="dronefly-cc-") as tmp:
            target = Path(tmp) / (out.stem + out.suffix)
            cmd = [*self.command, *flags, "-o", str(target), *map(str, srcs), *link]
            try:
                r = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout_s,
                                   cwd=tmp, env=_compiler_env())
            except subprocess.TimeoutExpired as e:
                raise ToolchainError(f"{self.kind} compiler for {platform} ran past "
                                     f"{timeout_s:g} s on {srcs[0].name}") from e
            if r.returncode != 0 or not target.is_file():
                lines = [ln for ln in (r.stderr or r.stdout).splitlines() if ln.strip()]
                raise ToolchainError(f"{self.kind} compiler for {platform} failed on "
                                     f"{', '.join(s.name for s in srcs)} (exit {r.returncode}): "
                                     + " | ".join(lines[:6]))
            if cached is not None:
                keep_binary(target, cached)
            shutil.move(str(target), out)
        return out


def cache_dir() -> Path | None:
    """The folder of compiled binaries kept between builds: ``$DRONEFLY_CACHE_DIR`` (``0``:
    none), else ``dronefly-fmu/native`` in ``$XDG_CACHE_HOME`` (default ``~/.cache``)."""
    env = os.environ.get("DRONEFLY_CACHE_DIR")
    if env == "0":
        return None
    if env:
        return Path(env)
    home = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(home) / "dronefly-fmu" / "native"


def _cached(tc: Toolchain, platform: str, flags: Sequence[str], srcs: Sequence[Path],
            include_dirs: Iterable[str | os.PathLike[str]], link: Sequence[str],
            suffix: str) -> Path | None:
    """Where the binary of these inputs is kept (None: no cache). The key hashes the compiler
    and its version, the platform, the flags less the include paths, and the names and bytes of
    the sources and of every file in the include folders."""
    folder = cache_dir()
    if folder is None:
        return None
    h = hashlib.sha256()
    for part in (tc.kind, tc.version, platform, *(f for f in flags if not f.startswith("-I")),
                 *link):
        h.update(part.encode() + b"\0")
    for src in srcs:
        h.update(src.name.encode() + b"\0" + src.read_bytes() + b"\0")
    for d in include_dirs:
        for f in sorted(Path(d).resolve().rglob("*")):
            if f.is_file() and f.suffix in (".h", ".c"):
                h.update(str(f.relative_to(Path(d).resolve())).encode() + b"\0"
                         + f.read_bytes() + b"\0")
    return folder / f"{h.hexdigest()}{suffix}"


def cached_binary(parts: Sequence[bytes], suffix: str) -> Path | None:
    """Where the binary made from ``parts`` (the compiler, its version, the flags, the sources:
    everything its bytes depend on) is kept in :func:`cache_dir` (None: no cache)."""
    folder = cache_dir()
    if folder is None:
        return None
    h = hashlib.sha256()
    for part in parts:
        h.update(hashlib.sha256(part).digest())
    return folder / f"{h.hexdigest()}{suffix}"


def keep_binary(binary: Path, cached: Path) -> None:
    """Copy ``binary`` into the cache, atomically; a cache that cannot be written is no cache."""
    try:
        cached.parent.mkdir(parents=True, exist_ok=True)
        fd, part = tempfile.mkstemp(dir=cached.parent, prefix=".part-")
        try:
            with os.fdopen(fd, "wb") as f:
                f.write(binary.read_bytes())
            shutil.copymode(binary, part)
            os.replace(part, cached)
        finally:
            if os.path.exists(part):
                os.unlink(part)
    except OSError:
        pass


def _compiler_env() -> dict[str, str]:
    """The compiler's environment: zig keeps its cache of built C libraries per user
    (``ZIG_GLOBAL_CACHE_DIR``, default ``~/.cache/zig``) and its local cache beside it, not in
    the working folder."""
    env = dict(os.environ)
    if "ZIG_GLOBAL_CACHE_DIR" not in env:
        home = env.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
        env["ZIG_GLOBAL_CACHE_DIR"] = str(Path(home) / "zig")
    env.setdefault("ZIG_LOCAL_CACHE_DIR", env["ZIG_GLOBAL_CACHE_DIR"])
    return env


def _version(cmd: Sequence[str], flag: str) -> str | None:
    try:
        r = subprocess.run([*cmd, flag], capture_output=True, text=True, timeout=60,
                           env=_compiler_env())
    except (OSError, subprocess.SubprocessError):
        return None
    lines = (r.stdout or r.stderr).strip().splitlines()
    return lines[0].strip() if r.returncode == 0 and lines else None


def _ziglang_installed() -> bool:
    return importlib.util.find_spec("ziglang") is not None


@functools.lru_cache(maxsize=None)
def _zig() -> Toolchain | None:
    if not _ziglang_installed():
        return None
    cmd = (sys.executable, "-m", "ziglang")
    version = _version(cmd, "version")
    return None if version is None else Toolchain("zig", (*cmd, "cc"), f"zig {version}")


@functools.lru_cache(maxsize=None)
def _host_cc() -> Toolchain | None:
    names = [os.environ["CC"]] if os.environ.get("CC") else []
    for name in [*names, "gcc", "cc", "clang"]:
        exe = shutil.which(name)
        if exe:
            version = _version([exe], "--version")
            if version:
                return Toolchain("host", (exe,), version)
    return None


def find_toolchain(platform: str | None = None, *, sanitize: bool = False) -> Toolchain | None:
    """The toolchain that builds for ``platform``: ``zig cc`` where the ``ziglang`` package is
    installed, else the host's C compiler for the host's own platform.

    Parameters
    ----------
    platform : str or None
        An FMI platform name; None: the host's (FMI 3.0 name).
    sanitize : bool
        Only a toolchain that builds with ``-fsanitize=address,undefined`` (the host's gcc or
        clang, preferred over zig then).

    Returns
    -------
    Toolchain or None
        None when there is none; :func:`missing_reason` says why in one line.
    """
    name = platform or host_platform("3.0")
    if name is None:
        return None
    _platform(name)
    order = (_host_cc, _zig) if sanitize else (_zig, _host_cc)
    for find in order:
        tc = find()
        if tc is not None and tc.can_build(name) and (tc.can_sanitize() or not sanitize):
            return tc
    return None


def missing_reason(platform: str | None = None, *, sanitize: bool = False) -> str | None:
    """Why :func:`find_toolchain` finds none, in one line; None when it finds one.

    Parameters
    ----------
    platform, sanitize
        As for :func:`find_toolchain`.

    Returns
    -------
    str or None
    """
    if find_toolchain(platform, sanitize=sanitize) is not None:
        return None
    name = platform or host_platform("3.0")
    if name is None:
        return (f"no C toolchain: this machine ({sys.platform}, {_pyplatform.machine()}) has no "
                "FMI platform name")
    if sanitize:
        return (f"no C toolchain with sanitizers for {name}: the host's gcc or clang on Linux "
                "builds with -fsanitize=address,undefined (.ci/setup-c-host.sh installs gcc)")
    zig = ("the 'ziglang' package is missing (pip install 'dronefly-fmu[native]')"
           if not _ziglang_installed() else
           "the 'ziglang' package is installed but `python -m ziglang version` failed")
    host = _host_cc()
    why_host = ("no gcc, cc or clang on PATH" if host is None else
                f"the host compiler {host.command[0]} builds for "
                f"{host_platform(_platform(name).fmi_version)} only")
    return f"no C toolchain for {name}: {zig} and {why_host}"


# ---------------------------------------------------------------------------------------------
# what a binary is, from its header
_ELF_MACHINE = {62: "x86_64", 183: "aarch64"}
_PE_MACHINE = {0x8664: "x86_64", 0xAA64: "aarch64"}
_MACHO_CPU = {0x01000007: "x86_64", 0x0100000C: "aarch64"}


def binary_platform(path: str | os.PathLike[str]) -> tuple[str, str, bool] | None:
    """The format, architecture and kind of a compiled binary, read from its header.

    Parameters
    ----------
    path : path
        A file.

    Returns
    -------
    tuple of (str, str, bool) or None
        ``(fmt, arch, shared)``: ``fmt`` ``"ELF"``, ``"PE"`` or ``"Mach-O"``; ``arch``
        ``"x86_64"``, ``"aarch64"`` or ``"machine 0x.."``; ``shared`` whether a shared library
        (ELF ``ET_DYN`` can also be a position-independent executable: True for both). None when
        the file is none of these 64-bit formats.
    """
    head = Path(path).read_bytes()[:4096]
    if head[:4] == b"\x7fELF" and len(head) >= 20 and head[4] == 2:  # ELFCLASS64
        order = "<" if head[5] == 1 else ">"
        e_type, e_machine = struct.unpack_from(order + "HH", head, 16)
        return "ELF", _ELF_MACHINE.get(e_machine, f"machine {e_machine:#x}"), e_type == 3
    if head[:2] == b"MZ" and len(head) >= 64:
        (pe,) = struct.unpack_from("<I", head, 0x3C)
        if head[pe:pe + 4] == b"PE\0\0" and len(head) >= pe + 24:
            machine, = struct.unpack_from("<H", head, pe + 4)
            characteristics, = struct.unpack_from("<H", head, pe + 22)
            return ("PE", _PE_MACHINE.get(machine, f"machine {machine:#x}"),
                    bool(characteristics & 0x2000))  # IMAGE_FILE_DLL
    if head[:4] == b"\xcf\xfa\xed\xfe" and len(head) >= 16:  # MH_MAGIC_64, little-endian
        cpu, _sub, filetype = struct.unpack_from("<iII", head, 4)
        return "Mach-O", _MACHO_CPU.get(cpu & 0xFFFFFFFF, f"machine {cpu:#x}"), filetype == 6
    return None
