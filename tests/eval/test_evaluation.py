"""Trajectory errors against known paths; the relations metric, ATE and RPE (against evo and
the shared logs' published odometry scores)."""

from __future__ import annotations

import math
import re
import time

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from fuzzypos.eval import (
    ErrorStatistics,
    EvaluationError,
    absolute_trajectory_error,
    position_errors,
    relations_errors,
    relative_pose_error,
    trajectory_errors,
)
from fuzzypos.eval.metrics import align_se2, associate, distance_along, nearest_stamps
from fuzzypos.geometry import Pose2D, compose, inverse, relative
from fuzzypos.io.relations import Relations
from helpers import DATA


def test_distance_along_a_square() -> None:
    sq = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0, 0, 0]], float)
    np.testing.assert_allclose(distance_along(sq), [0, 1, 2, 3, 4])


def test_errors_of_a_shifted_and_turned_path() -> None:
    truth = np.column_stack([np.arange(5.0), np.zeros(5), np.zeros(5)])
    est = truth + np.array([0.0, 0.3, math.radians(2)])
    est[-1, 1] = 0.5
    d, h = position_errors(truth, est)
    np.testing.assert_allclose(d, [0.3, 0.3, 0.3, 0.3, 0.5])
    np.testing.assert_allclose(h, math.radians(2))
    e = trajectory_errors(truth, est, scans_degraded=3)
    assert e.final_position_error_m == pytest.approx(0.5)
    assert e.mean_position_error_m == pytest.approx(0.34)
    assert e.max_position_error_m == pytest.approx(0.5)
    assert e.mean_heading_error_deg == pytest.approx(2.0)
    assert e.as_dict()["scans_degraded"] == 3


def test_heading_error_wraps() -> None:
    t = np.array([[0, 0, math.pi - 0.01]])
    e = np.array([[0, 0, -math.pi + 0.01]])
    _, h = position_errors(t, e)
    assert h[0] == pytest.approx(0.02)


@pytest.mark.parametrize(
    ("truth", "est", "what"),
    [
        (np.zeros((3, 3)), np.zeros((4, 3)), "3 poses"),
        (np.zeros((3, 2)), np.zeros((3, 2)), "(n, 3)"),
        (np.zeros((3, 3)), np.full((3, 3), np.nan), "non-finite"),
        (np.zeros((0, 3)), np.zeros((0, 3)), "no poses"),
    ],
)
def test_bad_input(truth, est, what) -> None:
    with pytest.raises(EvaluationError, match=what.replace("(", r"\(").replace(")", r"\)")):
        trajectory_errors(truth, est)


# -- helpers -------------------------------------------------------------------------------
def walk(n: int, seed: int = 0) -> np.ndarray:
    """A random planar trajectory of n poses, mostly forward."""
    rng = np.random.default_rng(seed)
    steps = np.column_stack(
        [
            rng.uniform(0.0, 0.5, n),
            rng.normal(0.0, 0.05, n),
            rng.normal(0.0, 0.3, n),
        ]
    )
    poses = np.zeros((n, 3))
    for k in range(1, n):
        poses[k] = compose(poses[k - 1], steps[k])
    return poses


def relations_of(stamps: np.ndarray, poses: np.ndarray, pairs, errors=None) -> Relations:
    """Relations between the given pose index pairs whose error against ``poses`` is
    ``errors`` (k, 3): ``ref = est ⊕ ⊖d`` gives ``⊖ref ⊕ est = d``."""
    i, j = np.asarray(pairs).T
    est = relative(poses[i], poses[j])
    d = np.zeros_like(est) if errors is None else np.asarray(errors, float)
    return Relations(stamps[i], stamps[j], compose(est, inverse(d)))


poses_st = st.tuples(
    st.floats(-50, 50), st.floats(-50, 50), st.floats(-math.pi, math.pi, exclude_max=True)
)


# -- statistics ----------------------------------------------------------------------------
def test_error_statistics() -> None:
    s = ErrorStatistics.of([3.0, 4.0, 0.0, 1.0])
    assert s.count == 4
    assert s.mean == 2.0
    assert s.median == 2.0
    assert s.std == pytest.approx(math.sqrt(2.5))  # population std: ddof = 0
    assert s.rmse == pytest.approx(math.sqrt(26 / 4))
    assert (s.min, s.max) == (0.0, 4.0)
    empty = ErrorStatistics.of([])
    assert empty.count == 0 and math.isnan(empty.mean) and math.isnan(empty.std)


