"""TUM trajectories (``timestamp tx ty tz qx qy qz qw``, one pose a line, ``#`` comments; the format
of the TUM RGB-D benchmark, read by evo): :func:`write_tum`, :func:`read_tum`, :func:`run_to_tum`.
Numbers are written as Python's repr (shortest exact text), so a float64 round-trips exactly.
"""
from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from bench.metrics import Trajectory
from bench.report.io import atomic_write_text
from bench.run import Run, RunError

__all__ = ["TUM_HEADER", "write_tum", "read_tum", "run_to_tum", "pose_rows"]

TUM_HEADER = "# timestamp tx ty tz qx qy qz qw"


_atomic_write_text = atomic_write_text  # one implementation: bench.report.io


def _tum_text(t: np.ndarray, xyz: np.ndarray, quat_xyzw: np.ndarray) -> str:
    mat = np.column_stack([t, xyz, quat_xyzw])
    fmt = " ".join(["%r"] * 8)  # repr: shortest text that round-trips a float64 exactly
    body = "\n".join(fmt % tuple(row) for row in mat.tolist())
    return f"{TUM_HEADER}\n{body}\n" if body else f"{TUM_HEADER}\n"


def write_tum(path: str | Path, t: Any, x: Any, y: Any, yaw: Any, z: Any = 0.0) -> Path:
    """Write a planar trajectory as TUM text (quaternion of a rotation ``yaw`` about z)."""
    t = np.asarray(t, float).reshape(-1)
    cols = {"x": x, "y": y, "yaw": yaw, "z": z}
    arr = {k: np.broadcast_to(np.asarray(v, float), t.shape) for k, v in cols.items()}
    for name, v in (("t", t), *arr.items()):
        bad = ~np.isfinite(v)
        if bad.any():
            i = int(np.flatnonzero(bad)[0])
            raise RunError(str(path), name, f"row {i}: {v[i]}", "TUM export needs finite values")
    half = 0.5 * arr["yaw"]
    quat = np.column_stack([np.zeros_like(t), np.zeros_like(t), np.sin(half), np.cos(half)])
    xyz = np.column_stack([arr["x"], arr["y"], arr["z"]])
    return _atomic_write_text(Path(path), _tum_text(t, xyz, quat))


def read_tum(path: str | Path) -> Trajectory:
    """Read a TUM file into a :class:`bench.metrics.Trajectory` (general 3-D rotations)."""
    from scipy.spatial.transform import Rotation

    path = Path(path)
    if not path.is_file():
        raise RunError(str(path), "<file>", str(path), "file not found")
    try:
        mat = np.loadtxt(path, comments="#", ndmin=2, dtype=float)
    except ValueError as exc:
        raise RunError(str(path), "<file>", str(exc).splitlines()[0].split(";")[0],
                       "TUM rows must be 8 numbers: timestamp tx ty tz qx qy qz qw") from None
    if mat.size == 0:
        raise RunError(str(path), "<file>", "empty", "a TUM file needs at least one pose")
    if mat.shape[1] != 8:
        raise RunError(str(path), "<file>", f"{mat.shape[1]} columns",
                       "TUM rows must be 8 numbers: timestamp tx ty tz qx qy qz qw")
    bad = ~np.isfinite(mat)
    if bad.any():
        r, c = (int(v) for v in np.argwhere(bad)[0])
        names = ("timestamp", "tx", "ty", "tz", "qx", "qy", "qz", "qw")
        raise RunError(str(path), names[c], f"pose {r}: {mat[r, c]}", "must be finite")
    qn = np.linalg.norm(mat[:, 4:], axis=1)
    off = np.abs(qn - 1.0) > 1e-6
    if off.any():
        r = int(np.flatnonzero(off)[0])
        raise RunError(str(path), "qx qy qz qw", f"pose {r}: norm {qn[r]}", "a unit quaternion")
    rot = Rotation.from_quat(mat[:, 4:]).as_matrix()
    return Trajectory(mat[:, 0], mat[:, 1:4], rot, name=path.stem)


def pose_rows(frame: Any, prefix: str, where: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(t, xyz, quat_xyzw) of the rows with a finite pose: ``{prefix}x, y, yaw`` and, when the columns exist,
    ``z`` (as the height change since the first pose) and ``roll``, ``pitch`` (the testbed's ZYX Euler angles,
    ``Rotation.from_euler("ZYX", [yaw, pitch, roll])``; 0 where absent)."""
    from scipy.spatial.transform import Rotation

    col = {k: np.asarray(frame[f"{prefix}{k}"], float) for k in ("x", "y", "yaw", "z", "roll", "pitch")
           if f"{prefix}{k}" in frame.columns}
    t = np.asarray(frame["t"], float)
    ok = np.isfinite(t) & np.isfinite(col["x"]) & np.isfinite(col["y"]) & np.isfinite(col["yaw"])
    for k in ("z", "roll", "pitch"):
        if k in col:
            ok &= np.isfinite(col[k])
    if not ok.any():
        raise RunError(where, f"{prefix}x/{prefix}y/{prefix}yaw", "no finite pose", "TUM export needs one pose at least")
    z = col["z"][ok] - col["z"][ok][0] if "z" in col else np.zeros(int(ok.sum()))
    euler = np.column_stack([col["yaw"][ok], *(col[k][ok] if k in col else np.zeros(int(ok.sum()))
                                               for k in ("pitch", "roll"))])
    quat = Rotation.from_euler("ZYX", euler).as_quat()  # x, y, z, w
    return t[ok], np.column_stack([col["x"][ok], col["y"][ok], z]), quat


def run_to_tum(run: Run | None, source: Any = "truth", path: str | Path | None = None) -> str | Path:
    """TUM export of a Run's ``truth``/``ref``/``gnss`` pose channels or of an Estimate (``source``).

    Truth and estimates are written in one frame: x, y as logged, z as the height change since the first pose
    (the truth logs the body origin's height, 0.085 m on the P3-AT at rest, an estimate starts at 0), and the full
    attitude where the channels have it (the truth's and Yi's EKF's roll and pitch; a planar estimate: yaw only).
    evo's APE on two exports of a planar run then equals the planar position error.

    Returns the written path when ``path`` is given, otherwise the TUM text."""
    if isinstance(source, str):
        if run is None:
            raise ValueError("run_to_tum: a pose source name needs a run")
        t, xyz, quat = pose_rows(run.data, f"{source}_", run.where)
    else:
        t, xyz, quat = pose_rows(source.data, "", str(path or getattr(source, "method", "estimate")))
    text = _tum_text(t, xyz, quat)
    return text if path is None else _atomic_write_text(Path(path), text)
