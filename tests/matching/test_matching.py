"""Tests of pairing (§3.7), the pose from two pairs (§4, eq. 19–22) and fusion (eq. 23–24).

Frames (SPEC step 9): unprimed points p are scan k's, primed points q scan k+1's, and the
transform sought is the increment u_k with p = T(u_k)·q. Each test builds its pairs from a
known rigid transform, so the answer is known exactly; the literal 4×4 system of eq. 22 and a
brute-force scipy least squares are the independent oracles.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import assume, given
from hypothesis import strategies as st
from scipy.optimize import least_squares

from fuzzypos import matching as M
from fuzzypos.config import FusionConfig
from fuzzypos.features import ANGULAR_POINT, BREAK_POINT, VIRTUAL_ANGULAR_POINT, FeaturePoints
from fuzzypos.geometry import inverse, transform_points, wrap_angle

ATOL = 1e-9


def angle_diff(a: float, b: float) -> float:
    return abs(float(wrap_angle(a - b)))


def eq22_matrix(q1: np.ndarray, q2: np.ndarray) -> np.ndarray:
    """The literal 4×4 matrix of eq. 21–22 (primed points)."""
    return np.array(
        [
            [q1[0], -q1[1], 1.0, 0.0],
            [q1[1], q1[0], 0.0, 1.0],
            [q2[0], -q2[1], 1.0, 0.0],
            [q2[1], q2[0], 0.0, 1.0],
        ]
    )


def eq22_solve(p1, p2, q1, q2) -> np.ndarray:
    """(cos θ, sin θ, a, b) by np.linalg.solve of eq. 22."""
    return np.linalg.solve(eq22_matrix(q1, q2), np.concatenate([p1, p2]))


def make_pairs(prev: np.ndarray, curr: np.ndarray, unc: np.ndarray | None = None) -> M.Pairs:
    m = len(prev)
    if unc is None:
        unc = np.zeros((m, 2))
    idx = np.arange(m, dtype=np.int64)
    prev, curr = np.asarray(prev, float), np.asarray(curr, float)
    return M.Pairs(idx, idx, prev, curr, np.asarray(unc, float))


def rigid_pairs(pose: np.ndarray, curr: np.ndarray, unc: np.ndarray | None = None) -> M.Pairs:
    """Pairs with p = T(pose)·q exactly."""
    return make_pairs(transform_points(pose, curr), curr, unc)


coord = st.floats(-10.0, 10.0, allow_nan=False)
point = st.tuples(coord, coord).map(np.array)
theta = st.floats(-math.pi, math.pi, exclude_min=True, exclude_max=True)
shift = st.floats(-3.5, 3.5)  # |t| <= 3.5·√2 < 5


# ---------------------------------------------------------------------------------------------
# eq. 19–22: the pose from two pairs
# ---------------------------------------------------------------------------------------------
@given(theta, shift, shift, point, point)
def test_two_pairs_recover_a_rigid_transform(th: float, a: float, b: float, q1, q2) -> None:
    assume(np.linalg.norm(q1 - q2) >= 0.5)
    pose = np.array([a, b, th])
    p1, p2 = transform_points(pose, q1), transform_points(pose, q2)
    got, valid = M.poses_from_two_pairs(p1[None], p2[None], q1[None], q2[None], 0.3)
    assert valid.tolist() == [True]
    assert got.shape == (1, 3)
    assert got[0, 0] == pytest.approx(a, abs=ATOL)
    assert got[0, 1] == pytest.approx(b, abs=ATOL)
    assert angle_diff(got[0, 2], th) < ATOL
    assert -math.pi <= got[0, 2] <= math.pi
    # the literal 4×4 solve of eq. 22 says the same
    c, s, a22, b22 = eq22_solve(p1, p2, q1, q2)
    assert math.hypot(c, s) == pytest.approx(1.0, abs=1e-9)  # rigid: already on the circle
    assert angle_diff(math.atan2(s, c), got[0, 2]) < ATOL
    assert a22 == pytest.approx(got[0, 0], abs=ATOL) and b22 == pytest.approx(got[0, 1], abs=ATOL)


@given(point, point, point, point)
def test_two_pairs_agree_with_the_literal_eq22_on_inconsistent_points(p1, p2, q1, q2) -> None:
    """Points that no rigid motion relates (|p1 − p2| ≠ |q1 − q2|): eq. 22 gives a similarity;
    after normalising (cos θ, sin θ) the angle is the same, and (a, b) is recomputed with that
    rotation so the two residuals cancel (the translation that best fits both points)."""
    assume(np.linalg.norm(q1 - q2) >= 0.5 and np.linalg.norm(p1 - p2) >= 0.5)
    got, valid = M.poses_from_two_pairs(p1[None], p2[None], q1[None], q2[None], 0.3)
    assert valid[0]
    c, s, _, _ = eq22_solve(p1, p2, q1, q2)
    assert angle_diff(math.atan2(s, c), got[0, 2]) < 1e-9
    r1 = p1 - transform_points(got[0], q1)
    r2 = p2 - transform_points(got[0], q2)
    np.testing.assert_allclose(r1 + r2, 0.0, atol=1e-9)


def test_eq22_determinant_is_minus_the_squared_separation() -> None:
    """SPEC step 9: det = ±|q1 − q2|², so close primed points make the system
    ill-conditioned."""
    q1, q2 = np.array([1.0, 2.0]), np.array([-0.5, 2.4])
    assert abs(np.linalg.det(eq22_matrix(q1, q2))) == pytest.approx(np.sum((q1 - q2) ** 2))


def test_two_pairs_flag_ill_conditioned_systems() -> None:
    pose = np.array([0.3, -0.2, 0.7])
    q1 = np.array([[2.0, 1.0], [2.0, 1.0], [2.0, 1.0], [2.0, 1.0], [2.0, 1.0]])
    q2 = q1 + np.array([[1e-4, 0.0], [0.0, 0.29], [0.0, 0.31], [0.0, 0.0], [-2.0, 0.0]])
    p1, p2 = transform_points(pose, q1), transform_points(pose, q2)
    got, valid = M.poses_from_two_pairs(p1, p2, q1, q2, min_separation=0.3)
    np.testing.assert_array_equal(valid, [False, False, True, False, True])
    assert np.all(np.isfinite(got))  # flagged, not NaN and no exception
    for k in (2, 4):
        np.testing.assert_allclose(got[k, :2], pose[:2], atol=1e-9)
        assert angle_diff(got[k, 2], pose[2]) < 1e-9
    # coincident primed points are invalid even without a separation threshold
    _, valid0 = M.poses_from_two_pairs(p1[3:4], p2[3:4], q1[3:4], q2[3:4], 0.0)
    assert not valid0[0]


def test_two_pairs_vectorised_matches_one_at_a_time() -> None:
    rng = np.random.default_rng(7)
    poses = rng.uniform(-3, 3, (20, 3))
    q1 = rng.uniform(-5, 5, (20, 2))
    q2 = q1 + rng.uniform(0.6, 3.0, (20, 2))
    p1 = transform_points(poses, q1)
    p2 = transform_points(poses, q2)
    got, valid = M.poses_from_two_pairs(p1, p2, q1, q2, 0.3)
    assert valid.all()
    np.testing.assert_allclose(got[:, :2], poses[:, :2], atol=1e-9)
    np.testing.assert_allclose(wrap_angle(got[:, 2] - poses[:, 2]), 0.0, atol=1e-9)


# ---------------------------------------------------------------------------------------------
# §3.7: pairing
# ---------------------------------------------------------------------------------------------
INCREMENT = np.array([0.4, -0.2, 0.3])  # pose of scan k+1 in the frame of scan k
PREV_XY = np.array(
    [[3.0, 0.0], [2.0, 2.5], [-1.0, 3.0], [-3.0, -1.0], [0.5, -2.5], [4.0, 3.5], [1.5, 1.0]]
)


def fp(
    xy: np.ndarray, kind: int | list[int] = ANGULAR_POINT, unc: np.ndarray | None = None
) -> FeaturePoints:
    xy = np.asarray(xy, float).reshape(-1, 2)
    k = np.broadcast_to(np.asarray(kind, dtype=np.int8), (len(xy),)).copy()
    u = np.linspace(0.1, 0.4, len(xy)) if unc is None else np.asarray(unc, float)
    return FeaturePoints(xy, u, k)


def scan_k1(prev_xy: np.ndarray, increment: np.ndarray = INCREMENT) -> np.ndarray:
    """Where scan k's points are seen from scan k+1 (eq. 17 with SPEC's fix: ⊖u·p)."""
    return transform_points(inverse(increment), prev_xy)


def test_pairing_with_the_exact_increment_pairs_each_point_with_its_image() -> None:
    perm = np.array([4, 0, 6, 2, 5, 1, 3])  # scan k+1 lists its points in another order
    curr_xy = scan_k1(PREV_XY)[perm]
    prev, curr = fp(PREV_XY), fp(curr_xy, unc=np.linspace(0.5, 0.8, 7))
    pairs = M.pair_features(prev, curr, INCREMENT, 0.5, same_kind_only=False, mutual=False)
    assert len(pairs) == len(PREV_XY)
    inv_perm = np.argsort(perm)
    np.testing.assert_array_equal(pairs.curr_index, inv_perm[pairs.prev_index])
    np.testing.assert_array_equal(np.sort(pairs.prev_index), np.arange(7))
    np.testing.assert_allclose(pairs.prev, PREV_XY[pairs.prev_index])
    np.testing.assert_allclose(pairs.curr, curr_xy[pairs.curr_index])
    np.testing.assert_allclose(pairs.uncertainty[:, 0], prev.uncertainty[pairs.prev_index])
    np.testing.assert_allclose(pairs.uncertainty[:, 1], curr.uncertainty[pairs.curr_index])
    # the pairs satisfy p = T(u)·q (eq. 20) exactly
    np.testing.assert_allclose(transform_points(INCREMENT, pairs.curr), pairs.prev, atol=1e-12)


def test_pairing_maps_with_the_inverse_increment() -> None:
    """With the increment's inverse as the prior (eq. 17 as printed) the points land 0.9 m off
    their images for this motion and nothing pairs at T = 0.5 m: the direction matters."""
    curr = fp(scan_k1(PREV_XY))
    wrong = M.pair_features(
        fp(PREV_XY), curr, inverse(INCREMENT), 0.5, same_kind_only=False, mutual=False
    )
    right = M.pair_features(fp(PREV_XY), curr, INCREMENT, 0.5, same_kind_only=False, mutual=False)
    assert len(right) == 7
    assert len(wrong) < 7


def test_pairing_tolerates_an_odometry_error_below_t() -> None:
    noisy_prior = INCREMENT + np.array([0.08, -0.05, 0.02])
    pairs = M.pair_features(
        fp(PREV_XY), fp(scan_k1(PREV_XY)), noisy_prior, 0.5, same_kind_only=False, mutual=False
    )
    np.testing.assert_array_equal(pairs.prev_index, pairs.curr_index)
    assert len(pairs) == 7


def test_a_point_with_two_candidates_is_left_unpaired() -> None:
    """§3.7 'If there is only one such point': a second scan-(k+1) point within T of the mapped
    point makes it ambiguous, so it is not paired; the others are unaffected."""
    curr_xy = scan_k1(PREV_XY)
    extra = curr_xy[2] + np.array([0.2, 0.1])  # within T = 0.5 of point 2's image
    curr = fp(np.vstack([curr_xy, extra]))
    pairs = M.pair_features(fp(PREV_XY), curr, INCREMENT, 0.5, same_kind_only=False, mutual=False)
    assert 2 not in pairs.prev_index.tolist()
    assert sorted(pairs.prev_index.tolist()) == [0, 1, 3, 4, 5, 6]
    np.testing.assert_array_equal(pairs.prev_index, pairs.curr_index)
    # beyond T the extra point is no candidate
    far = fp(np.vstack([curr_xy, curr_xy[2] + np.array([0.6, 0.0])]))
    assert (
        len(M.pair_features(fp(PREV_XY), far, INCREMENT, 0.5, same_kind_only=False, mutual=False))
        == 7
    )


def test_pairing_distance_is_strict_and_uses_t() -> None:
    prev = fp([[2.0, 0.0]])
    curr = fp([[2.3, 0.0]])
    zero = np.zeros(3)
    assert len(M.pair_features(prev, curr, zero, 0.31, same_kind_only=False, mutual=False)) == 1
    assert len(M.pair_features(prev, curr, zero, 0.29, same_kind_only=False, mutual=False)) == 0


def test_same_kind_only() -> None:
    curr_xy = scan_k1(PREV_XY)
    kinds_prev = [ANGULAR_POINT] * 7
    kinds_curr = [ANGULAR_POINT] * 7
    kinds_curr[1] = VIRTUAL_ANGULAR_POINT  # point 1 is seen as another kind in scan k+1
    prev, curr = fp(PREV_XY, kinds_prev), fp(curr_xy, kinds_curr)
    mixed = M.pair_features(prev, curr, INCREMENT, 0.5, same_kind_only=False, mutual=False)
    assert len(mixed) == 7
    same = M.pair_features(prev, curr, INCREMENT, 0.5, same_kind_only=True, mutual=False)
    assert sorted(same.prev_index.tolist()) == [0, 2, 3, 4, 5, 6]
    # an ambiguous second candidate of another kind does not count when kinds must agree
    extra = fp(np.vstack([curr_xy, curr_xy[2] + np.array([0.2, 0.0])]), kinds_prev + [BREAK_POINT])
    assert (
        2
        not in M.pair_features(
            prev, extra, INCREMENT, 0.5, same_kind_only=False, mutual=False
        ).prev_index.tolist()
    )
    kinds_agree = M.pair_features(prev, extra, INCREMENT, 0.5, same_kind_only=True, mutual=False)
    assert 2 in kinds_agree.prev_index.tolist()


def test_mutual() -> None:
    """Two scan-k points whose images both fall within T of one scan-(k+1) point (and of no
    other): each has exactly one candidate, so without ``mutual`` both pair with it; with
    ``mutual`` the scan-(k+1) point has two candidates and neither pair is kept."""
    prev_xy = np.array([[3.0, 0.0], [3.0, 0.4], [-2.0, 2.0]])
    curr_xy = scan_k1(np.array([[3.0, 0.2], [-2.0, 2.0]]))
    prev, curr = fp(prev_xy), fp(curr_xy)
    plain = M.pair_features(prev, curr, INCREMENT, 0.5, mutual=False, same_kind_only=False)
    got = sorted(zip(plain.prev_index.tolist(), plain.curr_index.tolist()))
    assert got == [(0, 0), (1, 0), (2, 1)]
    mutual = M.pair_features(prev, curr, INCREMENT, 0.5, mutual=True, same_kind_only=False)
    assert list(zip(mutual.prev_index.tolist(), mutual.curr_index.tolist())) == [(2, 1)]


def test_pairing_with_no_points() -> None:
    empty = FeaturePoints.empty()
    some = fp(PREV_XY)
    for a, b in ((empty, some), (some, empty), (empty, empty)):
        pairs = M.pair_features(a, b, INCREMENT, 0.5, same_kind_only=False, mutual=False)
        assert len(pairs) == 0
        assert pairs.prev.shape == (0, 2) and pairs.curr.shape == (0, 2)
        assert pairs.uncertainty.shape == (0, 2)


# ---------------------------------------------------------------------------------------------
# eq. 23–24: fusion by the certainty-weighted mean
# ---------------------------------------------------------------------------------------------
def test_weighted_mean_weights_are_one_minus_f() -> None:
    poses = np.array([[1.0, 2.0, 0.1], [3.0, -2.0, 0.5]])
    # f = 1: no influence
    only_first = M.fuse_weighted_mean(poses, np.array([0.0, 1.0]))
    only_second = M.fuse_weighted_mean(poses, np.array([1.0, 0.2]))
    np.testing.assert_allclose(only_first, poses[0], atol=1e-12)
    np.testing.assert_allclose(only_second, poses[1], atol=1e-12)
    # f = (0, 0.5): weights (1, 0.5), so the less uncertain solution counts twice as much
    got = M.fuse_weighted_mean(poses, np.array([0.0, 0.5]))
    assert got[0] == pytest.approx((1.0 * 1 + 0.5 * 3) / 1.5)
    assert got[1] == pytest.approx((1.0 * 2 + 0.5 * -2) / 1.5)
    expected_th = math.atan2(np.sin(0.1) + 0.5 * np.sin(0.5), np.cos(0.1) + 0.5 * np.cos(0.5))
    assert got[2] == pytest.approx(expected_th, abs=1e-12)
    # the paper's eq. 24 as printed (weights f) would give the opposite emphasis
    assert abs(got[0] - 1.0) < abs(got[0] - 3.0)


def test_weighted_mean_of_angles_is_circular() -> None:
    poses = np.array([[0.0, 0.0, math.radians(179.0)], [0.0, 0.0, math.radians(-179.0)]])
    th = M.fuse_weighted_mean(poses, np.zeros(2))[2]
    assert angle_diff(th, math.pi) < 1e-12  # 180°, not the arithmetic 0°
    # unequal weights pull towards the more certain one, across the ±π seam
    th2 = M.fuse_weighted_mean(poses, np.array([0.0, 0.5]))[2]
    expected = math.atan2(
        math.sin(poses[0, 2]) + 0.5 * math.sin(poses[1, 2]),
        math.cos(poses[0, 2]) + 0.5 * math.cos(poses[1, 2]),
    )
    assert angle_diff(th2, expected) < 1e-12
    assert angle_diff(th2, math.radians(179.0)) < angle_diff(th2, math.radians(-179.0))


def test_weighted_mean_with_all_weights_zero_does_not_divide_by_zero() -> None:
    poses = np.array([[1.0, 0.0, 0.2], [3.0, 4.0, 0.4]])
    with np.errstate(all="raise"):
        got = M.fuse_weighted_mean(poses, np.ones(2))
    assert np.all(np.isfinite(got))
    np.testing.assert_allclose(got[:2], [2.0, 2.0], atol=1e-12)  # equal weights
    assert got[2] == pytest.approx(0.3, abs=1e-12)


def test_two_pair_solutions_uncertainty_is_the_mean_of_four_points() -> None:
    """SPEC's fix of eq. 23: a solution's f is the mean over its four points."""
    curr = np.array([[1.0, 0.0], [0.0, 2.0], [-1.5, 0.5]])
    unc = np.array([[0.1, 0.3], [0.5, 0.7], [0.0, 0.2]])
    pairs = rigid_pairs(INCREMENT, curr, unc)
    sols = M.two_pair_solutions(pairs, 0.3, 100)
    assert len(sols) == 3
    for k in range(3):
        i, j = sols.i[k], sols.j[k]
        assert sols.uncertainty[k] == pytest.approx((unc[i].sum() + unc[j].sum()) / 4)
        np.testing.assert_allclose(sols.poses[k, :2], INCREMENT[:2], atol=1e-12)


# ---------------------------------------------------------------------------------------------
# least squares over all pairs
# ---------------------------------------------------------------------------------------------
def _brute_force(pairs: M.Pairs) -> np.ndarray:
    w = 1.0 - pairs.uncertainty.mean(axis=1)
    sw = np.sqrt(w)

    def resid(x: np.ndarray) -> np.ndarray:
        return (sw[:, None] * (transform_points(x, pairs.curr) - pairs.prev)).ravel()

    sol = least_squares(resid, np.zeros(3), xtol=1e-15, ftol=1e-15, gtol=1e-15, method="lm")
    return sol.x


@pytest.mark.parametrize("seed", range(6))
def test_least_squares_is_exact_on_noise_free_pairs(seed: int) -> None:
    rng = np.random.default_rng(seed)
    pose = np.array([rng.uniform(-4, 4), rng.uniform(-4, 4), rng.uniform(-math.pi, math.pi)])
    curr = rng.uniform(-6, 6, (8, 2))
    pairs = rigid_pairs(pose, curr, rng.uniform(0, 0.9, (8, 2)))
    got = M.fuse_least_squares(pairs)
    np.testing.assert_allclose(got[:2], pose[:2], atol=1e-9)
    assert angle_diff(got[2], pose[2]) < 1e-9


@pytest.mark.parametrize("seed", range(6))
def test_least_squares_matches_brute_force_on_noisy_pairs(seed: int) -> None:
    rng = np.random.default_rng(100 + seed)
    pose = np.array([rng.uniform(-2, 2), rng.uniform(-2, 2), rng.uniform(-1.0, 1.0)])
    curr = rng.uniform(-6, 6, (10, 2))
    prev = transform_points(pose, curr) + rng.normal(0.0, 0.03, (10, 2))
    unc = rng.uniform(0, 0.95, (10, 2))
    pairs = make_pairs(prev, curr, unc)
    got = M.fuse_least_squares(pairs)
    ref = _brute_force(pairs)
    np.testing.assert_allclose(got[:2], ref[:2], atol=1e-6)
    assert angle_diff(got[2], ref[2]) < 1e-6
    # and the weights matter: the unweighted fit is measurably different
    unweighted = _brute_force(make_pairs(prev, curr, np.zeros((10, 2))))
    assert np.abs(unweighted[:2] - ref[:2]).max() > 1e-4


# ---------------------------------------------------------------------------------------------
# estimate_increment: robust fusion
# ---------------------------------------------------------------------------------------------
TRUE_INC = np.array([0.35, -0.12, 0.21])
GOOD_CURR = np.array(
    [
        [3.0, 0.0],
        [2.0, 2.5],
        [-1.0, 3.0],
        [-3.0, -1.0],
        [0.5, -2.5],
        [4.0, 3.5],
        [1.5, 1.0],
        [-2.5, 2.0],
        [3.5, -2.0],
        [-0.5, -4.0],
    ]
)


def _pairs_with_outliers() -> M.Pairs:
    good = rigid_pairs(TRUE_INC, GOOD_CURR)
    bad_curr = np.array([[2.0, -3.5], [-4.0, 1.0]])
    bad_prev = transform_points(TRUE_INC, bad_curr) + np.array([[0.5, 0.0], [0.0, -0.5]])
    prev = np.vstack([good.prev, bad_prev])
    curr = np.vstack([good.curr, bad_curr])
    unc = np.full((12, 2), 0.2)
    return make_pairs(prev, curr, unc)


@pytest.mark.parametrize("method", ["least_squares", "weighted_mean"])
def test_robust_fusion_rejects_gross_outliers(method: str) -> None:
    pairs = _pairs_with_outliers()
    cfg = FusionConfig(method=method, robust=True)
    pose, n_used = M.estimate_increment(pairs, cfg, 0.3, 2)
    assert pose is not None
    np.testing.assert_allclose(pose[:2], TRUE_INC[:2], atol=1e-9)
    assert angle_diff(pose[2], TRUE_INC[2]) < 1e-9
    assert n_used == 10
    # without robustness the two outliers drag the estimate (the test can tell the difference)
    plain, _ = M.estimate_increment(pairs, FusionConfig(method=method, robust=False), 0.3, 2)
    assert plain is not None
    assert np.abs(plain[:2] - TRUE_INC[:2]).max() > 0.01


@pytest.mark.parametrize("method", ["least_squares", "weighted_mean"])
def test_estimate_increment_exact_without_outliers(method: str) -> None:
    pairs = rigid_pairs(TRUE_INC, GOOD_CURR, np.random.default_rng(3).uniform(0, 0.8, (10, 2)))
    for robust in (True, False):
        pose, n = M.estimate_increment(pairs, FusionConfig(method=method, robust=robust), 0.3, 2)
        assert pose is not None and n == 10
        np.testing.assert_allclose(pose[:2], TRUE_INC[:2], atol=1e-9)
        assert angle_diff(pose[2], TRUE_INC[2]) < 1e-9


def test_estimate_increment_without_enough_pairs() -> None:
    one = rigid_pairs(TRUE_INC, GOOD_CURR[:1])
    assert M.estimate_increment(one, FusionConfig(), 0.3, 2) == (None, 1)
    none = rigid_pairs(TRUE_INC, GOOD_CURR[:0])
    assert M.estimate_increment(none, FusionConfig(), 0.3, 2)[0] is None
    # two pairs whose primed points nearly coincide: no well-conditioned solution
    close = rigid_pairs(TRUE_INC, np.array([[1.0, 1.0], [1.0, 1.1]]))
    assert M.estimate_increment(close, FusionConfig(), 0.3, 2)[0] is None
    # two well-separated pairs fix a pose (eq. 19–22) ...
    two = rigid_pairs(TRUE_INC, GOOD_CURR[:2])
    for method in ("least_squares", "weighted_mean"):
        pose, n = M.estimate_increment(two, FusionConfig(method=method, robust=False), 0.3, 2)
        assert pose is not None and n == 2
        np.testing.assert_allclose(pose[:2], TRUE_INC[:2], atol=1e-9)
    # ... and robust fusion needs its minimum number of consistent pairs
    cfg = FusionConfig()
    k = max(2, getattr(cfg, "min_inliers", 2))
    few = rigid_pairs(TRUE_INC, GOOD_CURR[:k])
    pose, n = M.estimate_increment(few, cfg, 0.3, 2)
    assert pose is not None and n == k
    np.testing.assert_allclose(pose[:2], TRUE_INC[:2], atol=1e-9)
    if k > 2:
        assert (
            M.estimate_increment(rigid_pairs(TRUE_INC, GOOD_CURR[: k - 1]), cfg, 0.3, 2)[0] is None
        )