# -- matching by timestamp -----------------------------------------------------------------
def test_nearest_stamps_unsorted_ties_and_duplicates() -> None:
    stamps = np.array([5.0, 1.0, 3.0, 3.0, 0.0])
    idx, gap = nearest_stamps(stamps, [3.0, 2.0, 0.9, 4.0, 10.0, -1.0, 3.2])
    # 3.0 twice: the first given (index 2); 2.0 equally near 1 and 3: the earlier (1.0);
    # 4.0 equally near 3 and 5: the earlier (3.0, first duplicate)
    np.testing.assert_array_equal(idx, [2, 1, 1, 2, 0, 4, 2])
    np.testing.assert_allclose(gap, [0, 1, 0.1, 1, 5, 1, 0.2])


def test_associate_like_evo() -> None:
    ref = np.array([0.0, 1.0, 2.0, 3.0, 4.0])
    est = np.array([1.004, 3.0, 3.9, 0.02])  # fewer: the estimate drives, in its order
    ri, ei = associate(ref, est, max_stamp_gap=0.01)
    np.testing.assert_array_equal(ri, [1, 3])
    np.testing.assert_array_equal(ei, [0, 1])
    # swapped: the first one (4 stamps) drives, in its own order
    ri, ei = associate(est, ref, max_stamp_gap=0.2)
    np.testing.assert_array_equal(ri, [0, 1, 2, 3])
    np.testing.assert_array_equal(ei, [1, 3, 4, 0])
    with pytest.raises(EvaluationError, match="no reference and estimated stamps within"):
        associate(ref, ref + 0.5)


# -- the relations metric: analytic cases --------------------------------------------------
def test_relation_errors_by_hand() -> None:
    stamps = np.array([0.0, 1.0, 2.0])
    poses = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [2.2, 0.0, 0.0]])
    rel = Relations(
        np.array([0.0, 1.0, 0.0]),
        np.array([1.0, 2.0, 2.0]),
        np.array([[1.0, 0.0, 0.1], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0]]),
    )
    r = relations_errors(stamps, poses, rel)
    # est (1, 0, 0) against ref (1, 0, 0.1): ⊖ref ⊕ est = (0, 0, -0.1)
    np.testing.assert_allclose(r.translation_errors_m, [0.0, 0.2, 0.2], atol=1e-12)
    np.testing.assert_allclose(r.rotation_errors_deg, [math.degrees(0.1), 0, 0], atol=1e-12)
    assert r.all.matched == 3 and r.unmatched == 0
    assert r.all.translation_m.mean == pytest.approx(0.4 / 3)
    assert r.all.translation_m.median == pytest.approx(0.2)


def test_relation_errors_known_perturbations() -> None:
    rng = np.random.default_rng(3)
    poses = walk(60, seed=3)
    stamps = np.arange(60) * 0.5
    pairs = np.array([(k, k + 1) for k in range(0, 59, 2)] + [(0, 50), (5, 59), (10, 40)])
    d = np.column_stack(
        [
            rng.normal(0, 0.1, len(pairs)),
            rng.normal(0, 0.1, len(pairs)),
            rng.uniform(-3, 3, len(pairs)),
        ]
    )
    rel = relations_of(stamps, poses, pairs, d)
    r = relations_errors(stamps, poses, rel)
    trans = np.hypot(d[:, 0], d[:, 1])
    rot = np.degrees(np.abs(d[:, 2]))
    np.testing.assert_allclose(r.translation_errors_m, trans, atol=1e-9)
    np.testing.assert_allclose(r.rotation_errors_deg, rot, atol=1e-7)
    local = (stamps[pairs[:, 1]] - stamps[pairs[:, 0]]) <= 10.0
    assert r.local.matched == local.sum() == len(pairs) - 3
    assert r.local.translation_m.mean == pytest.approx(trans[local].mean())
    assert r.local.translation_m.std == pytest.approx(trans[local].std())
    assert r.local.rotation_deg.median == pytest.approx(np.median(rot[local]))
    assert r.all.rotation_deg.std == pytest.approx(rot.std())
    flat = r.as_dict()
    assert flat["all_matched"] == len(pairs)
    assert flat["local_trans_mean_m"] == pytest.approx(trans[local].mean())
    assert flat["all_rot_std_deg"] == pytest.approx(rot.std())
    assert "± " in r.format()


