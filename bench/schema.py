"""Strictly validated data: :func:`build` makes a frozen dataclass from a mapping (parsed TOML, or JSON
metadata), checking every key against the dataclass's fields, every value against its type hint and the
ranges of its ``_checks``; the few file fields in the papers' units (``*_deg``) are converted to SI.
Every problem raises :class:`SpecError` naming the file, the dotted field and the offending value.
Used for the specs of :mod:`bench.spec` and for the import mappings of :mod:`bench.formats`.
"""
from __future__ import annotations

import dataclasses
import math
import typing
from pathlib import Path
from typing import Any, Mapping

from bench.report.io import INF_STRINGS

__all__ = ["SpecError", "build", "read_toml"]


class SpecError(ValueError):
    """A spec file is malformed. The message names file, field and value."""

    def __init__(self, file: str | Path | None, fieldname: str, value: Any, expected: str):
        self.file, self.field, self.value, self.expected = str(file), fieldname, value, expected
        super().__init__(f"{file}: field '{fieldname}' = {value!r}: {expected}")



PA_PER_PSI = 6894.757293168361  # 1 psi = 1 lbf/in^2 (NIST SP 811)


def positive(x: float) -> bool:
    """A range check of the specs' ``_checks``: finite and > 0."""
    return x > 0 and math.isfinite(x)


def nonneg(x: float) -> bool:
    """A range check of the specs' ``_checks``: finite and >= 0."""
    return x >= 0 and math.isfinite(x)


_UNIT_FIELDS = {  # file field -> (dataclass field, converter)
    "slope_deg": ("slope", math.radians),
    "initial_yaw_deg": ("initial_yaw", math.radians),
    "soil_friction_angle_deg": ("soil_friction_angle", math.radians),
    "tire_pressure_psi": ("tire_pressure", lambda psi: psi * PA_PER_PSI),
}


def read_toml(path: Path, what: str = "file") -> dict[str, Any]:
    """A TOML file as a dict, or a one-line :class:`SpecError` naming it: not found (``what`` says which file was
    expected), malformed, or not UTF-8 (the spec, mapping, paper and kinematic-platform files all read through here)."""
    import tomllib

    path = Path(path)
    if not path.is_file():
        raise SpecError(path, "<file>", str(path), f"{what} not found")
    try:
        with open(path, "rb") as fh:
            return tomllib.load(fh)
    except tomllib.TOMLDecodeError as exc:
        raise SpecError(path, "<file>", str(path), f"malformed TOML: {exc}") from None
    except UnicodeDecodeError as exc:
        raise SpecError(path, "<file>", str(path), f"not UTF-8 text (TOML is UTF-8): byte {exc.start}") from None


def _json_inf(value: Any, tp: Any) -> Any:
    """A float field's "inf" / "-inf" (strict JSON has no infinity: bench.report.io.json_safe
    writes it as these strings, e.g. in runs_manifest.json) as the float; any other value as is."""
    if tp is float and isinstance(value, str):
        return INF_STRINGS.get(value.strip().lower(), value)
    return value


def _type_ok(value: Any, tp: Any) -> bool:
    if tp is float:
        return isinstance(value, (int, float)) and not isinstance(value, bool)
    if tp is int:
        return isinstance(value, int) and not isinstance(value, bool)
    if tp is str:
        return isinstance(value, str)
    if tp is bool:
        return isinstance(value, bool)
    return True


