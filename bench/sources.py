"""Where every platform and terrain parameter comes from: the ``[sources]`` table of each file.

Every parameter of ``scenarios/platforms/*.toml`` and ``scenarios/terrains/*.toml`` (every key but the
descriptive ``name`` and ``source``; nested tables by dotted key) names its source::

    [sources]
    mu_sa = {kind = "paper", ref = "Yu 2010 Table II (vinyl)"}
    shear_modulus = {kind = "chosen", ref = "K = 3 mm gives the trend of Wang 2015 Table 3",
                     claims = ["wang2015.chi_decreases"]}
    "motor.max_power" = {kind = "chosen", ref = "...", claims = ["yu2010.ramps_testbed"]}

Kinds (:data:`SOURCE_KINDS`): ``paper`` (a physical quantity a paper measured or gives: table / section),
``datasheet`` (a maker's data sheet, named), ``calibration`` (an unscored calibration run, named), ``real``
(real data, the file named), ``testbed`` (a testbed choice with no outcome in view: why), ``chosen``
(chosen to produce a claimed outcome: ``claims`` lists them as ``"<paper>.<claim id>"``; each becomes a
calibration target, :mod:`bench.reproduce.sources`).  A field the file does not set takes the dataclass
default, whose source is :data:`DEFAULT_REFS` (kind ``testbed``); a field ``--set`` changes gets kind
``override``.  A scenario file's ``[platform_overrides]`` / ``[terrain_overrides]`` are parameters too: each leaf
names its source in the scenario's own ``[sources]`` table under ``"platform.<key>"`` / ``"terrain.<key>"``
(:func:`override_sources`; same kinds, ``chosen`` with its claims), which the merged platform / terrain then carry::

    [terrain_overrides]
    roughness_gd0 = 256e-6
    [sources]
    "terrain.roughness_gd0" = {kind = "testbed", ref = "ISO 8608 class C, chosen before any run"}

:func:`file_sources` checks a file: a parameter without a source, a source without a parameter, an
unknown kind, a ``chosen`` source without claims is a one-line :class:`~bench.schema.SpecError` naming
the file, the field and its value.  :class:`Sources` is the read-only mapping field -> :class:`Source`
that a :class:`~bench.spec.Platform` / :class:`~bench.spec.Terrain` keeps (not part of its equality,
hash or :func:`~bench.spec.to_dict`: a source is provenance, not physics).
"""
from __future__ import annotations

import dataclasses
import difflib
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Iterable, Iterator, Mapping

from bench.schema import _UNIT_FIELDS, SpecError

__all__ = ["SOURCE_KINDS", "OVERRIDE", "DESCRIPTIVE", "DEFAULT_REFS", "Source", "Sources", "parameters",
           "file_sources", "override_sources", "default_sources"]

SOURCE_KINDS = ("paper", "datasheet", "calibration", "real", "testbed", "chosen")
#: the kinds whose value the testbed chose, and which may name an alternative for the sensitivity study
ALTERNATIVE_KINDS = ("chosen", "testbed")
OVERRIDE = "override"  # set by a scenario's overrides or --set; never written in a platform / terrain file
DESCRIPTIVE = ("name", "source")  # file keys that describe, not parameterise
_CLAIM = re.compile(r"^[a-z][a-z0-9_]*\.[A-Za-z0-9_]+$")
_ENTRY_KEYS = ("kind", "ref", "claims", "alternative", "alternative_ref")

