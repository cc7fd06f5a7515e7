"""Mandow et al. 2007: experimental ICR kinematics of a wheeled skid-steer robot.

Citation
    A. Mandow, J. L. Martinez, J. Morales, J. L. Blanco, A. Garcia-Cerezo and J. Gonzalez,
    "Experimental kinematics for wheeled skid-steer mobile robots", in Proc. IEEE/RSJ Int. Conf. on
    Intelligent Robots and Systems (IROS), San Diego, CA, USA, 2007, pp. 1222-1227.

Axes: Mandow's local frame has Y forward and X lateral to the RIGHT; the suite's body frame x forward,
y left.  :class:`IcrParams` keeps Mandow's names and signs (Table I typed in as printed) and converts at the
boundary: ``y_l = -x_ICRl``, ``y_r = -x_ICRr``, ``x_icr = y_ICRv`` (:mod:`methods.mandow2007.kinematics`).

Paper equation -> code
  (2)-(5)   tread ICRs from velocities ............ kinematics.IcrParams (fields), IcrParams.body_icr
  (6)-(7)   kinematic matrix A(K) ................. kinematics.kinematic_matrix, kinematics.body_velocities,
                                                    kinematics.dead_reckoning (eq. (6) integrated)
  (8)       symmetric model ....................... kinematics.IcrParams.symmetric
  (9)       steering efficiency chi ............... kinematics.steering_efficiency
  (10)      eccentricity e ........................ kinematics.eccentricity
  (11)      x_ICR from a pure rotation ............ symmetric.identify_symmetric (symmetric.run_travel,
                                                    symmetric.run_kind picks the runs)
  (12)      alpha from a straight line ............ symmetric.identify_symmetric
  (13)      segment cost J(K) ..................... segments.build_segments, segments.segment_increments,
                                                    segments.segment_cost, segments.segment_errors
                                                    (J(K) in C: _cost.c; segments.segment_cost_numpy its reference)
  Sec. III  GA, 8-bit genes, 40-bit chromosome .... ga.identify_ga (pygad), ga.decode_chromosomes,
                                                    ga.GeneRanges, ga.GaSettings
            second optimiser (not in the paper) ... ga.identify_de (scipy differential_evolution),
                                                    ga.DeSettings, ga.compare_optimisers
  (14)-(15) P3-AT server Ticksmm / Revcount ....... p3at.p3at_server_parameters, p3at.p3at_symmetric_model
  (16)-(17) control inputs V_l, V_r ............... not implemented (motion control, not estimation)
  Sec. IV-B default P3-AT model ................... p3at.P3AT_DEFAULT (alpha = 1, x_ICR = 0.3 m)
  Tables I, II (published parameters) ............. p3at.TABLE_I, p3at.TABLE_II
  Tables I-III, Fig. 6 on the testbed ............. repro (table1, table2, table3, table3_conditions)
  Sec. IV-C, Fig. 6 over seeds (95 % intervals) ... seeds (indexes, validation)
  (6)-(7) with (13) on real DRIVE windows ......... windows.AsymmetricICR (end-pose least squares)

Implementation choices the paper leaves open (documented, configurable)
    * Eq. (11) is written without alpha; the consistent form with eq. (3) is the default
      (:mod:`methods.mandow2007.symmetric`, ``alpha_in_eq11``).
    * Segments of eq. (13) are cut at every reference sample; ``segment_period`` merges them
      (:mod:`methods.mandow2007.segments`).
    * Gene ranges and the bit code are not published (:mod:`methods.mandow2007.ga`: ranges
      :meth:`GeneRanges.for_track`, Gray code by default).

Plugins (:mod:`methods.mandow2007.plugins`): ``mandow2007.default_p3at`` (:class:`DefaultP3at`),
``mandow2007.symmetric`` (:class:`Symmetric`), ``mandow2007.asymmetric_ga`` (:class:`AsymmetricGa`),
``mandow2007.asymmetric_de`` (:class:`AsymmetricDe`); the last two offer the real-data window model
``mandow2007_icr`` (``window_models``, :mod:`methods.mandow2007.windows`).
"""
from methods.mandow2007.ga import (
    GENE_BITS,
    DeSettings,
    GaSettings,
    GeneRanges,
    Identification,
    compare_optimisers,
    decode_chromosomes,
    identify_de,
    identify_ga,
)
from methods.mandow2007.kinematics import (
    PARAM_NAMES,
    IcrParams,
    body_velocities,
    dead_reckoning,
    eccentricity,
    kinematic_matrix,
    steering_efficiency,
)
from methods.mandow2007.p3at import (
    P3AT_DEFAULT,
    P3AT_ENCODER_GEAR,
    TABLE_I,
    TABLE_II,
    p3at_server_parameters,
    p3at_symmetric_model,
)
from methods.mandow2007.plugins import (
    PAPER,
    AsymmetricDe,
    AsymmetricGa,
    DefaultP3at,
    NotCalibratedError,
    Symmetric,
)
from methods.mandow2007.segments import (
    CalibrationDataError,
    Segments,
    build_segments,
    segment_cost,
    segment_errors,
    segment_increments,
)
from methods.mandow2007.symmetric import (
    RunTravel,
    SymmetricIdentification,
    identify_symmetric,
    run_kind,
    run_travel,
)

__all__ = [
    "GENE_BITS", "DeSettings", "GaSettings", "GeneRanges", "Identification", "compare_optimisers",
    "decode_chromosomes", "identify_de", "identify_ga", "PARAM_NAMES", "IcrParams", "body_velocities",
    "dead_reckoning", "eccentricity", "kinematic_matrix", "steering_efficiency", "P3AT_DEFAULT",
    "P3AT_ENCODER_GEAR", "TABLE_I", "TABLE_II", "p3at_server_parameters", "p3at_symmetric_model", "PAPER",
    "AsymmetricDe", "AsymmetricGa", "DefaultP3at", "NotCalibratedError", "Symmetric", "CalibrationDataError",
    "Segments", "build_segments", "segment_cost", "segment_errors", "segment_increments", "RunTravel",
    "SymmetricIdentification", "identify_symmetric", "run_kind", "run_travel",
]
