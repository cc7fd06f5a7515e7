"""From imported samples to a Run (shared by the CSV and the bag import): the strictly increasing
time check, a pose source's channels (gnss velocities in the world frame, truth velocities in the
body frame) and the finished Run, validated and checked for plausibility.
"""
from __future__ import annotations

from pathlib import Path
from typing import Any, Mapping

import numpy as np

from bench.formats.mapping import ImportMapping, _mapping_meta
from bench.formats.plausible import check_plausible
from bench.run import Run, RunError, from_arrays
from bench.spec import Platform, to_dict


def _check_time(where: str, name: str, t: np.ndarray, label: str = "line", base: int = 2) -> None:
    d = np.diff(t)
    if np.any(d <= 0):
        i = int(np.flatnonzero(d <= 0)[0])
        kind = "duplicated" if d[i] == 0 else "non-monotonic"
        raise RunError(where, name, f"{label} {i + 1 + base}: {float(t[i + 1])!r} after {float(t[i])!r}",
                       f"timestamps must increase strictly ({kind} timestamp)")


def _world_body(vx: np.ndarray, vy: np.ndarray, yaw: np.ndarray, to_world: bool) -> tuple[np.ndarray, np.ndarray]:
    c, s = np.cos(yaw), np.sin(yaw)
    if to_world:
        return c * vx - s * vy, s * vx + c * vy
    return c * vx + s * vy, -s * vx + c * vy


def _pose_channels(prefix: str, x: np.ndarray, y: np.ndarray, yaw: np.ndarray | None,
                   vx: np.ndarray | None, vy: np.ndarray | None, wz: np.ndarray | None,
                   vel_frame: str) -> dict[str, np.ndarray]:
    """Run channels of a pose source; gnss velocities are world-frame, truth velocities body."""
    out = {f"{prefix}_x": x, f"{prefix}_y": y}
    if yaw is not None:
        out[f"{prefix}_yaw"] = yaw
    if prefix == "ref":
        return out
    if vx is not None and vy is not None:
        want_world = prefix == "gnss"
        if (vel_frame == "world") != want_world:
            if yaw is None:
                raise ValueError("velocity frame conversion needs a yaw")
            vx, vy = _world_body(vx, vy, yaw, to_world=want_world)
        out[f"{prefix}_vx"], out[f"{prefix}_vy"] = vx, vy
    if wz is not None and prefix == "truth":
        out["truth_wz"] = wz
    return out

def _finish(cols: dict[str, np.ndarray], path: Path, mp: ImportMapping, platform: Platform | None,
            hints: Mapping[str, str], check: bool, extra_meta: Mapping[str, Any] | None = None) -> Run:
    meta: dict[str, Any] = {"run_id": mp.run_id or path.stem, "source_file": str(path),
                            "imported_from": path.name, "mapping": _mapping_meta(mp)}
    if platform is not None:
        meta["platform"] = to_dict(platform)
    meta.update(extra_meta or {})
    run = from_arrays(cols, meta)
    if len(cols) == 1:
        raise RunError(str(path), "<mapping>", mp.source_file or "<mapping>",
                       "the mapping names no channel to import")
    run.validate()
    if check and platform is not None:
        check_plausible(run, platform, hints, mp.platform.max_wheel_speed)
    return run
