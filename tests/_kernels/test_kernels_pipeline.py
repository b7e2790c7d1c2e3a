"""The pipeline's own small kernels (``fuzzypos._kernels.pipeline``) against their numpy
references beside their callers."""

from __future__ import annotations

import contextlib
import math

import numpy as np
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from fuzzypos._kernels.pipeline import move_surfaces
from fuzzypos.geometry import transform_points
from fuzzypos.matching import SurfacePoints
from helpers import numpy_kernels
from oracles import pipeline as pipeline_oracle

coord = st.floats(-50.0, 50.0, allow_nan=False)
angle = st.floats(-math.pi, math.pi, allow_nan=False, exclude_max=True)


def _surface(rng: np.random.Generator, n: int) -> SurfacePoints:
    xy = rng.uniform(-10.0, 10.0, (n, 2))
    a = rng.uniform(-math.pi, math.pi, n)
    return SurfacePoints(xy, np.stack((np.cos(a), np.sin(a)), axis=1), rng.uniform(0, 1, n))


@settings(max_examples=60, deadline=None)
@given(
    st.lists(st.tuples(coord, coord, angle, st.integers(0, 40)), min_size=1, max_size=4),
    st.integers(0, 2**32 - 1),
)
def test_the_moved_surfaces_are_the_numpy_ones(parts_spec, seed) -> None:
    """Every part's points and normals moved by its pose: the kernel gives the numpy
    reference's values (and the points are transform_points')."""
    rng = np.random.default_rng(seed)
    parts = [(_surface(rng, n), np.array([x, y, t])) for x, y, t, n in parts_spec]
    moves = [(x, y, math.cos(t), math.sin(t)) for x, y, t, _ in parts_spec]
    ends = np.cumsum([n for *_, n in parts_spec]).astype(np.int64)
    xy = np.concatenate([s.xy for s, _ in parts])
    normal = np.concatenate([s.normal for s, _ in parts])
    got_xy, got_normal = move_surfaces(xy, normal, np.array(moves), ends)
    want_xy, want_normal = pipeline_oracle.moved(parts, moves)
    np.testing.assert_allclose(got_xy, want_xy, rtol=0, atol=1e-9)
    np.testing.assert_allclose(got_normal, want_normal, rtol=0, atol=1e-9)
    by_pose = [transform_points(pose, s.xy) for s, pose in parts]
    np.testing.assert_allclose(want_xy, np.concatenate(by_pose), rtol=0, atol=1e-9)


def _spd(rng: np.random.Generator, scale: float) -> np.ndarray:
    a = rng.normal(size=(3, 3))
    return scale * (a @ a.T + 0.3 * np.eye(3))


@settings(max_examples=60, deadline=None)
@given(
    st.integers(0, 10**6),
    st.booleans(),
    st.booleans(),
    st.booleans(),
    st.sampled_from([True, False, None]),
)
def test_the_assessment_with_the_scans_own_motion_is_the_two_calls(
    seed, hold, prior_differs, gate_open, compiled
) -> None:
    """``Uncertainty.assess(..., with_scan_only=True)`` (one kernel call for both, compiled)
    gives the assessment of ``assess`` and the motion of ``scan_only`` called after it, from
    the previous covariance it leaves: the very values, compiled (True) or in numpy (False);
    and (None) the compiled values within 1e-9 of the numpy ones."""
    from fuzzypos.config import Config
    from fuzzypos.matching import Refinement
    from fuzzypos.pipeline import uncertainty as stage

    cfg = Config()
    rng = np.random.default_rng(seed)
    t_prev = rng.normal(scale=[0.5, 0.5, 1.0])
    prior = rng.normal(scale=[0.1, 0.1, 0.2])
    increment = np.array([*rng.normal(scale=0.3, size=2), rng.uniform(-math.pi, math.pi)])
    fit_prior = increment + (rng.normal(scale=0.02, size=3) if prior_differs else 0.0)
    fit = Refinement(
        increment, 150, 0.9, 0.8, information=_spd(rng, 1e5),
        prior_information=_spd(rng, 1e3),
        hold_information=_spd(rng, 1e4) if hold else np.zeros((3, 3)),
        hold_on_start=bool(rng.integers(2)), start=increment + rng.normal(scale=0.01, size=3),
        prior=fit_prior, gradient_covariance=_spd(rng, 1e3),
    )  # fmt: skip
    prior_cov, previous = _spd(rng, 1e-4), _spd(rng, 1e-5)

    Scan = tuple[np.ndarray, np.ndarray] | None

    def run(enabled: bool, fused: bool) -> tuple[stage.Assessment, Scan]:
        with contextlib.nullcontext() if enabled else numpy_kernels():
            u = stage.Uncertainty(cfg.covariance, cfg.gate)
            u._previous = previous.copy()
            judged = u.assess(t_prev, prior, prior_cov, increment, fit, gate_open, fused)
            scan = judged.scan_only if fused else (
                None if judged.rejected else u.scan_only(fit, t_prev)
            )  # fmt: skip
            return judged, scan

    def values(judged: stage.Assessment, scan: Scan) -> list[np.ndarray]:
        out = [judged.covariance, judged.keyframe_covariance, np.array([judged.gate or 0.0])]
        if scan is not None:
            out += list(scan)
        return out

    if compiled is None:
        (a, scan_a), (b, scan_b) = run(True, True), run(False, False)
        if b.gate is not None:  # (not where rounding could tip the gate)
            threshold = stage.Uncertainty(cfg.covariance, cfg.gate).threshold
            assume(abs(b.gate - threshold) > 1e-6)
        assert a.rejected == b.rejected and (scan_a is None) == (scan_b is None)
        for x, y in zip(values(a, scan_a), values(b, scan_b)):
            np.testing.assert_allclose(x, y, rtol=1e-9, atol=1e-9 * np.abs(y).max())
        return
    (a, scan_a), (b, scan_b) = run(compiled, True), run(compiled, False)
    assert a.rejected == b.rejected and a.gate == b.gate
    assert (scan_a is None) == (scan_b is None)
    assert not hold or scan_a is None  # a held fit has no motion of the scan's own
    for x, y in zip(values(a, scan_a), values(b, scan_b)):
        assert x.tobytes() == y.tobytes()


