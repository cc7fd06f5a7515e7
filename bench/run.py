"""Run: the recorded log of one experiment (arrays + metadata), Parquet I/O, content hash.

Columns (DESIGN.md), SI units, one row per log tick; a sensor sampled slower than the log rate
has NaN between its samples:

    t, cmd_wl, cmd_wr, enc_wl, enc_wr, tau_l, tau_r, i_l, i_r,
    imu_ax, imu_ay, imu_az, imu_gx, imu_gy, imu_gz,
    gnss_x, gnss_y, gnss_vx, gnss_vy, gnss_yaw, ref_x, ref_y, ref_yaw,
    truth_* (x, y, z, yaw, pitch, roll, vx, vy, wz, wl, wr, slip_l, slip_r, y_l, y_r, x_icr, ...)

``truth_*`` columns may be read only by metrics: :meth:`Run.without_truth` gives the view a
method sees.  A Run round-trips through Parquet bit-for-bit (float64 columns, metadata as JSON
in the schema).
"""
from __future__ import annotations

import hashlib
import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Iterable, Mapping

import numpy as np
import pandas as pd

SENSOR_CHANNELS = (
    "cmd_wl", "cmd_wr", "enc_wl", "enc_wr", "tau_l", "tau_r", "i_l", "i_r",
    "imu_ax", "imu_ay", "imu_az", "imu_gx", "imu_gy", "imu_gz",
    "gnss_x", "gnss_y", "gnss_vx", "gnss_vy", "gnss_yaw", "ref_x", "ref_y", "ref_yaw",
)
TRUTH_PREFIX = "truth_"
META_KEY = b"skidbench"


class RunError(ValueError):
    """A log is unusable. The message names the file (or run id), the column and the value."""

    def __init__(self, where: str, column: str, value: Any, expected: str):
        self.where, self.column, self.value, self.expected = where, column, value, expected
        super().__init__(f"{where}: column '{column}' = {value!r}: {expected}")


@dataclass(frozen=True)
class Run:
    """One logged run. ``data`` is a DataFrame with a float64 column per channel."""

    data: pd.DataFrame
    meta: Mapping[str, Any] = field(default_factory=dict)

    # ------------------------------------------------------------------ access
    @property
    def id(self) -> str:
        return str(self.meta.get("run_id", self.meta.get("scenario", "run")))

    @property
    def t(self) -> np.ndarray:
        return self.data["t"].to_numpy()

    @property
    def channels(self) -> frozenset[str]:
        return frozenset(self.data.columns)

    def __getitem__(self, name: str) -> np.ndarray:
        if name not in self.data.columns:
            raise RunError(self.where, name, None, f"missing channel; the run has {sorted(self.data.columns)}")
        return self.data[name].to_numpy()

    def has(self, name: str) -> bool:
        return name in self.data.columns and bool(np.isfinite(self.data[name].to_numpy()).any())

    @property
    def where(self) -> str:
        return str(self.meta.get("source_file") or self.meta.get("run_id") or "run")

    def samples(self, name: str) -> tuple[np.ndarray, np.ndarray]:
        """(t, values) at the rows where channel ``name`` has a sample (finite)."""
        v = self[name]
        m = np.isfinite(v)
        return self.t[m], v[m]

    def without_truth(self) -> "Run":
        """The view a method may read: every ``truth_*`` column withheld."""
        cols = [c for c in self.data.columns if not c.startswith(TRUTH_PREFIX)]
        return Run(self.data[cols], dict(self.meta, truth_withheld=True))

    def truth(self) -> pd.DataFrame:
        cols = ["t"] + [c for c in self.data.columns if c.startswith(TRUTH_PREFIX)]
        return self.data[cols]

    def require(self, channels: Iterable[str], who: str = "method") -> None:
        """Raise :class:`RunError` naming the first missing or empty channel ``who`` needs."""
        for c in sorted(channels):
            if c not in self.data.columns:
                raise RunError(self.where, c, None, f"missing channel required by {who}")
            if not np.isfinite(self.data[c].to_numpy()).any():
                raise RunError(self.where, c, "all NaN", f"channel required by {who} has no sample")

    def validate(self) -> "Run":
        """Check time and values: raises :class:`RunError` on the first problem found."""
        if "t" not in self.data.columns:
            raise RunError(self.where, "t", None, "missing time column")
        t = self.t
        if t.size == 0:
            raise RunError(self.where, "t", "empty", "a run needs at least one sample")
        if not np.all(np.isfinite(t)):
            i = int(np.flatnonzero(~np.isfinite(t))[0])
            raise RunError(self.where, "t", f"row {i}: {t[i]}", "time must be finite")
        d = np.diff(t)
        if np.any(d <= 0):
            i = int(np.flatnonzero(d <= 0)[0])
            raise RunError(
                self.where, "t", f"row {i + 1}: {float(t[i + 1])!r} after {float(t[i])!r}",
                "time must increase strictly (non-monotonic or duplicated timestamp)",
            )
        for c in self.data.columns:
            v = self.data[c].to_numpy()
            if np.isinf(v).any():
                i = int(np.flatnonzero(np.isinf(v))[0])
                raise RunError(self.where, c, f"row {i}: {v[i]}", "value must be finite (inf found)")
        return self

    # ------------------------------------------------------------------ identity
    def content_hash(self) -> str:
        """SHA-256 of the column names, the raw float64 bytes and the metadata (minus volatile keys)."""
        h = hashlib.sha256()
        for c in self.data.columns:
            h.update(c.encode())
            v = self.data[c].to_numpy(dtype=np.float64)
            v = np.where(np.isnan(v), np.nan, v)  # one canonical NaN: payload/sign bits are not data
            h.update(np.ascontiguousarray(v).tobytes())
        meta = {k: v for k, v in self.meta.items() if k not in ("source_file", "truth_withheld")}
        h.update(json.dumps(meta, sort_keys=True, default=str).encode())
        return h.hexdigest()

    # ------------------------------------------------------------------ I/O
    def to_parquet(self, path: str | Path) -> Path:
        """Write atomically (temp file + rename) so an interrupted write leaves nothing behind."""
        import pyarrow as pa
        import pyarrow.parquet as pq

        from bench.report.io import atomic_path

        table = pa.Table.from_pandas(self.data.astype(np.float64), preserve_index=False)
        meta = {k: v for k, v in self.meta.items() if k != "source_file"}
        schema_meta = dict(table.schema.metadata or {})
        schema_meta.pop(b"pandas", None)  # pandas metadata carries versions: keep files byte-stable
        schema_meta[META_KEY] = json.dumps(meta, sort_keys=True, default=str).encode()
        table = table.replace_schema_metadata(schema_meta)
        with atomic_path(path) as tmp:
            pq.write_table(table, tmp, compression="zstd", write_statistics=False)
        return Path(path)

    @classmethod
    def from_parquet(cls, path: str | Path) -> "Run":
        import pyarrow as pa
        import pyarrow.parquet as pq

        path = Path(path)
        if not path.is_file():
            raise RunError(str(path), "<file>", str(path), "file not found")
        try:
            table = pq.read_table(path)
        except (pa.ArrowInvalid, OSError) as exc:
            raise RunError(str(path), "<file>", str(path), f"not a readable Parquet file ({exc})") from None
        raw = (table.schema.metadata or {}).get(META_KEY)
        try:
            meta = json.loads(raw) if raw else {}
        except (json.JSONDecodeError, UnicodeDecodeError) as exc:
            raise RunError(str(path), "<metadata>", raw[:40], f"run metadata is not JSON ({exc})") from None
        if not isinstance(meta, dict):
            raise RunError(str(path), "<metadata>", type(meta).__name__, "run metadata must be a JSON object")
        meta["source_file"] = str(path)
        data = table.to_pandas()
        for c in data.columns:  # pandas' test: numpy's issubdtype raises on pandas' string / nullable dtypes
            if not pd.api.types.is_numeric_dtype(data[c]) or pd.api.types.is_bool_dtype(data[c]):
                raise RunError(str(path), c, str(data[c].dtype), "expected a numeric column")
        return cls(data.astype(np.float64), meta)


