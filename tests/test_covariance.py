"""SE(2) covariance propagation (fuzzypos.geometry): the Jacobians of compose against numerical
differentiation, propagation against known geometry, its algebra and a Monte-Carlo sample.

Convention: the error of an estimate ĝ of g is ε = ⊖g ⊕ ĝ (ĝ = g ⊕ ε), (x, y, θ) in the
frame of the pose itself."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from fuzzypos.geometry import (
    compose,
    compose_jacobians,
    covariance_to_parent,
    covariance_to_parent3,
    inverse,
    propagate,
    propagate3,
    wrap_angle,
)

coord = st.floats(-20.0, 20.0, allow_nan=False)
angle = st.floats(-math.pi, math.pi, allow_nan=False, exclude_max=True)
pose = st.tuples(coord, coord, angle).map(np.array)


def _numeric_jacobians(a: np.ndarray, b: np.ndarray, h: float = 1e-6) -> tuple:
    """Central differences of compose(a, b) in a and in b (θ differences wrapped)."""
    out = []
    for which in (0, 1):
        j = np.zeros((3, 3))
        for i in range(3):
            d = np.zeros(3)
            d[i] = h
            args_p = (a + d, b) if which == 0 else (a, b + d)
            args_m = (a - d, b) if which == 0 else (a, b - d)
            diff = compose(*args_p) - compose(*args_m)
            diff[2] = wrap_angle(diff[2])
            j[:, i] = diff / (2 * h)
        out.append(j)
    return tuple(out)


@settings(max_examples=200, deadline=None)
@given(pose, pose)
def test_compose_jacobians_match_numerical_differentiation(a, b):
    ja, jb = compose_jacobians(a, b)
    na, nb = _numeric_jacobians(a, b)
    np.testing.assert_allclose(ja, na, atol=1e-6 * (1 + np.abs(b[:2]).sum()))
    np.testing.assert_allclose(jb, nb, atol=1e-7)


def test_compose_jacobians_known_values():
    # a turned by 90°, b one metre ahead: turning a swings the result sideways (-x)
    ja, jb = compose_jacobians([0.0, 0.0, math.pi / 2], [1.0, 0.0, 0.0])
    np.testing.assert_allclose(ja, [[1, 0, -1], [0, 1, 0], [0, 0, 1]], atol=1e-15)
    np.testing.assert_allclose(jb, [[0, -1, 0], [1, 0, 0], [0, 0, 1]], atol=1e-15)
    ja, jb = compose_jacobians([3.0, -2.0, 0.0], [0.0, 0.0, 0.4])
    np.testing.assert_array_equal(ja, np.eye(3))
    np.testing.assert_array_equal(jb, np.eye(3))


def test_propagate_known_geometry():
    # a heading error of σ rad carried one metre ahead becomes a lateral error of d·σ
    s2 = 0.01**2
    d = 2.0
    c = propagate(np.diag([0.0, 0.0, s2]), [d, 0.0, 0.0], np.zeros((3, 3)))
    np.testing.assert_allclose(c, [[0, 0, 0], [0, d * d * s2, d * s2], [0, d * s2, s2]], atol=1e-18)
    # a standing robot turning by 90°: its position error is seen rotated by -90° in the new frame
    c = propagate(np.diag([4e-4, 1e-4, 0.0]), [0.0, 0.0, math.pi / 2], np.zeros((3, 3)))
    np.testing.assert_allclose(c, np.diag([1e-4, 4e-4, 0.0]), atol=1e-18)
    # no motion: the covariances add; no pose error: the increment's alone
    p, q = np.diag([1e-4, 2e-4, 3e-6]), np.diag([5e-6, 6e-6, 7e-8])
    np.testing.assert_allclose(propagate(p, [0, 0, 0], q), p + q, atol=1e-18)
    np.testing.assert_allclose(propagate(np.zeros((3, 3)), [1.0, 2.0, 0.5], q), q, atol=1e-18)


spd = st.tuples(
    st.floats(1e-6, 1.0), st.floats(1e-6, 1.0), st.floats(1e-6, 1.0), st.floats(-0.9, 0.9)
)


def _cov(v: tuple[float, float, float, float]) -> np.ndarray:
    sx, sy, st_, r = v
    c = np.diag([sx, sy, st_])
    c[0, 1] = c[1, 0] = r * math.sqrt(sx * sy)
    return c


@settings(max_examples=100, deadline=None)
@given(spd, pose, spd, pose, spd)
def test_propagate_twice_equals_propagating_the_composed_increment(p, u1, c1, u2, c2):
    """(P ⊕ u1) ⊕ u2 = P ⊕ (u1 ⊕ u2), with u1 ⊕ u2's covariance propagated the same way."""
    P, C1, C2 = _cov(p), _cov(c1), _cov(c2)
    two_steps = propagate(propagate(P, u1, C1), u2, C2)
    one_step = propagate(P, compose(u1, u2), propagate(C1, u2, C2))
    scale = 1.0 + float(np.abs(two_steps).max())
    np.testing.assert_allclose(two_steps, one_step, atol=1e-9 * scale)
    np.testing.assert_allclose(two_steps, two_steps.T, atol=0)
    assert np.linalg.eigvalsh(two_steps).min() > -1e-9 * scale