# sources of the dataclass defaults (a field the file does not set); kind "testbed"
DEFAULT_REFS: dict[str, str] = {
    "wheel_width": "default b = 0.05 m (Yu 2010 Table II)",
    "patch_length": "default Yu L = 0.31 m (Table II)",
    "patch_gap": "default Yu C = 0.24 m (Table II)",
    "cg_offset_x": "default 0: centre of mass at the geometric centre (Yu 2010 Sec. III, Wang 2015 assumption 1)",
    "cg_offset_y": "default 0: centre of mass at the geometric centre (Yu 2010 Sec. III, Wang 2015 assumption 1)",
    "wheel_radius_scale_l": "default 1: effective rolling radius = nominal",
    "wheel_radius_scale_r": "default 1: effective rolling radius = nominal",
    "actuator_delay": "default 0: no command delay modelled",
    "command_gain_sum": "default 1: the robot applies the command as given",
    "command_gain_diff": "default 1: the robot applies the command as given",
    "command_limit_mean": "default inf: no command limit",
    "command_limit_diff": "default inf: no command limit",
    "command_accel_mean": "default inf: no command acceleration limit",
    "command_accel_diff": "default inf: no command acceleration limit",
    "wheel_speed_limit": "default inf: no wheel-speed limit",
    "payload": "default 0: no payload",
    "tire_pressure": "default 0: no tire contact model (patch (L - C)/2 of Yu 2010 Table II, nominal radius)",
    "tire_modulus": "default 0: no tire contact model (patch (L - C)/2 of Yu 2010 Table II, nominal radius)",
    "tire_rolling_resistance": "default 0: the terrain's rolling resistance alone",
    "motor.controller_loss": "default 0: ideal motor controller (no voltage loss)",
    "motor.max_power": "default 0: no power limit beyond the current limit",
    "motor.gear_efficiency": "default 1: lossless gearbox (Yu 2010 models no gear loss)",
    "sensors.encoder.scale_error_l": "default 0: exact encoder scale",
    "sensors.encoder.scale_error_r": "default 0: exact encoder scale",
    "sensors.encoder.latency": "default 0: wheel speeds reported when counted",
    "sensors.imu.accel_noise": "default 0.02 m/s^2 per sample: generic MEMS IMU, not from a paper",
    "sensors.imu.gyro_noise": "default 0.002 rad/s per sample: generic MEMS IMU, not from a paper",
    "sensors.imu.accel_bias_walk": "default 1e-4 m/s^2/sqrt(s): generic MEMS IMU, not from a paper",
    "sensors.imu.gyro_bias_walk": "default 1e-5 rad/s/sqrt(s): generic MEMS IMU, not from a paper",
    "sensors.imu.gyro_bias_z": "default 0: no constant gyro bias",
    "sensors.imu.gyro_scale_z": "default 1: gyro z axis as the body's, exact gain",
    "sensors.imu.yaw_misalignment": "default 0: IMU axes along the body's",
    "sensors.imu.lever_x": "default 0: IMU at the centre of mass",
    "sensors.imu.lever_y": "default 0: IMU at the centre of mass",
    "sensors.imu.saturation_accel": "default 80 m/s^2: never reached by these robots",
    "sensors.imu.saturation_gyro": "default 8 rad/s: never reached by these robots",
    "mu_lat_ratio": "default 1: isotropic friction (Yu 2010 eq. (7): one mu per wheel)",
    "shear_modulus_lat_ratio": "default 1: isotropic shear (Yu 2010 eq. (7): one K per wheel)",
    "slope": "default 0: flat ground",
    "slip_velocity_eps": "default 0.02 m/s: numerical smoothing of the Coulomb sign() and floor of the "
                         "rolled-distance speed of the Janosi law (bench.sim.tire), no outcome in view",
    "friction_patches": "default none: uniform ground",
    "friction_speed_decay": "default 0: friction independent of the sliding speed (Yu 2010 eq. (7), Coulomb)",
    "powertrain_tau_l": "default 0: no lag beyond the PID and the DC motor (the first-order lag of DRIVE's model off)",
    "powertrain_tau_r": "default 0: no lag beyond the PID and the DC motor (the first-order lag of DRIVE's model off)",
    "sensors.gnss.rate_hz": "default 5 Hz: a common GNSS fix rate, not from a paper (Liu's and Mandow's set theirs)",
    "sensors.gnss.pos_noise": "default 0.02 m per fix: a generic RTK-class receiver, not from a paper",
    "sensors.gnss.vel_noise": "default 0.02 m/s per fix: a generic RTK-class receiver, not from a paper",
    "sensors.gnss.yaw_noise": "default 0.01 rad per fix: a generic dual-antenna heading, not from a paper",
    "sensors.gnss.drift_walk": "default 0: no drift of the GNSS position",
    "sensors.gnss.initial_drift": "default 0: no drift of the GNSS position",
    "sensors.gnss.drift_tau": "default 30 s: the drift's correlation time, unused while the drift is 0",
    "sensors.gnss.dropout_prob": "default 0: no dropped GNSS fixes",
    "sensors.gnss.outages": "default none: no GNSS outage",
    "roughness_gd0": "default 0: flat ground, no ISO 8608 roughness",
    "roughness_spacing": "default 0.1 m: the height field's grid, unused while roughness_gd0 = 0",
    "roughness_length_x": "default 51.2 m: the height field's extent, unused while roughness_gd0 = 0",
    "roughness_length_y": "default 51.2 m: the height field's extent, unused while roughness_gd0 = 0",
    "roughness_centre_x": "default 0: the height field's centre, unused while roughness_gd0 = 0",
    "roughness_centre_y": "default 0: the height field's centre, unused while roughness_gd0 = 0",
    "roughness_seed": "default 0: the height field's draw, unused while roughness_gd0 = 0",
    "soil_model": "default 'rigid': a firm surface, no Bekker-Wong sinkage or compaction resistance",
    "soil_n": "default 1: unused with the rigid soil model",
    "soil_k_c": "default 0: unused with the rigid soil model",
    "soil_k_phi": "default 0: unused with the rigid soil model",
    "soil_cohesion": "default 0: unused with the rigid soil model",
    "soil_friction_angle": "default 0: unused with the rigid soil model",
}


