"""Which spec files a scenario folder holds, and the file a name means: ``circle_vinyl`` is
``scenarios/circle_vinyl.toml``, platform ``husky`` is ``scenarios/platforms/husky.toml``; a path is itself.  An
unknown bare name is a one-line :class:`~bench.schema.SpecError` naming the known ones (a scenario's: the nearest)."""
from __future__ import annotations

import difflib
from pathlib import Path

from bench.paths import SCENARIO_DIR
from bench.schema import SpecError

__all__ = ["list_scenarios", "registered", "resolve_name", "known_file"]


def list_scenarios(root: Path = SCENARIO_DIR) -> list[str]:
    return sorted(p.stem for p in root.glob("*.toml"))


def registered(what: str, root: Path = SCENARIO_DIR) -> list[str]:
    """The names of the ``what`` ("platform" or "terrain") files of the scenario folder."""
    return list_scenarios(root / f"{what}s")


def resolve_name(name_or_path: str | Path, folder: Path) -> Path:
    p = Path(name_or_path)
    if p.suffix == ".toml" or p.is_absolute() or p.exists():
        return p
    return folder / f"{name_or_path}.toml"


def known_file(name_or_path: str | Path, root: Path, what: str) -> Path:
    """The file of a registered name or a path; an unknown bare name is one line naming the known ones (a scenario's:
    the nearest, `skidbench list` shows them all)."""
    folder, p = root if what == "scenario" else root / f"{what}s", Path(name_or_path)
    if not (path := resolve_name(name_or_path, folder)).exists() and p.suffix != ".toml" and len(p.parts) == 1:
        names = list_scenarios(folder)
        near = " or ".join(difflib.get_close_matches(p.name, names, n=3))
        hint = f"did you mean {near}? " if near else ""
        known = (f"{hint}(`skidbench list` shows them all, or give the path of a .toml file)"
                 if what == "scenario" else f"known: {', '.join(names)} (or the path of a .toml file)")
        raise SpecError(f"<{what} name>", what, str(name_or_path), f"unknown {what}; {known}")
    return path