def test_unmatched_relations_are_counted_not_scored() -> None:
    poses = walk(10)
    stamps = np.arange(10.0)
    rel = Relations(
        np.array([0.0, 1.00005, 2.0, 3.0]),
        np.array([1.0, 2.0, 3.5, 25.0]),
        np.zeros((4, 3)),
    )
    r = relations_errors(stamps, poses, rel)  # default gap 1e-4 s
    np.testing.assert_array_equal(r.is_matched, [True, True, False, False])
    assert r.unmatched == 2 and r.unmatched_local == 1 and r.all.matched == 2
    assert r.local.matched == 2
    assert np.isnan(r.translation_errors_m[2:]).all()
    np.testing.assert_allclose(r.stamp_gap_s, [0, 5e-5, 0.5, 16], atol=1e-9)
    wide = relations_errors(stamps, poses, rel, max_stamp_gap=0.5)
    assert wide.unmatched == 1


def test_stamps_going_backwards_and_order_of_scans() -> None:
    """Nearest in time regardless of file order: shuffling the scans changes nothing."""
    poses = walk(40, seed=1)
    stamps = np.arange(40) * 0.1 + 1000.0
    pairs = [(k, k + 3) for k in range(0, 36, 2)]
    d = np.tile([0.01, -0.02, 0.003], (len(pairs), 1))
    rel = relations_of(stamps, poses, pairs, d)
    perm = np.random.default_rng(0).permutation(40)
    a = relations_errors(stamps, poses, rel)
    b = relations_errors(stamps[perm], poses[perm], rel)
    np.testing.assert_allclose(a.translation_errors_m, b.translation_errors_m, atol=1e-12)
    np.testing.assert_array_equal(perm[b.index1], a.index1)


def test_duplicate_stamps_take_the_first_pose() -> None:
    stamps = np.array([0.0, 1.0, 1.0])
    poses = np.array([[0.0, 0, 0], [1.0, 0, 0], [5.0, 0, 0]])
    rel = Relations(np.array([0.0]), np.array([1.0]), np.array([[1.0, 0, 0]]))
    r = relations_errors(stamps, poses, rel)
    assert r.index2[0] == 1 and r.translation_errors_m[0] == 0.0


@given(poses_st, st.integers(0, 1000))
def test_relations_errors_invariant_to_moving_the_estimate(g, seed) -> None:
    poses = walk(30, seed=seed % 7)
    stamps = np.arange(30.0)
    pairs = [(k, k + 1) for k in range(29)] + [(0, 29), (3, 17)]
    d = np.random.default_rng(seed).normal(0, 0.1, (len(pairs), 3))
    rel = relations_of(stamps, poses, pairs, d)
    a = relations_errors(stamps, poses, rel)
    b = relations_errors(stamps, compose(np.array(g), poses), rel)
    np.testing.assert_allclose(b.translation_errors_m, a.translation_errors_m, atol=1e-8)
    np.testing.assert_allclose(b.rotation_errors_deg, a.rotation_errors_deg, atol=1e-7)


@pytest.mark.parametrize(
    ("kwargs", "what"),
    [
        ({"stamps": np.arange(4.0)}, "got 4 stamps for 5 poses"),
        ({"stamps": np.array([0, 1, np.inf, 3, 4.0])}, "stamps holds non-finite"),
        ({"stamps": np.zeros((5, 1))}, r"stamps must be an \(n,\) array"),
        ({"poses": np.zeros((5, 2))}, r"poses must be an \(n, 3\) array"),
        ({"relations": np.zeros((3, 8))}, "relations must be a fuzzypos.io.relations.Relations"),
        ({"relations": Relations([], [], np.zeros((0, 3)))}, "no relations"),
        ({"relations": Relations([50.0], [51.0], np.zeros((1, 3)))}, "no relation matched"),
        ({"max_stamp_gap": -1.0}, "max_stamp_gap must be >= 0"),
        ({"local_max_dt": float("nan")}, "local_max_dt"),
        ({"stamps": np.zeros(0), "poses": np.zeros((0, 3))}, "no poses"),
    ],
)
def test_relations_bad_input(kwargs, what) -> None:
    args = {
        "stamps": np.arange(5.0),
        "poses": walk(5),
        "relations": Relations([0.0], [1.0], np.zeros((1, 3))),
    }
    args.update(kwargs)
    stamps, poses, rel = args.pop("stamps"), args.pop("poses"), args.pop("relations")
    with pytest.raises(EvaluationError, match=what):
        relations_errors(stamps, poses, rel, **args)


