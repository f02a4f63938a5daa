"""Where profiles live and how their files are read: by name or by path, as TOML, and a
design profile over the one it names as its ``base``.

A design profile may name another as its ``base`` (``base = "default"``, or a path
relative to its own folder) and set only what differs: a maker's two-line profile then
keeps following the default as lampfab improves it, where a copy would keep the
settings of the day it was made.  ``profile`` checks the values.
"""

from __future__ import annotations

import tomllib
from pathlib import Path

from .errors import LampfabError

PROFILE_DIR = Path(__file__).resolve().parent.parent / "profiles"


def read_toml(path: Path) -> dict:
    """A profile file's TOML; a missing or malformed file is one LampfabError naming it."""
    try:
        with open(path, "rb") as fh:
            return tomllib.load(fh)
    except FileNotFoundError:
        raise LampfabError(f"{path}: profile not found") from None
    except tomllib.TOMLDecodeError as exc:
        raise LampfabError(f"{path}: not valid TOML ({exc})") from None


def resolve(name_or_path: str, folder: Path) -> Path:
    """A profile given by name (``draft``) or path (``my.toml``)."""
    p = Path(name_or_path)
    if p.suffix == ".toml" or p.exists():
        return p
    candidate = folder / f"{name_or_path}.toml"
    if not candidate.exists():
        names = sorted(q.stem for q in folder.glob("*.toml"))
        raise LampfabError(f"profile {name_or_path!r} not found in {folder}; available: {', '.join(names)}")
    return candidate


def design_tables(path: Path, sections, chain: tuple[Path, ...] = ()) -> tuple[dict, dict]:
    """A design profile's tables (``sections``: their names) over its ``base``'s, and
    which file set each key: ({section: {key: value}}, {(section, key): path})."""
    if path.resolve() in chain:
        raise LampfabError(f"{path}: base: the profiles name each other as their base "
                           f"({' -> '.join(str(q) for q in (*chain, path.resolve()))})")
    data = read_toml(path)
    unknown = set(data) - set(sections) - {"base"}
    if unknown:
        raise LampfabError(f"{path}: unknown section [{sorted(unknown)[0]}]; allowed: base, {', '.join(sections)}")
    for section in sections:
        if not isinstance(data.get(section, {}), dict):
            raise LampfabError(f"{path}: [{section}] must be a table")
    tables, origins = {}, {}
    if "base" in data:
        base = data["base"]
        if not isinstance(base, str) or not base:
            raise LampfabError(f"{path}: base: expected a profile's name or a .toml path, got {base!r}")
        try:
            # A .toml path is read beside the profile (an absolute one stays as it is).
            base_path = resolve(str(path.parent / base) if Path(base).suffix == ".toml" else base, PROFILE_DIR)
        except LampfabError as exc:
            raise LampfabError(f"{path}: base: {exc}") from None
        if not base_path.exists():
            raise LampfabError(f"{path}: base: {base_path} not found")
        tables, origins = design_tables(base_path, sections, (*chain, path.resolve()))
    for section in sections:
        for key, value in data.get(section, {}).items():
            tables.setdefault(section, {})[key] = value
            origins[(section, key)] = path
    return tables, origins
