"""Reading and writing every artifact lampfab makes.  The only module that touches files.

Every write goes to a temporary file in the same folder and is renamed into place, so
a stage killed mid-write never leaves a file that Make takes as done.
"""

from __future__ import annotations

import contextlib
import functools
import hashlib
import json
import os
import platform
import shutil
import subprocess
import sys
import tempfile
import time
from importlib import metadata
from pathlib import Path

import numpy as np

from .errors import LampfabError

# mkstemp makes its files private (0600); a finished artifact gets the mode any new
# file of this user gets, so a print shop's account or a web server can read it.
_UMASK = os.umask(0)
os.umask(_UMASK)
_FILE_MODE = 0o666 & ~_UMASK


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike, suffix: str = ""):
    """Yield a temporary path beside ``path``; rename it onto ``path`` on success."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=suffix or path.suffix, dir=path.parent)
    os.close(fd)
    try:
        yield Path(tmp)
        os.chmod(tmp, _FILE_MODE)
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        raise


def remove_stale_temps(path: str | os.PathLike) -> None:
    """Delete the temporary files of ``atomic_path(path)`` that a killed process left
    behind (kill -9 skips the clean-up).  Only the one writer of ``path`` may call it."""
    path = Path(path)
    for stale in path.parent.glob(f".{path.name}.*"):
        stale.unlink(missing_ok=True)


def remove(path) -> None:
    """Delete ``path`` if it exists (an artifact an earlier run made that no longer holds)."""
    Path(path).unlink(missing_ok=True)


def write_bytes(path, data: bytes) -> None:
    """``data`` as the whole of ``path`` (a file encoded by its format's module)."""
    with atomic_path(path) as tmp:
        tmp.write_bytes(data)


def write_text(path, text: str) -> None:
    with atomic_path(path) as tmp:
        tmp.write_text(text, encoding="utf-8")


def holds_text(path, text: str) -> bool:
    """Whether ``path`` exists and holds exactly ``text``."""
    path = Path(path)
    return path.is_file() and path.read_text(encoding="utf-8") == text


def write_csv(path, rows: np.ndarray, header: list[str], formats: list[str]) -> None:
    """(n, k) ``rows`` under a one-line ``header`` of k names, column j printed with
    ``formats[j]`` (printf style)."""
    with atomic_path(path) as tmp:
        np.savetxt(tmp, rows, delimiter=",", header=",".join(header), comments="", fmt=formats)


def write_json(path, data: dict) -> None:
    write_text(path, json.dumps(data, indent=2, default=_jsonable) + "\n")


def read_json(path) -> dict:
    try:
        return json.loads(Path(path).read_text())
    except FileNotFoundError:
        raise LampfabError(f"{path}: not found (run the stage that makes it first)") from None
    except json.JSONDecodeError as exc:
        raise LampfabError(f"{path}: not valid JSON ({exc})") from None


def write_npz(path, **arrays) -> None:
    with atomic_path(path, suffix=".npz") as tmp:
        np.savez(tmp, **arrays)


def read_npz(path) -> dict:
    try:
        with np.load(path) as data:
            return {k: data[k] for k in data.files}
    except FileNotFoundError:
        raise LampfabError(f"{path}: not found (run the stage that makes it first)") from None


def write_png(path, image: np.ndarray, normalize: bool = True) -> None:
    """Write a (rows, cols) or (rows, cols, 3) float image as an 8-bit sRGB PNG.

    ``normalize`` scales so the 99.5th percentile maps to white (linear input).
    """
    from PIL import Image

    with atomic_path(path, suffix=".png") as tmp:
        Image.fromarray(srgb8(image, normalize)).save(tmp, format="PNG")


def srgb8(image: np.ndarray, normalize: bool = True) -> np.ndarray:
    """A linear float image as 8-bit sRGB, same shape, uint8; ``normalize`` as
    ``write_png``'s."""
    img = np.asarray(image, dtype=np.float64)
    if normalize:
        top = np.percentile(img, 99.5) if img.size else 1.0
        img = img / top if top > 0 else img
    img = np.clip(img, 0.0, 1.0)
    srgb = np.where(img <= 0.0031308, 12.92 * img, 1.055 * np.power(img, 1 / 2.4) - 0.055)
    return np.round(srgb * 255).astype(np.uint8)


def write_linear_png16(path, image: np.ndarray) -> None:
    """Write a (rows, cols) linear image in [0, 1] losslessly as a 16-bit grey PNG."""
    from PIL import Image

    data = np.round(np.clip(image, 0, 1) * 65535).astype(np.uint16)
    with atomic_path(path, suffix=".png") as tmp:
        Image.fromarray(data).save(tmp, format="PNG")


def read_linear_png16(path) -> np.ndarray:
    """Read a target written by ``write_linear_png16``: (rows, cols) float64 in [0, 1]."""
    from PIL import Image

    try:
        with Image.open(path) as im:
            return np.asarray(im, dtype=np.float64) / 65535.0
    except FileNotFoundError:
        raise LampfabError(f"{path}: not found (run prepare first)") from None


def file_sha256(path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


@functools.lru_cache(maxsize=1)
def git_describe(package: Path = Path(__file__).resolve().parent) -> str | None:
    """``git describe --always --dirty`` of the git checkout lampfab runs from (the one
    that tracks ``package``), so a report says which code made it; None where lampfab
    is not run from a checkout (an installed copy) or git is missing."""
    git = shutil.which("git")
    if git is None:
        return None

    def ask(*args) -> str | None:
        try:
            run = subprocess.run([git, "-C", str(package), *args], capture_output=True, text=True, timeout=30)
        except (OSError, subprocess.SubprocessError):
            return None
        return run.stdout.strip() if run.returncode == 0 else None

    # A copy installed into a virtual environment inside a checkout is not that checkout's code.
    if ask("ls-files", "--error-unmatch", "__init__.py") is None:
        return None
    return ask("describe", "--always", "--dirty") or None


def versions() -> dict:
    out = {"python": sys.version.split()[0], "platform": platform.platform()}
    for pkg in ("lampfab", "mitsuba", "drjit", "manifold3d", "trimesh", "pymeshlab",
                "cadquery-ocp-novtk", "numpy", "scipy", "pillow", "scikit-image"):
        with contextlib.suppress(metadata.PackageNotFoundError):
            out[pkg] = metadata.version(pkg)
    return out


class StageReport:
    """The JSON report every stage writes: inputs (with hashes), settings, versions and
    the checkout's ``git describe``, wall time and key figures."""

    def __init__(self, stage: str, inputs: dict[str, str], settings: dict, seed: int | None = None):
        self.stage = stage
        self.start = time.time()
        self.data = {
            "stage": stage,
            "inputs": {k: {"path": str(v), "sha256": file_sha256(v)} for k, v in inputs.items()
                       if v and Path(v).is_file()},
            "seed": seed,
            "settings": settings,
            "versions": versions(),
            "git_describe": git_describe(),
            "figures": {},
        }

    def figure(self, **figures) -> None:
        self.data["figures"].update(figures)

    def write(self, path) -> None:
        self.data["wall_time_s"] = round(time.time() - self.start, 3)
        write_json(path, self.data)


def _jsonable(obj):
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, (np.floating, np.integer)):
        return obj.item()
    if isinstance(obj, Path):
        return str(obj)
    raise TypeError(f"not JSON serializable: {type(obj).__name__}")