def test_pose2d_sequences_score_like_arrays() -> None:
    """``relations_errors(stamps, [est.pose …], rel)``: an Estimate's pose is a Pose2D."""
    stamps = np.arange(5.0)
    poses = walk(5)
    as_poses = [Pose2D.from_array(p) for p in poses]
    rel = Relations([0.0, 1.0], [2.0, 4.0], np.array([[1.0, 0.1, 0.2], [0.5, 0.0, -0.1]]))
    a, b = relations_errors(stamps, poses, rel), relations_errors(stamps, as_poses, rel)
    np.testing.assert_array_equal(b.translation_errors_m, a.translation_errors_m)
    np.testing.assert_array_equal(b.rotation_errors_deg, a.rotation_errors_deg)
    assert relations_errors(stamps, tuple(as_poses), rel).all.matched == 2
    truth = trajectory_errors(as_poses, poses)
    assert truth.final_position_error_m == 0.0
    ate = absolute_trajectory_error(stamps, as_poses, stamps, poses)
    assert ate.rmse_m == pytest.approx(0.0, abs=1e-12)


@pytest.mark.parametrize(
    ("poses", "what"),
    [
        (["a", "b", "c", "d", "e"], r"poses must be an \(n, 3\) array of poses .* or a sequence"),
        ([object()] * 5, r"sequence of Pose2D, got list"),
        (Pose2D(1.0, 2.0, 0.0), "got a single Pose2D"),
        ([Pose2D(), [0.0, 1.0]] * 2 + [Pose2D()], r"poses must be an \(n, 3\) array"),
        ({"x": 1}, r"poses must be an \(n, 3\) array"),
    ],
)
def test_poses_that_are_not_poses_are_evaluation_errors(poses, what) -> None:
    rel = Relations([0.0], [1.0], np.zeros((1, 3)))
    with pytest.raises(EvaluationError, match=what):
        relations_errors(np.arange(5.0), poses, rel)
    with pytest.raises(EvaluationError, match=r"stamps must be an \(n,\) array"):
        relations_errors([object()] * 5, walk(5), rel)


# -- ATE -----------------------------------------------------------------------------------
def test_align_se2_recovers_a_rigid_motion() -> None:
    pts = walk(20)[:, :2]
    T = np.array([1.5, -2.0, 2.5])
    moved = compose(T, np.column_stack([pts, np.zeros(20)]))[:, :2]
    np.testing.assert_allclose(align_se2(pts, moved), T, atol=1e-12)
    # collinear points are fine in 2D; one distinct point gives θ = 0
    line = np.column_stack([np.arange(5.0), np.zeros(5)])
    np.testing.assert_allclose(align_se2(line, line[:, ::-1]), [0, 0, math.pi / 2], atol=1e-12)
    np.testing.assert_allclose(align_se2(np.ones((3, 2)), np.zeros((3, 2))), [-1, -1, 0])


def test_ate_of_a_rigidly_moved_estimate_is_zero() -> None:
    ref = walk(50)
    stamps = np.arange(50) * 0.1
    est = compose(np.array([10.0, -3.0, 1.0]), ref)
    a = absolute_trajectory_error(stamps, ref, stamps, est)
    assert a.matched == 50
    assert a.rmse_m == pytest.approx(0.0, abs=1e-9)
    assert a.rotation_deg.max == pytest.approx(0.0, abs=1e-9)
    np.testing.assert_allclose(a.alignment, inverse(np.array([10.0, -3.0, 1.0])), atol=1e-9)
    raw = absolute_trajectory_error(stamps, ref, stamps, est, align=False)
    assert raw.rmse_m > 1.0 and raw.as_dict()["aligned"] is False


def test_ate_of_a_known_offset() -> None:
    ref = walk(40, seed=2)
    stamps = np.arange(40.0)
    est = ref.copy()
    est[:, 0] += 0.3  # without alignment: 0.3 m everywhere
    assert absolute_trajectory_error(stamps, ref, stamps, est, align=False).rmse_m == (
        pytest.approx(0.3)
    )
    # alternating ±0.2 m across the path: alignment cannot remove it (mean offset is 0)
    n = np.tile([1.0, -1.0], 20)
    est2 = ref.copy()
    est2[:, 0] += 0.2 * n * np.cos(ref[:, 2] + math.pi / 2)
    est2[:, 1] += 0.2 * n * np.sin(ref[:, 2] + math.pi / 2)
    a = absolute_trajectory_error(stamps, ref, stamps, est2)
    assert a.rmse_m == pytest.approx(0.2, rel=0.05)
    assert a.rmse_m <= 0.2 + 1e-12  # the optimum is never worse than the identity


