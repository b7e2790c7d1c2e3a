"""Tests for fuzzypos.geometry (SE(2) poses, SPEC "Conventions")."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from fuzzypos.geometry import (
    Pose2D,
    _wrap_scalar,
    circular_mean,
    compose,
    compose3,
    inverse,
    relative,
    relative3,
    rotation_matrix,
    transform_points,
    wrap_angle,
)

coord = st.floats(-100.0, 100.0, allow_nan=False)
angle = st.floats(-10.0, 10.0, allow_nan=False)
poses = st.builds(Pose2D, coord, coord, angle)
points = st.tuples(coord, coord)

ATOL = 1e-9


def assert_pose_close(a, b, atol=ATOL):
    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float)
    np.testing.assert_allclose(a[..., :2], b[..., :2], atol=atol, rtol=0)
    # headings compared on the circle (both wrapped to [-pi, pi) but may sit either side of pi)
    d = wrap_angle(a[..., 2] - b[..., 2])
    np.testing.assert_allclose(d, 0.0, atol=atol)


# -- wrap_angle ---------------------------------------------------------------------------
@given(st.floats(-1e6, 1e6, allow_nan=False))
def test_wrap_angle_range_and_idempotent(a):
    w = float(wrap_angle(a))
    assert -math.pi <= w < math.pi
    assert float(wrap_angle(w)) == w
    # same angle on the circle
    assert math.isclose(math.cos(w), math.cos(a), abs_tol=1e-6)
    assert math.isclose(math.sin(w), math.sin(a), abs_tol=1e-6)


@given(st.floats(-math.pi, math.pi, allow_nan=False, exclude_max=True))
def test_wrap_angle_exact_in_range(a):
    assert float(wrap_angle(a)) == a


@pytest.mark.parametrize(
    "a, expected",
    [
        (math.pi, -math.pi),
        (-math.pi, -math.pi),
        (3 * math.pi, -math.pi),
        (2 * math.pi, 0.0),
        (math.pi / 2 + 2 * math.pi, math.pi / 2),
        (-3 * math.pi / 2, math.pi / 2),
    ],
)
def test_wrap_angle_known_values(a, expected):
    assert float(wrap_angle(a)) == pytest.approx(expected, abs=1e-12)


def test_wrap_angle_just_below_minus_pi_stays_in_range():
    # np.mod rounds up to 2*pi here; the result must still be in [-pi, pi)
    a = np.nextafter(-math.pi, -4.0)
    w = float(wrap_angle(a))
    assert -math.pi <= w < math.pi


@given(
    st.one_of(
        st.floats(-1e6, 1e6, allow_nan=False),
        # the edges: multiples of pi and their neighbours, where the mod rounds
        st.builds(
            lambda k, ulps: (
                float(np.nextafter(k * math.pi, math.copysign(math.inf, ulps)))
                if ulps
                else k * math.pi
            ),
            st.integers(-1000, 1000),
            st.integers(-1, 1),
        ),
        st.sampled_from([math.inf, -math.inf, math.nan]),
    )
)
def test_one_floats_wrap_is_wrap_angle_to_the_bit(a):
    """The scalar wrap the float paths use (``compose3``, ``Pose2D``) is ``wrap_angle``'s
    value to the last bit, NaN and infinities as numpy gives them."""
    with np.errstate(invalid="ignore"):  # (numpy's mod of an infinity)
        expected = float(wrap_angle(a))
        got = _wrap_scalar(a)
    assert np.array_equal(np.float64(got), np.float64(expected), equal_nan=True), (a, got)
    assert math.copysign(1.0, got) == math.copysign(1.0, expected) or math.isnan(expected)


def test_wrap_angle_array_shape_and_values():
    a = np.array([[0.0, 4.0], [-4.0, 7.0]])
    w = wrap_angle(a)
    assert w.shape == (2, 2)
    tau = 2 * math.pi
    np.testing.assert_allclose(w, [[0.0, 4.0 - tau], [tau - 4.0, 7.0 - tau]])


# -- compose / inverse / relative -----------------------------------------------------------
def test_compose_known_value():
    a = Pose2D(1.0, 2.0, math.pi / 2)
    b = Pose2D(3.0, 0.0, math.pi / 2)
    c = a @ b
    assert (c.x, c.y) == pytest.approx((1.0, 5.0), abs=1e-12)
    assert c.theta == pytest.approx(-math.pi)  # pi wrapped to -pi


def test_inverse_known_value():
    a = Pose2D(1.0, 0.0, math.pi / 2)
    inv = a.inverse()
    assert (inv.x, inv.y, inv.theta) == pytest.approx((0.0, 1.0, -math.pi / 2), abs=1e-12)


@given(poses)
def test_compose_with_inverse_is_identity(a):
    assert_pose_close((a @ a.inverse()).as_array(), [0.0, 0.0, 0.0])
    assert_pose_close((a.inverse() @ a).as_array(), [0.0, 0.0, 0.0])
    assert_pose_close(a.inverse().inverse().as_array(), a.as_array())


@given(poses)
def test_identity_is_neutral(a):
    e = Pose2D.identity()
    assert_pose_close((a @ e).as_array(), a.as_array())
    assert_pose_close((e @ a).as_array(), a.as_array())


@given(poses, poses, poses)
def test_compose_is_associative(a, b, c):
    assert_pose_close(((a @ b) @ c).as_array(), (a @ (b @ c)).as_array(), atol=1e-7)


@given(poses, poses)
def test_relative_recovers_increment(a, b):
    ab = compose(a.as_array(), b.as_array())
    assert_pose_close(relative(a.as_array(), ab), b.as_array(), atol=1e-7)
    assert_pose_close((a @ b).relative_to(a).as_array(), b.as_array(), atol=1e-7)


@given(poses, poses)
def test_float_triples_are_bit_identical_to_the_arrays(a, b):
    """compose3/relative3 (the pipeline's float fast paths) give the very floats of
    compose/relative on the arrays."""
    ta, tb = (a.x, a.y, a.theta), (b.x, b.y, b.theta)
    assert compose3(ta, tb) == tuple(compose(a.as_array(), b.as_array()).tolist())
    assert relative3(ta, tb) == tuple(relative(a.as_array(), b.as_array()).tolist())


@given(poses, poses, points)
def test_transform_points_consistent_with_compose(a, b, p):
    # moving p by b then by a == moving p by a ⊕ b
    via_two = transform_points(a.as_array(), transform_points(b.as_array(), p))
    via_composed = transform_points(compose(a.as_array(), b.as_array()), p)
    np.testing.assert_allclose(via_two, via_composed, atol=1e-6, rtol=0)
    # and a point at the origin of b's frame lands at b's position
    np.testing.assert_allclose(transform_points(b.as_array(), [0.0, 0.0]), [b.x, b.y], atol=1e-12)


@given(poses, points)
def test_transform_points_inverse_roundtrip(a, p):
    q = a.transform_points(p)
    back = a.inverse().transform_points(q)
    np.testing.assert_allclose(back, p, atol=1e-7, rtol=0)


def test_transform_points_known_value():
    pose = [1.0, 2.0, math.pi / 2]
    out = transform_points(pose, [[1.0, 0.0], [0.0, 1.0]])
    np.testing.assert_allclose(out, [[1.0, 3.0], [0.0, 2.0]], atol=1e-12)


def test_rotation_matrix_matches_transform():
    t = np.array([0.3, -2.0])
    R = rotation_matrix(t)
    assert R.shape == (2, 2, 2)
    p = np.array([1.5, -0.5])
    for k in range(2):
        np.testing.assert_allclose(R[k] @ p, transform_points([0.0, 0.0, t[k]], p), atol=1e-12)


# -- broadcasting over arrays of poses ------------------------------------------------------
pose_arrays = arrays(
    np.float64,
    st.integers(1, 6).map(lambda n: (n, 3)),
    elements=st.floats(-10.0, 10.0, allow_nan=False),
)


@given(pose_arrays, st.data())
def test_array_ops_match_pose2d_loop(A, data):
    n = A.shape[0]
    B = data.draw(arrays(np.float64, (n, 3), elements=st.floats(-10.0, 10.0, allow_nan=False)))
    P = data.draw(arrays(np.float64, (n, 2), elements=st.floats(-10.0, 10.0, allow_nan=False)))
    C = compose(A, B)
    Inv = inverse(A)
    R = relative(A, B)
    T = transform_points(A, P)  # one pose per point
    assert C.shape == Inv.shape == R.shape == (n, 3)
    assert T.shape == (n, 2)
    for k in range(n):
        a, b = Pose2D.from_array(A[k]), Pose2D.from_array(B[k])
        assert_pose_close(C[k], (a @ b).as_array())
        assert_pose_close(Inv[k], a.inverse().as_array())
        assert_pose_close(R[k], b.relative_to(a).as_array())
        np.testing.assert_allclose(T[k], a.transform_points(P[k]), atol=1e-9)


def test_compose_broadcasts_single_pose_against_many():
    a = np.array([1.0, -1.0, 0.7])
    B = np.array([[0.0, 0.0, 0.0], [1.0, 2.0, -3.0], [-4.0, 0.5, 3.1]])
    C = compose(a, B)
    assert C.shape == (3, 3)
    for k in range(3):
        assert_pose_close(C[k], (Pose2D(*a) @ Pose2D(*B[k])).as_array())


def test_transform_points_sets_per_pose():
    # N poses each moving the same M points: pose[:, None, :] against (M, 2)
    A = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, math.pi / 2], [0.0, -2.0, math.pi]])
    pts = np.array([[1.0, 0.0], [0.0, 1.0], [2.0, 2.0], [-1.0, 0.5]])
    out = transform_points(A[:, None, :], pts)
    assert out.shape == (3, 4, 2)
    for k in range(3):
        np.testing.assert_allclose(out[k], Pose2D(*A[k]).transform_points(pts), atol=1e-12)
    np.testing.assert_allclose(out[1, 0], [1.0, 1.0], atol=1e-12)


def test_bad_shapes_raise():
    with pytest.raises(ValueError, match="length 3"):
        compose([1.0, 2.0], [0.0, 0.0, 0.0])
    with pytest.raises(ValueError, match="length 2"):
        transform_points([0.0, 0.0, 0.0], [1.0, 2.0, 3.0])


# -- circular mean ------------------------------------------------------------------------------
def test_circular_mean_across_pi():
    m = circular_mean(np.radians([179.0, -179.0]))
    assert -math.pi <= m < math.pi
    assert abs(float(wrap_angle(m - math.pi))) < 1e-12  # 180 degrees, not 0
    assert abs(m) == pytest.approx(math.pi)


def test_circular_mean_values():
    assert circular_mean(np.radians([10.0, 30.0])) == pytest.approx(math.radians(20.0))
    assert circular_mean(np.radians([-170.0, 170.0, 180.0])) == pytest.approx(-math.pi)
    # weights pull the mean toward the heavier angle
    m = circular_mean([0.0, math.pi / 2], weights=[3.0, 1.0])
    assert m == pytest.approx(math.atan2(1.0, 3.0))
    # nothing to average
    assert circular_mean([]) == 0.0
    assert circular_mean([1.0, 2.0], weights=[0.0, 0.0]) == 0.0


@given(st.lists(angle, min_size=1, max_size=20), st.floats(-math.pi, math.pi))
def test_circular_mean_is_rotation_equivariant(angles, shift):
    a = np.asarray(angles)
    if np.hypot(np.sum(np.sin(a)), np.sum(np.cos(a))) < 1e-3:
        return  # mean undefined / ill-conditioned
    m0 = circular_mean(a)
    m1 = circular_mean(a + shift)
    assert -math.pi <= m1 < math.pi
    assert abs(float(wrap_angle(m1 - m0 - shift))) < 1e-6


# -- Pose2D --------------------------------------------------------------------------------------
@pytest.mark.parametrize("field", ["x", "y", "theta"])
@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf])
def test_pose2d_rejects_non_finite(field, bad):
    kw = {"x": 0.0, "y": 0.0, "theta": 0.0, field: bad}
    with pytest.raises(ValueError, match=field):
        Pose2D(**kw)


def test_pose2d_rejects_non_number():
    with pytest.raises(ValueError, match="x"):
        Pose2D("abc", 0.0, 0.0)


def test_pose2d_wraps_theta_and_roundtrips_array():
    p = Pose2D(1.0, 2.0, 3 * math.pi / 2)
    assert p.theta == pytest.approx(-math.pi / 2)
    assert Pose2D.from_array(p.as_array()) == p
    assert list(p) == [1.0, 2.0, p.theta]
    assert Pose2D(3.0, 4.0, 0.0).translation_norm == 5.0
    with pytest.raises(ValueError):
        Pose2D.from_array([1.0, 2.0])


@given(poses, poses)
def test_single_pose_paths_are_the_arrays_arithmetic(a, b):
    # one pose each: float arithmetic, bit-identical to numpy scalars' (the former code)
    pa, pb = a.as_array(), b.as_array()
    c, s = math.cos(pa[2]), math.sin(pa[2])
    x, y = pa[0] + c * pb[0] - s * pb[1], pa[1] + s * pb[0] + c * pb[1]
    np.testing.assert_array_equal(compose(pa, pb)[:2], [x, y])
    inv = [-(c * pa[0] + s * pa[1]), s * pa[0] - c * pa[1]]
    np.testing.assert_array_equal(inverse(pa)[:2], inv)
    np.testing.assert_array_equal(relative(pa, pb), compose(inverse(pa), pb))
    # the float64 fast path and the converting path (lists) agree to the bit
    np.testing.assert_array_equal(compose(pa, pb), compose(pa.tolist(), pb.tolist()))
    np.testing.assert_array_equal(relative(pa, pb), relative(pa.tolist(), pb.tolist()))
