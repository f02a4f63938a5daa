"""Importing Mitsuba and Dr.Jit with a backend that works on this machine.

Dr.Jit's CPU backend compiles kernels with the system's libLLVM.  Debian's libllvm14
and 15 abort with ``LLVM ERROR: Cannot select ... fminimum``; libllvm19 works, so it is
preferred when present (``make`` installs it).  ``LAMPFAB_VARIANT`` overrides the
variant (e.g. ``cuda_ad_mono`` on a GPU machine); by default a CUDA variant is used
when an NVIDIA driver is visible, else the LLVM one.
"""

from __future__ import annotations

import glob
import os
import shutil

from .errors import LampfabError

LLVM_CANDIDATES = (
    "/usr/lib/x86_64-linux-gnu/libLLVM-19.so*",
    "/usr/lib/aarch64-linux-gnu/libLLVM-19.so*",
    "/usr/lib/llvm-19/lib/libLLVM*.so*",
    "/usr/lib/*/libLLVM.so.2[0-9]*",
    "/usr/lib/*/libLLVM-2[0-9].so*",
)

_mi = None


def find_libllvm() -> str | None:
    for pattern in LLVM_CANDIDATES:
        hits = sorted(glob.glob(pattern))
        if hits:
            return hits[0]
    return None


def default_variant() -> str:
    if os.environ.get("LAMPFAB_VARIANT"):
        return os.environ["LAMPFAB_VARIANT"]
    return "cuda_ad_mono" if shutil.which("nvidia-smi") else "llvm_ad_mono"


def mitsuba():
    """Mitsuba, imported once with the variant set; raises LampfabError if no backend."""
    global _mi
    if _mi is not None:
        return _mi
    variant = default_variant()
    if variant.startswith("llvm") and "DRJIT_LIBLLVM_PATH" not in os.environ:
        lib = find_libllvm()
        if lib is None:
            raise LampfabError("no usable libLLVM found for Dr.Jit's CPU backend; "
                               "install Debian's libllvm19 (make does this) or set DRJIT_LIBLLVM_PATH")
        os.environ["DRJIT_LIBLLVM_PATH"] = lib
    import mitsuba as mi

    try:
        mi.set_variant(variant)
    except Exception as exc:  # noqa: BLE001 - Mitsuba raises bare Exceptions here
        raise LampfabError(f"Mitsuba variant {variant!r} is not usable here: {exc}") from None
    _mi = mi
    return mi