@settings(max_examples=60, deadline=None)
@given(st.integers(0, 10**6), st.floats(1e-8, 1e-1), st.floats(1e-8, 1e-1))
def test_the_refinements_priors_from_the_learned_noise_are_the_numpy_ones(
    seed, odometry_scale, previous_scale
) -> None:
    """``Uncertainty.prior_information``: the information of the features' and of the
    odometry's motion from the keyframe, in one compiled call as numpy's inverses give them
    (to 1e-9 of their size); the odometry's is the inverse of ``key_prior_covariance``."""
    from fuzzypos.config import Config
    from fuzzypos.pipeline import uncertainty as stage

    cfg = Config()
    rng = np.random.default_rng(seed)
    t_prev = rng.normal(scale=[1.0, 1.0, 1.5])
    prior = rng.normal(scale=[0.1, 0.1, 0.2])
    prior_cov, previous = _spd(rng, odometry_scale), _spd(rng, previous_scale)
    u = stage.Uncertainty(cfg.covariance, cfg.gate)
    u._previous = previous
    got = u.prior_information(t_prev, prior, prior_cov)
    want = pipeline_oracle.prior_information(u, t_prev, prior, prior_cov)
    for x, y in zip(got, want):
        np.testing.assert_allclose(x, y, rtol=1e-9, atol=1e-9 * np.abs(y).max())
    odometry = pipeline_oracle.key_prior_covariance(u, t_prev, prior, prior_cov)
    np.testing.assert_allclose(got[1] @ odometry, np.eye(3), atol=1e-8)
    np.testing.assert_allclose(got[0] @ (odometry + u.feature_covariance()), np.eye(3), atol=1e-8)


@settings(max_examples=60, deadline=None)
@given(st.integers(0, 10**6), st.booleans())
def test_the_prior_standing_is_the_numpy_one(seed, overruled) -> None:
    """Where the prior stands (nothing matched: ``assess`` of no match; or ``overruled`` from
    the covariance held before the match's assessment), the compiled kernel
    (``_kernels.uncertainty.prior_stands``) gives the numpy reference's covariances and leaves
    its previous covariance, within 1e-12 of their size; the increment's covariance is the
    prior's own, symmetric, with the floor."""
    from fuzzypos.config import Config
    from fuzzypos.pipeline import uncertainty as stage

    cfg = Config()
    rng = np.random.default_rng(seed)
    t_prev = rng.normal(scale=[0.5, 0.5, 1.0])
    prior = rng.normal(scale=[0.1, 0.1, 0.2])
    prior_cov, previous, held = _spd(rng, 1e-4), _spd(rng, 1e-5), _spd(rng, 1e-5)

    def run(compiled: bool) -> tuple[stage.Assessment, np.ndarray]:
        with contextlib.nullcontext() if compiled else numpy_kernels():
            u = stage.Uncertainty(cfg.covariance, cfg.gate)
            u._previous = previous.copy()
            if overruled:
                judged = u.overruled(held, t_prev, prior, prior_cov)
            else:
                judged = u.assess(t_prev, prior, prior_cov, None, None, gate_open=True)
            return judged, u.previous_covariance()

    (a, prev_a), (b, prev_b) = run(True), run(False)
    assert a.gate is None and b.gate is None and not a.rejected and not b.rejected
    for x, y in ((a.covariance, b.covariance), (a.keyframe_covariance, b.keyframe_covariance),
                 (prev_a, prev_b)):  # fmt: skip
        np.testing.assert_allclose(x, y, rtol=0, atol=1e-12 * np.abs(y).max())
    np.testing.assert_array_equal(a.covariance, a.covariance.T)
    np.testing.assert_array_equal(a.covariance, 0.5 * (prior_cov + prior_cov.T) + _floor(cfg))


def _floor(cfg) -> np.ndarray:  # type: ignore[no-untyped-def]
    """The covariance floor of ``cfg``'s covariance section."""
    f = cfg.covariance
    return np.diag([f.floor_translation**2, f.floor_translation**2, f.floor_rotation**2])
