"""Plain helpers the tests share: the repository's paths, `make` and the command line as
a user runs them, and a small lens (CYL, bumps, inner) for the solid, STEP and
fabrication tests.  Fixtures are in conftest.py."""

import contextlib
import importlib.util
import io
import os
import sys
import subprocess
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from lampfab import profile, surface
from lampfab.inner import default_inner_mesh

ROOT = Path(__file__).resolve().parent.parent

# The LED of the tiny lamps whose pictures the tests judge: the default, one package facing
# each wall (tiny apple r 0.91-0.93).  A tiny design (a few dozen nodes, two steps) cannot
# bend a flat LED's upward light far enough to judge its pictures by the same bars.
TINY_LED = profile.DEFAULT_LED

# The Makefile reads these with ?=: a developer's exported TEXT or ALLOW_FAIL would change
# every build the tests make.
_MAKE_VARIABLES = ("TARGET", "TEXT", "PANORAMA", "NAME", "PROFILE", "FAB", "ALLOW_FAIL", "BUILD",
                   "TARGET_FRONT", "TARGET_LEFT", "TARGET_RIGHT", "TARGET_FLOOR", "LED")


def load_script(path: str):
    """A script of the repository (``path`` relative to it: bench/ and examples/ are no
    packages) imported as a module."""
    spec = importlib.util.spec_from_file_location(Path(path).stem, ROOT / path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # its dataclasses look their module up
    spec.loader.exec_module(module)
    return module


def make(*args) -> subprocess.CompletedProcess:
    """``make`` in the repository with ``args`` (targets and VAR=value), its output captured."""
    env = {k: v for k, v in os.environ.items() if k not in _MAKE_VARIABLES}
    return subprocess.run(["make", "--no-print-directory", *args], cwd=ROOT, capture_output=True, text=True, env=env)


@dataclass
class Run:
    """What a command line call gave: its exit code and what it printed."""
    returncode: int
    stdout: str
    stderr: str


def cli(*args) -> Run:
    """``lampfab ARGS`` in this process (``lampfab.cli.main``), its output captured; an
    argparse exit (``--help``, a usage error) gives its code like any other."""
    from lampfab.cli import main

    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            code = main([str(a) for a in args])
        except SystemExit as exc:
            code = exc.code if isinstance(exc.code, int) else 1
    return Run(code, out.getvalue(), err.getvalue())


CYL = surface.Cylinder(radius_mm=40.0, height_mm=80.0)


def bumps(nu=32, nv=8, seed=0, amp=2.0):
    """Smooth random bumps of +-amp mm: a few low harmonics around and up."""
    rng = np.random.default_rng(seed)
    u = np.arange(nu)[:, None] * (2 * np.pi / nu)
    z = np.linspace(0.0, 1.0, nv)[None, :]
    h = np.zeros((nu, nv))
    for k in range(1, 5):
        for m in range(3):
            a, b, c = rng.normal(size=3)
            h += a * np.cos(k * u + b) * np.cos(m * np.pi * z + c)
    return h * (amp / np.abs(h).max())


def inner(sections=32, **kw):
    """A coarse inner layer sized for CYL: r 20 mm, floor at z 12, roof apex at z 68."""
    kw = {"radius_mm": 20.0, "z0_mm": 12.0, "z1_mm": 68.0, **kw}
    mesh = default_inner_mesh(sections=sections, **kw)
    return np.asarray(mesh.vertices, np.float64), np.asarray(mesh.faces, np.int64)
