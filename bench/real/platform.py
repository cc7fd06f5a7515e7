"""The platform of a real data set: a registered platform name, or a TOML file with what the scored models use.

The window models of the real-data benchmark need the wheel radius and the track alone (``window_models(wheel_radius,
track)``), so a robot the testbed has no spec for is described by

    name = "my_robot"        # optional: the file's stem
    wheel_radius = 0.3       # [m] from its maker's configuration
    track = 0.9              # [m] wheel separation (centre to centre)

(or the same keys under ``[platform]``).  Any other field of a testbed platform is kept for the report; a key that
is none of these is refused (a misspelt ``wheelradius`` would otherwise be ignored).  Lengths may be given in cm or mm
with a suffixed key (``wheel_radius_cm``); they are converted to metres here, at the file boundary.  A registered
name (``husky``) or the path of a full testbed spec loads through :func:`bench.spec.load_platform`.
"""
from __future__ import annotations

import dataclasses
import difflib
import math
from pathlib import Path
from typing import Any

from bench.schema import read_toml
from bench.spec import Platform, SpecError, load_platform, to_dict

__all__ = ["kinematic_platform", "REQUIRED"]

REQUIRED = ("wheel_radius", "track")
_LENGTH_UNITS = {"": 1.0, "_m": 1.0, "_cm": 0.01, "_mm": 0.001}


def _length(doc: dict[str, Any], key: str, path: Path) -> float:
    given = [(k, f) for suffix, f in _LENGTH_UNITS.items() if (k := key + suffix) in doc]
    if not given:
        raise SpecError(path, key, None, f"required field is missing (a length in m; the kinematic models use "
                        f"{' and '.join(REQUIRED)})")
    if len(given) > 1:
        raise SpecError(path, key, [k for k, _ in given], "given more than once (in different units)")
    k, factor = given[0]
    v = doc[k]
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v <= 0:
        raise SpecError(path, k, v, "expected a finite length > 0")
    ok, expected = Platform._checks[key]  # a wheeled robot's range, the testbed Platform's own check
    if not ok(float(v) * factor):
        raise SpecError(path, k, v, f"expected a length {expected} (given in {k[len(key) + 1:] or 'm'})")
    return float(v) * factor


def kinematic_platform(spec: str | Path) -> dict[str, Any]:
    """``{"name", "wheel_radius", "track", ...}`` [m] of a platform name or TOML path (module docstring)."""
    path = Path(spec)
    if path.suffix.lower() != ".toml":
        return to_dict(load_platform(str(spec)))  # a registered name (SpecError names the choices)
    doc = read_toml(path, "platform file")
    if isinstance(doc.get("platform"), dict):
        doc = doc["platform"]
    lengths = {r + s for r in REQUIRED for s in _LENGTH_UNITS}  # wheel_radius, wheel_radius_cm, ..., track_mm
    known = {f.name for f in dataclasses.fields(Platform)} | {"name", "source", "sources"} | lengths
    for k, v in doc.items():  # a misspelt key would be silently ignored: refused, with the nearest known one
        if k not in known:
            near = difflib.get_close_matches(k, sorted(known), 1)
            raise SpecError(path, k, v, "unknown key (a platform file has name, wheel_radius, track and the testbed "
                            "platform's fields)" + (f"; did you mean {near[0]!r}?" if near else ""))
    out = {k: v for k, v in doc.items() if k not in lengths}
    for key in REQUIRED:
        out[key] = _length(doc, key, path)
    name = out.get("name", path.stem)
    if not isinstance(name, str) or not name.strip():
        raise SpecError(path, "name", name, "expected a non-empty name")
    out["name"] = name.strip()
    return out
