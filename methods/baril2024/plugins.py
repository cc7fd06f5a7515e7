"""Baril 2024 (DRIVE): the method plugin ``baril2024.blr_slip``, the slip-based BLR model.

On Runs (:meth:`BlrSlip.calibrate`, :meth:`BlrSlip.estimate`): the slip BLRs are fitted on the calibration runs'
reference poses (body velocity over each reference interval, SE(2) logarithm of the relative pose, minus the
interval's mean IDD velocity of the measured wheel speeds), and a run is dead-reckoned from its first reference
pose with ``v_IDD + E[s]`` at the encoder instants.  On the real-data benchmark's DRIVE windows
(:meth:`BlrSlip.window_models`): the rows ``baril2024_blr_slip`` (measured wheel speeds) and
``baril2024_blr_slip_cmd`` (commands through the powertrain), :mod:`methods.baril2024.windows`.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, ClassVar, Sequence

import numpy as np

from bench.registry import Estimate, make_estimate
from bench.run import Run, RunError
from bench import registry
from methods.baselines import dead_reckon, encoder_speeds, has_reference, held_integral, initial_pose, \
    platform_geometry, reference_poses
from methods.baril2024.slip_blr import BayesianLinearRegression, SlipBlr, Velocities, body_twist, idd_velocities

if TYPE_CHECKING:
    from bench.real.windows import WindowModel

PAPER = "Baril et al. 2024 (DRIVE)"
REFERENCE = frozenset({"ref_x", "ref_y", "ref_yaw"})


class NotCalibratedError(registry.NotCalibratedError):
    """``baril2024.blr_slip`` was asked to estimate before its slip regressions were fitted."""


def run_training_data(run: Run) -> tuple[Velocities, Velocities]:
    """(mean IDD velocities, reference body velocities) per reference interval of ``run`` lying within its encoder
    samples, each (n_intervals,)."""
    track, radius = platform_geometry(run)
    te, wl, wr = encoder_speeds(run)
    tr, x, y, yaw = reference_poses(run)
    body = body_twist(x, y, yaw, np.diff(tr))
    t0, t1 = tr[:-1], tr[1:]
    inside = (t0 >= te[0]) & (t1 <= te[-1])
    vx, vy, wz = idd_velocities(wl, wr, radius, track)
    dt = (t1 - t0)[inside]
    idd = tuple(held_integral(te, v, t0[inside], t1[inside]) / dt for v in (vx, vy, wz))
    return idd, tuple(b[inside] for b in body)  # type: ignore[return-value]


@dataclass(frozen=True)
class BlrSlip:
    """``baril2024.blr_slip``: ideal differential drive plus the BLR body slips of DRIVE (Baril et al. 2024)."""

    name: str = "baril2024.blr_slip"
    paper: str = PAPER
    requires: frozenset[str] = frozenset({"enc_wl", "enc_wr"})
    calibration_requires: ClassVar[frozenset[str]] = REFERENCE
    prior: BayesianLinearRegression = BayesianLinearRegression()
    slip: SlipBlr | None = field(default=None, compare=False, repr=False)

    def calibrate(self, runs: Sequence[Run]) -> "BlrSlip":
        parts = [run_training_data(r) for r in runs if has_reference(r)]
        if not parts:
            raise RunError(runs[0].where if runs else "<no runs>", "ref_x", None,
                           f"{self.name} calibrates on reference poses: no calibration run has two")
        idd = tuple(np.concatenate([p[0][i] for p in parts]) for i in range(3))
        body = tuple(np.concatenate([p[1][i] for p in parts]) for i in range(3))
        return dataclasses.replace(self, slip=SlipBlr.fit(idd, body, self.prior))  # type: ignore[arg-type]

    def estimate(self, run: Run) -> Estimate:
        if self.slip is None:
            raise NotCalibratedError(f"{self.name}: the slip regressions are not fitted; call calibrate(runs) first")
        track, radius = platform_geometry(run)
        t, wl, wr = encoder_speeds(run)
        vx, vy, wz = self.slip.body_velocity(idd_velocities(wl, wr, radius, track))
        pose0 = initial_pose(run)
        x, y, yaw = dead_reckon(t, vx, vy, wz, pose0)
        info = {"track": track, "wheel_radius": radius, "initial_pose": pose0, **self.slip.params()}
        return make_estimate(self.name, info, t=t, x=x, y=y, yaw=yaw, vx=vx, vy=vy, wz=wz)

    def window_models(self, wheel_radius: float, track: float) -> list[WindowModel]:
        """The real-data benchmark's rows ``baril2024_blr_slip`` and ``baril2024_blr_slip_cmd``."""
        from methods.baril2024.windows import BlrSlipCmdWindows, BlrSlipWindows

        return [BlrSlipWindows(wheel_radius, track, self.prior), BlrSlipCmdWindows(wheel_radius, track, self.prior)]