@given(poses_st, st.integers(0, 1000))
def test_ate_invariant_to_moving_the_estimate(g, seed) -> None:
    rng = np.random.default_rng(seed)
    ref = walk(30, seed=seed % 5)
    est = ref + rng.normal(0, [0.2, 0.2, 0.05], ref.shape)
    stamps = np.arange(30.0)
    a = absolute_trajectory_error(stamps, ref, stamps, est)
    b = absolute_trajectory_error(stamps, ref, stamps, compose(np.array(g), est))
    assert b.rmse_m == pytest.approx(a.rmse_m, abs=1e-8)
    np.testing.assert_allclose(b.rotation_errors_deg, a.rotation_errors_deg, atol=1e-6)


# -- RPE -----------------------------------------------------------------------------------
def test_rpe_of_a_scaled_straight_line() -> None:
    n = 11
    ref = np.column_stack([np.arange(n) * 0.5, np.zeros(n), np.zeros(n)])
    est = ref * [1.2, 0, 0]  # each 0.5 m step is 0.6 m
    stamps = np.arange(n) * 0.1
    f1 = relative_pose_error(stamps, ref, stamps, est)
    assert f1.pairs == 10 and f1.delta_unit == "frames"
    np.testing.assert_allclose(f1.translation_errors_m, 0.1)
    np.testing.assert_array_equal(f1.ref_index[:2], [[0, 1], [1, 2]])
    f3 = relative_pose_error(stamps, ref, stamps, est, delta=3)
    np.testing.assert_array_equal(f3.ref_index[:, 0], [0, 3, 6])
    np.testing.assert_allclose(f3.translation_errors_m, 0.3)
    m1 = relative_pose_error(stamps, ref, stamps, est, delta=1.0, delta_unit="m")
    np.testing.assert_array_equal(m1.ref_index, [[0, 2], [2, 4], [4, 6], [6, 8], [8, 10]])
    np.testing.assert_allclose(m1.translation_errors_m, 0.2)
    # along the estimate's longer path 1 m is reached after 2 steps too (1.2 m) ...
    me = relative_pose_error(stamps, ref, stamps, est, delta=1.1, delta_unit="m")
    assert me.pairs == 3  # ... but 1.1 m along the reference takes 3 steps (1.5 m)
    me = relative_pose_error(
        stamps, ref, stamps, est, delta=1.1, delta_unit="m", pairs_from="estimate"
    )
    assert me.pairs == 5
    assert m1.as_dict()["trans_rmse_m"] == pytest.approx(0.2)


@given(poses_st, st.integers(0, 1000))
def test_rpe_invariant_to_moving_the_estimate(g, seed) -> None:
    rng = np.random.default_rng(seed)
    ref = walk(30, seed=seed % 5)
    est = ref + rng.normal(0, [0.2, 0.2, 0.05], ref.shape)
    stamps = np.arange(30.0)
    for kw in ({"delta": 1}, {"delta": 1.0, "delta_unit": "m", "pairs_from": "estimate"}):
        a = relative_pose_error(stamps, ref, stamps, est, **kw)
        b = relative_pose_error(stamps, ref, stamps, compose(np.array(g), est), **kw)
        np.testing.assert_array_equal(a.est_index, b.est_index)
        np.testing.assert_allclose(b.translation_errors_m, a.translation_errors_m, atol=1e-8)


@pytest.mark.parametrize(
    ("kwargs", "what"),
    [
        ({"delta": 0}, "delta must be a positive number"),
        ({"delta": 1.5}, "whole number"),
        ({"delta_unit": "s"}, "delta_unit must be 'frames' or 'm'"),
        ({"pairs_from": "both"}, "pairs_from must be"),
        ({"delta": 100}, "gives no pose pairs"),
        ({"delta": 1000.0, "delta_unit": "m"}, "gives no pose pairs"),
    ],
)
def test_rpe_bad_input(kwargs, what) -> None:
    ref = walk(10)
    with pytest.raises(EvaluationError, match=what):
        relative_pose_error(np.arange(10.0), ref, np.arange(10.0), ref, **kwargs)


