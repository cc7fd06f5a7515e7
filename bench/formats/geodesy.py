"""GNSS fixes (sensor_msgs/NavSatFix: WGS-84 latitude, longitude, ellipsoidal height) to local east/north metres
about a datum, with ``pymap3d.geodetic2enu`` on the WGS-84 ellipsoid (its exact geodetic -> ECEF -> ENU rotation,
not a flat-earth approximation); and, from the ENU track of the fixes, a world-frame velocity and the course over
ground, for the mapping's ``velocity = "fix_difference"`` / ``heading = "course"``.

Angles are radians and lengths metres here; degrees exist only in the bag's messages and the mapping's ``[datum]``
(converted by :mod:`bench.formats.bag` as they are read).

* The datum: the mapping's ``[datum]`` (:class:`~bench.formats.mapping.DatumMap`), else the first fix (by time)
  with status >= STATUS_FIX of the NavSatFix topics, one datum for all of them, so that two GNSS topics (e.g. a
  receiver as ``gnss`` and an RTK one as ``reference``) share one frame.  A fix without altitude (NaN, as the
  message allows) is placed at the datum's altitude: the horizontal position then moves by (height error /
  6.4e6) of its distance from the datum (1.6 mm at 1 km for 10 m).
* Fixes must lie within :data:`MAX_DATUM_DISTANCE` of the datum: the local ENU plane is a robot's test area, and a
  fix 100 km away is a wrong datum (latitude and longitude swapped, a sign lost) more often than a long drive.
* Velocity: ``numpy.gradient`` of east and north over the fix times (second order on uneven spacing, one-sided at
  the ends).  Its noise is about sqrt(2) pos_noise / (2 dt) (RTK 2 cm at 5 Hz: 0.07 m/s; a 2 m standalone fix
  makes it useless).  Course: atan2(v_north, v_east), CCW from east (the Run's yaw), where the speed is at least
  ``course_min_speed`` (none at rest); it is the body's heading only when driving forward without side slip
  (reversing gives heading + pi).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from bench.formats.mapping import DatumMap
from bench.run import RunError
from bench.spec import SpecError

__all__ = ["STATUS_NO_FIX", "STATUS_FIX", "COVARIANCE_TYPE_UNKNOWN", "MAX_DATUM_DISTANCE", "Datum", "mapping_datum",
           "choose_datum", "check_fix_range", "geodetic_to_enu", "check_near_datum", "track_velocity", "course"]

STATUS_NO_FIX = -1  # sensor_msgs/NavSatStatus: unable to fix position
STATUS_FIX = 0  # unaugmented fix (SBAS 1, GBAS 2: better)
COVARIANCE_TYPE_UNKNOWN = 0  # sensor_msgs/NavSatFix.position_covariance_type: no covariance given
MAX_DATUM_DISTANCE = 100e3  # [m] farthest fix from the datum accepted


@dataclass(frozen=True)
class Datum:
    """Origin of the local ENU frame: latitude, longitude [rad] and height above the WGS-84 ellipsoid [m]."""

    latitude: float
    longitude: float
    altitude: float
    source: str  # "mapping" or "first fix of <topic>"

    def as_meta(self) -> dict[str, Any]:
        """In the mapping's units (deg, deg, m), for the Run's metadata."""
        return {"latitude_deg": math.degrees(self.latitude), "longitude_deg": math.degrees(self.longitude),
                "altitude": self.altitude, "source": self.source}


def mapping_datum(dm: DatumMap, file: str) -> Datum | None:
    """The mapping's ``[datum]`` in radians (altitude NaN when not given), None when left out; a SpecError
    naming ``datum.<key>`` when only part of it is given or a value is out of range (mappings built in Python
    skip the TOML checks)."""
    if not dm.used:
        return None
    for key in ("latitude_deg", "longitude_deg"):
        if math.isnan(getattr(dm, key)):
            raise SpecError(file, f"datum.{key}", None, "the datum needs latitude_deg and longitude_deg "
                                                        "(or no [datum] section: the first fix)")
    for key, (ok, expected) in DatumMap._checks.items():
        value = getattr(dm, key)
        if not (key == "altitude" and math.isnan(value)) and not ok(value):
            raise SpecError(file, f"datum.{key}", value, f"expected {expected}")
    return Datum(math.radians(dm.latitude_deg), math.radians(dm.longitude_deg), dm.altitude, "mapping")


def choose_datum(given: Datum | None, first_fixes: list[tuple[int, str, float, float, float]]) -> Datum:
    """The datum: ``given`` (its NaN altitude the earliest first fix's), else the earliest of ``first_fixes``
    ((stamp_ns, topic, lat, lon [rad], alt [m]) of each NavSatFix topic's first usable fix); a NaN altitude is 0."""
    first = min(first_fixes)
    alt = first[4] if math.isfinite(first[4]) else 0.0
    if given is not None:
        return given if math.isfinite(given.altitude) else Datum(given.latitude, given.longitude, alt, given.source)
    return Datum(first[2], first[3], alt, f"first fix of {first[1]}")


def check_fix_range(where: str, topic: str, lat: np.ndarray, lon: np.ndarray) -> None:
    """RunError naming the first message whose latitude is outside [-pi/2, pi/2] or longitude outside [-pi, pi]
    (given in the message's degrees); NaN (a dropped sample) passes."""
    for name, v, lim in (("latitude", lat, math.pi / 2), ("longitude", lon, math.pi)):
        bad = np.flatnonzero(np.abs(v) > lim)
        if bad.size:
            i = int(bad[0])
            raise RunError(where, f"{topic} {name}", f"message {i}: {math.degrees(v[i])!r} deg",
                           f"a WGS-84 {name} in [-{math.degrees(lim):g}, {math.degrees(lim):g}] deg")


def geodetic_to_enu(lat: np.ndarray, lon: np.ndarray, alt: np.ndarray, datum: Datum
                    ) -> tuple[np.ndarray, np.ndarray]:
    """East, north [m] of fixes (lat, lon [rad], alt [m]; NaN alt = the datum's) about ``datum`` (WGS-84)."""
    import pymap3d

    alt = np.where(np.isfinite(alt), alt, datum.altitude)
    e, n, _ = pymap3d.geodetic2enu(np.asarray(lat, float), np.asarray(lon, float), alt, datum.latitude,
                                   datum.longitude, datum.altitude, ell=pymap3d.Ellipsoid.from_name("wgs84"),
                                   deg=False)
    return np.asarray(e, float), np.asarray(n, float)


def check_near_datum(where: str, topic: str, east: np.ndarray, north: np.ndarray, datum: Datum) -> None:
    """RunError naming the first fix farther than :data:`MAX_DATUM_DISTANCE` from the datum."""
    d = np.hypot(east, north)
    far = np.flatnonzero(d > MAX_DATUM_DISTANCE)
    if far.size:
        i = int(far[0])
        m = datum.as_meta()
        raise RunError(where, f"{topic} latitude/longitude", f"message {i}: {d[i] / 1e3:.1f} km from the datum "
                       f"({m['latitude_deg']:.6f}, {m['longitude_deg']:.6f} deg, {m['source']})",
                       f"fixes within {MAX_DATUM_DISTANCE / 1e3:g} km of the datum (a local ENU frame); "
                       "check [datum] (latitude and longitude swapped? a sign?)")


def track_velocity(t: np.ndarray, east: np.ndarray, north: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """World-frame velocity (v_east, v_north) [m/s] at the fixes from their ENU track (``numpy.gradient`` over
    the times ``t`` [s] of the finite fixes); NaN where a fix is NaN, all NaN with fewer than two fixes."""
    ve, vn = np.full(t.size, np.nan), np.full(t.size, np.nan)
    ok = np.isfinite(east) & np.isfinite(north)
    if ok.sum() >= 2:
        ve[ok], vn[ok] = np.gradient(east[ok], t[ok]), np.gradient(north[ok], t[ok])
    return ve, vn


def course(ve: np.ndarray, vn: np.ndarray, min_speed: float) -> np.ndarray:
    """Course over ground [rad], CCW from east, in (-pi, pi]; NaN where the speed is below ``min_speed``."""
    with np.errstate(invalid="ignore"):
        moving = np.hypot(ve, vn) >= min_speed
    return np.where(moving, np.arctan2(vn, ve), np.nan)
