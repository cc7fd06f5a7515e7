"""Mandow 2007 over seeds (methods/mandow2007/seeds.py): the 95 % half-widths in closed form, and the Sec. IV-C /
Fig. 6 metrics of the quick reproduction against their definitions (paired means, per-seed extremes)."""
from __future__ import annotations

import math

import pytest

from methods.mandow2007 import repro as MR
from methods.mandow2007.seeds import half_width, paired_statistics
from tests.methods.mandow2007.reproduction import quick_reproductions

T95_2DOF = 4.302652729911275  # Student t, 97.5 % quantile, 2 degrees of freedom


@pytest.fixture(scope="module")
def results(tmp_path_factory):
    return quick_reproductions(tmp_path_factory)


def test_half_width_is_the_student_t_interval():
    assert half_width([1.0, 2.0, 3.0]) == pytest.approx(T95_2DOF * 1.0 / math.sqrt(3), rel=1e-9)
    assert half_width([5.0, 5.0]) == 0.0
    assert math.isnan(half_width([1.0]))


def test_paired_statistics_use_the_paired_differences():
    # a - b is constant: the paired half-width is 0 although a and b themselves spread
    a, b, h = paired_statistics([1.0, 2.0, 3.0], [0.5, 1.5, 2.5])
    assert (a, b, h) == (2.0, 1.5, 0.0)
    a, b, h = paired_statistics([1.0, 2.0, 3.0], [0.0, 0.0, 0.0])
    assert h == pytest.approx(T95_2DOF / math.sqrt(3), rel=1e-9)


def test_indexes_follow_their_definitions(results):
    m = results[0]["mandow2007"].metrics
    keys = [f"{t}_{MR.SHORT[w]}" for t, w in MR.CONDITIONS]
    ys = [m[f"indexes.{k}_y_icr_v_mean"] for k in keys]
    assert m["indexes.y_icr_v_mean"] == pytest.approx(sum(ys) / 6, abs=1e-12)
    assert (m["indexes.y_icr_v_max"], m["indexes.y_icr_v_min"]) == (max(ys), min(ys))
    # a paired mean difference is the difference of the means
    assert m["indexes.chi_asphalt_minus_concrete_50psi"] == pytest.approx(
        m["indexes.asphalt_50psi_chi_mean"] - m["indexes.smooth_concrete_50psi_chi_mean"], abs=1e-12)
    # the mean of per-seed maxima is at least the largest mean (and the minimum likewise)
    pneu = [m[f"indexes.{k}_chi_mean"] for k in keys if not k.endswith("solid")]
    solid = [m[f"indexes.{k}_chi_mean"] for k in keys if k.endswith("solid")]
    assert m["indexes.pneumatic_max_chi"] >= max(pneu) - 1e-12
    assert m["indexes.solid_min_chi"] <= min(solid) + 1e-12
    assert m["indexes.e_abs_max"] == max(abs(m[f"indexes.{k}_e_mean"]) for k in keys)
    assert m["indexes.n_seeds"] == len(MR.SETTINGS.interval_seeds)
    for k in keys:  # every half-width is a number: every claim of Sec. IV-C is evaluated
        assert m[f"indexes.{k}_chi_half95"] >= 0.0


def test_validation_counts_the_conditions_won_beyond_the_interval(results):
    m = results[0]["mandow2007"].metrics
    k = "asphalt_20psi"
    a, b, h = (m[f"validation.{k}_{n}"] for n in ("asymmetric_path_rms_mean", "others_min_path_rms_mean",
                                                   "path_rms_half95"))
    assert b == min(m[f"validation.{k}_p3at_path_rms_mean"], m[f"validation.{k}_symmetric_path_rms_mean"])
    assert m[f"validation.{k}_asymmetric_best"] == float(a + h < b)
    won = [v for key, v in m.items() if key.endswith("_asymmetric_best") and key != "validation.n_asymmetric_best"]
    assert m["validation.n_asymmetric_best"] == sum(won)
    assert m["validation.n_validated"] == len(won) == 1  # quick mode validates the Table III condition only
