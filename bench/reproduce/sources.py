"""Calibration targets from the parameter sources of the testbed.

Every platform and terrain file (``scenarios/platforms/*.toml``, ``scenarios/terrains/*.toml``) gives the source
of each numeric parameter in a ``[sources]`` table, and every scenario file (``scenarios/*.toml``) the source of each
of its overrides (``"terrain.roughness_gd0" = {...}``)::

    [sources]
    mu_sa = {kind = "paper", ref = "Yu 2010 Table II (vinyl)"}
    shear_modulus = {kind = "chosen", ref = "K = 3 mm gives the trend of Wang 2015 Table 3",
                     claims = ["wang2015.chi_decreases"]}
    "motor.max_power" = {kind = "chosen", ref = "...", claims = ["yu2010.ramps_testbed"]}

A parameter of kind ``chosen`` was chosen to produce a claimed outcome: each claim it lists
(``"<paper>.<claim id>"``) is a *calibration target*, reported with its numbers and never counted as a verdict.
A file without ``[sources]`` has no calibration target; a nested entry (``[sources.motor]`` with ``max_power =
{...}``) is read as the dotted key ``motor.max_power``.  Whether every parameter has a source is checked by the
spec loader (:mod:`bench.spec`); this module only reads what the claims need.
"""
from __future__ import annotations

import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Iterator, Mapping

from bench.spec import SCENARIO_DIR

__all__ = ["ParameterSource", "SOURCE_DIRS", "parameter_sources", "calibration_targets"]

# the platform and terrain files, and the scenario files (the sources of their [platform_overrides] /
# [terrain_overrides], keyed "platform.<key>" / "terrain.<key>": bench.sources.override_sources)
SOURCE_DIRS = (SCENARIO_DIR / "platforms", SCENARIO_DIR / "terrains", SCENARIO_DIR)


@dataclass(frozen=True)
class ParameterSource:
    file: str          # e.g. "terrains/vinyl.toml"
    parameter: str     # e.g. "shear_modulus" or "motor.max_power"
    kind: str          # paper | datasheet | calibration | real | testbed | chosen
    ref: str
    claims: tuple[str, ...] = ()

    @property
    def name(self) -> str:
        """``<file stem>.<parameter>``: how the report names it (e.g. ``vinyl.shear_modulus``)."""
        return f"{Path(self.file).stem}.{self.parameter}"


def _entries(table: Mapping[str, Any], prefix: str = "") -> Iterator[tuple[str, Mapping[str, Any]]]:
    for key, val in table.items():
        if not isinstance(val, Mapping):
            continue
        if "kind" in val and not isinstance(val["kind"], Mapping):
            yield prefix + key, val
        else:
            yield from _entries(val, f"{prefix}{key}.")


def parameter_sources(dirs: tuple[Path, ...] | None = None) -> list[ParameterSource]:
    """Every ``[sources]`` entry of the platform and terrain files (none for a file without the table)."""
    out = []
    for folder in (SOURCE_DIRS if dirs is None else dirs):
        for path in sorted(Path(folder).glob("*.toml")):
            with open(path, "rb") as fh:
                data = tomllib.load(fh)
            for param, entry in _entries(data.get("sources", {})):
                claims = entry.get("claims", ())
                out.append(ParameterSource(f"{Path(folder).name}/{path.name}", param, str(entry.get("kind")),
                                           str(entry.get("ref", "")),
                                           tuple(claims) if isinstance(claims, (list, tuple)) else (str(claims),)))
    return out


def calibration_targets(dirs: tuple[Path, ...] | None = None) -> dict[str, list[ParameterSource]]:
    """``"<paper>.<claim id>"`` -> the parameters chosen to produce that claim's outcome (kind ``chosen``)."""
    out: dict[str, list[ParameterSource]] = {}
    for src in parameter_sources(dirs):
        if src.kind == "chosen":
            for claim in src.claims:
                out.setdefault(claim, []).append(src)
    return out