def _coerce(value: Any, tp: Any, file: Path | str, name: str) -> Any:
    convert = getattr(tp, "_from_spec", None)  # a type that converts its own file form (bench.sources.Sources)
    if convert is not None:
        return convert(value, file, name)
    origin = typing.get_origin(tp)
    if dataclasses.is_dataclass(tp):
        if not isinstance(value, Mapping):
            raise SpecError(file, name, value, f"expected a table for {tp.__name__}")
        return build(tp, value, file, name)
    if origin is tuple:
        args = typing.get_args(tp)
        if not isinstance(value, (list, tuple)):
            raise SpecError(file, name, value, "expected an array")
        inner = args[0]
        out = []
        for i, v in enumerate(value):
            iname = f"{name}[{i}]"
            if dataclasses.is_dataclass(inner):
                if isinstance(v, (list, tuple)):  # positional form: [t_end, a, b]
                    fnames = [f.name for f in dataclasses.fields(inner) if not f.name.startswith("_")]
                    if len(v) != len(fnames):
                        raise SpecError(file, iname, v, f"expected {len(fnames)} numbers {fnames}")
                    v = dict(zip(fnames, v))
                out.append(_coerce(v, inner, file, iname))
            elif typing.get_origin(inner) is tuple:
                out.append(_coerce(v, inner, file, iname))
            else:
                v = _json_inf(v, inner if inner is not Ellipsis else float)
                if not _type_ok(v, inner if inner is not Ellipsis else float):
                    raise SpecError(file, iname, v, f"expected {getattr(inner, '__name__', inner)}")
                out.append(float(v) if inner is float else v)
        return tuple(out)
    value = _json_inf(value, tp)
    if not _type_ok(value, tp):
        raise SpecError(file, name, value, f"expected {getattr(tp, '__name__', tp)}")
    if tp is float:
        value = float(value)
        if math.isnan(value):
            raise SpecError(file, name, value, "expected a number, not NaN")
    return value


def build(cls: type, data: Mapping[str, Any], file: Path | str = "<dict>", prefix: str = "") -> Any:
    """Build dataclass ``cls`` from a mapping, validating keys, types and ranges."""
    hints = typing.get_type_hints(cls)
    fields = {f.name: f for f in dataclasses.fields(cls) if not f.name.startswith("_")}
    kwargs: dict[str, Any] = {}
    given: dict[str, tuple[str, Any]] = {}  # dataclass field -> (the file's key, its value): errors name what was written
    for key, value in data.items():
        name = f"{prefix}.{key}" if prefix else key
        if key in _UNIT_FIELDS and _UNIT_FIELDS[key][0] in fields:
            target, conv = _UNIT_FIELDS[key]
            if not _type_ok(value, float):
                raise SpecError(file, name, value, "expected a number")
            kwargs[target] = conv(float(value))
            given[target] = (key, value)
            continue
        if key not in fields:
            raise SpecError(file, name, value, f"unknown key; allowed: {sorted(fields)}")
        kwargs[key] = _coerce(value, hints[key], file, name)
    missing = [
        n for n, f in fields.items()
        if n not in kwargs and f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING
    ]
    if missing:
        name = f"{prefix}.{missing[0]}" if prefix else missing[0]
        raise SpecError(file, name, None, "required field is missing")
    checks = getattr(cls, "_checks", {})
    for key, value in kwargs.items():
        file_key, file_value = given.get(key, (key, value))
        name = f"{prefix}.{file_key}" if prefix else file_key
        if key in checks:
            ok, expected = checks[key]
            if not ok(value):
                raise SpecError(file, name, file_value, f"expected {expected}"
                                + (f" (in SI: {key} = {value:.6g})" if file_key != key else ""))
        elif hints[key] is float and not math.isfinite(value) and not _inf_default(fields[key]):
            raise SpecError(file, name, file_value, "expected a finite number")
    obj = cls(**kwargs)
    whole = getattr(obj, "_check_whole", None)
    if whole is not None and (bad := whole()) is not None:
        raise SpecError(file, f"{prefix}.{bad[0]}" if prefix else bad[0], bad[1], f"expected {bad[2]}")
    return obj


def _inf_default(f: dataclasses.Field) -> bool:
    """A float field whose default is infinite (a limit: inf = none) may be set to infinity; any other may not."""
    return isinstance(f.default, float) and math.isinf(f.default)