@dataclass(frozen=True)
class Source:
    """Where a parameter's value comes from.  A ``chosen`` one names the ``claims`` it was chosen for.  A ``chosen`` or
    ``testbed`` one (a value the testbed chose, not measured) may name an ``alternative`` value (as the file writes it,
    with ``alternative_ref``: why that one) that the sensitivity study (:mod:`bench.reproduce.sensitivity`) runs the
    papers at, to show which verdicts the choice decides."""

    kind: str
    ref: str
    claims: tuple[str, ...] = ()
    alternative: Any = None
    alternative_ref: str = ""


class Sources(Mapping[str, Source]):
    """Read-only mapping dotted field -> :class:`Source` (immutable, so copies are the object itself)."""

    __slots__ = ("_d",)

    def __init__(self, entries: Mapping[str, Source] | Iterable[tuple[str, Source]] = ()):
        self._d = dict(entries)

    def __getitem__(self, key: str) -> Source:
        return self._d[key]

    def __iter__(self) -> Iterator[str]:
        return iter(self._d)

    def __len__(self) -> int:
        return len(self._d)

    def __hash__(self) -> int:
        return hash(tuple(sorted(self._d.items())))

    def __repr__(self) -> str:
        return f"Sources({len(self._d)} fields)"

    def __copy__(self) -> "Sources":
        return self

    def __deepcopy__(self, memo: dict) -> "Sources":
        return self

    def __reduce__(self) -> tuple:
        return Sources, (tuple(self._d.items()),)

    def chosen(self) -> dict[str, Source]:
        """The fields chosen to produce a claimed outcome."""
        return {k: s for k, s in self._d.items() if s.kind == "chosen"}

    def overridden(self, keys: Iterable[str], ref: str) -> "Sources":
        """A copy with ``keys`` (and every field under a key that names a table) of kind ``override``."""
        d = dict(self._d)
        for key in map(_field_name, keys):
            under = [k for k in d if k.startswith(key + ".")]
            for k in under or [key]:
                d[k] = Source(OVERRIDE, ref)
        return Sources(d)

    def sourced(self, given: Mapping[str, Source]) -> "Sources":
        """A copy with the fields of ``given`` (file keys, e.g. ``slope_deg``) taking those sources."""
        return Sources({**self._d, **{_field_name(k): v for k, v in given.items()}})

    @classmethod
    def _from_spec(cls, value: Any, file: Path | str, name: str) -> "Sources":
        """:func:`bench.schema.build`'s conversion: a Sources, or a table as in a file (nested or dotted keys),
        kinds checked (``override`` allowed here: merged scenario data carries it)."""
        if isinstance(value, Sources):
            return value
        if not isinstance(value, Mapping):
            raise SpecError(file, name, value, "expected a table of sources")
        out = {}
        for key, entry in _entries(value):
            out[_field_name(key)] = _source(entry, file, f"{name}.{key}", entry, (*SOURCE_KINDS, OVERRIDE))
        return cls(out)


