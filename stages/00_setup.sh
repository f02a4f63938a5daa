#!/usr/bin/env bash
# Stage 0: what the machine needs besides Python packages.
#  - libLLVM 19: Dr.Jit's CPU backend aborts on Debian's libllvm14/15 ("Cannot select fminimum").
#  - libGL / GLib: pymeshlab's wheel links against them.
set -euo pipefail
have_llvm() { ls /usr/lib/*/libLLVM-19.so* /usr/lib/llvm-19/lib/libLLVM*.so* >/dev/null 2>&1; }
have_gl() { ldconfig -p | grep -q 'libGL.so.1' && ldconfig -p | grep -q 'libgthread-2.0.so.0'; }
if have_llvm && have_gl; then exit 0; fi
if ! command -v apt-get >/dev/null; then
  echo "lampfab setup: need libLLVM 19 and libGL; install them with your package manager" >&2
  exit 1
fi
SUDO=""; [ "$(id -u)" -ne 0 ] && SUDO="sudo"
$SUDO apt-get update -qq
DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq libllvm19 libgl1 libglib2.0-0 >/dev/null