def _sample(cov: np.ndarray, n: int, rng: np.random.Generator) -> np.ndarray:
    return rng.multivariate_normal(np.zeros(3), cov, size=n)


def _error_cov(true: np.ndarray, est: np.ndarray) -> np.ndarray:
    """The sample covariance of ⊖true ⊕ est (about zero: the errors are unbiased to first
    order)."""
    e = compose(inverse(true)[None, :], est)
    return e.T @ e / len(e)


@pytest.mark.parametrize(
    ("pose_true", "inc_true", "pose_cov", "inc_cov"),
    [
        (
            [1.0, -2.0, 0.7],
            [0.5, 0.1, 0.3],
            np.diag([4e-4, 1e-4, 4e-4]),
            np.diag([1e-4, 4e-4, 1e-4]),
        ),
        (
            [-3.0, 4.0, -2.9],
            [2.0, -1.0, -1.2],
            _cov((9e-4, 1e-4, 2.5e-4, 0.5)),
            _cov((1e-4, 1e-4, 1e-4, -0.3)),
        ),
        (
            [0.0, 0.0, 0.0],
            [4.0, 0.0, 0.0],
            np.diag([1e-6, 1e-6, 1e-5]),
            np.diag([1e-6, 1e-6, 1e-8]),
        ),
    ],
)
def test_propagate_matches_a_monte_carlo_sample(pose_true, inc_true, pose_cov, inc_cov):
    """20,000 samples of p̂ = p ⊕ e and û = u ⊕ ε: the error of p̂ ⊕ û has propagate's
    covariance, within a few per cent."""
    rng = np.random.default_rng(7)
    n = 20_000
    p, u = np.asarray(pose_true), np.asarray(inc_true)
    p_hat = compose(p[None, :], _sample(pose_cov, n, rng))
    u_hat = compose(u[None, :], _sample(inc_cov, n, rng))
    sample = _error_cov(compose(p, u), compose(p_hat, u_hat))
    expected = propagate(pose_cov, u, inc_cov)
    scale = np.sqrt(np.outer(np.diag(expected), np.diag(expected)))
    np.testing.assert_allclose(np.diag(sample), np.diag(expected), rtol=0.04)
    # every entry within 4 % of the scale its variances set (correlations within 0.04)
    assert np.all(np.abs(sample - expected) <= 0.04 * scale)