def _field_name(key: str) -> str:
    """File key -> dataclass field (``slope_deg`` -> ``slope``, as :func:`bench.schema.build` converts it)."""
    head, _, last = key.rpartition(".")
    if last in _UNIT_FIELDS:
        last = _UNIT_FIELDS[last][0]
    return f"{head}.{last}" if head else last


def _entries(table: Mapping[str, Any], prefix: str = "") -> Iterator[tuple[str, Any]]:
    """(dotted key, entry) of a [sources] table; a sub-table without ``kind`` nests ([sources.motor]), as does one
    whose ``kind`` is itself a table (the source of a field named ``kind``, written as an unquoted dotted key:
    ``platform.sensors.reference.kind = {kind = ..., ref = ...}``)."""
    for key, val in table.items():
        entry = isinstance(val, Mapping) and "kind" in val and not isinstance(val["kind"], Mapping)
        if isinstance(val, Source) or entry or not isinstance(val, Mapping):
            yield prefix + key, val
        else:
            yield from _entries(val, f"{prefix}{key}.")


def _source(entry: Any, file: Path | str, field: str, value: Any, kinds: tuple[str, ...]) -> Source:
    """One entry as a Source; a malformed entry raises SpecError(file, field, value, why).  ``value`` is the
    parameter's value (its type is the alternative's), or the entry itself when the value is not at hand."""
    typed = value is not entry
    if isinstance(entry, Source):
        entry = dataclasses.asdict(entry)
    if not isinstance(entry, Mapping):
        raise SpecError(file, field, value, "source must be a table {kind = ..., ref = ...}")
    extra = sorted(set(entry) - set(_ENTRY_KEYS))
    if extra:
        raise SpecError(file, field, value, f"source has unknown key(s) {extra}; allowed: {list(_ENTRY_KEYS)}")
    kind, ref, claims = entry.get("kind"), entry.get("ref"), entry.get("claims", ())
    if kind not in kinds:
        raise SpecError(file, field, value, f"source kind {kind!r} is not one of {'|'.join(kinds)}")
    if not isinstance(ref, str) or not ref.strip():
        raise SpecError(file, field, value, f"source of kind {kind!r} needs a ref (where the number comes from)")
    if not isinstance(claims, (list, tuple)) or not all(isinstance(c, str) and _CLAIM.match(c) for c in claims):
        raise SpecError(file, field, value, f"source claims {claims!r} must be a list of \"<paper>.<claim id>\"")
    if kind == "chosen" and not claims:
        raise SpecError(file, field, value, "a 'chosen' source lists the claims it was chosen for "
                                            "(claims = [\"<paper>.<claim id>\"])")
    if kind != "chosen" and claims:
        raise SpecError(file, field, value, f"only a 'chosen' source lists claims (kind is {kind!r})")
    alt, alt_ref = entry.get("alternative"), entry.get("alternative_ref", "")
    if alt is not None or alt_ref:
        if kind not in ALTERNATIVE_KINDS:
            raise SpecError(file, field, value, f"only a 'chosen' or 'testbed' source names an alternative (kind is "
                                                f"{kind!r})")
        if not isinstance(alt_ref, str) or not alt_ref.strip() or alt is None:
            raise SpecError(file, field, value, "an alternative needs both alternative = <value> and "
                                                "alternative_ref = \"why this value\"")
        number = (int, float)
        if isinstance(value, bool) or isinstance(alt, bool):  # bool is an int to Python, not to a spec
            same = isinstance(value, bool) and isinstance(alt, bool)
        elif isinstance(value, number):
            same = isinstance(alt, number)
        else:
            same = type(alt) is type(value)
        if typed and not same:
            raise SpecError(file, field, alt, f"the alternative must be a value of the parameter's type "
                                              f"({type(value).__name__})")
    return Source(kind, ref.strip(), tuple(claims), alt, alt_ref.strip() if isinstance(alt_ref, str) else "")


