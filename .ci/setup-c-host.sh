#!/usr/bin/env bash
# Prepare a fresh Debian/Ubuntu machine for the tests of the C hosts and the native FMUs
# (tests/test_interop.py, tests/test_native_hosts.py, tests/test_toolchain.py):
# - gcc (the sanitizer builds; the C host of the pythonfmu FMUs) and file(1) (reads binaries'
#   headers independently of the project);
# - a shared libpython of the interpreter's major.minor version (pythonfmu's binary needs the
#   Python C API symbols from the host process; a C host gets them by LD_PRELOAD of it);
# - Wine (Debian's wine64: the Windows build of the C host runs the win64 binaries under it),
#   and its prefix, made once (13 s) in ~/.cache/dronefly-wine, where the tests look;
# - zig's cache of the C libraries of every FMI platform (its first build for Windows compiles
#   mingw-w64's runtime: minutes on 2 cores), filled by building a probe for each, when the
#   interpreter has the ziglang package (the test extra).
# - valgrind, for the exit double-free test of tests/test_reliability.py.
# Installs only what is missing; on a prepared machine it only checks, in seconds.
# Usage: .ci/setup-c-host.sh [python]   (default: $PYTHON or python3, the interpreter of the venv)
set -euo pipefail
PY="${1:-${PYTHON:-python3}}"
need=()
command -v gcc >/dev/null 2>&1 || need+=(gcc libc6-dev)
command -v file >/dev/null 2>&1 || need+=(file)
command -v valgrind >/dev/null 2>&1 || need+=(valgrind)
lib="$("$PY" - <<'PYEOF'
import ctypes.util, os, sys, sysconfig
libdir = sysconfig.get_config_var("LIBDIR") or ""
multi = sysconfig.get_config_var("MULTIARCH") or ""
so = sysconfig.get_config_var("INSTSONAME") or ""
cands = [os.path.join(libdir, so), os.path.join(libdir, multi, so)] if ".so" in so else []
hit = next((c for c in cands if os.path.isfile(c)), "")
if not hit and ctypes.util.find_library(f"python{sys.version_info[0]}.{sys.version_info[1]}"):
    hit = "system"
print(hit)
PYEOF
)"
if [ -z "$lib" ]; then
  need+=("libpython$("$PY" -c 'import sys; print("%d.%d" % sys.version_info[:2])')")
fi
wine=""
case "$(uname -s)-$(uname -m)" in
  Linux-x86_64)
    for w in wine64 wine /usr/lib/wine/wine64 /usr/lib/x86_64-linux-gnu/wine/wine64; do
      if command -v "$w" >/dev/null 2>&1; then wine="$(command -v "$w")"; break; fi
    done
    [ -n "$wine" ] || need+=(wine64) ;;
esac
if [ "${#need[@]}" -gt 0 ]; then
  SUDO=""
  if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
  echo "setup-c-host: installing ${need[*]}"
  $SUDO apt-get update -q
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -q --no-install-recommends "${need[@]}"
else
  echo "setup-c-host: gcc, file, valgrind, libpython and Wine present"
fi
# Debian's wine64 puts its loader in /usr/lib/wine/ (the `wine` package adds /usr/bin/wine)
if [ -z "$wine" ] && [ "$(uname -s)-$(uname -m)" = "Linux-x86_64" ]; then
  for w in wine64 wine /usr/lib/wine/wine64 /usr/lib/x86_64-linux-gnu/wine/wine64; do
    if command -v "$w" >/dev/null 2>&1; then wine="$(command -v "$w")"; break; fi
  done
fi
if [ -n "$wine" ]; then
  prefix="${WINEPREFIX:-$HOME/.cache/dronefly-wine}"
  if [ ! -d "$prefix/drive_c/windows" ]; then
    echo "setup-c-host: making the Wine prefix $prefix"
    mkdir -p "$(dirname "$prefix")"
    WINEPREFIX="$prefix" WINEDEBUG=-all "$wine" wineboot --init >/dev/null 2>&1 || true
    server="$(dirname "$wine")/wineserver"
    [ -x "$server" ] || server="$(command -v wineserver || true)"
    [ -z "$server" ] || WINEPREFIX="$prefix" "$server" -w || true   # the registry written
  fi
fi
# zig's cache: one probe per FMI platform (a no-op where it is filled already)
"$PY" - <<'PYEOF'
import importlib.util, os, sys, tempfile, time
from pathlib import Path
# zig itself compiles (the project's binary cache would answer the probe without running zig)
os.environ["DRONEFLY_CACHE_DIR"] = "0"
if importlib.util.find_spec("ziglang") is None or importlib.util.find_spec("dronefly") is None:
    print("setup-c-host: no ziglang or dronefly in this interpreter: zig's cache not filled")
    sys.exit(0)
from dronefly.harness.builder.toolchain import PLATFORMS, find_toolchain, fmi_include_dir
tc = find_toolchain("win64")
if tc is None or tc.kind != "zig":
    print("setup-c-host: zig cc does not start: zig's cache not filled")
    sys.exit(0)
t0 = time.monotonic()
with tempfile.TemporaryDirectory() as tmp:
    src = Path(tmp) / "probe.c"
    src.write_text('#include <math.h>\n#include <stdio.h>\n#include "fmi2Functions.h"\n'
                   'FMI2_Export double probe(double x) { return sqrt(x); }\n'
                   'int main(void) { printf("%g\\n", probe(4.0)); return 0; }\n')
    for name, p in PLATFORMS.items():
        tc.compile([src], Path(tmp) / f"{name}{p.suffix}", name, include_dirs=[fmi_include_dir()])
    for name in ("linux64", "win64"):  # executables: the C host's start-up files
        tc.compile([src], Path(tmp) / f"{name}.exe", name, shared=False,
                   include_dirs=[fmi_include_dir()])
print(f"setup-c-host: zig cc builds for {len(PLATFORMS)} platforms "
      f"({time.monotonic() - t0:.0f} s)")
PYEOF
# the native FMUs' binaries, every platform, into the build cache (a copy instead of a compile
# for every later build of the same sources: harness/builder/toolchain.py, cache_dir)
out="$(mktemp -d)"
t0=$(date +%s)
if "$PY" -m dronefly build --native --out "$out" >/dev/null; then
  echo "setup-c-host: native FMUs built into the cache ($(( $(date +%s) - t0 )) s)"
else
  echo "setup-c-host: dronefly build --native failed (the native tests will say why)"
fi
rm -rf "$out"