def test_ate_bad_input() -> None:
    ref = walk(10)
    with pytest.raises(EvaluationError, match="got 9 est_stamps for 10 poses"):
        absolute_trajectory_error(np.arange(10.0), ref, np.arange(9.0), ref)
    with pytest.raises(EvaluationError, match="ref_poses holds non-finite"):
        absolute_trajectory_error(np.arange(10.0), ref * np.nan, np.arange(10.0), ref)
    with pytest.raises(EvaluationError, match="no reference and estimated stamps"):
        absolute_trajectory_error(np.arange(10.0), ref, np.arange(10.0) + 100, ref)


# -- against evo ---------------------------------------------------------------------------
def _evo_traj(stamps: np.ndarray, poses: np.ndarray):
    from evo.core.trajectory import PoseTrajectory3D

    n = poses.shape[0]
    xyz = np.column_stack([poses[:, :2], np.zeros(n)])
    half = poses[:, 2] / 2
    quat = np.column_stack([np.cos(half), np.zeros(n), np.zeros(n), np.sin(half)])
    return PoseTrajectory3D(positions_xyz=xyz, orientations_quat_wxyz=quat, timestamps=stamps)


@pytest.mark.parametrize("seed", range(8))
def test_ate_and_rpe_agree_with_evo(seed: int) -> None:
    pytest.importorskip("evo")
    import copy

    from evo.core import metrics, sync

    rng = np.random.default_rng(seed)
    n = int(rng.integers(30, 200))
    ref = walk(n, seed=seed)
    ref_stamps = np.cumsum(rng.uniform(0.05, 0.2, n))
    keep = rng.random(n) > 0.2  # the estimate lacks some poses, its stamps jitter
    est = ref + rng.normal(0, [0.1, 0.1, 0.05], ref.shape)
    est = compose(np.array([3.0, -2.0, 1.0]), est)[keep]
    est_stamps = ref_stamps[keep] + rng.uniform(-0.004, 0.004, keep.sum())
    if seed % 2:  # the estimate has more poses: then the reference drives the association
        noisy = compose(np.array([1.0, 2.0, 0.3]), ref + rng.normal(0, 0.1, ref.shape))
        ref, est, ref_stamps, est_stamps = ref[keep], noisy, ref_stamps[keep], ref_stamps

    tr, te = sync.associate_trajectories(
        _evo_traj(ref_stamps, ref), _evo_traj(est_stamps, est), max_diff=0.01
    )
    ate = absolute_trajectory_error(ref_stamps, ref, est_stamps, est)
    np.testing.assert_array_equal(ref_stamps[ate.ref_index], tr.timestamps)
    np.testing.assert_array_equal(est_stamps[ate.est_index], te.timestamps)
    te_aligned = copy.deepcopy(te)
    te_aligned.align(tr)
    for relation, ours in (
        (metrics.PoseRelation.translation_part, ate.translation_errors_m),
        (metrics.PoseRelation.rotation_angle_deg, ate.rotation_errors_deg),
    ):
        ape = metrics.APE(relation)
        ape.process_data((tr, te_aligned))
        np.testing.assert_allclose(ours, ape.error, atol=1e-9)
        assert ape.get_statistic(metrics.StatisticsType.rmse) == pytest.approx(
            (ate.translation_m if ours is ate.translation_errors_m else ate.rotation_deg).rmse,
            abs=1e-9,
        )
    for delta, unit, evo_unit in (
        (1, "frames", metrics.Unit.frames),
        (2, "frames", metrics.Unit.frames),
        (1.0, "m", metrics.Unit.meters),
    ):
        for pairs_from in ("reference", "estimate"):
            ours = relative_pose_error(
                ref_stamps,
                ref,
                est_stamps,
                est,
                delta=delta,
                delta_unit=unit,
                pairs_from=pairs_from,
            )
            for relation, errors, stats in (
                (
                    metrics.PoseRelation.translation_part,
                    ours.translation_errors_m,
                    ours.translation_m,
                ),
                (
                    metrics.PoseRelation.rotation_angle_deg,
                    ours.rotation_errors_deg,
                    ours.rotation_deg,
                ),
            ):
                rpe = metrics.RPE(
                    relation, delta, evo_unit, pairs_from_reference=pairs_from == "reference"
                )
                rpe.process_data((tr, te))
                np.testing.assert_allclose(errors, rpe.error, atol=1e-9)
                for name in ("rmse", "mean", "median", "std", "max"):
                    assert getattr(stats, name) == pytest.approx(
                        rpe.get_statistic(metrics.StatisticsType(name)), abs=1e-9
                    )