def parameters(data: Mapping[str, Any], prefix: str = "") -> Iterator[tuple[str, Any]]:
    """(dotted key, value) of every parameter of a platform / terrain file: every leaf but ``name``,
    ``source`` and ``[sources]``; an array (outages, friction patches) is one parameter."""
    for key, val in data.items():
        if not prefix and key in (*DESCRIPTIVE, "sources"):
            continue
        if isinstance(val, Mapping):
            yield from parameters(val, f"{prefix}{key}.")
        else:
            yield prefix + key, val


def file_sources(data: Mapping[str, Any], file: Path | str) -> dict[str, Source]:
    """The checked sources of one platform / terrain file (keys as the file writes them): every parameter
    has one, every source names a parameter of the file."""
    raw = data.get("sources", {})
    if not isinstance(raw, Mapping):
        raise SpecError(file, "sources", raw, "expected a [sources] table")
    params = dict(parameters(data))
    if params and "sources" not in data:
        raise SpecError(file, "sources", None, "a testbed spec names the source of every parameter in a [sources] "
                        "table (copy one of scenarios/platforms/ or terrains/); a TOML with wheel_radius and track "
                        "alone serves `skidbench real` only")
    entries = dict(_entries(raw))
    for key, entry in entries.items():
        if key not in params:
            # most often a parameter's name misspelt above its [sources] entry: name that parameter, not the entry
            unsourced = [k for k in params if k not in entries]
            near = difflib.get_close_matches(key, unsourced, n=1, cutoff=0.6)
            if near:
                raise SpecError(file, near[0], params[near[0]], f"its [sources] entry is named {key}: one of the two "
                                "names is misspelt")
            raise SpecError(file, f"sources.{key}", entry.get("kind") if isinstance(entry, Mapping) else entry,
                            "a source for a parameter the file does not set")
    out = {}
    for key, value in params.items():
        if key not in entries:
            raise SpecError(file, key, value, f"no source: add {key} = {{kind = ..., ref = ...}} to [sources] "
                                              f"(kind {'|'.join(SOURCE_KINDS)})")
        out[key] = _source(entries[key], file, key, value, SOURCE_KINDS)
    return out


def override_sources(data: Mapping[str, Any], file: Path | str) -> dict[str, Source]:
    """The checked sources of a scenario file's overrides (keys ``"platform.<key>"`` / ``"terrain.<key>"`` as the
    file writes them): every leaf of ``[platform_overrides]`` / ``[terrain_overrides]`` has one in the scenario's
    ``[sources]``, and every source there names such a leaf."""
    raw = data.get("sources", {})
    if not isinstance(raw, Mapping):
        raise SpecError(file, "sources", raw, "expected a [sources] table")
    params = {f"{part}.{key}": value for part in ("platform", "terrain")
              for key, value in parameters(data.get(f"{part}_overrides") or {})}
    entries = dict(_entries(raw))
    for key, entry in entries.items():
        if key not in params:
            raise SpecError(file, f"sources.{key}", entry, "a source for no [platform_overrides] / "
                                                           "[terrain_overrides] entry of this scenario")
    out = {}
    for key, value in params.items():
        part, _, rest = key.partition(".")
        if key not in entries:
            raise SpecError(file, f"{part}_overrides.{rest}", value, f"no source: add \"{key}\" = {{kind = ..., "
                                                                     f"ref = ...}} to [sources] (kind {'|'.join(SOURCE_KINDS)})")
        out[key] = _source(entries[key], file, key, value, SOURCE_KINDS)
    return out


def default_sources(cls: type, present: Iterable[str], prefix: str = "") -> dict[str, Source]:
    """Sources of the fields of dataclass ``cls`` (nested dataclasses by dotted key) that ``present``
    (dataclass field names, dotted) does not set: the default's :data:`DEFAULT_REFS` entry."""
    present = set(present)
    out: dict[str, Source] = {}
    for f in dataclasses.fields(cls):
        if f.name.startswith("_") or (not prefix and f.name in (*DESCRIPTIVE, "sources")):
            continue
        key = prefix + f.name
        default = f.default_factory() if f.default_factory is not dataclasses.MISSING else f.default
        if dataclasses.is_dataclass(default):
            out.update(default_sources(type(default), present, key + "."))
        elif key not in present:
            ref = DEFAULT_REFS.get(key) or f"default {default!r} of bench.spec.{cls.__name__}.{f.name}"
            out[key] = Source("testbed", ref)
    return out
