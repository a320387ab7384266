#!/usr/bin/env bash
# Prepare a fresh Debian/Ubuntu machine for the C-host test of tests/test_interop.py:
# a C compiler, and a shared libpython of the interpreter's major.minor version (pythonfmu's
# binary needs the Python C API symbols from the host process; a C host gets them by
# LD_PRELOAD of that library); and valgrind, for the exit double-free test of
# tests/test_reliability.py. Installs only what is missing; a no-op on a prepared machine.
# Usage: .ci/setup-c-host.sh [python]   (default: $PYTHON or python3, the interpreter of the venv)
set -euo pipefail
PY="${1:-${PYTHON:-python3}}"
need=()
command -v gcc >/dev/null 2>&1 || need+=(gcc libc6-dev)
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
if [ "${#need[@]}" -gt 0 ]; then
  SUDO=""
  if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
  echo "setup-c-host: installing ${need[*]}"
  $SUDO apt-get update -q
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -q --no-install-recommends "${need[@]}"
else
  echo "setup-c-host: gcc, libpython and valgrind present"
fi
