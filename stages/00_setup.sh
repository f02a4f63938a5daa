#!/usr/bin/env bash
# Stage 0: what the machine needs besides Python packages.
#  - libLLVM 19: Dr.Jit's CPU backend aborts on Debian's libllvm14/15 ("Cannot select fminimum").
#  - libGL / GLib: pymeshlab's wheel links against them.
#  - Chromium: the test suite opens report.html in a real headless browser.
#  - ADMesh: the STL checker slicers' repair code descends from; export asks it whether
#    lens.stl needs any repair (none may be needed), and the tests do too.
#  - Tesseract OCR: verify reads a text lamp's words back from its renders.
#  - python3-venv: Debian ships Python without ensurepip, which `python3 -m venv` needs.
set -euo pipefail
if ! python3 -c 'import sys; sys.exit(sys.version_info < (3, 11))' 2>/dev/null; then
  echo "lampfab setup: needs Python 3.11 or newer as python3 (found: $(python3 --version 2>&1))" >&2
  exit 1
fi
have_venv() { python3 -c 'import ensurepip, venv' 2>/dev/null; }
have_llvm() { ls /usr/lib/*/libLLVM-19.so* /usr/lib/llvm-19/lib/libLLVM*.so* >/dev/null 2>&1; }
have_gl() { ldconfig -p | grep -q 'libGL.so.1' && ldconfig -p | grep -q 'libgthread-2.0.so.0'; }
have_browser() { command -v chromium >/dev/null || command -v chromium-browser >/dev/null; }
have_admesh() { command -v admesh >/dev/null; }
have_ocr() { command -v tesseract >/dev/null; }
if have_llvm && have_gl && have_browser && have_admesh && have_ocr && have_venv; then exit 0; fi
if ! command -v apt-get >/dev/null; then
  echo "lampfab setup: need libLLVM 19, libGL, ADMesh and Python's venv; install them with your package manager" >&2
  exit 1
fi
SUDO=""; [ "$(id -u)" -ne 0 ] && SUDO="sudo"
$SUDO apt-get update -qq
DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq libllvm19 libgl1 libglib2.0-0 admesh python3-venv >/dev/null
# Only the tests need the browser: a distribution without the package still designs lamps.
DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq chromium >/dev/null \
  || echo "lampfab setup: could not install chromium; the report's browser test will fail" >&2
# Only text lamps use OCR: without it they are designed as well, their words not read back.
DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq tesseract-ocr >/dev/null \
  || echo "lampfab setup: could not install tesseract-ocr; verify will not read text lamps' words back" >&2