def from_arrays(columns: Mapping[str, np.ndarray], meta: Mapping[str, Any] | None = None) -> Run:
    """Build a Run from a mapping of equal-length arrays (``t`` first)."""
    df = pd.DataFrame({k: np.asarray(v, dtype=np.float64) for k, v in columns.items()})
    return Run(df, dict(meta or {}))


def wrap_angle(a: np.ndarray | float) -> np.ndarray | float:
    """Wrap to [-pi, pi)."""
    return (np.asarray(a) + np.pi) % (2 * np.pi) - np.pi


def sensor_spec(run: Run, sensor: str, key: str) -> Any:
    """``meta.platform.sensors.<sensor>.<key>`` of a run as stored (None when the platform, the sensor or the key
    is absent); for error messages that name the value found."""
    plat = run.meta.get("platform")
    sensors = plat.get("sensors") if isinstance(plat, Mapping) else None
    spec = sensors.get(sensor) if isinstance(sensors, Mapping) else None
    return spec.get(key) if isinstance(spec, Mapping) else None


def sensor_spec_value(run: Run, sensor: str, key: str) -> float | None:
    """:func:`sensor_spec` as a float; None when absent or not a finite number (a bool is not a number here).
    Callers judge the sign."""
    v = sensor_spec(run, sensor, key)
    if not isinstance(v, (int, float)) or isinstance(v, bool) or not math.isfinite(v):
        return None
    return float(v)


def encoder_count_speed(run: Run) -> float | None:
    """One encoder count per sample as a wheel speed [rad/s]: 2 pi / counts_per_rev x rate_hz
    (``meta.platform.sensors.encoder``), the quantum of a count-difference speed; None when either value is
    absent or not > 0."""
    cpr, rate = sensor_spec_value(run, "encoder", "counts_per_rev"), sensor_spec_value(run, "encoder", "rate_hz")
    if cpr is None or rate is None or cpr <= 0 or rate <= 0:
        return None
    return 2.0 * math.pi * rate / cpr


def reference_position_noise(run: Run) -> float:
    """Standard deviation [m] of the run's reference-sensor position (``meta.platform.sensors.reference.
    pos_noise``), which noise identifications subtract from their residuals.  A run without it (e.g. an
    imported log whose mapping gives none) is an error, not a silently perfect reference."""
    sig = sensor_spec_value(run, "reference", "pos_noise")
    if sig is None or sig < 0:
        raise RunError(run.where, "meta platform.sensors.reference.pos_noise",
                       sensor_spec(run, "reference", "pos_noise"),
                       "the reference sensor's position noise [m] (finite, >= 0) is needed to identify noise "
                       "against it; give it in the platform spec or the import mapping")
    return float(sig)