# -- the shared logs -----------------------------------------------------------------------
_ODOMETRY: dict[str, tuple[np.ndarray, np.ndarray, float]] = {}


def shared_odometry(name: str) -> tuple[np.ndarray, np.ndarray, float]:
    """Stamps (scan.stamp), raw odometry poses and the reading time of a shared log (cached)."""
    log = DATA / name / f"{name}.clf.gz"
    if not log.exists():
        pytest.skip(f"shared data {log} is absent")
    if name not in _ODOMETRY:
        from fuzzypos.io import read_carmen

        t0 = time.perf_counter()
        rows = [(r.scan.stamp, *r.odometry) for r in read_carmen(log)]
        a = np.array(rows)
        _ODOMETRY[name] = (a[:, 0], a[:, 1:], time.perf_counter() - t0)
    return _ODOMETRY[name]


# The data README's raw odometry scores, verbatim: all relations, local relations.
README_ODOMETRY = {
    "intel": ("7.37 ± 14.35 m / 39.2 ± 53.8°", "0.0235 ± 0.023 m / 1.50 ± 1.24°"),
    "aces": ("0.55 ± 2.67 m / 2.33 ± 6.50°", "0.037 ± 0.040 m / 0.87 ± 1.15°"),
}
SCAN_COUNTS = {"intel": (13631, 2984, 1770), "aces": (7374, 1279, 1178)}


def _printed(score: str) -> dict[str, str]:
    m = re.fullmatch(r"(\S+) ± (\S+) m / (\S+) ± (\S+)°", score)
    assert m, score
    return dict(zip(("trans_mean", "trans_std", "rot_mean", "rot_std"), m.groups()))


@pytest.mark.parametrize("name", ["intel", "aces"])
def test_raw_odometry_reproduces_the_readme_scores(name: str) -> None:
    from fuzzypos.io.relations import read_relations

    rel_path = DATA / name / f"{name}.relations"
    if not rel_path.exists():
        pytest.skip(f"shared data {rel_path} is absent")
    stamps, odometry, read_s = shared_odometry(name)
    t0 = time.perf_counter()
    rel = read_relations(rel_path)
    r = relations_errors(stamps, odometry, rel)
    score_s = time.perf_counter() - t0
    scans, relations, local = SCAN_COUNTS[name]
    assert stamps.size == scans
    assert r.relations == r.all.matched == relations and r.unmatched == 0
    assert r.local.matched == local
    assert r.stamp_gap_s.max() == 0.0  # relation stamps are scan stamps exactly
    for group, got, printed in zip(("all", "local"), (r.all, r.local), README_ODOMETRY[name]):
        values = {
            "trans_mean": got.translation_m.mean,
            "trans_std": got.translation_m.std,
            "rot_mean": got.rotation_deg.mean,
            "rot_std": got.rotation_deg.std,
        }
        for key, text in _printed(printed).items():
            decimals = len(text.split(".")[1])
            assert f"{values[key]:.{decimals}f}" == text, (name, group, key, values[key])
    print(
        f"\n{name}: read {read_s:.2f} s, relations + scoring {score_s * 1e3:.1f} ms\n{r.format()}"
    )
    assert score_s < 1.0  # vectorised: milliseconds


@pytest.mark.parametrize("name", ["intel", "aces"])
def test_keyframe_stamps_are_scan_stamps(name: str) -> None:
    """The shared keyframes.tum associate exactly with the log's scans: ATE of raw odometry
    against them is well defined (no oracle for its value)."""
    from fuzzypos.io import read_tum

    path = DATA / name / f"{name}.keyframes.tum"
    if not path.exists():
        pytest.skip(f"shared data {path} is absent")
    stamps, odometry, _ = shared_odometry(name)
    kf_stamps, kf_poses = read_tum(path)
    ri, ei = associate(kf_stamps, stamps, max_stamp_gap=1e-6)
    assert ri.size == kf_stamps.size
    np.testing.assert_array_equal(stamps[ei], kf_stamps[ri])
    ate = absolute_trajectory_error(kf_stamps, kf_poses, stamps, odometry)
    assert ate.matched == kf_stamps.size and np.isfinite(ate.rmse_m)