def test_covariance_to_parent_known_values_and_a_sample():
    c = np.diag([4e-4, 1e-4, 1e-6])
    np.testing.assert_allclose(
        covariance_to_parent([5.0, 6.0, math.pi / 2], c), np.diag([1e-4, 4e-4, 1e-6]), atol=1e-18
    )
    np.testing.assert_array_equal(covariance_to_parent([5.0, 6.0, 0.0], c), c)
    # additive errors of (x, y, θ) in the parent frame of p ⊕ e, e ~ N(0, c)
    rng = np.random.default_rng(3)
    p = np.array([1.0, 2.0, 2.2])
    c = _cov((9e-4, 1e-4, 4e-4, 0.6))
    est = compose(p[None, :], _sample(c, 20_000, rng))
    d = est - p
    d[:, 2] = wrap_angle(d[:, 2])
    sample = d.T @ d / len(d)
    expected = covariance_to_parent(p, c)
    scale = np.sqrt(np.outer(np.diag(expected), np.diag(expected)))
    assert np.all(np.abs(sample - expected) <= 0.04 * scale)


@settings(max_examples=100, deadline=None)
@given(pose, spd)
def test_covariance_to_parent_is_a_rotation(p, c):
    C = _cov(c)
    W = covariance_to_parent(p, C)
    assert np.trace(W[:2, :2]) == pytest.approx(np.trace(C[:2, :2]), rel=1e-12, abs=1e-15)
    assert W[2, 2] == C[2, 2]
    np.testing.assert_allclose(np.linalg.eigvalsh(W), np.linalg.eigvalsh(C), atol=1e-12)
    back = covariance_to_parent([0.0, 0.0, -p[2]], W)
    np.testing.assert_allclose(back, C, atol=1e-12)


@pytest.mark.parametrize(
    "call",
    [
        lambda: propagate(np.eye(2), [0, 0, 0], np.eye(3)),
        lambda: propagate(np.eye(3), [0, 0], np.eye(3)),
        lambda: propagate(np.eye(3), [0, 0, 0], np.full((3, 3), np.nan)),
        lambda: covariance_to_parent([0, 0, 0], np.eye(4)),
        lambda: compose_jacobians(np.zeros((2, 3)), [0, 0, 0]),
    ],
)
def test_bad_shapes_and_values_raise(call):
    with pytest.raises(ValueError, match=r"covariance|pose|finite|one"):
        call()


# -- the float versions (the run job's, once a scan) ---------------------------------------------
def _upper(c: np.ndarray) -> tuple[float, ...]:
    return tuple(float(c[i, j]) for i, j in ((0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2)))


@settings(max_examples=200, deadline=None)
@given(spd, pose, spd)
def test_propagate3_is_propagate_in_floats(p, u, c):
    P, C = _cov(p), _cov(c)
    # a correlated heading too, which the diagonal-free _cov leaves out
    P[0, 2] = P[2, 0] = 0.3 * math.sqrt(P[0, 0] * P[2, 2])
    C[1, 2] = C[2, 1] = -0.2 * math.sqrt(C[1, 1] * C[2, 2])
    got = propagate3(_upper(P), tuple(u.tolist()), _upper(C))
    want = _upper(propagate(P, u, C))
    scale = float(np.abs(want).max())
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-13 * scale)


@settings(max_examples=200, deadline=None)
@given(spd, pose)
def test_covariance_to_parent3_is_covariance_to_parent_in_floats(p, where):
    P = _cov(p)
    P[1, 2] = P[2, 1] = 0.4 * math.sqrt(P[1, 1] * P[2, 2])
    got = covariance_to_parent3(float(where[2]), _upper(P))
    want = _upper(covariance_to_parent(where, P))
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-14 * float(np.abs(want).max()))


def test_the_float_versions_known_geometry():
    """The heading's error carried 2 m ahead (a lateral error 2σ); seen from a pose turned by
    90°, x and y swap."""
    s2, d = 0.01**2, 2.0
    got = propagate3((0.0, 0.0, 0.0, 0.0, 0.0, s2), (d, 0.0, 0.0), (0.0,) * 6)
    np.testing.assert_allclose(got, (0, 0, 0, d * d * s2, d * s2, s2), atol=1e-18)
    got = covariance_to_parent3(math.pi / 2, (4e-4, 0.0, 0.0, 1e-4, 0.0, 1e-6))
    np.testing.assert_allclose(got, (1e-4, 0.0, 0.0, 4e-4, 0.0, 1e-6), atol=1e-18)
