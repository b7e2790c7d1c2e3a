"""Line-to-line matching (beyond the paper): pairing lines between scans and the increment
from paired lines, on hand-made lines whose true motion is known."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from fuzzypos import matching as M
from fuzzypos.features import Lines
from fuzzypos.geometry import compose, inverse, relative

TRIM_ANGLE = math.radians(0.2)


def make_lines(
    normal_angles: list[float],
    distances: list[float],
    half_length: float = 1.5,
    noise: float = 1e-3,
) -> Lines:
    """Lines ``n·p = d`` (frame of the scan) with segments centred on the foot of the normal."""
    k = len(normal_angles)
    a = np.asarray(normal_angles, dtype=float)
    n = np.column_stack([np.cos(a), np.sin(a)])
    d = np.asarray(distances, dtype=float)
    direction = np.column_stack([n[:, 1], -n[:, 0]])
    start = n * d[:, None] - half_length * direction
    end = n * d[:, None] + half_length * direction
    return Lines(
        normal=n,
        distance=d,
        start=start,
        end=end,
        centre=0.5 * (start + end),
        n_points=np.full(k, 30),
        sigma=np.zeros(k),
        delta=np.zeros(k),
        uncertainty=np.zeros(k),
        segment=np.arange(k),
        cluster=np.zeros(k, dtype=np.int64),
        angle_variance=np.full(k, (noise / half_length) ** 2),
        distance_variance=np.full(k, noise**2 / 30),
    )


def seen_from(lines: Lines, increment: np.ndarray) -> Lines:
    """The same lines expressed in the frame of a robot moved by ``increment`` (frame k+1)."""
    inv = inverse(increment)
    c, s = math.cos(inv[2]), math.sin(inv[2])
    n = np.column_stack(
        [
            c * lines.normal[:, 0] - s * lines.normal[:, 1],
            s * lines.normal[:, 0] + c * lines.normal[:, 1],
        ]
    )
    d = lines.distance + n @ inv[:2]
    flip = np.where(d < 0, -1.0, 1.0)
    n, d = n * flip[:, None], d * flip

    def move(p: np.ndarray) -> np.ndarray:
        return (np.array([[c, -s], [s, c]]) @ p.T).T + inv[:2]

    start, end = move(lines.start), move(lines.end)
    return Lines(
        n,
        d,
        start,
        end,
        0.5 * (start + end),
        lines.n_points,
        lines.sigma,
        lines.delta,
        lines.uncertainty,
        lines.segment,
        lines.cluster,
        lines.angle_variance,
        lines.distance_variance,
    )


ROOM = make_lines(
    [0.0, math.pi / 2, math.pi, -math.pi / 2, math.radians(30)], [4.0, 3.0, 5.0, 2.5, 2.0]
)


def solve(
    prev: Lines,
    curr: Lines,
    start: np.ndarray,
    prior: np.ndarray | None = None,
    gates: tuple[float, float] = (math.radians(8), 0.5),
) -> np.ndarray | None:
    prior = start if prior is None else prior
    pairs = M.pair_lines(prev, curr, start, gates[0], gates[1], 0.5)
    return M.increment_from_lines(
        prev, curr, pairs, start, prior, 0.05, TRIM_ANGLE, 0.05, math.radians(20.0)
    )


@settings(derandomize=True, deadline=None, max_examples=60)
@given(
    st.floats(-0.5, 0.5),
    st.floats(-0.5, 0.5),
    st.floats(-20, 20),
    st.floats(-0.07, 0.07),
    st.floats(-0.07, 0.07),
    st.floats(-5, 5),
)
def test_exact_lines_give_the_exact_increment(x, y, th_deg, ex, ey, eth_deg) -> None:
    """Noise-free lines, a start off by up to 7 cm and 5°: the increment is exact (but for the
    prior's pull, a 5 cm-sigma measurement against lines a thousand times surer: under a
    hundredth of a millimetre here)."""
    truth = np.array([x, y, math.radians(th_deg)])
    start = compose(truth, np.array([ex, ey, math.radians(eth_deg)]))
    est = solve(ROOM, seen_from(ROOM, truth), start)
    assert est is not None
    err = relative(truth, est)
    assert math.hypot(err[0], err[1]) < 1e-5 and abs(err[2]) < 1e-9


def test_pairs_are_the_same_physical_lines() -> None:
    truth = np.array([0.3, -0.2, math.radians(10)])
    pairs = M.pair_lines(ROOM, seen_from(ROOM, truth), truth, math.radians(3), 0.2, 0.5)
    np.testing.assert_array_equal(pairs.prev_index, np.arange(len(ROOM)))
    np.testing.assert_array_equal(pairs.curr_index, np.arange(len(ROOM)))


def test_parallel_lines_apart_do_not_pair_and_extents_must_overlap() -> None:
    # a wall and a parallel box front 0.3 m in front of it: the gate keeps them apart
    prev = make_lines([0.0, 0.0], [4.0, 3.7])
    pairs = M.pair_lines(prev, prev, np.zeros(3), math.radians(3), 0.2, 0.5)
    np.testing.assert_array_equal(pairs.curr_index, pairs.prev_index)
    # the same line, but segments 10 m apart along it, does not pair
    far = make_lines([0.0], [4.0])
    moved = Lines(
        far.normal,
        far.distance,
        far.start + [0, 10],
        far.end + [0, 10],
        far.centre + [0, 10],
        far.n_points,
        far.sigma,
        far.delta,
        far.uncertainty,
        far.segment,
        far.cluster,
        far.angle_variance,
        far.distance_variance,
    )
    assert len(M.pair_lines(far, moved, np.zeros(3), math.radians(3), 0.2, 0.5)) == 0


def test_a_corridor_keeps_the_prior_along_its_length() -> None:
    """Two parallel walls (a corridor along x): the lines fix y and θ, the prior fixes x."""
    corridor = make_lines([math.pi / 2, -math.pi / 2], [1.0, 1.0], half_length=5.0)
    truth = np.array([0.4, 0.05, math.radians(2)])
    prior = np.array([0.25, 0.0, 0.0])  # odometry: 15 cm short, 5 cm and 2° off sideways
    est = solve(corridor, seen_from(corridor, truth), prior)
    assert est is not None
    assert abs(est[1] - truth[1]) < 1e-6 and abs(est[2] - truth[2]) < 1e-9
    assert abs(est[0] - prior[0]) < 1e-3  # along the corridor the prior decides


def test_one_false_line_pair_is_rejected() -> None:
    truth = np.array([0.2, 0.1, math.radians(5)])
    curr = seen_from(ROOM, truth)
    # one line of the next scan is off by 8 cm (a box front mistaken for the wall behind)
    bad = curr.distance.copy()
    bad[1] += 0.08
    curr = replace(curr, distance=bad)
    est = solve(ROOM, curr, truth)
    assert est is not None
    err = relative(truth, est)
    assert math.hypot(err[0], err[1]) < 1e-6 and abs(err[2]) < 1e-9


def test_noisy_lines_land_close() -> None:
    rng = np.random.default_rng(3)
    truth = np.array([0.3, -0.1, math.radians(-7)])
    errs = []
    for _ in range(50):
        curr = seen_from(ROOM, truth)
        ang = np.arctan2(curr.normal[:, 1], curr.normal[:, 0]) + rng.normal(
            0, 1e-3 / 1.5, len(curr)
        )
        n = np.column_stack([np.cos(ang), np.sin(ang)])
        d = curr.distance + rng.normal(0, 1e-3 / math.sqrt(30), len(curr))
        noisy = replace(curr, normal=n, distance=d)
        est = solve(ROOM, noisy, truth)
        assert est is not None
        errs.append(relative(truth, est))
    errs = np.array(errs)
    assert np.hypot(errs[:, 0], errs[:, 1]).max() < 0.005
    assert np.abs(errs[:, 2]).max() < math.radians(0.1)


def test_fewer_than_two_pairs_give_nothing() -> None:
    one = make_lines([0.0], [4.0])
    assert solve(one, one, np.zeros(3)) is None
    assert solve(ROOM, make_lines([1.0], [9.0]), np.zeros(3)) is None


def test_the_matcher_reads_a_keyframes_lines_once() -> None:
    """The line-matching kernel's arrays of the keyframe's lines are built once for every
    scan matched against it (and of a scan's, for when it becomes the keyframe): the same
    arrays, the same motion as a matcher that builds them afresh each time."""
    from fuzzypos.config import Config
    from fuzzypos.pipeline.feature_match import FeatureMatcher, _line_arrays

    cfg = Config()
    keyframe = ROOM
    scans = [seen_from(ROOM, np.array([0.05 * k, 0.02 * k, 0.01 * k])) for k in range(1, 4)]
    matcher = FeatureMatcher(cfg.matching, cfg.fusion)
    for k, scan in enumerate(scans, start=1):
        prior = np.array([0.05 * k, 0.02 * k, 0.01 * k]) + 0.01
        got = matcher.match_lines(keyframe, scan, None, prior)
        fresh = FeatureMatcher(cfg.matching, cfg.fusion).match_lines(keyframe, scan, None, prior)
        assert got[1] == fresh[1]
        np.testing.assert_array_equal(got[0], fresh[0])
        first = matcher._arrays_of(keyframe)
        assert matcher._arrays_of(keyframe) is first
        for x, y in zip(first, _line_arrays(keyframe), strict=True):
            np.testing.assert_array_equal(x, y)
    kept = [arrays for lines, arrays in matcher._recent if lines is scans[-1]]
    assert kept and matcher._arrays_of(scans[-1]) is kept[0]  # were it the next keyframe


def test_the_matchers_line_arrays_are_the_lines_own() -> None:
    """The line-matching kernel reads the lines' own values from its one flat array (the
    normals' angles it computes itself: ``Lines.normal_angle``'s within a last bit), for lines
    of the numpy chain and for the compiled chain's packed floats (read where they lie)."""
    from fuzzypos import sim
    from fuzzypos._kernels.lines import line_views
    from fuzzypos.config import Config
    from fuzzypos.features import extract_features
    from fuzzypos.pipeline.feature_match import _line_arrays

    scan = sim.simulate_scan(sim.world_by_name("office"), np.array([1.0, 0.5, 0.3]))
    packed = extract_features(scan, Config()).lines
    assert "_packed" in packed.__dict__ and len(packed) >= 2
    flat, first, nl = _line_arrays(packed)
    assert flat is packed.__dict__["_packed"].buffers[0] and first > 0  # no copy
    from fuzzypos._kernels import lines as kernel
    from fuzzypos._kernels.packing import LAYOUT

    for name, k in (("normal", kernel.LINE_NORMAL), ("distance", kernel.LINE_DISTANCE),
                    ("centre", kernel.LINE_CENTRE), ("angle_variance", kernel.LINE_ANGLE_VARIANCE),
                    ("distance_variance", kernel.LINE_DISTANCE_VARIANCE)):  # fmt: skip
        assert LAYOUT["Lines"][name][1][2] == k  # the kernel's layout is the packing's
    for lines in (ROOM, seen_from(ROOM, np.array([0.3, -0.2, 2.5])), packed):
        flat, first, nl = _line_arrays(lines)
        assert nl == len(lines)
        views = line_views(flat, first, nl)
        expected = (
            lines.normal_angle, lines.distance, lines.normal, lines.centre, lines.length,
            lines.angle_variance, lines.distance_variance,
        )  # fmt: skip
        # the angles: libm's atan2 in the kernel, numpy's own (SIMD on a CPU with AVX-512,
        # seen a last bit apart from libm's) in ``normal_angle``; the rest the very floats
        np.testing.assert_array_max_ulp(views[0], expected[0], maxulp=1)
        for got, want in zip(views[1:], expected[1:], strict=True):
            assert want is not None
            assert got.tobytes() == np.ascontiguousarray(want, dtype=np.float64).tobytes()


def test_the_matcher_needs_the_lines_variances() -> None:
    """Lines without variances (made by hand) are a typed error for the matcher, lines of
    none on either side give no motion."""
    import pytest

    from fuzzypos.config import Config
    from fuzzypos.features import FeatureError
    from fuzzypos.pipeline.feature_match import FeatureMatcher

    cfg = Config()
    matcher = FeatureMatcher(cfg.matching, cfg.fusion)
    bare = replace(ROOM, angle_variance=None, distance_variance=None)
    with pytest.raises(FeatureError, match="variances"):
        matcher.match_lines(bare, ROOM, None, np.zeros(3))
    none = make_lines([], [])
    assert matcher.match_lines(none, bare, None, np.zeros(3)) == (None, 0)
    assert matcher.match_lines(ROOM, ROOM, None, np.zeros(3))[0] is not None
